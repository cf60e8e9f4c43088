//! A sink that only counts (for benchmarks: the cost of everything but the output).

use crate::frame::EncodedFrame;
use crate::metrics::{Counter, Registry};

/// Discards frames, counting them and their bytes.
#[derive(Clone, Debug)]
pub struct NullSink {
    pub frames: Counter,
    pub bytes: Counter,
}

impl NullSink {
    pub fn new(registry: &Registry) -> NullSink {
        NullSink {
            frames: registry.counter("hilcam_null_frames_total", "Frames given to the null sink", &[]),
            bytes: registry.counter("hilcam_null_bytes_total", "Bytes given to the null sink", &[]),
        }
    }

    pub fn publish(&self, frame: &EncodedFrame) {
        self.frames.inc();
        self.bytes.add(frame.bytes.len() as u64);
    }
}
