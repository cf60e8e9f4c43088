//! What a piece of code logs, captured: the tests of load reports and warnings read it.

use std::io::Write;
use std::sync::{Arc, Mutex};

#[derive(Clone)]
struct Buf(Arc<Mutex<Vec<u8>>>);

impl Write for Buf {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// `f()`'s result and every line it logged (plain text, all levels the default shows).
pub fn with_log<T>(f: impl FnOnce() -> T) -> (T, String) {
    let buf = Buf(Arc::new(Mutex::new(Vec::new())));
    let w = buf.clone();
    let sub = tracing_subscriber::fmt().with_writer(move || w.clone()).with_ansi(false).finish();
    let out = tracing::subscriber::with_default(sub, f);
    let log = String::from_utf8(buf.0.lock().unwrap().clone()).unwrap();
    (out, log)
}

/// Load a scene file with its log.
pub fn load_logged(path: &std::path::Path) -> (Result<hilcam_core::scene::Scene, String>, String) {
    with_log(|| hilcam_core::scene::load(path).map_err(|e| e.to_string()))
}
