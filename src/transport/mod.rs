//! Async I/O feeding the pose codecs (placeholder).
