//! Samples per pixel for `quality = "sensor"`: as many as make the pixel as good as the
//! camera, within the frame's budget.
//!
//! A camera pixel holding S electrons fluctuates by √(S + dark + read²) from frame to
//! frame; a rendered pixel adds the Monte Carlo error of its mean, σ/√N for N samples of
//! per-sample standard deviation σ. The frame is "sensor-equivalent" at pixel p when
//! c·σₚ/√Nₚ ≤ k·σ_camera,ₚ (c: electrons per unit radiance there,
//! [`NoiseBound`]), i.e. when Nₚ ≥ c²σₚ² / (k²σ²_camera,ₚ).
//!
//! The frame starts as an adaptive frame does (`render::adaptive`): a pilot in every
//! pixel, here [`SensorPlan::PILOT`] samples (two, so that every pixel has a variance of
//! its own; a budget below it still spends the pilot). Each pixel's σₚ² and signal are then estimated from its eight
//! neighbours' pilots, never its own ([`neighbour_estimate`]): the count a pixel gets is
//! independent of its own samples, so its mean stays unbiased. Where the counts asked for
//! exceed the budget (`spp` per sampled pixel on average), every pixel's count is cut to a
//! common cap C, the largest that fits ("water-filling"): the cheap pixels all meet the
//! bound, the most expensive ones (edges, folds) get C samples and are reported as above
//! it.

use super::adaptive::{NeighbourEstimate, neighbour_estimate};
use super::camera::PixelKeys;
use super::integrator::Spp;
use super::noise_bound::NoiseBound;
use rayon::prelude::*;

/// No pixel gets more samples than this in one frame (the count is also held in a u32
/// and a sample index in the Sobol stream).
pub const MAX_SAMPLES: u32 = 4096;

/// The plan of one sensor-quality frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorPlan {
    pub bound: NoiseBound,
    /// Average samples per sampled pixel the frame may spend.
    pub budget: Spp,
    /// Each image pixel's place on the sensor (the bound's vignetting is in sensor pixels).
    pub keys: PixelKeys,
}

impl SensorPlan {
    /// Samples in every pixel before the counts are chosen.
    pub const PILOT: u32 = 2;

    /// Samples pixel (`row`, `col`) of the image needs (≥ [`SensorPlan::PILOT`], at most
    /// [`MAX_SAMPLES`]), from its neighbours' pilot statistics `stat` (`width` ×
    /// `rows` rows, the image's row `row` being row `row - base` of `stat`).
    pub fn need(&self, stat: &[[f32; 2]], width: usize, rows: usize, base: usize, row: u32, col: u32) -> u32 {
        let NeighbourEstimate { mean, variance } =
            neighbour_estimate(stat, width, rows, row as usize - base, col as usize);
        let (r, c) = self.keys.on_sensor(row, col);
        let allowed = self.bound.allowed_radiance_variance(f64::from(mean), r, c);
        let n = f64::from(variance) / allowed;
        if n.is_nan() {
            return Self::PILOT;
        }
        (n.ceil().max(f64::from(Self::PILOT)).min(f64::from(MAX_SAMPLES))) as u32
    }

    /// The common cap on the counts `needs` (one slice per band) so that Σ min(needₚ, cap)
    /// spends the budget: the largest whole C that fits, and the probability with which a
    /// pixel that needs more gets C + 1 (what is left of the budget, shared among them).
    pub fn cap<'a>(&self, needs: impl IndexedParallelIterator<Item = &'a [u32]> + Clone) -> Cap {
        let total = |c: u32| -> (u64, u64) {
            needs
                .clone()
                .map(|b| (b.iter().map(|&n| u64::from(n.min(c))).sum::<u64>(), b.len() as u64))
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
        };
        let (all, pixels) = total(MAX_SAMPLES);
        let budget = pixels * u64::from(self.budget.milli()) / 1000;
        if all <= budget {
            return Cap { whole: MAX_SAMPLES, extra: 0.0 };
        }
        // Σ min(need, C) grows with C: the largest C within the budget, by bisection
        // (at least the pilot, which every pixel has already spent).
        let (mut lo, mut hi) = (Self::PILOT, MAX_SAMPLES);
        while lo + 1 < hi {
            let mid = lo + (hi - lo) / 2;
            if total(mid).0 <= budget { lo = mid } else { hi = mid }
        }
        // The pixels above the cap share what is left: each gets one more sample with the
        // same probability (dithered by pixel, so the expected total is the budget).
        let above = total(lo + 1).0 - total(lo).0;
        let left = budget.saturating_sub(total(lo).0);
        Cap { whole: lo, extra: if above > 0 { (left as f64 / above as f64).min(1.0) } else { 0.0 } }
    }
}

/// The common cap of a frame's counts (see [`SensorPlan::cap`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cap {
    pub whole: u32,
    /// Probability that a pixel needing more than `whole` gets `whole + 1`.
    pub extra: f64,
}

impl Cap {
    /// The count of a pixel that needs `need`; `u` uniform in [0, 1), independent of the
    /// pixel's samples.
    #[inline]
    pub fn apply(&self, need: u32, u: f64) -> u32 {
        if need <= self.whole { need } else { self.whole + u32::from(u < self.extra) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::camera::Window;

    fn plan(k: f64, budget: &str) -> SensorPlan {
        let bound = NoiseBound { k, e_per_radiance: 100.0, floor_e2: 0.0, shot: true, cos4: None, psf_factor: 1.0 };
        let keys = PixelKeys::window(&Window { x: 0, y: 0, width: 3, height: 3 }, 3);
        SensorPlan { bound, budget: budget.parse().unwrap(), keys }
    }

    #[test]
    fn a_pixel_needs_enough_samples_to_meet_the_bound() {
        // Neighbours with means 1 and 3 alternating: mean 2 (200 e⁻, camera variance 200
        // e⁻²); their pilot values vary by s² = 8/7·… → need c²s² / (k² · 200).
        let mut stat = vec![[1.0f32, 0.0]; 9];
        for (i, s) in stat.iter_mut().enumerate() {
            if i % 2 == 1 {
                s[0] = 3.0;
            }
        }
        let m: Vec<f32> = (0..9).filter(|&i| i != 4).map(|i| stat[i][0]).collect();
        let mean = m.iter().sum::<f32>() / 8.0;
        let s2 = m.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / 7.0;
        let p = plan(0.5, "64");
        let want = (f64::from(s2) * 1e4 / (0.25 * f64::from(mean) * 100.0)).ceil() as u32;
        assert_eq!(p.need(&stat, 3, 3, 0, 1, 1), want);
        // A looser bound needs fewer, a flat neighbourhood only the pilot.
        assert!(plan(1.0, "64").need(&stat, 3, 3, 0, 1, 1) < want);
        assert_eq!(p.need(&[[2.0, 0.0]; 9], 3, 3, 0, 1, 1), SensorPlan::PILOT);
    }

    #[test]
    fn the_cap_is_the_largest_that_fits_the_budget() {
        let p = plan(0.5, "4");
        // 8 pixels needing 1 and 2 needing 100: 10 pixels × 4 = 40 samples; 8 + 2C ≤ 40 → C = 16.
        let needs = vec![1, 1, 1, 1, 1, 1, 1, 1, 100, 100];
        assert_eq!(p.cap(vec![&needs[..5], &needs[5..]].into_par_iter()), Cap { whole: 16, extra: 0.0 });
        // 41 samples: one left for the two capped pixels, each gets 17 with probability ½.
        let p41 = plan(0.5, "4.1");
        let cap = p41.cap(vec![&needs[..]].into_par_iter());
        assert_eq!(cap, Cap { whole: 16, extra: 0.5 });
        assert_eq!((cap.apply(100, 0.49), cap.apply(100, 0.5), cap.apply(3, 0.0)), (17, 16, 3));
        // Everything fits: no cap below the largest need.
        let small = [1, 2, 3, 4];
        assert!(p.cap(vec![&small[..]].into_par_iter()).whole >= 4);
    }
}
