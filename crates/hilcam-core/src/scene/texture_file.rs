//! A texture a model file names (MTL `map_Kd`, glTF `baseColorTexture`, …), decoded with
//! the `image` crate into hilcam's band. A colour: each channel sRGB-decoded to linear
//! (before any filtering), multiplied by the material's factor (`Kd`,
//! `baseColorFactor`), and reduced to the band as the mean of the three (docs/scene.md,
//! "Colour to band"). A value (roughness, metallic): one channel, linear, times its
//! factor. Alpha is ignored (surfaces are opaque).
//!
//! A texture that cannot be used — an unresolved placeholder (`$texture.png`), a missing
//! file, an image that does not decode — is an `Err` naming the file and the place that
//! named it; the scene then warns and renders the material with its factor.

use crate::render::texture::{MipMap, Texture};
use std::path::PathBuf;

/// Where a texture's encoded image is.
#[derive(Clone, Debug, PartialEq)]
pub enum ImageSource {
    File(PathBuf),
    /// Bytes inside the model file (a GLB buffer view, a data URI); `name` for messages.
    Bytes {
        name: String,
        data: std::sync::Arc<[u8]>,
    },
}

/// A material's texture as its model file gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    pub source: ImageSource,
    /// The material's colour factor, linear r g b: multiplies the decoded texels.
    pub factor: [f32; 3],
    /// `None`: a colour (sRGB, each channel times `factor`'s, then the band mean);
    /// `Some(c)`: a value, the image's channel `c` read linearly (not sRGB) times
    /// `factor[0]` (glTF's metallic-roughness: G roughness, B metallic).
    pub channel: Option<usize>,
    /// Where it was named, for messages (`panel.mtl:5`, `sat.glb, material `cells``).
    pub at: String,
}

impl TextureRef {
    /// The image's name for messages and the load report.
    pub fn name(&self) -> String {
        match &self.source {
            ImageSource::File(p) => p.display().to_string(),
            ImageSource::Bytes { name, .. } => name.clone(),
        }
    }
}

/// sRGB-encoded `c` ∈ [0, 1] → linear (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Decode `r` into a band texture with its mip-map.
///
/// # Errors
/// Why it cannot be used, naming the image and where it was named.
pub fn load_texture(r: &TextureRef) -> Result<Texture, String> {
    let name = r.name();
    let img = match &r.source {
        ImageSource::File(p) => {
            if p.to_string_lossy().contains('$') {
                return Err(format!(
                    "texture `{name}` is an unresolved placeholder (the exporter did not fill in the file name): {}",
                    r.at
                ));
            }
            let bytes = std::fs::read(p).map_err(|e| format!("texture `{name}` cannot be read ({e}): {}", r.at))?;
            image::load_from_memory(&bytes)
        }
        ImageSource::Bytes { data, .. } => image::load_from_memory(data),
    }
    .map_err(|e| format!("texture `{name}` does not decode as an image ({e}): {}", r.at))?;
    let rgb = img.to_rgb32f();
    let (w, h) = rgb.dimensions();
    // A lookup table per 8-bit code would be exact only for 8-bit images; 16-bit and
    // float images are decoded per texel.
    let [fr, fg, fb] = r.factor;
    let data: Vec<f32> = match r.channel {
        None => rgb
            .pixels()
            .map(|p| (fr * srgb_to_linear(p[0]) + fg * srgb_to_linear(p[1]) + fb * srgb_to_linear(p[2])) / 3.0)
            .collect(),
        Some(c) => rgb.pixels().map(|p| fr * p[c.min(2)]).collect(),
    };
    Ok(Texture { name, mip: MipMap::new(w, h, data) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(w: u32, h: u32, rgb: &[u8]) -> std::sync::Arc<[u8]> {
        let mut out = Vec::new();
        image::RgbImage::from_raw(w, h, rgb.to_vec())
            .unwrap()
            .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
            .unwrap();
        out.into()
    }

    #[test]
    fn srgb_128_is_linear_0_2158_times_the_factor_band_mean() {
        let r = TextureRef {
            source: ImageSource::Bytes { name: "grey".into(), data: png(1, 1, &[128, 128, 128]) },
            factor: [0.2, 0.5, 0.8],
            channel: None,
            at: "here".into(),
        };
        let t = load_texture(&r).unwrap();
        let v = t.mip.levels[0].data[0];
        // ((128/255 + 0.055)/1.055)^2.4 = 0.21586; × band mean of the factor, 0.5.
        assert!((v - 0.21586 * 0.5).abs() < 1e-5, "{v}");
        assert_eq!(srgb_to_linear(1.0), 1.0);
        assert_eq!(srgb_to_linear(0.0), 0.0);
    }

    #[test]
    fn a_coloured_texel_multiplies_each_channel_before_the_band_mean() {
        let r = TextureRef {
            source: ImageSource::Bytes { name: "red".into(), data: png(1, 1, &[255, 0, 0]) },
            factor: [0.6, 1.0, 1.0],
            channel: None,
            at: "here".into(),
        };
        assert!((load_texture(&r).unwrap().mip.levels[0].data[0] - 0.2).abs() < 1e-6);
    }

    #[test]
    fn a_value_channel_is_read_linearly_times_the_factor() {
        // glTF's metallic-roughness image: G is roughness, B metallic, both linear.
        let data = png(1, 1, &[10, 128, 255]);
        let r = |channel, f| TextureRef {
            source: ImageSource::Bytes { name: "mr".into(), data: data.clone() },
            factor: [f; 3],
            channel: Some(channel),
            at: "here".into(),
        };
        assert!((load_texture(&r(1, 0.5)).unwrap().mip.levels[0].data[0] - 0.5 * 128.0 / 255.0).abs() < 1e-6);
        assert_eq!(load_texture(&r(2, 1.0)).unwrap().mip.levels[0].data[0], 1.0);
    }

    #[test]
    fn unusable_textures_are_errors_naming_image_and_place() {
        let at = "panel.mtl:5".to_string();
        let f = |p: &str| TextureRef {
            source: ImageSource::File(p.into()),
            factor: [1.0; 3],
            channel: None,
            at: at.clone(),
        };
        let e = load_texture(&f("/x/$texture.png")).unwrap_err();
        assert!(e.contains("placeholder") && e.contains("$texture.png") && e.ends_with("panel.mtl:5"), "{e}");
        let e = load_texture(&f("/no/such/cells.png")).unwrap_err();
        assert!(e.contains("cannot be read") && e.contains("cells.png") && e.ends_with("panel.mtl:5"), "{e}");
        let bad = TextureRef {
            source: ImageSource::Bytes { name: "junk".into(), data: b"not an image".to_vec().into() },
            factor: [1.0; 3],
            channel: None,
            at,
        };
        assert!(load_texture(&bad).unwrap_err().contains("does not decode"));
    }
}
