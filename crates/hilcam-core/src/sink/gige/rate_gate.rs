//! AcquisitionFrameRate as the device applies it: which published frames go out on the
//! stream. Pure; `device.rs` calls it under its lock.
//!
//! A schedule at the frame rate that tolerates a quarter period of jitter: a source at
//! exactly the rate loses nothing, one at twice it loses half. The schedule is kept as
//! the time of the last frame sent, and the next is due one *current* period after it,
//! so a rate written between two frames applies to the very next one. (Storing the due
//! time computed with the old period instead dropped one frame after every rate
//! increase: after 2 → 4 Hz the first 4 Hz frame, 250 ms after the last, met a due
//! time 500 ms after it: issue 37.)

use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, Default)]
pub struct RateGate {
    /// When the schedule's last frame was due (not when it came: a late frame does not
    /// push the schedule back, an early one within the tolerance does not pull it in).
    last_due: Option<Instant>,
}

impl RateGate {
    /// Forget the schedule (acquisition start): the next frame goes out.
    pub fn reset(&mut self) {
        self.last_due = None;
    }

    /// Whether a frame published at `now` goes out at `rate_hz`; if so it is scheduled.
    pub fn admit(&mut self, now: Instant, rate_hz: f32) -> bool {
        let period = Duration::from_secs_f64(1.0 / f64::from(rate_hz.max(1e-3)));
        let due = self.last_due.map_or(now, |t| t + period);
        if now + period / 4 < due {
            return false;
        }
        // A late frame does not shift the schedule; after a gap it restarts from now.
        self.last_due = Some(due.max(now.checked_sub(period).unwrap_or(now)));
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames at `hz` from `t` for `n` periods: how many the gate at `rate` lets out.
    fn run(g: &mut RateGate, t: &mut Instant, hz: f64, rate: f32, n: u32) -> u32 {
        let mut sent = 0;
        for _ in 0..n {
            *t += Duration::from_secs_f64(1.0 / hz);
            sent += u32::from(g.admit(*t, rate));
        }
        sent
    }

    /// The schedule before issue 37: the due time of the next frame, stored with the
    /// period in force when the last frame went out.
    fn old_admit(next_due: &mut Option<Instant>, now: Instant, rate_hz: f32) -> bool {
        let period = Duration::from_secs_f64(1.0 / f64::from(rate_hz));
        let d = next_due.unwrap_or(now);
        if now + period / 4 < d {
            return false;
        }
        *next_due = Some(d.max(now.checked_sub(period).unwrap_or(now)) + period);
        true
    }

    #[test]
    fn the_old_schedule_dropped_the_first_frame_after_a_rate_increase() {
        let (mut due, t0) = (None, Instant::now());
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        assert!([0, 500, 1000].iter().all(|&ms| old_admit(&mut due, at(ms), 2.0)));
        // 2 → 4 Hz: the renderer's next frame comes 250 ms later, and meets a due time
        // 500 ms after the last one.
        assert!(!old_admit(&mut due, at(1250), 4.0), "the drop seen once after 2 → 4 Hz");
        assert!(old_admit(&mut due, at(1500), 4.0));
        let mut g = RateGate::default();
        assert!([0, 500, 1000].iter().all(|&ms| g.admit(at(ms), 2.0)));
        assert!(g.admit(at(1250), 4.0) && g.admit(at(1500), 4.0), "kept now");
    }

    #[test]
    fn a_rate_increase_drops_no_frame() {
        let (mut g, mut t) = (RateGate::default(), Instant::now());
        assert_eq!(run(&mut g, &mut t, 2.0, 2.0, 10), 10);
        // The client writes 4 Hz between two frames; the renderer re-times to 4 Hz.
        assert_eq!(run(&mut g, &mut t, 4.0, 4.0, 20), 20, "every 4 Hz frame goes out");
        assert_eq!(run(&mut g, &mut t, 2.0, 2.0, 10), 10, "and back");
    }

    #[test]
    fn a_source_faster_than_the_rate_is_thinned_and_jitter_is_tolerated() {
        let (mut g, mut t) = (RateGate::default(), Instant::now());
        assert_eq!(run(&mut g, &mut t, 20.0, 10.0, 40), 20, "20 Hz source at 10 Hz: half");
        // ±20 % jitter around 10 Hz: nothing lost.
        let mut sent = 0;
        for k in 0..50 {
            let jitter = if k % 2 == 0 { 0.02 } else { -0.02 };
            sent += u32::from(g.admit(t + Duration::from_secs_f64(0.1 * f64::from(k + 1) + jitter), 10.0));
        }
        assert_eq!(sent, 50);
    }

    #[test]
    fn after_a_pause_the_next_frame_goes_out_and_the_rate_holds() {
        let (mut g, mut t) = (RateGate::default(), Instant::now());
        assert!(g.admit(t, 10.0));
        t += Duration::from_secs(5);
        assert!(g.admit(t, 10.0));
        assert!((10..=11).contains(&run(&mut g, &mut t, 40.0, 10.0, 40)), "40 Hz for 1 s at 10 Hz");
    }
}
