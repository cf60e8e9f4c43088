//! A star field behind the target: point stars from a catalogue (right ascension,
//! declination, visual magnitude), placed by the camera's inertial attitude and added to
//! the radiance image before the sensor, so the optics, PSF, QE, integration and gain
//! turn each into DN like any radiance. `docs/stars.md` has the catalogue's provenance,
//! the zero point and the conventions.
//!
//! - [`catalogue`]: the CSV reader and magnitude → band irradiance.
//! - `deposit`: projection (through the lens distortion), occlusion by the target and the
//!   bilinear deposit.
//!
//! A star of band irradiance `E` (W/m², at the aperture) is deposited as the radiance
//! `E / Ω` spread over the four pixels nearest its image point, `Ω = (pitch / f)²` the
//! pixel's solid angle on the axis. The sensor turns radiance `L` into power per pixel
//! `L · pitch² · π / (4N²)` (`sensor::optics`), so the four pixels together receive
//! `E · f² π / (4N²) = E · A` with `A = π (f/N)² / 4` the aperture's area: the star's power.

pub mod catalogue;
mod deposit;

use glam::{DQuat, DVec3};

pub use catalogue::{StarCatalogueError, V_ZERO_FLUX_W_M2_NM, band_zero_point_w_m2};

/// One catalogue star.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Star {
    /// Harvard Revised (Bright Star) number, or the row's own number.
    pub hr: u32,
    /// Unit vector toward the star, inertial frame (J2000 equatorial: +X toward RA 0,
    /// Dec 0; +Z toward the north celestial pole).
    pub dir: DVec3,
    /// Johnson V magnitude.
    pub vmag: f64,
    /// Band irradiance at the aperture, W/m².
    pub irradiance_w_m2: f64,
}

/// The stars a scene draws behind its target.
#[derive(Clone, Debug)]
pub struct StarField {
    pub stars: Vec<Star>,
    /// Band irradiance of a V = 0 star, W/m².
    pub zero_point_w_m2: f64,
    /// Camera → inertial rotation for poses that carry none (the scene's `[pose]`).
    pub default_camera_to_inertial: DQuat,
}

/// What one frame's deposit did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StarStats {
    /// Stars whose image point fell on the image.
    pub in_view: u32,
    /// Of those, stars behind the target (not drawn).
    pub hidden: u32,
    /// Image rows written (`start..end`; empty when no star was drawn).
    pub rows: (u32, u32),
}

impl StarField {
    /// Unit vector toward right ascension `ra_deg`, declination `dec_deg` (inertial frame).
    pub fn direction(ra_deg: f64, dec_deg: f64) -> DVec3 {
        let (ra, dec) = (ra_deg.to_radians(), dec_deg.to_radians());
        DVec3::new(dec.cos() * ra.cos(), dec.cos() * ra.sin(), dec.sin())
    }

    /// Band irradiance of a star of visual magnitude `vmag`, W/m².
    pub fn irradiance_of(&self, vmag: f64) -> f64 {
        self.zero_point_w_m2 * 10f64.powf(-0.4 * vmag)
    }
}
