//! Auto-exposure across frames, like a navigation camera's: each frame's DN histogram
//! sets the next frame's integration time.

use super::adc::Adc;
use super::config::AutoExposureConfig;
use crate::render::film::Pixels;
use rayon::prelude::*;

/// Changes smaller than this fraction are ignored, so noise does not make the
/// integration time dither from frame to frame.
pub const DEAD_BAND: f64 = 0.02;

/// Auto-exposure state carried from frame to frame (one per camera stream).
#[derive(Clone, Debug, PartialEq)]
pub struct AutoExposure {
    cfg: AutoExposureConfig,
    adc: Adc,
    /// DN a saturated pixel reads: the ADC maximum, or the full well's DN if lower.
    saturation_dn: f64,
    t_s: f64,
}

/// What one update measured and decided.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureUpdate {
    /// The configured percentile of the frame's DN, minus the offset.
    pub measured_dn: f64,
    /// The DN that percentile should reach.
    pub target_dn: f64,
    /// Integration time of the frame just measured, s.
    pub previous_s: f64,
    /// Integration time for the next frame, s.
    pub next_s: f64,
}

impl AutoExposure {
    /// Start at `initial_s` (the detector's configured integration time), clamped into
    /// `[min_s, max_s]`. `full_well_e` (if any) sets the saturation level with the ADC.
    pub fn new(cfg: &AutoExposureConfig, adc: Adc, full_well_e: Option<f64>, initial_s: f64) -> Self {
        let fw_dn = full_well_e.map_or(f64::INFINITY, |fw| adc.offset_dn + fw / adc.gain_e_per_dn);
        AutoExposure {
            cfg: cfg.clone(),
            adc,
            saturation_dn: fw_dn.min(adc.max_dn as f64),
            t_s: if cfg.enabled { initial_s.clamp(cfg.min_s, cfg.max_s) } else { initial_s },
        }
    }

    /// The integration time to use for the next frame, s.
    pub fn integration_time_s(&self) -> f64 {
        self.t_s
    }

    /// Measure a frame taken with [`Self::integration_time_s`] and choose the next
    /// integration time. A black frame (percentile at the offset) lengthens it by
    /// `max_step`; a saturated one (percentile at the saturation level, where the true
    /// brightness is unknown) shortens it by `max_step`; otherwise the time scales by
    /// target / measured, limited to `max_step`. Disabled: measures but keeps the time.
    pub fn update(&mut self, pixels: &Pixels) -> ExposureUpdate {
        let target = self.cfg.target_fraction * self.adc.usable_range_dn();
        // Black sky reads near the offset: those codes are only counted.
        let low = (self.adc.offset_dn.max(0.0) + self.adc.usable_range_dn() / 64.0).min(self.adc.max_dn as f64);
        let p = percentile_dn_above(pixels, self.cfg.percentile, low as u16);
        let measured = (p - self.adc.offset_dn).max(0.0);
        let prev = self.t_s;
        if self.cfg.enabled {
            let step = self.cfg.max_step;
            let ratio = if measured < 0.5 {
                step
            } else if p >= self.saturation_dn - 0.5 {
                1.0 / step
            } else {
                (target / measured).clamp(1.0 / step, step)
            };
            if (ratio - 1.0).abs() > DEAD_BAND {
                self.t_s = (self.t_s * ratio).clamp(self.cfg.min_s, self.cfg.max_s);
            }
        }
        tracing::debug!(measured, target, prev, next = self.t_s, "auto-exposure");
        ExposureUpdate { measured_dn: measured, target_dn: target, previous_s: prev, next_s: self.t_s }
    }
}

/// Nearest-rank percentile `p` (0 < p ≤ 100) of integer pixels, via a histogram.
/// Float pixels have no DN: returns 0.
pub fn percentile_dn(pixels: &Pixels, p: f64) -> f64 {
    percentile_dn_above(pixels, p, 0)
}

/// [`percentile_dn`], the histogram kept of the values above `low` only: those at or
/// below it are counted, 16 at a time where none is above, and all of them are
/// histogrammed only when the percentile falls among them. The same result for any
/// `low`; a frame of black sky around a target is read about twice as fast with `low`
/// above the sky's codes.
pub fn percentile_dn_above(pixels: &Pixels, p: f64, low: u16) -> f64 {
    match pixels {
        Pixels::Mono8(d) => percentile(d, p, low.min(255) as u8),
        Pixels::Mono16 { data, .. } => percentile(data, p, low),
        Pixels::Float32(_) => 0.0,
    }
}

fn percentile<T: Copy + Ord + Into<usize> + Sync>(data: &[T], p: f64, low: T) -> f64 {
    let n = data.len() as u64;
    if n == 0 {
        return 0.0;
    }
    let rank = ((p / 100.0 * n as f64).ceil() as u64).clamp(1, n);
    let (below, hist) = histogram_above(data, low);
    let (mut cum, hist) =
        if below >= rank && low.into() > 0 { (0, histogram(data, 1 << (8 * size_of::<T>()))) } else { (below, hist) };
    // Below `low + 1`, `hist` is zero (or the whole histogram).
    for (v, c) in hist.iter().enumerate() {
        cum += c;
        if cum >= rank {
            return v as f64;
        }
    }
    low.into().max(hist.len().saturating_sub(1)) as f64
}

/// The number of values at or below `low`, and the counts of the others (a histogram as
/// long as their largest value needs, zero at and below `low`), over chunks in parallel.
fn histogram_above<T: Copy + Ord + Into<usize> + Sync>(data: &[T], low: T) -> (u64, Vec<u64>) {
    data.par_chunks(1 << 16)
        .fold(
            || (0u64, Vec::<u64>::new()),
            |(mut below, mut h), chunk| {
                let sixteens = chunk.chunks_exact(16);
                let mut mixed = |c: &[T], below: &mut u64| {
                    for &v in c {
                        if v <= low {
                            *below += 1;
                        } else {
                            if h.len() <= v.into() {
                                h.resize(v.into() + 1, 0);
                            }
                            h[v.into()] += 1;
                        }
                    }
                };
                mixed(sixteens.remainder(), &mut below);
                for c in sixteens {
                    // A loop the compiler vectorises; black sky ends here.
                    if c.iter().fold(low, |m, &v| m.max(v)) == low {
                        below += 16;
                    } else {
                        mixed(c, &mut below);
                    }
                }
                (below, h)
            },
        )
        .reduce(
            || (0, Vec::new()),
            |(a, mut ha), (b, hb)| {
                if ha.len() < hb.len() {
                    ha.resize(hb.len(), 0);
                }
                ha.iter_mut().zip(&hb).for_each(|(x, y)| *x += y);
                (a + b, ha)
            },
        )
}

/// Counts of each value below `bins`, over chunks in parallel. Within a chunk, four
/// interleaved tables: a frame is mostly a few codes, and one table would wait on its
/// own last increment of the same bin at nearly every pixel.
fn histogram<T: Copy + Into<usize> + Sync>(data: &[T], bins: usize) -> Vec<u64> {
    // Only as many bins as the largest value needs (a 10-bit frame fills 1024).
    let bins = data.par_iter().map(|v| (*v).into() + 1).max().unwrap_or(0).min(bins);
    data.par_chunks(1 << 16)
        .fold(
            || vec![0u32; 4 * bins],
            |mut h, chunk| {
                let quads = chunk.chunks_exact(4);
                for v in quads.remainder() {
                    h[(*v).into()] += 1;
                }
                for q in quads {
                    for (k, v) in q.iter().enumerate() {
                        h[k * bins + (*v).into()] += 1;
                    }
                }
                h
            },
        )
        .map(|h| (0..bins).map(|b| (0..4).map(|k| u64::from(h[k * bins + b])).sum()).collect::<Vec<u64>>())
        .reduce(Vec::new, |a, b| if a.is_empty() { b } else { a.iter().zip(&b).map(|(x, y)| x + y).collect() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentile() {
        let px = Pixels::Mono16 { data: (1..=100).collect(), bits: 12 };
        assert_eq!(percentile_dn(&px, 50.0), 50.0);
        assert_eq!(percentile_dn(&px, 99.5), 100.0);
        assert_eq!(percentile_dn(&px, 1.0), 1.0);
        assert_eq!(percentile_dn(&Pixels::Mono8(vec![7; 10]), 90.0), 7.0);
    }

    #[test]
    fn the_histogram_above_a_level_gives_the_same_percentiles() {
        // Mostly a low floor (in runs, and single values among bright ones), some bright.
        let mut r = crate::render::sampling::Rng::from_state(11);
        let data: Vec<u16> = (0..300_000u32)
            .map(|i| {
                let bright = (i / 1000).is_multiple_of(9) || r.next_u32().is_multiple_of(500);
                if bright { 40 + (r.next_u32() % 900) as u16 } else { 30 + (r.next_u32() % 5) as u16 }
            })
            .collect();
        let px = Pixels::Mono16 { data: data.clone(), bits: 10 };
        let px8 = Pixels::Mono8(data.iter().map(|&v| (v / 4) as u8).collect());
        let mut sorted = data.clone();
        sorted.sort_unstable();
        for p in [0.1, 10.0, 50.0, 88.0, 89.0, 95.0, 99.5, 100.0] {
            for low in [0, 1, 29, 31, 34, 35, 39, 41, 500, 1023, 2000, u16::MAX] {
                let want = (p / 100.0 * data.len() as f64).ceil() as usize;
                assert_eq!(percentile_dn_above(&px, p, low), sorted[want - 1] as f64, "p {p} low {low}");
                assert_eq!(percentile_dn_above(&px8, p, low), percentile_dn(&px8, p), "8 bits, p {p} low {low}");
            }
        }
        assert_eq!(percentile_dn_above(&Pixels::Mono16 { data: vec![], bits: 10 }, 50.0, 3), 0.0);
        assert_eq!(percentile_dn_above(&Pixels::Mono16 { data: vec![0; 5], bits: 10 }, 50.0, 0), 0.0);
    }
}
