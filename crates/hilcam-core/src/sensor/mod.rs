//! The camera sensor: entrance-pupil radiance → focal-plane irradiance → electrons →
//! digital numbers. `docs/sensor.md` gives the formulas and the config reference.
//!
//! Each effect is switched on by the camera preset's `[sensor]` table and is off
//! otherwise; with everything off a frame is the input radiance (× `radiance_scale`).
//!
//! - [`config`]: `SensorConfig` (serde) and `CameraPreset` (`[camera]` + `[sensor]`).
//! - [`optics`]: transmittance, cos⁴ vignetting, the photon budget.
//! - [`psf`]: Gaussian and Airy kernels, energy-preserving convolution.
//! - [`psf_band`]: a separable PSF row by row, with the whole-image convolution's bits.
//! - [`detector`]: QE, dark current, fixed pattern, shot noise, full well, read noise.
//! - [`stream`]: each pixel's counter-based noise streams, keyed by (frame seed, pixel).
//! - [`ziggurat`]: exact standard normal variates, fast.
//! - [`noise`]: Poisson variates; the fixed pattern's normals.
//! - [`empty_well`]: the DN of a pixel without charge, drawn from its exact distribution;
//!   `dark_run`: a run of such pixels, their draws hashed a chunk at a time;
//!   `dark_sums`: their mean dark charge summed per chunk of the array.
//! - `lit_run`: a row's lit pixels, a block at a time on one branch-free path.
//! - [`adc`]: gain, offset, bit depth, clipping.
//! - [`exposure`]: auto-exposure state across frames.
//! - [`ptc`]: photon-transfer measurement (gain and read noise from flat fields).
//! - [`mc_noise`]: the renderer's Monte Carlo variance through the chain, the camera's
//!   noise bound for `quality = "sensor"`, and the per-frame report.
//! - `convert`: the fused DN pass (optics, PSF, detector, ADC, report) over bands of rows;
//!   `optics_plan`: the optics it runs, planned per sensor and window.
//!
//! ```
//! use hilcam_core::render::camera::CameraModel;
//! use hilcam_core::render::film::{Pixels, RadianceImage};
//! use hilcam_core::sensor::{Sensor, SensorConfig};
//! let cam = CameraModel { width: 4, height: 2, pitch_um: 5.5, focal_mm: 16.0,
//!                         principal_point_px: [0.0, 0.0] };
//! let sensor = Sensor::new(&cam, &SensorConfig::default()).unwrap();
//! let out = sensor.apply(&RadianceImage::new(4, 2, 3.5), 7).unwrap();
//! assert_eq!(out.pixels, Pixels::Float32(vec![3.5; 8]));
//! ```

pub mod adc;
pub mod config;
mod convert;
mod dark_run;
mod dark_sums;
pub mod detector;
pub mod empty_well;
pub mod exposure;
mod lit_run;
pub mod mc_noise;
pub mod noise;
pub mod optics;
mod optics_plan;
pub mod psf;
pub mod psf_band;
pub mod ptc;
mod row_stats;
pub mod shutter;
pub mod stream;
pub mod ziggurat;

pub use config::{CameraPreset, NoiseMode, OutputKind, SensorConfig, check_quality};
pub use exposure::{AutoExposure, ExposureUpdate};
pub use mc_noise::McNoiseStats;
pub use shutter::{ExposureMode, ExposureTiming};

use crate::render::camera::{CameraModel, PixelKeys, Window};
use crate::render::film::{Pixels, RadianceImage};
use adc::Adc;
use detector::Detector;
use optics_plan::{PsfPlan, Scale};
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// Errors from loading, validating or applying a sensor model.
#[derive(Debug, thiserror::Error)]
pub enum SensorError {
    /// A config value is out of range or inconsistent; `field` is its TOML path.
    #[error("{field}: {message}")]
    Invalid { field: String, message: String },
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    /// TOML syntax or schema error (the message carries line and column).
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("radiance image is {got_w}×{got_h} but the camera is {want_w}×{want_h}")]
    SizeMismatch { got_w: u32, got_h: u32, want_w: u32, want_h: u32 },
    #[error("Monte Carlo variance image has {got} pixels but the frame has {want}")]
    VarianceSize { got: usize, want: usize },
}

/// A validated sensor model for one camera, ready to convert frames.
#[derive(Clone, Debug)]
pub struct Sensor {
    camera: CameraModel,
    cfg: SensorConfig,
    output: OutputKind,
    radiance_scale: f64,
    /// (horizontal, vertical) passes of a separable kernel, or one 2D kernel.
    psf: Vec<psf::Kernel>,
    /// Photo-electrons per second per unit radiance (None without a detector).
    e_per_radiance_s: Option<f64>,
    adc: Option<Adc>,
    fixed_pattern: Option<detector::FixedPattern>,
    /// The part of the array this sensor converts (the whole array unless [`Sensor::windowed`]).
    window: Window,
    /// τ cos⁴ over the window (None when it scales nothing) and the PSF's plan for it.
    scale: Option<Scale>,
    psf_plan: PsfPlan,
    /// The DN distribution of an empty well (with a detector whose shot noise is on and DN
    /// output): how the dark pixels are read.
    empty_well: Option<Arc<empty_well::EmptyWell>>,
    /// The mean dark charge's sums per chunk of the array (with a cached fixed pattern).
    dark_sums: Option<Arc<dark_sums::DarkSums>>,
}

/// One converted frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorOutput {
    pub pixels: Pixels,
    /// Integration time used, s (None without a detector).
    pub integration_time_s: Option<f64>,
    pub stats: FrameStats,
}

/// Per-frame counters, so that saturation and clipping are never silent.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Mean expected (noise-free) charge per pixel including dark charge, e⁻; with no
    /// detector, the mean scaled radiance.
    pub mean_expected_e: f64,
    /// Largest expected charge of any pixel, e⁻.
    pub max_expected_e: f64,
    /// Mean collected charge after shot noise and the full-well clip, e⁻.
    pub mean_collected_e: f64,
    /// Pixels whose well was full.
    pub full_well_pixels: u64,
    /// Pixels clipped at DN 0.
    pub adc_low_clipped: u64,
    /// Pixels at the ADC maximum.
    pub adc_high_clipped: u64,
    /// Mean output DN (0 for float output).
    pub mean_dn: f64,
    /// The frame's Monte Carlo noise against the camera's (present when a variance image
    /// was given and the sensor has a detector with DN output).
    pub mc: Option<McNoiseStats>,
}

impl Sensor {
    /// Validate `cfg` for `camera` and precompute kernels and the photon budget.
    ///
    /// # Errors
    /// [`SensorError::Invalid`] naming the offending field.
    pub fn new(camera: &CameraModel, cfg: &SensorConfig) -> Result<Sensor, SensorError> {
        if camera.width == 0 || camera.height == 0 {
            return Err(SensorError::Invalid {
                field: "camera.width".into(),
                message: "the camera has no pixels".into(),
            });
        }
        if !(camera.pitch_um > 0.0 && camera.focal_mm > 0.0) {
            return Err(SensorError::Invalid {
                field: "camera.pitch_um".into(),
                message: "pitch_um and focal_mm must be > 0".into(),
            });
        }
        cfg.validate(camera)?;
        let output = cfg.output_kind();
        let psf = match &cfg.optics.psf {
            None => vec![],
            Some(config::PsfConfig::Gaussian { sigma_px }) => {
                let (h, v) = psf::Kernel::gaussian(*sigma_px);
                vec![h, v]
            }
            Some(config::PsfConfig::Airy { wavelength_um, radius_px }) => {
                let n = cfg.f_number(camera).expect("validated");
                let wl: Vec<f64> = match (wavelength_um, &cfg.band) {
                    (Some(w), _) => vec![*w],
                    (None, Some(b)) => {
                        (0..16).map(|i| b.min_um + (i as f64 + 0.5) * (b.max_um - b.min_um) / 16.0).collect()
                    }
                    (None, None) => unreachable!("validated"),
                };
                vec![psf::Kernel::airy(n, camera.pitch_um, &wl, *radius_px)]
            }
        };
        if let Some(note) = cfg.float_output_note() {
            tracing::warn!("{note}");
        }
        let window = Window::full(camera);
        let adc = cfg.adc.as_ref().map(Adc::new);
        let empty_well = match (&cfg.detector, &adc, output) {
            (Some(d), Some(a), OutputKind::Dn) if d.shot_noise => {
                empty_well::EmptyWell::new(d.read_noise_e.unwrap_or(0.0), a).map(Arc::new)
            }
            _ => None,
        };
        let fixed_pattern = cfg.detector.as_ref().and_then(|d| {
            (d.prnu.unwrap_or(0.0) > 0.0 || d.dsnu_e_per_s.unwrap_or(0.0) > 0.0)
                .then(|| detector::FixedPattern::new(d.fpn_seed, camera.width as usize * camera.height as usize))
        });
        let dark_sums = match (&cfg.detector, &fixed_pattern) {
            (Some(d), Some(fp)) => fp.dsnu_run(0, camera.width as usize * camera.height as usize).map(|z| {
                let (i_d, dsnu) = (d.dark_current_e_per_s.unwrap_or(0.0), d.dsnu_e_per_s.unwrap_or(0.0));
                Arc::new(dark_sums::DarkSums::new(z, i_d, dsnu))
            }),
            _ => None,
        };
        Ok(Sensor {
            camera: camera.clone(),
            cfg: cfg.clone(),
            output,
            radiance_scale: cfg.radiance_scale.unwrap_or(1.0),
            scale: Scale::new(&cfg.optics, camera, &window),
            psf_plan: PsfPlan::new(&cfg.optics.psf, &psf, &window),
            psf,
            e_per_radiance_s: optics::electrons_per_radiance_second(cfg, camera),
            adc,
            empty_well,
            fixed_pattern,
            dark_sums,
            window,
        })
    }

    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// This sensor converting only `window` of its array (a client's ROI, grown by
    /// [`Sensor::psf_margin`]): each pixel gets the cos⁴ factor, fixed pattern and noise
    /// stream of its place on the full array. `window` must be inside the array.
    pub fn windowed(&self, window: Window) -> Sensor {
        Sensor {
            window,
            scale: Scale::new(&self.cfg.optics, &self.camera, &window),
            psf_plan: PsfPlan::new(&self.cfg.optics.psf, &self.psf, &window),
            ..self.clone()
        }
    }

    /// The part of the array converted.
    pub fn window(&self) -> Window {
        self.window
    }

    /// Columns and rows the PSF reads on each side of a pixel: a window grown by this
    /// gives its inner pixels the values they have in the full frame.
    pub fn psf_margin(&self) -> (u32, u32) {
        self.psf.iter().fold((0, 0), |(x, y), k| (x + k.rx as u32, y + k.ry as u32))
    }

    pub fn config(&self) -> &SensorConfig {
        &self.cfg
    }

    /// The output kind (float radiance or DN).
    pub fn output(&self) -> OutputKind {
        self.output
    }

    /// The ADC bit depth for DN output.
    pub fn bits(&self) -> Option<u8> {
        match self.output {
            OutputKind::Dn => self.adc.map(|a| a.bits),
            OutputKind::Float32 => None,
        }
    }

    /// Photo-electrons per second per unit post-optics radiance (None without a detector).
    pub fn electrons_per_radiance_second(&self) -> Option<f64> {
        self.e_per_radiance_s
    }

    /// A fresh auto-exposure state for a stream of frames (None unless configured).
    pub fn auto_exposure(&self) -> Option<AutoExposure> {
        let ae = self.cfg.auto_exposure.as_ref()?;
        let det = self.cfg.detector.as_ref()?;
        Some(AutoExposure::new(ae, self.adc?, det.full_well_e, det.integration_time_s))
    }

    /// The image-space optics alone: transmittance, cos⁴ vignetting, then the PSF.
    /// Returns the input unchanged (bit for bit) when none is configured.
    pub fn optics(&self, img: &RadianceImage) -> Result<RadianceImage, SensorError> {
        self.check_size(img)?;
        let o = &self.cfg.optics;
        let mut out = img.clone();
        let tau = o.transmittance.unwrap_or(1.0);
        if tau != 1.0 || o.cos4 {
            let w = img.width as usize;
            let (cam, keys) = (&self.camera, self.keys());
            out.data.par_chunks_mut(w).enumerate().for_each(|(row, line)| {
                for (col, v) in line.iter_mut().enumerate() {
                    let mut f = tau;
                    if o.cos4 {
                        let (r, c) = keys.on_sensor(row as u32, col as u32);
                        f *= optics::cos4(cam, c, r);
                    }
                    *v = (*v as f64 * f) as f32;
                }
            });
        }
        for k in &self.psf {
            out.data = psf::convolve(&out.data, img.width as usize, img.height as usize, k);
        }
        Ok(out)
    }

    /// Convert one frame at the configured integration time. Deterministic in
    /// `frame_seed`; parallel, with the same bytes whatever the thread count.
    pub fn apply(&self, img: &RadianceImage, frame_seed: u64) -> Result<SensorOutput, SensorError> {
        let t = self.cfg.detector.as_ref().map(|d| d.integration_time_s);
        self.apply_with_integration(img, frame_seed, t.unwrap_or(0.0))
    }

    /// Convert one frame with the integration time an auto-exposure state holds, then
    /// update that state from the result (the next frame gets the new time).
    pub fn apply_auto(
        &self,
        img: &RadianceImage,
        frame_seed: u64,
        ae: &mut AutoExposure,
    ) -> Result<(SensorOutput, ExposureUpdate), SensorError> {
        let out = self.apply_with_integration(img, frame_seed, ae.integration_time_s())?;
        let upd = ae.update(&out.pixels);
        Ok((out, upd))
    }

    /// Convert one frame at integration time `t_s` (ignored without a detector).
    pub fn apply_with_integration(
        &self,
        img: &RadianceImage,
        frame_seed: u64,
        t_s: f64,
    ) -> Result<SensorOutput, SensorError> {
        self.apply_with_variance(img, None, frame_seed, t_s, 0.0)
    }

    /// Convert one frame at integration time `t_s` that comes with the renderer's
    /// per-pixel Monte Carlo variance of the radiance mean (`variance`, radiance², the
    /// layout of `img`; 0 where exact). The variance is carried through the chain
    /// ([`mc_noise`]); with `noise = "substitute"` the shot noise drawn at a pixel with
    /// variance `v_e > 0` is only the remainder; `stats.mc` reports the noise against
    /// `k` times the camera's. Without a variance image this is
    /// [`Sensor::apply_with_integration`], byte for byte; with `noise = "add"` the pixels
    /// are the same as without one.
    pub fn apply_with_variance(
        &self,
        img: &RadianceImage,
        variance: Option<&[f32]>,
        frame_seed: u64,
        t_s: f64,
        k: f64,
    ) -> Result<SensorOutput, SensorError> {
        self.check_size(img)?;
        if let Some(v) = variance
            && v.len() != img.data.len()
        {
            return Err(SensorError::VarianceSize { got: v.len(), want: img.data.len() });
        }
        let w = img.width as usize;
        if self.output == OutputKind::Float32 {
            let rad = self.optics(img)?;
            let s = self.radiance_scale;
            let data: Vec<f32> =
                if s == 1.0 { rad.data } else { rad.data.par_iter().map(|v| (*v as f64 * s) as f32).collect() };
            let sum: f64 =
                data.par_chunks(w).map(|r| r.iter().map(|v| *v as f64).sum::<f64>()).collect::<Vec<_>>().iter().sum();
            let max = data.iter().fold(0.0f64, |m, v| m.max(*v as f64));
            let mean = sum / data.len() as f64;
            return Ok(SensorOutput {
                pixels: Pixels::Float32(data),
                integration_time_s: None,
                stats: FrameStats {
                    mean_expected_e: mean,
                    max_expected_e: max,
                    mean_collected_e: mean,
                    ..Default::default()
                },
            });
        }
        let adc = self.adc.expect("validated: DN output has an ADC");
        let det = self.detector(t_s);
        let (dn, rows) = self.convert_dn(img, variance, det.as_ref(), adc, frame_seed, k)?;
        let n = dn.len();
        let mut s = FrameStats::default();
        for r in &rows {
            s.mean_expected_e += r.expected;
            s.max_expected_e = s.max_expected_e.max(r.max_expected);
            s.mean_collected_e += r.collected;
            s.full_well_pixels += r.full;
            s.adc_low_clipped += r.low;
            s.adc_high_clipped += r.high;
            s.mean_dn += r.dn as f64;
        }
        s.mc = variance.filter(|_| det.is_some()).map(|_| McNoiseStats::from_rows(k, rows.iter().map(|r| r.mc)));
        s.mean_expected_e /= n as f64;
        s.mean_collected_e /= n as f64;
        s.mean_dn /= n as f64;
        if s.full_well_pixels > 0 || s.adc_high_clipped > 0 || s.adc_low_clipped > 0 {
            tracing::debug!(
                full_well = s.full_well_pixels,
                adc_high = s.adc_high_clipped,
                adc_low = s.adc_low_clipped,
                "sensor: saturated or clipped pixels"
            );
        }
        let pixels = if adc.bits == 8 {
            Pixels::Mono8(dn.into_iter().map(|v| v as u8).collect())
        } else {
            Pixels::Mono16 { data: dn, bits: adc.bits }
        };
        Ok(SensorOutput { pixels, integration_time_s: det.as_ref().map(|_| t_s), stats: s })
    }

    /// The detector at integration time `t_s` (None without one, or with float output).
    fn detector(&self, t_s: f64) -> Option<Detector> {
        match (&self.cfg.detector, self.e_per_radiance_s, self.output) {
            (Some(d), Some(k), OutputKind::Dn) => Some(Detector::new(d, k, t_s, self.fixed_pattern.clone())),
            _ => None,
        }
    }

    fn keys(&self) -> PixelKeys {
        PixelKeys::window(&self.window, self.camera.width)
    }

    fn check_size(&self, img: &RadianceImage) -> Result<(), SensorError> {
        if img.width != self.window.width
            || img.height != self.window.height
            || img.data.len() != img.width as usize * img.height as usize
        {
            return Err(SensorError::SizeMismatch {
                got_w: img.width,
                got_h: img.height,
                want_w: self.window.width,
                want_h: self.window.height,
            });
        }
        Ok(())
    }
}
