//! The seam between a camera transport and the serve loop: what a transport's clients
//! may ask of the renderer, whatever carries it (GigE Vision today; a SpaceWire bridge,
//! a ROS 2 topic or CoaXPress next). A transport returns a [`CameraControl`] beside its
//! [`super::Sink`] when it starts; serve merges it (`serve/camera.rs`) without knowing
//! the transport. docs/serve-config.md, "Adding a transport".

use crate::pipeline::FrameRequest;
use std::sync::{Arc, Mutex};
use tokio::sync::watch;

/// What a camera transport's clients ask of the renderer. Every part is optional: a
/// transport that only streams returns [`CameraControl::none`].
pub struct CameraControl {
    /// Names the transport in metrics (`hilcam_<metric>_triggers_dropped_total`).
    pub metric: &'static str,
    /// Names the transport in log lines ("GigE Vision").
    pub label: &'static str,
    /// What each frame renders (exposure, ROI), read as each frame starts; the default
    /// request renders the configured frame.
    pub requests: Option<watch::Receiver<FrameRequest>>,
    /// The frame rate (Hz) in `rate` trigger mode, from the next tick on; `None` inside:
    /// back to the configured rate.
    pub rate_requests: Option<watch::Receiver<Option<f64>>>,
    /// "Render now" from a client, as a bench's trigger message (`external` mode).
    pub triggers: Option<SoftwareTriggers>,
}

impl CameraControl {
    /// Nothing asked: the transport only receives frames.
    pub fn none(metric: &'static str, label: &'static str) -> Self {
        CameraControl { metric, label, requests: None, rate_requests: None, triggers: None }
    }
}

/// What serve calls on each software trigger.
pub type OnTrigger = Box<dyn Fn() + Send + Sync>;

/// A transport's software triggers: it calls [`SoftwareTriggers::fire`] on each, serve
/// [`SoftwareTriggers::connect`]s them to its inputs. A trigger before that goes nowhere.
#[derive(Clone, Default)]
pub struct SoftwareTriggers(Arc<Mutex<Option<OnTrigger>>>);

impl SoftwareTriggers {
    pub fn fire(&self) {
        if let Some(on_trigger) = self.0.lock().expect("triggers lock").as_ref() {
            on_trigger();
        }
    }

    /// Route every later [`SoftwareTriggers::fire`] to `on_trigger` (replacing any before).
    pub fn connect(&self, on_trigger: OnTrigger) {
        *self.0.lock().expect("triggers lock") = Some(on_trigger);
    }
}
