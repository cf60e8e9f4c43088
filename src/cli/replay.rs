//! `hilcam replay`: render a trajectory offline to files (resumable, shardable), or
//! re-render a recorded `serve` session frame for frame (`--session`).
//!
//! The flags become a [`ReplayRequest`] for [`hilcam_core::replay::run`]; this file adds
//! the progress bar and the summary. SIGINT, SIGTERM (Slurm's `scancel`, `docker stop`)
//! and SIGHUP ([`signal`]) let the frame in hand finish and be written, then stop with a
//! non-zero exit and a message saying how many frames are complete; the same command
//! resumes. A second signal exits at once (frames are written whole or not at all, so
//! even that leaves no partial frame).

use super::parse_sensor_k;
use super::signal::{self, Again};
use anyhow::{Context, bail};
use hilcam_core::render::integrator::{QualityMode, SamplerKind};
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::replay::{
    ReplayEvent, ReplayOutcome, ReplayRequest, ReplaySource, ReplayStats, Shard, TrajectoryOverrides, merge,
};
use hilcam_core::scene::file::parse_name;
use hilcam_core::serve::config::ServeConfig;
use hilcam_core::sink::recorder::ImageFormat;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
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
    let source = source(&a)?;
    let request =
        ReplayRequest { source, out, format: a.format, every: a.every, shard, truth: a.truth.unwrap_or_default() };
    let shutdown = signal::stop_on_signals(Again::ExitNow)?;
    let mut bar = None;
    let outcome = hilcam_core::replay::run(&request, &shutdown, |event| match event {
        ReplayEvent::Started(line) => {
            println!("{line}");
            bar = Some(Progress::new());
        }
        ReplayEvent::Progress(s) => bar.as_ref().expect("started").update(s),
    });
    if let Some(b) = &bar {
        b.finish();
    }
    let outcome = outcome?;
    print_summary(&outcome, &request);
    if outcome.verified && outcome.stats.rendered > 0 {
        println!(
            "{} frames re-rendered, each bit-identical to the stream (payload CRC-32 checked)",
            outcome.stats.rendered
        );
    }
    Ok(())
}

/// The frames' source from the flags: a session (with the scene a serve config names,
/// or a scene file) or a trajectory and its scene.
fn source(a: &ReplayArgs) -> anyhow::Result<ReplaySource> {
    if let Some(session) = &a.session {
        let scene = match a.config.as_ref().or(a.scene.as_ref()) {
            Some(p) if is_serve_config(p)? => Some(ServeConfig::load(p)?.scene),
            given => given.cloned(),
        };
        return Ok(ReplaySource::Session { session: session.clone(), scene, verify: !a.no_verify });
    }
    let (Some(trajectory), Some(scene)) = (&a.trajectory, &a.scene) else {
        bail!("--trajectory and --scene are required")
    };
    let overrides = TrajectoryOverrides {
        width: a.width,
        spp: a.spp,
        depth: a.depth,
        sampler: a.sampler,
        seed: a.seed,
        quality: a.quality,
        sensor_k: a.sensor_k,
        integration_s: a.integration_s,
    };
    Ok(ReplaySource::Trajectory { trajectory: trajectory.clone(), scene: scene.clone(), overrides })
}

/// A serve config names its scene with a top-level `scene = "…"`; a scene file does not.
fn is_serve_config(p: &Path) -> anyhow::Result<bool> {
    let text = std::fs::read_to_string(p).with_context(|| p.display().to_string())?;
    let v: toml::Table = toml::from_str(&text).with_context(|| p.display().to_string())?;
    Ok(v.get("scene").is_some_and(toml::Value::is_str))
}

/// The run's totals: frames, time, the Monte Carlo noise and the truth's cost.
fn print_summary(o: &ReplayOutcome, r: &ReplayRequest) {
    let stats = &o.stats;
    let secs = o.elapsed.as_secs_f64();
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
        o.log.display()
    );
    if stats.mc_lit_pixels > 0 {
        let total = super::mc_noise_total(stats.mc_above_bound, stats.mc_lit_pixels, stats.mc_k);
        println!("{total} (each frame's `mc_noise` in the log)");
    }
    if !r.truth.is_empty() && stats.rendered > 0 {
        let per_frame = |d: Duration| d.as_secs_f64() / stats.rendered as f64;
        let (frame, truth, write) =
            (per_frame(stats.frame_time), per_frame(stats.truth_time), per_frame(stats.truth_write_time));
        println!(
            "truth ({}): {:.4} s/frame computing ({:.1} % of the {:.3} s/frame rendering), {:.4} s/frame writing the EXR",
            r.truth,
            truth,
            100.0 * truth / frame.max(1e-12),
            frame,
            write
        );
    }
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
