//! The operator's live view (`[live]`, docs/live.md): a page at `/live` on the metrics
//! listener showing the newest frame, the pose and sun, where the target is, the frame
//! and pose counters and the last minute of render time, latency and spp.
//!
//! Viewing never slows the loop: the scheduler only swaps the newest frame into a slot
//! ([`LiveTap::frame`], a short lock). One encoder thread turns it into a JPEG at most
//! `max_rate_hz` times a second, only while someone watches, once for all viewers; each
//! viewer then gets it through its own bounded drop-oldest queue (the stream's policy,
//! [`crate::sink::queue`]), its losses counted in `hilcam_live_previews_dropped_total`.
//! Off (the default) nothing of this exists.
//!
//! - [`preview`]: frame → shrunk, scaled 8-bit image → JPEG.
//! - [`state`]: what the page shows beside the image.
//! - `http`: the routes (`/live`, `/live/state.json`, `/live/stream.mjpeg`).

mod http;
pub mod preview;
pub mod state;

use crate::frame::EncodedFrame;
use crate::metrics::{Counter, Gauge, Histogram, Registry, Routes};
use crate::pose::Pose;
use crate::render::camera::CameraModel;
use crate::shutdown::Shutdown;
use crate::sink::queue::DropOldest;
use serde::Deserialize;
use state::{LiveState, TargetSphere};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Bounds of `[live]`'s sizes (docs/serve-config.md): previews queued per viewer, viewers.
pub const QUEUE_DEPTH_MAX: usize = 64;
pub const MAX_VIEWERS_MAX: usize = 256;

/// `[live]` in the serve config.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LiveConfig {
    #[serde(default)]
    pub enabled: bool,
    /// Widest preview, pixels: frames are shrunk by the smallest integer factor that fits.
    #[serde(default = "default_max_width")]
    pub max_width: u32,
    /// Most previews encoded per second (the newest frame wins in between).
    #[serde(default = "default_max_rate_hz")]
    pub max_rate_hz: f64,
    #[serde(default = "default_quality")]
    pub jpeg_quality: u8,
    /// Previews queued per viewer before the oldest is dropped.
    #[serde(default = "default_queue_depth")]
    pub queue_depth: usize,
    /// More image streams than this are answered 503.
    #[serde(default = "default_max_viewers")]
    pub max_viewers: usize,
    /// Disconnect a viewer whose queue stayed full this long (it stopped reading), as a
    /// stalled stream client is; 0 = never.
    #[serde(default = "default_evict_after_s")]
    pub evict_after_s: f64,
}

fn default_max_width() -> u32 {
    512
}
fn default_max_rate_hz() -> f64 {
    10.0
}
fn default_quality() -> u8 {
    80
}
fn default_queue_depth() -> usize {
    2
}
fn default_max_viewers() -> usize {
    8
}
fn default_evict_after_s() -> f64 {
    5.0
}

impl Default for LiveConfig {
    fn default() -> Self {
        LiveConfig {
            enabled: false,
            max_width: default_max_width(),
            max_rate_hz: default_max_rate_hz(),
            jpeg_quality: default_quality(),
            queue_depth: default_queue_depth(),
            max_viewers: default_max_viewers(),
            evict_after_s: default_evict_after_s(),
        }
    }
}

impl LiveConfig {
    pub(super) fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(16..=8192).contains(&self.max_width) {
            return Err(("live.max_width", format!("must be 16..=8192, got {}", self.max_width)));
        }
        let r = self.max_rate_hz;
        if !(r.is_finite() && r > 0.0 && r <= 100.0) {
            return Err(("live.max_rate_hz", format!("must be in (0, 100], got {r}")));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return Err(("live.jpeg_quality", format!("must be 1..=100, got {}", self.jpeg_quality)));
        }
        if !(1..=QUEUE_DEPTH_MAX).contains(&self.queue_depth) {
            return Err(("live.queue_depth", format!("must be 1..={QUEUE_DEPTH_MAX}, got {}", self.queue_depth)));
        }
        if !(1..=MAX_VIEWERS_MAX).contains(&self.max_viewers) {
            return Err(("live.max_viewers", format!("must be 1..={MAX_VIEWERS_MAX}, got {}", self.max_viewers)));
        }
        let e = self.evict_after_s;
        if !(e.is_finite() && (0.0..=86_400.0).contains(&e)) {
            return Err(("live.evict_after_s", format!("must be 0 (never) or up to 86400 seconds, got {e}")));
        }
        Ok(())
    }

    /// [`LiveConfig::evict_after_s`] as a limit (None: never).
    pub fn evict_after(&self) -> Option<Duration> {
        (self.evict_after_s > 0.0).then(|| Duration::from_secs_f64(self.evict_after_s))
    }
}

/// One encoded preview, shared by every viewer.
pub struct Preview {
    pub frame_seq: u64,
    pub jpeg: Vec<u8>,
}

/// The newest delivered frame, waiting for the encoder.
#[derive(Default)]
struct Slot {
    frame: Option<Arc<EncodedFrame>>,
    /// Bumped per frame: the encoder encodes a generation once.
    generation: u64,
    stopping: bool,
}

struct Viewer {
    queue: DropOldest<Arc<Preview>>,
}

struct Metrics {
    encode: Arc<Histogram>,
    encoded: Counter,
    encode_errors: Counter,
    dropped: Counter,
    sent: Counter,
    viewers: Gauge,
    refused: Counter,
    evicted: Counter,
}

struct Shared {
    cfg: LiveConfig,
    registry: Arc<Registry>,
    slot: Mutex<Slot>,
    wake: Condvar,
    state: Mutex<LiveState>,
    /// The newest preview (a new viewer starts with it).
    preview: Mutex<Option<Arc<Preview>>>,
    viewers: Mutex<Vec<Arc<Viewer>>>,
    watching: AtomicUsize,
    m: Metrics,
    stop: Shutdown,
}

/// The live view: create with [`LiveView::start`], hand [`LiveView::tap`] to the
/// scheduler and [`LiveView::routes`] to the metrics listener, end with [`LiveView::close`].
pub struct LiveView {
    shared: Arc<Shared>,
    encoder: std::thread::JoinHandle<()>,
}

/// The scheduler's handle: [`LiveTap::frame`] per delivered frame.
#[derive(Clone)]
pub struct LiveTap(Arc<Shared>);

impl LiveTap {
    /// Show this frame (rendered from `pose`): a short lock, never an encode or a wait.
    pub fn frame(&self, pose: &Pose, frame: &Arc<EncodedFrame>, render_time: Duration) {
        self.0.state.lock().expect("live state poisoned").frame(pose, frame, render_time);
        let mut slot = self.0.slot.lock().expect("live slot poisoned");
        slot.frame = Some(frame.clone());
        slot.generation += 1;
        drop(slot);
        self.0.wake.notify_one();
    }
}

impl LiveView {
    /// Register the metrics and start the encoder thread.
    pub fn start(
        cfg: &LiveConfig,
        camera: &CameraModel,
        target: TargetSphere,
        registry: &Arc<Registry>,
    ) -> std::io::Result<LiveView> {
        let r = registry;
        let m = Metrics {
            encode: r.histogram(
                "hilcam_live_encode_seconds",
                "Live view: time to shrink, scale and JPEG-encode one preview",
                &[],
            ),
            encoded: r.counter("hilcam_live_previews_encoded_total", "Live view previews encoded", &[]),
            encode_errors: r.counter(
                "hilcam_live_encode_errors_total",
                "Live view previews that failed to encode",
                &[],
            ),
            dropped: r.counter(
                "hilcam_live_previews_dropped_total",
                "Live view previews a viewer lost because its queue was full (slow browser)",
                &[("reason", "queue_full")],
            ),
            sent: r.counter("hilcam_live_previews_sent_total", "Live view previews written to viewers", &[]),
            viewers: r.gauge("hilcam_live_viewers", "Live view image streams open", &[]),
            refused: r.counter(
                "hilcam_live_viewers_refused_total",
                "Live view streams refused (max_viewers open)",
                &[],
            ),
            evicted: r.counter(
                "hilcam_live_viewers_evicted_total",
                "Live view streams closed because the viewer stopped reading",
                &[],
            ),
        };
        let shared = Arc::new(Shared {
            cfg: cfg.clone(),
            registry: registry.clone(),
            slot: Mutex::new(Slot::default()),
            wake: Condvar::new(),
            state: Mutex::new(LiveState::new(camera.clone(), target)),
            preview: Mutex::new(None),
            viewers: Mutex::new(Vec::new()),
            watching: AtomicUsize::new(0),
            m,
            stop: Shutdown::new(),
        });
        let s = shared.clone();
        let encoder = std::thread::Builder::new().name("hilcam-live".into()).spawn(move || encode_loop(&s))?;
        Ok(LiveView { shared, encoder })
    }

    pub fn tap(&self) -> LiveTap {
        LiveTap(self.shared.clone())
    }

    /// `/live`, `/live/state.json` and `/live/stream.mjpeg`.
    pub fn routes(&self) -> Routes {
        http::routes(self.shared.clone())
    }

    /// Stop the encoder and close every viewer's stream.
    pub async fn close(self) {
        self.shared.stop.trigger();
        self.shared.slot.lock().expect("live slot poisoned").stopping = true;
        self.shared.wake.notify_all();
        let _ = tokio::task::spawn_blocking(move || self.encoder.join()).await;
    }
}

/// The encoder thread: wait until a frame not yet encoded is there, someone watches and
/// the rate allows, then encode it and queue it for every viewer.
fn encode_loop(s: &Shared) {
    let period = Duration::from_secs_f64(1.0 / s.cfg.max_rate_hz);
    let (mut done_generation, mut next_at) = (0u64, Instant::now());
    loop {
        let frame = {
            let mut slot = s.slot.lock().expect("live slot poisoned");
            loop {
                if slot.stopping {
                    return;
                }
                let due = slot.generation != done_generation && s.watching.load(Relaxed) > 0;
                let now = Instant::now();
                if due && now >= next_at {
                    break;
                }
                slot = if due {
                    s.wake.wait_timeout(slot, next_at - now).expect("live slot poisoned").0
                } else {
                    s.wake.wait(slot).expect("live slot poisoned")
                };
            }
            done_generation = slot.generation;
            slot.frame.clone().expect("a generation has a frame")
        };
        let t0 = Instant::now();
        next_at = t0 + period;
        let img = preview::preview(&frame.pixels(), frame.meta.width, frame.meta.height, s.cfg.max_width);
        let jpeg = match preview::jpeg(&img, s.cfg.jpeg_quality) {
            Ok(j) => j,
            Err(e) => {
                s.m.encode_errors.inc();
                tracing::warn!(frame = frame.meta.frame_seq, "live view: preview not encoded: {e}");
                continue;
            }
        };
        s.m.encode.record_duration(t0.elapsed());
        s.m.encoded.inc();
        let p = Arc::new(Preview { frame_seq: frame.meta.frame_seq, jpeg });
        *s.preview.lock().expect("live preview poisoned") = Some(p.clone());
        for v in s.viewers.lock().expect("live viewers poisoned").iter() {
            if v.queue.push(p.clone()).is_some() {
                s.m.dropped.inc();
            }
        }
    }
}
