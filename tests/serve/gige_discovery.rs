//! Broadcast discovery on loopback: `lo` has no broadcast address, but Linux delivers
//! a datagram sent to 127.255.255.255 to sockets bound to that address, which is where
//! the device listens for discovery by default when its address is a loopback one.
//! Every camera on the host answers; this test picks its own by the IP in the ack.

use crate::gige::{Rig, run};
use hilcam_core::sink::gige::discovery::FLAG_ALLOW_BROADCAST_ACK;
use hilcam_core::sink::gige::gvcp::{self, FLAG_ACK_REQUIRED, code};
use hilcam_core::sink::gige::registers as reg;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

const LOOPBACK_BROADCAST: Ipv4Addr = Ipv4Addr::new(127, 255, 255, 255);

/// The DISCOVERY_ACKs `sock` receives within `wait`, with their senders.
fn acks(sock: &UdpSocket, wait: Duration) -> Vec<(SocketAddr, gvcp::Ack)> {
    let until = Instant::now() + wait;
    let mut out = Vec::new();
    let mut buf = [0u8; 1024];
    while let Some(left) = until.checked_duration_since(Instant::now()).filter(|d| !d.is_zero()) {
        sock.set_read_timeout(Some(left)).unwrap();
        match sock.recv_from(&mut buf) {
            Ok((n, from)) => out.extend(gvcp::decode_ack(&buf[..n]).map(|a| (from, a))),
            Err(_) => break,
        }
    }
    out
}

fn current_ip(ack: &gvcp::Ack) -> Ipv4Addr {
    let i = reg::CURRENT_IP as usize;
    Ipv4Addr::from(u32::from_be_bytes(ack.payload[i..i + 4].try_into().unwrap()))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn broadcast_discovery_is_answered_with_the_control_address_and_arv_tool_still_finds_it_by_ip() {
    let ip = Ipv4Addr::new(127, 0, 0, 34);
    let rig = Rig::start(ip, 320, 240).await;
    let gvcp_port = rig.device.gvcp_addr().port();
    assert_eq!(rig.device.discovery_addr(), Some(SocketAddr::from((LOOPBACK_BROADCAST, gvcp_port))));
    tokio::task::spawn_blocking(move || {
        // 1. To the broadcast address: a unicast DISCOVERY_ACK from the camera's control address.
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        client.set_broadcast(true).unwrap();
        let to = SocketAddr::from((LOOPBACK_BROADCAST, gvcp_port));
        client.send_to(&gvcp::encode_command(FLAG_ACK_REQUIRED, code::DISCOVERY_CMD, 0xffff, &[]), to).unwrap();
        let got = acks(&client, Duration::from_millis(500));
        let (from, ack) =
            got.iter().find(|(_, a)| current_ip(a) == ip).unwrap_or_else(|| panic!("{ip} did not answer: {got:?}"));
        assert_eq!(*from, SocketAddr::from((ip, gvcp_port)), "answered from the control socket");
        assert_eq!((ack.status, ack.answer, ack.ack_id), (0, code::DISCOVERY_ACK, 0xffff));
        assert_eq!(ack.payload.len(), reg::DISCOVERY_LEN as usize);
        let model = &ack.payload[reg::MODEL_NAME as usize..][..23];
        assert_eq!(model, b"hilcam simulated camera");

        // 2. A client that allows a broadcast acknowledge also gets one on the broadcast
        //    address at its port (a socket bound there hears it; one on 127.0.0.1 would not).
        let listener = UdpSocket::bind((LOOPBACK_BROADCAST, 0)).unwrap();
        let port = listener.local_addr().unwrap().port();
        let sender = UdpSocket::bind(("127.0.0.1", port)).unwrap();
        sender.set_broadcast(true).unwrap();
        let flags = FLAG_ACK_REQUIRED | FLAG_ALLOW_BROADCAST_ACK;
        sender.send_to(&gvcp::encode_command(flags, code::DISCOVERY_CMD, 7, &[]), to).unwrap();
        let unicast = acks(&sender, Duration::from_millis(500));
        assert!(unicast.iter().any(|(_, a)| current_ip(a) == ip && a.ack_id == 7), "unicast copy: {unicast:?}");
        let broadcast = acks(&listener, Duration::from_millis(500));
        assert!(broadcast.iter().any(|(_, a)| current_ip(a) == ip && a.ack_id == 7), "broadcast copy: {broadcast:?}");

        // 3. Anything but DISCOVERY_CMD on the broadcast address is ignored (and counted).
        client.send_to(&gvcp::encode_command(FLAG_ACK_REQUIRED, code::READREG_CMD, 8, &[0, 0, 0, 0]), to).unwrap();
        assert!(acks(&client, Duration::from_millis(300)).is_empty(), "no camera answers a broadcast READREG");
    })
    .await
    .unwrap();
    assert_eq!(rig.counter("hilcam_gige_broadcast_discoveries_total", &[]), 2);
    assert_eq!(rig.counter("hilcam_gige_broadcast_acks_total", &[]), 1);
    assert_eq!(rig.counter("hilcam_gige_commands_rejected_total", &[("reason", "broadcast")]), 1);

    // Aravis, by address, as before.
    let (ok, out) =
        run("arv-tool-0.8", vec!["-a".into(), ip.to_string(), "control".into(), "SensorWidth".into()]).await;
    assert!(ok && out.contains("SensorWidth = 320"), "{out}");
}

#[tokio::test]
async fn unusable_discovery_and_pending_settings_are_refused_by_name() {
    use hilcam_core::metrics::Registry;
    use hilcam_core::sink::gige::{GigeConfig, GigeDevice};
    let ip = Ipv4Addr::new(127, 0, 0, 35);
    let refused = |cfg: GigeConfig| async move {
        match GigeDevice::start(&cfg, crate::gige::camera(64, 48), Registry::new()).await {
            Ok(_) => panic!("{cfg:?} accepted"),
            Err(e) => e.to_string(),
        }
    };
    let e =
        refused(GigeConfig { address: ip, discovery_address: Some(Ipv4Addr::UNSPECIFIED), ..GigeConfig::default() })
            .await;
    assert!(e.contains("output.gige.discovery_address: 0.0.0.0") && e.contains("127.255.255.255"), "{e}");
    let e = refused(GigeConfig { address: ip, pending_timeout_ms: 70_000, ..GigeConfig::default() }).await;
    assert!(e.contains("output.gige.pending_timeout_ms: 70000") && e.contains("10..=65535"), "{e}");
}
