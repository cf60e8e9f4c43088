//! The camera at the real pixel geometry, and the transform from pose to render frame.
//!
//! Camera frame: +Z along the boresight, +X toward increasing column, +Y toward
//! increasing row. Pixel (col, row) centre lies at
//! `((col + 0.5) − W/2 − cx, (row + 0.5) − H/2 − cy) × pitch` on the focal plane, where
//! `(cx, cy)` is the principal point's offset from the array centre, in pixels.

pub mod distortion;
mod lens_spans;
pub mod silhouette;
pub mod view;

use serde::Deserialize;
pub use silhouette::{Silhouette, SilhouetteBuffers};
pub use view::{PixelRect, TargetBounds, View};

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

impl CameraModel {
    /// Focal length expressed in pixels.
    pub fn focal_px(&self) -> f64 {
        self.focal_mm * 1e-3 / (self.pitch_um * 1e-6)
    }
}
