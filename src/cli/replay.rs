//! `hilcam replay`: render a trajectory offline to files (resumable, shardable), or
//! re-render a recorded `serve` session frame for frame (`--session`).
//!
//! SIGINT, SIGTERM (Slurm's `scancel`, `docker stop`) and SIGHUP let the frame in hand
//! finish and be written, then stop with a non-zero exit and a message saying how many
//! frames are complete; the same command resumes. A second signal exits at once (frames
//! are written whole or not at all, so even that leaves no partial frame).

use super::parse_sensor_k;
use anyhow::{Context, bail};
use hilcam_core::frame::FrameFlags;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::trajectory::Trajectory;
use hilcam_core::pose::validate::{check_pose, describe};
use hilcam_core::render::integrator::{QualityMode, SamplerKind};
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::replay::session_jobs;
use hilcam_core::replay::{
    FrameJob, ReplayConfig, ReplayStats, Shard, merge, pin_integration_time, replay_jobs_until, trajectory_jobs,
};
use hilcam_core::scene::file::parse_name;
use hilcam_core::scene::limits::checked_scaled_camera;
use hilcam_core::serve::config::ServeConfig;
use hilcam_core::session::Session;
use hilcam_core::sink::recorder::ImageFormat;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// Trajectory CSV (docs/trajectory.md); row k becomes frame k with pose seq k.
    #[arg(long, required_unless_present_any = ["merge", "session"])]
    pub trajectory: Option<PathBuf>,
    /// Scene file (TOML).
    #[arg(long, required_unless_present_any = ["merge", "session"])]
    pub scene: Option<PathBuf>,
    /// Session file recorded by `hilcam serve` ([record] session, docs/session.md):
    /// re-render exactly the frames it streamed, with their poses, settings and seeds.
    #[arg(long, conflicts_with_all = ["trajectory", "spp", "depth", "sampler", "seed", "integration_s", "width"])]
    pub session: Option<PathBuf>,
    /// With --session: the serve config or scene file (default: the scene the session names).
    #[arg(long, requires = "session", conflicts_with = "scene")]
    pub config: Option<PathBuf>,
    /// With --session: write frames even when one differs from what was streamed (by CRC).
    #[arg(long, requires = "session")]
    pub no_verify: bool,
    /// Output directory: images `frame_<k>.<ext>` and `frames*.jsonl`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Merge the shard logs of DIR into DIR/frames.jsonl and exit.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["trajectory", "scene", "out", "session"])]
    pub merge: Option<PathBuf>,
    /// Render at this many columns (same field of view; default: the camera's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Samples per pixel, ≥ 1 (default: the scene's); a fraction such as 1.25 gives
    /// every pixel one sample and shares the rest out where the pilot saw variance
    #[arg(long)]
    pub spp: Option<hilcam_core::render::integrator::Spp>,
    #[arg(long)]
    pub depth: Option<u32>,
    #[arg(long, value_parser = parse_name::<SamplerKind>)]
    pub sampler: Option<SamplerKind>,
    /// `sensor`: give each pixel samples until its Monte Carlo noise is below `--sensor-k`
    /// × the camera's own temporal noise there, `--spp` being the frame's budget (average
    /// per sampled pixel); `fixed`: `--spp` samples (default: the scene's).
    #[arg(long, value_parser = parse_name::<QualityMode>)]
    pub quality: Option<QualityMode>,
    /// The Monte Carlo noise bound as a fraction of the camera's temporal noise, in (0, 10]
    /// (default: the scene's `render.sensor_k`, 0.5); every frame's noise report uses it.
    #[arg(long, value_parser = parse_sensor_k)]
    pub sensor_k: Option<f32>,
    #[arg(long)]
    pub seed: Option<u64>,
    #[arg(long, value_parser = parse_name::<ImageFormat>, default_value = "png")]
    pub format: ImageFormat,
    /// Render every K-th trajectory row only.
    #[arg(long, default_value_t = 1)]
    pub every: u64,
    /// Render shard K of N (`K/N`, 0-based). Default: SLURM_ARRAY_TASK_ID of HILCAM_SHARD_COUNT
    /// (or of SLURM_ARRAY_TASK_COUNT for an array 0-(N-1)), JOB_COMPLETION_INDEX of
    /// HILCAM_SHARD_COUNT, else the whole trajectory.
    #[arg(long)]
    pub shard: Option<String>,
    /// Fixed sensor integration time (s), replacing auto-exposure; needed to shard or
    /// resume a scene whose sensor has auto-exposure.
    #[arg(long)]
    pub integration_s: Option<f64>,
    /// Ground-truth channels to write beside each frame as `truth_<k>.exr` (comma-separated:
    /// depth, mask, normal, body_xyz; docs/cluster.md).
    #[arg(long, value_parser = TruthChannels::parse, value_name = "CHANNELS")]
    pub truth: Option<TruthChannels>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

pub fn run(a: ReplayArgs) -> anyhow::Result<()> {
    if let Some(dir) = &a.merge {
        let m = merge(dir)?;
        println!("{}: merged {} logs, {} frames into frames.jsonl", dir.display(), m.logs, m.frames);
        if !m.gaps.is_empty() {
            println!("missing frames ({}): {:?}", m.gaps.len(), &m.gaps[..m.gaps.len().min(20)]);
        }
        return Ok(());
    }
    let Some(out) = a.out.clone() else { bail!("--out DIR is required") };
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let shard = match &a.shard {
        Some(s) => Shard::parse(s)?,
        None => Shard::from_env(|v| std::env::var(v).ok())?.unwrap_or(Shard::ALL),
    };
    if let Some(session) = &a.session {
        return run_session(&a, session, out, shard);
    }
    let (Some(traj), Some(scene_path)) = (&a.trajectory, &a.scene) else {
        bail!("--trajectory and --scene are required")
    };
    // The scene first: its [limits] and planet set the gate every row passes.
    let mut scene = hilcam_core::scene::load(scene_path)?;
    let mut samples = Trajectory::load_gated(traj, &scene.pose_limits())?;
    if let Some(t) = a.integration_s {
        pin_integration_time(&mut scene, t)?;
    }
    let settings = scene.render.overridden(a.spp, a.depth, a.sampler, a.seed).with_quality(a.quality, a.sensor_k);
    let camera = checked_scaled_camera(&scene.camera, a.width, None).map_err(anyhow::Error::msg)?;
    let mut pipeline = FramePipeline::new(Arc::new(scene), camera.clone())?;
    if pipeline.exposure_timing(None).integrates_motion() {
        // The camera integrates over its exposure: rows without rates move as their
        // neighbours say.
        hilcam_core::pose::rates::fill_missing_rates(&mut samples);
    }
    let cfg = ReplayConfig {
        out_dir: out.clone(),
        format: a.format,
        settings,
        every: a.every,
        shard,
        source: identity(traj, false)?,
        scene: identity(scene_path, true)?,
        truth: a.truth.unwrap_or_default(),
    };
    println!(
        "{}: {} poses → {} ({}x{}, spp {} depth {} {:?}, seed {}), shard {}/{}, every {}",
        traj.display(),
        samples.len(),
        out.display(),
        camera.width,
        camera.height,
        settings.spp,
        settings.depth,
        settings.sampler,
        settings.seed,
        shard.index,
        shard.count,
        a.every
    );
    render(&mut pipeline, &trajectory_jobs(&samples, &settings), &cfg).map(|_| ())
}

/// `--session`: the session's streamed frames, each checked against the streamed CRC.
fn run_session(a: &ReplayArgs, path: &Path, out: PathBuf, shard: Shard) -> anyhow::Result<()> {
    let session = Session::load(path)?;
    let h = &session.header;
    let jobs = session_jobs(&session, !a.no_verify);
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
    // The scene: a serve config's, a scene file, or the one the session names.
    let given = a.config.as_ref().or(a.scene.as_ref());
    let scene_path = match given {
        Some(p) if is_serve_config(p)? => ServeConfig::load(p)?.scene,
        Some(p) => p.clone(),
        None => PathBuf::from(&h.scene),
    };
    let scene = hilcam_core::scene::load(&scene_path)?;
    // The recorded poses passed the gate when they arrived; a file edited since must pass
    // it again (rendered as recorded, so the streamed CRCs still check).
    let limits = scene.pose_limits();
    for j in &jobs {
        if let Err(r) = check_pose(&j.pose, &limits) {
            bail!(
                "{}: frame {} (pose seq {}): pose refused: {r} ({})",
                path.display(),
                j.index,
                j.pose.seq,
                describe(&j.pose, r, &limits)
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
    let mut pipeline = FramePipeline::new(Arc::new(scene), camera)?;
    let settings = h.settings.to_settings();
    let cfg = ReplayConfig {
        out_dir: out.clone(),
        format: a.format,
        settings,
        every: a.every,
        shard,
        source: identity(path, false)?,
        scene: identity(&scene_path, true)?,
        truth: a.truth.unwrap_or_default(),
    };
    let flagged = |bit| jobs.iter().filter(|j| j.flags.contains(bit)).count();
    println!(
        "{}: {} frames ({} degraded, {} extrapolated, {} late) of {} poses → {} ({}x{}, best spp {} depth {} {:?}, \
         seed {}), shard {}/{}, every {}",
        path.display(),
        jobs.len(),
        flagged(FrameFlags::DEGRADED),
        flagged(FrameFlags::EXTRAPOLATED),
        flagged(FrameFlags::LATE),
        session.poses.len(),
        out.display(),
        h.width,
        h.height,
        settings.spp,
        settings.depth,
        settings.sampler,
        settings.seed,
        shard.index,
        shard.count,
        a.every
    );
    let stats = render(&mut pipeline, &jobs, &cfg)?;
    if !a.no_verify && stats.rendered > 0 {
        println!("{} frames re-rendered, each bit-identical to the stream (payload CRC-32 checked)", stats.rendered);
    }
    Ok(())
}

/// A serve config names its scene with a top-level `scene = "…"`; a scene file does not.
fn is_serve_config(p: &Path) -> anyhow::Result<bool> {
    let text = std::fs::read_to_string(p).with_context(|| p.display().to_string())?;
    let v: toml::Table = toml::from_str(&text).with_context(|| p.display().to_string())?;
    Ok(v.get("scene").is_some_and(toml::Value::is_str))
}

/// A file's identity for the manifest: its absolute path, plus a content checksum.
fn identity(p: &Path, content: bool) -> anyhow::Result<String> {
    let abs = std::fs::canonicalize(p).with_context(|| p.display().to_string())?;
    if !content {
        return Ok(abs.display().to_string());
    }
    let bytes = std::fs::read(&abs).with_context(|| abs.display().to_string())?;
    Ok(format!("{} (crc32 {:08x})", abs.display(), hilcam_core::frame::CRC32.checksum(&bytes)))
}

/// Render `jobs` with the progress bar and print the summary.
fn render(pipeline: &mut FramePipeline, jobs: &[FrameJob], cfg: &ReplayConfig) -> anyhow::Result<ReplayStats> {
    let bar = Progress::new();
    let t0 = Instant::now();
    stop_signal::install();
    let stats = replay_jobs_until(pipeline, jobs, cfg, |s| bar.update(s), stop_signal::received);
    bar.finish();
    let stats = stats.context("replay")?;
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "{} frames: {} rendered in {:.1} s ({:.2} s/frame), {} already done{}; log {}",
        stats.selected,
        stats.rendered,
        secs,
        secs / stats.rendered.max(1) as f64,
        stats.skipped,
        if stats.truncated_lines > 0 {
            format!(", {} truncated log lines ignored", stats.truncated_lines)
        } else {
            String::new()
        },
        cfg.out_dir.join(cfg.shard.log_name()).display()
    );
    if stats.mc_lit_pixels > 0 {
        let total = super::mc_noise_total(stats.mc_above_bound, stats.mc_lit_pixels, stats.mc_k);
        println!("{total} (each frame's `mc_noise` in the log)");
    }
    if !cfg.truth.is_empty() && stats.rendered > 0 {
        let per_frame = |d: Duration| d.as_secs_f64() / stats.rendered as f64;
        let (frame, truth, write) =
            (per_frame(stats.frame_time), per_frame(stats.truth_time), per_frame(stats.truth_write_time));
        println!(
            "truth ({}): {:.4} s/frame computing ({:.1} % of the {:.3} s/frame rendering), {:.4} s/frame writing the EXR",
            cfg.truth,
            truth,
            100.0 * truth / frame.max(1e-12),
            frame,
            write
        );
    }
    Ok(stats)
}

/// A progress bar on a terminal; otherwise (batch jobs) a log line every 30 s.
struct Progress {
    bar: ProgressBar,
    tty: bool,
    t0: Instant,
    last_log: std::cell::Cell<Instant>,
}

impl Progress {
    fn new() -> Self {
        let tty = std::io::stderr().is_terminal();
        let bar = ProgressBar::with_draw_target(
            None,
            if tty { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() },
        );
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {per_sec}  ETA {eta}  {msg}")
                .expect("valid template"),
        );
        let now = Instant::now();
        Progress { bar, tty, t0: now, last_log: std::cell::Cell::new(now) }
    }

    fn update(&self, s: &ReplayStats) {
        if self.bar.length().is_none() {
            self.bar.set_length(s.selected);
            self.bar.set_position(s.skipped);
            // Rate and ETA count only this run's frames.
            self.bar.reset_eta();
            self.bar.set_message(format!("({} already done)", s.skipped));
        }
        self.bar.set_position(s.skipped + s.rendered);
        let now = Instant::now();
        let done = s.skipped + s.rendered;
        if !self.tty && (now - self.last_log.get() >= Duration::from_secs(30) || done == s.selected) {
            self.last_log.set(now);
            let el = (now - self.t0).as_secs_f64();
            let rate = s.rendered as f64 / el.max(1e-9);
            let eta = (s.selected - done) as f64 / rate.max(1e-12);
            tracing::info!(
                "replay: {done}/{} frames ({} this run), {rate:.3} frames/s, ETA {:.0} s",
                s.selected,
                s.rendered,
                if s.rendered == 0 { f64::NAN } else { eta }
            );
        }
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// A stop request by signal, noted by the handler and acted on between frames.
mod stop_signal {
    use std::sync::atomic::{AtomicI32, Ordering};

    static RECEIVED: AtomicI32 = AtomicI32::new(0);

    extern "C" fn on_signal(sig: libc::c_int) {
        // Only async-signal-safe work here: an atomic swap, and _exit on the second signal.
        if RECEIVED.swap(sig, Ordering::SeqCst) != 0 {
            // SAFETY: _exit is async-signal-safe.
            unsafe { libc::_exit(128 + sig) }
        }
    }

    /// Route SIGINT, SIGTERM and SIGHUP to the flag (instead of immediate death).
    pub fn install() {
        for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            // SAFETY: the handler only touches an atomic and calls _exit.
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                action.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut action.sa_mask);
                libc::sigaction(sig, &action, std::ptr::null_mut());
            }
        }
    }

    /// The signal received so far, by name.
    pub fn received() -> Option<String> {
        match RECEIVED.load(Ordering::SeqCst) {
            0 => None,
            libc::SIGINT => Some("SIGINT".into()),
            libc::SIGTERM => Some("SIGTERM".into()),
            libc::SIGHUP => Some("SIGHUP".into()),
            n => Some(format!("signal {n}")),
        }
    }
}
