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

use crate::frame::FrameMeta;

/// Chunk id of the pixels ("HC" 0x0001).
pub const IMAGE_CHUNK_ID: u32 = 0x4843_0001;
/// Chunk id of the metadata ("HC" 0x0002).
pub const META_CHUNK_ID: u32 = 0x4843_0002;
/// Bytes of metadata.
pub const META_LEN: usize = 56;
/// Bytes the chunks add to the pixels: two trailers and the metadata.
pub const CHUNK_OVERHEAD: usize = 8 + META_LEN + 8;

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
    let integration_ns = (f64::from(m.integration_s) * 1e9).round().max(0.0) as u64;
    b[48..56].copy_from_slice(&integration_ns.to_be_bytes());
    b
}

/// Append the chunk trailers and metadata to `image` (the block's pixels).
pub fn append_chunks(image: &mut Vec<u8>, meta: &FrameMeta) {
    let image_len = image.len() as u32;
    image.extend_from_slice(&IMAGE_CHUNK_ID.to_be_bytes());
    image.extend_from_slice(&image_len.to_be_bytes());
    image.extend_from_slice(&encode_meta(meta));
    image.extend_from_slice(&META_CHUNK_ID.to_be_bytes());
    image.extend_from_slice(&(META_LEN as u32).to_be_bytes());
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
        append_chunks(&mut block, &meta);
        assert_eq!(block.len(), 4 + CHUNK_OVERHEAD);
        assert_eq!(find_chunk(&block, IMAGE_CHUNK_ID).unwrap(), &[1, 2, 3, 4]);
        let m = find_chunk(&block, META_CHUNK_ID).unwrap();
        assert_eq!(u32::from_be_bytes(m[8..12].try_into().unwrap()), 42);
        assert_eq!(u64::from_be_bytes(m[16..24].try_into().unwrap()), 123_456_789);
        assert_eq!(u32::from_be_bytes(m[12..16].try_into().unwrap()), FrameFlags::EXTRAPOLATED);
        assert_eq!(u32::from_be_bytes(m[40..44].try_into().unwrap()), 2500);
        assert_eq!(u64::from_be_bytes(m[48..56].try_into().unwrap()), 1_000_000);
        assert_eq!(find_chunk(&block, 0x1234), None);
    }
}
