//! Optics: radiance → focal-plane irradiance, natural vignetting, and the photon budget.
//!
//! For an object at infinity (every target of a navigation camera) an aplanatic lens of
//! working f-number `N` and transmittance `τ` turns entrance-pupil radiance `L` into
//! focal-plane irradiance `E = τ π L / (4 N²) · cos⁴θ` (W·m⁻²), θ the field angle.
//! `docs/sensor.md` derives the rest of the chain.

use super::config::{QeConfig, SensorConfig};
use crate::render::camera::CameraModel;

/// Planck constant, J·s (exact, SI 2019).
pub const PLANCK_H: f64 = 6.626_070_15e-34;
/// Speed of light, m/s (exact).
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;

/// Natural vignetting factor cos⁴θ at pixel (col, row) centre, θ the angle between the
/// pixel's line of sight and the optical axis (through the principal point).
#[inline]
pub fn cos4(camera: &CameraModel, col: u32, row: u32) -> f64 {
    let f = camera.focal_px();
    let x = (col as f64 + 0.5) - camera.width as f64 / 2.0 - camera.principal_point_px[0];
    let y = (row as f64 + 0.5) - camera.height as f64 / 2.0 - camera.principal_point_px[1];
    // cos²θ = f² / (f² + r²)
    let c2 = f * f / (f * f + x * x + y * y);
    c2 * c2
}

/// Band-mean of `QE(λ)·λ` (µm) and of `QE(λ)`, for a radiance spread evenly over the
/// band in wavelength (flat spectral radiance `L_λ = L / Δλ`). A curve is interpolated
/// linearly between its points and integrated with 4096 midpoint steps.
pub fn qe_band_means(qe: &QeConfig, min_um: f64, max_um: f64) -> (f64, f64) {
    match qe {
        QeConfig::Constant(q) => (q * 0.5 * (min_um + max_um), *q),
        QeConfig::Curve(pts) => {
            const STEPS: usize = 4096;
            let dl = (max_um - min_um) / STEPS as f64;
            let (mut ql, mut q) = (0.0, 0.0);
            for i in 0..STEPS {
                let l = min_um + (i as f64 + 0.5) * dl;
                let v = interp(pts, l);
                ql += v * l;
                q += v;
            }
            (ql / STEPS as f64, q / STEPS as f64)
        }
    }
}

/// Piecewise-linear interpolation, clamped at the ends.
fn interp(pts: &[[f64; 2]], x: f64) -> f64 {
    if x <= pts[0][0] {
        return pts[0][1];
    }
    for w in pts.windows(2) {
        if x <= w[1][0] {
            let t = (x - w[0][0]) / (w[1][0] - w[0][0]);
            return w[0][1] + t * (w[1][1] - w[0][1]);
        }
    }
    pts[pts.len() - 1][1]
}

/// Photo-electrons per second per pixel per unit (post-optics) radiance, W·sr⁻¹·m⁻²:
/// `π / (4N²) · pitch² · ⟨QE·λ⟩ / (h c)`. `None` unless the config has a detector
/// (validation guarantees the band and the aperture then).
pub fn electrons_per_radiance_second(cfg: &SensorConfig, camera: &CameraModel) -> Option<f64> {
    let det = cfg.detector.as_ref()?;
    let band = cfg.band.as_ref()?;
    let n = cfg.f_number(camera)?;
    let (qe_lambda_um, qe_mean) = qe_band_means(&det.qe, band.min_um, band.max_um);
    let qe_lambda_m = match det.effective_wavelength_um {
        Some(l) => qe_mean * l * 1e-6,
        None => qe_lambda_um * 1e-6,
    };
    let pitch_m = camera.pitch_um * 1e-6;
    let solid = std::f64::consts::PI / (4.0 * n * n);
    Some(solid * pitch_m * pitch_m * qe_lambda_m / (PLANCK_H * SPEED_OF_LIGHT))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curve_of_constant_equals_constant() {
        let c = QeConfig::Curve(vec![[0.4, 0.5], [0.8, 0.5]]);
        let (a, b) = qe_band_means(&c, 0.45, 0.75);
        let (a0, b0) = qe_band_means(&QeConfig::Constant(0.5), 0.45, 0.75);
        assert!((a - a0).abs() < 1e-12 && (b - b0).abs() < 1e-12);
    }

    #[test]
    fn linear_curve_band_mean_matches_closed_form() {
        // QE = λ over [0, 1] µm sampled on [0.5, 1]: ⟨QE·λ⟩ = ∫λ² / 0.5 = (1 − 1/8)/3/0.5.
        let c = QeConfig::Curve(vec![[0.0, 0.0], [1.0, 1.0]]);
        let (ql, q) = qe_band_means(&c, 0.5, 1.0);
        assert!((ql - (7.0 / 24.0) / 0.5).abs() < 1e-7, "{ql}");
        assert!((q - 0.75).abs() < 1e-12);
    }

    #[test]
    fn cos4_is_one_on_axis_and_matches_angle_off_axis() {
        let cam = CameraModel {
            width: 2,
            height: 2,
            pitch_um: 10.0,
            focal_mm: 0.01, // 1 px focal length: pixel centres at 45°·…
            principal_point_px: [0.0, 0.0],
        };
        // Pixel (1,1) centre is at (0.5, 0.5) px from the axis, f = 1 px.
        let th = (0.5f64.hypot(0.5)).atan();
        assert!((cos4(&cam, 1, 1) - th.cos().powi(4)).abs() < 1e-12);
    }
}
