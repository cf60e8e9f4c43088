//! The quality governor: which (spp, depth) the next frame renders at.
//!
//! `FixedQuality` always renders the configured quality (late frames are counted by the
//! caller). `FixedRate` walks a ladder — halve spp down to 1, then lower depth down to
//! 1 — to keep the render time inside the frame budget, and climbs back when a step up is
//! predicted to fit. Pure: it only sees the render times it is told about.

use crate::render::integrator::Spp;
use std::time::Duration;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Policy {
    /// Always the configured spp/depth; frames may be late (counted).
    #[default]
    FixedQuality,
    /// Lower spp, then depth, to meet the deadline; raise them again when there is slack.
    FixedRate,
}

/// One rung of the ladder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quality {
    pub spp: Spp,
    pub depth: u32,
}

/// Target fraction of the budget a frame may use (headroom for jitter, sensor, encode).
const TARGET: f64 = 0.85;

#[derive(Clone, Debug)]
pub struct Governor {
    policy: Policy,
    budget: Duration,
    ladder: Vec<Quality>,
    /// Index into `ladder` (0 = best quality).
    level: usize,
    /// Smoothed seconds per unit of [`Governor::cost`] (None until a frame is measured).
    rate: Option<f64>,
}

impl Governor {
    pub fn new(policy: Policy, budget: Duration, best: Quality) -> Self {
        let mut ladder = Vec::new();
        let mut spp = best.spp;
        loop {
            ladder.push(Quality { spp, depth: best.depth.max(1) });
            if spp == Spp::ONE {
                break;
            }
            spp = spp.halved();
        }
        for depth in (1..best.depth.max(1)).rev() {
            ladder.push(Quality { spp: Spp::ONE, depth });
        }
        Governor { policy, budget, ladder, level: 0, rate: None }
    }

    pub fn budget(&self) -> Duration {
        self.budget
    }

    /// Quality for the next frame.
    pub fn current(&self) -> Quality {
        self.ladder[self.level]
    }

    /// Relative cost of a rung: spp × a depth factor (each extra bounce costs less than
    /// the first hit because many bounce rays escape).
    fn cost(q: Quality) -> f64 {
        q.spp.get() * (1.0 + 0.7 * f64::from(q.depth - 1))
    }

    fn predict(&self, level: usize) -> f64 {
        self.rate.unwrap_or(0.0) * Self::cost(self.ladder[level])
    }

    /// Tell the governor how long the frame rendered at `q` took; returns the quality for
    /// the next frame.
    pub fn observe(&mut self, q: Quality, took: Duration) -> Quality {
        // One cost model for all rungs, refreshed by every frame: a load change seen at
        // one rung immediately updates the prediction for the others.
        let r = took.as_secs_f64() / Self::cost(q);
        self.rate = Some(match self.rate {
            Some(old) => 0.6 * old + 0.4 * r,
            None => r,
        });
        if self.policy == Policy::FixedQuality {
            return self.current();
        }
        let budget = self.budget.as_secs_f64() * TARGET;
        // Step down while the current rung is predicted over budget.
        while self.level + 1 < self.ladder.len() && self.predict(self.level) > budget {
            self.level += 1;
        }
        // Step up one rung at a time when it is predicted to fit with margin.
        if self.level > 0 && self.predict(self.level - 1) < budget * 0.9 {
            self.level -= 1;
        }
        self.current()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: f64) -> Duration {
        Duration::from_secs_f64(v / 1e3)
    }

    #[test]
    fn ladder_halves_spp_then_lowers_depth() {
        let g = Governor::new(Policy::FixedRate, ms(100.0), Quality { spp: Spp::whole(16), depth: 4 });
        let l: Vec<(u32, u32)> = g.ladder.iter().map(|q| (q.spp.floor(), q.depth)).collect();
        assert_eq!(l, vec![(16, 4), (8, 4), (4, 4), (2, 4), (1, 4), (1, 3), (1, 2), (1, 1)]);
        // Fractional budgets halve to the thousandth, down to 1.
        let g = Governor::new(Policy::FixedRate, ms(100.0), Quality { spp: "3".parse().unwrap(), depth: 1 });
        let l: Vec<String> = g.ladder.iter().map(|q| q.spp.to_string()).collect();
        assert_eq!(l, ["3", "1.5", "1"]);
        let g = Governor::new(Policy::FixedRate, ms(100.0), Quality { spp: "2.5".parse().unwrap(), depth: 1 });
        let l: Vec<String> = g.ladder.iter().map(|q| q.spp.to_string()).collect();
        assert_eq!(l, ["2.5", "1.25", "1"]);
    }

    /// A simulated renderer whose time is proportional to the rung's cost.
    fn simulate(policy: Policy, budget_ms: f64, ms_per_cost: f64, frames: usize) -> (Governor, Vec<Quality>) {
        let mut g = Governor::new(policy, ms(budget_ms), Quality { spp: Spp::whole(16), depth: 4 });
        let mut seen = Vec::new();
        for _ in 0..frames {
            let q = g.current();
            seen.push(q);
            g.observe(q, ms(Governor::cost(q) * ms_per_cost));
        }
        (g, seen)
    }

    #[test]
    fn fixed_rate_settles_on_the_best_rung_that_fits() {
        // Best quality costs 16·3.1 = 49.6 units; at 2 ms/unit = 99 ms, budget 40 ms.
        let (g, seen) = simulate(Policy::FixedRate, 40.0, 2.0, 30);
        let q = g.current();
        let t = Governor::cost(q) * 2.0;
        assert!(t <= 40.0 * TARGET, "settled on {q:?} taking {t} ms");
        // The next rung up would not fit.
        let better = g.ladder[g.ladder.iter().position(|x| *x == q).unwrap() - 1];
        assert!(Governor::cost(better) * 2.0 > 40.0 * TARGET * 0.9);
        // Once settled it stays (no oscillation) over the last 10 frames.
        assert!(seen[20..].iter().all(|x| *x == q), "{:?}", &seen[20..]);
    }

    #[test]
    fn fixed_rate_climbs_back_when_load_drops() {
        let mut g = Governor::new(Policy::FixedRate, ms(100.0), Quality { spp: Spp::whole(8), depth: 2 });
        // Heavy load: everything takes 10× longer.
        for _ in 0..10 {
            let q = g.current();
            g.observe(q, ms(Governor::cost(q) * 40.0));
        }
        let low = g.current();
        assert!(low.spp < Spp::whole(8));
        for _ in 0..40 {
            let q = g.current();
            g.observe(q, ms(Governor::cost(q) * 4.0));
        }
        assert_eq!(
            g.current(),
            Quality { spp: Spp::whole(8), depth: 2 },
            "came down to {low:?}, should be back at best"
        );
    }

    #[test]
    fn fixed_quality_never_changes() {
        let (g, seen) = simulate(Policy::FixedQuality, 1.0, 10.0, 10);
        assert!(seen.iter().all(|q| *q == Quality { spp: Spp::whole(16), depth: 4 }));
        assert_eq!(g.current(), Quality { spp: Spp::whole(16), depth: 4 });
    }

    #[test]
    fn impossible_budget_bottoms_out_at_one_spp_depth_one() {
        let (g, _) = simulate(Policy::FixedRate, 1.0, 100.0, 30);
        assert_eq!(g.current(), Quality { spp: Spp::whole(1), depth: 1 });
    }
}
