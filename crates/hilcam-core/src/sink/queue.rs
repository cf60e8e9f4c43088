//! The bounded drop-oldest queue every viewer of a live output gets (a TCP stream
//! client, a browser on the live page): pushing never waits; when the queue is full the
//! oldest item makes room and is handed back to be counted, so a slow reader always gets
//! the newest item next. While it stays full, it remembers since when (a reader that
//! stopped reading can be evicted).

use std::collections::VecDeque;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use tokio::sync::Notify;

pub struct DropOldest<T> {
    depth: usize,
    inner: Mutex<Inner<T>>,
    notify: Notify,
}

struct Inner<T> {
    items: VecDeque<T>,
    /// Since when the queue has been full without a break (reset whenever one is taken).
    full_since: Option<Instant>,
}

impl<T> DropOldest<T> {
    /// A queue of `depth` items (at least 1).
    pub fn new(depth: usize) -> Self {
        let depth = depth.max(1);
        DropOldest {
            depth,
            inner: Mutex::new(Inner { items: VecDeque::with_capacity(depth), full_since: None }),
            notify: Notify::new(),
        }
    }

    /// Queue `item` and wake the reader; the oldest item if it had to make room.
    pub fn push(&self, item: T) -> Option<T> {
        let mut q = self.inner.lock().expect("queue poisoned");
        let dropped = if q.items.len() >= self.depth { q.items.pop_front() } else { None };
        q.items.push_back(item);
        if q.items.len() >= self.depth {
            q.full_since.get_or_insert_with(Instant::now);
        }
        drop(q);
        self.notify.notify_one();
        dropped
    }

    /// The oldest queued item; taking one ends a "queue full" stretch.
    pub fn take(&self) -> Option<T> {
        let mut q = self.inner.lock().expect("queue poisoned");
        let item = q.items.pop_front()?;
        q.full_since = None;
        Some(item)
    }

    /// Resolves after the next [`DropOldest::push`] (or at once if one happened since the
    /// last wait): wait on this, then [`DropOldest::take`].
    pub async fn pushed(&self) {
        self.notify.notified().await
    }

    pub fn len(&self) -> usize {
        self.inner.lock().expect("queue poisoned").items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Empty the queue; how many items were in it.
    pub fn clear(&self) -> usize {
        self.inner.lock().expect("queue poisoned").items.drain(..).count()
    }

    /// How long the queue has been full without a break, if longer than `limit`.
    pub fn full_longer_than(&self, limit: Duration) -> Option<Duration> {
        let since = self.inner.lock().expect("queue poisoned").full_since?;
        Some(since.elapsed()).filter(|d| *d > limit)
    }

    /// Resolves once the queue has stayed full longer than `limit` (never for None),
    /// checking a few times per `limit` so that it comes at most ~25 % late.
    pub async fn stalled(&self, limit: Option<Duration>) -> Duration {
        let Some(limit) = limit else { return std::future::pending().await };
        let mut tick = tokio::time::interval((limit / 4).clamp(Duration::from_millis(10), Duration::from_millis(500)));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            if let Some(d) = self.full_longer_than(limit) {
                return d;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_queue_drops_its_oldest_and_keeps_the_newest() {
        let q = DropOldest::new(2);
        assert_eq!(q.push(1), None);
        assert_eq!(q.push(2), None);
        assert_eq!(q.push(3), Some(1));
        assert_eq!(q.push(4), Some(2));
        assert_eq!((q.take(), q.take(), q.take()), (Some(3), Some(4), None));
    }

    #[test]
    fn full_since_starts_when_full_and_ends_on_a_take() {
        let q = DropOldest::new(1);
        q.push(1);
        std::thread::sleep(Duration::from_millis(5));
        assert!(q.full_longer_than(Duration::from_millis(1)).is_some());
        q.take();
        assert!(q.full_longer_than(Duration::ZERO).is_none());
        assert!(q.is_empty());
    }
}
