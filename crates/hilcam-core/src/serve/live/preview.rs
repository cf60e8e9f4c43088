//! One frame → the live view's JPEG: shrunk by an integer box filter to at most
//! `max_width` columns, scaled like `hilcam render`'s 8-bit preview (the 99.9th
//! percentile of the frame's non-zero values is white, linear), encoded once.

use crate::render::film::{Pixels, preview_white};

/// An 8-bit grey preview.
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
    /// Frame columns per preview column (and rows per row): the box filter's side.
    pub factor: u32,
}

/// The smallest integer factor that brings `width` to at most `max_width` columns.
pub fn shrink_factor(width: u32, max_width: u32) -> u32 {
    width.div_ceil(max_width.max(1)).max(1)
}

/// `pixels` (`width` × `height`, any format) as an 8-bit preview at most `max_width`
/// wide. Each preview pixel is the mean of a `factor`² block (a ragged right/bottom edge
/// is cut off); white is [`preview_white`] of the full-resolution values, so a preview
/// and `hilcam render --out x.png` of the same radiance agree at `factor` 1.
pub fn preview(pixels: &Pixels, width: u32, height: u32, max_width: u32) -> PreviewImage {
    let values: Vec<f32> = match pixels {
        Pixels::Mono8(v) => v.iter().map(|&x| f32::from(x)).collect(),
        Pixels::Mono16 { data, .. } => data.iter().map(|&x| f32::from(x)).collect(),
        Pixels::Float32(v) => v.clone(),
    };
    let white = preview_white(values.iter().copied());
    let k = shrink_factor(width, max_width);
    let (w, h) = ((width / k).max(1), (height / k).max(1));
    let (k_cols, k_rows) = (k.min(width) as usize, k.min(height) as usize);
    let scale = 255.0 / (white * (k_cols * k_rows) as f32);
    let mut data = Vec::with_capacity(w as usize * h as usize);
    for row in 0..h as usize {
        for col in 0..w as usize {
            let mut sum = 0.0f32;
            for r in row * k_rows..(row + 1) * k_rows {
                let line = &values[r * width as usize..][col * k_cols..(col + 1) * k_cols];
                sum += line.iter().filter(|v| v.is_finite()).sum::<f32>();
            }
            data.push((sum * scale).clamp(0.0, 255.0).round() as u8);
        }
    }
    PreviewImage { width: w, height: h, data, factor: k }
}

/// Baseline JPEG of a grey preview at `quality` (1..=100).
pub fn jpeg(img: &PreviewImage, quality: u8) -> Result<Vec<u8>, image::ImageError> {
    let mut out = Vec::with_capacity(img.data.len() / 4);
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100)).encode(
        &img.data,
        img.width,
        img.height,
        image::ExtendedColorType::L8,
    )?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_is_the_smallest_that_fits() {
        assert_eq!(shrink_factor(1024, 512), 2);
        assert_eq!(shrink_factor(1000, 512), 2);
        assert_eq!(shrink_factor(1025, 512), 3);
        assert_eq!(shrink_factor(96, 512), 1);
    }

    #[test]
    fn full_size_matches_the_render_png_scaling() {
        // 1000 values 1..=1000: the 99.9th percentile (index 999 of 1000) is 1000.
        let v: Vec<f32> = (1..=1000).map(|i| i as f32).collect();
        let p = preview(&Pixels::Float32(v.clone()), 100, 10, 512);
        assert_eq!((p.width, p.height, p.factor), (100, 10, 1));
        for (out, x) in p.data.iter().zip(&v) {
            assert_eq!(*out, ((x / 1000.0) * 255.0).round() as u8);
        }
    }

    #[test]
    fn shrinking_averages_blocks() {
        // 4×2 → 2×1 at max_width 2: each output is the mean of a 2×2 block.
        let px = Pixels::Mono16 { data: vec![0, 100, 200, 200, 100, 200, 200, 200], bits: 12 };
        let p = preview(&px, 4, 2, 2);
        assert_eq!((p.width, p.height, p.factor), (2, 1, 2));
        // White is 200 (the 99.9th percentile of the non-zero values).
        assert_eq!(p.data, vec![(100.0f32 / 200.0 * 255.0).round() as u8, 255]);
    }

    #[test]
    fn jpeg_round_trips_within_compression_error() {
        let data: Vec<u8> = (0..64 * 64).map(|i| ((i % 64) * 4) as u8).collect();
        let img = PreviewImage { width: 64, height: 64, data: data.clone(), factor: 1 };
        let bytes = jpeg(&img, 90).unwrap();
        assert_eq!(&bytes[..2], &[0xFF, 0xD8], "a JPEG SOI marker");
        let back = image::load_from_memory(&bytes).unwrap().into_luma8();
        assert_eq!(back.dimensions(), (64, 64));
        // A smooth ramp at quality 90: a few DN of error at most.
        let worst = back.as_raw().iter().zip(&data).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
        assert!(worst <= 8, "worst error {worst}");
    }
}
