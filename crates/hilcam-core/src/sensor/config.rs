//! Sensor configuration: the `[sensor]` table of a camera preset, and its validation.
//!
//! Every effect is optional and off unless the file turns it on. With an empty
//! `[sensor]` table the output is the input radiance (times `radiance_scale`) as float32.

use super::SensorError;
use crate::render::camera::CameraModel;
use crate::render::camera::distortion::Distortion;
use serde::Deserialize;
use std::path::Path;

/// The whole `[sensor]` table.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// What the sensor sends: `"float32"` (radiance after the optics, times
    /// `radiance_scale`) or `"dn"` (digital numbers from the ADC). Default: `"dn"` when
    /// `[sensor.adc]` is present, else `"float32"`.
    #[serde(default)]
    pub output: Option<OutputKind>,
    /// Multiplier applied to the radiance when no detector is modelled: float32 output
    /// is `L × radiance_scale`; with `output = "dn"` and no detector, `L × radiance_scale`
    /// plays the role of the electron count fed to the ADC. Default 1.
    #[serde(default)]
    pub radiance_scale: Option<f64>,
    /// The spectral band the radiance is integrated over. Required by the detector
    /// (photon energy) and by the Airy PSF (default wavelengths).
    #[serde(default)]
    pub band: Option<BandConfig>,
    #[serde(default)]
    pub optics: OpticsConfig,
    #[serde(default)]
    pub detector: Option<DetectorConfig>,
    #[serde(default)]
    pub adc: Option<AdcConfig>,
    #[serde(default)]
    pub auto_exposure: Option<AutoExposureConfig>,
}

/// Output pixel kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OutputKind {
    /// Radiance (W·sr⁻¹·m⁻²) after the image-space optics, f32.
    Float32,
    /// Digital numbers: `Mono8` for an 8-bit ADC, else `Mono16` holding `bits` bits.
    Dn,
}

/// Spectral band, micrometres.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BandConfig {
    pub min_um: f64,
    pub max_um: f64,
}

/// Optics between the entrance pupil and the focal plane.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpticsConfig {
    /// Working f-number N = f / D. Give this or `aperture_mm`, not both.
    #[serde(default)]
    pub f_number: Option<f64>,
    /// Entrance-pupil diameter D, millimetres.
    #[serde(default)]
    pub aperture_mm: Option<f64>,
    /// Band-averaged transmittance of the optics, 0..=1 (applied to the radiance).
    #[serde(default)]
    pub transmittance: Option<f64>,
    /// Natural vignetting: multiply by cos⁴θ of each pixel's field angle.
    #[serde(default)]
    pub cos4: bool,
    /// Brown–Conrady lens distortion, applied by the renderer (see
    /// [`crate::render::camera::distortion`]); the sensor itself only validates it.
    #[serde(default)]
    pub distortion: Option<Distortion>,
    /// Point spread function (energy-preserving convolution of the radiance image).
    #[serde(default)]
    pub psf: Option<PsfConfig>,
}

/// Point spread function.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum PsfConfig {
    /// Gaussian of standard deviation `sigma_px` pixels (defocus, jitter, charge
    /// diffusion lumped together).
    Gaussian { sigma_px: f64 },
    /// Diffraction-limited Airy pattern of a circular unobstructed aperture at the
    /// optics' f-number. `wavelength_um` gives a monochromatic PSF; without it the PSF is
    /// averaged over the band. `radius_px` truncates the kernel (default: 8 first-zero radii,
    /// at least 3 px); the truncated kernel is renormalised so energy is preserved.
    Airy {
        #[serde(default)]
        wavelength_um: Option<f64>,
        #[serde(default)]
        radius_px: Option<u32>,
    },
}

/// Quantum efficiency: a band-average, or a curve of (wavelength µm, QE) points.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum QeConfig {
    Constant(f64),
    Curve(Vec<[f64; 2]>),
}

/// Photo-detector (electrons).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorConfig {
    /// Quantum efficiency (electrons per photon), constant or a curve over the band.
    pub qe: QeConfig,
    /// Integration (exposure) time, seconds; the start value when auto-exposure is on.
    pub integration_time_s: f64,
    /// Full-well capacity, electrons: the collected charge saturates there.
    #[serde(default)]
    pub full_well_e: Option<f64>,
    /// Mean dark current, electrons per second per pixel.
    #[serde(default)]
    pub dark_current_e_per_s: Option<f64>,
    /// Photon (and dark) shot noise: Poisson sampling of the collected charge.
    #[serde(default)]
    pub shot_noise: bool,
    /// How the shot noise meets the renderer's Monte Carlo noise (when a frame comes with
    /// its per-pixel Monte Carlo variance): `"add"` (default) draws the full shot noise on
    /// top; `"substitute"` draws only the part the Monte Carlo noise does not already
    /// supply (docs/sensor.md, "Monte Carlo noise and the sensor").
    #[serde(default)]
    pub noise: NoiseMode,
    /// Read noise, electrons rms (Gaussian, added after the full-well clip).
    #[serde(default)]
    pub read_noise_e: Option<f64>,
    /// Photo-response non-uniformity: rms relative gain spread (e.g. 0.01 = 1 %).
    #[serde(default)]
    pub prnu: Option<f64>,
    /// Dark-signal non-uniformity: rms spread of the dark current, e⁻/s.
    #[serde(default)]
    pub dsnu_e_per_s: Option<f64>,
    /// Seed of the fixed-pattern maps (a property of the physical sensor, not the frame).
    #[serde(default)]
    pub fpn_seed: u64,
    /// Effective wavelength for the photon energy, µm. Default: from the band and QE
    /// (see docs/sensor.md, "Photons").
    #[serde(default)]
    pub effective_wavelength_um: Option<f64>,
    /// When the rows integrate: `instant` (default), `global` or `rolling`.
    #[serde(default)]
    pub exposure: super::ExposureMode,
    /// Rolling shutter: delay between the starts of consecutive rows, µs.
    #[serde(default)]
    pub line_time_us: Option<f64>,
}

/// How the detector's shot noise combines with a frame's Monte Carlo noise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NoiseMode {
    /// Full shot noise on top of the Monte Carlo noise (the frame is noisier than the camera).
    #[default]
    Add,
    /// Shot noise of variance λ − v_e only (v_e the pixel's Monte Carlo variance in e⁻²),
    /// so the frame's temporal variance is the camera's wherever v_e ≤ λ.
    Substitute,
}

/// Analogue-to-digital conversion.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdcConfig {
    /// Bit depth, 8..=16 (8 → Mono8; otherwise Mono16 holding values < 2^bits).
    pub bits: u8,
    /// Conversion gain, electrons per DN.
    #[serde(default = "one")]
    pub gain_e_per_dn: f64,
    /// Black-level offset, DN, added before quantisation.
    #[serde(default)]
    pub offset_dn: f64,
}

fn one() -> f64 {
    1.0
}

/// Auto-exposure: after each frame, scale the integration time so that the
/// `percentile` of the frame's DN (above the offset) lands at `target_fraction` of the
/// ADC range, within `[min_s, max_s]`, changing by at most `max_step`× per frame.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AutoExposureConfig {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Percentile of the pixel values measured, 0 < p ≤ 100 (default 99.5: a small
    /// bright target on black sky still drives exposure).
    #[serde(default = "default_percentile")]
    pub percentile: f64,
    /// Where that percentile should sit, as a fraction of the usable DN range (0..1).
    #[serde(default = "default_target")]
    pub target_fraction: f64,
    pub min_s: f64,
    pub max_s: f64,
    /// Largest factor the integration time may change by between frames (> 1).
    #[serde(default = "default_step")]
    pub max_step: f64,
}

fn yes() -> bool {
    true
}
fn default_percentile() -> f64 {
    99.5
}
fn default_target() -> f64 {
    0.6
}
fn default_step() -> f64 {
    4.0
}

/// A camera preset file: `[camera]` intrinsics and `[sensor]` model in one TOML file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPreset {
    pub camera: CameraModel,
    #[serde(default)]
    pub sensor: SensorConfig,
}

impl CameraPreset {
    /// Read and parse a preset; the error names the file (and line, for syntax errors).
    /// Validation happens in [`super::Sensor::new`].
    pub fn load(path: &Path) -> Result<CameraPreset, SensorError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| SensorError::Io { path: path.to_path_buf(), source })?;
        toml::from_str(&text).map_err(|e| SensorError::Parse { path: path.to_path_buf(), message: e.to_string() })
    }
}

/// Largest `radiance_scale`: with radiance up to 1e6 the product stays far inside f32.
const MAX_RADIANCE_SCALE: f64 = 1.0e12;

fn invalid(field: &str, message: impl Into<String>) -> SensorError {
    SensorError::Invalid { field: field.to_string(), message: message.into() }
}

/// The rolling line times a frame can report (`line_time_ns`, a u32 of ns), µs.
pub const LINE_TIME_US_MIN: f64 = 0.001;
pub const LINE_TIME_US_MAX: f64 = u32::MAX as f64 / 1000.0;

fn positive(field: &str, v: f64) -> Result<(), SensorError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(field, format!("must be a finite number > 0 (got {v})")))
    }
}

fn non_negative(field: &str, v: f64) -> Result<(), SensorError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(field, format!("must be a finite number ≥ 0 (got {v})")))
    }
}

impl SensorConfig {
    /// The output kind after defaults.
    pub fn output_kind(&self) -> OutputKind {
        self.output.unwrap_or(if self.adc.is_some() { OutputKind::Dn } else { OutputKind::Float32 })
    }

    /// What a float32 output leaves out of a configured detector, as the warning at
    /// start-up says it (None: nothing is left out). The radiance skips the charge, noise
    /// and ADC stages; a global or rolling exposure still integrates the radiance over
    /// its time, and the frame is tagged with that integration time.
    pub fn float_output_note(&self) -> Option<String> {
        use super::ExposureMode;
        let det = self.detector.as_ref().filter(|_| self.output_kind() == OutputKind::Float32)?;
        let mode = match det.exposure {
            ExposureMode::Instant => {
                return Some(
                    "sensor: output = \"float32\" sends radiance; [sensor.detector] and [sensor.adc] are not applied"
                        .into(),
                );
            }
            ExposureMode::Global => "global",
            ExposureMode::Rolling => "rolling",
        };
        Some(format!(
            "sensor: output = \"float32\" sends radiance: [sensor.detector]'s {mode} exposure is applied (the \
             radiance is integrated over integration_time_s = {} s, and each frame is tagged with it); its charge, \
             noise and [sensor.adc] are not",
            det.integration_time_s
        ))
    }

    /// The f-number from `f_number` or `aperture_mm` and the focal length.
    pub fn f_number(&self, camera: &CameraModel) -> Option<f64> {
        match (self.optics.f_number, self.optics.aperture_mm) {
            (Some(n), _) => Some(n),
            (None, Some(d)) => Some(camera.focal_mm / d),
            (None, None) => None,
        }
    }

    /// Check every field; errors name the field as it is written in the TOML file.
    pub fn validate(&self, camera: &CameraModel) -> Result<(), SensorError> {
        if let Some(s) = self.radiance_scale {
            positive("sensor.radiance_scale", s)?;
            // Radiance is ≲ 1e6 W·sr⁻¹·m⁻² (the scene's limits); keep the product in f32.
            if s > MAX_RADIANCE_SCALE {
                return Err(invalid("sensor.radiance_scale", format!("must be ≤ {MAX_RADIANCE_SCALE:e} (got {s})")));
            }
        }
        if let Some(b) = &self.band {
            positive("sensor.band.min_um", b.min_um)?;
            positive("sensor.band.max_um", b.max_um)?;
            if b.max_um <= b.min_um {
                return Err(invalid("sensor.band.max_um", "must exceed min_um"));
            }
        }
        let o = &self.optics;
        if o.f_number.is_some() && o.aperture_mm.is_some() {
            return Err(invalid("sensor.optics.aperture_mm", "give f_number or aperture_mm, not both"));
        }
        if let Some(n) = o.f_number {
            positive("sensor.optics.f_number", n)?;
        }
        if let Some(d) = o.aperture_mm {
            positive("sensor.optics.aperture_mm", d)?;
        }
        if let Some(t) = o.transmittance
            && !(t > 0.0 && t <= 1.0)
        {
            return Err(invalid("sensor.optics.transmittance", format!("must be in (0, 1] (got {t})")));
        }
        if let Some(d) = &o.distortion {
            // Half-diagonal in normalised units, with 5 % margin for samples at pixel edges.
            let f = camera.focal_px();
            let (hw, hh) = (
                camera.width as f64 / 2.0 + camera.principal_point_px[0].abs(),
                camera.height as f64 / 2.0 + camera.principal_point_px[1].abs(),
            );
            let max_r = 1.05 * (hw * hw + hh * hh).sqrt() / f;
            d.validate(max_r).map_err(|e| invalid("sensor.optics.distortion", e.to_string()))?;
        }
        match &o.psf {
            Some(PsfConfig::Gaussian { sigma_px }) => {
                positive("sensor.optics.psf.sigma_px", *sigma_px)?;
                if *sigma_px > 64.0 {
                    return Err(invalid("sensor.optics.psf.sigma_px", "must be ≤ 64 px (a wider blur is not a PSF)"));
                }
            }
            Some(PsfConfig::Airy { wavelength_um, radius_px }) => {
                if self.f_number(camera).is_none() {
                    return Err(invalid(
                        "sensor.optics.psf",
                        "an Airy PSF needs sensor.optics.f_number or aperture_mm",
                    ));
                }
                match wavelength_um {
                    Some(w) => positive("sensor.optics.psf.wavelength_um", *w)?,
                    None if self.band.is_none() => {
                        return Err(invalid("sensor.optics.psf.wavelength_um", "give a wavelength or a [sensor.band]"));
                    }
                    None => {}
                }
                if let Some(r) = radius_px
                    && !(1..=64).contains(r)
                {
                    return Err(invalid("sensor.optics.psf.radius_px", format!("must be in 1..=64 (got {r})")));
                }
            }
            None => {}
        }
        if let Some(d) = &self.detector {
            self.validate_detector(d, camera)?;
        }
        if let Some(a) = &self.adc {
            if !(8..=16).contains(&a.bits) {
                return Err(invalid("sensor.adc.bits", format!("must be in 8..=16 (got {})", a.bits)));
            }
            positive("sensor.adc.gain_e_per_dn", a.gain_e_per_dn)?;
            non_negative("sensor.adc.offset_dn", a.offset_dn)?;
            if a.offset_dn >= ((1u32 << a.bits) - 1) as f64 {
                return Err(invalid("sensor.adc.offset_dn", "must be below the ADC maximum 2^bits − 1"));
            }
        }
        if self.output_kind() == OutputKind::Dn && self.adc.is_none() {
            return Err(invalid("sensor.output", "output = \"dn\" needs a [sensor.adc] table (bits, gain_e_per_dn)"));
        }
        if let Some(ae) = &self.auto_exposure {
            self.validate_auto_exposure(ae)?;
        }
        Ok(())
    }

    fn validate_detector(&self, d: &DetectorConfig, camera: &CameraModel) -> Result<(), SensorError> {
        let Some(band) = &self.band else {
            return Err(invalid("sensor.band", "the detector needs [sensor.band] (min_um, max_um) to count photons"));
        };
        if self.f_number(camera).is_none() {
            return Err(invalid("sensor.optics.f_number", "the detector needs the aperture (f_number or aperture_mm)"));
        }
        match &d.qe {
            QeConfig::Constant(q) => {
                if !(*q > 0.0 && *q <= 1.0) {
                    return Err(invalid("sensor.detector.qe", format!("must be in (0, 1] (got {q})")));
                }
            }
            QeConfig::Curve(pts) => {
                if pts.len() < 2 {
                    return Err(invalid("sensor.detector.qe", "a curve needs ≥ 2 points"));
                }
                if pts.iter().any(|p| !p[0].is_finite()) {
                    return Err(invalid("sensor.detector.qe", "curve wavelengths must be finite"));
                }
                for w in pts.windows(2) {
                    if w[1][0] <= w[0][0] {
                        return Err(invalid("sensor.detector.qe", "curve wavelengths must increase"));
                    }
                }
                if pts.iter().any(|p| !(p[1] >= 0.0 && p[1] <= 1.0)) {
                    return Err(invalid("sensor.detector.qe", "curve values must be in [0, 1]"));
                }
                if pts[0][0] > band.min_um || pts[pts.len() - 1][0] < band.max_um {
                    return Err(invalid("sensor.detector.qe", "the curve must cover the band [min_um, max_um]"));
                }
            }
        }
        // 0 is allowed: a zero-length exposure collects no charge and integrates no
        // motion (the instant frame's radiance; docs/sensor.md §11).
        non_negative("sensor.detector.integration_time_s", d.integration_time_s)?;
        if let Some(v) = d.full_well_e {
            positive("sensor.detector.full_well_e", v)?;
        }
        if let Some(v) = d.dark_current_e_per_s {
            non_negative("sensor.detector.dark_current_e_per_s", v)?;
        }
        if let Some(v) = d.read_noise_e {
            non_negative("sensor.detector.read_noise_e", v)?;
        }
        if let Some(v) = d.prnu
            && !(v.is_finite() && (0.0..0.5).contains(&v))
        {
            return Err(invalid("sensor.detector.prnu", format!("must be in [0, 0.5) (got {v})")));
        }
        if let Some(v) = d.dsnu_e_per_s {
            non_negative("sensor.detector.dsnu_e_per_s", v)?;
        }
        if d.noise == NoiseMode::Substitute {
            if !d.shot_noise {
                return Err(invalid(
                    "sensor.detector.noise",
                    "\"substitute\" replaces part of the shot noise: it needs shot_noise = true",
                ));
            }
            if self.output_kind() != OutputKind::Dn {
                return Err(invalid(
                    "sensor.detector.noise",
                    "\"substitute\" acts on the detector's charge: it needs DN output ([sensor.adc])",
                ));
            }
        }
        if let Some(v) = d.effective_wavelength_um {
            positive("sensor.detector.effective_wavelength_um", v)?;
        }
        match (d.exposure, d.line_time_us) {
            (super::ExposureMode::Rolling, None) => {
                return Err(invalid("sensor.detector.line_time_us", "a rolling exposure needs its line time (µs)"));
            }
            (super::ExposureMode::Rolling, Some(v)) => {
                positive("sensor.detector.line_time_us", v)?;
                // Frames carry it as a u32 of ns (header bytes 80..84, frames.jsonl): a
                // value it cannot hold would be reported saturated or as 0 (global).
                if !(LINE_TIME_US_MIN..=LINE_TIME_US_MAX).contains(&v) {
                    return Err(invalid(
                        "sensor.detector.line_time_us",
                        format!(
                            "{v} µs: frames report it in whole ns as a u32 (line_time_ns), so it must be \
                             {LINE_TIME_US_MIN}..={LINE_TIME_US_MAX} µs"
                        ),
                    ));
                }
            }
            (_, Some(_)) => {
                return Err(invalid(
                    "sensor.detector.line_time_us",
                    "only a rolling exposure has a line time (set exposure = \"rolling\")",
                ));
            }
            (_, None) => {}
        }
        Ok(())
    }

    fn validate_auto_exposure(&self, ae: &AutoExposureConfig) -> Result<(), SensorError> {
        if self.detector.is_none() || self.output_kind() != OutputKind::Dn {
            return Err(invalid(
                "sensor.auto_exposure",
                "needs [sensor.detector] and DN output (it adjusts the integration time)",
            ));
        }
        if !(ae.percentile > 0.0 && ae.percentile <= 100.0) {
            return Err(invalid(
                "sensor.auto_exposure.percentile",
                format!("must be in (0, 100] (got {})", ae.percentile),
            ));
        }
        if !(ae.target_fraction > 0.0 && ae.target_fraction < 1.0) {
            return Err(invalid(
                "sensor.auto_exposure.target_fraction",
                format!("must be in (0, 1) (got {})", ae.target_fraction),
            ));
        }
        positive("sensor.auto_exposure.min_s", ae.min_s)?;
        positive("sensor.auto_exposure.max_s", ae.max_s)?;
        if ae.max_s < ae.min_s {
            return Err(invalid("sensor.auto_exposure.max_s", "must be ≥ min_s"));
        }
        if !(ae.max_step > 1.0 && ae.max_step.is_finite()) {
            return Err(invalid("sensor.auto_exposure.max_step", format!("must be > 1 (got {})", ae.max_step)));
        }
        Ok(())
    }
}

/// Whether a sensor can judge `settings.quality`: `"sensor"` measures Monte Carlo noise
/// against the camera's, which needs a detector and DN output, and spends samples per
/// pixel, which a hybrid frame does not have.
pub fn check_quality(
    settings: &crate::render::integrator::RenderSettings,
    sensor: &SensorConfig,
) -> Result<(), String> {
    let quality = &settings.quality;
    if quality.is_sensor() && settings.method == crate::render::integrator::Method::Hybrid {
        return Err("\"sensor\" spends samples pixel by pixel, and method = \"hybrid\" takes a fixed 64 \
                    coverage samples per pixel: use \"fixed\", or method = \"path\""
            .into());
    }
    if quality.is_sensor() && (sensor.detector.is_none() || sensor.output_kind() != OutputKind::Dn) {
        return Err("\"sensor\" measures the Monte Carlo noise against the camera's own, which needs a \
                    [sensor.detector] and DN output ([sensor.adc]); use \"fixed\" for this camera"
            .into());
    }
    if let Some(d) = sensor.detector.as_ref().filter(|_| quality.is_sensor())
        && !d.shot_noise
        && d.read_noise_e.is_none_or(|r| r <= 0.0)
    {
        return Err("\"sensor\" keeps the Monte Carlo noise below the camera's own temporal noise, and this \
                    [sensor.detector] has none (shot_noise = false, no read_noise_e): every sample would be \
                    needed; turn on the camera's noise or use \"fixed\""
            .into());
    }
    Ok(())
}
