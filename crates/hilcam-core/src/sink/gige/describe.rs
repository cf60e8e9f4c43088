//! The camera a GigE Vision client sees, from hilcam's camera and sensor config.

use super::registers::{CameraDescription, FRAME_RATE_MAX};
use crate::render::camera::CameraModel;
use crate::sensor::SensorConfig;

/// Frame rate offered when the serve loop has none configured (Hz).
const DEFAULT_RATE_HZ: f32 = 10.0;

impl CameraDescription {
    /// Sensor geometry from `camera`; bit depth, integration time and its range from
    /// `sensor` (`[sensor.adc]`, `[sensor.detector]`, `[sensor.auto_exposure]`).
    /// Without an ADC the stream would carry radiance, which GigE Vision cannot:
    /// the caller refuses that configuration ([`CameraDescription::from_scene`] errs).
    ///
    /// `rate_hz` is AcquisitionFrameRate at start. With `rate_sets_schedule` (the serve
    /// loop renders at a fixed rate, which the client's AcquisitionFrameRate then sets)
    /// it is also the highest rate a client may write: the frame budget is made for it.
    /// Otherwise the rate only thins the frames and may be anything up to the XML's max.
    pub fn from_scene(
        camera: &CameraModel,
        sensor: &SensorConfig,
        rate_hz: Option<f64>,
        rate_sets_schedule: bool,
    ) -> Result<Self, String> {
        let adc = sensor.adc.as_ref().ok_or_else(|| {
            "[output.gige] needs a sensor with an ADC ([sensor.adc]): GigE Vision streams digital numbers".to_string()
        })?;
        let integration_s = sensor.detector.as_ref().map(|d| d.integration_time_s).unwrap_or(1e-3);
        let ae = sensor.auto_exposure.as_ref();
        let (min_s, max_s) = match ae {
            Some(a) => (a.min_s.min(integration_s), a.max_s.max(integration_s)),
            None => ((integration_s / 1000.0).max(1e-6), (integration_s * 1000.0).min(10.0)),
        };
        Ok(CameraDescription {
            sensor_width: camera.width,
            sensor_height: camera.height,
            adc_bits: adc.bits,
            exposure_us: (integration_s * 1e6) as f32,
            exposure_min_us: (min_s * 1e6) as f32,
            exposure_max_us: (max_s * 1e6) as f32,
            auto_exposure: ae.is_some_and(|a| a.enabled),
            frame_rate_hz: rate_hz.map(|r| r as f32).unwrap_or(DEFAULT_RATE_HZ),
            frame_rate_max_hz: match rate_hz {
                Some(r) if rate_sets_schedule => r as f32,
                _ => FRAME_RATE_MAX,
            },
            truth: Default::default(),
            truth_materials_len: 0,
            rate_sets_schedule: rate_hz.is_some() && rate_sets_schedule,
        })
    }
}
