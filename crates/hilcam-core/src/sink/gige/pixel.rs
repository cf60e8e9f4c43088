//! GigE Vision pixel formats (PFNC codes) and the conversion of a hilcam frame — the
//! sensor's digital numbers — into the ROI and format a client asked for. Pure.
//!
//! Every format is made from the same DN (one render, one sensor pass): Mono8 keeps
//! the top 8 bits, Mono10 / Mono12 are the DN as they are (LSB-aligned in 16 bits, as
//! PFNC defines them) when the ADC has that depth, Mono16 scales the DN to full scale
//! (`DN << (16 - bits)`). Pixels are little-endian, rows packed.

use crate::frame::{EncodedFrame, PixelFormat};
use crate::render::camera::Window;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GevPixelFormat {
    Mono8,
    Mono10,
    Mono12,
    Mono16,
}

impl GevPixelFormat {
    /// The PFNC code (PixelFormat register, GVSP leader).
    pub fn pfnc(self) -> u32 {
        match self {
            GevPixelFormat::Mono8 => 0x0108_0001,
            GevPixelFormat::Mono10 => 0x0110_0003,
            GevPixelFormat::Mono12 => 0x0110_0005,
            GevPixelFormat::Mono16 => 0x0110_0007,
        }
    }

    pub fn from_pfnc(code: u32) -> Option<Self> {
        [GevPixelFormat::Mono8, GevPixelFormat::Mono10, GevPixelFormat::Mono12, GevPixelFormat::Mono16]
            .into_iter()
            .find(|f| f.pfnc() == code)
    }

    pub fn name(self) -> &'static str {
        match self {
            GevPixelFormat::Mono8 => "Mono8",
            GevPixelFormat::Mono10 => "Mono10",
            GevPixelFormat::Mono12 => "Mono12",
            GevPixelFormat::Mono16 => "Mono16",
        }
    }

    pub fn bytes_per_pixel(self) -> usize {
        match self {
            GevPixelFormat::Mono8 => 1,
            _ => 2,
        }
    }

    /// Significant bits per pixel.
    pub fn bits(self) -> u8 {
        match self {
            GevPixelFormat::Mono8 => 8,
            GevPixelFormat::Mono10 => 10,
            GevPixelFormat::Mono12 => 12,
            GevPixelFormat::Mono16 => 16,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConvertError {
    #[error("frame {seq} is {format:?}: the GigE Vision stream sends the sensor's DN (Mono8/Mono16 frames)")]
    Format { seq: u64, format: PixelFormat },
    #[error("frame {seq} is {width}x{height}: ROI {roi_w}x{roi_h} at ({x}, {y}) is outside it")]
    Roi { seq: u64, width: u32, height: u32, roi_w: u32, roi_h: u32, x: u32, y: u32 },
    #[error("frame {seq} was rendered for the ROI {was:?}, the client now asks for {now:?}")]
    StaleRoi { seq: u64, was: Window, now: Window },
}

/// Shift a `from`-bit value to `to` bits (up or down).
fn rescale(v: u16, from: u8, to: u8) -> u16 {
    if to >= from { v << (to - from) } else { v >> (from - to) }
}

/// The ROI of `frame` in `format`, little-endian. A frame rendered for this ROI is sent
/// whole; one of the whole array is cropped at the offsets; one rendered for another ROI
/// (the client moved it while the frame rendered) is refused.
pub fn convert(frame: &EncodedFrame, roi: Window, format: GevPixelFormat) -> Result<Vec<u8>, ConvertError> {
    let m = &frame.meta;
    let (x0, y0) = if let Some(was) = frame.roi {
        if was != roi {
            return Err(ConvertError::StaleRoi { seq: m.frame_seq, was, now: roi });
        }
        (0, 0)
    } else if u64::from(roi.x) + u64::from(roi.width) <= u64::from(m.width)
        && u64::from(roi.y) + u64::from(roi.height) <= u64::from(m.height)
    {
        (roi.x, roi.y)
    } else {
        return Err(ConvertError::Roi {
            seq: m.frame_seq,
            width: m.width,
            height: m.height,
            roi_w: roi.width,
            roi_h: roi.height,
            x: roi.x,
            y: roi.y,
        });
    };
    let src_bpp = match m.format {
        PixelFormat::Mono8 => 1,
        PixelFormat::Mono16 => 2,
        PixelFormat::Float32 => return Err(ConvertError::Format { seq: m.frame_seq, format: m.format }),
    };
    let payload = frame.payload();
    let bits = m.bit_depth;
    let out_bpp = format.bytes_per_pixel();
    let mut out = Vec::with_capacity(roi.width as usize * roi.height as usize * out_bpp);
    let row_len = m.width as usize * src_bpp;
    for y in y0..y0 + roi.height {
        let row = &payload[y as usize * row_len..(y as usize + 1) * row_len];
        let px = &row[x0 as usize * src_bpp..(x0 + roi.width) as usize * src_bpp];
        match (src_bpp, format) {
            (1, GevPixelFormat::Mono8) => out.extend_from_slice(px),
            (1, f) => out.extend(px.iter().flat_map(|&b| rescale(u16::from(b), bits, f.bits()).to_le_bytes())),
            (_, GevPixelFormat::Mono8) => out
                .extend(px.chunks_exact(2).map(|c| rescale(u16::from_le_bytes([c[0], c[1]]), bits, 8).min(255) as u8)),
            (_, f) => out.extend(
                px.chunks_exact(2)
                    .flat_map(|c| rescale(u16::from_le_bytes([c[0], c[1]]), bits, f.bits()).to_le_bytes()),
            ),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{Frame, FrameFlags, FrameMeta};
    use crate::render::film::Pixels;
    use crate::render::integrator::Spp;

    pub(crate) fn frame12(w: u32, h: u32) -> EncodedFrame {
        let meta = FrameMeta {
            frame_seq: 3,
            pose_seq: 9,
            pose_t_ns: 0,
            pose_arrival_unix_ns: 0,
            emit_unix_ns: 0,
            width: w,
            height: h,
            format: PixelFormat::Mono16,
            bit_depth: 12,
            spp: Spp::from_milli(1000),
            depth: 1,
            integration_s: 0.0,
            line_time_ns: 0,
            flags: FrameFlags::default(),
        };
        let data = (0..w * h).map(|i| (i * 16 % 4096) as u16).collect();
        Frame::new(meta, Pixels::Mono16 { data, bits: 12 }).unwrap().encode()
    }

    #[test]
    fn formats_come_from_the_same_dn() {
        let f = frame12(4, 2);
        let full = Window { x: 0, y: 0, width: 4, height: 2 };
        let m12 = convert(&f, full, GevPixelFormat::Mono12).unwrap();
        assert_eq!(&m12[2..4], &16u16.to_le_bytes());
        let m16 = convert(&f, full, GevPixelFormat::Mono16).unwrap();
        assert_eq!(&m16[2..4], &256u16.to_le_bytes());
        let m8 = convert(&f, full, GevPixelFormat::Mono8).unwrap();
        assert_eq!(m8, vec![0, 1, 2, 3, 4, 5, 6, 7]);
    }

    #[test]
    fn roi_crops_a_whole_frame_passes_one_rendered_for_it_and_refuses_a_stale_one() {
        let f = frame12(4, 3);
        let roi = Window { x: 1, y: 1, width: 2, height: 2 };
        let m8 = convert(&f, roi, GevPixelFormat::Mono8).unwrap();
        assert_eq!(m8, vec![5, 6, 9, 10]);
        let small = EncodedFrame { roi: Some(roi), ..frame12(2, 2) };
        assert_eq!(convert(&small, roi, GevPixelFormat::Mono8).unwrap(), vec![0, 1, 2, 3], "rendered for it");
        let off = Window { x: 3, y: 0, width: 2, height: 2 };
        assert!(matches!(convert(&f, off, GevPixelFormat::Mono8), Err(ConvertError::Roi { .. })));
        let moved = Window { x: 0, ..roi };
        let e = convert(&small, moved, GevPixelFormat::Mono8).unwrap_err();
        assert!(matches!(e, ConvertError::StaleRoi { .. }), "rendered for another ROI: {e}");
    }
}
