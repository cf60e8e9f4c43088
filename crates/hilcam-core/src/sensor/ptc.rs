//! Photon transfer (EMVA 1288 style): recover a sensor's conversion gain and read noise
//! from flat fields, the way one characterises a real camera.
//!
//! For each radiance level two frames A, B with different seeds give the mean
//! `μ = (⟨A⟩ + ⟨B⟩)/2` and the temporal variance `σ² = var(A − B)/2` (the difference
//! cancels fixed-pattern noise). With `K = 1/gain` (DN per e⁻), shot noise gives
//! `σ² − σ²_dark = K (μ − μ_dark)`, and the dark frame `σ²_dark = K² σ²_read + 1/12`
//! (the last term is quantisation).

use super::{Sensor, SensorError};
use crate::render::film::{Pixels, RadianceImage};

/// One level of the photon-transfer curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PtcPoint {
    /// Flat-field radiance, W·sr⁻¹·m⁻².
    pub radiance: f64,
    /// Mean signal, DN (offset included).
    pub mean_dn: f64,
    /// Temporal variance, DN².
    pub var_dn: f64,
}

/// Gain and read noise fitted from a photon-transfer curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PtcFit {
    pub gain_e_per_dn: f64,
    /// Dark temporal noise referred to electrons (read noise plus dark-charge shot noise).
    pub read_noise_e: f64,
}

fn as_f64(px: &Pixels) -> Vec<f64> {
    match px {
        Pixels::Mono8(d) => d.iter().map(|v| *v as f64).collect(),
        Pixels::Mono16 { data, .. } => data.iter().map(|v| *v as f64).collect(),
        Pixels::Float32(d) => d.iter().map(|v| *v as f64).collect(),
    }
}

/// Measure one level from two frames (seeds `seed`, `seed + 1`).
pub fn measure(sensor: &Sensor, radiance: f64, seed: u64) -> Result<PtcPoint, SensorError> {
    let cam = sensor.camera();
    let img = RadianceImage::new(cam.width, cam.height, radiance as f32);
    let a = sensor.apply(&img, seed)?.pixels;
    let b = sensor.apply(&img, seed.wrapping_add(1))?.pixels;
    Ok(point_from_frames(radiance, &a, &b))
}

/// One level from two frames of the same scene taken with independent noise (for frames
/// made elsewhere, e.g. from renders with their own Monte Carlo noise).
pub fn point_from_frames(radiance: f64, a: &Pixels, b: &Pixels) -> PtcPoint {
    let (a, b) = (as_f64(a), as_f64(b));
    assert_eq!(a.len(), b.len(), "frame sizes");
    let n = a.len() as f64;
    let mean = (a.iter().sum::<f64>() + b.iter().sum::<f64>()) / (2.0 * n);
    let d: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
    let dm = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|v| (v - dm) * (v - dm)).sum::<f64>() / (n - 1.0) / 2.0;
    PtcPoint { radiance, mean_dn: mean, var_dn: var }
}

/// Fit `K` through the origin of (μ − μ_dark, σ² − σ²_dark) over `points` (which should
/// stay below saturation), and the read noise from `dark`.
pub fn fit(dark: &PtcPoint, points: &[PtcPoint]) -> PtcFit {
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for p in points {
        let x = p.mean_dn - dark.mean_dn;
        let y = p.var_dn - dark.var_dn;
        sxy += x * y;
        sxx += x * x;
    }
    let k = sxy / sxx;
    PtcFit { gain_e_per_dn: 1.0 / k, read_noise_e: (dark.var_dn - 1.0 / 12.0).max(0.0).sqrt() / k }
}
