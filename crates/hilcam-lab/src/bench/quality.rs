//! The independent judge of sensor-equivalent frames (issue 36): how many lit pixels of a
//! frame carry more error than half the camera's own temporal noise, counted from many
//! seeds of the same pose against a converged reference — not from the frame's own report.
//!
//! Each row renders `seeds` frames of one pose (seeds `base + 1 …`, the same frame index)
//! through the whole pipeline (render + sensor, what `serve` sends, timed), and takes each
//! frame's radiance through the sensor's linear chain (τ cos⁴, PSF, photo-electrons per
//! unit radiance at the held integration time; PRNU left out: it scales signal and error
//! alike), clipped at the full well as the camera clips it. Per lit pixel (reference ≥ 1
//! e⁻):
//!
//! - σ²_seed: the unbiased variance over the seeds — the noise a board sees from frame to
//!   frame;
//! - MSE: σ²_seed + bias², bias² estimated as (mean − reference)² − σ²_seed/N − σ²_ref,
//!   floored at 0 — an error that is the same for every seed (a cache filled alike for
//!   every seed, a fixed sample pattern) counts here;
//! - σ²_cam = signal + dark + read² + gain²/12 (shot, dark and read noise, quantisation).
//!
//! A pixel is *above* when σ²_seed > k²σ²_cam (the noise share) and, for the error share,
//! when MSE > k²σ²_cam. The reference is averaged from independent chunks, so its own
//! variance σ²_ref is known and taken out of the bias.

use super::median;
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Pose;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{Method, QualityGoal, RenderSettings, Spp};
use hilcam_core::sensor::{McNoiseStats, SensorError};
use std::fmt::Write as _;

/// The bound's fraction of the camera's noise the issue asks for.
pub const K: f64 = 0.5;

/// The camera's conversion of radiance to expected photo-charge at one integration time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conversion {
    /// Photo-electrons per unit radiance after the optics, at the held integration time.
    pub e_per_radiance: f64,
    /// The well's capacity, e⁻: a pixel's charge is clipped there, as the camera's is (a
    /// glint far above it is the same white whatever its Monte Carlo error).
    pub full_well_e: f64,
    /// Dark charge (with shot noise) + read noise², e⁻².
    pub floor_e2: f64,
    /// Quantisation noise, e⁻² (gain²/12).
    pub quant_e2: f64,
}

impl Conversion {
    /// The conversion of `pipeline`'s sensor at integration time `t_s`; None without a
    /// detector with DN output.
    pub fn of(pipeline: &FramePipeline, t_s: f64) -> Option<Conversion> {
        let s = pipeline.sensor();
        let bound = s.noise_bound(t_s, K)?;
        let gain = s.config().adc.as_ref().map_or(0.0, |a| a.gain_e_per_dn);
        let full_well_e = s.config().detector.as_ref().and_then(|d| d.full_well_e).unwrap_or(f64::INFINITY);
        Some(Conversion {
            e_per_radiance: bound.e_per_radiance,
            full_well_e,
            floor_e2: bound.floor_e2,
            quant_e2: gain * gain / 12.0,
        })
    }

    /// The camera's temporal noise variance at expected photo-charge `signal_e`, e⁻².
    pub fn camera_e2(&self, signal_e: f64) -> f64 {
        signal_e.max(0.0) + self.floor_e2 + self.quant_e2
    }
}

/// Per-pixel running sums of the photo-charge over seeds.
#[derive(Clone, Debug, Default)]
pub struct SeedSums {
    pub n: u32,
    sum: Vec<f64>,
    sum_sq: Vec<f64>,
    /// Each frame's light-weighted centroid (x, y), pixels; None for a dark frame.
    pub centroids: Vec<Option<[f64; 2]>>,
    width: usize,
}

impl SeedSums {
    /// Add one frame's photo-charge image, `width` pixels wide.
    pub fn add(&mut self, e: &[f64], width: usize) {
        self.width = width;
        self.centroids.push(centroid(e, width));
        if self.sum.is_empty() {
            self.sum = vec![0.0; e.len()];
            self.sum_sq = vec![0.0; e.len()];
        }
        for ((s, q), &x) in self.sum.iter_mut().zip(&mut self.sum_sq).zip(e) {
            *s += x;
            *q += x * x;
        }
        self.n += 1;
    }

    /// Mean of pixel `i`.
    pub fn mean(&self, i: usize) -> f64 {
        self.sum[i] / f64::from(self.n.max(1))
    }

    /// Unbiased variance of one frame's pixel `i` (0 with fewer than two frames).
    pub fn variance(&self, i: usize) -> f64 {
        if self.n < 2 {
            return 0.0;
        }
        let n = f64::from(self.n);
        let m = self.sum[i] / n;
        ((self.sum_sq[i] - n * m * m) / (n - 1.0)).max(0.0)
    }

    pub fn len(&self) -> usize {
        self.sum.len()
    }

    pub fn is_empty(&self) -> bool {
        self.sum.is_empty()
    }
}

/// The light-weighted centroid of an image `width` pixels wide (pixel centres at + 0.5).
pub fn centroid(e: &[f64], width: usize) -> Option<[f64; 2]> {
    let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
    for (i, &v) in e.iter().enumerate() {
        sx += v * ((i % width) as f64 + 0.5);
        sy += v * ((i / width) as f64 + 0.5);
        s += v;
    }
    (s > 0.0).then(|| [sx / s, sy / s])
}

/// A converged reference in photo-charge: each pixel's mean and the variance of that mean.
#[derive(Clone, Debug)]
pub struct Reference {
    pub width: u32,
    pub height: u32,
    pub mean_e: Vec<f64>,
    pub mean_var_e2: Vec<f64>,
    /// Samples per pixel in all.
    pub spp: u64,
}

impl Reference {
    /// The reference from the photo-charge sums of `chunks` independent renders.
    pub fn from_chunks(width: u32, height: u32, sums: &SeedSums, spp: u64) -> Reference {
        let n = f64::from(sums.n.max(1));
        let mean_e = (0..sums.len()).map(|i| sums.mean(i)).collect();
        let mean_var_e2 = (0..sums.len()).map(|i| sums.variance(i) / n).collect();
        Reference { width, height, mean_e, mean_var_e2, spp }
    }
}

/// What the judge found for one row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Judgement {
    /// Reference pixels with ≥ 1 e⁻.
    pub lit: u64,
    /// Lit pixels whose seed-to-seed σ exceeds k·σ_cam.
    pub above_noise: u64,
    /// Lit pixels whose RMS error (noise and bias) exceeds k·σ_cam.
    pub above_error: u64,
    /// √mean(σ²_seed/σ²_cam) and √mean(MSE/σ²_cam) over lit pixels.
    pub rms_noise_ratio: f64,
    pub rms_error_ratio: f64,
    /// Σ mean / Σ reference − 1 over lit pixels.
    pub mean_bias: f64,
    /// The frames' mean light-weighted centroid minus the reference's, pixels (x, y),
    /// and the standard error of that mean (its seed-to-seed spread / √N).
    pub centroid_shift_px: [f64; 2],
    pub centroid_se_px: f64,
}

impl Judgement {
    pub fn noise_share(&self) -> f64 {
        self.above_noise as f64 / self.lit.max(1) as f64
    }

    pub fn error_share(&self) -> f64 {
        self.above_error as f64 / self.lit.max(1) as f64
    }

    /// Length of the centroid shift, pixels.
    pub fn centroid_shift(&self) -> f64 {
        self.centroid_shift_px[0].hypot(self.centroid_shift_px[1])
    }
}

/// A map of each lit pixel's RMS error as a fraction of `k`·σ_cam: 8-bit, 128 at the
/// bound, 255 at twice it or more, 0 where unlit (to see where a row's error is).
pub fn error_map(sums: &SeedSums, reference: &Reference, conv: &Conversion, k: f64) -> Vec<u8> {
    let n = f64::from(sums.n.max(1));
    (0..reference.mean_e.len())
        .map(|i| {
            let r = reference.mean_e[i];
            if r < 1.0 {
                return 0;
            }
            let var = sums.variance(i);
            let d = sums.mean(i) - r;
            let mse = var + (d * d - var / n - reference.mean_var_e2[i]).max(0.0);
            let ratio = (mse / (k * k * conv.camera_e2(r))).sqrt();
            (ratio * 128.0).round().clamp(1.0, 255.0) as u8
        })
        .collect()
}

/// Judge `sums` (a row's frames, photo-charge) against `reference` at bound `k`.
pub fn judge(sums: &SeedSums, reference: &Reference, conv: &Conversion, k: f64) -> Judgement {
    let w = reference.width as usize;
    let n = f64::from(sums.n.max(1));
    let mut j = Judgement::default();
    let (mut r_noise, mut r_err, mut sum_m, mut sum_r) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..reference.mean_e.len() {
        let (m, r) = (sums.mean(i), reference.mean_e[i]);
        if r < 1.0 {
            continue;
        }
        let var = sums.variance(i);
        let d = m - r;
        let bias2 = (d * d - var / n - reference.mean_var_e2[i]).max(0.0);
        let mse = var + bias2;
        let cam = conv.camera_e2(r);
        j.lit += 1;
        j.above_noise += u64::from(var > k * k * cam);
        j.above_error += u64::from(mse > k * k * cam);
        r_noise += var / cam;
        r_err += mse / cam;
        sum_m += m;
        sum_r += r;
    }
    if j.lit > 0 {
        j.rms_noise_ratio = (r_noise / j.lit as f64).sqrt();
        j.rms_error_ratio = (r_err / j.lit as f64).sqrt();
        j.mean_bias = sum_m / sum_r - 1.0;
    }
    let frames: Vec<[f64; 2]> = sums.centroids.iter().flatten().copied().collect();
    if let (Some(c), false) = (centroid(&reference.mean_e, w), frames.is_empty()) {
        let k = frames.len() as f64;
        let mean = [frames.iter().map(|f| f[0]).sum::<f64>() / k, frames.iter().map(|f| f[1]).sum::<f64>() / k];
        j.centroid_shift_px = [mean[0] - c[0], mean[1] - c[1]];
        if frames.len() > 1 {
            let var =
                frames.iter().map(|f| (f[0] - mean[0]).powi(2) + (f[1] - mean[1]).powi(2)).sum::<f64>() / (k - 1.0);
            j.centroid_se_px = (var / k).sqrt();
        }
    }
    j
}

/// The photo-charge image of a radiance image through `pipeline`'s optics, clipped at the
/// full well.
///
/// # Errors
/// The sensor's (a size mismatch).
pub fn photo_charge(pipeline: &FramePipeline, img: &RadianceImage, conv: &Conversion) -> Result<Vec<f64>, SensorError> {
    let rad = pipeline.sensor().optics(img)?;
    Ok(rad.data.iter().map(|v| (f64::from(*v) * conv.e_per_radiance).min(conv.full_well_e)).collect())
}

/// A row of the table: how its frames are rendered.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub label: String,
    pub settings: RenderSettings,
}

/// Frames timed per row after its seeds' frames.
const WARM_FRAMES: u64 = 3;

/// One row's frames measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowResult {
    pub judgement: Judgement,
    /// Median render and sensor time per frame, s, of frames that follow a frame of the
    /// same seed (as every frame of a running bench does: what a frame keeps from the
    /// last, such as the hybrid method's body-frame cells, is kept).
    pub render_s: f64,
    pub sensor_s: f64,
    /// Median render time of each seed's first frame, s (the cells filled anew).
    pub first_render_s: f64,
    /// Mean camera samples per traced pixel.
    pub spp: f64,
    /// Mean share of lit pixels above k in the frames' own reports (None without one).
    pub own_share: Option<f64>,
}

/// A row's frames measured, with its error map ([`error_map`]).
pub struct Measured {
    pub result: RowResult,
    pub map: Vec<u8>,
}

impl RowResult {
    pub fn frame_s(&self) -> f64 {
        self.render_s + self.sensor_s
    }
}

/// Render `seeds` frames of `settings` at `pose` (seeds `settings.seed + 1 …`, frame index
/// `index`) through `pipeline` at integration time `t_s`, and judge them. `on_frame` is
/// given each seed's index and radiance (what is judged) as it is made.
///
/// # Errors
/// The pipeline's.
#[allow(clippy::too_many_arguments)]
pub fn measure_row(
    pipeline: &mut FramePipeline,
    pose: &Pose,
    settings: &RenderSettings,
    seeds: u32,
    index: u64,
    t_s: f64,
    reference: &Reference,
    conv: &Conversion,
    mut on_frame: impl FnMut(u32, &RadianceImage),
) -> Result<Measured, SensorError> {
    let request = FrameRequest { integration_s: Some(t_s), roi: None };
    let mut sums = SeedSums::default();
    let (mut render, mut sensor, mut spp, mut own) = (Vec::new(), Vec::new(), 0.0, Vec::new());
    for s in 0..seeds.max(2) {
        let set = RenderSettings { seed: settings.seed.wrapping_add(1 + u64::from(s)), ..*settings };
        let f = pipeline.frame_requested(pose, &set, index, &request)?;
        render.push(f.render.time.as_secs_f64());
        sensor.push(f.sensor_time.as_secs_f64());
        spp += f.render.samples as f64 / f.render.traced_pixels.max(1) as f64;
        if let Some(m) = f.mc_noise {
            own.push(share_at(&m, pipeline, t_s)?);
        }
        let e = photo_charge(pipeline, pipeline.last_render().0, conv)?;
        sums.add(&e, pipeline.camera().width as usize);
        on_frame(s, pipeline.last_render().0);
    }
    // Timed: frames after the last seed's, same seed, the next frame indices.
    let first = median(std::mem::take(&mut render));
    sensor.clear();
    let last = RenderSettings { seed: settings.seed.wrapping_add(u64::from(seeds.max(2))), ..*settings };
    for k in 1..=WARM_FRAMES {
        let f = pipeline.frame_requested(pose, &last, index + k, &request)?;
        render.push(f.render.time.as_secs_f64());
        sensor.push(f.sensor_time.as_secs_f64());
    }
    let n = f64::from(sums.n);
    let result = RowResult {
        judgement: judge(&sums, reference, conv, K),
        render_s: median(render),
        sensor_s: median(sensor),
        first_render_s: first,
        spp: spp / n,
        own_share: (!own.is_empty()).then(|| own.iter().sum::<f64>() / own.len() as f64),
    };
    Ok(Measured { result, map: error_map(&sums, reference, conv, K) })
}

/// The share of lit pixels above [`K`] in the last frame's own report (recounted at K
/// when the frame's bound was another).
fn share_at(m: &McNoiseStats, pipeline: &FramePipeline, t_s: f64) -> Result<f64, SensorError> {
    if (m.k - K).abs() < 1e-9 {
        return Ok(m.above_fraction);
    }
    let (img, var) = pipeline.last_render();
    Ok(match var {
        Some(v) => pipeline.sensor().mc_noise_stats(img, v, t_s, K)?.map_or(m.above_fraction, |s| s.above_fraction),
        None => m.above_fraction,
    })
}

/// The converged reference: `chunks` path-traced renders of `spp` samples in every pixel
/// (not adaptive, seeds far from the rows'), averaged in photo-charge.
pub fn reference(
    pipeline: &FramePipeline,
    pose: &Pose,
    base: &RenderSettings,
    spp: u32,
    chunks: u32,
    conv: &Conversion,
    mut progress: impl FnMut(u32),
) -> Result<Reference, SensorError> {
    let mut sums = SeedSums::default();
    let (w, h) = (pipeline.camera().width, pipeline.camera().height);
    for c in 0..chunks.max(2) {
        let s = RenderSettings {
            spp: Spp::whole(spp.max(1)),
            adaptive: false,
            quality: QualityGoal::FIXED,
            seed: base.seed.wrapping_add(0x5eed_0000 + u64::from(c)),
            method: Method::Path,
            ..*base
        };
        let (img, _) = pipeline.radiance(pose, &s, 0);
        sums.add(&photo_charge(pipeline, &img, conv)?, w as usize);
        progress(c);
    }
    Ok(Reference::from_chunks(w, h, &sums, u64::from(spp.max(1)) * u64::from(sums.n)))
}

/// One CSV line per row.
pub fn to_csv(rows: &[(Row, RowResult)]) -> String {
    let mut s = String::from(
        "row,mean_spp,render_ms,first_render_ms,sensor_ms,frame_ms,fps,lit,noise_share,error_share,own_share,rms_noise_ratio,\
         rms_error_ratio,mean_bias,centroid_shift_px,centroid_se_px\n",
    );
    for (row, r) in rows {
        let j = &r.judgement;
        let _ = writeln!(
            s,
            "{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{:.6},{:.6},{},{:.4},{:.4},{:.6},{:.5},{:.5}",
            row.label,
            r.spp,
            r.render_s * 1e3,
            r.first_render_s * 1e3,
            r.sensor_s * 1e3,
            r.frame_s() * 1e3,
            1.0 / r.frame_s(),
            j.lit,
            j.noise_share(),
            j.error_share(),
            r.own_share.map_or(String::new(), |v| format!("{v:.6}")),
            j.rms_noise_ratio,
            j.rms_error_ratio,
            j.mean_bias,
            j.centroid_shift(),
            j.centroid_se_px
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn conv() -> Conversion {
        Conversion { e_per_radiance: 1.0, full_well_e: f64::INFINITY, floor_e2: 100.0, quant_e2: 0.0 }
    }

    #[test]
    fn a_pixel_with_the_cameras_noise_is_above_half_of_it_and_a_quiet_one_is_not() {
        // Pixel 0: four frames alternate 1000 ± 20 e⁻ (σ = 23.1, unbiased); σ_cam =
        // √(1000 + 100) = 33.2, so 0.5 σ_cam = 16.6: above. Pixel 1: constant.
        let reference =
            Reference { width: 2, height: 1, mean_e: vec![1000.0, 1000.0], mean_var_e2: vec![0.0; 2], spp: 1 };
        let mut sums = SeedSums::default();
        for s in [1.0, -1.0, 1.0, -1.0] {
            sums.add(&[1000.0 + 20.0 * s, 1000.0], 2);
        }
        let j = judge(&sums, &reference, &conv(), K);
        assert_eq!((j.lit, j.above_noise, j.above_error), (2, 1, 1));
        assert!((sums.variance(0) - 1600.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn a_bias_that_every_seed_shares_counts_as_error_not_as_noise() {
        // Every seed 30 e⁻ above the reference: no seed-to-seed noise, but an error of
        // 30 > 0.5 · √(1000 + 100).
        let reference = Reference { width: 1, height: 1, mean_e: vec![1000.0], mean_var_e2: vec![0.0], spp: 1 };
        let mut sums = SeedSums::default();
        for _ in 0..16 {
            sums.add(&[1030.0], 1);
        }
        let j = judge(&sums, &reference, &conv(), K);
        assert_eq!((j.above_noise, j.above_error), (0, 1));
        assert!((j.mean_bias - 0.03).abs() < 1e-12);
    }

    #[test]
    fn the_references_own_noise_is_not_counted_as_bias() {
        // Mean 10 e⁻ off, but the reference's mean has σ 10 e⁻: the squared difference is
        // all reference noise, so no bias is left.
        let reference = Reference { width: 1, height: 1, mean_e: vec![1000.0], mean_var_e2: vec![100.0], spp: 1 };
        let mut sums = SeedSums::default();
        for _ in 0..16 {
            sums.add(&[1010.0], 1);
        }
        assert_eq!(judge(&sums, &reference, &conv(), K).above_error, 0);
    }

    #[test]
    fn the_centroid_shift_is_where_the_light_moved() {
        // Light moves from pixel 0 to pixel 1 in half the frames: the centroid shifts by
        // half a pixel in x.
        let reference = Reference { width: 2, height: 1, mean_e: vec![100.0, 0.0], mean_var_e2: vec![0.0; 2], spp: 1 };
        let mut sums = SeedSums::default();
        sums.add(&[100.0, 0.0], 2);
        sums.add(&[0.0, 100.0], 2);
        let j = judge(&sums, &reference, &conv(), K);
        assert!((j.centroid_shift_px[0] - 0.5).abs() < 1e-12 && j.centroid_shift_px[1].abs() < 1e-12);
    }
}
