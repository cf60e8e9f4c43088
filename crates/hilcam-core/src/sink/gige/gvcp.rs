//! GVCP (GigE Vision Control Protocol) packets: a pure codec over bytes, no I/O.
//!
//! Every field is big-endian. A command is an 8-byte header — key `0x42`, flags,
//! command code, payload length, request id — and its payload; an acknowledge is an
//! 8-byte header — status, answer code, payload length, ack id — and its payload.
//! Layouts follow the GigE Vision 2.x specification as implemented by Aravis
//! (`arvgvcpprivate.h`); the byte tables are in `docs/gige.md`.

/// The well-known GVCP port.
pub const GVCP_PORT: u16 = 3956;
/// First byte of every command.
pub const KEY: u8 = 0x42;
/// Command flag: the sender wants an acknowledge.
pub const FLAG_ACK_REQUIRED: u8 = 0x01;
/// Command flag on PACKETRESEND: 64-bit block id and 32-bit packet ids follow.
pub const FLAG_EXTENDED_IDS: u8 = 0x10;
/// Header length of commands and acknowledges.
pub const HEADER_LEN: usize = 8;
/// Largest READMEM / WRITEMEM data block (keeps a datagram under 576 bytes).
pub const MAX_MEM_BLOCK: u32 = 536;
/// Largest number of (address, value) pairs in one WRITEREG / addresses in one READREG.
pub const MAX_REGS: usize = 67;

/// Command and acknowledge codes.
pub mod code {
    pub const DISCOVERY_CMD: u16 = 0x0002;
    pub const DISCOVERY_ACK: u16 = 0x0003;
    pub const PACKETRESEND_CMD: u16 = 0x0040;
    pub const READREG_CMD: u16 = 0x0080;
    pub const READREG_ACK: u16 = 0x0081;
    pub const WRITEREG_CMD: u16 = 0x0082;
    pub const WRITEREG_ACK: u16 = 0x0083;
    pub const READMEM_CMD: u16 = 0x0084;
    pub const READMEM_ACK: u16 = 0x0085;
    pub const WRITEMEM_CMD: u16 = 0x0086;
    pub const WRITEMEM_ACK: u16 = 0x0087;
    pub const PENDING_ACK: u16 = 0x0089;
}

/// GigE Vision status codes (acknowledge header, bytes 0..2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum Status {
    Success = 0x0000,
    NotImplemented = 0x8001,
    InvalidParameter = 0x8002,
    InvalidAddress = 0x8003,
    WriteProtect = 0x8004,
    BadAlignment = 0x8005,
    AccessDenied = 0x8006,
    Busy = 0x8007,
    PacketUnavailable = 0x800C,
    InvalidHeader = 0x800E,
    Error = 0x8FFF,
}

impl Status {
    pub fn code(self) -> u16 {
        self as u16
    }
    /// Label for logs and metrics.
    pub fn name(self) -> &'static str {
        match self {
            Status::Success => "success",
            Status::NotImplemented => "not_implemented",
            Status::InvalidParameter => "invalid_parameter",
            Status::InvalidAddress => "invalid_address",
            Status::WriteProtect => "write_protect",
            Status::BadAlignment => "bad_alignment",
            Status::AccessDenied => "access_denied",
            Status::Busy => "busy",
            Status::PacketUnavailable => "packet_unavailable",
            Status::InvalidHeader => "invalid_header",
            Status::Error => "error",
        }
    }
}

/// A decoded command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    Discovery,
    ReadReg(Vec<u32>),
    WriteReg(Vec<(u32, u32)>),
    ReadMem {
        address: u32,
        count: u16,
    },
    WriteMem {
        address: u32,
        data: Vec<u8>,
    },
    /// Resend packets `first..=last` of block `block_id` (no acknowledge is sent).
    PacketResend {
        block_id: u64,
        first: u32,
        last: u32,
    },
}

/// A command with its header fields.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    pub flags: u8,
    /// The command code as sent (also for commands this device does not implement).
    pub code: u16,
    pub req_id: u16,
    pub command: Command,
}

impl Request {
    pub fn ack_required(&self) -> bool {
        self.flags & FLAG_ACK_REQUIRED != 0
    }
}

/// Why a datagram is not a valid command. When the header was readable, `reply` holds
/// what to answer with (command code, request id, status); otherwise nothing is answered.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("GVCP command rejected ({}): {reason}", status.name())]
pub struct Rejected {
    pub status: Status,
    /// (command code, request id) when the header could be read.
    pub reply_to: Option<(u16, u16)>,
    pub reason: String,
}

fn be16(b: &[u8], i: usize) -> u16 {
    u16::from_be_bytes([b[i], b[i + 1]])
}
fn be32(b: &[u8], i: usize) -> u32 {
    u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// Decode one datagram. Never panics, whatever the bytes (fuzzed: `fuzz_targets/gvcp_decode.rs`).
pub fn decode(buf: &[u8]) -> Result<Request, Rejected> {
    if buf.len() < HEADER_LEN {
        return Err(Rejected {
            status: Status::InvalidHeader,
            reply_to: None,
            reason: format!("{} bytes, a GVCP header has {HEADER_LEN}", buf.len()),
        });
    }
    let (key, flags, code, len, req_id) = (buf[0], buf[1], be16(buf, 2), be16(buf, 4) as usize, be16(buf, 6));
    let reject = |status: Status, reason: String| Rejected { status, reply_to: Some((code, req_id)), reason };
    if key != KEY {
        return Err(Rejected {
            status: Status::InvalidHeader,
            reply_to: None,
            reason: format!("key byte {key:#04x}, commands start with {KEY:#04x}"),
        });
    }
    let payload = &buf[HEADER_LEN..];
    if payload.len() < len {
        return Err(reject(
            Status::InvalidHeader,
            format!("header says {len} payload bytes, datagram has {}", payload.len()),
        ));
    }
    let p = &payload[..len];
    let command = match code {
        code::DISCOVERY_CMD => Command::Discovery,
        code::READREG_CMD => {
            if p.is_empty() || !p.len().is_multiple_of(4) || p.len() / 4 > MAX_REGS {
                return Err(reject(
                    Status::InvalidParameter,
                    format!("READREG payload {} bytes: 4..={} in steps of 4", p.len(), MAX_REGS * 4),
                ));
            }
            Command::ReadReg(p.chunks_exact(4).map(|c| be32(c, 0)).collect())
        }
        code::WRITEREG_CMD => {
            if p.is_empty() || !p.len().is_multiple_of(8) || p.len() / 8 > MAX_REGS {
                return Err(reject(
                    Status::InvalidParameter,
                    format!("WRITEREG payload {} bytes: 8..={} in steps of 8", p.len(), MAX_REGS * 8),
                ));
            }
            Command::WriteReg(p.chunks_exact(8).map(|c| (be32(c, 0), be32(c, 4))).collect())
        }
        code::READMEM_CMD => {
            if p.len() != 8 {
                return Err(reject(Status::InvalidParameter, format!("READMEM payload {} bytes, needs 8", p.len())));
            }
            let count = be16(p, 6);
            if count == 0 || u32::from(count) > MAX_MEM_BLOCK || !count.is_multiple_of(4) {
                return Err(reject(
                    Status::InvalidParameter,
                    format!("READMEM count {count}: 4..={MAX_MEM_BLOCK} in steps of 4"),
                ));
            }
            Command::ReadMem { address: be32(p, 0), count }
        }
        code::WRITEMEM_CMD => {
            let n = p.len().saturating_sub(4);
            if p.len() < 8 || !n.is_multiple_of(4) || n as u32 > MAX_MEM_BLOCK {
                return Err(reject(
                    Status::InvalidParameter,
                    format!(
                        "WRITEMEM payload {} bytes: address + 4..={MAX_MEM_BLOCK} data bytes in steps of 4",
                        p.len()
                    ),
                ));
            }
            Command::WriteMem { address: be32(p, 0), data: p[4..].to_vec() }
        }
        code::PACKETRESEND_CMD => {
            if flags & FLAG_EXTENDED_IDS != 0 {
                if p.len() != 20 {
                    return Err(reject(
                        Status::InvalidParameter,
                        format!("PACKETRESEND (extended ids) payload {} bytes, needs 20", p.len()),
                    ));
                }
                let block_id = u64::from_be_bytes(p[12..20].try_into().expect("8 bytes"));
                Command::PacketResend { block_id, first: be32(p, 4), last: be32(p, 8) }
            } else {
                if p.len() != 12 {
                    return Err(reject(
                        Status::InvalidParameter,
                        format!("PACKETRESEND payload {} bytes, needs 12", p.len()),
                    ));
                }
                Command::PacketResend {
                    block_id: u64::from(be32(p, 0) & 0xFFFF),
                    first: be32(p, 4) & 0x00FF_FFFF,
                    last: be32(p, 8) & 0x00FF_FFFF,
                }
            }
        }
        other => {
            return Err(reject(Status::NotImplemented, format!("command code {other:#06x}")));
        }
    };
    Ok(Request { flags, code, req_id, command })
}

/// The acknowledge code that answers command `code` (commands are even, acks odd).
pub fn ack_code(code: u16) -> u16 {
    code | 1
}

/// An acknowledge: header + payload.
pub fn encode_ack(status: Status, answer: u16, ack_id: u16, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&status.code().to_be_bytes());
    out.extend_from_slice(&answer.to_be_bytes());
    out.extend_from_slice(&(payload.len() as u16).to_be_bytes());
    out.extend_from_slice(&ack_id.to_be_bytes());
    out.extend_from_slice(payload);
    out
}

/// READREG_ACK with one value per address.
pub fn readreg_ack(status: Status, ack_id: u16, values: &[u32]) -> Vec<u8> {
    let payload: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    encode_ack(status, code::READREG_ACK, ack_id, &payload)
}

/// WRITEREG_ACK: `index` is the number of registers written (on error, the index of
/// the one that failed).
pub fn writereg_ack(status: Status, ack_id: u16, index: u16) -> Vec<u8> {
    let mut payload = [0u8; 4];
    payload[2..].copy_from_slice(&index.to_be_bytes());
    encode_ack(status, code::WRITEREG_ACK, ack_id, &payload)
}

/// READMEM_ACK: the address, then the data.
pub fn readmem_ack(ack_id: u16, address: u32, data: &[u8]) -> Vec<u8> {
    let mut payload = Vec::with_capacity(4 + data.len());
    payload.extend_from_slice(&address.to_be_bytes());
    payload.extend_from_slice(data);
    encode_ack(Status::Success, code::READMEM_ACK, ack_id, &payload)
}

/// WRITEMEM_ACK: `written` bytes were stored.
pub fn writemem_ack(status: Status, ack_id: u16, written: u16) -> Vec<u8> {
    let mut payload = [0u8; 4];
    payload[2..].copy_from_slice(&written.to_be_bytes());
    encode_ack(status, code::WRITEMEM_ACK, ack_id, &payload)
}

/// PENDING_ACK: the real acknowledge follows within `timeout_ms`.
pub fn pending_ack(ack_id: u16, timeout_ms: u16) -> Vec<u8> {
    let mut payload = [0u8; 4];
    payload[2..].copy_from_slice(&timeout_ms.to_be_bytes());
    encode_ack(Status::Success, code::PENDING_ACK, ack_id, &payload)
}

/// An error acknowledge for `rejected` (None when the header was unreadable).
pub fn reject_ack(rejected: &Rejected) -> Option<Vec<u8>> {
    let (code, req_id) = rejected.reply_to?;
    Some(encode_ack(rejected.status, ack_code(code), req_id, &[]))
}

/// Build a command (the client side; tests and the bench use it).
pub fn encode_command(flags: u8, code: u16, req_id: u16, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.push(KEY);
    out.push(flags);
    out.extend_from_slice(&code.to_be_bytes());
    out.extend_from_slice(&(payload.len() as u16).to_be_bytes());
    out.extend_from_slice(&req_id.to_be_bytes());
    out.extend_from_slice(payload);
    out
}

/// A decoded acknowledge (client side).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ack {
    pub status: u16,
    pub answer: u16,
    pub ack_id: u16,
    pub payload: Vec<u8>,
}

/// Decode an acknowledge (client side); None if it is shorter than its header says.
pub fn decode_ack(buf: &[u8]) -> Option<Ack> {
    if buf.len() < HEADER_LEN {
        return None;
    }
    let len = be16(buf, 4) as usize;
    let payload = buf.get(HEADER_LEN..HEADER_LEN + len)?.to_vec();
    Some(Ack { status: be16(buf, 0), answer: be16(buf, 2), ack_id: be16(buf, 6), payload })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readreg_roundtrip() {
        let cmd = encode_command(FLAG_ACK_REQUIRED, code::READREG_CMD, 7, &[0, 0, 0x0a, 0, 0, 0, 0, 4]);
        let req = decode(&cmd).unwrap();
        assert_eq!(req.command, Command::ReadReg(vec![0x0a00, 4]));
        assert_eq!(req.req_id, 7);
        assert!(req.ack_required());
    }

    #[test]
    fn resend_standard_ids_keep_24_bits() {
        let mut p = Vec::new();
        p.extend_from_slice(&0x0001_0005u32.to_be_bytes());
        p.extend_from_slice(&0xff00_0003u32.to_be_bytes());
        p.extend_from_slice(&9u32.to_be_bytes());
        let req = decode(&encode_command(0, code::PACKETRESEND_CMD, 1, &p)).unwrap();
        assert_eq!(req.command, Command::PacketResend { block_id: 5, first: 3, last: 9 });
    }

    #[test]
    fn malformed_commands_get_statuses() {
        assert_eq!(decode(&[0x42, 1, 0]).unwrap_err().reply_to, None);
        let bad_key = decode(&encode_command(1, code::READREG_CMD, 1, &[0; 4]).iter().map(|_| 0).collect::<Vec<u8>>());
        assert_eq!(bad_key.unwrap_err().status, Status::InvalidHeader);
        let odd = decode(&encode_command(1, code::READREG_CMD, 3, &[0; 3])).unwrap_err();
        assert_eq!((odd.status, odd.reply_to), (Status::InvalidParameter, Some((code::READREG_CMD, 3))));
        let unknown = decode(&encode_command(1, 0x00c0, 4, &[])).unwrap_err();
        assert_eq!(unknown.status, Status::NotImplemented);
        let ack = reject_ack(&unknown).unwrap();
        assert_eq!(decode_ack(&ack).unwrap(), Ack { status: 0x8001, answer: 0x00c1, ack_id: 4, payload: vec![] });
        let short = decode(&[0x42, 1, 0, 0x80, 0, 8, 0, 1, 0, 0]).unwrap_err();
        assert_eq!(short.status, Status::InvalidHeader);
    }

    #[test]
    fn readmem_count_is_bounded_and_aligned() {
        let mk = |count: u16| {
            let mut p = 0x200u32.to_be_bytes().to_vec();
            p.extend_from_slice(&[0, 0]);
            p.extend_from_slice(&count.to_be_bytes());
            decode(&encode_command(1, code::READMEM_CMD, 1, &p))
        };
        assert_eq!(mk(512).unwrap().command, Command::ReadMem { address: 0x200, count: 512 });
        assert!(mk(0).is_err());
        assert!(mk(6).is_err());
        assert!(mk(540).is_err());
    }
}
