//! `hilcam replay`: render a trajectory offline to files (resumable, shardable).

use crate::cli::render::scaled_camera;
use crate::integrator::SamplerKind;
use crate::pipeline::FramePipeline;
use crate::replay::{ReplayConfig, ReplayStats, Shard, merge, pin_integration_time, replay};
use crate::sink::recorder::ImageFormat;
use crate::trajectory::Trajectory;
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// Trajectory CSV (docs/trajectory.md); row k becomes frame k with pose seq k.
    #[arg(long, required_unless_present = "merge")]
    pub trajectory: Option<PathBuf>,
    /// Scene file (TOML).
    #[arg(long, required_unless_present = "merge")]
    pub scene: Option<PathBuf>,
    /// Output directory: images `frame_<k>.<ext>` and `frames*.jsonl`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Merge the shard logs of DIR into DIR/frames.jsonl and exit.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["trajectory", "scene", "out"])]
    pub merge: Option<PathBuf>,
    /// Render at this many columns (same field of view; default: the camera's).
    #[arg(long)]
    pub width: Option<u32>,
    #[arg(long)]
    pub spp: Option<u32>,
    #[arg(long)]
    pub depth: Option<u32>,
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerKind>,
    #[arg(long)]
    pub seed: Option<u64>,
    #[arg(long, value_enum, default_value = "png")]
    pub format: ImageFormat,
    /// Render every K-th trajectory row only.
    #[arg(long, default_value_t = 1)]
    pub every: u64,
    /// Render shard K of N (`K/N`, 0-based). Default: from SLURM_ARRAY_TASK_ID/_COUNT/_MIN
    /// or JOB_COMPLETION_INDEX + HILCAM_SHARD_COUNT, else the whole trajectory.
    #[arg(long)]
    pub shard: Option<String>,
    /// Fixed sensor integration time (s), replacing auto-exposure; needed to shard or
    /// resume a scene whose sensor has auto-exposure.
    #[arg(long)]
    pub integration_s: Option<f64>,
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
    let (Some(traj), Some(scene_path)) = (&a.trajectory, &a.scene) else {
        bail!("--trajectory and --scene are required")
    };
    let Some(out) = a.out.clone() else { bail!("--out DIR is required") };
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let shard = match &a.shard {
        Some(s) => Shard::parse(s)?,
        None => Shard::from_env(|v| std::env::var(v).ok())?.unwrap_or(Shard::ALL),
    };
    let samples = Trajectory::load(traj)?;
    let mut scene = crate::scene::load(scene_path)?;
    if let Some(t) = a.integration_s {
        pin_integration_time(&mut scene, t)?;
    }
    let settings = scene.render.overridden(a.spp, a.depth, a.sampler, a.seed);
    let camera = scaled_camera(&scene.camera, a.width, None);
    let mut pipeline = FramePipeline::new(Arc::new(scene), camera.clone())?;
    let cfg = ReplayConfig { out_dir: out.clone(), format: a.format, settings, every: a.every, shard };
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
    let bar = Progress::new();
    let t0 = Instant::now();
    let stats = replay(&mut pipeline, &samples, &cfg, |s| bar.update(s)).context("replay")?;
    bar.finish();
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
        out.join(shard.log_name()).display()
    );
    Ok(())
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
