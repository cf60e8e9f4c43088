//! The recorder: each frame as an image file plus one JSON line of metadata, written by
//! its own thread from a bounded queue. When the disk is slower than the frame rate the
//! newest frame is refused and counted (`hilcam_recorder_frames_dropped_total`); the
//! caller never waits for the disk.
//!
//! When writing fails (a full disk) the frame is not saved and counted
//! (`hilcam_recorder_errors_total{reason="disk_full"|"io"|"encode"}`), reported once
//! and then periodically ([`super::failure_log`]), and the recorder carries on: frames
//! are saved again as soon as there is room. An image file appears whole or not at all
//! ([`film::write_file_atomically`]), and a frame's line goes into `frames.jsonl` only
//! after its image is in place (if the line cannot be written, the image is removed):
//! the log lists exactly the image files present.

use super::failure_log::{FailureLog, Reason};
use super::line_log::LineLog;
use crate::frame::{EncodedFrame, FrameMeta};
use crate::metrics::{Counter, Registry};
use crate::render::film::{self, ImageWriteError, Pixels, RadianceImage};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{self, SyncSender, TrySendError};
use std::time::Duration;

/// Image file format, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    /// 8/16-bit PNG (float frames: a preview scaled to the 99.9th percentile).
    Png,
    /// 16-bit TIFF (float frames: preview as for PNG).
    Tiff,
    /// Single-channel float OpenEXR (integer frames: DN as float).
    Exr,
    /// Greyscale portable float map (integer frames: DN as float).
    Pfm,
}

impl ImageFormat {
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Tiff => "tif",
            ImageFormat::Exr => "exr",
            ImageFormat::Pfm => "pfm",
        }
    }
}

/// The file name a frame is saved under: `frame_<seq, 10 digits>.<ext>`.
pub fn frame_file_name(frame_seq: u64, format: ImageFormat) -> String {
    format!("frame_{frame_seq:010}.{}", format.extension())
}

/// Write pixels as `format`, converting where the file type cannot hold them as they
/// are: float → integer formats as a preview, integer → float formats as DN values.
pub fn write_frame_image(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &Pixels,
    format: ImageFormat,
) -> Result<(), ImageWriteError> {
    let float_file = matches!(format, ImageFormat::Exr | ImageFormat::Pfm);
    match pixels {
        Pixels::Float32(d) if !float_file => {
            let img = RadianceImage { width, height, data: d.clone() };
            film::write_radiance(path, &img, None, false).map(|_| ())
        }
        Pixels::Mono8(d) if float_file => {
            let f = d.iter().map(|v| *v as f32).collect();
            film::write_pixels(path, width, height, &Pixels::Float32(f))
        }
        Pixels::Mono16 { data, .. } if float_file => {
            let f = data.iter().map(|v| *v as f32).collect();
            film::write_pixels(path, width, height, &Pixels::Float32(f))
        }
        px => film::write_pixels(path, width, height, px),
    }
}

/// One line of `frames.jsonl`: the frame's [`FrameMeta`] (its fields at the top level,
/// `pixel_format` by name) followed by what the file adds: the LATE and EXTRAPOLATED bits
/// of `flags` spelled out, the payload's length and CRC, and the image file's name.
///
/// Reading is forward-compatible: fields this version does not know are ignored, so a
/// newer hilcam's log still reads (serde's `deny_unknown_fields` cannot be combined
/// with the flattened metadata). A missing field, a wrong type or an unknown
/// `pixel_format` is an error; readers ([`crate::replay`]) name the file and line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    #[serde(flatten)]
    pub meta: FrameMeta,
    /// `flags` has [`crate::frame::FrameFlags::LATE`].
    pub late: bool,
    /// `flags` has [`crate::frame::FrameFlags::EXTRAPOLATED`].
    pub extrapolated: bool,
    pub payload_len: u64,
    /// CRC-32/ISO-HDLC of the payload, as in the header.
    pub payload_crc32: u32,
    pub file: String,
    /// Ground truth written beside the image (`hilcam replay --truth`), absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<TruthRecord>,
    /// How the frame's Monte Carlo noise compared with the camera's (DN frames with a
    /// detector; [`crate::sensor::McNoiseStats`]), absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mc_noise: Option<crate::sensor::McNoiseStats>,
}

/// What a frame's log line says of its ground truth ([`crate::render::truth`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthRecord {
    /// The truth EXR's name, beside the image.
    pub file: String,
    /// Its channels, comma-separated (`depth,mask,normal,body_xyz`).
    pub channels: String,
    /// Pixels whose centre ray hits the target (nonzero mask).
    pub target_pixels: u64,
    /// Their mean centre, continuous pixel coordinates [x, y] (pixel (col, row) has its
    /// centre at (col + 0.5, row + 0.5)); absent when no pixel centre sees the target.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_centroid_px: Option<[f64; 2]>,
    /// Their bounding box [col0, row0, col1, row1], half-open; absent with the centroid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_bbox_px: Option<[u32; 4]>,
}

impl TruthRecord {
    /// The log entry of `truth` written as `file`.
    pub fn new(file: String, truth: &crate::render::truth::TruthImage) -> TruthRecord {
        let f = truth.footprint();
        TruthRecord {
            file,
            channels: truth.channels.to_string(),
            target_pixels: f.map_or(0, |f| f.pixels),
            target_centroid_px: f.map(|f| f.centroid_px),
            target_bbox_px: f.map(|f| f.bbox_px),
        }
    }
}

impl FrameRecord {
    pub fn new(meta: &FrameMeta, payload: &[u8], file: String) -> FrameRecord {
        FrameRecord {
            meta: *meta,
            late: meta.flags.late(),
            extrapolated: meta.flags.extrapolated(),
            payload_len: payload.len() as u64,
            payload_crc32: crate::frame::CRC32.checksum(payload),
            file,
            truth: None,
            mc_noise: None,
        }
    }
}

/// Recorder settings.
#[derive(Clone, Debug)]
pub struct RecorderConfig {
    /// Output directory (created if missing); holds the images and `frames.jsonl`.
    pub dir: PathBuf,
    pub format: ImageFormat,
    /// Frames waiting for the disk before new ones are refused (default 8).
    pub queue_depth: usize,
    /// While writes keep failing, report "still failing" at most this often (default 5 s).
    pub failure_report_every: Duration,
}

impl RecorderConfig {
    pub fn new(dir: impl Into<PathBuf>, format: ImageFormat) -> Self {
        RecorderConfig { dir: dir.into(), format, queue_depth: 8, failure_report_every: Duration::from_secs(5) }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum RecorderError {
    #[error("recorder: {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    /// The image file could not be written (the error names the file).
    #[error("{0}")]
    Image(ImageWriteError),
    /// The truth EXR could not be written (the error names the file).
    #[error("{0}")]
    Truth(super::truth_exr::TruthWriteError),
    #[error("recorder thread panicked")]
    Panicked,
}

/// What the recorder did, returned by [`Recorder::finish`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecorderStats {
    pub written: u64,
    /// Refused because the queue was full (disk slower than the frame rate).
    pub dropped: u64,
    /// Frames not saved because a write failed (all reasons).
    pub errors: u64,
    /// Of those, because the disk was full.
    pub disk_full: u64,
}

/// The error counters, one per [`Reason`] plus the recorder thread having stopped.
#[derive(Clone)]
struct ErrorCounters {
    by_reason: Vec<(Reason, Counter)>,
    stopped: Counter,
}

impl ErrorCounters {
    fn new(registry: &Registry) -> ErrorCounters {
        let c = |label| {
            registry.counter(
                "hilcam_recorder_errors_total",
                "Frames the recorder could not save: disk_full, io, encode, or stopped (writer thread gone)",
                &[("reason", label)],
            )
        };
        ErrorCounters { by_reason: Reason::ALL.iter().map(|r| (*r, c(r.label()))).collect(), stopped: c("stopped") }
    }

    fn get(&self, r: Reason) -> &Counter {
        &self.by_reason.iter().find(|(x, _)| *x == r).expect("a counter per reason").1
    }

    fn total(&self) -> u64 {
        self.by_reason.iter().map(|(_, c)| c.get()).sum::<u64>() + self.stopped.get()
    }
}

/// A running recorder; [`Recorder::publish`] never blocks.
pub struct Recorder {
    tx: SyncSender<Arc<EncodedFrame>>,
    thread: std::thread::JoinHandle<Result<(), RecorderError>>,
    written: Counter,
    dropped: Counter,
    errors: ErrorCounters,
}

/// Name of the metadata log inside the recorder directory.
pub const LOG_NAME: &str = "frames.jsonl";

impl Recorder {
    /// Create the directory and `frames.jsonl` (appending), start the writer thread.
    pub fn start(cfg: RecorderConfig, registry: &Registry) -> Result<Recorder, RecorderError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| RecorderError::Io { path, source }
        };
        std::fs::create_dir_all(&cfg.dir).map_err(io(&cfg.dir))?;
        let log_path = cfg.dir.join(LOG_NAME);
        let mut log = LineLog::open(&log_path).map_err(io(&log_path))?;
        let written = registry.counter("hilcam_recorder_frames_written_total", "Frames saved by the recorder", &[]);
        let dropped = registry.counter(
            "hilcam_recorder_frames_dropped_total",
            "Frames the recorder refused because its queue was full (disk too slow)",
            &[],
        );
        let errors = ErrorCounters::new(registry);
        let (tx, rx) = mpsc::sync_channel::<Arc<EncodedFrame>>(cfg.queue_depth.max(1));
        let (w, e) = (written.clone(), errors.clone());
        let thread = std::thread::Builder::new()
            .name("hilcam-recorder".into())
            .spawn(move || {
                let mut failures = FailureLog::new(format!("recorder {}", cfg.dir.display()), cfg.failure_report_every);
                for frame in rx {
                    match record_one(&cfg, &frame, &mut log) {
                        Ok(()) => {
                            w.inc();
                            failures.succeeded();
                        }
                        Err((reason, err)) => {
                            e.get(reason).inc();
                            failures.failed(reason, &err);
                        }
                    }
                }
                failures.finish();
                Ok(())
            })
            .map_err(io(Path::new("<recorder thread>")))?;
        Ok(Recorder { tx, thread, written, dropped, errors })
    }

    /// Queue a frame for the disk; returns false (and counts a drop) if the queue is full.
    pub fn publish(&self, frame: Arc<EncodedFrame>) -> bool {
        match self.tx.try_send(frame) {
            Ok(()) => true,
            Err(TrySendError::Full(f)) => {
                self.dropped.inc();
                tracing::warn!(seq = f.meta.frame_seq, "recorder queue full: frame not saved");
                false
            }
            Err(TrySendError::Disconnected(f)) => {
                self.errors.stopped.inc();
                tracing::error!(seq = f.meta.frame_seq, "recorder thread has stopped");
                false
            }
        }
    }

    /// Write out everything queued, close the log, and return the totals. Blocks: call
    /// it from `spawn_blocking` in async code ([`super::Sink::close`] does).
    pub fn finish(self) -> Result<RecorderStats, RecorderError> {
        drop(self.tx);
        self.thread.join().map_err(|_| RecorderError::Panicked)??;
        Ok(RecorderStats {
            written: self.written.get(),
            dropped: self.dropped.get(),
            errors: self.errors.total(),
            disk_full: self.errors.get(Reason::DiskFull).get(),
        })
    }
}

/// Save one frame: its truth EXR when it carries truth, the image (each whole or not at
/// all), then its log line; when a later step fails the files already written are
/// removed again, so the log never misses a file present nor claims one absent.
fn record_one(cfg: &RecorderConfig, frame: &EncodedFrame, log: &mut LineLog) -> Result<(), (Reason, RecorderError)> {
    let Some(truth) = &frame.truth else { return record_image(cfg, frame, log, None) };
    let name = super::truth_exr::truth_file_name(frame.meta.frame_seq);
    let path = cfg.dir.join(&name);
    super::truth_exr::write_truth_exr(&path, truth).map_err(|e| {
        let reason = match &e {
            e if e.is_disk_full() => Reason::DiskFull,
            super::truth_exr::TruthWriteError::Io { .. } => Reason::Io,
            _ => Reason::Encode,
        };
        (reason, RecorderError::Truth(e))
    })?;
    record_image(cfg, frame, log, Some(TruthRecord::new(name, truth))).inspect_err(|_| remove(&path))
}

fn remove(path: &Path) {
    if let Err(e) = std::fs::remove_file(path) {
        tracing::error!(file = %path.display(), "cannot remove the file of a frame not logged: {e}");
    }
}

/// Save the image, then the log line (with `truth`, whose file is written already).
fn record_image(
    cfg: &RecorderConfig,
    frame: &EncodedFrame,
    log: &mut LineLog,
    truth: Option<TruthRecord>,
) -> Result<(), (Reason, RecorderError)> {
    let m = &frame.meta;
    let name = frame_file_name(m.frame_seq, cfg.format);
    let path = cfg.dir.join(&name);
    write_frame_image(&path, m.width, m.height, &frame.pixels(), cfg.format).map_err(|e| {
        let reason = match &e {
            e if e.is_disk_full() => Reason::DiskFull,
            ImageWriteError::Io { .. } => Reason::Io,
            _ => Reason::Encode,
        };
        (reason, RecorderError::Image(e))
    })?;
    let rec = FrameRecord { truth, mc_noise: frame.mc_noise, ..FrameRecord::new(m, frame.payload(), name) };
    let line = serde_json::to_string(&rec).expect("FrameRecord serialises");
    log.append(&line).map_err(|source| {
        let reason = if film::is_disk_full(&source) { Reason::DiskFull } else { Reason::Io };
        remove(&path);
        (reason, RecorderError::Io { path: log.path().to_path_buf(), source })
    })
}
