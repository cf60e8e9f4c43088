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
    let n = 256u32;
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
        // Where an estimate exceeds λ substitution leaves v̂ − λ too much variance, but
        // that happens at a few border pixels (three or five neighbours) of the brightest
        // level only: below 0.1 % of the pixels, 3e-4 of the frame's variance at most.
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
    // (12 × 65 536 independent pixels) and the renderer's estimate (its neighbours'
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
    // relative standard error √(2/65 536) = 0.55 %: the gain (slope over five levels) and
    // the read noise (√ of the dark variance: 0.28 %) come out within ≈ 0.3 %; the issue
    // asks for 3 %.
    let fit = ptc::fit(&points[0], &points[1..]);
    eprintln!("photon transfer with substitution: {fit:?} (configured gain {GAIN}, read noise {READ})");
    assert!((fit.gain_e_per_dn / GAIN - 1.0).abs() < 0.03, "{fit:?}");
    assert!((fit.read_noise_e / READ - 1.0).abs() < 0.03, "{fit:?}");
}
