//! Reporting a write failure that repeats frame after frame (a full disk) without one
//! log line per frame: the first failure is an ERROR, then a "still failing, N frames
//! not written" WARN at most every `every`, and an INFO when writing works again.

use std::time::{Duration, Instant};

/// Why a frame was not written: the `reason` label of the error counters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reason {
    /// ENOSPC / EDQUOT.
    DiskFull,
    /// Any other I/O error (permissions, the directory vanished, …).
    Io,
    /// The image could not be encoded.
    Encode,
}

impl Reason {
    pub const ALL: [Reason; 3] = [Reason::DiskFull, Reason::Io, Reason::Encode];

    pub fn label(self) -> &'static str {
        match self {
            Reason::DiskFull => "disk_full",
            Reason::Io => "io",
            Reason::Encode => "encode",
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Reason::DiskFull => "disk full",
            Reason::Io => "I/O error",
            Reason::Encode => "encoding error",
        }
    }
}

struct Failing {
    reason: Reason,
    since: Instant,
    last_report: Instant,
    failed: u64,
    failed_since_report: u64,
}

pub struct FailureLog {
    /// Who is writing where, e.g. "recorder /data/frames".
    what: String,
    every: Duration,
    state: Option<Failing>,
}

impl FailureLog {
    pub fn new(what: String, every: Duration) -> FailureLog {
        FailureLog { what, every, state: None }
    }

    /// A frame was not written; `error` names the file and the cause.
    pub fn failed(&mut self, reason: Reason, error: &dyn std::fmt::Display) {
        let now = Instant::now();
        match &mut self.state {
            Some(f) if f.reason == reason => {
                f.failed += 1;
                f.failed_since_report += 1;
                if now - f.last_report >= self.every {
                    tracing::warn!(
                        "{}: still failing ({}): {} frames not written in the last {:.0} s, {} since {:.0} s ago; \
                         last: {error}",
                        self.what,
                        reason.describe(),
                        f.failed_since_report,
                        (now - f.last_report).as_secs_f64(),
                        f.failed,
                        (now - f.since).as_secs_f64()
                    );
                    f.last_report = now;
                    f.failed_since_report = 0;
                }
            }
            _ => {
                tracing::error!(
                    "{}: cannot write frames ({}): {error}; frames are not saved until this clears (reported again \
                     at most every {} s)",
                    self.what,
                    reason.describe(),
                    self.every.as_secs()
                );
                let failed = self.state.as_ref().map_or(0, |f| f.failed) + 1;
                let since = self.state.as_ref().map_or(now, |f| f.since);
                self.state = Some(Failing { reason, since, last_report: now, failed, failed_since_report: 0 });
            }
        }
    }

    /// A frame was written: ends a failing stretch (logged once).
    pub fn succeeded(&mut self) {
        if let Some(f) = self.state.take() {
            tracing::info!(
                "{}: writing frames again after {} not written over {:.1} s",
                self.what,
                f.failed,
                f.since.elapsed().as_secs_f64()
            );
        }
    }

    /// At the end: a last line if it ended while failing.
    pub fn finish(&mut self) {
        if let Some(f) = self.state.take() {
            tracing::warn!(
                "{}: stopped while failing ({}): {} frames not written over {:.1} s",
                self.what,
                f.reason.describe(),
                f.failed,
                f.since.elapsed().as_secs_f64()
            );
        }
    }
}
