//! Photon transfer measured on rendered frames, and the sensor-quality report against the
//! truth measured over many renders (issue 27).
//!
//! "Within statistical error" means within 4 standard errors, each computed from the
//! same frames (per-pixel spreads, or the spread of per-frame values).

use super::sensor::quiet_detector;
use crate::common;
use common::scenes::*;
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::film::{Pixels, RadianceImage};
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::sampling::Sequence;
use hilcam_core::render::{FrameBuffers, RenderOptions, render_into};
use hilcam_core::scene::Scene;
use hilcam_core::sensor::config::{AdcConfig, BandConfig};
use hilcam_core::sensor::{NoiseMode, Sensor, SensorConfig, SensorOutput, ptc};

// ---------------------------------------------------------------- the plate

/// Lambert albedo, sun incidence and sky radiance of the plate scene.
const RHO: f32 = 0.5;
const INCIDENCE_DEG: f64 = 30.0;
const SKY: f32 = 1.8;
/// The detector: conversion gain (e⁻/DN), read noise (e⁻), ADC offset (DN).
const GAIN: f64 = 2.0;
const READ: f64 = 6.0;
const OFFSET: f64 = 100.0;

/// A 2 m Lambert plate at 5 m facing the camera and filling its `n` × `n` frame (2000 px
/// focal length: the plate spans 800 px), lit by the sun at 30° and a uniform sky.
fn plate(n: u32) -> (Scene, CameraModel) {
    let cam = camera(n, n, 20.0, 40.0);
    let pose = Pose { sun_dir: sun_at_incidence(INCIDENCE_DEG), ..Pose::ahead(5.0) };
    let mut s = scene(square(0.0, 0.0, 0.0, 2.0, 0), vec![lambert("paint", RHO)], cam.clone(), pose, plate_settings(0));
    s.background = SKY;
    (s, cam)
}

/// One sample per pixel, depth 2, uniform hemisphere sampling, independent numbers.
fn plate_settings(seed: u64) -> RenderSettings {
    RenderSettings {
        spp: Spp::ONE,
        depth: 2,
        sampler: SamplerKind::Uniform,
        sequence: Sequence::Independent,
        roulette: false,
        adaptive: false,
        seed,
        ..Default::default()
    }
}

/// The plate's exact radiance and the exact variance of one sample of it. The sun term
/// ρE cosθᵢ/π has no variance (a flat plate never shadows itself). The bounce direction
/// is uniform over the hemisphere, so cosθ = u is uniform on [0, 1] and the weight is
/// f cosθ / pdf = (ρ/π) u · 2π = 2ρu; every bounce ray escapes the flat plate and
/// collects the sky B: the sky term 2ρBu has mean ρB and variance (2ρB)²/12 = ρ²B²/3.
fn plate_truth() -> (f64, f64) {
    let (rho, sky) = (f64::from(RHO), f64::from(SKY));
    let sun = rho * 593.1 * INCIDENCE_DEG.to_radians().cos() / std::f64::consts::PI;
    (sun + rho * sky, rho * rho * sky * sky / 3.0)
}

/// (radiance, the renderer's Monte Carlo variance of each pixel's mean).
fn render_plate(scene: &Scene, cam: &CameraModel, seed: u64) -> (RadianceImage, Vec<f32>) {
    let mut buffers = FrameBuffers::<()>::default();
    let view = scene.view(cam, &scene.pose);
    render_into(&mut buffers, scene, &view, &RenderOptions::new(plate_settings(seed), 0).with_noise(None, true));
    let var = buffers.variance().unwrap().to_vec();
    (buffers.take_image(), var)
}

/// A DN camera: band 0.45–0.75 µm, f/4, QE 0.5, shot and read noise, a 16-bit ADC and no
/// full well (nothing clips), no PRNU, DSNU, dark current, cos⁴ or PSF.
fn plate_sensor(cam: &CameraModel, noise: NoiseMode) -> Sensor {
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    det.read_noise_e = Some(READ);
    det.noise = noise;
    let mut cfg = SensorConfig {
        band: Some(BandConfig { min_um: 0.45, max_um: 0.75 }),
        detector: Some(det),
        adc: Some(AdcConfig { bits: 16, gain_e_per_dn: GAIN, offset_dn: OFFSET }),
        ..Default::default()
    };
    cfg.optics.f_number = Some(4.0);
    Sensor::new(cam, &cfg).unwrap()
}

fn dn(p: &Pixels) -> Vec<f64> {
    match p {
        Pixels::Mono16 { data, .. } => data.iter().map(|v| f64::from(*v)).collect(),
        other => panic!("{other:?}"),
    }
}

/// Mean and standard error of the mean of independent values.
fn mean_se(x: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = x.clone().count() as f64;
    let m = x.clone().sum::<f64>() / n;
    let var = x.map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// The photon-transfer curve of pairs of independent 1-spp frames of the plate.
///
/// Exposures by integration time, from dark (t = 0) to 10 000 e⁻. The Monte Carlo
/// variance in electrons grows as t² (c²·σ²), the shot noise as t (c·L): at 10 000 e⁻ the
/// sky B = 1.8 gives v_e = λ·σ²/L² = 0.39 λ, and less below. Substitution can only take
/// away shot noise the frame has (v_e < λ); 0.39 λ keeps each pixel's estimate, which
/// scatters by about ±50 % at one sample from eight neighbours, below λ.
///
/// Each exposure renders two frames with different render and sensor seeds, so the pair
/// difference carries both frames' Monte Carlo noise. With `noise = "substitute"` the fit
/// gives the configured gain and read noise; with `"add"` the variance exceeds the
/// camera's (the first render converted twice with the same two sensor seeds: its Monte
/// Carlo noise cancels) by the Monte Carlo variance of the radiance pair, by the
/// variance the sensor reports and by the analytic one.
#[test]
fn photon_transfer_of_rendered_plate_frames() {
    let n = 512u32;
    let (scene, cam) = plate(n);
    let sub = plate_sensor(&cam, NoiseMode::Substitute);
    let add = plate_sensor(&cam, NoiseMode::Add);
    let (l_true, var_true) = plate_truth();
    let c_s = add.electrons_per_radiance_second().unwrap();
    let pixels = (n * n) as usize;
    let g2 = GAIN * GAIN;

    let mut points = vec![];
    // Pooled over the pairs: per-sample radiance variance from the pair differences,
    // and the renderer's mean variance estimate of every frame.
    let (mut pair_var, mut estimates) = (vec![], vec![]);
    let (mut excess_sum, mut mc_sum, mut reported_sum) = (0.0, 0.0, 0.0);
    for (i, lambda) in [0.0, 200.0, 600.0, 2000.0, 5000.0, 10000.0].into_iter().enumerate() {
        let c = lambda / l_true; // e⁻ per unit radiance over the exposure
        let t = c / c_s;
        let (img_a, var_a) = render_plate(&scene, &cam, 10 + 2 * i as u64);
        let (img_b, var_b) = render_plate(&scene, &cam, 11 + 2 * i as u64);
        let seed = 1000 + 2 * i as u64;
        let run = |s: &Sensor, img: &RadianceImage, var: &[f32], seed: u64| -> SensorOutput {
            s.apply_with_variance(img, Some(var), seed, t, 1.0).unwrap()
        };
        let (sa, sb) = (run(&sub, &img_a, &var_a, seed), run(&sub, &img_b, &var_b, seed + 1));
        let p = ptc::point_from_frames(l_true, &sa.pixels, &sb.pixels);
        // The mean signal is the exact radiance's charge (2N values of variance σ²).
        let se = (p.var_dn / (2 * pixels) as f64).sqrt();
        assert!((p.mean_dn - OFFSET - lambda / GAIN).abs() < 4.0 * se + 1e-9, "λ {lambda}: {p:?}");
        points.push(p);
        for (img, var) in [(&img_a, &var_a), (&img_b, &var_b)] {
            estimates.push(var.iter().map(|v| f64::from(*v)).sum::<f64>() / pixels as f64);
            assert!(img.data.iter().all(|v| v.is_finite()));
        }
        pair_var.extend(img_a.data.iter().zip(&img_b.data).map(|(a, b)| (f64::from(*a) - f64::from(*b)).powi(2) / 2.0));
        if lambda == 0.0 {
            continue;
        }
        // Noise added: frames of independent renders against the camera alone.
        let (aa, ab) = (run(&add, &img_a, &var_a, seed), run(&add, &img_b, &var_b, seed + 1));
        let camera_b = run(&add, &img_a, &var_a, seed + 1);
        let (a, b, cb) = (dn(&aa.pixels), dn(&ab.pixels), dn(&camera_b.pixels));
        // Per pixel: e = excess of (A − B)²/2 over the camera's (A − B')²/2, and the
        // Monte Carlo variance of the radiance pair in DN², m = c²(L_a − L_b)²/(2g²). The
        // pixels are independent, and e − m cancels most of the shared noise.
        let e: Vec<f64> = (0..pixels).map(|p| ((a[p] - b[p]).powi(2) - (a[p] - cb[p]).powi(2)) / 2.0).collect();
        let m: Vec<f64> = (0..pixels)
            .map(|p| c * c * (f64::from(img_a.data[p]) - f64::from(img_b.data[p])).powi(2) / (2.0 * g2))
            .collect();
        let (excess, se_excess) = mean_se(e.iter().copied());
        let (mc, _) = mean_se(m.iter().copied());
        let (diff, se_diff) = mean_se(e.iter().zip(&m).map(|(e, m)| e - m));
        let (ma, mb) = (aa.stats.mc.unwrap(), ab.stats.mc.unwrap());
        let reported = (ma.mc_variance_e2_mean + mb.mc_variance_e2_mean) / 2.0 / g2;
        let analytic = c * c * var_true / g2;
        eprintln!(
            "λ {lambda:>6}: excess {excess:.3} ± {se_excess:.3} DN², radiance pairs {mc:.3} (difference ± {se_diff:.3}), reported {reported:.3}, \
             analytic {analytic:.3} (v_e/λ {:.3}); above shot: {} + {}",
            analytic * g2 / lambda,
            ma.above_shot,
            mb.above_shot
        );
        assert!(diff.abs() < 4.0 * se_diff, "λ {lambda}: excess {excess} vs radiance pairs {mc} (± {se_diff})");
        // The report is the renderer's estimate carried through the chain (exactly: no
        // PRNU, cos⁴ or PSF here), so it agrees with the excess as the estimate does with
        // the truth (checked below); per exposure, within the excess's error.
        let want = c * c * (estimates[estimates.len() - 2] + estimates[estimates.len() - 1]) / 2.0;
        assert!((reported * g2 - want).abs() < 1e-5 * want, "λ {lambda}: reported {} vs {want}", reported * g2);
        assert!((excess - reported).abs() < 4.0 * se_excess, "λ {lambda}: excess {excess} vs reported {reported}");
        assert_eq!(ma.lit_pixels, pixels as u64);
        // Where an estimate exceeds λ substitution leaves v̂ − λ too much variance. The
        // sample variance of eight neighbours' bounded (uniform) values reaches at most
        // 3.4× the true one, so only the brightest level (v_e = 0.39 λ) has such pixels,
        // below 0.1 % of them: 3e-4 of the frame's variance at most.
        assert!(ma.above_shot + mb.above_shot < pixels as u64 / 1000, "{ma:?} {mb:?}");
        excess_sum += excess;
        mc_sum += mc;
        reported_sum += reported;
    }
    eprintln!(
        "over the exposures: excess / radiance-pair MC variance {:.4}, excess / reported {:.4}",
        excess_sum / mc_sum,
        excess_sum / reported_sum
    );

    // The renderer's Monte Carlo noise is the analytic one: the pair differences
    // (12 × 262 144 independent pixels) and the renderer's estimate (its neighbours'
    // estimates share samples, so its error comes from the spread of the 12 frames).
    let (measured, se_measured) = mean_se(pair_var.iter().copied());
    let (estimated, se_estimated) = mean_se(estimates.iter().copied());
    eprintln!(
        "per-sample variance: analytic {var_true:.5}, pair differences {measured:.5} ± {se_measured:.5}, \
         renderer's estimate {estimated:.5} ± {se_estimated:.5}"
    );
    assert!((measured - var_true).abs() < 4.0 * se_measured, "pairs {measured} vs {var_true}");
    assert!((estimated - var_true).abs() < 4.0 * se_estimated, "estimate {estimated} vs {var_true}");

    // Substitution: the photon-transfer fit is the camera's. Each pair variance has a
    // relative standard error √(2/262 144) = 0.28 %: the gain (slope over five levels) and
    // the read noise (√ of the dark variance: 0.14 %) come out within ≈ 0.2 %; the issue
    // asks for 3 %.
    let fit = ptc::fit(&points[0], &points[1..]);
    for p in &points {
        eprintln!("substituted: mean {:.2} DN, variance {:.3} DN²", p.mean_dn, p.var_dn);
    }
    eprintln!("photon transfer with substitution: {fit:?} (configured gain {GAIN}, read noise {READ})");
    assert!((fit.gain_e_per_dn / GAIN - 1.0).abs() < 0.03, "{fit:?}");
    assert!((fit.read_noise_e / READ - 1.0).abs() < 0.03, "{fit:?}");
}

// ---------------------------------------------------------------- the report's truth

/// The satellite with every material Lambertian (albedo 0.5): no glints.
fn matte_satellite() -> Scene {
    let mut scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    for m in &mut scene.target.materials {
        *m = lambert(&m.name, 0.5);
    }
    scene
}

/// ln Γ(x), x > 0 (Lanczos, g = 7, 9 terms: ≈ 1e-15 relative).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let a = C[0] + (1..9).map(|i| C[i] / (x + i as f64)).sum::<f64>();
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised upper incomplete gamma function Q(a, x) = P(χ²₂ₐ > 2x): its series
/// below x = a + 1, Lentz's continued fraction above (Numerical Recipes §6.2).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let front = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        while term.abs() > sum.abs() * 1e-15 {
            n += 1.0;
            term *= x / n;
            sum += term;
        }
        1.0 - sum * front
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let (mut c, mut d) = (1.0 / tiny, 1.0 / b);
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            d = if d.abs() < tiny { tiny } else { d };
            c = b + an / c;
            c = if c.abs() < tiny { tiny } else { c };
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        front * h
    }
}

/// P(s² > τ) for the unbiased sample variance s² of n Gaussian values of variance σ²:
/// (n − 1)s²/σ² is χ² with n − 1 degrees of freedom.
fn p_sample_variance_above(n: f64, sigma2: f64, tau: f64) -> f64 {
    if sigma2 <= 0.0 {
        return 0.0;
    }
    gamma_q((n - 1.0) / 2.0, (n - 1.0) * tau / (2.0 * sigma2))
}

#[test]
fn gamma_q_against_closed_forms() {
    // Q(1, x) = e^(−x); Q(1/2, x) = erfc(√x); χ²₁ at 3.841 and χ²₁₀ at 18.307: 5 %.
    for x in [0.01, 0.5, 1.0, 2.0, 7.0, 30.0] {
        assert!((gamma_q(1.0, x) / (-x).exp() - 1.0).abs() < 1e-12, "{x}");
    }
    assert!((gamma_q(0.5, 1.0) - 0.157_299_207_050_285_1).abs() < 1e-12);
    assert!((gamma_q(0.5, 3.841_458_820_694_124 / 2.0) - 0.05).abs() < 1e-9);
    assert!((gamma_q(5.0, 18.307_038_053_275_146 / 2.0) - 0.05).abs() < 1e-9);
    assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-13);
    assert!((ln_gamma(101.0) - 363.739_375_555_563_5).abs() < 1e-9);
}

/// What `seeds` sensor-quality frames report, and what the renders show.
#[derive(Debug)]
struct ReportTruth {
    /// Mean over the frames of their reported fraction of lit pixels above the bound.
    reported: f64,
    /// Standard error of `reported − per_frame` (spread of the per-frame differences).
    se: f64,
    /// The fraction above the bound of the pixels' variance measured across the frames
    /// (the sample variance of each pixel's radiance over the seeds), on the mean image.
    empirical: f64,
    /// Mean over the frames of the fraction whose count N in that frame gives σ²/N above
    /// the bound, σ² each pixel's per-sample variance pooled over every frame.
    per_frame: f64,
    /// What the report would be if each pixel's samples were Gaussian: the mean over the
    /// frames of P(s²/N > bound) with (N − 1)s²/σ² a χ² variate.
    gaussian: f64,
    lit: f64,
}

fn report_truth(scene: &Scene, cam: &CameraModel, budget: u32, depth: u32, seeds: u64) -> ReportTruth {
    let k = 0.5;
    let sensor = plate_sensor(cam, NoiseMode::Add);
    // The brightest pixels at ≈ 6000 e⁻, 6 e⁻ read noise.
    let t = 6000.0 / (sensor.electrons_per_radiance_second().unwrap() * 150.0);
    let bound = sensor.noise_bound(t, k).unwrap();
    let settings = RenderSettings { spp: Spp::whole(budget), depth, sequence: Sequence::Independent, ..scene.render }
        .with_quality(Some(hilcam_core::render::integrator::QualityMode::Sensor), Some(k as f32));
    let view = scene.view(cam, &scene.pose);
    let (w, n) = (cam.width as usize, (cam.width * cam.height) as usize);
    let (mut sum, mut sum_sq, mut sigma2) = (vec![0.0f64; n], vec![0.0f64; n], vec![0.0f64; n]);
    let mut frames = vec![];
    let r = seeds as f64;
    for seed in 0..seeds {
        let mut buffers = FrameBuffers::<()>::default();
        let options =
            RenderOptions::new(RenderSettings { seed: 5000 + seed, ..settings }, 0).with_noise(Some(bound), true);
        render_into(&mut buffers, scene, &view, &options);
        let var = buffers.variance().unwrap().to_vec();
        let count = buffers.sample_counts();
        let img = buffers.take_image();
        let mc = sensor.apply_with_variance(&img, Some(&var), seed, t, k).unwrap().stats.mc.unwrap();
        for p in 0..n {
            let x = f64::from(img.data[p]);
            sum[p] += x;
            sum_sq[p] += x * x;
            sigma2[p] += f64::from(var[p]) * f64::from(count[p]) / r;
        }
        frames.push((img, count, mc.above_bound as f64 / mc.lit_pixels as f64));
    }
    // Per frame: the truth (σ²/N through the report's own code, on the frame's radiance)
    // and the Gaussian model's expectation of the report.
    let (mut diffs, mut reported, mut per_frame, mut gaussian) = (vec![], 0.0, 0.0, 0.0);
    for (img, count, frac) in &frames {
        let v: Vec<f32> =
            (0..n).map(|p| if count[p] > 0 { (sigma2[p] / f64::from(count[p])) as f32 } else { 0.0 }).collect();
        let mc = sensor.apply_with_variance(img, Some(&v), 0, t, k).unwrap().stats.mc.unwrap();
        let truth = mc.above_bound as f64 / mc.lit_pixels as f64;
        let (mut expect, mut lit) = (0.0, 0u64);
        for p in 0..n {
            let (row, col) = ((p / w) as u32, (p % w) as u32);
            let l = f64::from(img.data[p]);
            if bound.e_per_radiance_at(row, col) * l >= 1.0 {
                lit += 1;
                let allowed = bound.allowed_radiance_variance(l, row, col);
                let n = f64::from(count[p]);
                expect += p_sample_variance_above(n, sigma2[p], allowed * n);
            }
        }
        assert_eq!(lit, mc.lit_pixels);
        diffs.push(frac - truth);
        reported += frac / r;
        per_frame += truth / r;
        gaussian += expect / lit as f64 / r;
    }
    let (_, se) = mean_se(diffs.iter().copied());
    let mean =
        RadianceImage { width: cam.width, height: cam.height, data: sum.iter().map(|s| (s / r) as f32).collect() };
    let emp: Vec<f32> = (0..n).map(|p| ((sum_sq[p] - sum[p] * sum[p] / r) / (r - 1.0)).max(0.0) as f32).collect();
    let mc = sensor.apply_with_variance(&mean, Some(&emp), 0, t, k).unwrap().stats.mc.unwrap();
    let empirical = mc.above_bound as f64 / mc.lit_pixels as f64;
    ReportTruth { reported, se, empirical, per_frame, gaussian, lit: mc.lit_pixels as f64 }
}

/// `quality = "sensor"` (k = 0.5, budget 64) on the matte satellite at depth 1, 100 seeds
/// at 128 × 96: the fraction of lit pixels above the bound that the frames report is the
/// fraction their true variance puts there.
///
/// Depth 1's only noise is where a pixel's samples differ (the target's edges, shadow
/// boundaries), two-valued and bounded. The report thresholds each pixel's s²/N, an
/// unbiased but skewed estimate at few samples, so its count is biased low: for Gaussian
/// samples the χ² distribution of s² predicts 0.001 of it here, the two-valued samples
/// make it 0.007 (measured: reported 0.367, per-frame truth 0.374, Gaussian model 0.373;
/// the frame-to-frame standard error of the difference is 0.0003). The test holds the
/// report to within 0.02 (about 5 % of the fraction) of the truth and never above it by
/// more than 4 standard errors: the trust docs/sensor.md states for this regime.
#[test]
fn the_sensor_quality_report_counts_the_pixels_truly_above_the_bound() {
    let scene = matte_satellite();
    let cam = scaled_camera(&scene, 128, 96, [0.0, 0.0]);
    let r = report_truth(&scene, &cam, 64, 1, 100);
    eprintln!("matte satellite, depth 1, budget 64: {r:?}");
    assert!(r.lit > 2000.0, "{r:?}");
    assert!(r.reported <= r.per_frame + 4.0 * r.se, "{r:?}");
    assert!(r.per_frame - r.reported < 0.02, "{r:?}");
    // Against each pixel's variance measured across the 100 frames (the renders' own
    // truth, with the 14 % scatter of a 100-frame variance: thresholded, it reads higher).
    assert!(r.reported <= r.empirical && r.empirical - r.reported < 0.03, "{r:?}");
}

/// Where the report cannot be trusted: indirect light (depth 2) on the matte satellite and
/// the glossy satellite's glints, where a pixel's rare bright samples make s²/N at a
/// sample count near the bound read low in most frames. Measured (50 seeds each, budget
/// 64), asserted only in sign and loosely.
#[test]
fn the_sensor_quality_report_under_counts_rare_bright_samples() {
    let matte = matte_satellite();
    let glossy = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    let cam = scaled_camera(&matte, 128, 96, [0.0, 0.0]);
    for (what, scene) in [("matte", &matte), ("glossy", &glossy)] {
        let r = report_truth(scene, &cam, 64, 2, 50);
        eprintln!("{what} satellite, depth 2, budget 64: {r:?}");
        assert!(r.reported < r.per_frame && r.reported > 0.6 * r.per_frame, "{what}: {r:?}");
        // The Gaussian model explains part of it, the samples' skew the rest.
        assert!(r.reported < r.gaussian && r.gaussian < r.per_frame, "{what}: {r:?}");
    }
}
