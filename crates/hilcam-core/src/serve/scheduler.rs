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
use crate::link::InputEvent;
use crate::metrics::{Counter, Gauge, Histogram, Registry};
use crate::pipeline::{FramePipeline, FrameRequest};
use crate::pose::Pose;
use crate::render::integrator::RenderSettings;
use crate::render::truth::TruthChannels;
use crate::session::writer::SessionTap;
use crate::session::{FrameFailedLine, FrameLine, SessionLine};
use crate::shutdown::Shutdown;
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
    /// Move the pose to the exposure mid-time with its rates (`Rate` mode); to the
    /// exposure start when the camera integrates motion (`exposure_start`).
    pub extrapolate: bool,
    /// The camera integrates over its exposure (a global or rolling exposure): a frame's
    /// pose is the one at the exposure's start, and the renderer moves it from there.
    pub exposure_start: bool,
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
    /// What a camera client asks of each frame (a GigE Vision client's ExposureTime and
    /// ROI), read as each frame starts; the default request: the configured frame.
    pub requests: Option<tokio::sync::watch::Receiver<FrameRequest>>,
    /// A camera client's frame rate (Hz; a GigE Vision client's AcquisitionFrameRate):
    /// in `Rate` mode the ticker runs at it from the next tick on; `None` inside = back
    /// to `rate_hz`. The device bounds it (the configured rate is its maximum). Ignored
    /// in the other modes, where frames follow poses or triggers.
    pub rate_requests: Option<tokio::sync::watch::Receiver<Option<f64>>>,
    /// The live view (`[live]`): shown every delivered frame, never waited for.
    pub live: Option<super::live::LiveTap>,
    /// Ground truth computed with every frame and sent after its payload (`[output] truth`);
    /// empty: none, and the frames are the same bytes as without the key.
    pub truth: TruthChannels,
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
    /// Lit pixels of DN frames compared with the camera's noise, and those above the
    /// bound ([`crate::sensor::McNoiseStats`], summed over frames).
    pub mc_lit_pixels: u64,
    pub mc_above_bound: u64,
    /// The bound's k (the last such frame's: `[render] sensor_k`, default 0.5).
    pub mc_k: f64,
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
    /// What the camera client asked of this frame (see [`SchedulerConfig::requests`]).
    request: FrameRequest,
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
    /// Time spent computing the frame's truth (None with truth off).
    truth_time: Option<Duration>,
}

/// The scheduler's metric series. Built once by `serve::run` before the server
/// announces itself, so a `/metrics` scrape made before the first frame already lists
/// every series (at zero), then handed to [`run_scheduler`].
pub struct SchedulerMetrics {
    frames: Counter,
    late: Counter,
    degraded: Counter,
    superseded: Counter,
    skipped: Counter,
    failed: Vec<(&'static str, Counter)>,
    triggers: Counter,
    render: Arc<Histogram>,
    truth: Arc<Histogram>,
    spp: Gauge,
    spp_milli: Gauge,
    depth: Gauge,
    rate_millihz: Gauge,
    mc_lit: Counter,
    mc_above: Counter,
    mc_above_ppm: Gauge,
    mc_rms_milli: Gauge,
}

impl SchedulerMetrics {
    pub fn new(r: &Registry) -> Self {
        SchedulerMetrics {
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
            truth: r.histogram(
                "hilcam_truth_seconds",
                "Ground-truth time per frame ([output] truth; part of hilcam_render_seconds)",
                &[],
            ),
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
            rate_millihz: r.gauge(
                "hilcam_frame_rate_setting_millihz",
                "Rate the scheduler renders at in rate trigger mode, in mHz (0 in pose / external mode)",
                &[],
            ),
            mc_lit: r.counter(
                "hilcam_mc_lit_pixels_total",
                "Lit pixels of DN frames whose Monte Carlo noise was compared with the camera's",
                &[],
            ),
            mc_above: r.counter(
                "hilcam_mc_above_bound_pixels_total",
                "Lit pixels whose Monte Carlo noise exceeded k times the camera's temporal noise",
                &[],
            ),
            mc_above_ppm: r.gauge(
                "hilcam_frame_mc_above_bound_ppm",
                "Lit pixels of the last frame above the Monte Carlo noise bound, parts per million",
                &[],
            ),
            mc_rms_milli: r.gauge(
                "hilcam_frame_mc_rms_ratio_milli",
                "RMS ratio of Monte Carlo to camera noise over the last frame's lit pixels, in thousandths",
                &[],
            ),
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
                late: flags.late(),
                extrapolated: flags.extrapolated(),
                degraded: flags.degraded(),
                integration_s: d.integration_s,
                payload_crc32: crc,
                request: j.request,
                mc_noise: frame.mc_noise,
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
    truth: TruthChannels,
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
                render_job(&mut pipeline, &job, budget, truth)
            }));
            let (frame, integration_s, truth_time) = attempt.unwrap_or_else(|payload| {
                pipeline.reset();
                let message = panic_message(payload.as_ref());
                (Err(FrameFailure { reason: "panic", message }), None, None)
            });
            let late = frame.as_ref().map(|f| f.meta.flags.contains(FrameFlags::LATE)).unwrap_or(false);
            let d = Done { job, frame, render_time: t0.elapsed(), quality, late, integration_s, truth_time };
            if done.blocking_send(d).is_err() {
                break;
            }
        }
    })
}

/// Render, convert and encode one job (with its truth when `truth` is not empty: the
/// frame's time to compute it is returned).
fn render_job(
    pipeline: &mut FramePipeline,
    job: &Job,
    budget: Duration,
    truth: TruthChannels,
) -> (Result<Arc<EncodedFrame>, FrameFailure>, Option<f64>, Option<Duration>) {
    let f = match pipeline.frame_requested(&job.pose, &job.settings, job.index, &job.request) {
        Ok(f) => f,
        Err(e) => return (Err(FrameFailure { reason: "sensor", message: e.to_string() }), None, None),
    };
    let t0 = Instant::now();
    let truth = match truth.is_empty() {
        true => None,
        false => match pipeline.truth(&job.pose, &job.request, truth) {
            Ok(t) => Some(Arc::new(t)),
            Err(e) => return (Err(FrameFailure { reason: "sensor", message: e.to_string() }), None, None),
        },
    };
    let truth_time = truth.as_ref().map(|_| t0.elapsed());
    let late = job.reference.elapsed() > budget;
    let flags = if late { job.flags.with(FrameFlags::LATE) } else { job.flags };
    let meta =
        FrameMeta { pose_arrival_unix_ns: job.arrival_unix_ns, ..FrameMeta::rendered(job.index, &job.pose, &f, flags) };
    let integration_s = f.integration_s;
    let encoded = Frame::new(meta, f.pixels).map(|mut fr| {
        fr.meta.emit_unix_ns = unix_ns_now();
        let encoded = match truth {
            Some(t) => fr.encode_with_truth(t),
            None => fr.encode(),
        };
        Arc::new(EncodedFrame { roi: job.request.roi, mc_noise: f.mc_noise, ..encoded })
    });
    (encoded.map_err(|e| FrameFailure { reason: "encode", message: e.to_string() }), integration_s, truth_time)
}

/// The text of a panic payload (`panic!` with a literal or a formatted message).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic with a non-text payload".into())
}

/// The loop's state between events: what is due, what is rendering, what was counted.
struct Loop {
    cfg: SchedulerConfig,
    m: SchedulerMetrics,
    s: SchedulerSummary,
    sinks: Arc<Vec<Sink>>,
    governor: Governor,
    /// The configured quality: a frame below it is flagged degraded.
    best: Quality,
    /// The newest pose and its arrival.
    latest: Option<(Pose, Instant)>,
    /// Poses accepted since the last render started.
    pending: u64,
    /// A frame is due; its reference instant.
    want: Option<Instant>,
    busy: bool,
    inputs_open: bool,
    /// Index of the next frame.
    index: u64,
    last_integration: f64,
    render_times: RenderTimes,
    failures_in_row: u32,
}

impl Loop {
    fn new(cfg: SchedulerConfig, sinks: Arc<Vec<Sink>>, m: SchedulerMetrics) -> Self {
        let best = Quality { spp: cfg.settings.spp, depth: cfg.settings.depth };
        Loop {
            governor: Governor::new(cfg.policy, cfg.budget, best),
            m,
            s: SchedulerSummary::default(),
            sinks,
            best,
            latest: None,
            pending: 0,
            want: None,
            busy: false,
            inputs_open: true,
            index: 0,
            last_integration: 0.0,
            render_times: RenderTimes::default(),
            failures_in_row: 0,
            cfg,
        }
    }

    fn all_frames_started(&self) -> bool {
        self.cfg.max_frames.is_some_and(|n| self.index >= n)
    }

    /// Nothing left to do: the frame budget is spent, or the inputs closed and no frame
    /// can become due (a `Rate` ticker keeps rendering the last pose).
    fn finished(&self) -> bool {
        let starved = !self.inputs_open && self.cfg.trigger != TriggerMode::Rate && self.want.is_none();
        !self.busy && (self.all_frames_started() || starved)
    }

    fn on_input(&mut self, ev: Option<InputEvent>) {
        match ev {
            None => self.inputs_open = false,
            Some(InputEvent::Pose { pose, arrival }) => {
                if let Some(tap) = &self.cfg.session {
                    tap.pose(&pose, arrival);
                }
                self.s.poses += 1;
                self.pending += 1;
                self.latest = Some((pose, arrival));
                if self.cfg.trigger == TriggerMode::Pose {
                    self.want = Some(arrival);
                }
            }
            Some(InputEvent::Trigger { arrival, .. }) => {
                self.s.triggers += 1;
                self.m.triggers.inc();
                if self.cfg.trigger == TriggerMode::External {
                    if self.want.is_some() {
                        self.skip_busy();
                    }
                    self.want = Some(arrival);
                }
            }
            Some(InputEvent::Heartbeat { .. }) => {}
        }
    }

    fn on_tick(&mut self, tick: Instant) {
        if self.busy || self.want.is_some() {
            self.skip_busy();
        } else {
            self.want = Some(tick);
        }
    }

    fn skip_busy(&mut self) {
        self.s.skipped_busy += 1;
        self.m.skipped.inc();
    }

    /// A frame came back from the renderer: learn its time, publish or count it. `false`
    /// when the renderer is taken to be broken (`s.fatal` says why).
    fn on_done(&mut self, d: Option<Done>) -> bool {
        self.busy = false;
        let Some(d) = d else {
            self.s.fatal = Some("the render thread stopped unexpectedly".into());
            return false;
        };
        self.governor.observe(d.quality, d.render_time);
        if let Some(i) = d.integration_s {
            self.last_integration = i;
        }
        self.deliver(&d);
        if self.failures_in_row >= MAX_CONSECUTIVE_FAILURES {
            let e = d.frame.as_ref().err().map(ToString::to_string).unwrap_or_default();
            self.s.fatal = Some(format!("{} frames in a row failed; the last: {e}", self.failures_in_row));
            return false;
        }
        true
    }

    /// Publish a finished frame to every sink and count it (late, degraded, its quality),
    /// or count and log its failure.
    fn deliver(&mut self, d: &Done) {
        let (m, s) = (&self.m, &mut self.s);
        self.render_times.record(d.render_time);
        m.render.record_duration(d.render_time);
        if let Some(t) = d.truth_time {
            m.truth.record_duration(t);
        }
        record(self.cfg.session.as_ref(), d);
        match &d.frame {
            Ok(frame) => {
                self.failures_in_row = 0;
                for sink in self.sinks.iter() {
                    sink.publish(frame);
                }
                if let Some(live) = &self.cfg.live {
                    live.frame(&d.job.pose, frame, d.render_time);
                }
                s.frames += 1;
                m.frames.inc();
                m.spp.set(i64::from(d.quality.spp.floor()));
                m.spp_milli.set(i64::from(d.quality.spp.milli()));
                m.depth.set(i64::from(d.quality.depth));
                if let Some(mc) = &frame.mc_noise {
                    m.mc_lit.add(mc.lit_pixels);
                    m.mc_above.add(mc.above_bound);
                    m.mc_above_ppm.set((mc.above_fraction * 1e6).round() as i64);
                    m.mc_rms_milli.set((mc.rms_ratio * 1e3).round() as i64);
                    s.mc_lit_pixels += mc.lit_pixels;
                    s.mc_above_bound += mc.above_bound;
                    s.mc_k = mc.k;
                }
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
                self.failures_in_row += 1;
                s.failed += 1;
                if let Some((_, c)) = m.failed.iter().find(|(r, _)| *r == e.reason) {
                    c.inc();
                }
                tracing::error!(
                    frame = d.job.index,
                    pose_seq = d.job.pose.seq,
                    in_a_row = self.failures_in_row,
                    "frame failed, not delivered: {e}"
                );
            }
        }
    }

    /// The next job, when a frame is due, the renderer is free and a pose exists.
    fn due_job(&mut self) -> Option<Job> {
        let (Some(reference), false, Some((pose, arrival))) = (self.want, self.busy, self.latest) else {
            return None;
        };
        self.want = None;
        if self.all_frames_started() {
            return None;
        }
        let superseded = self.pending.saturating_sub(1);
        self.s.superseded += superseded;
        self.m.superseded.add(superseded);
        self.pending = 0;
        let q = self.governor.current();
        let mut flags = FrameFlags::default();
        if q != self.best {
            flags = flags.with(FrameFlags::DEGRADED);
        }
        let (pose, extrapolated_s) = match self.exposure_pose(&pose, arrival, reference) {
            Some((moved, dt)) => {
                flags = flags.with(FrameFlags::EXTRAPOLATED);
                (moved, dt)
            }
            None => (pose, 0.0),
        };
        let job = Job {
            pose,
            source_arrival: arrival,
            extrapolated_s,
            started: Instant::now(),
            poses_received: self.s.poses,
            arrival_unix_ns: unix_ns_of(arrival),
            reference,
            settings: RenderSettings { spp: q.spp, depth: q.depth, ..self.cfg.settings },
            request: self.cfg.requests.as_ref().map(|rx| *rx.borrow()).unwrap_or_default(),
            index: self.index,
            flags,
        };
        self.index += 1;
        self.busy = true;
        Some(job)
    }

    /// The pose moved to the exposure mid-time (or start, for a camera that integrates
    /// motion) with its rates and the seconds it moved (`Rate` mode with `extrapolate`;
    /// None when it did not move).
    fn exposure_pose(&self, pose: &Pose, arrival: Instant, reference: Instant) -> Option<(Pose, f64)> {
        if !(self.cfg.extrapolate && self.cfg.trigger == TriggerMode::Rate) {
            return None;
        }
        let to_mid = if self.cfg.exposure_start { 0.0 } else { self.last_integration * 0.5 };
        let dt = reference.saturating_duration_since(arrival).as_secs_f64() + to_mid;
        let (moved, did_move) = extrapolate(pose, dt);
        did_move.then_some((moved, dt))
    }

    /// Poses still waiting at shutdown were replaced by the newest one, which was not
    /// rendered either; count them so that accepted = rendered-from + superseded + 1.
    fn summary(mut self) -> SchedulerSummary {
        let unrendered = self.pending.saturating_sub(1);
        self.s.superseded += unrendered;
        self.m.superseded.add(unrendered);
        self.s.render_p50_ms = self.render_times.percentile_ms(0.5);
        self.s.render_p99_ms = self.render_times.percentile_ms(0.99);
        self.s
    }
}

/// The configured `Rate` mode rate (None in the other modes: frames wait for a pose or
/// a trigger).
fn configured_rate(cfg: &SchedulerConfig) -> Option<f64> {
    match (cfg.trigger, cfg.rate_hz) {
        (TriggerMode::Rate, Some(hz)) if hz > 0.0 => Some(hz),
        _ => None,
    }
}

/// A ticker at `hz` whose first tick is at `first`.
fn ticker_at(hz: f64, first: tokio::time::Instant) -> tokio::time::Interval {
    let mut t = tokio::time::interval_at(first, Duration::from_secs_f64(1.0 / hz));
    t.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    t
}

/// The `Rate` mode rate the scheduler follows: the configured one, or a camera client's.
struct TickRate {
    configured: f64,
    current: f64,
    requests: Option<tokio::sync::watch::Receiver<Option<f64>>>,
    /// The newest tick (the next one under a new rate is one new period after it).
    last_tick: Option<Instant>,
}

impl TickRate {
    fn new(configured: f64, mut requests: Option<tokio::sync::watch::Receiver<Option<f64>>>) -> Self {
        let current = requests.as_mut().and_then(|r| *r.borrow_and_update()).unwrap_or(configured);
        TickRate { configured, current, requests, last_tick: None }
    }

    /// The next requested rate; never ready without a request channel (or once it closed).
    async fn changed(&mut self) -> Option<f64> {
        match self.requests.as_mut() {
            Some(rx) => match rx.changed().await {
                Ok(()) => Some(rx.borrow_and_update().unwrap_or(self.configured)),
                Err(_) => {
                    self.requests = None;
                    std::future::pending().await
                }
            },
            None => std::future::pending().await,
        }
    }

    /// Switch to `hz`: the ticker to run from now on, or None when the rate is unchanged
    /// (or not usable: the device refuses such writes, this only guards the division).
    fn switch(&mut self, hz: f64, m: &SchedulerMetrics) -> Option<tokio::time::Interval> {
        if hz == self.current || !(hz.is_finite() && hz > 0.0) {
            return None;
        }
        tracing::info!(
            from_hz = self.current,
            to_hz = hz,
            configured_hz = self.configured,
            "frame rate set by the camera client"
        );
        self.current = hz;
        m.rate_millihz.set((hz * 1e3).round() as i64);
        let now = Instant::now();
        let next = self.last_tick.map_or(now, |t| (t + Duration::from_secs_f64(1.0 / hz)).max(now));
        Some(ticker_at(hz, tokio::time::Instant::from_std(next)))
    }
}

async fn next_rate(rate: &mut Option<TickRate>) -> Option<f64> {
    match rate.as_mut() {
        Some(r) => r.changed().await,
        None => std::future::pending().await,
    }
}

async fn next_tick(ticker: &mut Option<tokio::time::Interval>) -> Option<Instant> {
    match ticker.as_mut() {
        Some(t) => Some(t.tick().await.into_std()),
        None => None,
    }
}

/// Run until `shutdown` is triggered, the inputs close (in `Pose`/`External` mode), or
/// `max_frames` frames are out. The frame in flight is finished and published. However
/// it stops (done, or the renderer failed), it triggers `shutdown` for the rest of the
/// server. Counts into `metrics`.
pub async fn run_scheduler(
    cfg: SchedulerConfig,
    pipeline: FramePipeline,
    mut inputs: mpsc::Receiver<InputEvent>,
    sinks: Arc<Vec<Sink>>,
    metrics: SchedulerMetrics,
    shutdown: Shutdown,
) -> SchedulerSummary {
    let (job_tx, job_rx) = std::sync::mpsc::channel::<Job>();
    let (done_tx, mut done_rx) = mpsc::channel::<Done>(1);
    let renderer = spawn_renderer(pipeline, cfg.budget, cfg.fault.clone(), cfg.truth, job_rx, done_tx);
    let mut rate = configured_rate(&cfg).map(|hz| TickRate::new(hz, cfg.rate_requests.clone()));
    let mut ticker = rate.as_ref().map(|r| ticker_at(r.current, tokio::time::Instant::now()));
    metrics.rate_millihz.set(rate.as_ref().map_or(0, |r| (r.current * 1e3).round() as i64));
    let mut st = Loop::new(cfg, sinks, metrics);
    let renderer = match renderer {
        Ok(r) => r,
        Err(e) => {
            st.s.fatal = Some(format!("cannot start the render thread: {e}"));
            shutdown.trigger();
            return st.summary();
        }
    };
    let stopped = shutdown.wait();
    tokio::pin!(stopped);
    while !st.finished() {
        tokio::select! {
            _ = &mut stopped => break,
            ev = inputs.recv(), if st.inputs_open => st.on_input(ev),
            Some(tick) = next_tick(&mut ticker), if ticker.is_some() => {
                if let Some(r) = rate.as_mut() {
                    r.last_tick = Some(tick);
                }
                st.on_tick(tick)
            }
            Some(hz) = next_rate(&mut rate) => {
                if let Some(t) = rate.as_mut().and_then(|r| r.switch(hz, &st.m)) {
                    ticker = Some(t);
                }
            }
            d = done_rx.recv(), if st.busy => {
                if !st.on_done(d) {
                    break;
                }
            }
        }
        if let Some(job) = st.due_job()
            && job_tx.send(job).is_err()
        {
            tracing::error!("render thread is gone");
            break;
        }
    }
    shutdown.trigger();
    // Finish the frame in flight (unless the renderer is what failed), then stop the
    // render thread.
    if st.busy && st.s.fatal.is_none() {
        match done_rx.recv().await {
            Some(d) => st.deliver(&d),
            None => st.s.fatal = Some("the render thread stopped unexpectedly".into()),
        }
    }
    drop(job_tx);
    let _ = tokio::task::spawn_blocking(move || renderer.join()).await;
    st.summary()
}
