//! CAN codecs: the pose as a group of classic 8-byte frames, or as one CAN FD
//! frame, plus single-frame trigger and heartbeat. Pure functions over a
//! transport-neutral [`CanFrame`]; the SocketCAN and slcan transports convert.
//!
//! Identifier map, relative to a configurable base ([`CanIds`]):
//!
//! | id | frame |
//! |---|---|
//! | base + 0 … base + 10 | classic pose group, frame index = id − base |
//! | base + 0x0E | heartbeat (classic, 8 bytes: seq u32, status u32) |
//! | base + 0x0F | trigger (classic, 8 bytes: simulation time ns u64) |
//! | base + 0x10 | CAN FD pose (48 or 64 bytes) |
//!
//! Both pose encodings share the *compact pose block* (little-endian):
//! flags u8, t_ns u64, position f32 ×3, attitude i24 ×4 (Q23, scalar first),
//! sun i16 ×3 (Q15), optional velocity f32 ×3, optional angular rate f32 ×3, optional
//! planet centre f32 ×3 (camera frame, m).
//! `docs/protocol.md` gives the precision of each field and why.

use super::crc::crc16_ccitt;
use super::wire::{Reader, Writer};
use super::{Message, Pose};
use glam::{DQuat, DVec3};

/// Offset of the heartbeat frame id from the base id.
pub const HEARTBEAT_OFFSET: u32 = 0x0E;
/// Offset of the trigger frame id from the base id.
pub const TRIGGER_OFFSET: u32 = 0x0F;
/// Offset of the CAN FD pose frame id from the base id.
pub const FD_POSE_OFFSET: u32 = 0x10;
/// Most frames a classic pose group can have (all three options: 75 block bytes + CRC).
pub const MAX_GROUP_FRAMES: usize = 11;
/// Block flag: velocity present.
pub const FLAG_VELOCITY: u8 = 0x01;
/// Block flag: angular rate present.
pub const FLAG_ANGULAR_RATE: u8 = 0x02;
/// Block flag: the planet's centre present (camera frame, metres).
pub const FLAG_PLANET: u8 = 0x04;
/// Longest FD pose payload: seq byte + block.
pub const FD_MAX_LEN: usize = 64;
/// Quaternion component scale: value = raw / `QUAT_SCALE` (Q23, step 1.19e-7).
pub const QUAT_SCALE: f64 = 8_388_607.0;
/// Sun component scale: value = raw / `SUN_SCALE` (Q15, step 3.05e-5).
pub const SUN_SCALE: f64 = 32_767.0;
/// Compact block length without optional parts.
pub const BLOCK_BASE_LEN: usize = 1 + 8 + 12 + 12 + 6;
/// Group stream payload bytes per classic frame (byte 0 is the group sequence).
pub const GROUP_BYTES_PER_FRAME: usize = 7;

/// A CAN frame as the codecs see it (classic ≤ 8 bytes or FD ≤ 64 bytes).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct CanFrame {
    /// Identifier (11 or 29 bits).
    pub id: u32,
    /// 29-bit identifier.
    pub extended: bool,
    /// CAN FD frame.
    pub fd: bool,
    /// FD bit-rate switch.
    pub brs: bool,
    len: u8,
    data: [u8; 64],
}

impl std::fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:X}{}#", self.id, if self.fd { "##" } else { "" })?;
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

/// Legal CAN FD data lengths.
pub const FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

fn id_fits(id: u32, extended: bool) -> bool {
    id <= if extended { 0x1FFF_FFFF } else { 0x7FF }
}

impl CanFrame {
    /// A classic data frame; `None` if `data` exceeds 8 bytes or `id` its width.
    pub fn new(id: u32, extended: bool, data: &[u8]) -> Option<Self> {
        if data.len() > 8 || !id_fits(id, extended) {
            return None;
        }
        let mut d = [0; 64];
        d[..data.len()].copy_from_slice(data);
        Some(CanFrame { id, extended, fd: false, brs: false, len: data.len() as u8, data: d })
    }

    /// An FD frame; `data` is zero-padded up to the next legal FD length.
    /// `None` if longer than 64 bytes or `id` exceeds its width.
    pub fn new_fd(id: u32, extended: bool, data: &[u8], brs: bool) -> Option<Self> {
        let len = *FD_LENGTHS.iter().find(|&&l| l >= data.len())?;
        let mut f = CanFrame::new(id, extended, &[])?;
        f.data[..data.len()].copy_from_slice(data);
        f.len = len as u8;
        f.fd = true;
        f.brs = brs;
        Some(f)
    }

    /// The data bytes.
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }
}

/// Which identifiers carry hilcam's messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CanIds {
    base: u32,
    extended: bool,
}

/// A base id whose id range does not fit the identifier width.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("CAN base id {base:#x}: base + 0x10 exceeds the {} identifier range", if *.extended { "29-bit" } else { "11-bit" })]
pub struct CanIdError {
    /// The rejected base.
    pub base: u32,
    /// Whether 29-bit ids were requested.
    pub extended: bool,
}

impl CanIds {
    /// Default base id (11-bit) used by `hilcam send` and the examples.
    pub const DEFAULT_BASE: u32 = 0x300;

    /// Ids `base ..= base + 0x10`, standard or extended.
    ///
    /// # Errors
    /// When `base + 0x10` does not fit the identifier width.
    pub fn new(base: u32, extended: bool) -> Result<Self, CanIdError> {
        match base.checked_add(FD_POSE_OFFSET) {
            Some(top) if id_fits(top, extended) => Ok(CanIds { base, extended }),
            _ => Err(CanIdError { base, extended }),
        }
    }
    /// The base id.
    pub fn base(&self) -> u32 {
        self.base
    }
    /// Whether ids are 29-bit.
    pub fn extended(&self) -> bool {
        self.extended
    }
}

impl Default for CanIds {
    fn default() -> Self {
        CanIds { base: Self::DEFAULT_BASE, extended: false }
    }
}

fn flags_of(p: &Pose) -> u8 {
    (if p.velocity.is_some() { FLAG_VELOCITY } else { 0 })
        | (if p.angular_rate.is_some() { FLAG_ANGULAR_RATE } else { 0 })
        | (if p.planet_centre.is_some() { FLAG_PLANET } else { 0 })
}

/// Whether `pose` fits one CAN FD frame: all but a pose with both rates and a planet
/// (1 + 75 bytes of 64), which goes as a classic group or on the serial link.
pub fn fits_fd(pose: &Pose) -> bool {
    // The seq byte and the block: 1 + n ≤ 64.
    block_len(flags_of(pose)).is_some_and(|n| n < FD_MAX_LEN)
}

/// Length of the compact block for `flags`, or `None` for unknown flag bits.
pub fn block_len(flags: u8) -> Option<usize> {
    if flags & !(FLAG_VELOCITY | FLAG_ANGULAR_RATE | FLAG_PLANET) != 0 {
        return None;
    }
    Some(BLOCK_BASE_LEN + 12 * (flags.count_ones() as usize))
}

fn quantise(v: f64, scale: f64) -> i32 {
    // `as` saturates and maps NaN to 0; the clamp keeps ±1 symmetric.
    ((v * scale).round() as i32).clamp(-(scale as i32), scale as i32)
}

fn write_block(p: &Pose, out: &mut Vec<u8>) {
    let mut w = Writer(out);
    w.u8(flags_of(p));
    w.u64(p.t_ns);
    w.dvec3_f32(p.position);
    for c in [p.attitude.w, p.attitude.x, p.attitude.y, p.attitude.z] {
        w.i24(quantise(c, QUAT_SCALE));
    }
    for c in p.sun_dir.to_array() {
        w.i16(quantise(c, SUN_SCALE) as i16);
    }
    if let Some(v) = p.velocity {
        w.dvec3_f32(v);
    }
    if let Some(v) = p.angular_rate {
        w.dvec3_f32(v);
    }
    if let Some(c) = p.planet_centre {
        w.dvec3_f32(c);
    }
}

/// Reads a block whose length the caller checked against [`block_len`].
fn read_block(seq: u32, b: &[u8]) -> Pose {
    let mut r = Reader::new(b);
    let flags = r.u8();
    let t_ns = r.u64();
    let position = r.dvec3_f32();
    let q: [f64; 4] = std::array::from_fn(|_| r.i24() as f64 / QUAT_SCALE);
    let s: [f64; 3] = std::array::from_fn(|_| r.i16() as f64 / SUN_SCALE);
    let velocity = (flags & FLAG_VELOCITY != 0).then(|| r.dvec3_f32());
    let angular_rate = (flags & FLAG_ANGULAR_RATE != 0).then(|| r.dvec3_f32());
    let planet_centre = (flags & FLAG_PLANET != 0).then(|| r.dvec3_f32());
    Pose {
        seq,
        t_ns,
        position,
        attitude: DQuat::from_xyzw(q[1], q[2], q[3], q[0]),
        sun_dir: DVec3::from_array(s),
        velocity,
        angular_rate,
        camera_to_inertial: None,
        planet_centre,
    }
}

/// Number of classic frames in a group whose block has `flags`.
pub fn group_frames(flags: u8) -> Option<usize> {
    block_len(flags).map(|n| (n + 2).div_ceil(GROUP_BYTES_PER_FRAME))
}

/// The classic frames (6 to 11) carrying `pose`; the group sequence is the
/// low byte of `pose.seq`.
pub fn encode_group(ids: CanIds, pose: &Pose) -> Vec<CanFrame> {
    let seq = pose.seq as u8;
    let mut stream = vec![seq];
    write_block(pose, &mut stream);
    let crc = crc16_ccitt(&stream);
    stream.extend_from_slice(&crc.to_le_bytes());
    let body = &stream[1..];
    body.chunks(GROUP_BYTES_PER_FRAME)
        .enumerate()
        .map(|(k, chunk)| {
            let mut d = [0u8; 8];
            d[0] = seq;
            d[1..1 + chunk.len()].copy_from_slice(chunk);
            CanFrame::new(ids.base + k as u32, ids.extended, &d).expect("id range checked")
        })
        .collect()
}

/// The CAN FD frame carrying `pose` (48 or 64 bytes): seq u8 then the block; None when
/// it does not fit ([`fits_fd`]).
pub fn encode_fd(ids: CanIds, pose: &Pose, brs: bool) -> Option<CanFrame> {
    let mut d = vec![pose.seq as u8];
    write_block(pose, &mut d);
    CanFrame::new_fd(ids.base + FD_POSE_OFFSET, ids.extended, &d, brs)
}

/// Decodes the payload of an FD pose frame.
///
/// # Errors
/// [`GroupDrop::BadFlags`] for unknown flags, [`GroupDrop::BadLength`] when the
/// frame is shorter than its flags require.
pub fn decode_fd(data: &[u8]) -> Result<Pose, GroupDrop> {
    if data.len() < 2 {
        return Err(GroupDrop::BadLength(data.len() as u8));
    }
    let n = block_len(data[1]).ok_or(GroupDrop::BadFlags(data[1]))?;
    if data.len() < 1 + n {
        return Err(GroupDrop::BadLength(data.len() as u8));
    }
    Ok(read_block(data[0] as u32, &data[1..1 + n]))
}

/// The frames for any message: a pose as a classic group (or one FD frame when
/// `fd` and it fits: a pose that does not is sent as a classic group), a trigger or
/// heartbeat as one classic frame.
pub fn encode_message(ids: CanIds, msg: &Message, fd: bool) -> Vec<CanFrame> {
    let id = |off: u32| ids.base + off;
    match msg {
        Message::Pose(p) if fd && fits_fd(p) => vec![encode_fd(ids, p, true).expect("fits")],
        Message::Pose(p) => encode_group(ids, p),
        Message::Trigger { t_ns, .. } => {
            vec![CanFrame::new(id(TRIGGER_OFFSET), ids.extended, &t_ns.to_le_bytes()).expect("8")]
        }
        Message::Heartbeat { seq, status, .. } => {
            let mut d = seq.to_le_bytes().to_vec();
            d.extend_from_slice(&status.to_le_bytes());
            vec![CanFrame::new(id(HEARTBEAT_OFFSET), ids.extended, &d).expect("8")]
        }
    }
}

/// Why a pose group (or a single hilcam frame) was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum GroupDrop {
    /// A new group started before this one was complete.
    #[error("group incomplete: a frame is missing")]
    MissingFrame,
    /// A frame with another group sequence (or beyond the group's length)
    /// arrived mid-group.
    #[error("frames of different groups mixed")]
    MixedSequence,
    /// The same frame index arrived twice in one group.
    #[error("duplicate frame in group")]
    DuplicateFrame,
    /// The group CRC-16 does not match.
    #[error("group CRC mismatch")]
    Crc,
    /// A hilcam frame with the wrong data length.
    #[error("frame has wrong data length {0}")]
    BadLength(u8),
    /// Unknown flag bits in the pose block.
    #[error("bad pose flags {0:#04x}")]
    BadFlags(u8),
}

impl GroupDrop {
    /// Stable snake_case name for logs and metric labels.
    pub fn as_str(&self) -> &'static str {
        match self {
            GroupDrop::MissingFrame => "missing_frame",
            GroupDrop::MixedSequence => "mixed_sequence",
            GroupDrop::DuplicateFrame => "duplicate_frame",
            GroupDrop::Crc => "crc",
            GroupDrop::BadLength(_) => "bad_length",
            GroupDrop::BadFlags(_) => "bad_flags",
        }
    }
}

/// What one frame did to the assembler.
#[derive(Clone, Copy, Debug, PartialEq)]
// A pose (232 bytes with its optional planet centre) moves by value: boxing it would
// allocate per message on the allocation-free input path.
#[allow(clippy::large_enum_variant)]
pub enum CanEvent {
    /// A complete message.
    Message(Message),
    /// A group (or a malformed hilcam frame) was dropped.
    Dropped(GroupDrop),
}

#[derive(Clone, Copy, Debug)]
struct Pending {
    seq: u8,
    have: u16,
    stream: [u8; MAX_GROUP_FRAMES * GROUP_BYTES_PER_FRAME],
}

/// Reassembles pose groups and decodes the single-frame messages.
///
/// Frames of one group must not interleave with another group of the same
/// base id; a frame that breaks a group drops the pending group (counted by
/// the caller from the returned [`CanEvent::Dropped`]) and starts a new one,
/// so one lost frame costs exactly one pose.
#[derive(Debug)]
pub struct CanAssembler {
    ids: CanIds,
    pending: Option<Pending>,
    foreign: u64,
}

impl CanAssembler {
    /// An assembler for the given ids.
    pub fn new(ids: CanIds) -> Self {
        CanAssembler { ids, pending: None, foreign: 0 }
    }

    /// Frames seen with ids outside hilcam's range (other bus traffic).
    pub fn foreign_frames(&self) -> u64 {
        self.foreign
    }

    /// Drops a pending incomplete group (call when the bus has been idle for
    /// longer than a group takes, or at shutdown).
    pub fn flush(&mut self) -> Option<CanEvent> {
        self.pending.take().map(|_| CanEvent::Dropped(GroupDrop::MissingFrame))
    }

    /// Feeds one received frame.
    pub fn push(&mut self, f: &CanFrame) -> Option<CanEvent> {
        let base = self.ids.base;
        if f.extended != self.ids.extended || f.id < base || f.id > base + FD_POSE_OFFSET {
            self.foreign += 1;
            return None;
        }
        let off = f.id - base;
        let d = f.data();
        match off {
            FD_POSE_OFFSET if f.fd => Some(match decode_fd(d) {
                Ok(p) => CanEvent::Message(Message::Pose(p)),
                Err(e) => CanEvent::Dropped(e),
            }),
            TRIGGER_OFFSET | HEARTBEAT_OFFSET if !f.fd => {
                if d.len() != 8 {
                    return Some(CanEvent::Dropped(GroupDrop::BadLength(d.len() as u8)));
                }
                let mut r = Reader::new(d);
                Some(CanEvent::Message(if off == TRIGGER_OFFSET {
                    Message::Trigger { seq: 0, t_ns: r.u64() }
                } else {
                    Message::Heartbeat { seq: r.u32(), status: r.u32(), t_ns: 0 }
                }))
            }
            k if (k as usize) < MAX_GROUP_FRAMES && !f.fd => {
                if d.len() != 8 {
                    return Some(CanEvent::Dropped(GroupDrop::BadLength(d.len() as u8)));
                }
                self.push_group_frame(k as usize, d)
            }
            _ => {
                self.foreign += 1;
                None
            }
        }
    }

    fn push_group_frame(&mut self, idx: usize, d: &[u8]) -> Option<CanEvent> {
        let seq = d[0];
        let bit = 1u16 << idx;
        let mut dropped = None;
        if let Some(p) = &self.pending {
            if p.seq != seq {
                dropped = Some(if idx == 0 { GroupDrop::MissingFrame } else { GroupDrop::MixedSequence });
            } else if p.have & bit != 0 {
                dropped = Some(GroupDrop::DuplicateFrame);
            }
        }
        if dropped.is_some() || self.pending.is_none() {
            self.pending = Some(Pending { seq, have: 0, stream: [0; MAX_GROUP_FRAMES * GROUP_BYTES_PER_FRAME] });
        }
        let p = self.pending.as_mut().expect("set above");
        p.have |= bit;
        let at = idx * GROUP_BYTES_PER_FRAME;
        p.stream[at..at + GROUP_BYTES_PER_FRAME].copy_from_slice(&d[1..8]);
        if let Some(reason) = dropped {
            return Some(CanEvent::Dropped(reason));
        }
        if p.have & 1 == 0 {
            return None; // flags (and so the group length) not known yet
        }
        let flags = p.stream[0];
        let Some(n) = group_frames(flags) else {
            self.pending = None;
            return Some(CanEvent::Dropped(GroupDrop::BadFlags(flags)));
        };
        if p.have >> n != 0 {
            self.pending = None;
            return Some(CanEvent::Dropped(GroupDrop::MixedSequence));
        }
        if p.have != (1u16 << n) - 1 {
            return None;
        }
        let p = self.pending.take().expect("checked");
        let len = block_len(flags).expect("checked");
        let mut crc_input = Vec::with_capacity(len + 1);
        crc_input.push(p.seq);
        crc_input.extend_from_slice(&p.stream[..len]);
        let got = u16::from_le_bytes([p.stream[len], p.stream[len + 1]]);
        if crc16_ccitt(&crc_input) != got {
            return Some(CanEvent::Dropped(GroupDrop::Crc));
        }
        Some(CanEvent::Message(Message::Pose(read_block(p.seq as u32, &p.stream[..len]))))
    }
}
