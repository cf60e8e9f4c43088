//! A lock-free latency histogram with HDR-style log-linear buckets.
//!
//! Values are u64 (nanoseconds for latencies). Values below 128 get one bucket each;
//! above, every power of two is split into 64 equal buckets, so a bucket's width is at
//! most 1/64 of its lower bound. A quantile is reported as the middle of the bucket that
//! holds the exact nearest-rank quantile, hence within ±1/128 (0.78 %) of it.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Duration;

const LINEAR: usize = 128;
const SUB: usize = 64;
/// 128 exact buckets + 64 per octave for exponents 7..=63.
pub const BUCKETS: usize = LINEAR + (64 - 7) * SUB;

/// Index of the bucket holding `v`.
pub fn bucket_of(v: u64) -> usize {
    if v < LINEAR as u64 {
        return v as usize;
    }
    let e = 63 - v.leading_zeros() as usize; // >= 7
    let sub = ((v >> (e - 6)) & (SUB as u64 - 1)) as usize;
    LINEAR + (e - 7) * SUB + sub
}

/// Inclusive value range `[lo, hi]` of bucket `b`.
pub fn bucket_bounds(b: usize) -> (u64, u64) {
    if b < LINEAR {
        return (b as u64, b as u64);
    }
    let k = b - LINEAR;
    let shift = k / SUB + 1; // e - 6
    let lo = ((SUB + k % SUB) as u64) << shift;
    (lo, lo + ((1u64 << shift) - 1))
}

/// Concurrent histogram: `record` is a few relaxed atomic adds, callable from any thread.
pub struct Histogram {
    buckets: Box<[AtomicU64]>,
    count: AtomicU64,
    sum: AtomicU64,
    min: AtomicU64,
    max: AtomicU64,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram {
            buckets: (0..BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            count: AtomicU64::new(0),
            sum: AtomicU64::new(0),
            min: AtomicU64::new(u64::MAX),
            max: AtomicU64::new(0),
        }
    }
}

impl std::fmt::Debug for Histogram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Histogram").field("count", &self.count.load(Relaxed)).finish_non_exhaustive()
    }
}

impl Histogram {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn record(&self, v: u64) {
        self.buckets[bucket_of(v)].fetch_add(1, Relaxed);
        self.count.fetch_add(1, Relaxed);
        self.sum.fetch_add(v, Relaxed);
        self.min.fetch_min(v, Relaxed);
        self.max.fetch_max(v, Relaxed);
    }

    /// Record a duration in nanoseconds (saturating at u64::MAX ns ≈ 584 years).
    pub fn record_duration(&self, d: Duration) {
        self.record(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    }

    /// A consistent-enough copy for reporting (concurrent records may straddle it).
    pub fn snapshot(&self) -> HistogramSnapshot {
        let counts: Vec<u64> = self.buckets.iter().map(|b| b.load(Relaxed)).collect();
        let min = self.min.load(Relaxed);
        HistogramSnapshot {
            count: counts.iter().sum(),
            sum: self.sum.load(Relaxed),
            min: (min != u64::MAX).then_some(min),
            max: (min != u64::MAX).then(|| self.max.load(Relaxed)),
            counts,
        }
    }
}

/// A histogram's state at one moment; subtract two with [`HistogramSnapshot::since`].
#[derive(Clone, Debug, PartialEq)]
pub struct HistogramSnapshot {
    pub counts: Vec<u64>,
    pub count: u64,
    pub sum: u64,
    /// Exact extremes when known (not for an interval delta).
    pub min: Option<u64>,
    pub max: Option<u64>,
}

impl HistogramSnapshot {
    /// The nearest-rank `q`-quantile (0 < q ≤ 1): the middle of the bucket holding the
    /// ⌈q·n⌉-th smallest value, clamped to the exact min/max. `None` if empty.
    pub fn quantile(&self, q: f64) -> Option<u64> {
        if self.count == 0 {
            return None;
        }
        let rank = ((q * self.count as f64).ceil() as u64).clamp(1, self.count);
        let mut cum = 0;
        for (b, &c) in self.counts.iter().enumerate() {
            cum += c;
            if cum >= rank {
                let (lo, hi) = bucket_bounds(b);
                let mid = lo + (hi - lo) / 2;
                let mid = self.min.map_or(mid, |m| mid.max(m));
                return Some(self.max.map_or(mid, |m| mid.min(m)));
            }
        }
        self.max
    }

    /// Mean of the recorded values.
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum as f64 / self.count as f64)
    }

    /// What was recorded after `earlier` (same histogram); min/max become unknown.
    pub fn since(&self, earlier: &HistogramSnapshot) -> HistogramSnapshot {
        let counts: Vec<u64> = self.counts.iter().zip(&earlier.counts).map(|(a, b)| a.saturating_sub(*b)).collect();
        HistogramSnapshot {
            count: counts.iter().sum(),
            sum: self.sum.saturating_sub(earlier.sum),
            min: None,
            max: None,
            counts,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_tile_the_u64_range_without_gaps() {
        let mut next = 0u64;
        for b in 0..BUCKETS {
            let (lo, hi) = bucket_bounds(b);
            assert_eq!(lo, next, "bucket {b}");
            assert!(hi >= lo);
            assert_eq!(bucket_of(lo), b);
            assert_eq!(bucket_of(hi), b);
            // Width is at most 1/64 of the lower bound above the linear range.
            if b >= LINEAR {
                assert!((hi - lo + 1) * 64 <= lo, "bucket {b}");
            }
            next = hi.wrapping_add(1);
        }
        assert_eq!(next, 0, "last bucket ends at u64::MAX");
    }
}
