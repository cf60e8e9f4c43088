//! A client's ExposureTime as the integration time the serve loop's sensor uses.

use super::{CameraSettings, GigeDevice};
use tokio::sync::watch;

/// The integration time (s) that `s` asks of the sensor, or `None` for the sensor's own
/// (auto-exposure on, or the configured time the client has not changed — so a client
/// that only reads leaves every frame's bytes as they were).
pub fn integration_override(initial: &CameraSettings, s: &CameraSettings) -> Option<f64> {
    let untouched = !initial.exposure_auto && s.exposure_us == initial.exposure_us;
    (!s.exposure_auto && !untouched).then(|| f64::from(s.exposure_us) * 1e-6)
}

/// A channel of [`integration_override`] that follows the device's settings until the
/// device stops; the scheduler reads it as each frame starts. From then on an exposure
/// write from a client that accepts PENDING_ACK is acknowledged once a frame with it is
/// published.
pub fn follow_exposure(device: &GigeDevice) -> watch::Receiver<Option<f64>> {
    device.mark_exposure_followed();
    let mut settings = device.settings();
    let initial = *settings.borrow();
    let (tx, rx) = watch::channel(integration_override(&initial, &initial));
    tokio::spawn(async move {
        while settings.changed().await.is_ok() {
            let t = integration_override(&initial, &settings.borrow_and_update());
            if tx.send_if_modified(|v| std::mem::replace(v, t) != t) {
                tracing::info!(integration_s = ?t, "GigE Vision client set the exposure (None: the sensor's own)");
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
}
