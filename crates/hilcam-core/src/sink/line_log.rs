//! An append-only JSON-lines log whose every line lands whole or not at all: a write
//! that fails part-way (disk full) is cut back off, so the log never holds half a line
//! and the next line still starts on a line of its own.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

pub struct LineLog {
    file: File,
    path: PathBuf,
    /// Bytes of complete lines in the file.
    len: u64,
}

impl LineLog {
    /// Open `path` for appending (created if missing).
    pub fn open(path: &Path) -> std::io::Result<LineLog> {
        let file = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
        let len = file.metadata()?.len();
        Ok(LineLog { file, path: path.to_path_buf(), len })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Append `line` and a newline in one write; on error, truncate what part of it was
    /// written (the error returned is the write's).
    pub fn append(&mut self, line: &str) -> std::io::Result<()> {
        let mut bytes = Vec::with_capacity(line.len() + 1);
        bytes.extend_from_slice(line.as_bytes());
        bytes.push(b'\n');
        match self.file.write_all(&bytes) {
            Ok(()) => {
                self.len += bytes.len() as u64;
                Ok(())
            }
            Err(e) => {
                if let Err(t) = self.file.set_len(self.len) {
                    tracing::error!(file = %self.path.display(), "cannot cut a partly written line back off: {t}");
                }
                Err(e)
            }
        }
    }
}
