//! Offline replay: every pose of a trajectory rendered through [`FramePipeline`] to image
//! files plus one JSON line per frame ([`FrameRecord`], the recorder's format).
//!
//! - Frame index = pose seq = trajectory row index, so replayed frame k is exactly
//!   `FramePipeline::frame(&samples[k].to_pose(k), settings, k)`: the same payload bytes
//!   (and CRC) as the live frame from a fresh pipeline fed the same poses in order.
//! - Resumable: each image is written under a temporary name and renamed
//!   ([`crate::render::film::write_file_atomically`]), then its line is appended whole
//!   ([`crate::sink::line_log`]); on start the done set is rebuilt from every
//!   `frames*.jsonl` in the directory (a truncated last line is tolerated, and cut from
//!   our own log). A full disk stops the run with [`ReplayError::DiskFull`] and leaves
//!   no partial file; a [`Shutdown`] ([`replay_jobs_until`], [`run`]; the CLI's SIGINT/
//!   SIGTERM/SIGHUP) ends it after the frame in hand with [`ReplayError::Interrupted`].
//!   Either way the same command resumes.
//! - [`run`]: what `hilcam replay` does, from a [`ReplayRequest`] (a trajectory and a
//!   scene, or a recorded session) to the frames on disk.
//! - Sharding: shard K/N renders the selected frames whose position j has j mod N = K,
//!   logging to `frames.shard-K-of-N.jsonl`; [`merge`] combines the logs.
//! - Auto-exposure carries state from frame to frame, so a shard, a resumed run or
//!   `every > 1` would not see the live exposure history: [`replay`] refuses them unless
//!   the integration time is pinned ([`pin_integration_time`]).
//! - Sessions: [`replay_jobs`] renders any list of [`FrameJob`]s — a recorded `serve`
//!   session's frames ([`session_jobs`]) with their own poses, settings and
//!   indices, each checked against the CRC that was streamed.
//! - The directory's [`manifest`] pins scene, size and settings: a resume with others is refused.

use crate::frame::{FrameFlags, FrameMeta, unix_ns_now};
use crate::pipeline::{FramePipeline, FrameRequest};
use crate::pose::trajectory::TrajectorySample;
use crate::render::integrator::RenderSettings;
use crate::render::truth::TruthChannels;
use crate::scene::Scene;
use crate::sensor::SensorError;
use crate::shutdown::Shutdown;
use crate::sink::line_log::LineLog;
use crate::sink::recorder::{FrameRecord, ImageFormat, TruthRecord, frame_file_name, write_frame_image};
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

/// Name of an unsharded replay's metadata log (the recorder's name).
pub const LOG_NAME: &str = crate::sink::recorder::LOG_NAME;

pub mod manifest;
mod run;
mod shard;
/// The truth EXR writer, shared with the recorder (`hilcam serve`).
pub use crate::sink::truth_exr;
pub use run::{ReplayEvent, ReplayOutcome, ReplayRequest, ReplaySource, TrajectoryOverrides, run};
pub use shard::{SHARD_COUNT_VAR, Shard};

/// Errors of replay, sharding and merging; each names the file, line or variable.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}: not a frame record: {msg}")]
    BadLine { path: PathBuf, line: usize, msg: String },
    #[error("shard `{0}`: expected K/N with 0 ≤ K < N (e.g. 3/16)")]
    BadShard(String),
    #[error("environment variable {var}: {msg}")]
    Env { var: &'static str, msg: String },
    #[error(
        "the sensor has auto-exposure, whose state runs from frame to frame; {what} would not reproduce the live \
         exposures. Pin the integration time (--integration-s SECONDS) or render all frames in one run"
    )]
    AutoExposure { what: String },
    #[error("--integration-s: the sensor has no [sensor.detector], so there is no integration time to pin")]
    NoDetector,
    #[error("--integration-s {0}: must be finite and ≥ 0")]
    BadIntegration(f64),
    #[error("--every must be ≥ 1")]
    BadEvery,
    #[error("{path}:{line}: frame {frame} was rendered at {found}, this run renders {expected}; use another --out")]
    Mismatch { path: PathBuf, line: usize, frame: u64, found: String, expected: String },
    #[error(
        "{dir}: was rendered with {field} = {found}, this run has {field} = {expected}; resume with the same \
         settings, use another --out, or delete {dir}/{} to accept",
        manifest::MANIFEST_NAME
    )]
    ManifestMismatch { dir: PathBuf, field: &'static str, found: String, expected: String },
    #[error("{path}: not a replay manifest: {msg}")]
    BadManifest { path: PathBuf, msg: String },
    #[error(
        "frame {frame}: the re-rendered payload has CRC-32 {got:08x}, the session streamed {expected:08x}: the \
         scene, camera or hilcam version differs from the live run (--no-verify writes the frames anyway)"
    )]
    NotIdentical { frame: u64, expected: u32, got: u32 },
    #[error("frame {frame}: {source}")]
    Sensor { frame: u64, source: SensorError },
    #[error("frame {frame}: {path}: {msg}")]
    Image { frame: u64, path: PathBuf, msg: String },
    #[error(
        "{dir}: disk full: frame {frame} ({file}) could not be written ({msg}); {done} of {selected} frames are \
         complete there, none partial: free space and run the same command again to resume"
    )]
    DiskFull { dir: PathBuf, frame: u64, file: String, msg: String, done: u64, selected: u64 },
    #[error(
        "stopped by {signal}: {done} of {selected} frames are complete in {dir}{}; run the same command again to \
         resume",
        .last.map_or(String::new(), |k| format!(" (the last written: frame {k})"))
    )]
    Interrupted { signal: String, dir: PathBuf, done: u64, selected: u64, last: Option<u64> },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ReplayError + '_ {
    move |source| ReplayError::Io { path: path.to_path_buf(), source }
}

/// The frame indices a run renders, in order: every `every`-th row, then this shard's share.
pub fn select_frames(n_rows: u64, every: u64, shard: Shard) -> Vec<u64> {
    (0..n_rows)
        .step_by(every.max(1) as usize)
        .enumerate()
        .filter(|(j, _)| *j as u64 % shard.count == shard.index)
        .map(|(_, k)| k)
        .collect()
}

/// Pin the scene's sensor to a fixed integration time and switch auto-exposure off, so
/// any subset of frames renders independently of the others.
pub fn pin_integration_time(scene: &mut Scene, seconds: f64) -> Result<(), ReplayError> {
    if !(seconds.is_finite() && seconds >= 0.0) {
        return Err(ReplayError::BadIntegration(seconds));
    }
    let det = scene.sensor.detector.as_mut().ok_or(ReplayError::NoDetector)?;
    det.integration_time_s = seconds;
    scene.sensor.auto_exposure = None;
    Ok(())
}

/// What to render and where.
#[derive(Clone, Debug)]
pub struct ReplayConfig {
    pub out_dir: PathBuf,
    pub format: ImageFormat,
    pub settings: RenderSettings,
    /// Render every `every`-th trajectory row (≥ 1).
    pub every: u64,
    pub shard: Shard,
    /// What the poses come from (trajectory or session file), for the manifest.
    pub source: String,
    /// Which scene (path and content checksum), for the manifest.
    pub scene: String,
    /// Ground-truth channels written beside each frame (`truth_<k>.exr`); empty: none.
    pub truth: TruthChannels,
}

/// Progress after each frame (rendered or skipped).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReplayStats {
    /// Frames this run is responsible for.
    pub selected: u64,
    /// Rendered by this run.
    pub rendered: u64,
    /// Already done in the directory (resume).
    pub skipped: u64,
    /// Truncated trailing lines ignored while reading the logs.
    pub truncated_lines: u64,
    /// Time this run spent rendering frames (render + sensor) and computing their truth
    /// channels (zero without `truth`), for the cost of truth relative to a frame.
    pub frame_time: std::time::Duration,
    pub truth_time: std::time::Duration,
    /// Time spent encoding and writing the truth files.
    pub truth_write_time: std::time::Duration,
    /// Lit pixels of the rendered DN frames compared with the camera's noise, and those
    /// whose Monte Carlo noise was above the bound (summed `mc_noise` of the frames).
    pub mc_lit_pixels: u64,
    pub mc_above_bound: u64,
    /// The bound's k (the last such frame's: `[render] sensor_k`, default 0.5).
    pub mc_k: f64,
}

/// A frame log entry read back, with where it came from.
struct Done {
    rec: FrameRecord,
    path: PathBuf,
    line: usize,
}

/// All `frames*.jsonl` logs in `dir`, sorted by name.
pub fn log_files(dir: &Path) -> Result<Vec<PathBuf>, ReplayError> {
    let mut v = Vec::new();
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(v),
        Err(e) => return Err(ReplayError::Io { path: dir.to_path_buf(), source: e }),
    };
    for e in rd {
        let p = e.map_err(io(dir))?.path();
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.starts_with("frames") && name.ends_with(".jsonl") {
            v.push(p);
        }
    }
    v.sort();
    Ok(v)
}

/// Parse a log. A last line without its newline that does not parse is a write cut short
/// by a kill: it is skipped and counted; any other bad line is an error.
fn read_log(path: &Path, truncated: &mut u64) -> Result<Vec<Done>, ReplayError> {
    let text = std::fs::read_to_string(path).map_err(io(path))?;
    let mut out = Vec::new();
    let complete = text.ends_with('\n');
    let lines: Vec<&str> = text.lines().collect();
    for (i, l) in lines.iter().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<FrameRecord>(l) {
            Ok(rec) => out.push(Done { rec, path: path.to_path_buf(), line: i + 1 }),
            Err(_) if i + 1 == lines.len() && !complete => {
                *truncated += 1;
                tracing::warn!(file = %path.display(), line = i + 1, "ignoring a truncated last line");
            }
            Err(e) => return Err(ReplayError::BadLine { path: path.to_path_buf(), line: i + 1, msg: e.to_string() }),
        }
    }
    Ok(out)
}

/// Cut a log back to its last newline so that appended lines start on a line of their own.
fn trim_partial_line(path: &Path) -> Result<(), ReplayError> {
    let Ok(bytes) = std::fs::read(path) else { return Ok(()) };
    if bytes.is_empty() || bytes.ends_with(b"\n") {
        return Ok(());
    }
    let keep = bytes.iter().rposition(|b| *b == b'\n').map_or(0, |p| p + 1);
    let f = std::fs::OpenOptions::new().write(true).open(path).map_err(io(path))?;
    f.set_len(keep as u64).map_err(io(path))
}

/// The frames already complete in `dir`: a log line whose image file exists and is not
/// empty. A line rendered at another size or quality than this run gives that frame
/// (`expected(k)`) is refused.
fn done_frames(
    dir: &Path,
    truth: TruthChannels,
    expected: impl Fn(u64) -> (RenderSettings, (u32, u32)),
    stats: &mut ReplayStats,
) -> Result<HashSet<u64>, ReplayError> {
    let mut done = HashSet::new();
    for log in log_files(dir)? {
        for d in read_log(&log, &mut stats.truncated_lines)? {
            let r = &d.rec.meta;
            let (want, (w, h)) = expected(r.frame_seq);
            let (found, expected) = (
                format!("{}x{} spp {} depth {}", r.width, r.height, r.spp, r.depth),
                format!("{w}x{h} spp {} depth {}", want.spp, want.depth),
            );
            if found != expected {
                return Err(ReplayError::Mismatch { path: d.path, line: d.line, frame: r.frame_seq, found, expected });
            }
            let written = |file: &str| std::fs::metadata(dir.join(file)).is_ok_and(|m| m.len() > 0);
            // With truth on, a frame is done when its truth file is there too.
            let truth_done = truth.is_empty() || d.rec.truth.as_ref().is_some_and(|t| written(&t.file));
            if written(&d.rec.file) && truth_done {
                done.insert(r.frame_seq);
            }
        }
    }
    Ok(done)
}

/// One frame to render: its index (frame number and random-number domain), the pose and
/// settings to render it with, the flags to log, and optionally the payload CRC it must
/// reproduce (a session re-render checks every frame against what was streamed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameJob {
    pub index: u64,
    pub pose: crate::pose::Pose,
    pub settings: RenderSettings,
    pub flags: FrameFlags,
    pub expect_crc32: Option<u32>,
    /// What the camera client asked of the frame live (its exposure and ROI).
    pub request: FrameRequest,
}

/// The jobs of a trajectory: row k is frame k with pose seq k at `settings`.
pub fn trajectory_jobs(samples: &[TrajectorySample], settings: &RenderSettings) -> Vec<FrameJob> {
    (0..samples.len())
        .map(|k| FrameJob {
            index: k as u64,
            pose: samples[k].to_pose(k as u32),
            settings: *settings,
            flags: FrameFlags::default(),
            expect_crc32: None,
            request: FrameRequest::default(),
        })
        .collect()
}

/// The session's streamed frames as replay jobs: same index, pose, settings and flags,
/// and the streamed payload CRC to check the re-render against (`verify`).
pub fn session_jobs(session: &crate::session::Session, verify: bool) -> Vec<FrameJob> {
    session
        .frames
        .iter()
        .map(|f| FrameJob {
            index: f.index,
            pose: f.pose.to_pose(),
            settings: f.settings.to_settings(),
            flags: f.frame_flags(),
            expect_crc32: verify.then_some(f.payload_crc32),
            request: f.request,
        })
        .collect()
}

/// Render the selected frames of `samples` through `pipeline` into `cfg.out_dir`,
/// skipping frames already done; `progress` is called after every frame.
pub fn replay(
    pipeline: &mut FramePipeline,
    samples: &[TrajectorySample],
    cfg: &ReplayConfig,
    progress: impl FnMut(&ReplayStats),
) -> Result<ReplayStats, ReplayError> {
    replay_jobs(pipeline, &trajectory_jobs(samples, &cfg.settings), cfg, progress)
}

/// Render the selected `jobs` (every `cfg.every`-th, then this shard's share, by
/// position in `jobs`) into `cfg.out_dir`, skipping frames already done. `cfg.settings`
/// goes into the directory's manifest (a resume with other settings is refused); each
/// frame renders with its job's own settings.
pub fn replay_jobs(
    pipeline: &mut FramePipeline,
    jobs: &[FrameJob],
    cfg: &ReplayConfig,
    progress: impl FnMut(&ReplayStats),
) -> Result<ReplayStats, ReplayError> {
    replay_jobs_until(pipeline, jobs, cfg, progress, &Shutdown::new())
}

/// [`replay_jobs`], looking at `stop` before each frame: once triggered, the run ends
/// there (the frames before it are complete and logged) with [`ReplayError::Interrupted`]
/// naming its cause.
pub fn replay_jobs_until(
    pipeline: &mut FramePipeline,
    jobs: &[FrameJob],
    cfg: &ReplayConfig,
    mut progress: impl FnMut(&ReplayStats),
    stop: &Shutdown,
) -> Result<ReplayStats, ReplayError> {
    if cfg.every == 0 {
        return Err(ReplayError::BadEvery);
    }
    let dir = &cfg.out_dir;
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let full = (pipeline.camera().width, pipeline.camera().height);
    let size = |r: &FrameRequest| r.roi.map_or(full, |w| (w.width, w.height));
    let manifest = manifest::ReplayManifest::new(cfg, pipeline);
    let has_manifest = manifest::check(dir, &manifest)?;
    let mut stats = ReplayStats::default();
    let log_path = dir.join(cfg.shard.log_name());
    trim_partial_line(&log_path)?;
    let by_index: std::collections::HashMap<u64, (RenderSettings, (u32, u32))> =
        jobs.iter().map(|j| (j.index, (j.settings, size(&j.request)))).collect();
    let done = done_frames(dir, cfg.truth, |k| by_index.get(&k).copied().unwrap_or((cfg.settings, full)), &mut stats)?;
    let positions = select_frames(jobs.len() as u64, cfg.every, cfg.shard);
    stats.selected = positions.len() as u64;
    let todo: Vec<&FrameJob> =
        positions.iter().map(|&j| &jobs[j as usize]).filter(|job| !done.contains(&job.index)).collect();
    stats.skipped = stats.selected - todo.len() as u64;
    if pipeline.sensor().auto_exposure().is_some() && !todo.is_empty() {
        let gap = jobs.iter().enumerate().find(|(j, job)| job.index != *j as u64).map(|(j, _)| j as u64);
        let what = if cfg.shard.count > 1 {
            format!("shard {}/{}", cfg.shard.index, cfg.shard.count)
        } else if cfg.every > 1 {
            format!("--every {}", cfg.every)
        } else if stats.skipped > 0 || todo.first().map(|j| j.index) != Some(0) {
            format!("resuming ({} of {} frames already in {})", stats.skipped, stats.selected, dir.display())
        } else if let Some(k) = gap {
            format!("a frame list with frame {k} missing")
        } else {
            String::new()
        };
        if !what.is_empty() {
            return Err(ReplayError::AutoExposure { what });
        }
    }
    if !has_manifest {
        manifest::write(dir, &manifest)?;
    }
    let mut log = LineLog::open(&log_path).map_err(io(&log_path))?;
    progress(&stats);
    let mut last = None;
    // Kept from frame to frame: only the rows the last truth hit are cleared.
    let mut planes = crate::render::truth::TruthPlanes::default();
    for job in todo {
        let k = job.index;
        if stop.is_triggered() {
            let signal = stop.cause().unwrap_or("a stop request").to_string();
            let done = stats.skipped + stats.rendered;
            return Err(ReplayError::Interrupted { signal, dir: dir.clone(), done, selected: stats.selected, last });
        }
        let t0 = std::time::Instant::now();
        let f = pipeline
            .frame_requested(&job.pose, &job.settings, k, &job.request)
            .map_err(|source| ReplayError::Sensor { frame: k, source })?;
        stats.frame_time += t0.elapsed();
        let payload = f.pixels.to_le_bytes();
        let crc = crate::frame::CRC32.checksum(&payload);
        if let Some(want) = job.expect_crc32
            && want != crc
        {
            return Err(ReplayError::NotIdentical { frame: k, expected: want, got: crc });
        }
        let name = frame_file_name(k, cfg.format);
        let path = dir.join(&name);
        let done = stats.skipped + stats.rendered;
        let disk_full = |msg: String| ReplayError::DiskFull {
            dir: dir.clone(),
            frame: k,
            file: name.clone(),
            msg,
            done,
            selected: stats.selected,
        };
        // Whole or not at all: a failed write leaves no file behind.
        write_frame_image(&path, f.width, f.height, &f.pixels, cfg.format).map_err(|e| match e.is_disk_full() {
            true => disk_full(e.to_string()),
            false => ReplayError::Image { frame: k, path: path.clone(), msg: e.to_string() },
        })?;
        let mut record_truth = None;
        if !cfg.truth.is_empty() {
            let t0 = std::time::Instant::now();
            let truth = pipeline
                .truth_into(&job.pose, &job.request, cfg.truth, &mut planes)
                .map_err(|source| ReplayError::Sensor { frame: k, source })?;
            stats.truth_time += t0.elapsed();
            let truth_name = truth_exr::truth_file_name(k);
            let truth_path = dir.join(&truth_name);
            let t0 = std::time::Instant::now();
            let written = truth_exr::write_truth_exr(&truth_path, truth);
            stats.truth_write_time += t0.elapsed();
            if let Err(e) = written {
                // The image without its truth is not a complete frame.
                let _ = std::fs::remove_file(&path);
                return Err(match e.is_disk_full() {
                    true => ReplayError::DiskFull {
                        dir: dir.clone(),
                        frame: k,
                        file: truth_name,
                        msg: e.to_string(),
                        done,
                        selected: stats.selected,
                    },
                    false => ReplayError::Image { frame: k, path: truth_path, msg: e.to_string() },
                });
            }
            record_truth = Some(TruthRecord::new(truth_name, truth));
        }
        let mut meta = FrameMeta::rendered(k, &job.pose, &f, job.flags);
        meta.emit_unix_ns = unix_ns_now();
        let mut record = FrameRecord::new(&meta, &payload, name.clone());
        record.truth = record_truth;
        record.mc_noise = f.mc_noise;
        if let Some(mc) = &f.mc_noise {
            stats.mc_lit_pixels += mc.lit_pixels;
            stats.mc_above_bound += mc.above_bound;
            stats.mc_k = mc.k;
        }
        let line = serde_json::to_string(&record).expect("FrameRecord serialises");
        if let Err(e) = log.append(&line) {
            // The log must not miss a file that is present: take the image back out.
            let _ = std::fs::remove_file(&path);
            if let Some(t) = &record.truth {
                let _ = std::fs::remove_file(dir.join(&t.file));
            }
            let msg = format!("{}: {e}", log_path.display());
            return Err(if crate::render::film::is_disk_full(&e) { disk_full(msg) } else { io(&log_path)(e) });
        }
        last = Some(k);
        stats.rendered += 1;
        progress(&stats);
    }
    Ok(stats)
}

/// What [`merge`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergeStats {
    pub logs: usize,
    pub frames: u64,
    /// Frame indices missing between 0 and the highest one present, at the stride of the
    /// indices present (the gcd, so a `--every K` run has no gaps).
    pub gaps: Vec<u64>,
}

/// Merge every `frames*.jsonl` in `dir` into `frames.jsonl`, one line per frame in frame
/// order (a frame logged twice, e.g. re-rendered after its file was lost, keeps its last
/// line). Written to a temporary file and renamed; the shard logs are left in place.
pub fn merge(dir: &Path) -> Result<MergeStats, ReplayError> {
    let logs = log_files(dir)?;
    let mut truncated = 0;
    let mut by_frame = BTreeMap::new();
    for log in &logs {
        for d in read_log(log, &mut truncated)? {
            by_frame.insert(d.rec.meta.frame_seq, d.rec);
        }
    }
    let tmp = dir.join(".frames.jsonl.merge");
    let mut text = String::new();
    for r in by_frame.values() {
        text.push_str(&serde_json::to_string(r).expect("FrameRecord serialises"));
        text.push('\n');
    }
    std::fs::write(&tmp, text).map_err(io(&tmp))?;
    let out = dir.join(LOG_NAME);
    std::fs::rename(&tmp, &out).map_err(io(&out))?;
    // The stride of a `--every K` run: the gcd of the frame indices present.
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let step = by_frame.keys().fold(0, |g, k| gcd(g, *k)).max(1);
    let last = by_frame.keys().next_back().copied();
    let gaps =
        last.map_or(Vec::new(), |l| (0..l).step_by(step as usize).filter(|k| !by_frame.contains_key(k)).collect());
    Ok(MergeStats { logs: logs.len(), frames: by_frame.len() as u64, gaps })
}
