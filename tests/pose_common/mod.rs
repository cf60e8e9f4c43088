//! Shared fixtures for the device tests: a pty "null-modem cable", the Python
//! interpreter with pyserial/python-can, and event collection helpers.
#![allow(dead_code)]

use hilcam_core::link::{InputCounters, InputEvent};
use serialport::{SerialPort, TTYPort};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// Generous limit for waiting on I/O (a guard against hangs, not a timing check).
pub const PATIENCE: Duration = Duration::from_secs(30);

/// Two pty pairs whose masters are bridged by threads: bytes written to
/// `a` come out of `b` and vice versa, like a null-modem cable between two
/// tty paths.
pub struct NullModem {
    pub a: String,
    pub b: String,
    _slaves: (TTYPort, TTYPort),
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl NullModem {
    pub fn new() -> Self {
        let (ma, sa) = TTYPort::pair().expect("pty pair");
        let (mb, sb) = TTYPort::pair().expect("pty pair");
        let a = sa.name().unwrap();
        let b = sb.name().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let pump = |mut from: TTYPort, mut to: TTYPort, stop: Arc<AtomicBool>| {
            std::thread::spawn(move || {
                from.set_timeout(Duration::from_millis(20)).unwrap();
                to.set_timeout(PATIENCE).unwrap();
                let mut buf = [0u8; 4096];
                while !stop.load(Ordering::Relaxed) {
                    match from.read(&mut buf) {
                        Ok(n) if n > 0 => {
                            if to.write_all(&buf[..n]).is_err() {
                                return;
                            }
                        }
                        Ok(_) => {}
                        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                        Err(_) => std::thread::sleep(Duration::from_millis(5)),
                    }
                }
            })
        };
        let ma2 = ma.try_clone_native().unwrap();
        let mb2 = mb.try_clone_native().unwrap();
        let threads = vec![pump(ma, mb2, stop.clone()), pump(mb, ma2, stop.clone())];
        NullModem { a, b, _slaves: (sa, sb), stop, threads }
    }
}

impl Drop for NullModem {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// The Python interpreter with pyserial and python-can. Missing, it is a test
/// failure with the fix in the message (never a silent pass);
/// `scripts/setup-python.sh` (run by `scripts/test.sh`) creates it.
pub fn python() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("HILCAM_PYTHON").map(PathBuf::from),
        std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/hilcam/venv/bin/python")),
    ];
    for p in candidates.into_iter().flatten() {
        let ok = std::process::Command::new(&p).args(["-c", "import serial, can"]).status().is_ok_and(|s| s.success());
        if ok {
            return Some(p);
        }
    }
    panic!(
        "no Python with pyserial and python-can: run scripts/setup-python.sh \
         (scripts/test.sh does) or set HILCAM_PYTHON"
    );
}

/// Repository root (for examples/ and scenes/).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Receives events until `pred(events)` holds or [`PATIENCE`] passes.
pub async fn collect_until(
    rx: &mut mpsc::Receiver<InputEvent>,
    events: &mut Vec<InputEvent>,
    pred: impl Fn(&[InputEvent]) -> bool,
) -> bool {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    while !pred(events) {
        match tokio::time::timeout_at(deadline, rx.recv()).await {
            Ok(Some(e)) => events.push(e),
            _ => return pred(events),
        }
    }
    true
}

/// Polls `pred` every 10 ms until it holds or [`PATIENCE`] passes.
pub async fn wait_for(pred: impl Fn() -> bool) -> bool {
    let t0 = Instant::now();
    while !pred() {
        if t0.elapsed() > PATIENCE {
            return false;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    true
}

pub fn poses(events: &[InputEvent]) -> Vec<hilcam_core::pose::Pose> {
    events
        .iter()
        .filter_map(|e| match e {
            InputEvent::Pose { pose, .. } => Some(*pose),
            _ => None,
        })
        .collect()
}

pub fn get(c: &std::sync::atomic::AtomicU64) -> u64 {
    c.load(Ordering::Relaxed)
}

pub fn counters() -> Arc<InputCounters> {
    Arc::new(InputCounters::new())
}

/// Writes `chunks` to `w` from a thread, pausing `gap` between them.
pub fn write_all_slowly(mut w: TTYPort, chunks: Vec<Vec<u8>>, gap: Duration) -> std::thread::JoinHandle<()> {
    w.set_timeout(PATIENCE).unwrap();
    std::thread::spawn(move || {
        for c in chunks {
            w.write_all(&c).unwrap();
            w.flush().unwrap();
            std::thread::sleep(gap);
        }
    })
}

pub fn pty_name(p: &TTYPort) -> String {
    p.name().unwrap()
}

/// A pty pair whose master writes wait up to [`PATIENCE`] (the default 100 ms
/// write timeout is too short on a loaded machine).
pub fn pty_pair() -> (TTYPort, TTYPort) {
    let (mut m, s) = TTYPort::pair().unwrap();
    m.set_timeout(PATIENCE).unwrap();
    (m, s)
}
