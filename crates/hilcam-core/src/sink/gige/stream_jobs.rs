//! The stream thread's work queue: frames to send and resend requests, each bounded
//! on its own, frames first, so that a flood of resend requests never delays the
//! controller's frames nor grows without bound. What does not fit is handed back to
//! the caller, which counts it.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex};
use std::time::Duration;

/// Frames queued at most (the one being sent is not counted): the renderer publishes
/// one frame while the previous one streams, so two means the stream is a frame behind.
pub const FRAMES_MAX: usize = 2;
/// Resend requests queued at most.
pub const RESENDS_MAX: usize = 16;

/// What the stream thread does next.
#[derive(Debug, PartialEq)]
pub enum Next<F, R> {
    Frame(F),
    Resend(R),
    /// Nothing within the wait: check the stop flag, wait again.
    Idle,
    Stopped,
}

pub struct Jobs<F, R> {
    state: Mutex<State<F, R>>,
    ready: Condvar,
}

struct State<F, R> {
    frames: VecDeque<F>,
    resends: VecDeque<R>,
    stopped: bool,
}

impl<F, R> Default for Jobs<F, R> {
    fn default() -> Self {
        Jobs {
            state: Mutex::new(State { frames: VecDeque::new(), resends: VecDeque::new(), stopped: false }),
            ready: Condvar::new(),
        }
    }
}

impl<F, R> Jobs<F, R> {
    /// Queue a frame, or hand it back when [`FRAMES_MAX`] are waiting.
    pub fn push_frame(&self, f: F) -> Result<(), F> {
        let mut s = self.state.lock().expect("jobs lock");
        if s.frames.len() >= FRAMES_MAX || s.stopped {
            return Err(f);
        }
        s.frames.push_back(f);
        self.ready.notify_one();
        Ok(())
    }

    /// Queue a resend request, or hand it back when [`RESENDS_MAX`] are waiting.
    pub fn push_resend(&self, r: R) -> Result<(), R> {
        let mut s = self.state.lock().expect("jobs lock");
        if s.resends.len() >= RESENDS_MAX || s.stopped {
            return Err(r);
        }
        s.resends.push_back(r);
        self.ready.notify_one();
        Ok(())
    }

    /// Wake the stream thread for good.
    pub fn stop(&self) {
        self.state.lock().expect("jobs lock").stopped = true;
        self.ready.notify_all();
    }

    /// The next job, frames first; waits up to `wait`.
    pub fn next(&self, wait: Duration) -> Next<F, R> {
        let s = self.state.lock().expect("jobs lock");
        let (mut s, _) = self
            .ready
            .wait_timeout_while(s, wait, |s| !s.stopped && s.frames.is_empty() && s.resends.is_empty())
            .expect("jobs lock");
        if s.stopped {
            return Next::Stopped;
        }
        if let Some(f) = s.frames.pop_front() {
            return Next::Frame(f);
        }
        s.resends.pop_front().map_or(Next::Idle, Next::Resend)
    }

    /// A waiting resend request, without waiting (served between a frame's packets).
    pub fn take_resend(&self) -> Option<R> {
        let mut s = self.state.lock().expect("jobs lock");
        if s.stopped { None } else { s.resends.pop_front() }
    }

    pub fn stopped(&self) -> bool {
        self.state.lock().expect("jobs lock").stopped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_go_first_and_both_queues_are_bounded() {
        let j: Jobs<u32, u32> = Jobs::default();
        for r in 0..RESENDS_MAX as u32 {
            j.push_resend(r).unwrap();
        }
        assert_eq!(j.push_resend(99), Err(99), "a full resend queue hands the request back");
        j.push_frame(1).unwrap();
        j.push_frame(2).unwrap();
        assert_eq!(j.push_frame(3), Err(3));
        assert_eq!(j.next(Duration::ZERO), Next::Frame(1), "frames before the earlier resends");
        assert_eq!(j.next(Duration::ZERO), Next::Frame(2));
        assert_eq!(j.next(Duration::ZERO), Next::Resend(0));
        j.stop();
        assert_eq!(j.next(Duration::from_secs(60)), Next::Stopped, "stop wakes a waiting thread at once");
        assert_eq!(j.push_frame(4), Err(4));
    }
}
