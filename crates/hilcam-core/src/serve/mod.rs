//! `hilcam serve`: the real-time loop from pose to frame on the wire (tokio shell over the
//! synchronous renderer).
//!
//! - [`config`]: the TOML configuration.
//! - [`scheduler`]: latest-pose-wins triggering, the render thread, publishing.
//! - [`governor`]: the quality ladder that keeps frames inside their budget.
//! - [`render_times`]: the summary's render time percentiles, over a fixed window.
//! - [`extrapolate`]: poses moved to the exposure mid-time with their rates.
//! - [`live`]: the operator's live page on the metrics listener (`[live]`).
//! - `inputs`, `outputs`, `helpers`, `session_file`: what [`run`] starts around the
//!   scheduler (the pose input; the sinks; `/metrics` and the summary log; the session
//!   file), each stopped by the one [`Shutdown`].
//! - `camera`: the camera transports' control (frame and rate requests, software
//!   triggers) merged for the scheduler, whatever the transport.

mod camera;
pub mod config;
pub mod extrapolate;
pub mod governor;
mod helpers;
mod inputs;
pub mod live;
mod outputs;
pub mod render_times;
pub mod scheduler;
mod session_file;

use crate::link::{InputCounters, InputEvent};
use crate::metrics::{Histogram, Registry};
use crate::pipeline::FramePipeline;
use crate::render::camera::CameraModel;
use crate::render::integrator::RenderSettings;
use crate::session::writer::{SessionStats, SessionWriter};
use crate::shutdown::Shutdown;
use anyhow::Context;
use config::ServeConfig;
use helpers::Helpers;
use outputs::Outputs;
use scheduler::{SchedulerConfig, SchedulerSummary, run_scheduler};
use session_file::SessionClock;
use std::net::SocketAddr;
use std::sync::Arc;
use tokio::sync::{mpsc, oneshot};

/// Where a running server can be reached (sent once it is listening).
#[derive(Clone, Debug)]
pub struct ServeInfo {
    pub stream: SocketAddr,
    pub metrics: Option<SocketAddr>,
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct ServeReport {
    pub scheduler: SchedulerSummary,
    /// Pose arrival → last byte written to a client, milliseconds (p50, p95, p99).
    pub latency_ms: Option<(f64, f64, f64)>,
    pub poses_accepted: u64,
    pub poses_rejected: u64,
    /// Frames dropped per stream client (slow readers).
    pub client_drops: u64,
    /// The session file written, if one was recorded.
    pub session: Option<crate::session::writer::SessionStats>,
}

/// Options for embedding the server (tests, demo).
#[derive(Default)]
pub struct Embed {
    /// Use these inputs instead of opening the configured device.
    pub inputs: Option<mpsc::Receiver<InputEvent>>,
    /// Told the bound addresses once listening.
    pub ready: Option<oneshot::Sender<ServeInfo>>,
    /// Stop after this many frames.
    pub max_frames: Option<u64>,
    /// Render-fault injection for tests ([`scheduler::SchedulerConfig::fault`]).
    pub render_fault: Option<scheduler::FaultInjector>,
}

/// Run the server until `stop` resolves (or `embed.max_frames` frames are out, or the
/// renderer fails). All of them trigger one [`Shutdown`]: the scheduler finishes the
/// frame in flight while the inputs and helpers stop, then the sinks close.
pub async fn run(
    cfg: ServeConfig,
    mut embed: Embed,
    stop: impl std::future::Future + Send + 'static,
) -> anyhow::Result<ServeReport> {
    if !cfg.cameras.is_empty() {
        // Parsed and checked, not driven yet: refused rather than served as one camera.
        anyhow::bail!(
            "camera: this config describes a rig of {} cameras ([[camera]]); `hilcam serve` does not drive a rig \
             yet (docs/rig.md)",
            cfg.cameras.len()
        );
    }
    let shutdown = Shutdown::when(stop);
    let clock = SessionClock::now();
    let scene = Arc::new(crate::scene::load(&cfg.scene)?);
    let camera = scene.camera.scaled(cfg.width, None);
    let table = crate::render::truth::materials_table(&scene.materials).len();
    if cfg.output.truth.contains(crate::render::truth::TruthChannel::Mask)
        && table > crate::frame::truth_block::MATERIALS_MAX_LEN
    {
        anyhow::bail!(
            "output.truth: the mask's material table of {} is {table} bytes, more than the {} a truth block carries",
            cfg.scene.display(),
            crate::frame::truth_block::MATERIALS_MAX_LEN
        );
    }
    let o = &cfg.render;
    let settings = scene.render.overridden(o.spp, o.depth, o.sampler, o.seed).with_quality(o.quality, o.sensor_k);
    crate::sensor::check_quality(&settings, &scene.sensor)
        .map_err(|m| anyhow::anyhow!("render.quality (scene {}, or [render] here): {m}", cfg.scene.display()))?;
    let pipeline = FramePipeline::new(scene.clone(), camera.clone()).context("sensor")?;
    // A camera that integrates over its exposure renders each frame from the pose at the
    // exposure's start.
    let exposure_start = pipeline.exposure_timing(None).integrates_motion();
    let registry = Registry::new();
    let counters = Arc::new(InputCounters::new());
    let input_name = if embed.inputs.is_some() { "embedded" } else { cfg.input.kind() };
    let (inputs, input_task) = match embed.inputs.take() {
        Some(rx) => (rx, None),
        None => inputs::start(&cfg.input, counters.clone(), &shutdown, exposure_start, scene.pose_limits())?,
    };
    let out = Outputs::start(&cfg, &scene, &camera, &registry, inputs).await?;
    let session = session_file::start(&cfg, &camera, &settings, input_name, clock, &registry)?;
    let live = start_live(&cfg, &scene, &camera, &registry)?;
    let routes = live.as_ref().map(live::LiveView::routes);
    let helpers = Helpers::start(&cfg, &registry, routes, &counters, &shutdown).await?;
    // Before the announcement: a scrape from then on lists the scheduler's series.
    let metrics = scheduler::SchedulerMetrics::new(&registry);
    let info = ServeInfo { stream: out.stream_addr, metrics: helpers.metrics_addr };
    announce(&info, &camera, &settings, embed.ready.take());

    let mut sched_cfg = scheduler_config(&cfg, settings, exposure_start, &mut embed, session.as_ref(), out.camera);
    sched_cfg.live = live.as_ref().map(live::LiveView::tap);
    let sinks = Arc::new(out.sinks);
    let summary = run_scheduler(sched_cfg, pipeline, out.inputs, sinks.clone(), metrics, shutdown.clone()).await;

    // Shut down: the inputs and helpers stop on the signal (the scheduler triggered it
    // when it stopped), then the sinks close (a clean close for clients).
    shutdown.trigger();
    if let Some(t) = input_task {
        let _ = t.await;
    }
    helpers.join().await;
    if let Some(l) = live {
        l.close().await;
    }
    let client_drops = outputs::close(sinks).await;
    let session = session_file::finish(session, &counters, &summary).await?;
    if let Some(cause) = &summary.fatal {
        tracing::error!(frames = summary.frames, failed = summary.failed, "stopping: {cause}");
        anyhow::bail!("the renderer failed: {cause} (frames delivered {}, failed {})", summary.frames, summary.failed);
    }
    Ok(report(summary, &out.latency, &counters, client_drops, session))
}

/// Log where the server is and tell the embedder.
fn announce(
    info: &ServeInfo,
    camera: &CameraModel,
    settings: &RenderSettings,
    ready: Option<oneshot::Sender<ServeInfo>>,
) {
    tracing::info!(
        stream = %info.stream,
        metrics = ?info.metrics,
        camera = format!("{}x{}", camera.width, camera.height),
        spp = %settings.spp,
        depth = settings.depth,
        "serving"
    );
    if let Some(tx) = ready {
        let _ = tx.send(info.clone());
    }
}

fn scheduler_config(
    cfg: &ServeConfig,
    settings: RenderSettings,
    exposure_start: bool,
    embed: &mut Embed,
    session: Option<&SessionWriter>,
    camera: camera::CameraRequests,
) -> SchedulerConfig {
    SchedulerConfig {
        trigger: cfg.trigger.mode,
        rate_hz: cfg.trigger.rate_hz,
        extrapolate: cfg.trigger.extrapolate,
        exposure_start,
        budget: cfg.budget(),
        policy: cfg.governor.policy,
        settings,
        max_frames: embed.max_frames,
        session: session.map(SessionWriter::tap),
        fault: embed.render_fault.take(),
        requests: camera.requests,
        rate_requests: camera.rate_requests,
        live: None,
        truth: cfg.output.truth,
    }
}

/// The live view when `[live]` is enabled (nothing at all otherwise).
fn start_live(
    cfg: &ServeConfig,
    scene: &crate::scene::Scene,
    camera: &CameraModel,
    registry: &Arc<Registry>,
) -> anyhow::Result<Option<live::LiveView>> {
    if !cfg.live.enabled {
        return Ok(None);
    }
    let t = &scene.target;
    let sphere =
        live::state::TargetSphere { centre_body: t.frame_origin_body + t.bounds.centre, radius_m: t.bounds.radius };
    Ok(Some(live::LiveView::start(&cfg.live, camera, sphere, registry).context("live view thread")?))
}

fn report(
    scheduler: SchedulerSummary,
    latency: &Histogram,
    counters: &InputCounters,
    client_drops: u64,
    session: Option<SessionStats>,
) -> ServeReport {
    let snap = latency.snapshot();
    let q = |p| snap.quantile(p).map(|ns| ns as f64 / 1e6).unwrap_or(0.0);
    ServeReport {
        scheduler,
        latency_ms: (snap.count > 0).then(|| (q(0.5), q(0.95), q(0.99))),
        poses_accepted: counters.accepted.load(std::sync::atomic::Ordering::Relaxed),
        poses_rejected: counters.rejected_total(),
        client_drops,
        session,
    }
}
