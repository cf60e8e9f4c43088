//! Session recording for `hilcam serve`: every pose the scheduler received and every
//! frame it rendered, as [`crate::session`] lines, so a bench run can be re-rendered
//! frame for frame (`hilcam replay --session`).
//!
//! The scheduler never waits for the disk: it hands lines to a bounded queue
//! ([`SessionTap`], `try_send`) drained by a writer thread with a buffered file. A full
//! queue drops the line and counts it (`hilcam_session_records_dropped_total{reason}`,
//! warned at most once a second); the `end` line carries the total, so a re-render knows
//! the file is incomplete.

use crate::frame::unix_ns_now;
use crate::metrics::{Counter, Registry};
use crate::pose::Pose;
use crate::session::{EndLine, FrameLine, PoseFields, PoseLine, SessionHeader, SessionLine};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Lines the queue holds before dropping (≈ 1 s of 10 kHz poses).
pub const QUEUE_LINES: usize = 16_384;

/// Flush the file at least this often while lines arrive (and whenever the queue is idle).
const FLUSH_EVERY: Duration = Duration::from_millis(200);

#[derive(Debug, thiserror::Error)]
pub enum SessionWriteError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: already exists; a session file is never overwritten (choose another [record] session name)")]
    Exists { path: PathBuf },
}

/// What the writer did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SessionStats {
    pub path: PathBuf,
    /// Lines written, header and end included.
    pub written: u64,
    /// Lines dropped (queue full or written after a write error).
    pub dropped: u64,
}

/// The scheduler's handle: cheap to clone, never blocks.
#[derive(Clone)]
pub struct SessionTap {
    tx: SyncSender<SessionLine>,
    start: Instant,
    source: Arc<str>,
    dropped_full: Counter,
    last_warn: Arc<Mutex<Option<Instant>>>,
}

impl std::fmt::Debug for SessionTap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionTap").field("source", &self.source).finish_non_exhaustive()
    }
}

impl SessionTap {
    /// ns from the session start to `t` (0 for instants before it).
    pub fn mono_ns(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.start).as_nanos() as u64
    }

    /// Record a received pose.
    pub fn pose(&self, pose: &Pose, arrival: Instant) {
        let ago = Instant::now().saturating_duration_since(arrival).as_nanos() as u64;
        self.send(SessionLine::Pose(PoseLine {
            mono_ns: self.mono_ns(arrival),
            unix_ns: unix_ns_now().saturating_sub(ago),
            source: self.source.to_string(),
            pose: PoseFields::from(pose),
        }));
    }

    /// Record a rendered frame.
    pub fn frame(&self, line: FrameLine) {
        self.send(SessionLine::Frame(line));
    }

    /// Record any other line (failed frames).
    pub fn send(&self, line: SessionLine) {
        match self.tx.try_send(line) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                self.dropped_full.inc();
                let mut last = self.last_warn.lock().expect("session warn lock");
                if last.is_none_or(|t| t.elapsed() >= Duration::from_secs(1)) {
                    *last = Some(Instant::now());
                    tracing::warn!(
                        dropped = self.dropped_full.get(),
                        "session writer behind: session lines dropped (counted in the end line)"
                    );
                }
            }
            Err(TrySendError::Disconnected(_)) => {
                self.dropped_full.inc();
                tracing::error!("session writer stopped: session line dropped");
            }
        }
    }
}

/// The writer thread and its queue.
pub struct SessionWriter {
    tap: SessionTap,
    path: PathBuf,
    written: Counter,
    dropped_error: Counter,
    thread: std::thread::JoinHandle<Result<(), std::io::Error>>,
}

impl SessionWriter {
    /// Create `path` (never overwriting), write the header and start the writer thread.
    /// `start` is the zero of every `mono_ns`; `source` names the input in pose lines.
    pub fn start(
        path: &Path,
        header: &SessionHeader,
        start: Instant,
        source: &str,
        registry: &Registry,
    ) -> Result<SessionWriter, SessionWriteError> {
        let io = |source| SessionWriteError::Io { path: path.to_path_buf(), source };
        let file = match std::fs::OpenOptions::new().write(true).create_new(true).open(path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                return Err(SessionWriteError::Exists { path: path.to_path_buf() });
            }
            Err(e) => return Err(io(e)),
        };
        let mut out = std::io::BufWriter::with_capacity(1 << 16, file);
        writeln!(out, "{}", SessionLine::Header(header.clone()).encode()).and_then(|_| out.flush()).map_err(io)?;
        let help = "Session lines not written";
        let dropped_full = registry.counter("hilcam_session_records_dropped_total", help, &[("reason", "queue_full")]);
        let dropped_error =
            registry.counter("hilcam_session_records_dropped_total", help, &[("reason", "write_error")]);
        let written = registry.counter("hilcam_session_records_written_total", "Session lines written", &[]);
        written.inc();
        let (tx, rx) = std::sync::mpsc::sync_channel(QUEUE_LINES);
        let (w, e, p) = (written.clone(), dropped_error.clone(), path.to_path_buf());
        let thread = std::thread::Builder::new()
            .name("hilcam-session".into())
            .spawn(move || write_lines(rx, out, &p, &w, &e))
            .map_err(io)?;
        let tap = SessionTap { tx, start, source: source.into(), dropped_full, last_warn: Arc::default() };
        Ok(SessionWriter { tap, path: path.to_path_buf(), written, dropped_error, thread })
    }

    /// A handle for the scheduler.
    pub fn tap(&self) -> SessionTap {
        self.tap.clone()
    }

    /// Lines dropped so far.
    pub fn dropped(&self) -> u64 {
        self.tap.dropped_full.get() + self.dropped_error.get()
    }

    /// Write the `end` line (its `records_dropped` and times are filled in here), wait for
    /// the file to be complete and close it. Blocks: call from a blocking context.
    pub fn finish(self, mut end: EndLine) -> Result<SessionStats, SessionWriteError> {
        end.mono_ns = self.tap.mono_ns(Instant::now());
        end.unix_ns = unix_ns_now();
        end.records_dropped = self.dropped();
        // The end line waits for room: it must not be the one line lost.
        let sent = self.tap.tx.send(SessionLine::End(end)).is_ok();
        let SessionWriter { tap, path, written, dropped_error, thread } = self;
        let dropped_full = tap.dropped_full.clone();
        drop(tap);
        let result = thread.join().unwrap_or_else(|_| Err(std::io::Error::other("session writer panicked")));
        result.map_err(|source| SessionWriteError::Io { path: path.clone(), source })?;
        if !sent {
            return Err(SessionWriteError::Io {
                path,
                source: std::io::Error::other("writer gone before the end line"),
            });
        }
        Ok(SessionStats { path, written: written.get(), dropped: dropped_full.get() + dropped_error.get() })
    }
}

/// The writer thread: until the `end` line (or every sender is gone).
fn write_lines(
    rx: Receiver<SessionLine>,
    mut out: std::io::BufWriter<std::fs::File>,
    path: &Path,
    written: &Counter,
    dropped_error: &Counter,
) -> Result<(), std::io::Error> {
    let mut failed: Option<std::io::Error> = None;
    let mut last_flush = Instant::now();
    loop {
        let line = match rx.recv_timeout(FLUSH_EVERY) {
            Ok(l) => l,
            Err(RecvTimeoutError::Timeout) => {
                flush(&mut out, &mut failed, path);
                last_flush = Instant::now();
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => break,
        };
        let end = matches!(line, SessionLine::End(_));
        if failed.is_some() {
            dropped_error.inc();
        } else if let Err(e) = writeln!(out, "{}", line.encode()) {
            tracing::error!(file = %path.display(), "session file: {e}; later lines are dropped (counted)");
            dropped_error.inc();
            failed = Some(e);
        } else {
            written.inc();
        }
        if end {
            break;
        }
        if last_flush.elapsed() >= FLUSH_EVERY {
            flush(&mut out, &mut failed, path);
            last_flush = Instant::now();
        }
    }
    match failed {
        Some(e) => Err(e),
        None => out.flush(),
    }
}

/// Flush unless a write already failed; the first failure is logged and kept.
fn flush(out: &mut std::io::BufWriter<std::fs::File>, failed: &mut Option<std::io::Error>, path: &Path) {
    if failed.is_none()
        && let Err(e) = out.flush()
    {
        tracing::error!(file = %path.display(), "session file: {e}; later lines are dropped (counted)");
        *failed = Some(e);
    }
}
