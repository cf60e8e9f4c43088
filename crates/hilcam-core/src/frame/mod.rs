//! A rendered frame with the metadata that travels with it (stream and recorder), and
//! the wire header codec: pure functions over bytes, no I/O.
//!
//! Wire layout of one frame: an 88-byte little-endian header ([`HEADER_LEN`]) followed
//! by `payload_len` bytes of pixels (row-major, little-endian, no padding). The byte
//! table is in `docs/protocol.md`, section "Frame stream (TCP)". Both checksums are
//! CRC-32/ISO-HDLC (the "IEEE" CRC of zlib, Ethernet and PNG: `crc::CRC_32_ISO_HDLC`).

use crate::pipeline::RenderedFrame;
use crate::pose::Pose;
use crate::render::film::Pixels;
use crate::render::integrator::Spp;
use serde::{Deserialize, Serialize};
use std::time::{SystemTime, UNIX_EPOCH};

pub mod truth_block;

pub use crate::render::film::PixelFormat;

/// Per-frame flag bits (header bytes 20..24). Unknown bits are preserved, not rejected,
/// so that a newer sender's flags pass through an older receiver. In JSON: the plain
/// number.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct FrameFlags(pub u32);

impl FrameFlags {
    /// The frame missed its deadline (rendered with a reduced budget or emitted late).
    pub const LATE: u32 = 1 << 0;
    /// Rendered from a pose extrapolated past the last received one.
    pub const EXTRAPOLATED: u32 = 1 << 1;
    /// The render budget was cut by the governor (fewer spp or bounces than configured).
    pub const DEGRADED: u32 = 1 << 2;
    /// The camera integrates over time (a global or rolling exposure): `pose_t_ns` is
    /// the start of row 0's exposure, and row `r` integrates over
    /// `[pose_t_ns + r·line_time_ns, … + integration_s]`. Without it the frame shows the
    /// instant `pose_t_ns`.
    pub const EXPOSURE_START: u32 = 1 << 3;
    /// A ground-truth block follows the payload ([`truth_block`]); only in version 2
    /// headers (a version 1 receiver cannot skip the block, so it must refuse the frame).
    pub const TRUTH: u32 = 1 << 4;

    pub fn contains(self, bit: u32) -> bool {
        self.0 & bit == bit
    }
    pub fn with(self, bit: u32) -> Self {
        FrameFlags(self.0 | bit)
    }
    pub fn late(self) -> bool {
        self.contains(Self::LATE)
    }
    pub fn extrapolated(self) -> bool {
        self.contains(Self::EXTRAPOLATED)
    }
    pub fn degraded(self) -> bool {
        self.contains(Self::DEGRADED)
    }
}

/// Everything the header says about a frame except the payload's length and checksum
/// (which are computed from the payload when encoding). The one metadata type: the TCP
/// header, the recorder's and replay's `frames.jsonl` lines
/// ([`crate::sink::recorder::FrameRecord`]) and `hilcam recv` all carry it. In JSON the
/// fields keep their names except `format`, written `pixel_format` as its name
/// ("Mono8", "Mono16", "Float32"); `flags` is the plain number.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameMeta {
    /// Frame counter of this run, starting at 0; gaps mean frames a receiver lost.
    pub frame_seq: u64,
    /// Sequence number of the pose the frame was rendered from.
    pub pose_seq: u32,
    /// That pose's timestamp, simulation time, ns.
    pub pose_t_ns: u64,
    /// When the pose arrived at hilcam, wall clock, ns since the UNIX epoch (0: none).
    pub pose_arrival_unix_ns: u64,
    /// When the frame was encoded for the sinks, wall clock, ns since the UNIX epoch.
    pub emit_unix_ns: u64,
    pub width: u32,
    pub height: u32,
    #[serde(rename = "pixel_format", with = "pixel_format_name")]
    pub format: PixelFormat,
    /// Significant bits per pixel: 1..=8 (Mono8), 1..=16 (Mono16), 32 (Float32).
    pub bit_depth: u8,
    /// Samples per pixel used for this frame (the average, when it has a fraction). The
    /// header carries the whole part in bytes 58..60 and the thousandths in 62..64, which
    /// older receivers read as reserved.
    pub spp: Spp,
    /// Maximum path depth (bounces) used for this frame.
    pub depth: u16,
    /// Sensor integration (exposure) time in seconds; 0 when no sensor model ran.
    pub integration_s: f32,
    /// Rolling shutter: delay between the starts of consecutive rows, ns (0 otherwise).
    /// Header bytes 80..84, which older receivers read as reserved.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub line_time_ns: u32,
    pub flags: FrameFlags,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

impl FrameMeta {
    /// The metadata of frame `index` rendered from `pose`: what a live frame's header
    /// says, and what a replayed frame (a trajectory row, or a session `frame` line's
    /// index, pose, settings and flags) implies. The wall-clock fields
    /// (`pose_arrival_unix_ns`, `emit_unix_ns`) are 0: the caller stamps those it knows.
    pub fn rendered(index: u64, pose: &Pose, f: &RenderedFrame, flags: FrameFlags) -> FrameMeta {
        let flags = if f.exposure.integrates_motion() { flags.with(FrameFlags::EXPOSURE_START) } else { flags };
        FrameMeta {
            frame_seq: index,
            pose_seq: pose.seq,
            pose_t_ns: pose.t_ns,
            pose_arrival_unix_ns: 0,
            emit_unix_ns: 0,
            width: f.width,
            height: f.height,
            format: f.pixels.format(),
            bit_depth: bit_depth_of(&f.pixels),
            spp: f.settings.spp,
            depth: f.settings.depth.min(u32::from(u16::MAX)) as u16,
            integration_s: f.integration_s.unwrap_or(0.0) as f32,
            line_time_ns: (f.exposure.line_time_s * 1e9).round().clamp(0.0, f64::from(u32::MAX)) as u32,
            flags,
        }
    }

    /// Payload size in bytes implied by the dimensions and format.
    pub fn payload_len(&self) -> u64 {
        // Saturating: u32 × u32 × 4 can exceed u64, and a saturated length matches no payload.
        (self.width as u64).saturating_mul(self.height as u64).saturating_mul(self.format.bytes_per_pixel() as u64)
    }
}

/// `PixelFormat` in JSON: its name. An unknown name is an error that lists the known ones.
mod pixel_format_name {
    use super::PixelFormat;
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    const ALL: [PixelFormat; 3] = [PixelFormat::Mono8, PixelFormat::Mono16, PixelFormat::Float32];

    fn name(f: PixelFormat) -> &'static str {
        match f {
            PixelFormat::Mono8 => "Mono8",
            PixelFormat::Mono16 => "Mono16",
            PixelFormat::Float32 => "Float32",
        }
    }

    pub fn serialize<S: Serializer>(f: &PixelFormat, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(name(*f))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<PixelFormat, D::Error> {
        let text = String::deserialize(d)?;
        ALL.into_iter().find(|f| name(*f) == text).ok_or_else(|| {
            D::Error::custom(format!("unknown pixel_format \"{text}\" (expected Mono8, Mono16 or Float32)"))
        })
    }
}

/// A frame: metadata plus pixels, consistent with each other (see [`Frame::new`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub meta: FrameMeta,
    pub pixels: Pixels,
}

/// A frame whose metadata does not match its pixels.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FrameError {
    #[error("frame {seq}: {width}x{height} needs {expected} pixels, buffer has {actual}")]
    SizeMismatch { seq: u64, width: u32, height: u32, expected: u64, actual: u64 },
    #[error("frame {seq}: bit depth {bits} is invalid for {format:?}")]
    BitDepth { seq: u64, bits: u8, format: PixelFormat },
}

impl Frame {
    /// Build a frame; `meta.format` and `meta.bit_depth` are taken from the pixels
    /// (8 for Mono8, `bits` for Mono16, 32 for Float32), the size is checked.
    pub fn new(mut meta: FrameMeta, pixels: Pixels) -> Result<Frame, FrameError> {
        meta.format = pixels.format();
        meta.bit_depth = bit_depth_of(&pixels);
        let expected = meta.width as u64 * meta.height as u64;
        if pixels.len() as u64 != expected {
            return Err(FrameError::SizeMismatch {
                seq: meta.frame_seq,
                width: meta.width,
                height: meta.height,
                expected,
                actual: pixels.len() as u64,
            });
        }
        if !meta.format.valid_bits(meta.bit_depth) {
            return Err(FrameError::BitDepth { seq: meta.frame_seq, bits: meta.bit_depth, format: meta.format });
        }
        Ok(Frame { meta, pixels })
    }

    /// Header + payload as one buffer, ready to be shared by all sinks (version 1: the
    /// `TRUTH` bit is cleared, as no block follows; [`Frame::encode_with_truth`] adds one).
    pub fn encode(&self) -> EncodedFrame {
        let meta = FrameMeta { flags: FrameFlags(self.meta.flags.0 & !FrameFlags::TRUTH), ..self.meta };
        EncodedFrame { meta, bytes: self.encode_bytes(&meta, &[]), roi: None, truth: None, mc_noise: None }
    }

    /// The header for `meta`, the payload, then the `after` pieces (a truth block's
    /// length and bytes, or nothing), in one buffer.
    fn encode_bytes(&self, meta: &FrameMeta, after: &[&[u8]]) -> Vec<u8> {
        let payload = self.pixels.to_le_bytes();
        let mut bytes = Vec::with_capacity(HEADER_LEN + payload.len() + after.iter().map(|a| a.len()).sum::<usize>());
        bytes.extend_from_slice(&encode_header(meta, &payload));
        bytes.extend_from_slice(&payload);
        after.iter().for_each(|a| bytes.extend_from_slice(a));
        bytes
    }
}

/// The bit depth a header gives `pixels`: 8 for Mono8, the sensor's bits for Mono16, 32
/// for Float32.
pub fn bit_depth_of(pixels: &Pixels) -> u8 {
    match pixels {
        Pixels::Mono8(_) => 8,
        Pixels::Mono16 { bits, .. } => *bits,
        Pixels::Float32(_) => 32,
    }
}

/// A frame encoded once for every sink (share it as `Arc<EncodedFrame>`, never copy).
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedFrame {
    pub meta: FrameMeta,
    /// The 88-byte header followed by the payload.
    pub bytes: Vec<u8>,
    /// The region of the sensor the pixels are, when a camera client asked for one
    /// (`FrameRequest::roi`); None: the whole array. Not on the wire: the header has
    /// the size, and a GigE Vision stream carries the offsets in its leader.
    pub roi: Option<crate::render::camera::Window>,
    /// The frame's ground truth when `[output] truth` asks for it (also encoded in
    /// `bytes`, after the payload: [`truth_block`]).
    pub truth: Option<std::sync::Arc<crate::render::truth::TruthImage>>,
    /// How the frame's Monte Carlo noise compares with the camera's (DN frames with a
    /// detector; [`crate::sensor::McNoiseStats`]). Not on the wire: the recorder's and
    /// the session's frame lines carry it.
    pub mc_noise: Option<crate::sensor::McNoiseStats>,
}

impl EncodedFrame {
    pub fn payload(&self) -> &[u8] {
        &self.bytes[HEADER_LEN..HEADER_LEN + self.meta.payload_len() as usize]
    }
    /// The pixels, decoded from the payload (a copy; for sinks that need typed pixels).
    pub fn pixels(&self) -> Pixels {
        pixels_from_le_bytes(self.meta.format, self.meta.bit_depth, self.payload())
    }
}

/// Header magic, bytes 0..4: ASCII "HLCF" (HiLcam Frame).
pub const MAGIC: [u8; 4] = *b"HLCF";
/// Wire version of a frame without a truth block (every frame when `[output] truth` is
/// off); this codec accepts it and [`VERSION_TRUTH`].
pub const VERSION: u16 = 1;
/// Wire version of a frame that may carry a truth block ([`FrameFlags::TRUTH`]): the
/// same 88-byte header.
pub const VERSION_TRUTH: u16 = 2;
/// Header size in bytes for version 1 (also sent in bytes 6..8).
pub const HEADER_LEN: usize = 88;

/// CRC-32/ISO-HDLC (poly 0x04C11DB7 reflected, init and xorout 0xFFFFFFFF): the CRC of
/// zlib, PNG and Ethernet; Python's `zlib.crc32` computes the same value.
pub const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Wall-clock now, ns since the UNIX epoch (0 if the clock is before 1970).
pub fn unix_ns_now() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_nanos() as u64).unwrap_or(0)
}

/// A decoded header: the metadata plus the payload's length and CRC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameHeader {
    pub meta: FrameMeta,
    pub payload_len: u64,
    pub payload_crc: u32,
    /// A truth block (`u64` length, then the block) follows the payload: version 2 with
    /// [`FrameFlags::TRUTH`].
    pub truth_block: bool,
}

/// Why bytes could not be decoded. `Incomplete` is normal on a stream (read more);
/// `Malformed` means the stream is not a valid hilcam frame stream.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DecodeError {
    #[error("need {needed} more bytes")]
    Incomplete { needed: usize },
    #[error("malformed frame header: {0}")]
    Malformed(#[from] Malformed),
}

/// The protocol violations the decoder detects, each naming the field.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum Malformed {
    #[error("bad magic {0:02x?} (expected \"HLCF\")")]
    Magic([u8; 4]),
    #[error("unsupported version {0} (this build speaks {VERSION} and {VERSION_TRUTH})")]
    Version(u16),
    #[error("header_len {0} (versions 1 and 2 require {HEADER_LEN})")]
    HeaderLen(u16),
    #[error("header CRC {found:#010x}, computed {computed:#010x}")]
    HeaderCrc { found: u32, computed: u32 },
    #[error("unknown pixel_format code {0}")]
    PixelFormat(u8),
    #[error("bit_depth {bits} invalid for {format:?}")]
    BitDepth { bits: u8, format: PixelFormat },
    #[error("payload_len {found}, but {width}x{height} {format:?} needs {expected}")]
    PayloadLen { found: u64, expected: u64, width: u32, height: u32, format: PixelFormat },
    #[error("frame {seq}: payload CRC {found:#010x}, computed {computed:#010x}")]
    PayloadCrc { seq: u64, found: u32, computed: u32 },
    #[error("spp {whole} and spp_frac_milli {milli}: a budget is at least 1 and its thousandths at most 999")]
    Spp { whole: u16, milli: u16 },
    /// A width or height above `MAX_SIDE_PX`: refused before anything is allocated.
    #[error("{field} {value} above the limit of {limit} pixels")]
    Dimension { field: &'static str, value: u32, limit: u32 },
    /// A truth block length no `width`×`height` frame can have: refused before allocating.
    #[error("truth_len {found} above the limit of {limit} bytes for {width}x{height}")]
    TruthLen { found: u64, limit: u64, width: u32, height: u32 },
    /// A truth block that fails its CRC or layout (its frame only; the length was read).
    #[error("frame {seq}: {message}")]
    TruthBlock { seq: u64, message: String },
}

/// Encode the header for `meta` and `payload` (the payload's length and CRC go in it).
pub fn encode_header(meta: &FrameMeta, payload: &[u8]) -> [u8; HEADER_LEN] {
    let mut h = [0u8; HEADER_LEN];
    h[0..4].copy_from_slice(&MAGIC);
    let version = if meta.flags.contains(FrameFlags::TRUTH) { VERSION_TRUTH } else { VERSION };
    h[4..6].copy_from_slice(&version.to_le_bytes());
    h[6..8].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
    h[8..16].copy_from_slice(&meta.frame_seq.to_le_bytes());
    h[16..20].copy_from_slice(&meta.pose_seq.to_le_bytes());
    h[20..24].copy_from_slice(&meta.flags.0.to_le_bytes());
    h[24..32].copy_from_slice(&meta.pose_t_ns.to_le_bytes());
    h[32..40].copy_from_slice(&meta.pose_arrival_unix_ns.to_le_bytes());
    h[40..48].copy_from_slice(&meta.emit_unix_ns.to_le_bytes());
    h[48..52].copy_from_slice(&meta.width.to_le_bytes());
    h[52..56].copy_from_slice(&meta.height.to_le_bytes());
    h[56] = meta.format.code();
    h[57] = meta.bit_depth;
    h[58..60].copy_from_slice(&(meta.spp.floor() as u16).to_le_bytes());
    h[60..62].copy_from_slice(&meta.depth.to_le_bytes());
    h[62..64].copy_from_slice(&(meta.spp.fraction_milli() as u16).to_le_bytes());
    h[64..68].copy_from_slice(&meta.integration_s.to_le_bytes());
    h[68..72].copy_from_slice(&CRC32.checksum(payload).to_le_bytes());
    h[72..80].copy_from_slice(&(payload.len() as u64).to_le_bytes());
    h[80..84].copy_from_slice(&meta.line_time_ns.to_le_bytes());
    let crc = CRC32.checksum(&h[..84]);
    h[84..88].copy_from_slice(&crc.to_le_bytes());
    h
}

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}
fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"))
}
fn u64_at(b: &[u8], i: usize) -> u64 {
    u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"))
}

/// Decode and validate a header from the start of `buf` (extra bytes are ignored).
///
/// Checks, in order: length, magic, version, header_len, header CRC, pixel format,
/// bit depth, spp, width and height at most `crate::render::camera::MAX_SIDE_PX`,
/// and that payload_len equals width·height·bytes-per-pixel. Reserved bytes
/// are ignored (senders write zeros).
pub fn decode_header(buf: &[u8]) -> Result<FrameHeader, DecodeError> {
    if buf.len() < HEADER_LEN {
        return Err(DecodeError::Incomplete { needed: HEADER_LEN - buf.len() });
    }
    let b = &buf[..HEADER_LEN];
    let magic: [u8; 4] = b[0..4].try_into().expect("4 bytes");
    if magic != MAGIC {
        return Err(Malformed::Magic(magic).into());
    }
    let version = u16_at(b, 4);
    if version != VERSION && version != VERSION_TRUTH {
        return Err(Malformed::Version(version).into());
    }
    let header_len = u16_at(b, 6);
    if header_len as usize != HEADER_LEN {
        return Err(Malformed::HeaderLen(header_len).into());
    }
    let found = u32_at(b, 84);
    let computed = CRC32.checksum(&b[..84]);
    if found != computed {
        return Err(Malformed::HeaderCrc { found, computed }.into());
    }
    let format = PixelFormat::from_code(b[56]).ok_or(Malformed::PixelFormat(b[56]))?;
    let bit_depth = b[57];
    if !format.valid_bits(bit_depth) {
        return Err(Malformed::BitDepth { bits: bit_depth, format }.into());
    }
    // Bounded before anything is sized from them (an empty frame, 0 × n, allocates nothing).
    for (field, value) in [("width", u32_at(b, 48)), ("height", u32_at(b, 52))] {
        if value > crate::render::camera::MAX_SIDE_PX {
            return Err(Malformed::Dimension { field, value, limit: crate::render::camera::MAX_SIDE_PX }.into());
        }
    }
    let (whole, milli) = (u16_at(b, 58), u16_at(b, 62));
    if whole == 0 || milli > 999 {
        return Err(Malformed::Spp { whole, milli }.into());
    }
    let meta = FrameMeta {
        frame_seq: u64_at(b, 8),
        pose_seq: u32_at(b, 16),
        flags: FrameFlags(u32_at(b, 20)),
        pose_t_ns: u64_at(b, 24),
        pose_arrival_unix_ns: u64_at(b, 32),
        emit_unix_ns: u64_at(b, 40),
        width: u32_at(b, 48),
        height: u32_at(b, 52),
        format,
        bit_depth,
        spp: Spp::from_milli(u32::from(whole) * 1000 + u32::from(milli)),
        depth: u16_at(b, 60),
        integration_s: f32::from_le_bytes(b[64..68].try_into().expect("4 bytes")),
        line_time_ns: u32_at(b, 80),
    };
    let payload_len = u64_at(b, 72);
    if payload_len != meta.payload_len() {
        return Err(Malformed::PayloadLen {
            found: payload_len,
            expected: meta.payload_len(),
            width: meta.width,
            height: meta.height,
            format,
        }
        .into());
    }
    let truth_block = version == VERSION_TRUTH && meta.flags.contains(FrameFlags::TRUTH);
    Ok(FrameHeader { meta, payload_len, payload_crc: u32_at(b, 68), truth_block })
}

/// Check a payload against its header's CRC.
pub fn check_payload(header: &FrameHeader, payload: &[u8]) -> Result<(), Malformed> {
    let computed = CRC32.checksum(payload);
    if computed != header.payload_crc {
        return Err(Malformed::PayloadCrc { seq: header.meta.frame_seq, found: header.payload_crc, computed });
    }
    Ok(())
}

/// Decode one whole frame from the start of `buf`; returns it and the bytes consumed
/// (a truth block, if any, is consumed and dropped: [`decode_frame_with_truth`]).
pub fn decode_frame(buf: &[u8]) -> Result<(Frame, usize), DecodeError> {
    decode_frame_with_truth(buf).map(|(f, _, used)| (f, used))
}

/// [`decode_frame`] with the frame's truth block, decoded (`None` without one; a block
/// that fails its checks is an error after the whole frame has arrived).
#[allow(clippy::type_complexity)]
pub fn decode_frame_with_truth(buf: &[u8]) -> Result<(Frame, Option<truth_block::WireTruth>, usize), DecodeError> {
    let header = decode_header(buf)?;
    let (w, h) = (header.meta.width, header.meta.height);
    let end = HEADER_LEN as u64 + header.payload_len;
    let total = if header.truth_block {
        let Some(len) = buf.get(end as usize..end as usize + 8) else {
            return Err(DecodeError::Incomplete { needed: (end + 8 - buf.len() as u64) as usize });
        };
        let len = u64::from_le_bytes(len.try_into().expect("8 bytes"));
        truth_block::check_truth_len(w, h, len)?;
        end + 8 + len
    } else {
        end
    };
    if (buf.len() as u64) < total {
        return Err(DecodeError::Incomplete { needed: (total - buf.len() as u64) as usize });
    }
    let payload = &buf[HEADER_LEN..end as usize];
    check_payload(&header, payload)?;
    let truth = match header.truth_block {
        false => None,
        true => Some(truth_block::decode_frame_truth(&header.meta, &buf[end as usize + 8..total as usize])?),
    };
    let pixels = pixels_from_le_bytes(header.meta.format, header.meta.bit_depth, payload);
    let frame = Frame { meta: header.meta, pixels };
    Ok((frame, truth, total as usize))
}

/// Pixels from a little-endian payload (length must be a multiple of the pixel size;
/// a trailing partial pixel is ignored).
pub fn pixels_from_le_bytes(format: PixelFormat, bit_depth: u8, payload: &[u8]) -> Pixels {
    match format {
        PixelFormat::Mono8 => Pixels::Mono8(payload.to_vec()),
        PixelFormat::Mono16 => Pixels::Mono16 {
            data: payload.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect(),
            bits: bit_depth,
        },
        PixelFormat::Float32 => {
            Pixels::Float32(payload.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
        }
    }
}
