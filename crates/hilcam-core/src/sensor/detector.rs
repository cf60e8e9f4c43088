//! The photo-detector: expected charge → collected electrons (fixed pattern, shot
//! noise, full well) → voltage-equivalent electrons (read noise).

use super::config::DetectorConfig;
use super::noise;
use crate::render::sampling::Rng;
use rayon::prelude::*;
use std::sync::Arc;

/// Fixed-pattern maps up to this many pixels (8 bytes each) are computed once and
/// cached; larger arrays (the 81-Mpixel paper camera) recompute them per frame.
pub const FPN_CACHE_MAX_PIXELS: usize = 1 << 24;

/// The sensor's fixed pattern: two standard normal values per pixel (PRNU, DSNU), a pure
/// function of (`fpn_seed`, pixel). Cached or computed on the fly, with the same values.
#[derive(Clone, Debug, PartialEq)]
pub struct FixedPattern {
    seed: u64,
    map: Option<Arc<Vec<[f32; 2]>>>,
}

impl FixedPattern {
    pub fn new(seed: u64, pixels: usize) -> Self {
        let map = (pixels <= FPN_CACHE_MAX_PIXELS)
            .then(|| Arc::new((0..pixels as u64).into_par_iter().map(|p| Self::compute(seed, p)).collect()));
        FixedPattern { seed, map }
    }

    #[inline]
    fn compute(seed: u64, pixel: u64) -> [f32; 2] {
        let (a, b) = noise::normal_pair(&mut noise::fixed_pattern_rng(seed, pixel));
        [a as f32, b as f32]
    }

    /// The (PRNU, DSNU) normal values of `pixel`.
    #[inline]
    pub fn z(&self, pixel: u64) -> [f32; 2] {
        match &self.map {
            Some(m) => m[pixel as usize],
            None => Self::compute(self.seed, pixel),
        }
    }
}

/// The detector's per-pixel parameters, resolved from the config once per frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Detector {
    /// Photo-electrons per unit radiance (W·sr⁻¹·m⁻², after the optics) over the
    /// integration time.
    pub e_per_radiance: f64,
    /// Mean dark charge over the integration time, e⁻.
    pub dark_e: f64,
    /// Rms dark-charge non-uniformity over the integration time, e⁻.
    pub dsnu_e: f64,
    pub prnu: f64,
    /// Present when PRNU or DSNU is configured.
    pub fixed_pattern: Option<FixedPattern>,
    pub shot_noise: bool,
    pub full_well_e: Option<f64>,
    pub read_noise_e: f64,
}

/// The charge of one pixel at each stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelCharge {
    /// Expected (noise-free) photo + dark charge, before the full-well clip, e⁻.
    pub expected_e: f64,
    /// Collected charge after shot noise and the full-well clip, e⁻.
    pub collected_e: f64,
    /// True when the well was full.
    pub full: bool,
    /// Collected charge plus read noise, in electrons (the ADC's input).
    pub read_e: f64,
}

impl Detector {
    /// Resolve the config for one integration time; `e_per_radiance_s` comes from
    /// [`super::optics::electrons_per_radiance_second`]; `fixed_pattern` from
    /// [`FixedPattern::new`] (needed only when PRNU or DSNU is configured).
    pub fn new(
        cfg: &DetectorConfig,
        e_per_radiance_s: f64,
        integration_time_s: f64,
        fixed_pattern: Option<FixedPattern>,
    ) -> Self {
        let t = integration_time_s;
        Detector {
            e_per_radiance: e_per_radiance_s * t,
            dark_e: cfg.dark_current_e_per_s.unwrap_or(0.0) * t,
            dsnu_e: cfg.dsnu_e_per_s.unwrap_or(0.0) * t,
            prnu: cfg.prnu.unwrap_or(0.0),
            fixed_pattern,
            shot_noise: cfg.shot_noise,
            full_well_e: cfg.full_well_e,
            read_noise_e: cfg.read_noise_e.unwrap_or(0.0),
        }
    }

    /// Expected charge of `pixel` (index row·width + col) under `radiance`, with the
    /// fixed pattern: `L·k·(1 + PRNU·z₁) + max(0, dark + DSNU·z₂)`. The pattern is a pure
    /// function of (`fpn_seed`, pixel), identical in every frame.
    #[inline]
    pub fn expected(&self, radiance: f64, pixel: u64) -> f64 {
        let (photo, dark) = self.expected_parts(radiance, pixel);
        photo + dark
    }

    /// [`Detector::expected`] as its (photo, dark) parts, e⁻.
    #[inline]
    pub fn expected_parts(&self, radiance: f64, pixel: u64) -> (f64, f64) {
        let mut photo = radiance.max(0.0) * self.e_per_radiance;
        let mut dark = self.dark_e;
        if let Some(fp) = &self.fixed_pattern {
            let [z1, z2] = fp.z(pixel);
            photo *= (1.0 + self.prnu * z1 as f64).max(0.0);
            dark = (dark + self.dsnu_e * z2 as f64).max(0.0);
        }
        (photo, dark)
    }

    /// Photo-electrons per unit radiance at `pixel`, PRNU included: the slope of
    /// [`Detector::expected`] in the radiance (for radiance ≥ 0).
    #[inline]
    pub fn photo_gain(&self, pixel: u64) -> f64 {
        match &self.fixed_pattern {
            Some(fp) => self.e_per_radiance * (1.0 + self.prnu * fp.z(pixel)[0] as f64).max(0.0),
            None => self.e_per_radiance,
        }
    }

    /// Sample the pixel's charge: Poisson shot noise (if on), full-well clip, then
    /// Gaussian read noise. `rng` is the pixel's frame stream.
    #[inline]
    pub fn sample(&self, expected_e: f64, rng: &mut Rng) -> PixelCharge {
        let need_normal = self.read_noise_e > 0.0 || (self.shot_noise && expected_e >= noise::POISSON_EXACT_BELOW);
        let (z_shot, z_read) = if need_normal { noise::normal_pair(rng) } else { (0.0, 0.0) };
        let e = if self.shot_noise { noise::poisson(expected_e, z_shot, rng) } else { expected_e };
        self.clip_and_read(expected_e, e, z_read)
    }

    /// [`Detector::sample`] for a pixel whose expected charge already carries Monte Carlo
    /// noise of variance `mc_var_e2` (e⁻², > 0): only the remaining shot-noise variance is
    /// drawn, Gaussian, `⌊λ + √max(0, λ − v − 1/12)·z + ½⌋` (the 1/12 is what rounding
    /// adds, as in [`noise::poisson_normal`]), so that Monte Carlo plus shot noise has the
    /// camera's variance λ wherever v ≤ λ. Shot noise must be on (validated).
    #[inline]
    pub fn sample_substituted(&self, expected_e: f64, mc_var_e2: f64, rng: &mut Rng) -> PixelCharge {
        let (z_shot, z_read) = noise::normal_pair(rng);
        let sd = (expected_e - mc_var_e2 - 1.0 / 12.0).max(0.0).sqrt();
        let e = super::adc::floor(expected_e + sd * z_shot + 0.5).max(0.0);
        self.clip_and_read(expected_e, e, z_read)
    }

    /// The collected charge `e` clipped at the full well, then read with noise `z_read`.
    #[inline]
    fn clip_and_read(&self, expected_e: f64, e: f64, z_read: f64) -> PixelCharge {
        let (e, full) = match self.full_well_e {
            Some(fw) if e >= fw => (fw, true),
            _ => (e, false),
        };
        PixelCharge { expected_e, collected_e: e, full, read_e: e + self.read_noise_e * z_read }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cached_and_recomputed_fixed_pattern_agree() {
        let cached = FixedPattern::new(7, 1000);
        let live = FixedPattern { seed: 7, map: None };
        for p in [0u64, 1, 500, 999] {
            assert_eq!(cached.z(p), live.z(p));
        }
        assert_ne!(cached.z(0), FixedPattern::new(8, 1).z(0));
    }
}
