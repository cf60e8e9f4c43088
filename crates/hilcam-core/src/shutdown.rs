//! The one way to stop a long-running part: `serve` (its scheduler, inputs, helpers and
//! sinks), `replay`'s render loop, `send`'s pacing thread, the GigE Vision device's
//! control loop and stream thread. The command line turns SIGINT/SIGTERM/SIGHUP into
//! [`Shutdown::trigger_by`] (the binary's `cli/signal.rs`); the scheduler triggers it
//! when it stops by itself (fatal or done).
//!
//! A cloneable handle over a `watch` channel: [`Shutdown::trigger`] from anywhere (async
//! or not, any number of times); async tasks wait with [`Shutdown::wait`], blocking
//! loops poll [`Shutdown::is_triggered`] or sleep with [`Shutdown::sleep`] /
//! [`Shutdown::sleep_until`]. A component that stops on its own (the frame stream's
//! accept loop and clients, `hilcam send`'s pacing thread) owns an instance of its own.
//!
//! At the crate root, below every module: the links, the sinks, replay and serve all
//! hold one, and none of them is the others' owner.

use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};
use tokio::sync::watch;

#[derive(Clone, Debug)]
pub struct Shutdown {
    tx: Arc<watch::Sender<bool>>,
    /// Why it was triggered first (a signal's name), for messages such as replay's
    /// "stopped by SIGTERM".
    cause: Arc<OnceLock<&'static str>>,
}

impl Default for Shutdown {
    fn default() -> Self {
        Shutdown::new()
    }
}

impl Shutdown {
    pub fn new() -> Self {
        Shutdown { tx: Arc::new(watch::Sender::new(false)), cause: Arc::default() }
    }

    /// A signal triggered when `stop` resolves (a task on the current tokio runtime
    /// waits for it; it ends when either happens).
    pub fn when(stop: impl std::future::Future + Send + 'static) -> Self {
        let s = Shutdown::new();
        let t = s.clone();
        tokio::spawn(async move {
            tokio::select! {
                _ = stop => t.trigger(),
                _ = t.wait() => {}
            }
        });
        s
    }

    /// Ask everything that holds this signal to stop (idempotent).
    pub fn trigger(&self) {
        self.tx.send_replace(true);
    }

    /// [`Shutdown::trigger`], noting `cause` (kept only if it is the first).
    pub fn trigger_by(&self, cause: &'static str) {
        // Set before the trigger, so whoever sees the trigger sees the cause.
        let _ = self.cause.set(cause);
        self.trigger();
    }

    /// The first [`Shutdown::trigger_by`]'s cause (None if none was given).
    pub fn cause(&self) -> Option<&'static str> {
        self.cause.get().copied()
    }

    pub fn is_triggered(&self) -> bool {
        *self.tx.borrow()
    }

    /// Resolves once triggered (at once if it already was).
    pub async fn wait(&self) {
        let mut rx = self.tx.subscribe();
        // The sender lives in `self`, so the channel cannot close while this waits.
        let _ = rx.wait_for(|stop| *stop).await;
    }

    /// [`Shutdown::wait`] as an owned future (for APIs that take `impl Future`).
    pub async fn wait_owned(self) {
        self.wait().await
    }

    /// Blocking sleep for `d` in short steps, so a trigger is seen within 10 ms;
    /// `false` if triggered.
    pub fn sleep(&self, d: Duration) -> bool {
        let until = Instant::now() + d;
        while Instant::now() < until {
            if self.is_triggered() {
                return false;
            }
            std::thread::sleep(Duration::from_millis(10).min(d));
        }
        !self.is_triggered()
    }

    /// [`Shutdown::sleep`] until `due` (no sleep if it has passed); `false` if triggered.
    pub fn sleep_until(&self, due: Instant) -> bool {
        match due.checked_duration_since(Instant::now()) {
            Some(d) if !d.is_zero() => self.sleep(d),
            _ => !self.is_triggered(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn every_clone_sees_one_trigger_and_late_waiters_return_at_once() {
        let s = Shutdown::new();
        let (a, b) = (s.clone(), s.clone());
        let waiter = tokio::spawn(async move { a.wait().await });
        assert!(!b.is_triggered());
        s.trigger();
        s.trigger();
        tokio::time::timeout(Duration::from_secs(5), waiter).await.expect("waiter woke").unwrap();
        assert!(b.is_triggered());
        tokio::time::timeout(Duration::from_secs(1), b.wait()).await.expect("already triggered");
    }

    #[tokio::test]
    async fn when_triggers_on_the_future_and_a_blocking_sleep_ends_early() {
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let s = Shutdown::when(rx);
        let sleeper = s.clone();
        let t0 = std::time::Instant::now();
        let slept = tokio::task::spawn_blocking(move || sleeper.sleep(Duration::from_secs(30)));
        tx.send(()).unwrap();
        assert!(!slept.await.unwrap(), "sleep reports the trigger");
        assert!(t0.elapsed() < Duration::from_secs(5), "the sleep ended early: {:?}", t0.elapsed());
        assert!(s.is_triggered());
    }

    #[test]
    fn the_first_cause_is_kept_and_seen_with_the_trigger() {
        let s = Shutdown::new();
        let seen = s.clone();
        assert_eq!((seen.is_triggered(), seen.cause()), (false, None));
        s.trigger_by("SIGTERM");
        s.trigger_by("SIGINT");
        assert_eq!((seen.is_triggered(), seen.cause()), (true, Some("SIGTERM")));
    }

    #[test]
    fn sleep_until_waits_for_the_deadline_unless_triggered() {
        let s = Shutdown::new();
        let t0 = Instant::now();
        assert!(s.sleep_until(t0 + Duration::from_millis(30)), "not triggered: slept to the end");
        assert!(t0.elapsed() >= Duration::from_millis(30), "{:?}", t0.elapsed());
        assert!(s.sleep_until(t0), "a deadline in the past returns at once");
        s.trigger();
        let t1 = Instant::now();
        assert!(!s.sleep_until(t1 + Duration::from_secs(30)), "triggered: reports it");
        assert!(t1.elapsed() < Duration::from_secs(1), "{:?}", t1.elapsed());
        assert!(!s.sleep_until(t1), "triggered, deadline passed: still reports it");
    }
}
