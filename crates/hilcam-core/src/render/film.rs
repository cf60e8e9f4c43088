//! Radiance images (W·sr⁻¹·m⁻² in the band), pixel buffers, and writing them to files.
//!
//! The file extension picks the format: `.exr` and `.pfm` keep float32 values exactly;
//! `.png` (8- or 16-bit) and `.tif`/`.tiff` (16-bit) hold integer pixels. A float image
//! written to an integer format is a *preview*, scaled so that `scale` maps to full white.

use std::io::Write;
use std::path::{Path, PathBuf};

/// How the payload's pixels are encoded (little-endian, row-major, no padding).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PixelFormat {
    Mono8,
    /// 16-bit container; the sensor's bit depth (10/12/16) is in the metadata.
    Mono16,
    /// Entrance-pupil radiance, W·sr⁻¹·m⁻², f32.
    Float32,
}

impl PixelFormat {
    /// The wire code (header byte 56).
    pub fn code(self) -> u8 {
        match self {
            PixelFormat::Mono8 => 1,
            PixelFormat::Mono16 => 2,
            PixelFormat::Float32 => 3,
        }
    }

    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(PixelFormat::Mono8),
            2 => Some(PixelFormat::Mono16),
            3 => Some(PixelFormat::Float32),
            _ => None,
        }
    }

    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Mono8 => 1,
            PixelFormat::Mono16 => 2,
            PixelFormat::Float32 => 4,
        }
    }

    /// Significant bit depths a header may carry for this format.
    pub(crate) fn valid_bits(self, bits: u8) -> bool {
        match self {
            PixelFormat::Mono8 => (1..=8).contains(&bits),
            PixelFormat::Mono16 => (1..=16).contains(&bits),
            PixelFormat::Float32 => bits == 32,
        }
    }
}

/// A single-channel float image, row-major, `data[row * width + col]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RadianceImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl RadianceImage {
    /// # Panics
    /// When `width × height` overflows `usize` (only on a 32-bit target; callers bound
    /// both sides by `camera::MAX_SIDE_PX`).
    pub fn new(width: u32, height: u32, fill: f32) -> Self {
        let n = (width as usize).checked_mul(height as usize).expect("image size overflows usize");
        RadianceImage { width, height, data: vec![fill; n] }
    }

    pub fn get(&self, col: u32, row: u32) -> f32 {
        self.data[row as usize * self.width as usize + col as usize]
    }

    /// The value a preview maps to full white: the 99.9th percentile of the non-zero
    /// pixels, so that a few glints do not turn the rest of the image black.
    pub fn preview_scale(&self) -> f32 {
        preview_white(self.data.iter().copied())
    }
}

/// The value a preview maps to full white, of any image's values: the 99.9th percentile
/// of the finite non-zero ones (1 when there are none). `hilcam render`'s 8-bit PNG and
/// the live view (`serve`'s `[live]`) both scale by it.
pub fn preview_white(values: impl Iterator<Item = f32>) -> f32 {
    let mut v: Vec<f32> = values.filter(|x| *x > 0.0 && x.is_finite()).collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = ((v.len() as f64 * 0.999) as usize).min(v.len() - 1);
    let (_, x, _) = v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *x
}

/// Pixels of one frame in one of the streamable formats.
#[derive(Clone, Debug, PartialEq)]
pub enum Pixels {
    Mono8(Vec<u8>),
    /// Values in a 16-bit container; `bits` (8..=16) is the sensor's significant depth.
    Mono16 {
        data: Vec<u16>,
        bits: u8,
    },
    Float32(Vec<f32>),
}

impl Pixels {
    /// `window` of an image `width` columns wide (`window` inside it), row by row.
    pub fn crop(&self, width: u32, window: &crate::render::camera::Window) -> Pixels {
        fn rows<T: Copy>(v: &[T], width: u32, w: &crate::render::camera::Window) -> Vec<T> {
            let (x, n, stride) = (w.x as usize, w.width as usize, width as usize);
            let mut out = Vec::with_capacity(n * w.height as usize);
            for row in w.y as usize..(w.y + w.height) as usize {
                out.extend_from_slice(&v[row * stride + x..row * stride + x + n]);
            }
            out
        }
        match self {
            Pixels::Mono8(v) => Pixels::Mono8(rows(v, width, window)),
            Pixels::Mono16 { data, bits } => Pixels::Mono16 { data: rows(data, width, window), bits: *bits },
            Pixels::Float32(v) => Pixels::Float32(rows(v, width, window)),
        }
    }

    pub fn format(&self) -> PixelFormat {
        match self {
            Pixels::Mono8(_) => PixelFormat::Mono8,
            Pixels::Mono16 { .. } => PixelFormat::Mono16,
            Pixels::Float32(_) => PixelFormat::Float32,
        }
    }

    pub fn len(&self) -> usize {
        match self {
            Pixels::Mono8(d) => d.len(),
            Pixels::Mono16 { data, .. } => data.len(),
            Pixels::Float32(d) => d.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Little-endian bytes, row-major, no padding (the wire and recorder layout).
    pub fn to_le_bytes(&self) -> Vec<u8> {
        match self {
            Pixels::Mono8(d) => d.clone(),
            Pixels::Mono16 { data, .. } => data.iter().flat_map(|v| v.to_le_bytes()).collect(),
            Pixels::Float32(d) => d.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }
}

/// Errors from writing image files; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageWriteError {
    #[error("{path}: unsupported extension (use .exr, .pfm, .png, .tif or .tiff)")]
    UnsupportedExtension { path: PathBuf },
    #[error("{path}: {what} cannot hold {format:?} pixels")]
    FormatMismatch { path: PathBuf, what: &'static str, format: PixelFormat },
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: {source}")]
    Image { path: PathBuf, source: image::ImageError },
    #[error("{path}: {message}")]
    Exr { path: PathBuf, message: String },
    #[error("{path}: {len} pixel values do not make a {width}x{height} image")]
    Size { path: PathBuf, width: u32, height: u32, len: usize },
}

/// What a write did: for an integer preview of float data, the radiance mapped to white.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WriteInfo {
    pub preview_scale: Option<f32>,
}

/// Write a radiance image; `.exr`/`.pfm` exactly, `.png` (8-bit) / `.tif` (16-bit) as a
/// preview scaled by [`RadianceImage::preview_scale`] unless `scale` is given.
pub fn write_radiance(
    path: &Path,
    img: &RadianceImage,
    scale: Option<f32>,
    png16: bool,
) -> Result<WriteInfo, ImageWriteError> {
    match ext(path).as_str() {
        "exr" | "pfm" => {
            write_pixels(path, img.width, img.height, &Pixels::Float32(img.data.clone()))?;
            Ok(WriteInfo { preview_scale: None })
        }
        e @ ("png" | "tif" | "tiff") => {
            let s = scale.unwrap_or_else(|| img.preview_scale());
            let sixteen = png16 || e != "png";
            let px = if sixteen {
                let data = img.data.iter().map(|v| ((v / s).clamp(0.0, 1.0) * 65535.0).round() as u16).collect();
                Pixels::Mono16 { data, bits: 16 }
            } else {
                Pixels::Mono8(img.data.iter().map(|v| ((v / s).clamp(0.0, 1.0) * 255.0).round() as u8).collect())
            };
            write_pixels(path, img.width, img.height, &px)?;
            Ok(WriteInfo { preview_scale: Some(s) })
        }
        _ => Err(ImageWriteError::UnsupportedExtension { path: path.to_path_buf() }),
    }
}

/// Write pixels in the format the extension names. Mono16 values are written as stored
/// (a 12-bit sensor's DN stay 0..4095 in the 16-bit file). The file appears whole or not
/// at all: see [`write_file_atomically`].
pub fn write_pixels(path: &Path, width: u32, height: u32, px: &Pixels) -> Result<(), ImageWriteError> {
    let bytes = encode_pixels(path, width, height, px)?;
    write_file_atomically(path, &bytes).map_err(|source| ImageWriteError::Io { path: path.to_path_buf(), source })
}

/// The file bytes of `px` in the format `path`'s extension names (encoded in memory, so
/// that every write error surfaces at [`write_file_atomically`]).
fn encode_pixels(path: &Path, width: u32, height: u32, px: &Pixels) -> Result<Vec<u8>, ImageWriteError> {
    let p = || path.to_path_buf();
    let img_err = |source| ImageWriteError::Image { path: p(), source };
    let mut out = std::io::Cursor::new(Vec::new());
    if u64::from(width) * u64::from(height) != px.len() as u64 {
        return Err(ImageWriteError::Size { path: p(), width, height, len: px.len() });
    }
    use image::ImageFormat::{Png, Tiff};
    match (ext(path).as_str(), px) {
        ("png", Pixels::Mono8(d)) => image::GrayImage::from_raw(width, height, d.clone())
            .expect("size checked above")
            .write_to(&mut out, Png)
            .map_err(img_err)?,
        (e @ ("png" | "tif" | "tiff"), Pixels::Mono16 { data, .. }) => {
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(width, height, data.clone())
                .expect("size checked above")
                .write_to(&mut out, if e == "png" { Png } else { Tiff })
                .map_err(img_err)?
        }
        ("tif" | "tiff", Pixels::Mono8(d)) => image::GrayImage::from_raw(width, height, d.clone())
            .expect("size checked above")
            .write_to(&mut out, Tiff)
            .map_err(img_err)?,
        ("pfm", Pixels::Float32(d)) => return Ok(encode_pfm(width, height, d)),
        ("exr", Pixels::Float32(d)) => encode_exr(path, width, height, d, &mut out)?,
        ("exr" | "pfm", other) => {
            return Err(ImageWriteError::FormatMismatch {
                path: p(),
                what: "a float image file",
                format: other.format(),
            });
        }
        ("png" | "tif" | "tiff", other) => {
            return Err(ImageWriteError::FormatMismatch {
                path: p(),
                what: "an integer image file",
                format: other.format(),
            });
        }
        _ => return Err(ImageWriteError::UnsupportedExtension { path: p() }),
    }
    Ok(out.into_inner())
}

/// Write `bytes` to `path` so that the file is either complete or absent: into a hidden
/// temporary file in the same directory (same filesystem), renamed over `path` once
/// every byte is written; on any error the temporary file is removed. A full disk thus
/// leaves no empty or truncated file behind, and a reader never sees half a file. (No
/// fsync: this guards against write errors and readers, not against power loss.)
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("file");
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let tmp = path.with_file_name(format!(".{name}.{}-{n}{TEMP_SUFFIX}", std::process::id()));
    let written = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .and_then(|mut f| f.write_all(bytes))
        .and_then(|_| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// How [`write_file_atomically`]'s temporary files end (`.<name>.<pid>-<n>.tmp`).
pub const TEMP_SUFFIX: &str = ".tmp";

impl ImageWriteError {
    /// The write failed because the filesystem is full (ENOSPC) or over quota (EDQUOT).
    pub fn is_disk_full(&self) -> bool {
        match self {
            ImageWriteError::Io { source, .. } => is_disk_full(source),
            _ => false,
        }
    }
}

/// ENOSPC or EDQUOT: no room to write, until space is freed.
pub fn is_disk_full(e: &std::io::Error) -> bool {
    matches!(e.kind(), std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded)
}

fn ext(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// Portable float map, greyscale (`Pf`), little-endian (negative scale), rows bottom-to-top.
fn encode_pfm(width: u32, height: u32, data: &[f32]) -> Vec<u8> {
    let mut out = format!("Pf\n{width} {height}\n-1.0\n").into_bytes();
    out.reserve(data.len() * 4);
    for row in (0..height as usize).rev() {
        for v in &data[row * width as usize..(row + 1) * width as usize] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Read a greyscale PFM written by [`write_pixels`] (either endianness) back into a radiance image.
pub fn read_pfm(path: &Path) -> std::io::Result<RadianceImage> {
    let bytes = std::fs::read(path)?;
    let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("{}: {m}", path.display()));
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err(bad("truncated header"));
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).to_string());
    }
    pos += 1; // the single whitespace byte after the scale
    if fields[0] != "Pf" {
        return Err(bad("not a greyscale PFM (Pf)"));
    }
    let w: u32 = fields[1].parse().map_err(|_| bad("bad width"))?;
    let h: u32 = fields[2].parse().map_err(|_| bad("bad height"))?;
    for (field, v) in [("width", w), ("height", h)] {
        crate::render::camera::check_side(v).map_err(|m| bad(&format!("{field} {m}")))?;
    }
    let little = fields[3].parse::<f32>().map_err(|_| bad("bad scale"))? < 0.0;
    let n = (w as usize).checked_mul(h as usize).ok_or_else(|| bad("size overflows"))?;
    let end = n.checked_mul(4).and_then(|b| b.checked_add(pos)).ok_or_else(|| bad("size overflows"))?;
    if bytes.len() < end {
        return Err(bad("truncated pixel data"));
    }
    let mut img = RadianceImage::new(w, h, 0.0);
    for (i, c) in bytes[pos..pos + 4 * n].chunks_exact(4).enumerate() {
        let b = [c[0], c[1], c[2], c[3]];
        let v = if little { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) };
        let (row, col) = (h as usize - 1 - i / w as usize, i % w as usize);
        img.data[row * w as usize + col] = v;
    }
    Ok(img)
}

/// Single-channel ("Y") float32 EXR: the `image` crate only writes RGB(A) EXR.
fn encode_exr(
    path: &Path,
    width: u32,
    height: u32,
    data: &[f32],
    out: &mut std::io::Cursor<Vec<u8>>,
) -> Result<(), ImageWriteError> {
    use exr::prelude::*;
    let w = width as usize;
    let channels =
        SpecificChannels::build().with_channel("Y").with_pixel_fn(|pos: Vec2<usize>| (data[pos.y() * w + pos.x()],));
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::named("radiance"),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    Image::from_layer(layer)
        .write()
        .to_buffered(out)
        .map_err(|e| ImageWriteError::Exr { path: path.to_path_buf(), message: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_that_do_not_fill_the_size_are_an_error_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.png");
        let e = write_pixels(&path, 4, 4, &Pixels::Mono8(vec![0; 3])).unwrap_err();
        assert_eq!(e.to_string(), format!("{}: 3 pixel values do not make a 4x4 image", path.display()));
        assert!(!path.exists());
    }

    #[test]
    fn pfm_round_trips_exactly_and_rows_are_top_first() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.pfm");
        let mut img = RadianceImage::new(3, 2, 0.0);
        img.data = vec![1.0, 2.0, 3.0, 4.5, f32::MIN_POSITIVE, 1e30];
        write_radiance(&p, &img, None, false).unwrap();
        assert_eq!(read_pfm(&p).unwrap(), img);
    }

    #[test]
    fn png_preview_maps_scale_to_white_and_reports_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let mut img = RadianceImage::new(2, 1, 0.0);
        img.data = vec![5.0, 10.0];
        let info = write_radiance(&p, &img, Some(10.0), false).unwrap();
        assert_eq!(info.preview_scale, Some(10.0));
        let back = image::open(&p).unwrap().into_luma8();
        assert_eq!(back.as_raw(), &vec![128u8, 255]);
    }

    #[test]
    fn exr_and_tiff_write_and_wrong_pairs_are_named_errors() {
        let dir = tempfile::tempdir().unwrap();
        let img = RadianceImage::new(4, 4, 2.0);
        write_radiance(&dir.path().join("a.exr"), &img, None, false).unwrap();
        write_radiance(&dir.path().join("a.tiff"), &img, None, false).unwrap();
        let e = write_pixels(&dir.path().join("b.exr"), 1, 1, &Pixels::Mono8(vec![1])).unwrap_err();
        assert!(e.to_string().contains("b.exr"), "{e}");
        let e = write_radiance(&dir.path().join("c.jpg"), &img, None, false).unwrap_err();
        assert!(e.to_string().contains("c.jpg"), "{e}");
    }
}
