//! `[output.gige]`: where the camera lives, what it calls itself, and the bounds of
//! every size in it (refused at start, naming the key: `docs/serve-config.md`).

use super::discovery;
use super::gvcp::GVCP_PORT;
use super::registers::{self as reg, PACKET_SIZE_INC, PACKET_SIZE_MAX, PACKET_SIZE_MIN};
use std::net::Ipv4Addr;

/// Blocks the resend ring may keep: each is a whole frame (a 1024² Mono16 block is 2 MiB).
pub const RESEND_RING_MAX: usize = 64;
/// The link speeds the stream may be paced at, Mb/s: 10 Mb/s Ethernet to 100 GbE.
pub const LINK_MBPS_MIN: u32 = 10;
pub const LINK_MBPS_MAX: u32 = 100_000;

/// `[output.gige]`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GigeConfig {
    /// Address the GVCP and GVSP sockets bind (default 127.0.0.1; a real bench uses the
    /// address of the NIC facing the board). Clients address the camera by it.
    pub address: Ipv4Addr,
    /// GVCP port (3956, the standard; clients such as Aravis only use 3956).
    pub gvcp_port: u16,
    /// GVSP source port (0: any free port).
    pub stream_port: u16,
    /// Initial packet size (IP datagram bytes), until a client writes GevSCPSPacketSize.
    pub packet_size: u32,
    /// The speed of the link the camera simulates, Mb/s (default 1000): packets leave no
    /// faster than it carries them; a client's GevSCPD adds its delay after each.
    pub link_mbps: u32,
    /// Bootstrap strings: at most 31 bytes (manufacturer, model), 15 (serial, user_name).
    pub manufacturer: String,
    pub model: String,
    pub serial: String,
    /// DeviceUserID at start (clients may write it).
    pub user_name: String,
    /// Blocks kept for resends, 1..=[`RESEND_RING_MAX`].
    pub resend_ring: usize,
    /// Serve the XML zipped (stored) instead of plain.
    pub zip_xml: bool,
    /// The longest a slow write waits for the renderer before its final acknowledge
    /// (ms; the pending timeout register, and the time a PENDING_ACK announces).
    pub pending_timeout_ms: u32,
    /// Answer DISCOVERY_CMD sent to a broadcast address (extra sockets on
    /// `discovery_address` and on 255.255.255.255, port `gvcp_port`).
    pub broadcast_discovery: bool,
    /// Where directed-broadcast discovery is heard (default: the subnet broadcast of
    /// `address`, 127.255.255.255 on loopback). Not 0.0.0.0: Linux refuses it while the
    /// control socket holds the port on `address`.
    pub discovery_address: Option<Ipv4Addr>,
    /// Let a client stream to a broadcast or multicast address (SCDA). Off: only unicast
    /// destinations are accepted, so no client can spray the stream over a subnet.
    pub allow_broadcast_stream: bool,
}

impl Default for GigeConfig {
    fn default() -> Self {
        GigeConfig {
            address: Ipv4Addr::LOCALHOST,
            gvcp_port: GVCP_PORT,
            stream_port: 0,
            packet_size: 1500,
            link_mbps: 1000,
            manufacturer: "hilcam".into(),
            model: "hilcam simulated camera".into(),
            serial: "HILCAM0001".into(),
            user_name: String::new(),
            resend_ring: 8,
            zip_xml: false,
            pending_timeout_ms: 1000,
            broadcast_discovery: true,
            discovery_address: None,
            allow_broadcast_stream: false,
        }
    }
}

impl GigeConfig {
    /// Every key within its bounds: `Err((key, why))`, the key as the serve config spells it.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let a = self.address;
        if a.is_unspecified() || a.is_broadcast() || a.is_multicast() {
            return Err((
                "output.gige.address",
                format!(
                    "{a}: the camera needs one unicast address, which clients reach it at and its bootstrap \
                     registers report (the bench NIC's address, or 127.0.0.1)"
                ),
            ));
        }
        if !(1..=RESEND_RING_MAX).contains(&self.resend_ring) {
            return Err((
                "output.gige.resend_ring",
                format!("{}: must be 1..={RESEND_RING_MAX} blocks", self.resend_ring),
            ));
        }
        let p = self.packet_size;
        if !((PACKET_SIZE_MIN..=PACKET_SIZE_MAX).contains(&p) && p.is_multiple_of(PACKET_SIZE_INC)) {
            return Err((
                "output.gige.packet_size",
                format!("{p}: must be {PACKET_SIZE_MIN}..={PACKET_SIZE_MAX} in steps of {PACKET_SIZE_INC}"),
            ));
        }
        let l = self.link_mbps;
        if !(LINK_MBPS_MIN..=LINK_MBPS_MAX).contains(&l) {
            return Err(("output.gige.link_mbps", format!("{l}: must be {LINK_MBPS_MIN}..={LINK_MBPS_MAX} Mb/s")));
        }
        let t = self.pending_timeout_ms;
        if !(reg::PENDING_TIMEOUT_MIN_MS..=reg::PENDING_TIMEOUT_MAX_MS).contains(&t) {
            return Err((
                "output.gige.pending_timeout_ms",
                format!("{t}: must be {}..={} ms", reg::PENDING_TIMEOUT_MIN_MS, reg::PENDING_TIMEOUT_MAX_MS),
            ));
        }
        for (key, value, field_len) in [
            ("output.gige.manufacturer", &self.manufacturer, 32),
            ("output.gige.model", &self.model, 32),
            ("output.gige.serial", &self.serial, 16),
            ("output.gige.user_name", &self.user_name, reg::USER_NAME_LEN as usize),
        ] {
            // NUL-terminated bootstrap fields: one byte is the terminator.
            if value.len() >= field_len {
                return Err((
                    key,
                    format!("{value:?} is {} bytes of UTF-8; the field holds {}", value.len(), field_len - 1),
                ));
            }
        }
        if self.broadcast_discovery && self.discovery_address.is_some_and(|d| d.is_unspecified()) {
            return Err((
                "output.gige.discovery_address",
                format!(
                    "0.0.0.0: port {} is already the control socket's on {a}, so it cannot also be bound on every \
                     address; use the subnet's broadcast address (the default, {}); limited broadcasts \
                     (255.255.255.255) are heard anyway",
                    self.gvcp_port,
                    discovery::subnet_broadcast(a)
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(cfg: GigeConfig) -> String {
        let (key, why) = cfg.validate().expect_err("refused");
        format!("{key}: {why}")
    }

    #[test]
    fn every_size_has_a_bound_named_by_its_key() {
        assert!(GigeConfig::default().validate().is_ok());
        let d = GigeConfig::default;
        let e = refused(GigeConfig { resend_ring: 1_000_000_000, ..d() });
        assert_eq!(e, "output.gige.resend_ring: 1000000000: must be 1..=64 blocks");
        assert!(refused(GigeConfig { resend_ring: 0, ..d() }).starts_with("output.gige.resend_ring: 0"));
        assert!(refused(GigeConfig { packet_size: 100_000, ..d() }).starts_with("output.gige.packet_size: 100000"));
        let e = refused(GigeConfig { pending_timeout_ms: 70_000, ..d() });
        assert_eq!(e, "output.gige.pending_timeout_ms: 70000: must be 10..=65535 ms");
        assert_eq!(refused(GigeConfig { link_mbps: 0, ..d() }), "output.gige.link_mbps: 0: must be 10..=100000 Mb/s");
        // 8 characters, 16 bytes: refused whole, never cut mid-character.
        let e = refused(GigeConfig { user_name: "ÄÖÜßäöüé".into(), ..d() });
        assert!(e.starts_with("output.gige.user_name: \"ÄÖÜßäöüé\" is 16 bytes"), "{e}");
        assert!(GigeConfig { user_name: "Kamera äöü 1".into(), ..d() }.validate().is_ok());
        assert!(refused(GigeConfig { model: "m".repeat(32), ..d() }).starts_with("output.gige.model"));
    }

    #[test]
    fn unusable_addresses_name_what_to_use_instead() {
        let d = GigeConfig::default;
        let e = refused(GigeConfig {
            address: Ipv4Addr::new(127, 0, 0, 35),
            discovery_address: Some(Ipv4Addr::UNSPECIFIED),
            ..d()
        });
        assert!(e.starts_with("output.gige.discovery_address: 0.0.0.0") && e.contains("127.255.255.255"), "{e}");
        let e = refused(GigeConfig { address: Ipv4Addr::UNSPECIFIED, ..d() });
        assert!(e.starts_with("output.gige.address: 0.0.0.0") && !e.contains("0.0.0.255"), "{e}");
        assert!(refused(GigeConfig { address: Ipv4Addr::new(239, 1, 1, 1), ..d() }).starts_with("output.gige.address"));
    }
}
