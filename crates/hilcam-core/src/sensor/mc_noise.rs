//! The renderer's Monte Carlo noise through the sensor: its bound, its variance carried
//! through the linear chain, and the per-frame report.
//!
//! A rendered pixel's radiance is a Monte Carlo mean with variance `v` (radiance²,
//! estimated by the renderer from its samples; independent between pixels). The sensor's
//! chain up to the charge is linear, so the variance follows the signal exactly:
//!
//! - optics: `v · (τ cos⁴θ)²`;
//! - PSF: `Σᵢ W(o,i)² vᵢ`, the kernel's weights squared ([`super::psf::convolve_variance`]);
//! - charge: `· (k_e (1 + PRNU·z₁))²`, `k_e` the photo-electrons per unit radiance over the
//!   integration time, giving `v_e` in e⁻²; DN²: `v_e / gain²`.
//!
//! `docs/sensor.md` ("Monte Carlo noise and the sensor") gives the substitution of shot
//! noise and the assumptions.

use super::config::OutputKind;
use super::detector::Detector;
use super::{Sensor, SensorError, psf};
use crate::render::film::RadianceImage;
use crate::render::noise_bound::{Cos4, NoiseBound};
use rayon::prelude::*;

/// How a frame's Monte Carlo noise compares with the camera's own temporal noise
/// (present in [`super::FrameStats`] when the frame came with a variance image and the
/// sensor has a detector with DN output).
///
/// Lit pixels are those whose expected photo-charge (the rendered radiance converted, dark
/// charge excluded) is at least 1 e⁻. At a lit pixel, the Monte Carlo standard deviation
/// σ_mc = √v_e (after optics and PSF, PRNU included) is compared with the camera's
/// temporal noise σ_cam = √(photo + dark + read²) (photo and dark only with shot noise on),
/// both in electrons at that pixel.
///
/// It is written as the `mc_noise` object of a frame's `frames.jsonl` line and session
/// `frame` line under these field names.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct McNoiseStats {
    /// The bound's fraction `k` (σ_mc ≤ k·σ_cam meets it).
    pub k: f64,
    /// Pixels whose expected photo-charge is ≥ 1 e⁻.
    pub lit_pixels: u64,
    /// Lit pixels with σ_mc > k·σ_cam.
    pub above_bound: u64,
    /// `above_bound / lit_pixels` (0 without lit pixels).
    pub above_fraction: f64,
    /// Lit pixels whose Monte Carlo variance exceeds their shot-noise variance (v_e >
    /// photo + dark; with shot noise off, v_e > 0): with `noise = "substitute"` they get
    /// no shot noise and are still noisier than the camera.
    pub above_shot: u64,
    /// Mean of σ_mc / σ_cam over lit pixels (0 without lit pixels). Each pixel's σ_mc
    /// is the square root of an estimate, so this mean reads low at few samples.
    pub mean_ratio: f64,
    /// √(mean of σ_mc² / σ_cam²) over lit pixels: built from the unbiased variance
    /// estimates, the ratio's honest summary (0 without lit pixels).
    pub rms_ratio: f64,
    /// Mean Monte Carlo variance over lit pixels, e⁻².
    pub mc_variance_e2_mean: f64,
}

/// Per-row partial sums of [`McNoiseStats`] (reduced in row order).
#[derive(Clone, Copy, Default)]
pub(super) struct McRow {
    pub lit: u64,
    pub above: u64,
    pub above_shot: u64,
    pub ratio: f64,
    pub ratio2: f64,
    pub var_e2: f64,
}

impl McRow {
    /// Count pixel `pixel` of radiance `l` and Monte Carlo variance `v` (radiance², both
    /// after the optics) at detector `d`; its expected photo and dark charge and its
    /// variance in e⁻² (PRNU included), for the caller's draw.
    #[inline]
    pub fn add_pixel(&mut self, k: f64, d: &Detector, l: f64, v: f64, pixel: u64) -> (f64, f64, f64) {
        let (photo, dark) = d.expected_parts(l, pixel);
        let g = d.photo_gain(pixel);
        let v_e = v * g * g;
        self.add(k, d.shot_noise, photo, dark, v_e, d.read_noise_e * d.read_noise_e);
        (photo, dark, v_e)
    }

    /// Count one pixel: expected `photo` and `dark` charge, Monte Carlo variance `v_e`
    /// (e⁻²), read noise `read_e2` (e⁻²).
    #[inline]
    pub fn add(&mut self, k: f64, shot: bool, photo: f64, dark: f64, v_e: f64, read_e2: f64) {
        if photo < 1.0 {
            return;
        }
        let shot_e2 = if shot { photo + dark } else { 0.0 };
        let cam = shot_e2 + read_e2;
        self.lit += 1;
        self.above += (v_e > k * k * cam) as u64;
        self.above_shot += (v_e > shot_e2) as u64;
        let r2 = if cam > 0.0 { v_e / cam } else { 0.0 };
        self.ratio += r2.sqrt();
        self.ratio2 += r2;
        self.var_e2 += v_e;
    }
}

impl McNoiseStats {
    pub(super) fn from_rows(k: f64, rows: impl Iterator<Item = McRow>) -> McNoiseStats {
        let mut s = McNoiseStats { k, ..Default::default() };
        for r in rows {
            s.lit_pixels += r.lit;
            s.above_bound += r.above;
            s.above_shot += r.above_shot;
            s.mean_ratio += r.ratio;
            s.rms_ratio += r.ratio2;
            s.mc_variance_e2_mean += r.var_e2;
        }
        if s.lit_pixels > 0 {
            s.above_fraction = s.above_bound as f64 / s.lit_pixels as f64;
            s.mean_ratio /= s.lit_pixels as f64;
            s.rms_ratio = (s.rms_ratio / s.lit_pixels as f64).sqrt();
            s.mc_variance_e2_mean /= s.lit_pixels as f64;
        }
        s
    }
}

impl Sensor {
    /// The camera's temporal noise at integration time `t_s`, for the renderer's
    /// `quality = "sensor"` budget: None unless the sensor has a detector and DN output.
    /// Its `e_per_radiance_at(row, col)` (sensor pixel coordinates, whatever the window) is
    /// the expected photo-charge per unit entrance radiance without PRNU;
    /// `floor_e2` = dark charge (with shot noise on) + read noise².
    pub fn noise_bound(&self, t_s: f64, k: f64) -> Option<NoiseBound> {
        if self.output != OutputKind::Dn {
            return None;
        }
        let d = Detector::new(self.cfg.detector.as_ref()?, self.e_per_radiance_s?, t_s, None);
        let o = &self.cfg.optics;
        let cam = &self.camera;
        let cos4 = o.cos4.then(|| Cos4 {
            focal_px: cam.focal_px(),
            centre: [
                cam.width as f64 / 2.0 + cam.principal_point_px[0],
                cam.height as f64 / 2.0 + cam.principal_point_px[1],
            ],
        });
        Some(NoiseBound {
            k,
            e_per_radiance: d.e_per_radiance * o.transmittance.unwrap_or(1.0),
            floor_e2: if d.shot_noise { d.dark_e } else { 0.0 } + d.read_noise_e * d.read_noise_e,
            shot: d.shot_noise,
            cos4,
            psf_factor: self.psf_variance_factor(),
        })
    }

    /// Σ W² of the PSF (1 without one): the factor by which it divides an interior
    /// pixel's Monte Carlo variance when its neighbours have the same variance.
    pub fn psf_variance_factor(&self) -> f64 {
        self.psf.iter().map(|k| k.weights.iter().map(|w| *w as f64 * *w as f64).sum::<f64>()).product()
    }

    /// A Monte Carlo variance image (radiance², the layout of the frame) after the
    /// image-space optics: `· (τ cos⁴θ)²`, then the PSF with squared weights.
    pub fn optics_variance(&self, variance: &[f32]) -> Result<Vec<f32>, SensorError> {
        let (w, h) = (self.window.width as usize, self.window.height as usize);
        if variance.len() != w * h {
            return Err(SensorError::VarianceSize { got: variance.len(), want: w * h });
        }
        let o = &self.cfg.optics;
        let tau = o.transmittance.unwrap_or(1.0);
        let mut out = variance.to_vec();
        if tau != 1.0 || o.cos4 {
            let (cam, keys) = (&self.camera, self.keys());
            out.par_chunks_mut(w).enumerate().for_each(|(row, line)| {
                for (col, v) in line.iter_mut().enumerate() {
                    let mut f = tau;
                    if o.cos4 {
                        let (r, c) = keys.on_sensor(row as u32, col as u32);
                        f *= super::optics::cos4(cam, c, r);
                    }
                    *v = (*v as f64 * f * f) as f32;
                }
            });
        }
        for k in &self.psf {
            out = psf::convolve_variance(&out, w, h, k);
        }
        Ok(out)
    }

    /// The report [`Sensor::apply_with_variance`] gives for this radiance and variance
    /// at integration time `t_s`, against bound `k`, without converting the frame: the
    /// same pixels counted the same way, so one frame can be judged against several `k`.
    /// None without a detector with DN output.
    pub fn mc_noise_stats(
        &self,
        img: &RadianceImage,
        variance: &[f32],
        t_s: f64,
        k: f64,
    ) -> Result<Option<McNoiseStats>, SensorError> {
        let Some(d) = self.detector(t_s) else { return Ok(None) };
        let rad = self.optics(img)?;
        if variance.len() != img.data.len() {
            return Err(SensorError::VarianceSize { got: variance.len(), want: img.data.len() });
        }
        let v = self.optics_variance(variance)?;
        let (w, keys) = (img.width as usize, self.keys());
        let rows: Vec<McRow> = rad
            .data
            .par_chunks(w)
            .zip(v.par_chunks(w))
            .enumerate()
            .map(|(row, (l, vr))| {
                let mut r = McRow::default();
                for (col, (l, v)) in l.iter().zip(vr).enumerate() {
                    r.add_pixel(k, &d, *l as f64, *v as f64, keys.key(row as u32, col as u32));
                }
                r
            })
            .collect();
        Ok(Some(McNoiseStats::from_rows(k, rows.into_iter())))
    }

    /// The Monte Carlo variance of each pixel's charge, e⁻² (PRNU included), at
    /// integration time `t_s`; None without a detector (or with float output).
    pub fn mc_variance_e2(&self, variance: &[f32], t_s: f64) -> Result<Option<Vec<f64>>, SensorError> {
        let Some(det) = self.detector(t_s) else { return Ok(None) };
        let v = self.optics_variance(variance)?;
        let keys = self.keys();
        let w = self.window.width as usize;
        let mut out = vec![0.0f64; v.len()];
        out.par_chunks_mut(w).zip(v.par_chunks(w)).enumerate().for_each(|(row, (o, src))| {
            for (col, (o, s)) in o.iter_mut().zip(src).enumerate() {
                let g = det.photo_gain(keys.key(row as u32, col as u32));
                *o = *s as f64 * g * g;
            }
        });
        Ok(Some(out))
    }

    /// The Monte Carlo variance of each output pixel in the output's units squared: DN²
    /// (`v_e / gain²`, or `(v · radiance_scale / gain)²` without a detector) or, for float
    /// output, (radiance · `radiance_scale`)².
    pub fn mc_variance_output(&self, variance: &[f32], t_s: f64) -> Result<Vec<f64>, SensorError> {
        let s2 = self.radiance_scale * self.radiance_scale;
        let Some(adc) = self.adc.filter(|_| self.output == OutputKind::Dn) else {
            return Ok(self.optics_variance(variance)?.iter().map(|v| *v as f64 * s2).collect());
        };
        let g2 = adc.gain_e_per_dn * adc.gain_e_per_dn;
        Ok(match self.mc_variance_e2(variance, t_s)? {
            Some(e2) => e2.into_iter().map(|v| v / g2).collect(),
            None => self.optics_variance(variance)?.iter().map(|v| *v as f64 * s2 / g2).collect(),
        })
    }
}
