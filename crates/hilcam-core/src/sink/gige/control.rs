//! The control channel's logic: GVCP commands in, acknowledges and effects out, with
//! the control privilege (CCP) and its heartbeat. Pure: the caller passes the peer and
//! the time; `device.rs` owns the socket.
//!
//! Rules (GigE Vision control / exclusive access; `docs/gige.md`, "Privilege"):
//! - Anyone may discover. The first client that writes CCP with the control (bit 1) or
//!   exclusive (bit 0) bit becomes the controller; while it holds the privilege, writes
//!   from any other client are refused with ACCESS_DENIED, including its CCP write.
//! - Exclusive access also refuses others' reads (and ignores their resend requests);
//!   control access lets them read (monitor).
//! - Stream channel registers (SCP, SCPS, SCPD, SCDA, SCCFG) are written by the
//!   controller only: without one they are refused too, so no stranger opens or
//!   redirects the stream.
//! - PACKETRESEND is honoured only from the stream's destination address.
//! - Every command from the controller is a heartbeat; after `GevHeartbeatTimeout` ms
//!   without one control is released, acquisition stops and the stream channel closes.
//!   With the heartbeat disabled the same happens after
//!   [`reg::HEARTBEAT_DISABLED_RELEASE_MS`] of silence, so a vanished controller cannot
//!   hold the camera for ever.
//! - With no controller, other writes are accepted from anyone (as Aravis' fake camera
//!   does), so `arv-tool control Width=…` works without a session.

use super::gvcp::{self, Command, Request, Status, code};
use super::registers::{self as reg, Effect, Registers};
use std::net::{IpAddr, SocketAddr};
use std::time::{Duration, Instant};

/// What handling one datagram produced.
#[derive(Debug, Default)]
pub struct Outcome {
    /// The acknowledge to send back to the peer (None: nothing to send).
    pub reply: Option<Vec<u8>>,
    /// Effects of the writes that succeeded, in order.
    pub effects: Vec<Effect>,
    /// A resend request: (block id, first packet, last packet).
    pub resend: Option<(u64, u32, u32)>,
    /// The command was malformed or refused: this status went back (or would have).
    pub error: Option<Status>,
    /// Why (for the log).
    pub reason: Option<String>,
    /// The rejection's class, the `reason` label of `hilcam_gige_commands_rejected_total`.
    pub class: Option<Rejection>,
    /// The controller's privilege was taken, released or lost.
    pub control_changed: bool,
}

/// Classes of rejected commands (metric labels).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Rejection {
    /// Not a valid GVCP command (header, length, unknown code).
    Malformed,
    /// Valid, but the address or value is refused.
    Refused,
    /// Another client holds the privilege this needs.
    AccessDenied,
    /// PACKETRESEND from an address that is not the stream's destination.
    ResendNotDestination,
}

impl Rejection {
    pub const ALL: [Rejection; 4] =
        [Rejection::Malformed, Rejection::Refused, Rejection::AccessDenied, Rejection::ResendNotDestination];

    pub fn label(self) -> &'static str {
        match self {
            Rejection::Malformed => "malformed",
            Rejection::Refused => "refused",
            Rejection::AccessDenied => "access_denied",
            Rejection::ResendNotDestination => "resend_not_destination",
        }
    }
}

/// Control-channel state around the register map.
pub struct Control {
    pub regs: Registers,
    controller: Option<(SocketAddr, Instant)>,
    /// Commands answered with PENDING_ACK whose final acknowledge has not gone out. A
    /// client waiting for one sends no heartbeat, so none expires meanwhile.
    pending: u32,
}

impl Control {
    pub fn new(regs: Registers) -> Self {
        Control { regs, controller: None, pending: 0 }
    }

    /// A command from `peer` was answered with PENDING_ACK.
    pub fn begin_pending(&mut self) {
        self.pending += 1;
    }

    /// Its final acknowledge went out at `now`: the controller's heartbeat counts from here.
    pub fn end_pending(&mut self, peer: SocketAddr, now: Instant) {
        self.pending = self.pending.saturating_sub(1);
        if let Some((addr, ref mut last)) = self.controller
            && addr == peer
        {
            *last = now;
        }
    }

    pub fn controller(&self) -> Option<SocketAddr> {
        self.controller.map(|(a, _)| a)
    }

    /// Release control if the controller's heartbeat is older than the timeout.
    /// Returns true when it did (acquisition stopped, stream closed).
    pub fn expire(&mut self, now: Instant) -> bool {
        let Some((_, last)) = self.controller else { return false };
        if self.pending > 0 {
            return false;
        }
        let timeout_ms = if self.regs.heartbeat_disabled() {
            reg::HEARTBEAT_DISABLED_RELEASE_MS.max(self.regs.heartbeat_timeout_ms)
        } else {
            self.regs.heartbeat_timeout_ms
        };
        if now.saturating_duration_since(last) > Duration::from_millis(u64::from(timeout_ms)) {
            self.release();
            return true;
        }
        false
    }

    fn release(&mut self) {
        self.controller = None;
        self.regs.ccp = 0;
        self.regs.acquiring = false;
        self.regs.tl_params_locked = false;
        self.regs.stream.host_port = 0;
    }

    /// Whether `peer` is shut out by another client's exclusive access.
    fn excluded(&self, peer: SocketAddr) -> bool {
        self.regs.ccp & reg::CCP_EXCLUSIVE != 0 && self.controller.is_some_and(|(c, _)| c != peer)
    }

    /// Handle one datagram from `peer` at `now`.
    pub fn handle(&mut self, datagram: &[u8], peer: SocketAddr, now: Instant) -> Outcome {
        let mut out = Outcome { control_changed: self.expire(now), ..Outcome::default() };
        let req = match gvcp::decode(datagram) {
            Ok(r) => r,
            Err(rejected) => {
                out.reply = gvcp::reject_ack(&rejected);
                out.error = Some(rejected.status);
                out.reason = Some(rejected.reason);
                out.class = Some(Rejection::Malformed);
                return out;
            }
        };
        if let Some((addr, ref mut last)) = self.controller
            && addr == peer
        {
            *last = now;
        }
        let ack = req.ack_required();
        if req.command != Command::Discovery && self.excluded(peer) {
            out.error = Some(Status::AccessDenied);
            out.reason = Some(format!("command {:#06x}: another client has exclusive access", req.code));
            out.class = Some(Rejection::AccessDenied);
            if ack && !matches!(req.command, Command::PacketResend { .. }) {
                out.reply = Some(gvcp::encode_ack(Status::AccessDenied, gvcp::ack_code(req.code), req.req_id, &[]));
            }
            return out;
        }
        let reply = self.dispatch(&req, peer, now, &mut out);
        if ack || req.code == code::DISCOVERY_CMD {
            out.reply = reply;
        }
        out
    }

    fn dispatch(&mut self, req: &Request, peer: SocketAddr, now: Instant, out: &mut Outcome) -> Option<Vec<u8>> {
        let id = req.req_id;
        let fail = |status: Status, reason: String, out: &mut Outcome| {
            out.error = Some(status);
            out.reason = Some(reason);
            let class = if status == Status::AccessDenied { Rejection::AccessDenied } else { Rejection::Refused };
            out.class = Some(class);
        };
        match &req.command {
            Command::Discovery => {
                let data = self.regs.read_block(0, reg::DISCOVERY_LEN).expect("bootstrap block is readable");
                Some(gvcp::encode_ack(Status::Success, code::DISCOVERY_ACK, id, &data))
            }
            Command::ReadReg(addrs) => {
                let mut values = Vec::with_capacity(addrs.len());
                for &a in addrs {
                    match self.regs.read_u32(a) {
                        Ok(v) => values.push(v),
                        Err(st) => {
                            fail(st, format!("READREG {a:#010x}"), out);
                            return Some(gvcp::readreg_ack(st, id, &values));
                        }
                    }
                }
                Some(gvcp::readreg_ack(Status::Success, id, &values))
            }
            Command::WriteReg(pairs) => {
                for (i, &(a, v)) in pairs.iter().enumerate() {
                    if let Err(st) = self.write_word(a, v, peer, now, out) {
                        fail(st, format!("WRITEREG {a:#010x} = {v:#010x}"), out);
                        return Some(gvcp::writereg_ack(st, id, i as u16));
                    }
                }
                Some(gvcp::writereg_ack(Status::Success, id, pairs.len() as u16))
            }
            Command::ReadMem { address, count } => match self.regs.read_block(*address, u32::from(*count)) {
                Ok(data) => Some(gvcp::readmem_ack(id, *address, &data)),
                Err(st) => {
                    fail(st, format!("READMEM {address:#010x} + {count}"), out);
                    Some(gvcp::encode_ack(st, code::READMEM_ACK, id, &address.to_be_bytes()))
                }
            },
            Command::WriteMem { address, data } => {
                for (k, w) in data.chunks_exact(4).enumerate() {
                    let a = address.wrapping_add(4 * k as u32);
                    let v = u32::from_be_bytes(w.try_into().expect("4 bytes"));
                    if let Err(st) = self.write_word(a, v, peer, now, out) {
                        fail(st, format!("WRITEMEM {a:#010x}"), out);
                        return Some(gvcp::writemem_ack(st, id, (4 * k) as u16));
                    }
                }
                Some(gvcp::writemem_ack(Status::Success, id, data.len() as u16))
            }
            Command::PacketResend { block_id, first, last } => {
                let ch = &self.regs.stream;
                if ch.host_port != 0 && IpAddr::V4(ch.destination) == peer.ip() {
                    out.resend = Some((*block_id, *first, *last));
                } else {
                    out.error = Some(Status::AccessDenied);
                    out.reason = Some(format!("PACKETRESEND from {peer}: the stream goes to {}", ch.destination));
                    out.class = Some(Rejection::ResendNotDestination);
                }
                None
            }
        }
    }

    /// One register write with the privilege rules; CCP is handled here.
    fn write_word(&mut self, a: u32, v: u32, peer: SocketAddr, now: Instant, out: &mut Outcome) -> Result<(), Status> {
        let held_by_other = matches!(self.controller, Some((c, _)) if c != peer);
        if held_by_other {
            return Err(Status::AccessDenied);
        }
        // The stream channel is the controller's: nobody else opens or redirects it.
        if Registers::is_stream_channel(a) && self.controller.is_none() {
            return Err(Status::AccessDenied);
        }
        if a == reg::CCP {
            if v & (reg::CCP_CONTROL | reg::CCP_EXCLUSIVE) != 0 {
                if self.controller.is_none() {
                    out.control_changed = true;
                }
                self.controller = Some((peer, now));
                self.regs.ccp = v & (reg::CCP_CONTROL | reg::CCP_EXCLUSIVE);
            } else {
                if self.controller.is_some() {
                    out.control_changed = true;
                    out.effects.push(Effect::AcquisitionStop);
                }
                self.release();
            }
            return Ok(());
        }
        let effect = self.regs.write_u32(a, v)?;
        match effect {
            Effect::AcquisitionStart => self.regs.acquiring = true,
            Effect::AcquisitionStop => self.regs.acquiring = false,
            _ => {}
        }
        out.effects.push(effect);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sink::gige::gvcp::{FLAG_ACK_REQUIRED, decode_ack, encode_command};
    use crate::sink::gige::registers::tests::registers;

    fn writereg(a: u32, v: u32, id: u16) -> Vec<u8> {
        let mut p = a.to_be_bytes().to_vec();
        p.extend_from_slice(&v.to_be_bytes());
        encode_command(FLAG_ACK_REQUIRED, code::WRITEREG_CMD, id, &p)
    }

    fn status(o: &Outcome) -> u16 {
        decode_ack(o.reply.as_ref().unwrap()).unwrap().status
    }

    #[test]
    fn second_client_cannot_take_control_and_heartbeat_expiry_releases() {
        let mut c = Control::new(registers());
        let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.1:5000".parse().unwrap(), "127.0.0.1:5001".parse().unwrap());
        let t0 = Instant::now();
        let o = c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 1), a, t0);
        assert_eq!(status(&o), 0);
        assert!(o.control_changed);
        assert_eq!(status(&c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 2), b, t0)), Status::AccessDenied.code());
        assert_eq!(status(&c.handle(&writereg(reg::WIDTH, 16, 3), b, t0)), Status::AccessDenied.code());
        assert_eq!(status(&c.handle(&writereg(reg::ACQUISITION_START, 1, 4), a, t0)), 0);
        assert!(c.regs.acquiring);
        // 3 s default timeout: a command at 2 s keeps control, silence until 5.1 s loses it.
        c.handle(
            &encode_command(FLAG_ACK_REQUIRED, code::READREG_CMD, 5, &reg::CCP.to_be_bytes()),
            a,
            t0 + Duration::from_secs(2),
        );
        assert!(!c.expire(t0 + Duration::from_millis(4900)));
        assert!(c.expire(t0 + Duration::from_millis(5100)));
        assert!(!c.regs.acquiring);
        assert_eq!(c.controller(), None);
        assert_eq!(status(&c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 6), b, t0 + Duration::from_secs(6))), 0);
        assert_eq!(c.controller(), Some(b));
    }

    fn readreg(a: u32, id: u16) -> Vec<u8> {
        encode_command(FLAG_ACK_REQUIRED, code::READREG_CMD, id, &a.to_be_bytes())
    }

    /// Issue 37, defect 7: a stranger could write the stream channel and redirect it.
    #[test]
    fn only_the_controller_opens_or_redirects_the_stream() {
        let mut c = Control::new(registers());
        let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.1:5000".parse().unwrap(), "127.0.0.2:5001".parse().unwrap());
        let t0 = Instant::now();
        for r in [reg::SCDA0, reg::SCP0, reg::SCPD0, reg::SCPS0] {
            let o = c.handle(&writereg(r, 1500, 1), b, t0);
            assert_eq!((status(&o), o.class), (Status::AccessDenied.code(), Some(Rejection::AccessDenied)), "{r:#x}");
        }
        assert_eq!(status(&c.handle(&writereg(reg::WIDTH, 32, 2), b, t0)), 0, "other writes need no session");
        c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 3), a, t0);
        assert_eq!(status(&c.handle(&writereg(reg::SCDA0, 0x7f00_0001, 4), a, t0)), 0);
        assert_eq!(status(&c.handle(&writereg(reg::SCDA0, 0x7f00_0002, 5), b, t0)), Status::AccessDenied.code());
        assert_eq!(c.regs.stream.destination, std::net::Ipv4Addr::LOCALHOST);
    }

    #[test]
    fn exclusive_access_refuses_others_reads_control_access_does_not() {
        let mut c = Control::new(registers());
        let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.1:5000".parse().unwrap(), "127.0.0.2:5001".parse().unwrap());
        let t0 = Instant::now();
        c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 1), a, t0);
        assert_eq!(status(&c.handle(&readreg(reg::WIDTH, 2), b, t0)), 0, "control access: others may read");
        c.handle(&writereg(reg::CCP, reg::CCP_EXCLUSIVE, 3), a, t0);
        let o = c.handle(&readreg(reg::WIDTH, 4), b, t0);
        assert_eq!((status(&o), o.class), (Status::AccessDenied.code(), Some(Rejection::AccessDenied)));
        let o = c.handle(&encode_command(FLAG_ACK_REQUIRED, code::DISCOVERY_CMD, 5, &[]), b, t0);
        assert_eq!(status(&o), 0, "discovery is always answered");
        assert_eq!(status(&c.handle(&readreg(reg::WIDTH, 6), a, t0)), 0);
    }

    /// Issue 37, defect 7: with the heartbeat disabled a vanished controller held the
    /// camera for ever.
    #[test]
    fn a_silent_controller_is_released_even_with_the_heartbeat_disabled() {
        let mut c = Control::new(registers());
        let a: SocketAddr = "127.0.0.1:5000".parse().unwrap();
        let t0 = Instant::now();
        c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 1), a, t0);
        c.handle(&writereg(reg::GVCP_CONFIG, reg::GVCP_CONFIG_HEARTBEAT_DISABLE, 2), a, t0);
        assert!(!c.expire(t0 + Duration::from_secs(30)), "heartbeat disabled: 3 s of silence is fine");
        let limit = Duration::from_millis(u64::from(reg::HEARTBEAT_DISABLED_RELEASE_MS));
        assert!(c.expire(t0 + limit + Duration::from_millis(1)));
        assert_eq!(c.controller(), None);
    }

    /// Issue 37, defect 2: PACKETRESEND was served for anyone.
    #[test]
    fn resends_are_served_only_for_the_streams_destination() {
        let mut c = Control::new(registers());
        let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.1:5000".parse().unwrap(), "127.0.0.2:5001".parse().unwrap());
        let t0 = Instant::now();
        let resend = encode_command(0, code::PACKETRESEND_CMD, 9, &[0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 2]);
        let o = c.handle(&resend, a, t0);
        assert_eq!((o.resend, o.class), (None, Some(Rejection::ResendNotDestination)), "no stream open");
        c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 1), a, t0);
        c.handle(&writereg(reg::SCDA0, 0x7f00_0001, 2), a, t0);
        c.handle(&writereg(reg::SCP0, 40000, 3), a, t0);
        assert_eq!(c.handle(&resend, a, t0).resend, Some((1, 1, 2)));
        let o = c.handle(&resend, b, t0);
        assert_eq!((o.resend, o.class, o.reply), (None, Some(Rejection::ResendNotDestination), None));
    }

    proptest::proptest! {
        /// Random and adversarial datagrams from a stranger and the controller: no panic,
        /// every rejection classified, and whatever is accepted leaves the registers
        /// within their bounds (the ROI inside the sensor, the delay bounded, the stream
        /// unicast and the controller's).
        #[test]
        fn hostile_datagrams_leave_the_registers_in_bounds(
            ops in proptest::collection::vec((0u8..6, proptest::prelude::any::<u32>(), proptest::prelude::any::<u32>(),
                                               proptest::collection::vec(proptest::prelude::any::<u8>(), 0..64)), 1..64)
        ) {
            let mut c = Control::new(registers());
            let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.1:5000".parse().unwrap(), "127.0.0.2:5001".parse().unwrap());
            let t0 = Instant::now();
            c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 1), a, t0);
            let addrs = [reg::SCPD0, reg::SCDA0, reg::SCP0, reg::SCPS0, reg::WIDTH, reg::OFFSET_X, reg::HEIGHT,
                         reg::USER_NAME, reg::CHUNK_SELECTOR, reg::CHUNK_ENABLE, reg::TL_PARAMS_LOCKED, reg::CCP];
            for (k, (kind, x, v, raw)) in ops.into_iter().enumerate() {
                let peer = if k % 2 == 0 { a } else { b };
                let addr = addrs[x as usize % addrs.len()];
                let datagram = match kind {
                    0 => raw,
                    1 => writereg(addr, v, k as u16),
                    2 => writereg(x, v, k as u16),
                    3 => readreg(x & !3, k as u16),
                    4 => encode_command(0, code::PACKETRESEND_CMD, k as u16, &[x.to_be_bytes(), v.to_be_bytes(), v.to_be_bytes()].concat()),
                    _ => encode_command(raw.first().copied().unwrap_or(1), (x & 0xFFFF) as u16, k as u16, &raw),
                };
                let before = c.regs.stream;
                let o = c.handle(&datagram, peer, t0);
                proptest::prop_assert_eq!(o.error.is_some(), o.class.is_some());
                let r = &c.regs;
                let s = &r.settings;
                proptest::prop_assert!(s.width >= 1 && s.offset_x + s.width <= r.camera.sensor_width);
                proptest::prop_assert!(s.height >= 1 && s.offset_y + s.height <= r.camera.sensor_height);
                proptest::prop_assert!(r.stream.packet_delay_ticks <= reg::SCPD_MAX_TICKS);
                let d = r.stream.destination;
                proptest::prop_assert!(!(d.is_broadcast() || d.is_multicast() || d == std::net::Ipv4Addr::new(127, 255, 255, 255)));
                proptest::prop_assert!(std::str::from_utf8(r.user_id().as_bytes()).is_ok());
                let st = r.stream;
                let shaped = (st.destination, st.packet_delay_ticks, st.packet_size)
                    != (before.destination, before.packet_delay_ticks, before.packet_size)
                    || (st.host_port != before.host_port && st.host_port != 0);
                if shaped {
                    proptest::prop_assert_eq!(c.controller(), Some(peer), "only the controller shapes the stream");
                }
            }
        }
    }

    #[test]
    fn no_heartbeat_expires_while_a_pending_command_waits() {
        let mut c = Control::new(registers());
        let a: SocketAddr = "127.0.0.1:5000".parse().unwrap();
        let t0 = Instant::now();
        c.handle(&writereg(reg::CCP, reg::CCP_CONTROL, 1), a, t0);
        c.begin_pending();
        assert!(!c.expire(t0 + Duration::from_secs(10)), "the client is waiting for our acknowledge");
        c.end_pending(a, t0 + Duration::from_secs(10));
        assert!(!c.expire(t0 + Duration::from_secs(12)), "the heartbeat counts from the final acknowledge");
        assert!(c.expire(t0 + Duration::from_millis(13_100)));
    }

    #[test]
    fn bad_writes_and_garbage_get_statuses() {
        let mut c = Control::new(registers());
        let a: SocketAddr = "127.0.0.1:5000".parse().unwrap();
        let now = Instant::now();
        let o = c.handle(&writereg(reg::WIDTH, 1_000_000, 1), a, now);
        assert_eq!(status(&o), Status::InvalidParameter.code());
        assert_eq!(o.error, Some(Status::InvalidParameter));
        let o = c.handle(&[0x42, 1, 0, 0x80, 0, 3, 0, 9, 1, 2, 3], a, now);
        assert_eq!(status(&o), Status::InvalidParameter.code());
        let o = c.handle(b"hello", a, now);
        assert!(o.reply.is_none() && o.error == Some(Status::InvalidHeader));
    }

    #[test]
    fn discovery_carries_the_bootstrap_block() {
        let mut c = Control::new(registers());
        let o = c.handle(
            &encode_command(0x10, code::DISCOVERY_CMD, 1, &[]),
            "127.0.0.1:1".parse().unwrap(),
            Instant::now(),
        );
        let ack = decode_ack(o.reply.as_ref().unwrap()).unwrap();
        assert_eq!(ack.answer, code::DISCOVERY_ACK);
        assert_eq!(ack.payload.len(), reg::DISCOVERY_LEN as usize);
        assert_eq!(&ack.payload[reg::MODEL_NAME as usize..reg::MODEL_NAME as usize + 10], b"hilcam-sim");
    }
}
