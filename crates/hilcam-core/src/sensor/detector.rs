//! The photo-detector: expected charge → collected electrons (fixed pattern, shot
//! noise, full well) → voltage-equivalent electrons (read noise).

use super::config::DetectorConfig;
use super::noise;
use super::stream::PixelNoise;
use super::ziggurat::{self, Ziggurat};
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
    map: Option<Arc<FpnMaps>>,
}

/// The cached pattern as two planes, so that a pass that needs only one reads only it.
#[derive(Debug, PartialEq)]
struct FpnMaps {
    prnu: Vec<f32>,
    dsnu: Vec<f32>,
    /// The largest DSNU value of any pixel (bounds every pixel's dark charge).
    dsnu_max: f32,
}

impl FixedPattern {
    pub fn new(seed: u64, pixels: usize) -> Self {
        let map = (pixels <= FPN_CACHE_MAX_PIXELS).then(|| {
            let z: Vec<[f32; 2]> = (0..pixels as u64).into_par_iter().map(|p| Self::compute(seed, p)).collect();
            let dsnu: Vec<f32> = z.iter().map(|z| z[1]).collect();
            let dsnu_max = dsnu.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            Arc::new(FpnMaps { prnu: z.iter().map(|z| z[0]).collect(), dsnu, dsnu_max })
        });
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
            Some(m) => [m.prnu[pixel as usize], m.dsnu[pixel as usize]],
            None => Self::compute(self.seed, pixel),
        }
    }

    /// The DSNU value of `pixel` alone.
    #[inline]
    pub fn z_dsnu(&self, pixel: u64) -> f32 {
        match &self.map {
            Some(m) => m.dsnu[pixel as usize],
            None => Self::compute(self.seed, pixel)[1],
        }
    }

    /// The DSNU values of pixels `first..first + n` (one sensor row's run), when the
    /// pattern is cached.
    #[inline]
    pub fn dsnu_run(&self, first: u64, n: usize) -> Option<&[f32]> {
        self.map.as_ref().map(|m| &m.dsnu[first as usize..first as usize + n])
    }

    /// The (PRNU, DSNU) values of pixels `first..first + n`, when the pattern is cached.
    #[inline]
    pub fn runs(&self, first: u64, n: usize) -> Option<(&[f32], &[f32])> {
        let r = first as usize..first as usize + n;
        self.map.as_ref().map(|m| (&m.prnu[r.clone()], &m.dsnu[r]))
    }

    /// The largest DSNU value of any pixel, when the pattern is cached.
    pub fn dsnu_max(&self) -> Option<f32> {
        self.map.as_ref().map(|m| m.dsnu_max)
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
    /// The normal variates' tables.
    zig: &'static Ziggurat,
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
            zig: ziggurat::tables(),
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
        match &self.fixed_pattern {
            Some(fp) => self.expected_parts_z(radiance, fp.z(pixel)),
            None => self.expected_parts_z(radiance, [0.0; 2]),
        }
    }

    /// [`Detector::expected_parts`] at a pixel whose fixed pattern is `z` (ignored
    /// without one).
    #[inline]
    pub fn expected_parts_z(&self, radiance: f64, z: [f32; 2]) -> (f64, f64) {
        let photo = radiance.max(0.0) * self.e_per_radiance;
        match &self.fixed_pattern {
            Some(_) => (photo * self.prnu_factor(z[0]), self.dark_z(z[1])),
            None => (photo, self.dark_e),
        }
    }

    /// `max(0, 1 + PRNU·z₁)`.
    #[inline]
    fn prnu_factor(&self, z1: f32) -> f64 {
        (1.0 + self.prnu * z1 as f64).max(0.0)
    }

    /// The mean dark charge of a pixel whose DSNU value is `z2`, e⁻ (with a fixed pattern).
    #[inline]
    pub fn dark_z(&self, z2: f32) -> f64 {
        (self.dark_e + self.dsnu_e * z2 as f64).max(0.0)
    }

    /// An upper bound of every pixel's mean dark charge, e⁻ (None when the pattern is
    /// not cached: then each pixel's must be computed).
    pub fn dark_max(&self) -> Option<f64> {
        match &self.fixed_pattern {
            Some(fp) => fp.dsnu_max().map(|z| self.dark_z(z)),
            None => Some(self.dark_e),
        }
    }

    /// Photo-electrons per unit radiance at `pixel`, PRNU included: the slope of
    /// [`Detector::expected`] in the radiance (for radiance ≥ 0).
    #[inline]
    pub fn photo_gain(&self, pixel: u64) -> f64 {
        match &self.fixed_pattern {
            Some(fp) => self.photo_gain_z(fp.z(pixel)[0]),
            None => self.e_per_radiance,
        }
    }

    /// [`Detector::photo_gain`] at a pixel whose PRNU value is `z1`.
    #[inline]
    pub fn photo_gain_z(&self, z1: f32) -> f64 {
        match &self.fixed_pattern {
            Some(_) => self.e_per_radiance * self.prnu_factor(z1),
            None => self.e_per_radiance,
        }
    }

    /// Sample the pixel's charge: Poisson shot noise (if on), full-well clip, then
    /// Gaussian read noise, from the pixel's frame streams `s`.
    #[inline(always)]
    pub fn sample(&self, expected_e: f64, s: &mut PixelNoise) -> PixelCharge {
        let e = if self.shot_noise { noise::poisson_with(self.zig, expected_e, &mut s.shot) } else { expected_e };
        self.clip_and_read(expected_e, e, s)
    }

    /// [`Detector::sample`] for a pixel whose expected charge already carries Monte Carlo
    /// noise of variance `mc_var_e2` (e⁻², > 0): only the remaining shot-noise variance is
    /// drawn, Gaussian, `⌊λ + √max(0, λ − v − 1/12)·z + ½⌋` (the 1/12 is what rounding
    /// adds, as in [`noise::poisson_normal`]), so that Monte Carlo plus shot noise has the
    /// camera's variance λ wherever v ≤ λ. Shot noise must be on (validated).
    #[inline]
    pub fn sample_substituted(&self, expected_e: f64, mc_var_e2: f64, s: &mut PixelNoise) -> PixelCharge {
        let z_shot = self.zig.normal(&mut s.shot);
        let sd = (expected_e - mc_var_e2 - 1.0 / 12.0).max(0.0).sqrt();
        let e = super::adc::floor(expected_e + sd * z_shot + 0.5).max(0.0);
        self.clip_and_read(expected_e, e, s)
    }

    /// The collected charge `e` clipped at the full well, then read with noise from the
    /// read stream of `s` (no draw without read noise).
    #[inline(always)]
    pub fn clip_and_read(&self, expected_e: f64, e: f64, s: &mut PixelNoise) -> PixelCharge {
        let (e, full) = match self.full_well_e {
            Some(fw) if e >= fw => (fw, true),
            _ => (e, false),
        };
        let read_e = if self.read_noise_e > 0.0 { e + self.read_noise_e * self.zig.normal(&mut s.read) } else { e };
        PixelCharge { expected_e, collected_e: e, full, read_e }
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
            assert_eq!(cached.z_dsnu(p), live.z(p)[1]);
        }
        let max = (0..1000).map(|p| live.z(p)[1]).fold(f32::MIN, f32::max);
        assert_eq!(cached.dsnu_max(), Some(max));
        assert_ne!(cached.z(0), FixedPattern::new(8, 1).z(0));
    }
}
