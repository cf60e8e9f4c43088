//! Frame sinks: where encoded frames go. All take `Arc<EncodedFrame>` (encoded once,
//! shared) and none blocks the caller: each has a bounded queue and counts what it drops.
//!
//! - [`tcp`]: the TCP frame stream server (any number of clients, drop-oldest queues).
//! - [`queue`]: the bounded drop-oldest queue of each stream client and live viewer.
//! - [`recorder`]: image files plus a JSON-lines metadata log, on its own thread.
//! - [`null`]: counts and discards (benchmarks).
//! - [`failure_log`]: one report per stretch of failed writes (a full disk), not one per frame.
//! - [`line_log`]: append-only JSON lines, each written whole or not at all.
//! - [`client`]: the reference stream client (`hilcam recv`, and the in-process demo).
//! - [`truth_exr`]: a frame's ground truth as a multi-channel EXR (recorder and replay).
//! - [`camera_control`]: what a camera transport's clients ask of the renderer (frame and
//!   rate requests, software triggers), whatever the transport: the seam serve merges.

pub mod camera_control;
pub mod client;
pub mod failure_log;
pub mod gige;
pub mod line_log;
pub mod null;
pub mod queue;
pub mod recorder;
pub mod tcp;
pub mod truth_exr;

pub use client::{RecvError, RecvOptions, RecvSummary, receive};
pub use null::NullSink;
pub use recorder::{FrameRecord, ImageFormat, Recorder, RecorderConfig, RecorderError, RecorderStats};
pub use tcp::{ClientStats, FrameWritten, PublishReport, StreamConfig, StreamError, StreamServer, WriteHook};

use crate::frame::EncodedFrame;
use std::sync::Arc;

/// One frame output; the closed set of sinks (dispatch by `match`).
pub enum Sink {
    Stream(StreamServer),
    Recorder(Recorder),
    Null(NullSink),
    /// The GigE Vision camera's stream (docs/gige.md).
    Gige(crate::sink::gige::GigeDevice),
}

impl Sink {
    /// Hand a frame over without blocking (each sink queues it or counts a drop).
    pub fn publish(&self, frame: &Arc<EncodedFrame>) {
        match self {
            Sink::Stream(s) => {
                s.publish(frame.clone());
            }
            Sink::Recorder(r) => {
                r.publish(frame.clone());
            }
            Sink::Null(n) => n.publish(frame),
            Sink::Gige(g) => g.publish(frame),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Sink::Stream(_) => "stream",
            Sink::Recorder(_) => "recorder",
            Sink::Null(_) => "null",
            Sink::Gige(_) => "gige",
        }
    }

    /// Flush and close: the stream finishes frames in flight, the recorder writes its
    /// queue out (on a blocking thread, so this never stalls the runtime).
    pub async fn close(self) {
        match self {
            Sink::Stream(s) => s.shutdown().await,
            Sink::Recorder(r) => match tokio::task::spawn_blocking(move || r.finish()).await {
                Ok(Ok(stats)) => tracing::info!(?stats, "recorder closed"),
                Ok(Err(e)) => tracing::error!("recorder: {e}"),
                Err(e) => tracing::error!("recorder thread: {e}"),
            },
            Sink::Null(_) => {}
            Sink::Gige(g) => g.shutdown().await,
        }
    }
}
