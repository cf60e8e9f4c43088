//! The camera at the real pixel geometry, and the transform from pose to render frame.
//!
//! Camera frame: +Z along the boresight, +X toward increasing column, +Y toward
//! increasing row. Pixel (col, row) centre lies at
//! `((col + 0.5) − W/2 − cx, (row + 0.5) − H/2 − cy) × pitch` on the focal plane, where
//! `(cx, cy)` is the principal point's offset from the array centre, in pixels.

pub mod distortion;
pub mod motion;
pub mod view;
pub mod window;

pub use motion::Motion;
use serde::Deserialize;
pub use view::{PartSphere, PixelRect, TargetBounds, View};
pub use window::{PixelKeys, Window};

/// Intrinsics of a pinhole camera, as read from `[camera]` in a scene or config file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraModel {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Pixel pitch, micrometres (square pixels).
    pub pitch_um: f64,
    /// Focal length, millimetres.
    pub focal_mm: f64,
    /// Principal point offset from the array centre, pixels (+x toward increasing column,
    /// +y toward increasing row).
    #[serde(default)]
    pub principal_point_px: [f64; 2],
}

/// Largest image side, pixels: 16384² float radiance is 1 GiB, the most one frame may
/// take. Every width and height (scene `[camera]`, camera files, `--width`/`--height`,
/// the serve config, a received frame header) is checked against it up front.
pub const MAX_SIDE_PX: u32 = 16384;

/// `Err` (the limit and the value; the caller names the field) unless `1 ≤ v ≤ MAX_SIDE_PX`.
pub fn check_side(v: u32) -> Result<(), String> {
    if (1..=MAX_SIDE_PX).contains(&v) { Ok(()) } else { Err(format!("must be in 1..={MAX_SIDE_PX} pixels, got {v}")) }
}

impl CameraModel {
    /// The same camera at another resolution, with the same field of view: `width` (or
    /// the width `height` implies at this aspect ratio) with the pitch scaled to match.
    pub fn scaled(&self, width: Option<u32>, height: Option<u32>) -> CameraModel {
        let Some(w) =
            width.or(height.map(|h| (f64::from(h) * f64::from(self.width) / f64::from(self.height)).round() as u32))
        else {
            return self.clone();
        };
        let k = f64::from(self.width) / f64::from(w);
        let h = height.unwrap_or_else(|| ((f64::from(self.height) / k).round() as u32).max(1));
        CameraModel {
            width: w.max(1),
            height: h,
            pitch_um: self.pitch_um * k,
            focal_mm: self.focal_mm,
            principal_point_px: self.principal_point_px.map(|v| v / k),
        }
    }

    /// Both sides within `1..=MAX_SIDE_PX`; the error names the field and the limit.
    pub fn check_size(&self) -> Result<(), (&'static str, String)> {
        check_side(self.width).map_err(|m| ("width", m))?;
        check_side(self.height).map_err(|m| ("height", m))
    }

    /// Focal length expressed in pixels.
    pub fn focal_px(&self) -> f64 {
        self.focal_mm * 1e-3 / (self.pitch_um * 1e-6)
    }
}
