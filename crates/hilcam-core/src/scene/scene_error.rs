//! What a scene file's refusal says: the file, and where it can the line and the field.

use std::ops::Range;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    /// toml's message already says "at line L, column C".
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}:{line}: {field}: {message}")]
    Field { path: PathBuf, line: usize, field: String, message: String },
    #[error("{path}: {field}: {message}")]
    Missing { path: PathBuf, field: String, message: String },
}

/// Where a scene file's errors point: its path, and its text for the line of a span.
#[derive(Clone, Copy)]
pub(super) struct At<'a> {
    pub path: &'a Path,
    pub src: &'a str,
}

impl At<'_> {
    /// A field's refusal at the line where its value starts.
    pub fn field(&self, span: Range<usize>, field: &str, message: String) -> SceneError {
        SceneError::Field {
            path: self.path.to_path_buf(),
            line: line_of(self.src, span.start),
            field: field.into(),
            message,
        }
    }

    /// A refusal of something the file lacks (no line to point at).
    pub fn missing(&self, field: &str, message: String) -> SceneError {
        SceneError::Missing { path: self.path.to_path_buf(), field: field.into(), message }
    }
}

fn line_of(src: &str, offset: usize) -> usize {
    src[..offset.min(src.len())].bytes().filter(|b| *b == b'\n').count() + 1
}
