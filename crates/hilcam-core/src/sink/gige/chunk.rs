//! The chunk data appended to each GVSP block when ChunkModeActive is on: hilcam's
//! frame metadata, so a client can check which pose a frame was rendered from. Pure.
//!
//! GenICam chunks are read from the end of the block backwards: each chunk is its
//! data followed by an 8-byte trailer (chunk id, data length; big-endian). A block is
//!
//! | bytes | content |
//! |---|---|
//! | `image` | the pixels (the image chunk's data) |
//! | 8 | id [`IMAGE_CHUNK_ID`], length = image bytes |
//! | [`META_LEN`] | the metadata below |
//! | 8 | id [`META_CHUNK_ID`], length = [`META_LEN`] |
//!
//! Metadata, big-endian: `frame_seq` u64 @0, `pose_seq` u32 @8, `flags` u32 @12
//! (bit 0 LATE, 1 EXTRAPOLATED, 2 DEGRADED), `pose_t_ns` u64 @16,
//! `pose_arrival_unix_ns` u64 @24, `emit_unix_ns` u64 @32, `spp_milli` u32 @40
//! (samples per pixel × 1000), `depth` u16 @44, `bit_depth` u8 @46 (the ADC's),
//! reserved u8 @47, `integration_ns` u64 @48.
//!
//! Then the SFNC chunks, 8 bytes each, big-endian: ChunkTimestamp ([`TIMESTAMP_CHUNK_ID`],
//! u64 ticks, the leader's timestamp), ChunkExposureTime ([`EXPOSURE_CHUNK_ID`], f64 µs,
//! what the frame integrated), ChunkFrameID ([`FRAME_ID_CHUNK_ID`], u64, the GVSP block
//! id). A client switches each chunk but the image with ChunkSelector / ChunkEnable
//! ([`ChunkKind`]); all are on at start.
//!
//! With `[output] truth` each block also carries the frame's ground truth, after the
//! metadata: a footprint chunk ([`FOOTPRINT_CHUNK_ID`], [`FOOTPRINT_LEN`] bytes,
//! big-endian like the metadata: `target_pixels` u64 @0, centroid x, y f64 @8 and @16
//! (continuous pixel coordinates of the block's window; NaN when no pixel), bbox
//! col0, row0, col1, row1 u32 @24, half-open) and one chunk per channel
//! ([`truth_chunk_id`]: depth 0x48430011, mask 0x48430012, normal 0x48430013, body_xyz
//! 0x48430014), whose data are the channel's planes over the block's window,
//! little-endian like the pixels: f32 (mask u32), x plane then y then z. With the mask
//! comes [`MATERIALS_CHUNK_ID`]: the mask's id → material-name table (ASCII,
//! `1=name;2=name;…`, as the stream's block carries it), NUL-terminated and padded with
//! NULs to a multiple of 4 bytes.

use crate::frame::FrameMeta;
use crate::frame::truth_block::channel_id;
use crate::render::camera::Window;
use crate::render::truth::{TruthChannel, TruthChannels, TruthImage};

/// Chunk id of the pixels ("HC" 0x0001).
pub const IMAGE_CHUNK_ID: u32 = 0x4843_0001;
/// Chunk id of the metadata ("HC" 0x0002).
pub const META_CHUNK_ID: u32 = 0x4843_0002;
/// Bytes of metadata.
pub const META_LEN: usize = 56;
/// Chunk ids of the SFNC chunks ("HC" 0x0020..0x0022), 8 bytes of data each.
pub const TIMESTAMP_CHUNK_ID: u32 = 0x4843_0020;
pub const EXPOSURE_CHUNK_ID: u32 = 0x4843_0021;
pub const FRAME_ID_CHUNK_ID: u32 = 0x4843_0022;
const SFNC_CHUNK_LEN: usize = 8 + 8;
/// Bytes the chunks add to the pixels with every chunk enabled but truth: the image
/// trailer, the metadata and the three SFNC chunks.
pub const CHUNK_OVERHEAD: usize = 8 + META_LEN + 8 + 3 * SFNC_CHUNK_LEN;

/// The chunks a client switches with ChunkSelector / ChunkEnable (the image chunk is
/// always sent). The value is the ChunkSelector register's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChunkKind {
    Timestamp = 0,
    ExposureTime = 1,
    FrameId = 2,
    HilcamMetadata = 3,
    HilcamTruth = 4,
}

impl ChunkKind {
    pub const ALL: [ChunkKind; 5] = [
        ChunkKind::Timestamp,
        ChunkKind::ExposureTime,
        ChunkKind::FrameId,
        ChunkKind::HilcamMetadata,
        ChunkKind::HilcamTruth,
    ];

    pub fn from_u32(v: u32) -> Option<ChunkKind> {
        ChunkKind::ALL.get(v as usize).copied()
    }

    /// The ChunkSelector entry's name.
    pub fn name(self) -> &'static str {
        match self {
            ChunkKind::Timestamp => "Timestamp",
            ChunkKind::ExposureTime => "ExposureTime",
            ChunkKind::FrameId => "FrameID",
            ChunkKind::HilcamMetadata => "HilcamMetadata",
            ChunkKind::HilcamTruth => "HilcamTruth",
        }
    }
}

/// Which [`ChunkKind`]s are enabled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChunkSet(u8);

impl ChunkSet {
    pub const ALL: ChunkSet = ChunkSet(0x1F);

    pub fn contains(self, k: ChunkKind) -> bool {
        self.0 & (1 << k as u8) != 0
    }

    pub fn with(self, k: ChunkKind, on: bool) -> ChunkSet {
        if on { ChunkSet(self.0 | (1 << k as u8)) } else { ChunkSet(self.0 & !(1 << k as u8)) }
    }
}

/// The SFNC chunks' values for one block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SfncValues {
    /// Leader timestamp, ticks.
    pub timestamp: u64,
    /// What the frame integrated, µs.
    pub exposure_us: f64,
    /// The GVSP block id.
    pub frame_id: u64,
}

/// Bytes the chunks of `set` add to a `width`×`height` image (truth only with channels;
/// `materials_len`: bytes of the scene's material table, sent with the mask).
pub fn chunks_len(set: ChunkSet, truth: TruthChannels, materials_len: u32, width: u32, height: u32) -> u64 {
    let mut n = 8u64;
    if set.contains(ChunkKind::HilcamMetadata) {
        n += (META_LEN + 8) as u64;
    }
    for k in [ChunkKind::Timestamp, ChunkKind::ExposureTime, ChunkKind::FrameId] {
        if set.contains(k) {
            n += SFNC_CHUNK_LEN as u64;
        }
    }
    if set.contains(ChunkKind::HilcamTruth) {
        n += truth_chunks_len(truth, materials_len, width, height);
    }
    n
}

/// Chunk id of the truth footprint ("HC" 0x0010).
pub const FOOTPRINT_CHUNK_ID: u32 = 0x4843_0010;
/// Bytes of the footprint chunk's data.
pub const FOOTPRINT_LEN: usize = 40;

/// Chunk id of the mask's material table ("HC" 0x0015: the stream's item 5).
pub const MATERIALS_CHUNK_ID: u32 = FOOTPRINT_CHUNK_ID + crate::frame::truth_block::MATERIALS_ID as u32;

/// Bytes of the material-table chunk's data for a table of `len` bytes: NUL-terminated,
/// padded to a multiple of 4.
pub fn materials_chunk_data_len(len: u32) -> u32 {
    (len / 4 + 1) * 4
}

/// Chunk id of truth channel `c`: [`FOOTPRINT_CHUNK_ID`] + its stream id (depth 1, mask 2,
/// normal 3, body_xyz 4).
pub fn truth_chunk_id(c: TruthChannel) -> u32 {
    FOOTPRINT_CHUNK_ID + u32::from(channel_id(c))
}

fn components(c: TruthChannel) -> usize {
    match c {
        TruthChannel::Depth | TruthChannel::Mask => 1,
        TruthChannel::Normal | TruthChannel::BodyXyz => 3,
    }
}

/// Bytes the truth chunks add to a `width`×`height` block (0 without channels), the
/// material table (`materials_len` bytes) included when the mask is sent.
pub fn truth_chunks_len(channels: TruthChannels, materials_len: u32, width: u32, height: u32) -> u64 {
    if channels.is_empty() {
        return 0;
    }
    let n = u64::from(width) * u64::from(height);
    let data: u64 = channels.iter().map(|c| 8 + n * 4 * components(c) as u64).sum();
    let table =
        if channels.contains(TruthChannel::Mask) { 8 + u64::from(materials_chunk_data_len(materials_len)) } else { 0 };
    (8 + FOOTPRINT_LEN as u64) + data + table
}

/// Append the footprint and channel chunks of `truth` over `window` (whose offsets are
/// relative to the truth image, which must contain it) to `block`.
pub fn append_truth_chunks(block: &mut Vec<u8>, truth: &TruthImage, window: Window) {
    let tw = truth.width as usize;
    let (x0, x1) = (window.x as usize, (window.x + window.width) as usize);
    let rows = window.y as usize..(window.y + window.height) as usize;
    let crop =
        |plane: &[f32]| -> Vec<f32> { rows.clone().flat_map(|r| plane[r * tw + x0..r * tw + x1].to_vec()).collect() };
    let mask: Vec<u32> = rows.clone().flat_map(|r| truth.mask[r * tw + x0..r * tw + x1].to_vec()).collect();
    // The footprint of the window's own mask, in its coordinates.
    let windowed = TruthImage {
        width: window.width,
        height: window.height,
        channels: TruthChannels::NONE,
        mask,
        materials: None,
        depth: Vec::new(),
        normal: Default::default(),
        body_xyz: Default::default(),
    };
    let f = windowed.footprint();
    let mut fp = [0u8; FOOTPRINT_LEN];
    fp[0..8].copy_from_slice(&f.map_or(0, |f| f.pixels).to_be_bytes());
    let [cx, cy] = f.map_or([f64::NAN; 2], |f| f.centroid_px);
    fp[8..16].copy_from_slice(&cx.to_be_bytes());
    fp[16..24].copy_from_slice(&cy.to_be_bytes());
    for (k, v) in f.map_or([0; 4], |f| f.bbox_px).into_iter().enumerate() {
        fp[24 + 4 * k..28 + 4 * k].copy_from_slice(&v.to_be_bytes());
    }
    push_chunk(block, FOOTPRINT_CHUNK_ID, |b| b.extend_from_slice(&fp));
    for c in truth.channels.iter() {
        push_chunk(block, truth_chunk_id(c), |b| match c {
            TruthChannel::Depth => b.extend(crop(&truth.depth).iter().flat_map(|v| v.to_le_bytes())),
            TruthChannel::Mask => b.extend(windowed.mask.iter().flat_map(|v| v.to_le_bytes())),
            TruthChannel::Normal => b.extend(truth.normal.iter().flat_map(|p| crop(p)).flat_map(|v| v.to_le_bytes())),
            TruthChannel::BodyXyz => {
                b.extend(truth.body_xyz.iter().flat_map(|p| crop(p)).flat_map(|v| v.to_le_bytes()))
            }
        });
    }
    if truth.channels.contains(TruthChannel::Mask) {
        let table = truth.materials.as_deref().unwrap_or("").as_bytes();
        push_chunk(block, MATERIALS_CHUNK_ID, |b| {
            b.extend_from_slice(table);
            b.resize(b.len() + (materials_chunk_data_len(table.len() as u32) as usize - table.len()), 0);
        });
    }
}

/// Append a chunk: its data (written by `data`), then its trailer.
fn push_chunk(block: &mut Vec<u8>, id: u32, data: impl FnOnce(&mut Vec<u8>)) {
    let start = block.len();
    data(block);
    let len = (block.len() - start) as u32;
    block.extend_from_slice(&id.to_be_bytes());
    block.extend_from_slice(&len.to_be_bytes());
}

/// An integration time (s, f32 as frames carry it) in whole ns: what the chunks and
/// ExposureTime report (0.001 s is 1 000 000 ns, not the f32's 1 000 000.05).
pub fn integration_ns(integration_s: f32) -> u64 {
    (f64::from(integration_s) * 1e9).round().max(0.0) as u64
}

/// The metadata chunk's data.
pub fn encode_meta(m: &FrameMeta) -> [u8; META_LEN] {
    let mut b = [0u8; META_LEN];
    b[0..8].copy_from_slice(&m.frame_seq.to_be_bytes());
    b[8..12].copy_from_slice(&m.pose_seq.to_be_bytes());
    b[12..16].copy_from_slice(&m.flags.0.to_be_bytes());
    b[16..24].copy_from_slice(&m.pose_t_ns.to_be_bytes());
    b[24..32].copy_from_slice(&m.pose_arrival_unix_ns.to_be_bytes());
    b[32..40].copy_from_slice(&m.emit_unix_ns.to_be_bytes());
    b[40..44].copy_from_slice(&m.spp.milli().to_be_bytes());
    b[44..46].copy_from_slice(&m.depth.to_be_bytes());
    b[46] = m.bit_depth;
    b[48..56].copy_from_slice(&integration_ns(m.integration_s).to_be_bytes());
    b
}

/// Append the image trailer, then the metadata and SFNC chunks `set` enables, to
/// `image` (the block's pixels). Truth is appended by [`append_truth_chunks`].
pub fn append_chunks(image: &mut Vec<u8>, meta: &FrameMeta, set: ChunkSet, sfnc: &SfncValues) {
    let image_len = image.len() as u32;
    image.extend_from_slice(&IMAGE_CHUNK_ID.to_be_bytes());
    image.extend_from_slice(&image_len.to_be_bytes());
    if set.contains(ChunkKind::HilcamMetadata) {
        push_chunk(image, META_CHUNK_ID, |b| b.extend_from_slice(&encode_meta(meta)));
    }
    if set.contains(ChunkKind::Timestamp) {
        push_chunk(image, TIMESTAMP_CHUNK_ID, |b| b.extend_from_slice(&sfnc.timestamp.to_be_bytes()));
    }
    if set.contains(ChunkKind::ExposureTime) {
        push_chunk(image, EXPOSURE_CHUNK_ID, |b| b.extend_from_slice(&sfnc.exposure_us.to_be_bytes()));
    }
    if set.contains(ChunkKind::FrameId) {
        push_chunk(image, FRAME_ID_CHUNK_ID, |b| b.extend_from_slice(&sfnc.frame_id.to_be_bytes()));
    }
}

/// Find chunk `id` in a block, walking back from the end (the client side; tests).
pub fn find_chunk(block: &[u8], id: u32) -> Option<&[u8]> {
    let mut end = block.len();
    while end >= 8 {
        let cid = u32::from_be_bytes(block[end - 8..end - 4].try_into().ok()?);
        let len = u32::from_be_bytes(block[end - 4..end].try_into().ok()?) as usize;
        let start = (end - 8).checked_sub(len)?;
        if cid == id {
            return Some(&block[start..end - 8]);
        }
        end = start;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{FrameFlags, PixelFormat};
    use crate::render::integrator::Spp;

    #[test]
    fn chunks_are_found_from_the_end() {
        let meta = FrameMeta {
            frame_seq: 7,
            pose_seq: 42,
            pose_t_ns: 123_456_789,
            pose_arrival_unix_ns: 1,
            emit_unix_ns: 2,
            width: 2,
            height: 2,
            format: PixelFormat::Mono16,
            bit_depth: 12,
            spp: Spp::from_milli(2500),
            depth: 3,
            integration_s: 0.001,
            line_time_ns: 0,
            flags: FrameFlags(FrameFlags::EXTRAPOLATED),
        };
        let mut block = vec![1, 2, 3, 4];
        let sfnc = SfncValues { timestamp: 123_456_789, exposure_us: 1000.0, frame_id: 9 };
        append_chunks(&mut block, &meta, ChunkSet::ALL, &sfnc);
        assert_eq!(block.len(), 4 + CHUNK_OVERHEAD);
        assert_eq!(chunks_len(ChunkSet::ALL, TruthChannels::NONE, 0, 2, 1), CHUNK_OVERHEAD as u64);
        let be = |id| u64::from_be_bytes(find_chunk(&block, id).unwrap().try_into().unwrap());
        assert_eq!((be(TIMESTAMP_CHUNK_ID), be(FRAME_ID_CHUNK_ID)), (123_456_789, 9));
        assert_eq!(f64::from_bits(be(EXPOSURE_CHUNK_ID)), 1000.0);
        // Without the metadata and the timestamp: the rest is still found, the length follows.
        let set = ChunkSet::ALL.with(ChunkKind::HilcamMetadata, false).with(ChunkKind::Timestamp, false);
        let mut small = vec![1, 2, 3, 4];
        append_chunks(&mut small, &meta, set, &sfnc);
        assert_eq!(small.len() as u64, 4 + chunks_len(set, TruthChannels::NONE, 0, 2, 1));
        assert_eq!(find_chunk(&small, META_CHUNK_ID), None);
        assert_eq!(find_chunk(&small, IMAGE_CHUNK_ID).unwrap(), &[1, 2, 3, 4]);
        assert!(find_chunk(&small, FRAME_ID_CHUNK_ID).is_some());
        assert_eq!(find_chunk(&block, IMAGE_CHUNK_ID).unwrap(), &[1, 2, 3, 4]);
        let m = find_chunk(&block, META_CHUNK_ID).unwrap();
        assert_eq!(u32::from_be_bytes(m[8..12].try_into().unwrap()), 42);
        assert_eq!(u64::from_be_bytes(m[16..24].try_into().unwrap()), 123_456_789);
        assert_eq!(u32::from_be_bytes(m[12..16].try_into().unwrap()), FrameFlags::EXTRAPOLATED);
        assert_eq!(u32::from_be_bytes(m[40..44].try_into().unwrap()), 2500);
        assert_eq!(u64::from_be_bytes(m[48..56].try_into().unwrap()), 1_000_000);
        assert_eq!(find_chunk(&block, 0x1234), None);
    }

    #[test]
    fn truth_chunks_hold_the_windows_planes_and_its_own_footprint() {
        let channels = TruthChannels::parse("depth,mask,normal").unwrap();
        // 3×2: pixels (1, 0) and (2, 1) hit; the window is columns 1..3, both rows.
        let truth = TruthImage {
            width: 3,
            height: 2,
            channels,
            mask: vec![0, 1, 0, 0, 0, 2],
            materials: None,
            depth: vec![9.0, 1.0, 9.0, 9.0, 9.0, 2.0],
            normal: [vec![0.5; 6], vec![0.25; 6], vec![-1.0; 6]],
            body_xyz: Default::default(),
        };
        let window = Window { x: 1, y: 0, width: 2, height: 2 };
        let mut block = vec![7; 8];
        append_truth_chunks(&mut block, &truth, window);
        assert_eq!(block.len() as u64, 8 + truth_chunks_len(channels, 0, 2, 2));
        let f32s = |b: &[u8]| b.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect::<Vec<_>>();
        assert_eq!(f32s(find_chunk(&block, 0x4843_0011).unwrap()), [1.0, 9.0, 9.0, 2.0]);
        let mask = find_chunk(&block, 0x4843_0012).unwrap();
        assert_eq!(mask, [1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0]);
        assert_eq!(f32s(find_chunk(&block, 0x4843_0013).unwrap()), [[0.5; 4], [0.25; 4], [-1.0; 4]].concat());
        let fp = find_chunk(&block, FOOTPRINT_CHUNK_ID).unwrap();
        assert_eq!(u64::from_be_bytes(fp[0..8].try_into().unwrap()), 2);
        // Window columns 0 and 1 (image columns 1 and 2): centres 0.5 and 1.5, rows 0.5 and 1.5.
        assert_eq!(f64::from_be_bytes(fp[8..16].try_into().unwrap()), 1.0);
        assert_eq!(f64::from_be_bytes(fp[16..24].try_into().unwrap()), 1.0);
        let bbox: Vec<u32> = fp[24..40].chunks_exact(4).map(|c| u32::from_be_bytes(c.try_into().unwrap())).collect();
        assert_eq!(bbox, [0, 0, 2, 2]);
        assert_eq!(find_chunk(&block, 0x4843_0014), None, "body_xyz not asked for");
    }
}
