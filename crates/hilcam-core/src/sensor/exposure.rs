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
        let p = percentile_dn(pixels, self.cfg.percentile);
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
    let hist = match pixels {
        Pixels::Mono8(d) => histogram(d, 256),
        Pixels::Mono16 { data, .. } => histogram(data, 65536),
        Pixels::Float32(_) => return 0.0,
    };
    let n: u64 = hist.iter().sum();
    if n == 0 {
        return 0.0;
    }
    let rank = ((p / 100.0 * n as f64).ceil() as u64).clamp(1, n);
    let mut cum = 0u64;
    for (v, c) in hist.iter().enumerate() {
        cum += c;
        if cum >= rank {
            return v as f64;
        }
    }
    (hist.len() - 1) as f64
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
}
