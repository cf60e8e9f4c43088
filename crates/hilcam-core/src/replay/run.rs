//! What `hilcam replay` does, without the command line: load the trajectory and scene (or
//! the recorded session), check them, build the pipeline and render into the output
//! directory until done or until the [`Shutdown`] is triggered. The CLI parses flags,
//! picks the shard, draws the progress and prints the summary.

use super::{FrameJob, ReplayConfig, ReplayStats, Shard, pin_integration_time, replay_jobs_until};
use super::{session_jobs, trajectory_jobs};
use crate::frame::FrameFlags;
use crate::pipeline::FramePipeline;
use crate::pose::trajectory::Trajectory;
use crate::pose::validate::{check_pose, describe};
use crate::render::integrator::{QualityMode, SamplerKind, Spp};
use crate::render::truth::TruthChannels;
use crate::scene::limits::checked_scaled_camera;
use crate::session::Session;
use crate::shutdown::Shutdown;
use crate::sink::recorder::ImageFormat;
use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// One replay run: where the frames come from and where they go.
#[derive(Clone, Debug)]
pub struct ReplayRequest {
    pub source: ReplaySource,
    /// Output directory: images `frame_<k>.<ext>` and `frames*.jsonl`.
    pub out: PathBuf,
    pub format: ImageFormat,
    /// Render every `every`-th frame only.
    pub every: u64,
    pub shard: Shard,
    /// Ground-truth channels written beside each frame; empty: none.
    pub truth: TruthChannels,
}

#[derive(Clone, Debug)]
pub enum ReplaySource {
    /// A trajectory CSV: row k is frame k with pose seq k, rendered with `scene`.
    Trajectory { trajectory: PathBuf, scene: PathBuf, overrides: TrajectoryOverrides },
    /// A recorded `serve` session, re-rendered frame for frame with its own poses,
    /// settings and seeds. `scene`: None renders with the scene the session names.
    /// `verify`: each frame must match the streamed payload CRC.
    Session { session: PathBuf, scene: Option<PathBuf>, verify: bool },
}

/// What a trajectory replay changes of the scene's camera and render settings.
#[derive(Clone, Copy, Debug, Default)]
pub struct TrajectoryOverrides {
    pub width: Option<u32>,
    pub spp: Option<Spp>,
    pub depth: Option<u32>,
    pub sampler: Option<SamplerKind>,
    pub seed: Option<u64>,
    pub quality: Option<QualityMode>,
    pub sensor_k: Option<f32>,
    /// A fixed integration time (s) in place of auto-exposure.
    pub integration_s: Option<f64>,
}

/// What [`run`] tells its caller while it runs.
pub enum ReplayEvent<'a> {
    /// Everything is loaded and checked, rendering starts: what will be rendered, in one line.
    Started(&'a str),
    /// After every frame (rendered or skipped).
    Progress(&'a ReplayStats),
}

/// What a finished run did.
#[derive(Clone, Debug)]
pub struct ReplayOutcome {
    pub stats: ReplayStats,
    /// This run's frame log.
    pub log: PathBuf,
    /// Time from [`ReplayEvent::Started`] to the end.
    pub elapsed: Duration,
    /// Every rendered frame was checked bit-identical to the session's stream.
    pub verified: bool,
}

/// Run `request` until its frames are done or `shutdown` is triggered (the frame in hand
/// is finished and logged, then [`super::ReplayError::Interrupted`] names the cause).
///
/// # Errors
/// Unreadable or refused inputs (each message names the file), or the render's
/// [`super::ReplayError`] in the context `replay`.
pub fn run(
    request: &ReplayRequest,
    shutdown: &Shutdown,
    mut on: impl FnMut(ReplayEvent<'_>),
) -> anyhow::Result<ReplayOutcome> {
    let (mut pipeline, jobs, cfg, line) = match &request.source {
        ReplaySource::Trajectory { trajectory, scene, overrides } => {
            prepare_trajectory(request, trajectory, scene, overrides)?
        }
        ReplaySource::Session { session, scene, verify } => {
            prepare_session(request, session, scene.as_deref(), *verify)?
        }
    };
    on(ReplayEvent::Started(&line));
    let t0 = Instant::now();
    let stats =
        replay_jobs_until(&mut pipeline, &jobs, &cfg, |s| on(ReplayEvent::Progress(s)), shutdown).context("replay")?;
    let verified = matches!(request.source, ReplaySource::Session { verify: true, .. });
    Ok(ReplayOutcome { stats, log: cfg.out_dir.join(cfg.shard.log_name()), elapsed: t0.elapsed(), verified })
}

type Prepared = (FramePipeline, Vec<FrameJob>, ReplayConfig, String);

fn prepare_trajectory(
    r: &ReplayRequest,
    traj: &Path,
    scene_path: &Path,
    o: &TrajectoryOverrides,
) -> anyhow::Result<Prepared> {
    // The scene first: its [limits] and planet set the gate every row passes.
    let mut scene = crate::scene::load(scene_path)?;
    let mut samples = Trajectory::load_gated(traj, &scene.pose_limits())?;
    if let Some(t) = o.integration_s {
        pin_integration_time(&mut scene, t)?;
    }
    let settings = scene.render.overridden(o.spp, o.depth, o.sampler, o.seed).with_quality(o.quality, o.sensor_k);
    let camera = checked_scaled_camera(&scene.camera, o.width, None).map_err(anyhow::Error::msg)?;
    let pipeline = FramePipeline::new(Arc::new(scene), camera.clone())?;
    if pipeline.exposure_timing(None).integrates_motion() {
        // The camera integrates over its exposure: rows without rates move as their
        // neighbours say.
        crate::pose::rates::fill_missing_rates(&mut samples);
    }
    let cfg = config(r, settings, identity(traj, false)?, identity(scene_path, true)?);
    let line = format!(
        "{}: {} poses → {}",
        traj.display(),
        samples.len(),
        run_summary(r, (camera.width, camera.height), &settings, "spp")
    );
    let jobs = trajectory_jobs(&samples, &settings);
    Ok((pipeline, jobs, cfg, line))
}

/// A session's streamed frames, each checked against the streamed CRC when `verify`.
fn prepare_session(r: &ReplayRequest, path: &Path, given: Option<&Path>, verify: bool) -> anyhow::Result<Prepared> {
    let session = Session::load(path)?;
    let h = &session.header;
    let jobs = session_jobs(&session, verify);
    match &session.end {
        None => tracing::warn!("{}: no end line (the server did not stop cleanly)", path.display()),
        Some(e) if e.records_dropped > 0 => tracing::warn!(
            "{}: the server dropped {} session lines; frames missing from the file are not re-rendered",
            path.display(),
            e.records_dropped
        ),
        Some(_) => {}
    }
    let gaps = session.frame_gaps();
    if !gaps.is_empty() {
        tracing::warn!("{}: {} frame indices missing (first {})", path.display(), gaps.len(), gaps[0]);
    }
    let scene_path = given.map_or_else(|| PathBuf::from(&h.scene), Path::to_path_buf);
    let scene = crate::scene::load(&scene_path)?;
    // The recorded poses passed the gate when they arrived; a file edited since must pass
    // it again (rendered as recorded, so the streamed CRCs still check).
    let limits = scene.pose_limits();
    for j in &jobs {
        if let Err(reason) = check_pose(&j.pose, &limits) {
            bail!(
                "{}: frame {} (pose seq {}): pose refused: {reason} ({})",
                path.display(),
                j.index,
                j.pose.seq,
                describe(&j.pose, reason, &limits)
            );
        }
    }
    let camera = scene.camera.scaled(h.width_setting, None);
    if (camera.width, camera.height) != (h.width, h.height) {
        bail!(
            "{}: the session streamed {}x{} frames, {} gives {}x{} (width setting {:?})",
            path.display(),
            h.width,
            h.height,
            scene_path.display(),
            camera.width,
            camera.height,
            h.width_setting
        );
    }
    let pipeline = FramePipeline::new(Arc::new(scene), camera)?;
    let settings = h.settings.to_settings();
    let cfg = config(r, settings, identity(path, false)?, identity(&scene_path, true)?);
    let flagged = |bit| jobs.iter().filter(|j| j.flags.contains(bit)).count();
    let line = format!(
        "{}: {} frames ({} degraded, {} extrapolated, {} late) of {} poses → {}",
        path.display(),
        jobs.len(),
        flagged(FrameFlags::DEGRADED),
        flagged(FrameFlags::EXTRAPOLATED),
        flagged(FrameFlags::LATE),
        session.poses.len(),
        run_summary(r, (h.width, h.height), &settings, "best spp")
    );
    Ok((pipeline, jobs, cfg, line))
}

/// The start line's tail: where the frames go, their size and settings, and the shard.
fn run_summary(
    r: &ReplayRequest,
    (width, height): (u32, u32),
    s: &crate::render::integrator::RenderSettings,
    spp: &str,
) -> String {
    format!(
        "{} ({width}x{height}, {spp} {} depth {} {:?}, seed {}), shard {}/{}, every {}",
        r.out.display(),
        s.spp,
        s.depth,
        s.sampler,
        s.seed,
        r.shard.index,
        r.shard.count,
        r.every
    )
}

fn config(
    r: &ReplayRequest,
    settings: crate::render::integrator::RenderSettings,
    source: String,
    scene: String,
) -> ReplayConfig {
    ReplayConfig {
        out_dir: r.out.clone(),
        format: r.format,
        settings,
        every: r.every,
        shard: r.shard,
        source,
        scene,
        truth: r.truth,
    }
}

/// A file's identity for the manifest: its absolute path, plus a content checksum.
fn identity(p: &Path, content: bool) -> anyhow::Result<String> {
    let abs = std::fs::canonicalize(p).with_context(|| p.display().to_string())?;
    if !content {
        return Ok(abs.display().to_string());
    }
    let bytes = std::fs::read(&abs).with_context(|| abs.display().to_string())?;
    Ok(format!("{} (crc32 {:08x})", abs.display(), crate::frame::CRC32.checksum(&bytes)))
}
