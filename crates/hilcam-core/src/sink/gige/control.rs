//! The control channel's logic: GVCP commands in, acknowledges and effects out, with
//! the control privilege (CCP) and its heartbeat. Pure: the caller passes the peer and
//! the time; `device.rs` owns the socket.
//!
//! Rules: anyone may discover and read. The first client that writes CCP with the
//! control (or exclusive) bit becomes the controller; while it holds control, writes
//! from any other client are refused with ACCESS_DENIED, including its CCP write. Every
//! command from the controller is a heartbeat; after `GevHeartbeatTimeout` ms without
//! one (unless the heartbeat is disabled) control is released, acquisition stops and
//! the stream channel closes. With no controller, writes are accepted from anyone (as
//! Aravis' fake camera does), so `arv-tool control` works without a session.

use super::gvcp::{self, Command, Request, Status, code};
use super::registers::{self as reg, Effect, Registers};
use std::net::SocketAddr;
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
    /// The controller's privilege was taken, released or lost.
    pub control_changed: bool,
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
        if self.regs.heartbeat_disabled() || self.pending > 0 {
            return false;
        }
        if now.saturating_duration_since(last) > Duration::from_millis(u64::from(self.regs.heartbeat_timeout_ms)) {
            self.release();
            return true;
        }
        false
    }

    fn release(&mut self) {
        self.controller = None;
        self.regs.ccp = 0;
        self.regs.acquiring = false;
        self.regs.stream.host_port = 0;
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
                return out;
            }
        };
        if let Some((addr, ref mut last)) = self.controller
            && addr == peer
        {
            *last = now;
        }
        let ack = req.ack_required();
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
                out.resend = Some((*block_id, *first, *last));
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
