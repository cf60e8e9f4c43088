//! The render times the run summary reports (p50, p99), kept in a fixed window.
//!
//! A server runs for days at tens of frames per second: keeping every render time would
//! grow without bound. The window holds the newest [`RenderTimes::WINDOW`] times (32 KiB),
//! so the percentiles are exact for a run shorter than that and describe the recent
//! frames of a longer one; the whole run's distribution is in the
//! `hilcam_render_seconds` histogram.

use std::time::Duration;

pub struct RenderTimes {
    /// Seconds; a ring once full (`next` is the oldest entry).
    times: Vec<f64>,
    next: usize,
}

impl Default for RenderTimes {
    fn default() -> Self {
        RenderTimes { times: Vec::with_capacity(Self::WINDOW), next: 0 }
    }
}

impl RenderTimes {
    /// How many of the newest render times are kept.
    pub const WINDOW: usize = 4096;

    pub fn record(&mut self, d: Duration) {
        let s = d.as_secs_f64();
        if self.times.len() < Self::WINDOW {
            self.times.push(s);
        } else {
            self.times[self.next] = s;
            self.next = (self.next + 1) % Self::WINDOW;
        }
    }

    /// Times held (at most [`Self::WINDOW`]).
    pub fn len(&self) -> usize {
        self.times.len()
    }

    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The `q` quantile (0..=1) of the window in milliseconds (nearest rank); 0 when empty.
    pub fn percentile_ms(&self, q: f64) -> f64 {
        let mut sorted = self.times.clone();
        sorted.sort_by(f64::total_cmp);
        let rank = ((sorted.len() as f64 - 1.0) * q).round() as usize;
        sorted.get(rank).copied().unwrap_or(0.0) * 1e3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn a_short_run_reports_exact_percentiles() {
        let mut t = RenderTimes::default();
        assert_eq!(t.percentile_ms(0.5), 0.0);
        for n in [5, 1, 3, 2, 4] {
            t.record(ms(n));
        }
        assert_eq!(t.percentile_ms(0.5), 3.0);
        assert_eq!(t.percentile_ms(0.99), 5.0);
        assert_eq!(t.percentile_ms(0.0), 1.0);
    }

    #[test]
    fn a_long_run_keeps_only_the_newest_window() {
        let mut t = RenderTimes::default();
        // Slow frames first, then a window's worth of fast ones: the slow ones are gone.
        for _ in 0..3 * RenderTimes::WINDOW {
            t.record(ms(100));
        }
        for n in 0..RenderTimes::WINDOW as u64 {
            t.record(ms(1 + n % 10));
        }
        assert_eq!(t.len(), RenderTimes::WINDOW);
        assert_eq!(t.times.capacity(), RenderTimes::WINDOW);
        assert_eq!(t.percentile_ms(0.99), 10.0);
        assert_eq!(t.percentile_ms(0.0), 1.0);
        // One more slow frame replaces the oldest fast one and shows at the top.
        t.record(ms(100));
        assert_eq!(t.len(), RenderTimes::WINDOW);
        assert_eq!(t.percentile_ms(1.0), 100.0);
    }
}
