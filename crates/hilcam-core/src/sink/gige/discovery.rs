//! Broadcast discovery: a client that does not know the camera's address sends
//! DISCOVERY_CMD to a broadcast address, port 3956. On Linux a datagram sent to a
//! broadcast address reaches sockets bound to that address or to 0.0.0.0, never one
//! bound to a unicast address (such as the control socket), so the device listens on
//! an extra socket bound to the broadcast address. It is bound with SO_REUSEADDR so
//! that every camera on the host hears the same broadcast and answers it.
//!
//! Answers go out from the control socket (source: the camera's address and GVCP
//! port), to the sender; when the client allows broadcast acknowledges (flag 0x10,
//! for a client outside the camera's subnet) a copy is also broadcast to the subnet,
//! at the sender's port.

use super::gvcp::{self, Command};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};

/// DISCOVERY_CMD flag: the client accepts a broadcast DISCOVERY_ACK.
pub const FLAG_ALLOW_BROADCAST_ACK: u8 = 0x10;

/// The broadcast address of the camera's subnet: the loopback network's
/// (127.255.255.255) on loopback, else the /24 the subnet register (0x0034) reports.
pub fn subnet_broadcast(ip: Ipv4Addr) -> Ipv4Addr {
    let o = ip.octets();
    if ip.is_loopback() { Ipv4Addr::new(127, 255, 255, 255) } else { Ipv4Addr::new(o[0], o[1], o[2], 255) }
}

/// Whether `datagram` is a DISCOVERY_CMD (the only command a device answers on a
/// broadcast address).
pub fn is_discovery(datagram: &[u8]) -> bool {
    gvcp::decode(datagram).is_ok_and(|r| r.command == Command::Discovery)
}

/// Whether `datagram` is a DISCOVERY_CMD that allows a broadcast acknowledge.
pub fn broadcast_ack_allowed(datagram: &[u8]) -> bool {
    gvcp::decode(datagram).is_ok_and(|r| r.command == Command::Discovery && r.flags & FLAG_ALLOW_BROADCAST_ACK != 0)
}

/// Where the broadcast copy of an acknowledge to `peer` goes.
pub fn broadcast_destination(broadcast: Ipv4Addr, peer: SocketAddr) -> SocketAddr {
    SocketAddr::V4(SocketAddrV4::new(broadcast, peer.port()))
}

/// Bind the discovery socket on `addr:port`, shared with other cameras on the host.
pub fn bind(addr: Ipv4Addr, port: u16) -> std::io::Result<tokio::net::UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    s.set_reuse_address(true)?;
    s.set_nonblocking(true)?;
    s.bind(&SocketAddr::V4(SocketAddrV4::new(addr, port)).into())?;
    tokio::net::UdpSocket::from_std(s.into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sink::gige::gvcp::{FLAG_ACK_REQUIRED, code, encode_command};

    #[test]
    fn broadcast_addresses_and_flags() {
        assert_eq!(subnet_broadcast(Ipv4Addr::new(127, 0, 0, 34)), Ipv4Addr::new(127, 255, 255, 255));
        assert_eq!(subnet_broadcast(Ipv4Addr::new(192, 168, 7, 20)), Ipv4Addr::new(192, 168, 7, 255));
        let plain = encode_command(FLAG_ACK_REQUIRED, code::DISCOVERY_CMD, 0xffff, &[]);
        let allow = encode_command(FLAG_ACK_REQUIRED | FLAG_ALLOW_BROADCAST_ACK, code::DISCOVERY_CMD, 1, &[]);
        let read = encode_command(FLAG_ACK_REQUIRED | FLAG_ALLOW_BROADCAST_ACK, code::READREG_CMD, 2, &[0, 0, 0, 0]);
        assert!(is_discovery(&plain) && is_discovery(&allow) && !is_discovery(&read) && !is_discovery(b"\x42"));
        assert!(!broadcast_ack_allowed(&plain) && broadcast_ack_allowed(&allow) && !broadcast_ack_allowed(&read));
    }

    #[tokio::test]
    async fn several_cameras_share_the_discovery_address() {
        let a = bind(Ipv4Addr::new(127, 255, 255, 255), 0).unwrap();
        let port = a.local_addr().unwrap().port();
        let b = bind(Ipv4Addr::new(127, 255, 255, 255), port).expect("a second camera binds the same address");
        assert_eq!(b.local_addr().unwrap().port(), port);
    }
}
