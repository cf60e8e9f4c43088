//! The real-time loop: inputs → latest pose → render (off the tokio workers) → sinks.
//!
//! - The latest pose wins: poses that arrive while a frame renders replace each other;
//!   the ones never rendered are counted as superseded. No backlog can build: at most
//!   one frame renders and the input channel is bounded.
//! - Rendering runs on a dedicated thread (which fans out on the rayon pool), so tokio
//!   workers never block; publishing to the sinks never waits for a client, so the next
//!   frame renders while the previous one streams.
//! - The governor picks each frame's quality; every frame carries the quality it was
//!   rendered at, and flags for late / degraded / extrapolated.

use super::extrapolate::extrapolate;
use super::governor::{Governor, Policy, Quality};
use super::render_times::RenderTimes;
use crate::frame::{EncodedFrame, Frame, FrameFlags, FrameMeta, decode_header, unix_ns_now};
use crate::link::{InputEvent, Shutdown};
use crate::metrics::{Counter, Gauge, Histogram, Registry};
use crate::pipeline::FramePipeline;
use crate::pose::Pose;
use crate::render::integrator::RenderSettings;
use crate::session::writer::SessionTap;
use crate::session::{FrameFailedLine, FrameLine, SessionLine};
use crate::sink::Sink;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// What starts a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum TriggerMode {
    /// Every accepted pose (latest wins while a frame renders).
    #[default]
    Pose,
    /// A fixed frame rate from the latest pose.
    Rate,
    /// A trigger message from the bench.
    External,
}

#[derive(Clone)]
pub struct SchedulerConfig {
    pub trigger: TriggerMode,
    /// Frames per second in `Rate` mode.
    pub rate_hz: Option<f64>,
    /// Move the pose to the exposure mid-time with its rates (`Rate` mode).
    pub extrapolate: bool,
    /// Time from the frame's reference instant (pose arrival, tick or trigger) to emit.
    pub budget: Duration,
    pub policy: Policy,
    /// Best quality (the governor may go below it under `FixedRate`).
    pub settings: RenderSettings,
    /// Stop after this many frames (demo, tests); None = until shutdown.
    pub max_frames: Option<u64>,
    /// Record every received pose and rendered frame (session file).
    pub session: Option<SessionTap>,
    /// Called on the render thread with each frame's index just before it renders: a
    /// panic here is a render fault (tests inject one to show what the server does).
    pub fault: Option<FaultInjector>,
    /// An integration time set from outside (a GigE Vision client's ExposureTime), read
    /// as each frame starts; `None` in the channel: the sensor's own (configured or auto).
    pub exposure: Option<tokio::sync::watch::Receiver<Option<f64>>>,
}

/// See [`SchedulerConfig::fault`].
pub type FaultInjector = Arc<dyn Fn(u64) + Send + Sync>;

/// After this many failed frames in a row the renderer is taken to be broken: the
/// scheduler stops and `serve` exits non-zero with the cause, rather than stay up as a
/// camera that never delivers a frame.
pub const MAX_CONSECUTIVE_FAILURES: u32 = 3;

/// Why a frame was not delivered (the `reason` label of `hilcam_frames_failed_total`).
#[derive(Clone, Debug)]
pub struct FrameFailure {
    /// `sensor`, `encode` or `panic`.
    pub reason: &'static str,
    pub message: String,
}

impl FrameFailure {
    /// Every reason, for exporting zero-valued counters.
    pub const REASONS: [&'static str; 3] = ["sensor", "encode", "panic"];
}

impl std::fmt::Display for FrameFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.reason, self.message)
    }
}

/// What a run did (also in the metrics registry).
#[derive(Clone, Debug, Default)]
pub struct SchedulerSummary {
    pub frames: u64,
    /// Frames that failed (sensor, encode or a render panic), counted and logged.
    pub failed: u64,
    /// Set when the scheduler stopped because the renderer is broken (see
    /// [`MAX_CONSECUTIVE_FAILURES`]) or its thread died; `serve` then exits non-zero.
    pub fatal: Option<String>,
    pub late: u64,
    pub degraded: u64,
    pub superseded: u64,
    pub skipped_busy: u64,
    pub poses: u64,
    pub triggers: u64,
    /// Render time percentiles of the newest [`RenderTimes::WINDOW`] frames.
    pub render_p50_ms: f64,
    pub render_p99_ms: f64,
}

struct Job {
    /// The pose rendered (extrapolated when `extrapolated_s` ≠ 0).
    pose: Pose,
    /// Arrival of the received pose it came from.
    source_arrival: Instant,
    extrapolated_s: f64,
    /// When the job was handed to the renderer.
    started: Instant,
    /// Poses received when it started.
    poses_received: u64,
    arrival_unix_ns: u64,
    /// Lateness is measured from here (pose arrival, tick or trigger).
    reference: Instant,
    settings: RenderSettings,
    /// Integration time override for the sensor (see [`SchedulerConfig::exposure`]).
    exposure_s: Option<f64>,
    index: u64,
    flags: FrameFlags,
}

struct Done {
    job: Job,
    frame: Result<Arc<EncodedFrame>, FrameFailure>,
    render_time: Duration,
    quality: Quality,
    late: bool,
    integration_s: Option<f64>,
}

struct Metrics {
    frames: Counter,
    late: Counter,
    degraded: Counter,
    superseded: Counter,
    skipped: Counter,
    failed: Vec<(&'static str, Counter)>,
    triggers: Counter,
    render: Arc<Histogram>,
    spp: Gauge,
    spp_milli: Gauge,
    depth: Gauge,
}

impl Metrics {
    fn new(r: &Registry) -> Self {
        Metrics {
            frames: r.counter("hilcam_frames_rendered_total", "Frames rendered and published", &[]),
            late: r.counter("hilcam_frames_late_total", "Frames emitted after their deadline", &[]),
            degraded: r.counter("hilcam_frames_degraded_total", "Frames rendered below the configured quality", &[]),
            superseded: r.counter(
                "hilcam_poses_superseded_total",
                "Accepted poses replaced by a newer one before rendering",
                &[],
            ),
            skipped: r.counter(
                "hilcam_frames_skipped_total",
                "Frame slots not rendered",
                &[("reason", "renderer_busy")],
            ),
            failed: FrameFailure::REASONS
                .iter()
                .map(|&reason| {
                    (
                        reason,
                        r.counter(
                            "hilcam_frames_failed_total",
                            "Frames not delivered, by cause",
                            &[("reason", reason)],
                        ),
                    )
                })
                .collect(),
            triggers: r.counter("hilcam_triggers_total", "External trigger messages received", &[]),
            render: r.histogram("hilcam_render_seconds", "Render + sensor + encode time per frame", &[]),
            spp: r.gauge(
                "hilcam_frame_spp",
                "Whole samples per pixel of the last frame (the budget's integer part)",
                &[],
            ),
            spp_milli: r.gauge(
                "hilcam_frame_spp_milli",
                "Samples per pixel of the last frame, in thousandths (1250 = 1.25)",
                &[],
            ),
            depth: r.gauge("hilcam_frame_depth", "Path depth of the last frame", &[]),
        }
    }
}

fn unix_ns_of(t: Instant) -> u64 {
    let ago = Instant::now().saturating_duration_since(t);
    unix_ns_now().saturating_sub(ago.as_nanos() as u64)
}

/// Hand a finished frame's session line to the writer (never waits).
fn record(tap: Option<&SessionTap>, d: &Done) {
    let Some(tap) = tap else { return };
    let j = &d.job;
    match &d.frame {
        Ok(frame) => {
            let flags = frame.meta.flags;
            let crc = decode_header(&frame.bytes)
                .map(|h| h.payload_crc)
                .unwrap_or_else(|_| crate::frame::CRC32.checksum(frame.payload()));
            tap.frame(FrameLine {
                index: j.index,
                mono_ns: tap.mono_ns(j.started),
                source_seq: j.pose.seq,
                source_mono_ns: tap.mono_ns(j.source_arrival),
                poses_received: j.poses_received,
                extrapolated_s: j.extrapolated_s,
                pose: (&j.pose).into(),
                settings: (&j.settings).into(),
                flags: flags.0,
                late: flags.contains(FrameFlags::LATE),
                extrapolated: flags.contains(FrameFlags::EXTRAPOLATED),
                degraded: flags.contains(FrameFlags::DEGRADED),
                integration_s: d.integration_s,
                payload_crc32: crc,
            });
        }
        Err(e) => tap.send(SessionLine::FrameFailed(FrameFailedLine {
            index: j.index,
            mono_ns: tap.mono_ns(j.started),
            source_seq: j.pose.seq,
            error: e.to_string(),
        })),
    }
}

/// The render thread: owns the pipeline (and its auto-exposure state).
///
/// A panic while rendering one frame (a bug, or an input no check caught) is caught
/// here: the frame is reported failed with reason `panic`, the pipeline's buffers and
/// auto-exposure state are reset (a frame that stopped half-way may have left them
/// inconsistent), and the next job renders normally.
fn spawn_renderer(
    mut pipeline: FramePipeline,
    budget: Duration,
    fault: Option<FaultInjector>,
    jobs: std::sync::mpsc::Receiver<Job>,
    done: mpsc::Sender<Done>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new().name("hilcam-render".into()).spawn(move || {
        while let Ok(job) = jobs.recv() {
            let t0 = Instant::now();
            let quality = Quality { spp: job.settings.spp, depth: job.settings.depth };
            let attempt = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                if let Some(f) = &fault {
                    f(job.index);
                }
                render_job(&mut pipeline, &job, budget)
            }));
            let (frame, integration_s) = attempt.unwrap_or_else(|payload| {
                pipeline.reset();
                let message = panic_message(payload.as_ref());
                (Err(FrameFailure { reason: "panic", message }), None)
            });
            let late = frame.as_ref().map(|f| f.meta.flags.contains(FrameFlags::LATE)).unwrap_or(false);
            let d = Done { job, frame, render_time: t0.elapsed(), quality, late, integration_s };
            if done.blocking_send(d).is_err() {
                break;
            }
        }
    })
}

/// Render, convert and encode one job.
fn render_job(
    pipeline: &mut FramePipeline,
    job: &Job,
    budget: Duration,
) -> (Result<Arc<EncodedFrame>, FrameFailure>, Option<f64>) {
    let f = match pipeline.frame_exposed(&job.pose, &job.settings, job.index, job.exposure_s) {
        Ok(f) => f,
        Err(e) => return (Err(FrameFailure { reason: "sensor", message: e.to_string() }), None),
    };
    let late = job.reference.elapsed() > budget;
    let flags = if late { job.flags.with(FrameFlags::LATE) } else { job.flags };
    let meta = FrameMeta {
        frame_seq: job.index,
        pose_seq: job.pose.seq,
        pose_t_ns: job.pose.t_ns,
        pose_arrival_unix_ns: job.arrival_unix_ns,
        emit_unix_ns: 0,
        width: f.width,
        height: f.height,
        format: f.pixels.format(),
        bit_depth: 0,
        spp: job.settings.spp,
        depth: job.settings.depth.min(u32::from(u16::MAX)) as u16,
        integration_s: f.integration_s.unwrap_or(0.0) as f32,
        flags,
    };
    let encoded = Frame::new(meta, f.pixels).map(|mut fr| {
        fr.meta.emit_unix_ns = unix_ns_now();
        Arc::new(fr.encode())
    });
    (encoded.map_err(|e| FrameFailure { reason: "encode", message: e.to_string() }), f.integration_s)
}

/// The text of a panic payload (`panic!` with a literal or a formatted message).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic with a non-text payload".into())
}

/// Publish a finished frame to every sink and count it (late, degraded, its quality),
/// or count and log its failure; `failures_in_row` tracks consecutive failures.
fn deliver(
    d: &Done,
    sinks: &[Sink],
    m: &Metrics,
    s: &mut SchedulerSummary,
    failures_in_row: &mut u32,
    tap: Option<&SessionTap>,
) {
    m.render.record_duration(d.render_time);
    record(tap, d);
    match &d.frame {
        Ok(frame) => {
            *failures_in_row = 0;
            for sink in sinks {
                sink.publish(frame);
            }
            s.frames += 1;
            m.frames.inc();
            m.spp.set(i64::from(d.quality.spp.floor()));
            m.spp_milli.set(i64::from(d.quality.spp.milli()));
            m.depth.set(i64::from(d.quality.depth));
            if d.late {
                s.late += 1;
                m.late.inc();
            }
            if frame.meta.flags.contains(FrameFlags::DEGRADED) {
                s.degraded += 1;
                m.degraded.inc();
            }
        }
        Err(e) => {
            *failures_in_row += 1;
            s.failed += 1;
            if let Some((_, c)) = m.failed.iter().find(|(r, _)| *r == e.reason) {
                c.inc();
            }
            tracing::error!(
                frame = d.job.index,
                pose_seq = d.job.pose.seq,
                in_a_row = *failures_in_row,
                "frame failed, not delivered: {e}"
            );
        }
    }
}

/// Run until `shutdown` is triggered, the inputs close (in `Pose`/`External` mode), or
/// `max_frames` frames are out. The frame in flight is finished and published. However
/// it stops (done, or the renderer failed), it triggers `shutdown` for the rest of the
/// server.
pub async fn run_scheduler(
    cfg: SchedulerConfig,
    pipeline: FramePipeline,
    mut inputs: mpsc::Receiver<InputEvent>,
    sinks: Arc<Vec<Sink>>,
    registry: Arc<Registry>,
    shutdown: Shutdown,
) -> SchedulerSummary {
    let m = Metrics::new(&registry);
    let mut s = SchedulerSummary::default();
    let (job_tx, job_rx) = std::sync::mpsc::channel::<Job>();
    let (done_tx, mut done_rx) = mpsc::channel::<Done>(1);
    let renderer = match spawn_renderer(pipeline, cfg.budget, cfg.fault.clone(), job_rx, done_tx) {
        Ok(r) => r,
        Err(e) => {
            s.fatal = Some(format!("cannot start the render thread: {e}"));
            shutdown.trigger();
            return s;
        }
    };
    let best = Quality { spp: cfg.settings.spp, depth: cfg.settings.depth };
    let mut governor = Governor::new(cfg.policy, cfg.budget, best);
    let mut ticker = match (cfg.trigger, cfg.rate_hz) {
        (TriggerMode::Rate, Some(hz)) if hz > 0.0 => {
            let mut t = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
            t.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            Some(t)
        }
        _ => None,
    };
    let stopped = shutdown.wait();
    tokio::pin!(stopped);

    let mut latest: Option<(Pose, Instant)> = None;
    let mut pending = 0u64; // poses accepted since the last render started
    let mut want: Option<Instant> = None; // a frame is due; its reference instant
    let mut busy = false;
    let mut inputs_open = true;
    let mut index = 0u64;
    let mut last_integration = 0.0f64;
    let mut render_times = RenderTimes::default();
    let mut failures_in_row = 0u32;

    loop {
        let done_all = cfg.max_frames.is_some_and(|n| index >= n);
        if done_all && !busy {
            break;
        }
        if !inputs_open && !busy && cfg.trigger != TriggerMode::Rate && want.is_none() {
            break;
        }
        tokio::select! {
            _ = &mut stopped => break,
            ev = inputs.recv(), if inputs_open => match ev {
                None => inputs_open = false,
                Some(InputEvent::Pose { pose, arrival }) => {
                    if let Some(tap) = &cfg.session {
                        tap.pose(&pose, arrival);
                    }
                    s.poses += 1;
                    pending += 1;
                    latest = Some((pose, arrival));
                    if cfg.trigger == TriggerMode::Pose {
                        want = Some(arrival);
                    }
                }
                Some(InputEvent::Trigger { arrival, .. }) => {
                    s.triggers += 1;
                    m.triggers.inc();
                    if cfg.trigger == TriggerMode::External {
                        if want.is_some() {
                            s.skipped_busy += 1;
                            m.skipped.inc();
                        }
                        want = Some(arrival);
                    }
                }
                Some(InputEvent::Heartbeat { .. }) => {}
            },
            Some(tick) = async { match ticker.as_mut() { Some(t) => Some(t.tick().await), None => None } }, if ticker.is_some() => {
                if busy || want.is_some() {
                    s.skipped_busy += 1;
                    m.skipped.inc();
                } else {
                    want = Some(tick.into_std());
                }
            }
            d = done_rx.recv(), if busy => {
                busy = false;
                let Some(d) = d else {
                    s.fatal = Some("the render thread stopped unexpectedly".into());
                    break;
                };
                render_times.record(d.render_time);
                governor.observe(d.quality, d.render_time);
                if let Some(i) = d.integration_s {
                    last_integration = i;
                }
                deliver(&d, &sinks, &m, &mut s, &mut failures_in_row, cfg.session.as_ref());
                if failures_in_row >= MAX_CONSECUTIVE_FAILURES {
                    let e = d.frame.as_ref().err().map(ToString::to_string).unwrap_or_default();
                    s.fatal = Some(format!("{failures_in_row} frames in a row failed; the last: {e}"));
                    break;
                }
            }
        }

        // Start the next frame when one is due, the renderer is free, and a pose exists.
        if let (Some(reference), false, Some((pose, arrival))) = (want, busy, latest) {
            if cfg.max_frames.is_some_and(|n| index >= n) {
                want = None;
                continue;
            }
            want = None;
            let superseded = pending.saturating_sub(1);
            s.superseded += superseded;
            m.superseded.add(superseded);
            pending = 0;
            let q = governor.current();
            let settings = RenderSettings { spp: q.spp, depth: q.depth, ..cfg.settings };
            let mut flags = FrameFlags::default();
            if q != best {
                flags = flags.with(FrameFlags::DEGRADED);
            }
            let mut pose = pose;
            let mut extrapolated_s = 0.0;
            if cfg.extrapolate && cfg.trigger == TriggerMode::Rate {
                let dt = reference.saturating_duration_since(arrival).as_secs_f64() + last_integration * 0.5;
                let (p, moved) = extrapolate(&pose, dt);
                if moved {
                    pose = p;
                    extrapolated_s = dt;
                    flags = flags.with(FrameFlags::EXTRAPOLATED);
                }
            }
            let job = Job {
                pose,
                source_arrival: arrival,
                extrapolated_s,
                started: Instant::now(),
                poses_received: s.poses,
                arrival_unix_ns: unix_ns_of(arrival),
                reference,
                settings,
                exposure_s: cfg.exposure.as_ref().and_then(|rx| *rx.borrow()),
                index,
                flags,
            };
            if job_tx.send(job).is_err() {
                tracing::error!("render thread is gone");
                break;
            }
            index += 1;
            busy = true;
        }
    }

    shutdown.trigger();
    // Finish the frame in flight (unless the renderer is what failed), then stop the
    // render thread.
    if busy && s.fatal.is_none() {
        match done_rx.recv().await {
            Some(d) => {
                render_times.record(d.render_time);
                deliver(&d, &sinks, &m, &mut s, &mut failures_in_row, cfg.session.as_ref());
            }
            None => s.fatal = Some("the render thread stopped unexpectedly".into()),
        }
    }
    // Poses still waiting at shutdown were replaced by the newest one, which was not
    // rendered either; count them so that accepted = rendered-from + superseded + 1.
    let unrendered = pending.saturating_sub(1);
    s.superseded += unrendered;
    m.superseded.add(unrendered);
    drop(job_tx);
    let _ = tokio::task::spawn_blocking(move || renderer.join()).await;
    s.render_p50_ms = render_times.percentile_ms(0.5);
    s.render_p99_ms = render_times.percentile_ms(0.99);
    s
}
