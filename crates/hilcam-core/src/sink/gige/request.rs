//! A client's ExposureTime and ROI as the [`FrameRequest`] the serve loop renders, its
//! AcquisitionFrameRate as the rate the serve loop renders at (`rate` trigger mode), and
//! both with TriggerSoftware as the device's [`CameraControl`].

use super::{CameraSettings, GigeDevice};
use crate::pipeline::FrameRequest;
use crate::render::camera::Window;
use crate::sink::camera_control::CameraControl;
use tokio::sync::watch;

/// The integration time (s) that `s` asks of the sensor, or `None` for the sensor's own
/// (auto-exposure on, or the configured time the client has not changed — so a client
/// that only reads leaves every frame's bytes as they were).
pub fn integration_override(initial: &CameraSettings, s: &CameraSettings) -> Option<f64> {
    let untouched = !initial.exposure_auto && s.exposure_us == initial.exposure_us;
    (!s.exposure_auto && !untouched).then(|| f64::from(s.exposure_us) * 1e-6)
}

/// The region `s` asks for, or `None` for the whole sensor (`initial` is the whole).
pub fn roi(initial: &CameraSettings, s: &CameraSettings) -> Option<Window> {
    let w = s.window();
    (w != initial.window()).then_some(w)
}

/// What `s` asks of each frame.
pub fn frame_request(initial: &CameraSettings, s: &CameraSettings) -> FrameRequest {
    FrameRequest { integration_s: integration_override(initial, s), roi: roi(initial, s) }
}

/// The frame rate (Hz) `s` asks of the renderer, or `None` for the configured one
/// (the client has not changed AcquisitionFrameRate).
pub fn rate_override(initial: &CameraSettings, s: &CameraSettings) -> Option<f64> {
    (s.frame_rate_hz != initial.frame_rate_hz).then(|| f64::from(s.frame_rate_hz))
}

/// What the device's clients ask of the renderer: their exposure and ROI, their frame
/// rate and their software triggers (serve merges it like any transport's).
pub fn camera_control(device: &GigeDevice) -> CameraControl {
    CameraControl {
        metric: "gige",
        label: "GigE Vision",
        requests: Some(follow_requests(device)),
        rate_requests: Some(follow_frame_rate(device)),
        triggers: Some(device.software_triggers()),
    }
}

/// A channel of [`frame_request`] that follows the device's settings until the device
/// stops; the scheduler reads it as each frame starts. From then on an exposure or ROI
/// write from a client that accepts PENDING_ACK is acknowledged once a frame showing it
/// is published.
pub fn follow_requests(device: &GigeDevice) -> watch::Receiver<FrameRequest> {
    device.mark_requests_followed();
    follow(device, frame_request, |r| {
        tracing::info!(
            integration_s = ?r.integration_s,
            roi = ?r.roi,
            "GigE Vision client changed the frame (None: the sensor's own exposure, the whole array)"
        )
    })
}

/// A channel of [`rate_override`] that follows the device's settings until the device
/// stops: the scheduler's tick rate in `rate` trigger mode (it logs the change).
pub fn follow_frame_rate(device: &GigeDevice) -> watch::Receiver<Option<f64>> {
    follow(device, rate_override, |_| {})
}

/// A channel of `what(initial, settings)`, sent (and `changed` called) only when the
/// value changes.
fn follow<T: PartialEq + Copy + Send + Sync + 'static>(
    device: &GigeDevice,
    what: fn(&CameraSettings, &CameraSettings) -> T,
    changed: fn(&T),
) -> watch::Receiver<T> {
    let mut settings = device.settings();
    let initial = *settings.borrow();
    let (tx, rx) = watch::channel(what(&initial, &initial));
    tokio::spawn(async move {
        while settings.changed().await.is_ok() {
            let v = what(&initial, &settings.borrow_and_update());
            if tx.send_if_modified(|old| std::mem::replace(old, v) != v) {
                changed(&v);
            }
            if tx.is_closed() {
                break;
            }
        }
    });
    rx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_changed_or_manual_exposure_overrides_the_sensor() {
        let cam = crate::sink::gige::registers::tests::camera();
        let fixed = CameraSettings { exposure_auto: false, exposure_us: 250.0, ..CameraSettings::initial(&cam) };
        assert_eq!(integration_override(&fixed, &fixed), None, "untouched: the configured time, same bytes");
        let written = CameraSettings { exposure_us: 500.0, ..fixed };
        assert_eq!(integration_override(&fixed, &written), Some(500e-6));
        let auto = CameraSettings { exposure_auto: true, ..fixed };
        assert_eq!(integration_override(&auto, &auto), None, "auto-exposure runs");
        let manual = CameraSettings { exposure_auto: false, ..auto };
        assert_eq!(integration_override(&auto, &manual), Some(250e-6), "auto switched off: the written time");
    }

    #[test]
    fn only_a_region_smaller_than_the_sensor_is_an_roi() {
        let cam = crate::sink::gige::registers::tests::camera();
        let full = CameraSettings::initial(&cam);
        assert_eq!(frame_request(&full, &full), FrameRequest::default(), "the whole array: the configured frame");
        let small = CameraSettings { width: 16, height: 8, offset_x: 4, offset_y: 2, ..full };
        assert_eq!(roi(&full, &small), Some(Window { x: 4, y: 2, width: 16, height: 8 }));
    }

    #[test]
    fn only_a_changed_frame_rate_overrides_the_configured_one() {
        let cam = crate::sink::gige::registers::tests::camera();
        let initial = CameraSettings::initial(&cam);
        assert_eq!(rate_override(&initial, &initial), None);
        assert_eq!(rate_override(&initial, &CameraSettings { frame_rate_hz: 5.0, ..initial }), Some(5.0));
    }
}
