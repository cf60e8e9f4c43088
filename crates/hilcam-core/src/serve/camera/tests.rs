//! The camera-control seam with a fake transport (no network): its software trigger,
//! frame request and frame-rate request reach the scheduler through [`connect`], as a
//! GigE Vision client's do, and the frames go to its sink.

use super::{CameraRequests, connect};
use crate::link::InputEvent;
use crate::metrics::Registry;
use crate::pipeline::{FramePipeline, FrameRequest};
use crate::pose::Pose;
use crate::render::camera::Window;
use crate::serve::governor::Policy;
use crate::serve::scheduler::{SchedulerConfig, SchedulerMetrics, SchedulerSummary, TriggerMode, run_scheduler};
use crate::shutdown::Shutdown;
use crate::sink::camera_control::{CameraControl, SoftwareTriggers};
use crate::sink::{NullSink, Sink};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

const SIZE: u32 = 16;

/// A transport as its clients drive it, seen from the test.
struct FakeTransport {
    requests: watch::Sender<FrameRequest>,
    rate: Arc<watch::Sender<Option<f64>>>,
    triggers: SoftwareTriggers,
}

impl FakeTransport {
    /// Started: the sink serve publishes to and the control serve merges.
    fn start(registry: &Registry) -> (FakeTransport, Sink, CameraControl) {
        let (requests, requests_rx) = watch::channel(FrameRequest::default());
        let (rate, rate_rx) = watch::channel(None);
        let triggers = SoftwareTriggers::default();
        let control = CameraControl {
            metric: "fake",
            label: "fake transport",
            requests: Some(requests_rx),
            rate_requests: Some(rate_rx),
            triggers: Some(triggers.clone()),
        };
        (FakeTransport { requests, rate: Arc::new(rate), triggers }, Sink::Null(NullSink::new(registry)), control)
    }
}

/// A lit sphere filling a 16² camera, one sample per pixel.
fn pipeline() -> FramePipeline {
    let dir = tempfile::tempdir().unwrap();
    let mesh = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes/sphere.obj");
    let text = format!(
        "[[mesh]]\nobj = \"{}\"\n[materials.white_paint]\nmodel = \"lambert\"\nrho = 0.5\n[camera]\nwidth = \
         {SIZE}\nheight = {SIZE}\npitch_um = 10.0\nfocal_mm = 2.0\n[render]\nspp = 1\ndepth = 1\n",
        mesh.display()
    );
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let scene = crate::scene::load(&path).unwrap();
    let camera = scene.camera.clone();
    FramePipeline::new(Arc::new(scene), camera).unwrap()
}

/// The scheduler fed through the seam: `drive` acts as the clients (and the bench, on
/// `inputs`) before the scheduler starts; its frames go to the fake transport's sink.
/// The summary, the bytes the sink got and the time the run took.
async fn serve_fake(
    trigger: TriggerMode,
    rate_hz: Option<f64>,
    frames: u64,
    registry: &Registry,
    drive: impl FnOnce(&FakeTransport, &mpsc::Sender<InputEvent>),
) -> (SchedulerSummary, u64, Duration) {
    let (fake, sink, control) = FakeTransport::start(registry);
    let Sink::Null(null) = &sink else { unreachable!() };
    let null = null.clone();
    let (tx, rx) = mpsc::channel(16);
    let mut camera = CameraRequests::default();
    let inputs = connect(control, rx, registry, &mut camera).unwrap();
    drive(&fake, &tx);
    let pipeline = pipeline();
    let cfg = SchedulerConfig {
        trigger,
        rate_hz,
        extrapolate: false,
        exposure_start: false,
        budget: Duration::from_secs(10),
        policy: Policy::FixedQuality,
        settings: pipeline.scene().render,
        max_frames: Some(frames),
        session: None,
        fault: None,
        requests: camera.requests,
        rate_requests: camera.rate_requests,
        live: None,
        truth: Default::default(),
    };
    let t0 = Instant::now();
    let run =
        run_scheduler(cfg, pipeline, inputs, Arc::new(vec![sink]), SchedulerMetrics::new(registry), Shutdown::new());
    let summary = tokio::time::timeout(Duration::from_secs(60), run).await.expect("the scheduler finished");
    drop((fake, tx));
    (summary, null.bytes.get(), t0.elapsed())
}

fn pose() -> InputEvent {
    InputEvent::Pose { pose: Pose::ahead(10.0), arrival: Instant::now() }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_software_trigger_renders_a_frame_with_the_requested_roi() {
    let roi = Window { x: 2, y: 2, width: 8, height: 4 };
    let registry = Registry::new();
    let (s, roi_bytes, _) = serve_fake(TriggerMode::External, None, 1, &registry, |fake, bench| {
        fake.requests.send_replace(FrameRequest { integration_s: None, roi: Some(roi) });
        bench.try_send(pose()).unwrap();
        fake.triggers.fire();
    })
    .await;
    assert_eq!((s.frames, s.triggers, s.poses, s.fatal.as_deref()), (1, 1, 1, None), "{s:?}");
    let text = registry.render_prometheus();
    assert!(text.contains("hilcam_fake_triggers_dropped_total 0"), "the transport's own counter:\n{text}");

    // The same without the request: the whole array, the pixels beyond the ROI more.
    let (s, full_bytes, _) = serve_fake(TriggerMode::External, None, 1, &Registry::new(), |fake, bench| {
        bench.try_send(pose()).unwrap();
        fake.triggers.fire();
    })
    .await;
    assert_eq!(s.frames, 1);
    let more_pixels = u64::from(SIZE * SIZE - roi.width * roi.height);
    assert!(full_bytes > roi_bytes, "{full_bytes} vs {roi_bytes}");
    assert_eq!((full_bytes - roi_bytes) % more_pixels, 0, "{full_bytes} vs {roi_bytes}: whole pixels apart");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rate_request_sets_the_schedulers_frame_rate() {
    // Configured: a frame every 5 s (4 frames: 15 s). The client asks for 100 Hz once the
    // first frame is out.
    let registry = Registry::new();
    let (s, _, took) = serve_fake(TriggerMode::Rate, Some(0.2), 4, &registry, |fake, bench| {
        bench.try_send(pose()).unwrap();
        let rate = fake.rate.clone();
        tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(200)).await;
            rate.send_replace(Some(100.0));
        });
    })
    .await;
    assert_eq!(s.frames, 4, "{s:?}");
    assert!(took < Duration::from_secs(4), "4 frames took {took:?}: the requested rate was not followed");
    let millihz = registry.gauge("hilcam_frame_rate_setting_millihz", "", &[]).get();
    assert_eq!(millihz, 100_000);
}
