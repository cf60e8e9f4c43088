//! `hilcam serve`: the real-time loop from pose to frame on the wire (tokio shell over the
//! synchronous renderer).
//!
//! - [`config`]: the TOML configuration.
//! - [`scheduler`]: latest-pose-wins triggering, the render thread, publishing.
//! - [`governor`]: the quality ladder that keeps frames inside their budget.
//! - [`render_times`]: the summary's render time percentiles, over a fixed window.
//! - [`extrapolate`]: poses moved to the exposure mid-time with their rates.
//! - [`session`]: the session file writer (poses received, frames rendered).

pub mod config;
pub mod extrapolate;
pub mod governor;
mod inputs;
pub mod render_times;
pub mod scheduler;

/// The server's one stop signal (defined with the links, the earliest layer that waits on it).
pub use crate::link::Shutdown;
use crate::link::{InputCounters, InputEvent};
use crate::metrics::{Registry, serve_http, spawn_summary_logger};
use crate::pipeline::FramePipeline;
use crate::session::writer::SessionWriter;
use crate::session::{EndLine, SessionHeader};
use crate::sink::{Recorder, RecorderConfig, Sink, StreamConfig, StreamServer, WriteHook};
use anyhow::Context;
use config::ServeConfig;
use scheduler::{SchedulerConfig, SchedulerSummary, run_scheduler};
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
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

/// Copy the transports' atomic counters into the registry (as deltas, so they stay
/// counters). The first call registers every counter, zeros included, so `/metrics`
/// lists them all from the start (the Prometheus convention).
fn mirror_input_counters(registry: &Registry, counters: &InputCounters, seen: &Mutex<HashMap<String, u64>>) {
    let mut seen = seen.lock().expect("counter mirror lock");
    counters.for_each(|name, labels, v| {
        let key = format!("{name}{{{labels}}}");
        let first = !seen.contains_key(&key);
        let last = seen.entry(key).or_insert(0);
        if v > *last || first {
            let label_pairs: Vec<(&str, String)> = labels
                .split(',')
                .filter_map(|kv| kv.split_once('=').map(|(k, v)| (k, v.trim_matches('"').to_string())))
                .collect();
            let refs: Vec<(&str, &str)> = label_pairs.iter().map(|(k, v)| (*k, v.as_str())).collect();
            registry.counter(name, "pose input counter (see docs/protocol.md)", &refs).add(v - *last);
            *last = v;
        }
    });
}

/// Run the server until `stop` resolves (or `embed.max_frames` frames are out, or the
/// renderer fails). All of them trigger one [`Shutdown`]: the scheduler finishes the
/// frame in flight while the inputs and helpers stop, then the sinks close.
pub async fn run(
    cfg: ServeConfig,
    mut embed: Embed,
    stop: impl std::future::Future + Send + 'static,
) -> anyhow::Result<ServeReport> {
    let shutdown = Shutdown::when(stop);
    // The zero of the session file's clocks (monotonic and wall).
    let (session_start, session_start_unix) = (std::time::Instant::now(), crate::frame::unix_ns_now());
    let embedded = embed.inputs.is_some();
    let scene = Arc::new(crate::scene::load(&cfg.scene)?);
    let camera = scene.camera.scaled(cfg.width, None);
    let o = &cfg.render;
    let settings = scene.render.overridden(o.spp, o.depth, o.sampler, o.seed);
    let pipeline = FramePipeline::new(scene.clone(), camera.clone()).context("sensor")?;
    let registry = Registry::new();
    let counters = Arc::new(InputCounters::new());
    let mut tasks = Vec::new();

    // Inputs.
    let mut inputs = match embed.inputs.take() {
        Some(rx) => rx,
        None => {
            let (rx, task) = inputs::start(&cfg.input, counters.clone(), &shutdown)?;
            tasks.extend(task);
            rx
        }
    };

    // Sinks.
    let latency = registry.histogram(
        "hilcam_frame_latency_seconds",
        "Pose arrival to the frame's last byte written to a client",
        &[],
    );
    let hook: WriteHook = {
        let latency = latency.clone();
        Arc::new(move |w| {
            if w.pose_arrival_unix_ns != 0 {
                latency.record(w.latency_ns());
            }
        })
    };
    let stream_cfg = StreamConfig {
        bind: cfg.stream.listen,
        queue_depth: cfg.stream.queue_depth,
        max_clients: cfg.stream.max_clients,
        evict_after: cfg.stream.evict_after(),
        ..StreamConfig::default()
    };
    let stream = StreamServer::bind(stream_cfg, registry.clone(), Some(hook)).await?;
    let stream_addr = stream.local_addr();
    let mut sinks = vec![Sink::Stream(stream)];
    if let Some(r) = &cfg.record
        && let Some(dir) = &r.dir
    {
        sinks.push(Sink::Recorder(Recorder::start(RecorderConfig::new(dir, r.format), &registry)?));
    }
    let mut exposure = None;
    if let Some(g) = &cfg.output.gige {
        let desc = crate::sink::gige::CameraDescription::from_scene(&camera, &scene.sensor, cfg.trigger.rate_hz)
            .map_err(anyhow::Error::msg)?;
        let device = crate::sink::gige::GigeDevice::start(g, desc, registry.clone()).await?;
        let dropped =
            registry.counter("hilcam_gige_triggers_dropped_total", "Software triggers the input queue refused", &[]);
        inputs = crate::sink::gige::triggers::merge_software_triggers(inputs, &device, dropped);
        exposure = Some(crate::sink::gige::exposure::follow_exposure(&device));
        sinks.push(Sink::Gige(device));
    }
    let input_name = if embedded { "embedded" } else { cfg.input.kind() };
    let session_writer = match cfg.record.as_ref().and_then(|r| r.session.as_ref()) {
        Some(path) => {
            let mut header = session_header(&cfg, &camera, &settings, input_name);
            header.start_unix_ns = session_start_unix;
            Some(SessionWriter::start(path, &header, session_start, input_name, &registry)?)
        }
        None => None,
    };
    let sinks = Arc::new(sinks);

    // Observability.
    let mut metrics_addr = None;
    if let Some(addr) = cfg.metrics.listen {
        let listener = tokio::net::TcpListener::bind(addr).await.with_context(|| format!("metrics listen {addr}"))?;
        metrics_addr = Some(listener.local_addr()?);
        tasks.push(tokio::spawn(serve_http(listener, registry.clone(), shutdown.clone().wait_owned())));
    }
    let seen = Arc::new(Mutex::new(HashMap::new()));
    mirror_input_counters(&registry, &counters, &seen);
    {
        let (registry, counters, seen, stop) = (registry.clone(), counters.clone(), seen.clone(), shutdown.clone());
        tasks.push(tokio::spawn(async move {
            let mut t = tokio::time::interval(Duration::from_millis(250));
            loop {
                tokio::select! {
                    _ = t.tick() => mirror_input_counters(&registry, &counters, &seen),
                    _ = stop.wait() => break,
                }
            }
        }));
    }
    let summary_logger = spawn_summary_logger(
        registry.clone(),
        Duration::from_secs_f64(cfg.metrics.print_interval_s),
        shutdown.clone().wait_owned(),
    );
    tracing::info!(
        stream = %stream_addr,
        metrics = ?metrics_addr,
        camera = format!("{}x{}", camera.width, camera.height),
        spp = %settings.spp,
        depth = settings.depth,
        "serving"
    );
    if let Some(tx) = embed.ready.take() {
        let _ = tx.send(ServeInfo { stream: stream_addr, metrics: metrics_addr });
    }

    let sched_cfg = SchedulerConfig {
        trigger: cfg.trigger.mode,
        rate_hz: cfg.trigger.rate_hz,
        extrapolate: cfg.trigger.extrapolate,
        budget: cfg.budget(),
        policy: cfg.governor.policy,
        settings,
        max_frames: embed.max_frames,
        session: session_writer.as_ref().map(SessionWriter::tap),
        fault: embed.render_fault.take(),
        exposure,
    };
    let summary = run_scheduler(sched_cfg, pipeline, inputs, sinks.clone(), registry.clone(), shutdown.clone()).await;

    // Shut down: the inputs and helpers stop on the signal (the scheduler triggered it
    // when it stopped), then the sinks close (a clean close for clients).
    shutdown.trigger();
    for t in tasks {
        let _ = t.await;
    }
    let _ = summary_logger.await;
    mirror_input_counters(&registry, &counters, &seen);
    let mut client_drops = 0;
    if let Ok(sinks) = Arc::try_unwrap(sinks) {
        for s in sinks {
            if let Sink::Stream(st) = &s {
                client_drops = st.clients().iter().map(|c| c.dropped).sum();
            }
            s.close().await;
        }
    }
    let session = match session_writer {
        Some(w) => {
            let end = session_end(&counters, &summary);
            let stats = tokio::task::spawn_blocking(move || w.finish(end)).await.context("session writer")??;
            if stats.dropped > 0 {
                tracing::warn!(file = %stats.path.display(), dropped = stats.dropped, "session lines were dropped");
            }
            Some(stats)
        }
        None => None,
    };
    if let Some(cause) = &summary.fatal {
        tracing::error!(frames = summary.frames, failed = summary.failed, "stopping: {cause}");
        anyhow::bail!("the renderer failed: {cause} (frames delivered {}, failed {})", summary.frames, summary.failed);
    }
    let snap = latency.snapshot();
    let q = |p| snap.quantile(p).map(|ns| ns as f64 / 1e6).unwrap_or(0.0);
    Ok(ServeReport {
        scheduler: summary,
        latency_ms: (snap.count > 0).then(|| (q(0.5), q(0.95), q(0.99))),
        poses_accepted: counters.accepted.load(std::sync::atomic::Ordering::Relaxed),
        poses_rejected: counters.rejected_total(),
        client_drops,
        session,
    })
}

/// The session file's first line: how this server renders.
fn session_header(
    cfg: &ServeConfig,
    camera: &crate::render::camera::CameraModel,
    settings: &crate::render::integrator::RenderSettings,
    input: &str,
) -> SessionHeader {
    let lower = |v: &dyn std::fmt::Debug| format!("{v:?}").to_lowercase();
    SessionHeader {
        version: crate::session::SESSION_VERSION,
        hilcam: env!("CARGO_PKG_VERSION").to_string(),
        start_unix_ns: 0,
        scene: std::fs::canonicalize(&cfg.scene).unwrap_or(cfg.scene.clone()).display().to_string(),
        width_setting: cfg.width,
        width: camera.width,
        height: camera.height,
        settings: settings.into(),
        trigger: lower(&cfg.trigger.mode),
        extrapolate: cfg.trigger.extrapolate,
        policy: match cfg.governor.policy {
            governor::Policy::FixedQuality => "fixed-quality".into(),
            governor::Policy::FixedRate => "fixed-rate".into(),
        },
        input: input.to_string(),
    }
}

/// The session file's last line: the run's pose and frame counters.
fn session_end(counters: &InputCounters, s: &SchedulerSummary) -> EndLine {
    use crate::pose::validate::Rejection;
    use std::sync::atomic::Ordering::Relaxed;
    EndLine {
        poses_accepted: counters.accepted.load(Relaxed),
        poses_rejected: Rejection::ALL
            .iter()
            .map(|r| (r.as_str().to_string(), counters.rejected(*r)))
            .filter(|(_, n)| *n > 0)
            .collect(),
        input_channel_full: counters.channel_full.load(Relaxed),
        poses_received: s.poses,
        poses_superseded: s.superseded,
        frames: s.frames,
        frames_failed: s.failed,
        fatal: s.fatal.clone(),
        ..EndLine::default()
    }
}
