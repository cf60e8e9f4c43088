//! Async I/O feeding the pose codecs: serial, SocketCAN and slcan receivers as
//! tokio tasks, and the sending side used by `hilcam send`.
//!
//! Each receiver is `run_*(cfg, tx, counters, shutdown)`: it decodes, validates
//! (see [`crate::pose::validate`]) and pushes [`InputEvent`]s into a bounded
//! `tokio::sync::mpsc` channel until `shutdown` resolves or the receiver side
//! of the channel is dropped. Device failures never end the task: it counts
//! them, logs them and reopens the device with exponential backoff.
//!
//! Channel policy: the transports never wait on a full channel (a stalled
//! reader would overflow the kernel's UART/CAN buffers instead); an event that
//! does not fit is dropped and counted in [`InputCounters::channel_full`].
//! Size the channel for the burst you expect (e.g. 1024).

mod counters;
mod events;
pub mod send;
pub mod serial;
pub mod slcan;
pub mod socketcan;

pub use counters::InputCounters;
pub(crate) use events::EventSink;
pub use events::InputEvent;

use std::time::Duration;

/// Reopen backoff: starts at `min`, doubles per failure up to `max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Backoff {
    /// First wait after a failure.
    pub min: Duration,
    /// Longest wait.
    pub max: Duration,
}

impl Default for Backoff {
    fn default() -> Self {
        Backoff { min: Duration::from_millis(50), max: Duration::from_secs(2) }
    }
}

impl Backoff {
    pub(crate) fn next(&self, cur: Duration) -> Duration {
        (cur * 2).clamp(self.min, self.max)
    }
}

/// Sleeps `d` in short steps so a stop request is seen promptly; returns
/// `false` if stopped.
pub(crate) fn sleep_unless_stopped(d: Duration, stop: &std::sync::atomic::AtomicBool) -> bool {
    let until = std::time::Instant::now() + d;
    while std::time::Instant::now() < until {
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(10).min(d));
    }
    !stop.load(std::sync::atomic::Ordering::Relaxed)
}

/// Runs the blocking loop `body(stop)` on a blocking thread until `shutdown`
/// resolves (then sets `stop` and waits for it) or the loop returns by itself.
pub(crate) async fn run_blocking_until<F>(body: F, shutdown: impl std::future::Future)
where
    F: FnOnce(&std::sync::atomic::AtomicBool) + Send + 'static,
{
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    let mut task = tokio::task::spawn_blocking(move || body(&stop2));
    tokio::select! {
        _ = shutdown => {
            stop.store(true, Ordering::Relaxed);
            let _ = task.await;
        }
        _ = &mut task => {}
    }
}
