//! The serial (UART) frame: pure encode/decode over bytes and an incremental
//! [`SerialDecoder`] that resynchronises after garbage.
//!
//! Layout (little-endian; byte tables and hex dumps in `docs/protocol.md`):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | sync `A5 5A` |
//! | 2 | 1 | version (1) |
//! | 3 | 1 | type: 1 pose, 2 trigger, 3 heartbeat |
//! | 4 | 2 | payload length N (u16) |
//! | 6 | 4 | sequence number (u32) |
//! | 10 | 8 | simulation time, ns (u64) |
//! | 18 | N | payload |
//! | 18+N | 4 | CRC-32C over bytes 2 .. 18+N |

use super::crc::crc32c;
use super::wire::{Reader, Writer};
use super::{Message, Pose};

/// The two sync bytes that start every frame.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Protocol version this codec speaks.
pub const VERSION: u8 = 1;
/// Bytes before the payload (sync .. timestamp).
pub const HEADER_LEN: usize = 18;
/// Bytes of the trailing CRC.
pub const CRC_LEN: usize = 4;
/// Message type byte of a pose.
pub const TYPE_POSE: u8 = 1;
/// Message type byte of a trigger.
pub const TYPE_TRIGGER: u8 = 2;
/// Message type byte of a heartbeat.
pub const TYPE_HEARTBEAT: u8 = 3;
/// Pose payload flag: relative velocity present.
pub const FLAG_VELOCITY: u8 = 0x01;
/// Pose payload flag: angular rate present.
pub const FLAG_ANGULAR_RATE: u8 = 0x02;
/// Pose payload flag: the planet's centre present (moves the scene's `[planet]`; after
/// the rates). Without it a frame is byte for byte what it always was.
pub const FLAG_PLANET: u8 = 0x04;
const KNOWN_FLAGS: u8 = FLAG_VELOCITY | FLAG_ANGULAR_RATE | FLAG_PLANET;
/// Pose payload without optional blocks: flags, 3 reserved, 10 × f64.
pub const POSE_BASE_LEN: usize = 4 + 10 * 8;
/// One optional 3 × f64 block.
pub const POSE_OPT_LEN: usize = 3 * 8;
/// Longest frame this version can produce (pose with all three optional blocks).
pub const MAX_FRAME_LEN: usize = HEADER_LEN + POSE_BASE_LEN + 3 * POSE_OPT_LEN + CRC_LEN;

/// Why bytes at the start of a buffer are not a valid frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum Malformed {
    /// The bytes do not start with the sync word (garbage between frames).
    #[error("no sync word")]
    NoSync,
    /// Unsupported protocol version.
    #[error("unsupported version {0}")]
    BadVersion(u8),
    /// Unknown message type.
    #[error("unknown message type {0}")]
    UnknownType(u8),
    /// Payload length impossible for the message type.
    #[error("payload length {len} invalid for message type {ty}")]
    BadLength {
        /// Message type byte.
        ty: u8,
        /// Payload length field.
        len: u16,
    },
    /// CRC-32C mismatch (corruption, or a sync word inside garbage).
    #[error("CRC mismatch: frame says {got:#010x}, computed {computed:#010x}")]
    Crc {
        /// CRC carried by the frame.
        got: u32,
        /// CRC computed over the frame.
        computed: u32,
    },
    /// Pose flags with unknown bits, nonzero reserved bytes, or flags that
    /// disagree with the payload length.
    #[error("bad pose flags {0:#04x}")]
    BadFlags(u8),
}

impl Malformed {
    /// Stable snake_case name for logs and metric labels.
    pub fn as_str(&self) -> &'static str {
        match self {
            Malformed::NoSync => "no_sync",
            Malformed::BadVersion(_) => "bad_version",
            Malformed::UnknownType(_) => "unknown_type",
            Malformed::BadLength { .. } => "bad_length",
            Malformed::Crc { .. } => "crc",
            Malformed::BadFlags(_) => "bad_flags",
        }
    }
}

/// Result of trying to decode one frame at the start of a buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// A frame may start here but more bytes are needed (at least `needed` in all).
    #[error("incomplete frame: need {needed} bytes")]
    Incomplete {
        /// Total buffer length needed before decoding can progress.
        needed: usize,
    },
    /// The bytes here are not a valid frame: skip at least one byte.
    #[error("malformed frame: {0}")]
    Malformed(Malformed),
}

fn expected_pose_len(flags: u8) -> usize {
    let mut n = POSE_BASE_LEN;
    if flags & FLAG_VELOCITY != 0 {
        n += POSE_OPT_LEN;
    }
    if flags & FLAG_ANGULAR_RATE != 0 {
        n += POSE_OPT_LEN;
    }
    if flags & FLAG_PLANET != 0 {
        n += POSE_OPT_LEN;
    }
    n
}

fn length_ok(ty: u8, len: u16) -> bool {
    let len = len as usize;
    match ty {
        TYPE_POSE => [0, 1, 2, 3].iter().any(|k| len == POSE_BASE_LEN + k * POSE_OPT_LEN),
        TYPE_TRIGGER => len == 0,
        TYPE_HEARTBEAT => len == 4,
        _ => false,
    }
}

/// Decodes one frame at the start of `buf`, returning the message and the number
/// of bytes it occupied.
///
/// Checks run in the order the bytes arrive (sync, version, type, length, CRC,
/// payload), so garbage is rejected as early as possible and a corrupted length
/// can never make the caller wait for more than [`MAX_FRAME_LEN`] bytes.
///
/// # Errors
/// [`FrameError::Incomplete`] when `buf` is a valid prefix of a frame;
/// [`FrameError::Malformed`] when it cannot be one.
pub fn decode_frame(buf: &[u8]) -> Result<(Message, usize), FrameError> {
    use FrameError::{Incomplete, Malformed as M};
    let need = |n: usize| Err(Incomplete { needed: n });
    if buf.is_empty() {
        return need(1);
    }
    if buf[0] != SYNC[0] {
        return Err(M(Malformed::NoSync));
    }
    if buf.len() < 2 {
        return need(2);
    }
    if buf[1] != SYNC[1] {
        return Err(M(Malformed::NoSync));
    }
    if buf.len() < 3 {
        return need(3);
    }
    if buf[2] != VERSION {
        return Err(M(Malformed::BadVersion(buf[2])));
    }
    if buf.len() < 4 {
        return need(4);
    }
    let ty = buf[3];
    if !matches!(ty, TYPE_POSE | TYPE_TRIGGER | TYPE_HEARTBEAT) {
        return Err(M(Malformed::UnknownType(ty)));
    }
    if buf.len() < 6 {
        return need(6);
    }
    let len = u16::from_le_bytes([buf[4], buf[5]]);
    if !length_ok(ty, len) {
        return Err(M(Malformed::BadLength { ty, len }));
    }
    let total = HEADER_LEN + len as usize + CRC_LEN;
    if buf.len() < total {
        return need(total);
    }
    let body_end = HEADER_LEN + len as usize;
    let computed = crc32c(&buf[2..body_end]);
    let got = u32::from_le_bytes(buf[body_end..total].try_into().expect("4 bytes"));
    if got != computed {
        return Err(M(Malformed::Crc { got, computed }));
    }
    let mut r = Reader::new(&buf[6..body_end]);
    let seq = r.u32();
    let t_ns = r.u64();
    let msg = match ty {
        TYPE_POSE => {
            let flags = r.u8();
            let reserved = [r.u8(), r.u8(), r.u8()];
            if flags & !KNOWN_FLAGS != 0 || reserved != [0; 3] || expected_pose_len(flags) != len as usize {
                return Err(M(Malformed::BadFlags(flags)));
            }
            let position = r.dvec3_f64();
            let attitude = r.dquat_f64();
            let sun_dir = r.dvec3_f64();
            let velocity = (flags & FLAG_VELOCITY != 0).then(|| r.dvec3_f64());
            let angular_rate = (flags & FLAG_ANGULAR_RATE != 0).then(|| r.dvec3_f64());
            let planet_centre = (flags & FLAG_PLANET != 0).then(|| r.dvec3_f64());
            Message::Pose(Pose {
                seq,
                t_ns,
                position,
                attitude,
                sun_dir,
                velocity,
                angular_rate,
                camera_to_inertial: None,
                planet_centre,
            })
        }
        TYPE_TRIGGER => Message::Trigger { seq, t_ns },
        _ => Message::Heartbeat { seq, t_ns, status: r.u32() },
    };
    Ok((msg, total))
}

/// Appends the frame for `msg` to `out`.
pub fn encode_frame_into(msg: &Message, out: &mut Vec<u8>) {
    let start = out.len();
    let mut w = Writer(out);
    w.u8(SYNC[0]);
    w.u8(SYNC[1]);
    w.u8(VERSION);
    let (ty, seq, t_ns) = match *msg {
        Message::Pose(p) => (TYPE_POSE, p.seq, p.t_ns),
        Message::Trigger { seq, t_ns } => (TYPE_TRIGGER, seq, t_ns),
        Message::Heartbeat { seq, t_ns, .. } => (TYPE_HEARTBEAT, seq, t_ns),
    };
    w.u8(ty);
    let len_at = w.0.len();
    w.u16(0); // patched below
    w.u32(seq);
    w.u64(t_ns);
    match *msg {
        Message::Pose(p) => {
            let flags = if p.velocity.is_some() { FLAG_VELOCITY } else { 0 }
                | if p.angular_rate.is_some() { FLAG_ANGULAR_RATE } else { 0 }
                | if p.planet_centre.is_some() { FLAG_PLANET } else { 0 };
            w.u8(flags);
            w.0.extend_from_slice(&[0; 3]);
            w.dvec3_f64(p.position);
            w.dquat_f64(p.attitude);
            w.dvec3_f64(p.sun_dir);
            if let Some(v) = p.velocity {
                w.dvec3_f64(v);
            }
            if let Some(v) = p.angular_rate {
                w.dvec3_f64(v);
            }
            if let Some(c) = p.planet_centre {
                w.dvec3_f64(c);
            }
        }
        Message::Trigger { .. } => {}
        Message::Heartbeat { status, .. } => w.u32(status),
    }
    let len = (out.len() - start - HEADER_LEN) as u16;
    out[len_at..len_at + 2].copy_from_slice(&len.to_le_bytes());
    let crc = crc32c(&out[start + 2..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

/// The frame for `msg`.
pub fn encode_frame(msg: &Message) -> Vec<u8> {
    let mut out = Vec::with_capacity(MAX_FRAME_LEN);
    encode_frame_into(msg, &mut out);
    out
}

/// What [`SerialDecoder::next_event`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
// A pose (232 bytes with its optional planet centre) moves by value: boxing it would
// allocate per message on the allocation-free input path.
#[allow(clippy::large_enum_variant)]
pub enum DecodeEvent {
    /// A frame with a valid CRC and layout.
    Message(Message),
    /// `bytes` bytes were skipped to resynchronise; `reason` says why the first
    /// of them could not start a frame.
    Discarded {
        /// Number of bytes dropped.
        bytes: usize,
        /// Why the frame at the first dropped byte was rejected.
        reason: Malformed,
    },
}

/// Running totals of a [`SerialDecoder`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Frames decoded.
    pub frames: u64,
    /// Bytes skipped while resynchronising.
    pub discarded_bytes: u64,
    /// Times the decoder had to skip bytes to find the next frame.
    pub resyncs: u64,
    /// Resyncs caused by a CRC mismatch.
    pub crc_failures: u64,
}

/// Incremental decoder: push bytes as they arrive, pull events.
///
/// On a malformed frame it drops the first byte and scans to the next possible
/// sync byte, so a valid frame that follows (or even overlaps) garbage is never
/// lost. The buffer stays bounded: it never holds more than the bytes pushed
/// since the last event plus one partial frame.
#[derive(Debug, Default)]
pub struct SerialDecoder {
    buf: Vec<u8>,
    start: usize,
    stats: DecoderStats,
}

impl SerialDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 && self.start >= self.buf.len() / 2 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes held back waiting for the rest of a frame.
    pub fn buffered(&self) -> usize {
        self.buf.len() - self.start
    }

    /// Totals so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// The next message or discard, or `None` when more bytes are needed.
    pub fn next_event(&mut self) -> Option<DecodeEvent> {
        let data = &self.buf[self.start..];
        match decode_frame(data) {
            Ok((msg, n)) => {
                self.start += n;
                self.stats.frames += 1;
                Some(DecodeEvent::Message(msg))
            }
            Err(FrameError::Incomplete { .. }) => None,
            Err(FrameError::Malformed(reason)) => {
                let skip = 1 + data[1..].iter().position(|&b| b == SYNC[0]).unwrap_or(data.len() - 1);
                self.start += skip;
                self.stats.discarded_bytes += skip as u64;
                self.stats.resyncs += 1;
                if matches!(reason, Malformed::Crc { .. }) {
                    self.stats.crc_failures += 1;
                }
                Some(DecodeEvent::Discarded { bytes: skip, reason })
            }
        }
    }
}
