//! The photo-detector: expected charge → collected electrons (fixed pattern, shot
//! noise, full well) → voltage-equivalent electrons (read noise).

use super::config::DetectorConfig;
use super::noise;
use crate::sampling::Rng;

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
    pub fpn_seed: u64,
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
    /// [`super::optics::electrons_per_radiance_second`].
    pub fn new(cfg: &DetectorConfig, e_per_radiance_s: f64, integration_time_s: f64) -> Self {
        let t = integration_time_s;
        Detector {
            e_per_radiance: e_per_radiance_s * t,
            dark_e: cfg.dark_current_e_per_s.unwrap_or(0.0) * t,
            dsnu_e: cfg.dsnu_e_per_s.unwrap_or(0.0) * t,
            prnu: cfg.prnu.unwrap_or(0.0),
            fpn_seed: cfg.fpn_seed,
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
        let mut photo = radiance.max(0.0) * self.e_per_radiance;
        let mut dark = self.dark_e;
        if self.prnu > 0.0 || self.dsnu_e > 0.0 {
            let (z1, z2) = noise::normal_pair(&mut noise::fixed_pattern_rng(self.fpn_seed, pixel));
            photo *= (1.0 + self.prnu * z1).max(0.0);
            dark = (dark + self.dsnu_e * z2).max(0.0);
        }
        photo + dark
    }

    /// Sample the pixel's charge: Poisson shot noise (if on), full-well clip, then
    /// Gaussian read noise. `rng` is the pixel's frame stream.
    #[inline]
    pub fn sample(&self, expected_e: f64, rng: &mut Rng) -> PixelCharge {
        let need_normal = self.read_noise_e > 0.0
            || (self.shot_noise && expected_e >= noise::POISSON_EXACT_BELOW);
        let (z_shot, z_read) = if need_normal {
            noise::normal_pair(rng)
        } else {
            (0.0, 0.0)
        };
        let mut e = if self.shot_noise {
            noise::poisson(expected_e, z_shot, rng)
        } else {
            expected_e
        };
        let mut full = false;
        if let Some(fw) = self.full_well_e
            && e >= fw
        {
            e = fw;
            full = true;
        }
        PixelCharge {
            expected_e,
            collected_e: e,
            full,
            read_e: e + self.read_noise_e * z_read,
        }
    }
}
