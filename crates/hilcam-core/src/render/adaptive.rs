//! Adaptive sample counts per pixel, chosen so that every pixel's estimate stays unbiased.
//!
//! A frame's error is not spread evenly: on the shipped satellite at 4 spp, 1 % of the
//! target's pixels (MLI folds, silhouette and shadow edges, the inside of the white
//! antenna dish where light bounces) hold 80 % of the squared error. Spending the samples
//! where the variance is minimises Σ σ²ₚ / Nₚ for a fixed Σ Nₚ at Nₚ ∝ σₚ.
//!
//! So a frame is rendered in two stages: a pilot of `pilot` = ⌊spp/2⌋ samples (at least
//! one) in every pixel, then the rest of the budget (`spp` per pixel on average, which
//! may have a fraction: 1.25 leaves a quarter of a sample per pixel) shared out by a weight
//! that grows with each pixel's estimated standard deviation σ̂: the variance between its
//! neighbours' pilot means (edges, shadow boundaries, and noise) plus the mean variance
//! within their pilots (noise; none with a one-sample pilot). The weight is √σ̂, not σ̂:
//! the noisy pixels (folds, the dish) are also the expensive ones — their paths bounce
//! and their rays start among small triangles, ~2.4× the cost of an average sample — and
//! the optimum for per-sample cost cₚ is Nₚ ∝ σₚ/√cₚ; √σ̂ measured best on the shipped
//! satellite (docs/performance.md).
//!
//! The estimate for pixel p is taken from the pilot samples of its eight *neighbours
//! only*, never its own: the number of samples p gets is
//! then independent of p's own random numbers, so the mean of its first Nₚ samples is an
//! unbiased estimate whatever Nₚ is (each sample of p's sequence is, on its own, an
//! unbiased sample of the pixel). Using p's own pilot values would bias it (a pixel whose
//! pilot came out high would be sampled differently from one whose pilot came out low).
//! The fractional part of each share is dithered by a hash of (seed, frame, pixel), also
//! independent of p's samples, so the expected total is the budget. (One link remains:
//! the frame-wide normalisation of the shares sums every pixel's weight, including those
//! of p's neighbours, which read p. p's pilot thus moves its own share by about one part
//! in the number of pixels, ~10⁻⁵ on a 1024² frame — far below any measurable bias; the
//! tests check means to 0.3 %.)

use crate::render::integrator::Spp;
use crate::render::sampling::mix64;

/// Share of the mean weight added to every pixel's: a pixel whose neighbours all looked
/// flat still gets some of the budget (a defensive mixture with uniform sampling).
const FLOOR: f64 = 0.05;
/// Extra samples per pixel below which the weights follow σ̂, not √σ̂ (see
/// [`Adaptive::concentrated`]).
const CONCENTRATE_BELOW: f64 = 0.375;
/// No pixel gets more than this many times the average extra samples.
const CAP: u32 = 16;

/// The two-stage plan of a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Adaptive {
    /// Samples every pixel gets in the pilot stage.
    pub pilot: u32,
    /// Average samples per sampled pixel over the whole frame, in thousandths.
    pub spp_milli: u32,
    /// Share the rest evenly (a fraction of a sample in every pixel, dithered) instead of
    /// by what the pilot saw: a fractional budget without adaptive sampling.
    pub uniform: bool,
}

impl Adaptive {
    /// The plan for `spp` samples per pixel on average, shared out by the pilot's variance
    /// when `adaptive`; `None` when every pixel gets the same whole number of samples
    /// (`spp` 1, or a whole `spp` without `adaptive`).
    ///
    /// The pilot is half the budget, and at least one sample: from 1 to 2 spp the pilot is
    /// one sample and the fraction goes where it saw variance.
    pub fn new(spp: Spp, adaptive: bool) -> Option<Adaptive> {
        if adaptive && spp > Spp::ONE {
            Some(Adaptive { pilot: (spp.floor() / 2).max(1), spp_milli: spp.milli(), uniform: false })
        } else if !spp.is_whole() {
            Some(Adaptive { pilot: spp.floor(), spp_milli: spp.milli(), uniform: true })
        } else {
            None
        }
    }

    /// Average samples per pixel beyond the pilot.
    fn extra(&self) -> f64 {
        f64::from(self.spp_milli) / 1000.0 - f64::from(self.pilot)
    }

    /// Largest sample count a pixel can get.
    pub fn max_samples(&self) -> u32 {
        self.pilot + (f64::from(CAP) * self.extra()).ceil() as u32
    }

    /// What the pilot of one pixel tells its neighbours, from the sum and sum of squares
    /// of its pilot samples: their mean and (with two or more) their variance.
    pub fn statistic(&self, sum: f32, sum_sq: f32) -> [f32; 2] {
        let n = self.pilot as f32;
        [sum / n, sample_variance(sum, sum_sq, self.pilot)]
    }

    /// The statistic of a pixel that was not sampled (it sees the background exactly).
    pub fn background_statistic(&self, background: f32) -> [f32; 2] {
        [background, 0.0]
    }

    /// Weight of pixel (`row`, `col`) from the pilot statistics `stat` (`width` ×
    /// `height`, row-major) of its eight neighbours, never its own: √σ̂ with σ̂² the
    /// variance of the neighbours' pilot means plus the mean of their pilot variances —
    /// or σ̂ itself when the extra budget is small ([`Adaptive::concentrated`]).
    pub fn weight(&self, stat: &[[f32; 2]], width: usize, height: usize, row: usize, col: usize) -> f32 {
        let sigma = neighbour_estimate(stat, width, height, row, col).variance.sqrt();
        if self.concentrated() { sigma } else { sigma.sqrt() }
    }

    /// Whether the extra samples follow σ̂ rather than √σ̂: with less than ~⅓ of a sample
    /// per pixel to share, the best use is on the few worst pixels (the optimum with a
    /// pilot already in every pixel gives nothing to most pixels and more to the worst),
    /// and σ̂ concentrates it there. Measured on the shipped satellite (err² × time,
    /// docs/performance.md): σ̂ is 15 % better at 1.125 spp and 10 % at 1.25,
    /// √σ̂ 6 % better at 1.5 and from 2 spp on.
    pub fn concentrated(&self) -> bool {
        self.extra() < CONCENTRATE_BELOW
    }

    /// How the extra budget is shared, from the weights of every sampled pixel of the
    /// frame (`bands`, summed in the order given, so the answer is the same for any thread
    /// count): in proportion to `weight + FLOOR·mean`, at most `CAP` times the average
    /// extra per pixel, and what the capped pixels cannot take goes to the others.
    pub fn shares<'a>(&self, bands: impl Iterator<Item = &'a [f32]> + Clone) -> Shares {
        let extra = self.extra();
        let cap = f64::from(CAP) * extra;
        let (mut total, mut pixels) = (0.0f64, 0u64);
        for b in bands.clone() {
            total += b.iter().map(|&w| f64::from(w)).sum::<f64>();
            pixels += b.len() as u64;
        }
        if total <= 0.0 || !total.is_finite() {
            // Nothing varies anywhere: the uniform plan.
            return Shares { floor: 1.0, scale: extra, cap };
        }
        let floor = FLOOR * total / pixels as f64;
        let budget = extra * pixels as f64;
        let scale = budget / (total + floor * pixels as f64);
        // One redistribution step: the capped pixels keep `cap`, the rest share the rest.
        let (mut capped_weight, mut capped) = (0.0f64, 0u64);
        for b in bands {
            for &w in b {
                let w = f64::from(w) + floor;
                if w * scale > cap {
                    capped_weight += w;
                    capped += 1;
                }
            }
        }
        let rest = total + floor * pixels as f64 - capped_weight;
        let scale = if capped > 0 && rest > 0.0 { (budget - capped as f64 * cap).max(0.0) / rest } else { scale };
        Shares { floor, scale, cap }
    }

    /// Sample counts of pixels with weights `weight` (frame pixel indices `index`):
    /// `pilot` plus their share, its fraction dithered by `(seed, frame, pixel index)`.
    pub fn counts(&self, shares: &Shares, weight: &[f32], index: &[u64], seed: u64, frame: u64) -> Vec<u32> {
        let mut out = Vec::new();
        self.counts_into(shares, weight, index, seed, frame, &mut out);
        out
    }

    /// [`Adaptive::counts`] into `out` (replacing its contents, keeping its buffer).
    pub fn counts_into(
        &self,
        shares: &Shares,
        weight: &[f32],
        index: &[u64],
        seed: u64,
        frame: u64,
        out: &mut Vec<u32>,
    ) {
        out.clear();
        // The frame's key once, then one mix per pixel.
        let key = mix64(seed ^ mix64(frame ^ 0x6164_6170_7469_7665));
        out.extend(weight.iter().zip(index).map(|(&w, &i)| {
            let share = ((f64::from(w) + shares.floor) * shares.scale).min(shares.cap);
            let u = (mix64(key ^ i) >> 11) as f64 / (1u64 << 53) as f64;
            self.pilot + (share + u).floor() as u32
        }));
    }
}

/// What the pilot statistics of a pixel's eight neighbours (never its own) say about it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeighbourEstimate {
    /// Mean of the neighbours' pilot means.
    pub mean: f32,
    /// σ̂²: the variance between the neighbours' pilot means (edges, shading, and the noise
    /// of their means) plus the mean variance within their pilots (noise). With a
    /// one-sample pilot and a locally flat radiance it is the per-sample variance; where
    /// the radiance varies across the neighbourhood it is larger (conservative).
    pub variance: f32,
}

/// [`NeighbourEstimate`] of pixel (`row`, `col`) from the pilot statistics `stat`
/// (`width` × `height`, row-major, `[mean, variance]` per pixel).
pub fn neighbour_estimate(stat: &[[f32; 2]], width: usize, height: usize, row: usize, col: usize) -> NeighbourEstimate {
    let (mut sum, mut sum_sq, mut var, mut n) = (0.0f32, 0.0f32, 0.0f32, 0u32);
    for r in row.saturating_sub(1)..(row + 2).min(height) {
        for c in col.saturating_sub(1)..(col + 2).min(width) {
            if (r, c) != (row, col) {
                let [m, v] = stat[r * width + c];
                sum += m;
                sum_sq += m * m;
                var += v;
                n += 1;
            }
        }
    }
    let between = sample_variance(sum, sum_sq, n);
    let within = if n > 0 { var / n as f32 } else { 0.0 };
    NeighbourEstimate { mean: if n > 0 { sum / n as f32 } else { 0.0 }, variance: between + within }
}

/// Extra samples of a pixel of weight w: `min(cap, (w + floor) · scale)` (see
/// [`Adaptive::shares`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shares {
    floor: f64,
    scale: f64,
    cap: f64,
}

/// Unbiased sample variance of `n` values from their sum and sum of squares (≥ 0).
pub fn sample_variance(sum: f32, sum_sq: f32, n: u32) -> f32 {
    if n < 2 {
        return 0.0;
    }
    let n = n as f32;
    ((sum_sq - sum * sum / n) / (n - 1.0)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The counts `plan` gives pixels of weights `w` (pixel indices 0, 1, …), keyed by `seed`.
    fn counts_of(plan: &Adaptive, w: &[f32], seed: u64) -> Vec<u32> {
        let index: Vec<u64> = (0..w.len() as u64).collect();
        plan.counts(&plan.shares(std::iter::once(w)), w, &index, seed, seed + 1)
    }

    #[test]
    fn pilot_is_half_the_budget() {
        let spp = |s: &str| s.parse::<Spp>().unwrap();
        assert_eq!(Adaptive::new(spp("1"), true), None);
        assert_eq!(Adaptive::new(spp("2"), true), Some(Adaptive { pilot: 1, spp_milli: 2000, uniform: false }));
        assert_eq!(Adaptive::new(spp("3"), true).unwrap().pilot, 1);
        assert_eq!(Adaptive::new(spp("4"), true).unwrap().pilot, 2);
        assert_eq!(Adaptive::new(spp("64"), true).unwrap().pilot, 32);
        // A fraction between 1 and 2: one pilot sample, the fraction shared out.
        assert_eq!(Adaptive::new(spp("1.25"), true), Some(Adaptive { pilot: 1, spp_milli: 1250, uniform: false }));
        assert_eq!(Adaptive::new(spp("1.25"), true).unwrap().max_samples(), 1 + 4);
        // Without adaptive sampling: a whole budget is one stage, a fraction is dithered.
        assert_eq!(Adaptive::new(spp("4"), false), None);
        assert_eq!(Adaptive::new(spp("2.5"), false), Some(Adaptive { pilot: 2, spp_milli: 2500, uniform: true }));
    }

    #[test]
    fn a_fraction_is_spent_evenly_without_adaptive_sampling() {
        let plan = Adaptive::new("1.3".parse().unwrap(), false).unwrap();
        let n = 50_000usize;
        let counts = counts_of(&plan, &vec![0.0f32; n], 3);
        assert!(counts.iter().all(|&c| c == 1 || c == 2));
        let mean = counts.iter().map(|&c| f64::from(c)).sum::<f64>() / n as f64;
        assert!((mean - 1.3).abs() < 0.01, "mean {mean}");
    }

    #[test]
    fn a_fractional_budget_is_kept_on_average() {
        // 1.125 spp: 1 pilot sample, an eighth of a sample per pixel more where it varies.
        let plan = Adaptive::new("1.125".parse().unwrap(), true).unwrap();
        let n = 40_000usize;
        let w: Vec<f32> = (0..n).map(|i| if i % 10 == 0 { 1.0 } else { 0.0 }).collect();
        let counts = counts_of(&plan, &w, 5);
        let sum: u64 = counts.iter().map(|&c| u64::from(c)).sum();
        assert!((sum as f64 / n as f64 - 1.125).abs() < 0.01, "{sum} samples for {n} pixels");
        assert!(counts.iter().all(|&c| c >= 1 && c <= plan.max_samples()));
        // The tenth of the pixels that vary get most of it.
        let busy: u64 = counts.iter().step_by(10).map(|&c| u64::from(c - 1)).sum();
        assert!(busy as f64 > 0.6 * (sum - n as u64) as f64, "{busy} of {}", sum - n as u64);
    }

    #[test]
    fn weight_reads_the_neighbours_only() {
        let plan = Adaptive { pilot: 2, spp_milli: 4000, uniform: false };
        // Neighbours all alike with no pilot variance: weight 0, whatever the centre holds.
        let mut stat = vec![[3.0f32, 0.0]; 9];
        stat[4] = [100.0, 1e6];
        assert_eq!(plan.weight(&stat, 3, 3, 1, 1), 0.0);
        // Within-pixel variance 16 in every neighbour: σ̂ = 4, weight 2.
        for (i, s) in stat.iter_mut().enumerate() {
            if i != 4 {
                s[1] = 16.0;
            }
        }
        assert!((plan.weight(&stat, 3, 3, 1, 1) - 2.0).abs() < 1e-6);
        // One neighbour's mean differs (an edge): the variance between the eight adds.
        stat[0][0] = 11.0;
        let means = [11.0f32, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0];
        let mean = means.iter().sum::<f32>() / 8.0;
        let between = means.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / 7.0;
        assert!((plan.weight(&stat, 3, 3, 1, 1) - (between + 16.0).sqrt().sqrt()).abs() < 1e-5);
        // A corner pixel has three neighbours.
        assert!(plan.weight(&stat, 3, 3, 0, 0) > 0.0);
        // A small extra budget: the weight is σ̂ itself.
        let small = Adaptive::new("1.25".parse().unwrap(), true).unwrap();
        assert!(small.concentrated() && !plan.concentrated());
        assert!((small.weight(&stat, 3, 3, 1, 1) - (between + 16.0).sqrt()).abs() < 1e-4);
        assert!(!Adaptive::new("1.5".parse().unwrap(), true).unwrap().concentrated());
    }

    #[test]
    fn counts_share_the_budget_in_proportion_and_keep_its_total() {
        let plan = Adaptive { pilot: 2, spp_milli: 8000, uniform: false }; // 6 extra per pixel on average
        let n = 20_000usize;
        // Half the pixels flat, half with σ = 1: the noisy half gets ~41× the extra samples
        // of the flat half ((1 + f)/f with f = FLOOR · mean σ = 0.025).
        let sigma: Vec<f32> = (0..n).map(|i| if i % 2 == 0 { 0.0 } else { 1.0 }).collect();
        let counts = counts_of(&plan, &sigma, 1);
        let sum: u64 = counts.iter().map(|&c| u64::from(c)).sum();
        let budget = 8.0 * n as f64;
        assert!((sum as f64 - budget).abs() < 0.01 * budget, "{sum} vs {budget}");
        let mean = |odd: usize| {
            let v: Vec<f64> = counts.iter().skip(odd).step_by(2).map(|&c| f64::from(c - plan.pilot)).collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        let ratio = mean(1) / mean(0);
        assert!((ratio / (1.025 / 0.025) - 1.0).abs() < 0.05, "ratio {ratio}");
        assert!(counts.iter().all(|&c| c >= plan.pilot && c <= plan.max_samples()));
    }

    #[test]
    fn flat_frames_are_sampled_uniformly() {
        let plan = Adaptive::new(Spp::whole(4), true).unwrap();
        let flat = [0.0; 5];
        let shares = plan.shares(std::iter::once(&flat[..]));
        assert_eq!(plan.counts(&shares, &flat, &[0, 1, 2, 3, 4], 0, 0), vec![4; 5]);
    }

    #[test]
    fn what_capped_pixels_cannot_take_goes_to_the_others() {
        // One pixel with a huge weight among 999 equal ones: it is capped at 16× the
        // average extra, and the budget is still spent.
        let plan = Adaptive { pilot: 1, spp_milli: 2000, uniform: false };
        let mut w = vec![1.0f32; 1000];
        w[0] = 1e6;
        let counts = counts_of(&plan, &w, 0);
        assert_eq!(counts[0], 1 + 16);
        let sum: u32 = counts.iter().sum();
        assert!((f64::from(sum) / 2000.0 - 1.0).abs() < 0.01, "{sum} samples for 2000");
    }

    #[test]
    fn sample_variance_matches_the_definition() {
        let v = [1.0f32, 2.0, 4.0];
        let (s, q) = (v.iter().sum::<f32>(), v.iter().map(|x| x * x).sum::<f32>());
        let mean = s / 3.0;
        let direct = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / 2.0;
        assert!((sample_variance(s, q, 3) - direct).abs() < 1e-6);
        assert_eq!(sample_variance(5.0, 25.0, 1), 0.0);
    }
}
