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

use crate::shutdown::Shutdown;

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

/// Runs the blocking loop `body(stop)` on a blocking thread until `shutdown`
/// resolves (then triggers `stop` and waits for the loop) or the loop returns by itself.
pub(crate) async fn run_blocking_until<F>(body: F, shutdown: impl std::future::Future)
where
    F: FnOnce(&Shutdown) + Send + 'static,
{
    let stop = Shutdown::new();
    let for_loop = stop.clone();
    let mut task = tokio::task::spawn_blocking(move || body(&for_loop));
    tokio::select! {
        _ = shutdown => {
            stop.trigger();
            let _ = task.await;
        }
        _ = &mut task => {}
    }
}
