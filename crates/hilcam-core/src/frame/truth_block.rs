//! The ground-truth block a frame may carry after its payload on the TCP stream
//! (`[output] truth`; docs/protocol.md "Ground truth block"). Pure codec, no I/O.
//!
//! A frame with a block has header version 2 and flag bit 4 [`FrameFlags::TRUTH`]; after
//! the payload come a u64 `truth_len` and `truth_len` bytes:
//!
//! | offset | size | type | field |
//! |---:|---:|---|---|
//! | 0 | 2 | u16 | item count n |
//! | 2 | 6 | | reserved, 0 |
//! | 8 | 8 | u64 | `target_pixels`: pixels whose centre ray hits the target |
//! | 16 | 16 | f64 ×2 | centroid x, y (continuous pixel coordinates; NaN when 0 pixels) |
//! | 32 | 16 | u32 ×4 | bbox col0, row0, col1, row1, half-open (0 when 0 pixels) |
//! | 48 | … | | n items: u16 channel id, u8 element type, u8 components, u32 reserved, u64 data bytes, data |
//! | end−4 | 4 | u32 | CRC-32/ISO-HDLC of bytes 0 … end−5 |
//!
//! Channel ids: 1 depth (f32 ×1), 2 mask (u32 ×1), 3 normal (f32 ×3), 4 body_xyz (f32 ×3);
//! element types 1 = f32, 2 = u32. Data are component planes one after another (all x,
//! then all y, then all z), each row-major like the payload, little-endian. With the mask
//! comes item 5, `materials` (element type 3 = ASCII text, 1 component): the mask's
//! id → material-name table, `1=name;2=name;…` ([`crate::render::truth::materials_table`]),
//! at most [`MATERIALS_MAX_LEN`] bytes, not padded.

use super::{EncodedFrame, Frame, FrameFlags, Malformed};
use crate::render::truth::{Footprint, TruthChannel, TruthChannels, TruthImage};
use std::sync::Arc;

/// Bytes before the first item.
pub const FIXED_LEN: usize = 48;
/// Bytes of an item's own header (before its data).
pub const ITEM_HEADER_LEN: usize = 16;

const F32: u8 = 1;
const U32: u8 = 2;
const TEXT: u8 = 3;
/// Item id of the mask's material table (after the four channels).
pub const MATERIALS_ID: u16 = 5;
/// The longest material table a block carries (and a receiver accepts): a serve config
/// whose scene has a longer one and sends the mask is refused at start.
pub const MATERIALS_MAX_LEN: usize = 65_536;

/// [`super::CRC32`] (the same CRC, the same values) with slice-by-16 tables: a block is
/// up to 16 bytes per pixel per channel, tens of MB at 1024², where the bytewise table
/// would cost ~0.1 s per frame.
const BLOCK_CRC: crc::Crc<u32, crc::Table<16>> = crc::Crc::<u32, crc::Table<16>>::new(&crc::CRC_32_ISO_HDLC);

/// Append `values` as little-endian 4-byte words (a sized copy: no per-byte pushes).
fn put_le<T: Copy>(b: &mut Vec<u8>, values: &[T], to_le: impl Fn(T) -> [u8; 4]) {
    let start = b.len();
    b.resize(start + 4 * values.len(), 0);
    for (dst, &v) in b[start..].chunks_exact_mut(4).zip(values) {
        dst.copy_from_slice(&to_le(v));
    }
}

/// The wire id of channel `c` (1-based in canonical order).
pub fn channel_id(c: TruthChannel) -> u16 {
    c as u16 + 1
}

/// (element type, components) of channel `c` on the wire.
fn layout(c: TruthChannel) -> (u8, u8) {
    match c {
        TruthChannel::Depth => (F32, 1),
        TruthChannel::Mask => (U32, 1),
        TruthChannel::Normal | TruthChannel::BodyXyz => (F32, 3),
    }
}

/// The largest `truth_len` a receiver accepts for a `width`×`height` frame: room for 16
/// four-byte values per pixel (today's channels use at most 8), the material table and
/// 1 KiB of headers, so a corrupt or hostile length cannot ask for more than a few times
/// the image.
pub fn max_truth_len(width: u32, height: u32) -> u64 {
    1024 + MATERIALS_MAX_LEN as u64 + 64 * u64::from(width) * u64::from(height)
}

/// The material table a block of `truth` carries: with the mask only.
fn materials_item(truth: &TruthImage) -> Option<&str> {
    truth.materials.as_deref().filter(|_| truth.channels.contains(TruthChannel::Mask))
}

/// A frame's truth as the block carries it: the channels sent, and the footprint (sent
/// whether or not the mask is). Channels not sent are empty vectors, the mask included.
#[derive(Clone, Debug, PartialEq)]
pub struct WireTruth {
    pub image: TruthImage,
    pub footprint: Option<Footprint>,
}

/// Why a block's content was refused: it spoils that frame's truth only (its length
/// was read, so the stream stays in step).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TruthBlockError {
    #[error("truth block CRC {found:#010x}, computed {computed:#010x}")]
    Crc { found: u32, computed: u32 },
    #[error("truth block: {0}")]
    Layout(String),
}

/// The block of `truth` (without the `truth_len` prefix).
pub fn encode_truth_block(truth: &TruthImage) -> Vec<u8> {
    let n = truth.width as usize * truth.height as usize;
    let items: Vec<TruthChannel> = truth.channels.iter().collect();
    let table = materials_item(truth);
    let data_len: usize = items.iter().map(|&c| n * 4 * layout(c).1 as usize).sum();
    let mut b = Vec::with_capacity(FIXED_LEN + (items.len() + 1) * ITEM_HEADER_LEN + data_len + 4);
    b.extend_from_slice(&((items.len() + usize::from(table.is_some())) as u16).to_le_bytes());
    b.extend_from_slice(&[0; 6]);
    let f = truth.footprint();
    b.extend_from_slice(&f.map_or(0, |f| f.pixels).to_le_bytes());
    for v in f.map_or([f64::NAN; 2], |f| f.centroid_px) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in f.map_or([0; 4], |f| f.bbox_px) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for c in items {
        let (ty, comps) = layout(c);
        b.extend_from_slice(&channel_id(c).to_le_bytes());
        b.extend_from_slice(&[ty, comps, 0, 0, 0, 0]);
        b.extend_from_slice(&((n * 4 * comps as usize) as u64).to_le_bytes());
        match c {
            TruthChannel::Depth => put_le(&mut b, &truth.depth, f32::to_le_bytes),
            TruthChannel::Mask => put_le(&mut b, &truth.mask, u32::to_le_bytes),
            TruthChannel::Normal => truth.normal.iter().for_each(|p| put_le(&mut b, p, f32::to_le_bytes)),
            TruthChannel::BodyXyz => truth.body_xyz.iter().for_each(|p| put_le(&mut b, p, f32::to_le_bytes)),
        }
    }
    if let Some(t) = table {
        b.extend_from_slice(&MATERIALS_ID.to_le_bytes());
        b.extend_from_slice(&[TEXT, 1, 0, 0, 0, 0]);
        b.extend_from_slice(&(t.len() as u64).to_le_bytes());
        b.extend_from_slice(t.as_bytes());
    }
    let crc = BLOCK_CRC.checksum(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

fn le_u64(b: &[u8], i: usize) -> u64 {
    u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"))
}

/// Decode a block (the `truth_len` bytes after the length) of a `width`×`height` frame.
/// Items of unknown channel ids are skipped (a newer sender's channels).
pub fn decode_truth_block(width: u32, height: u32, b: &[u8]) -> Result<WireTruth, TruthBlockError> {
    let bad = |m: String| TruthBlockError::Layout(m);
    if b.len() < FIXED_LEN + 4 {
        return Err(bad(format!("{} bytes, at least {} needed", b.len(), FIXED_LEN + 4)));
    }
    let (body, tail) = b.split_at(b.len() - 4);
    let found = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
    let computed = BLOCK_CRC.checksum(body);
    if found != computed {
        return Err(TruthBlockError::Crc { found, computed });
    }
    let n = width as usize * height as usize;
    let count = u16::from_le_bytes([body[0], body[1]]);
    let pixels = le_u64(body, 8);
    let f64_at = |i| f64::from_le_bytes(body[i..i + 8].try_into().expect("8 bytes"));
    let u32_at = |i: usize| u32::from_le_bytes(body[i..i + 4].try_into().expect("4 bytes"));
    let footprint = (pixels > 0).then(|| Footprint {
        centroid_px: [f64_at(16), f64_at(24)],
        bbox_px: [u32_at(32), u32_at(36), u32_at(40), u32_at(44)],
        pixels,
    });
    let mut image = TruthImage {
        width,
        height,
        channels: TruthChannels::NONE,
        mask: Vec::new(),
        materials: None,
        depth: Vec::new(),
        normal: Default::default(),
        body_xyz: Default::default(),
    };
    let mut at = FIXED_LEN;
    for k in 0..count {
        let item = body.get(at..at + ITEM_HEADER_LEN).ok_or_else(|| bad(format!("item {k} runs past the end")))?;
        let (id, ty, comps, len) = (u16::from_le_bytes([item[0], item[1]]), item[2], item[3], le_u64(item, 8));
        let start = at + ITEM_HEADER_LEN;
        let data = usize::try_from(len)
            .ok()
            .and_then(|len| body.get(start..start.checked_add(len)?))
            .ok_or_else(|| bad(format!("item {k} (channel {id}): {len} data bytes run past the end")))?;
        at = start + data.len();
        if id == MATERIALS_ID {
            let text = std::str::from_utf8(data)
                .ok()
                .filter(|t| (ty, comps) == (TEXT, 1) && t.len() <= MATERIALS_MAX_LEN && t.is_ascii())
                .ok_or_else(|| {
                    bad(format!("item {k} (materials): not a table of ASCII text of at most {MATERIALS_MAX_LEN} bytes"))
                })?;
            image.materials = Some(text.into());
            continue;
        }
        let Some(c) = TruthChannel::ALL.into_iter().find(|&c| channel_id(c) == id) else { continue };
        if (ty, comps) != layout(c) || data.len() != n * 4 * comps as usize {
            return Err(bad(format!(
                "channel {} (id {id}): type {ty} x{comps}, {} bytes; {width}x{height} needs type {} x{} and {} bytes",
                c.name(),
                data.len(),
                layout(c).0,
                layout(c).1,
                n * 4 * layout(c).1 as usize
            )));
        }
        let f32s = |d: &[u8]| d.chunks_exact(4).map(|w| f32::from_le_bytes(w.try_into().expect("4"))).collect();
        let planes = |d: &[u8]| -> [Vec<f32>; 3] {
            let p = n * 4;
            [f32s(&d[..p]), f32s(&d[p..2 * p]), f32s(&d[2 * p..])]
        };
        match c {
            TruthChannel::Depth => image.depth = f32s(data),
            TruthChannel::Mask => {
                image.mask = data.chunks_exact(4).map(|w| u32::from_le_bytes(w.try_into().expect("4"))).collect()
            }
            TruthChannel::Normal => image.normal = planes(data),
            TruthChannel::BodyXyz => image.body_xyz = planes(data),
        }
        image.channels = image.channels.with(c);
    }
    Ok(WireTruth { image, footprint })
}

/// [`decode_truth_block`] for the frame `meta` describes, its failure named by frame as a
/// stream error (what a receiver counts).
pub fn decode_frame_truth(meta: &super::FrameMeta, b: &[u8]) -> Result<WireTruth, Malformed> {
    decode_truth_block(meta.width, meta.height, b)
        .map_err(|e| Malformed::TruthBlock { seq: meta.frame_seq, message: e.to_string() })
}

/// Check a `truth_len` read off the stream before anything is allocated for it.
pub fn check_truth_len(width: u32, height: u32, truth_len: u64) -> Result<(), Malformed> {
    let limit = max_truth_len(width, height);
    if truth_len > limit {
        return Err(Malformed::TruthLen { found: truth_len, limit, width, height });
    }
    Ok(())
}

impl Frame {
    /// Header (version 2, flag [`FrameFlags::TRUTH`]) + payload + `truth_len` + the truth
    /// block, as one buffer; the truth also travels beside the bytes for the sinks that
    /// write it (recorder) or re-encode it (GigE chunks).
    pub fn encode_with_truth(&self, truth: Arc<TruthImage>) -> EncodedFrame {
        let meta = super::FrameMeta { flags: self.meta.flags.with(FrameFlags::TRUTH), ..self.meta };
        let block = encode_truth_block(&truth);
        let bytes = self.encode_bytes(&meta, &[&(block.len() as u64).to_le_bytes(), &block]);
        EncodedFrame { meta, bytes, roi: None, truth: Some(truth), mc_noise: None }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image() -> TruthImage {
        let channels = TruthChannels::parse("depth,mask,normal,body_xyz").unwrap();
        TruthImage {
            width: 3,
            height: 1,
            channels,
            mask: vec![0, 2, 1],
            materials: Some("1=gold;2=paint".into()),
            depth: vec![f32::INFINITY, 5.0, 5.5],
            normal: [vec![f32::NAN, 0.0, 0.1], vec![f32::NAN, 0.0, 0.2], vec![f32::NAN, -1.0, -0.9]],
            body_xyz: [vec![f32::NAN, 1.0, 2.0], vec![f32::NAN, 3.0, 4.0], vec![f32::NAN, 5.0, 6.0]],
        }
    }

    #[test]
    fn a_block_decodes_to_the_channels_and_footprint_it_was_encoded_from() {
        let t = image();
        let b = encode_truth_block(&t);
        assert_eq!(b.len(), FIXED_LEN + 5 * ITEM_HEADER_LEN + 3 * 4 * 8 + "1=gold;2=paint".len() + 4);
        let w = decode_truth_block(3, 1, &b).unwrap();
        assert_eq!(w.footprint, t.footprint());
        assert_eq!(w.image.materials.as_deref(), Some("1=gold;2=paint"));
        assert_eq!((w.image.channels, &w.image.mask, &w.image.depth), (t.channels, &t.mask, &t.depth));
        // NaN ≠ NaN: compare the bits.
        let bits = |p: &[Vec<f32>; 3]| p.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&w.image.normal), bits(&t.normal));
        assert_eq!(bits(&w.image.body_xyz), bits(&t.body_xyz));
    }

    #[test]
    fn a_flipped_bit_or_a_wrong_size_is_refused_and_unknown_channels_are_skipped() {
        let t = TruthImage { channels: TruthChannels::parse("depth").unwrap(), ..image() };
        let mut b = encode_truth_block(&t);
        b[FIXED_LEN + ITEM_HEADER_LEN] ^= 1;
        assert!(matches!(decode_truth_block(3, 1, &b), Err(TruthBlockError::Crc { .. })));
        let b = encode_truth_block(&t);
        assert!(matches!(decode_truth_block(4, 1, &b), Err(TruthBlockError::Layout(_))));
        // Channel id 99 (a newer sender's): skipped, the footprint still read.
        let mut b = encode_truth_block(&t);
        b.truncate(b.len() - 4);
        b[FIXED_LEN] = 99;
        let crc = BLOCK_CRC.checksum(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        let w = decode_truth_block(3, 1, &b).unwrap();
        assert!(w.image.channels.is_empty() && w.image.depth.is_empty());
        assert_eq!(w.footprint.unwrap().pixels, 2);
        assert!(check_truth_len(3, 1, max_truth_len(3, 1) + 1).is_err());
    }
}
