//! Rate-limited warnings: a flood of bad datagrams must not flood the log. The first
//! occurrence of each reason is logged at once; after that at most one line per
//! reason per interval, carrying how many were suppressed since the last. The counts
//! themselves live in the metrics, which see every occurrence.

use std::collections::HashMap;
use std::time::{Duration, Instant};

/// One line per reason per [`LogLimit::INTERVAL`].
#[derive(Debug, Default)]
pub struct LogLimit {
    last: HashMap<&'static str, (Instant, u64)>,
}

impl LogLimit {
    pub const INTERVAL: Duration = Duration::from_secs(10);

    /// Whether to log an occurrence of `reason` at `now`: `Some(suppressed)` (how many
    /// were not logged since the last line) or `None` (count it and stay quiet).
    pub fn admit(&mut self, reason: &'static str, now: Instant) -> Option<u64> {
        match self.last.get_mut(reason) {
            Some((at, suppressed)) if now.saturating_duration_since(*at) < Self::INTERVAL => {
                *suppressed += 1;
                None
            }
            Some((at, suppressed)) => {
                *at = now;
                Some(std::mem::take(suppressed))
            }
            None => {
                self.last.insert(reason, (now, 0));
                Some(0)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_reason_per_interval_with_the_count() {
        let mut l = LogLimit::default();
        let t0 = Instant::now();
        assert_eq!(l.admit("malformed", t0), Some(0));
        for k in 1..=1000 {
            assert_eq!(l.admit("malformed", t0 + Duration::from_millis(k)), None);
        }
        assert_eq!(l.admit("refused", t0), Some(0), "each reason has its own line");
        assert_eq!(l.admit("malformed", t0 + LogLimit::INTERVAL), Some(1000));
        assert_eq!(l.admit("malformed", t0 + LogLimit::INTERVAL + Duration::from_secs(1)), None);
    }
}
