//! Sensor model tests (issue 6): each against an independent or analytic answer.

use glam::DVec2;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::camera::distortion::Distortion;
use hilcam_core::render::film::{Pixels, RadianceImage};
use hilcam_core::sensor::config::{AdcConfig, AutoExposureConfig, BandConfig, DetectorConfig, PsfConfig, QeConfig};
use hilcam_core::sensor::{CameraPreset, OutputKind, Sensor, SensorConfig, SensorError, psf, ptc};
use std::path::Path;

const H: f64 = 6.626_070_15e-34;
const C: f64 = 299_792_458.0;

fn cam(w: u32, h: u32) -> CameraModel {
    CameraModel { width: w, height: h, pitch_um: 5.5, focal_mm: 16.0, principal_point_px: [0.0, 0.0] }
}

/// A detector config with every noise source off (QE 0.5).
pub(crate) fn quiet_detector(t: f64) -> DetectorConfig {
    DetectorConfig {
        qe: QeConfig::Constant(0.5),
        integration_time_s: t,
        full_well_e: None,
        dark_current_e_per_s: None,
        shot_noise: false,
        noise: Default::default(),
        read_noise_e: None,
        prnu: None,
        dsnu_e_per_s: None,
        fpn_seed: 0,
        effective_wavelength_um: None,
        exposure: Default::default(),
        line_time_us: None,
    }
}

pub(crate) fn dn_config(det: DetectorConfig, adc: AdcConfig) -> SensorConfig {
    let mut c = SensorConfig {
        band: Some(BandConfig { min_um: 0.45, max_um: 0.75 }),
        detector: Some(det),
        adc: Some(adc),
        ..Default::default()
    };
    c.optics.f_number = Some(4.0);
    c.optics.transmittance = Some(0.9);
    c
}

pub(crate) fn adc(bits: u8, gain: f64, offset: f64) -> AdcConfig {
    AdcConfig { bits, gain_e_per_dn: gain, offset_dn: offset }
}

fn dn_values(px: &Pixels) -> Vec<f64> {
    match px {
        Pixels::Mono8(d) => d.iter().map(|v| *v as f64).collect(),
        Pixels::Mono16 { data, .. } => data.iter().map(|v| *v as f64).collect(),
        Pixels::Float32(d) => d.iter().map(|v| *v as f64).collect(),
    }
}

/// Electrons from the radiometric chain written out independently of the crate:
/// E = τ π L / (4 N²); photons = E · p² · t · λ / (h c); electrons = QE · photons.
fn predicted_electrons(l: f64, tau: f64, n: f64, pitch_um: f64, t: f64, qe_lambda_m: f64) -> f64 {
    let e = tau * std::f64::consts::PI * l / (4.0 * n * n);
    e * (pitch_um * 1e-6).powi(2) * t * qe_lambda_m / (H * C)
}

// ---------------------------------------------------------------- all effects off

#[test]
fn all_effects_off_output_equals_scaled_radiance_exactly() {
    let c = cam(37, 23);
    let mut img = RadianceImage::new(37, 23, 0.0);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = ((i * 7919) % 1000) as f32 * 0.173 + 1e-3;
    }
    let s = Sensor::new(&c, &SensorConfig::default()).unwrap();
    let a = s.apply(&img, 1).unwrap();
    let b = s.apply(&img, 2).unwrap();
    assert_eq!(a.pixels, Pixels::Float32(img.data.clone()));
    assert_eq!(a, b, "no effect may depend on the seed");
    assert_eq!(a.integration_time_s, None);

    let cfg = SensorConfig { radiance_scale: Some(2.5), ..Default::default() };
    let out = Sensor::new(&c, &cfg).unwrap().apply(&img, 0).unwrap();
    let want: Vec<f32> = img.data.iter().map(|v| (*v as f64 * 2.5) as f32).collect();
    assert_eq!(out.pixels, Pixels::Float32(want));

    // DN output without a detector: round(L × scale / gain) + offset, as integers.
    let cfg = SensorConfig { radiance_scale: Some(10.0), adc: Some(adc(16, 1.0, 0.0)), ..Default::default() };
    let out = Sensor::new(&c, &cfg).unwrap().apply(&img, 0).unwrap();
    let want: Vec<u16> = img.data.iter().map(|v| (*v as f64 * 10.0).round() as u16).collect();
    assert_eq!(out.pixels, Pixels::Mono16 { data: want, bits: 16 });
}

// ---------------------------------------------------------------- radiometry

#[test]
fn uniform_radiance_gives_the_predicted_electron_count() {
    let c = cam(256, 256);
    let t = 2e-3;
    let l = 10.0; // ≈ 40 000 e⁻: inside the 16-bit range at 1 e⁻/DN
    let mut det = quiet_detector(t);
    det.shot_noise = true;
    det.read_noise_e = Some(5.0);
    let cfg = dn_config(det, adc(16, 1.0, 100.0));
    let s = Sensor::new(&c, &cfg).unwrap();
    let out = s.apply(&RadianceImage::new(256, 256, l as f32), 3).unwrap();
    // Constant QE 0.5 and a flat spectrum: the band's mid wavelength 0.6 µm.
    let want = predicted_electrons(l, 0.9, 4.0, 5.5, t, 0.5 * 0.6e-6);
    let st = &out.stats;
    assert!((st.mean_expected_e / want - 1.0).abs() < 1e-6, "{} vs {want}", st.mean_expected_e);
    assert!((st.mean_collected_e / want - 1.0).abs() < 0.005, "{}", st.mean_collected_e);
    let mean_dn = dn_values(&out.pixels).iter().sum::<f64>() / 65536.0;
    assert!(((mean_dn - 100.0) / want - 1.0).abs() < 0.005, "mean DN {mean_dn} for {want} e⁻");
    assert_eq!(out.integration_time_s, Some(t));
}

#[test]
fn qe_curve_band_average_matches_the_closed_form() {
    // QE(λ) = 0.2 + 0.5 λ (λ in µm) over 0.45–0.75 µm: ⟨QE·λ⟩ = (1/Δλ)∫(0.2λ + 0.5λ²)dλ.
    let (a, b, l0, l1) = (0.2f64, 0.5f64, 0.45f64, 0.75f64);
    let mean_ql = (a / 2.0 * (l1 * l1 - l0 * l0) + b / 3.0 * (l1.powi(3) - l0.powi(3))) / (l1 - l0);
    let mut det = quiet_detector(1e-3);
    det.qe = QeConfig::Curve(vec![[0.4, a + b * 0.4], [0.8, a + b * 0.8]]);
    let cfg = dn_config(det, adc(16, 1.0, 0.0));
    let s = Sensor::new(&cam(8, 8), &cfg).unwrap();
    let out = s.apply(&RadianceImage::new(8, 8, 20.0), 0).unwrap();
    let want = predicted_electrons(20.0, 0.9, 4.0, 5.5, 1e-3, mean_ql * 1e-6);
    assert!((out.stats.mean_expected_e / want - 1.0).abs() < 1e-6);
}

#[test]
fn aperture_diameter_and_f_number_agree() {
    let mut a = dn_config(quiet_detector(1e-3), adc(16, 1.0, 0.0));
    let mut b = a.clone();
    a.optics.f_number = Some(16.0 / 4.0);
    b.optics.f_number = None;
    b.optics.aperture_mm = Some(4.0);
    let img = RadianceImage::new(4, 4, 10.0);
    let ea = Sensor::new(&cam(4, 4), &a).unwrap().apply(&img, 0).unwrap();
    let eb = Sensor::new(&cam(4, 4), &b).unwrap().apply(&img, 0).unwrap();
    assert_eq!(ea.stats.mean_expected_e, eb.stats.mean_expected_e);
}

#[test]
fn dark_current_accumulates_over_the_integration_time() {
    let mut det = quiet_detector(0.5);
    det.dark_current_e_per_s = Some(2000.0);
    let cfg = dn_config(det, adc(16, 1.0, 0.0));
    let out = Sensor::new(&cam(16, 16), &cfg).unwrap().apply(&RadianceImage::new(16, 16, 0.0), 0).unwrap();
    assert_eq!(dn_values(&out.pixels), vec![1000.0; 256]);
}

#[test]
fn cos4_and_transmittance_scale_the_radiance() {
    let mut c = cam(64, 48);
    c.focal_mm = 0.1; // short focal length: large field angles
    c.principal_point_px = [3.0, -2.0];
    let mut cfg = SensorConfig::default();
    cfg.optics.cos4 = true;
    cfg.optics.transmittance = Some(0.5);
    let out = Sensor::new(&c, &cfg).unwrap().apply(&RadianceImage::new(64, 48, 2.0), 0).unwrap();
    let Pixels::Float32(d) = out.pixels else { panic!("float output") };
    let f = c.focal_mm * 1e-3 / (c.pitch_um * 1e-6);
    for (col, row) in [(0u32, 0u32), (63, 47), (35, 22), (10, 40)] {
        let x = (col as f64 + 0.5 - 32.0 - 3.0) * 1.0;
        let y = (row as f64 + 0.5 - 24.0 + 2.0) * 1.0;
        let theta = (x.hypot(y) / f).atan();
        let want = 2.0 * 0.5 * theta.cos().powi(4);
        let got = d[(row * 64 + col) as usize] as f64;
        assert!((got - want).abs() < 1e-6, "({col},{row}) {got} vs {want}");
    }
}

// ---------------------------------------------------------------- photon transfer

#[test]
fn photon_transfer_recovers_configured_gain_and_read_noise() {
    let (gain, read) = (2.0, 6.0);
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    det.read_noise_e = Some(read);
    det.prnu = Some(0.02); // fixed pattern: cancelled by the frame difference
    det.fpn_seed = 5;
    let cfg = dn_config(det, adc(16, gain, 100.0));
    let s = Sensor::new(&cam(256, 256), &cfg).unwrap();
    let k = s.electrons_per_radiance_second().unwrap() * 1e-3 * 0.9;
    let dark = ptc::measure(&s, 0.0, 10).unwrap();
    let pts: Vec<ptc::PtcPoint> = [500.0, 2000.0, 5000.0, 10000.0, 20000.0, 40000.0]
        .iter()
        .enumerate()
        .map(|(i, e)| ptc::measure(&s, e / k, 20 + 2 * i as u64).unwrap())
        .collect();
    let fit = ptc::fit(&dark, &pts);
    assert!((fit.gain_e_per_dn / gain - 1.0).abs() < 0.03, "gain {}", fit.gain_e_per_dn);
    assert!((fit.read_noise_e / read - 1.0).abs() < 0.03, "read noise {}", fit.read_noise_e);
    // And the variance is linear in the mean: each level's own slope agrees.
    for p in &pts {
        let slope = (p.var_dn - dark.var_dn) / (p.mean_dn - dark.mean_dn);
        assert!((slope * gain - 1.0).abs() < 0.05, "{p:?}");
    }
}

#[test]
fn fixed_pattern_is_the_same_every_frame_and_has_the_configured_spread() {
    let mut det = quiet_detector(1e-3);
    det.prnu = Some(0.03);
    det.fpn_seed = 77;
    let cfg = dn_config(det, adc(16, 0.25, 0.0));
    let s = Sensor::new(&cam(128, 128), &cfg).unwrap();
    let k = s.electrons_per_radiance_second().unwrap() * 1e-3 * 0.9;
    let img = RadianceImage::new(128, 128, (10_000.0 / k) as f32);
    let a = s.apply(&img, 1).unwrap();
    let b = s.apply(&img, 2).unwrap();
    assert_eq!(a.pixels, b.pixels, "no temporal noise configured");
    let v = dn_values(&a.pixels);
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
    assert!((sd / m / 0.03 - 1.0).abs() < 0.03, "PRNU {}", sd / m);
    // Another sensor serial number (seed) has another pattern.
    let mut cfg2 = cfg.clone();
    cfg2.detector.as_mut().unwrap().fpn_seed = 78;
    let c = Sensor::new(&cam(128, 128), &cfg2).unwrap().apply(&img, 1).unwrap();
    assert_ne!(a.pixels, c.pixels);
}

// ---------------------------------------------------------------- saturation, clipping, offset

#[test]
fn saturation_at_full_well_clipping_at_adc_max_and_offset() {
    let c = cam(32, 32);
    let bright = RadianceImage::new(32, 32, 1e6);
    // Full well below the ADC range: every pixel reads offset + FW / gain.
    let mut det = quiet_detector(1e-3);
    det.full_well_e = Some(10_000.0);
    det.shot_noise = true;
    let cfg = dn_config(det.clone(), adc(12, 4.0, 50.0));
    let out = Sensor::new(&c, &cfg).unwrap().apply(&bright, 0).unwrap();
    assert_eq!(dn_values(&out.pixels), vec![50.0 + 2500.0; 1024]);
    assert_eq!(out.stats.full_well_pixels, 1024);
    assert_eq!(out.stats.adc_high_clipped, 0);
    assert_eq!(out.stats.mean_collected_e, 10_000.0);

    // ADC range below the full well: clipped at 2^bits − 1, counted.
    let cfg = dn_config(det.clone(), adc(10, 4.0, 50.0));
    let out = Sensor::new(&c, &cfg).unwrap().apply(&bright, 0).unwrap();
    assert_eq!(out.pixels, Pixels::Mono16 { data: vec![1023; 1024], bits: 10 });
    assert_eq!(out.stats.adc_high_clipped, 1024);
    let cfg = dn_config(det.clone(), adc(8, 4.0, 50.0));
    let out = Sensor::new(&c, &cfg).unwrap().apply(&bright, 0).unwrap();
    assert_eq!(out.pixels, Pixels::Mono8(vec![255; 1024]));

    // Dark frame, no read noise: exactly the offset.
    let dark = RadianceImage::new(32, 32, 0.0);
    let cfg = dn_config(det.clone(), adc(12, 4.0, 50.0));
    let out = Sensor::new(&c, &cfg).unwrap().apply(&dark, 0).unwrap();
    assert_eq!(dn_values(&out.pixels), vec![50.0; 1024]);

    // With read noise the mean stays at the offset; with offset 0, negative excursions
    // clip at DN 0 and are counted.
    det.read_noise_e = Some(8.0);
    let c = cam(128, 128);
    let dark = RadianceImage::new(128, 128, 0.0);
    let cfg = dn_config(det.clone(), adc(12, 1.0, 50.0));
    let out = Sensor::new(&c, &cfg).unwrap().apply(&dark, 0).unwrap();
    assert!((out.stats.mean_dn - 50.0).abs() < 0.2, "{}", out.stats.mean_dn);
    assert_eq!(out.stats.adc_low_clipped, 0);
    let cfg = dn_config(det, adc(12, 1.0, 0.0));
    let out = Sensor::new(&c, &cfg).unwrap().apply(&dark, 0).unwrap();
    // Half the pixels fall below zero before rounding (P(z < −1/16) ≈ 0.475).
    let frac = out.stats.adc_low_clipped as f64 / 16384.0;
    assert!((frac - 0.475).abs() < 0.02, "{frac}");
}

// ---------------------------------------------------------------- determinism

#[test]
fn noise_is_deterministic_per_seed_and_independent_of_thread_count() {
    let text = std::fs::read_to_string(preset("nav1024.toml")).unwrap();
    let mut p: CameraPreset = toml::from_str(&text).unwrap();
    p.camera.width = 96;
    p.camera.height = 64;
    p.camera.focal_mm = 16.0 * 96.0 / 1024.0; // keep the field of view
    let s = Sensor::new(&p.camera, &p.sensor).unwrap();
    let mut img = RadianceImage::new(96, 64, 0.0);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = (i % 97) as f32 * 0.8;
    }
    let run = |threads: usize, seed: u64| {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| s.apply(&img, seed).unwrap())
    };
    let a = run(1, 42);
    assert_eq!(a, run(3, 42));
    assert_eq!(a, run(8, 42));
    assert_ne!(a.pixels, run(2, 43).pixels);
}

// ---------------------------------------------------------------- PSF

fn total(v: &[f32]) -> f64 {
    v.iter().map(|x| *x as f64).sum()
}

#[test]
fn psf_conserves_total_signal_including_at_the_borders() {
    let (w, h) = (61, 45);
    let mut img = vec![0f32; w * h];
    for (i, v) in img.iter_mut().enumerate() {
        *v = ((i * 2654435761) % 1000) as f32; // signal right up to the edges
    }
    let (gh, gv) = psf::Kernel::gaussian(1.7);
    let g = psf::convolve(&psf::convolve(&img, w, h, &gh), w, h, &gv);
    assert!((total(&g) / total(&img) - 1.0).abs() < 1e-6);
    let a = psf::Kernel::airy(4.0, 5.5, &[0.45, 0.6, 0.75], None);
    let out = psf::convolve(&img, w, h, &a);
    assert!((total(&out) / total(&img) - 1.0).abs() < 1e-6);
    // Through the sensor, with cos⁴ off: same.
    let mut cfg = SensorConfig::default();
    cfg.optics.psf = Some(PsfConfig::Gaussian { sigma_px: 2.5 });
    let s = Sensor::new(&cam(w as u32, h as u32), &cfg).unwrap();
    let r = RadianceImage { width: w as u32, height: h as u32, data: img.clone() };
    let o = s.optics(&r).unwrap();
    assert!((total(&o.data) / total(&img) - 1.0).abs() < 1e-6);
    assert_ne!(o.data, img);
}

#[test]
fn gaussian_psf_spreads_a_point_by_sigma_squared_plus_a_pixel() {
    // A pixel-integrated Gaussian's second moment is σ² + 1/12 (box of one pixel).
    let (w, h) = (41, 41);
    let mut img = vec![0f32; w * h];
    img[20 * w + 20] = 1.0;
    let sigma = 1.3;
    let (gh, gv) = psf::Kernel::gaussian(sigma);
    let out = psf::convolve(&psf::convolve(&img, w, h, &gh), w, h, &gv);
    let mut m2 = 0.0;
    for (i, v) in out.iter().enumerate() {
        let dx = (i % w) as f64 - 20.0;
        m2 += *v as f64 * dx * dx;
    }
    assert!((m2 - (sigma * sigma + 1.0 / 12.0)).abs() < 2e-4, "{m2}");
}

#[test]
fn airy_psf_has_its_first_dark_ring_at_1_22_lambda_n() {
    // λ = 1 µm, N = 20, 1 µm pixels: the first zero at 24.4 px, the second maximum
    // near 32.7 px (v = 5.1356) in a kernel much finer than the pattern.
    let k = psf::Kernel::airy(20.0, 1.0, &[1.0], Some(40));
    let side = 81;
    let row: Vec<f32> = (0..side).map(|x| k.weights[40 * side + x]).collect();
    let ring = &row[40 + 20..40 + 30];
    let argmin = ring.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).unwrap().0 + 20;
    assert_eq!(argmin, 24);
    let second = &row[40 + 28..40 + 38];
    let argmax = second.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0 + 28;
    assert!((32..=33).contains(&argmax), "{argmax}");
    // Symmetric.
    for d in 1..40 {
        assert_eq!(row[40 + d], row[40 - d]);
    }
}

// ---------------------------------------------------------------- distortion

fn corner_samples(cam: &CameraModel) -> Vec<DVec2> {
    // Pixel corners and centres along the border and diagonal, incl. the image corners.
    let (w, h) = (cam.width as f64, cam.height as f64);
    let mut v = vec![DVec2::new(0.0, 0.0), DVec2::new(w, 0.0), DVec2::new(0.0, h), DVec2::new(w, h)];
    for i in 0..=64 {
        let t = i as f64 / 64.0;
        v.push(DVec2::new(t * w, 0.0));
        v.push(DVec2::new(w, t * h));
        v.push(DVec2::new(t * w, t * h));
        v.push(DVec2::new(t * w + 0.5, (1.0 - t) * h - 0.5));
    }
    v
}

pub(crate) fn preset(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("config/cameras").join(name)
}

#[test]
fn undistort_inverts_distort_to_a_micro_pixel_at_the_corners() {
    let strong = Distortion { k1: -0.25, k2: 0.08, k3: -0.01, p1: 1e-3, p2: -5e-4 };
    let mut cases = vec![];
    for name in ["nav1024.toml", "nav2048.toml"] {
        let p = CameraPreset::load(&preset(name)).unwrap();
        let d = p.sensor.optics.distortion.unwrap();
        assert!(!d.is_identity());
        cases.push((p.camera.clone(), d));
        cases.push((p.camera, strong));
    }
    for (c, d) in cases {
        let f = c.focal_px();
        let pp =
            DVec2::new(c.width as f64 / 2.0 + c.principal_point_px[0], c.height as f64 / 2.0 + c.principal_point_px[1]);
        for p in corner_samples(&c) {
            // Ideal → distorted → ideal, and distorted → ideal → distorted.
            let back = d.undistort_px(d.distort_px(p, pp, f), pp, f);
            assert!((back - p).length() < 1e-6, "{d:?} at {p}: {back}");
            let fwd = d.distort_px(d.undistort_px(p, pp, f), pp, f);
            assert!((fwd - p).length() < 1e-6, "{d:?} at {p}: {fwd}");
        }
    }
}

#[test]
fn undistort_agrees_with_an_independent_radial_bisection() {
    // Radial-only model: r_d = r (1 + k1 r² + k2 r⁴ + k3 r⁶) along a fixed azimuth,
    // solved by bisection on r (monotonic on the field).
    let d = Distortion { k1: -0.2, k2: 0.05, k3: 0.01, ..Default::default() };
    let g = |r: f64| r * (1.0 + d.k1 * r * r + d.k2 * r.powi(4) + d.k3 * r.powi(6));
    for &(rd, az) in &[(0.05, 0.3), (0.2, 1.0), (0.35, 2.5), (0.5, -0.7)] {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if g(mid) < rd { lo = mid } else { hi = mid }
        }
        let dir = DVec2::new(f64::cos(az), f64::sin(az));
        let got = d.undistort(dir * rd);
        assert!((got - dir * lo).length() < 1e-12, "{got} vs {}", dir * lo);
    }
}

#[test]
fn a_straight_line_bends_the_right_way() {
    // A horizontal line y = 0.3 (normalised): barrel (k1 < 0) pulls the ends, which
    // are farther from the centre, inward more than the middle, so the line bows away
    // from the centre; pincushion (k1 > 0) makes it bow toward the centre.
    let line: Vec<DVec2> = (-10..=10).map(|i| DVec2::new(i as f64 * 0.04, 0.3)).collect();
    for (k1, ends_higher) in [(-0.2, false), (0.2, true)] {
        let d = Distortion { k1, ..Default::default() };
        let y: Vec<f64> = line.iter().map(|p| d.distort(*p).y).collect();
        let (mid, end) = (y[10], y[0]);
        assert_eq!(y[0], y[20], "symmetric");
        assert_eq!(end > mid, ends_higher, "k1 = {k1}: end {end}, middle {mid}");
        // The middle point lies on the axis: it moves only radially.
        assert!((mid - 0.3 * (1.0 + k1 * 0.09)).abs() < 1e-15);
        // Every point moves along its own radius (no tangential terms).
        for (p, q) in line.iter().zip(line.iter().map(|p| d.distort(*p))) {
            assert!(p.perp_dot(q).abs() < 1e-15);
        }
    }
}

#[test]
fn distortion_that_folds_over_inside_the_field_is_rejected_naming_the_field() {
    let c = cam(1024, 1024); // half-diagonal ≈ 0.25 normalised
    let mut cfg = SensorConfig::default();
    cfg.optics.distortion = Some(Distortion { k1: -6.0, ..Default::default() });
    let e = Sensor::new(&c, &cfg).unwrap_err();
    assert!(e.to_string().starts_with("sensor.optics.distortion:"), "{e}");
}

// ---------------------------------------------------------------- auto-exposure

#[test]
fn auto_exposure_settles_on_the_target_and_reports_each_frame() {
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    det.read_noise_e = Some(5.0);
    det.full_well_e = Some(20_000.0);
    let mut cfg = dn_config(det, adc(12, 5.0, 40.0));
    cfg.auto_exposure = Some(AutoExposureConfig {
        enabled: true,
        percentile: 99.0,
        target_fraction: 0.5,
        min_s: 1e-6,
        max_s: 1.0,
        max_step: 4.0,
    });
    let c = cam(64, 64);
    let s = Sensor::new(&c, &cfg).unwrap();
    // A bright square on black sky (25 % of the pixels): saturates at the start time.
    let mut img = RadianceImage::new(64, 64, 0.0);
    for r in 16..48 {
        for col in 16..48 {
            img.data[r * 64 + col] = 400.0;
        }
    }
    let mut ae = s.auto_exposure().unwrap();
    let target = 0.5 * (4095.0 - 40.0);
    let mut times = vec![];
    for i in 0..12 {
        let (out, upd) = s.apply_auto(&img, i, &mut ae).unwrap();
        assert_eq!(out.integration_time_s, Some(upd.previous_s));
        times.push(upd.previous_s);
        if i == 0 {
            assert!(out.stats.adc_high_clipped > 0 || out.stats.full_well_pixels > 0);
            // Saturated: the true level is unknown, so the largest step down.
            assert_eq!(upd.next_s, upd.previous_s / 4.0);
        }
    }
    // Converged: the square's level sits at the target within the dead band + noise,
    // and the time no longer changes.
    let k = s.electrons_per_radiance_second().unwrap() * 0.9 * 400.0;
    let level = k * times[11] / 5.0;
    assert!((level / target - 1.0).abs() < 0.05, "{level} vs {target}; {times:?}");
    assert_eq!(times[10], times[11]);
    // The steps never exceed max_step.
    for w in times.windows(2) {
        assert!(w[1] / w[0] <= 4.0 + 1e-12 && w[0] / w[1] <= 4.0 + 1e-12);
    }
    // A black scene lengthens the exposure by max_step per frame, up to max_s.
    let mut ae = s.auto_exposure().unwrap();
    let t0 = ae.integration_time_s();
    let black = RadianceImage::new(64, 64, 0.0);
    let (_, u) = s.apply_auto(&black, 0, &mut ae).unwrap();
    assert_eq!(u.next_s, t0 * 4.0);
}

// ---------------------------------------------------------------- config and presets

#[test]
fn presets_load_validate_and_describe_the_cameras() {
    for name in ["paper.toml", "nav1024.toml", "nav2048.toml"] {
        let p = CameraPreset::load(&preset(name)).unwrap();
        assert_eq!(p.sensor.band, Some(BandConfig { min_um: 0.45, max_um: 0.75 }));
        // Validation only (the 9000² paper camera would be slow to build a frame for).
        p.sensor.validate(&p.camera).unwrap();
    }
    let p = CameraPreset::load(&preset("paper.toml")).unwrap();
    assert_eq!((p.camera.width, p.camera.height), (9000, 9000));
    assert_eq!((p.camera.pitch_um, p.camera.focal_mm), (16.0, 6000.0));
    let n = CameraPreset::load(&preset("nav1024.toml")).unwrap();
    let fov = 2.0 * (n.camera.width as f64 / 2.0 / n.camera.focal_px()).atan();
    assert!((fov.to_degrees() - 20.0).abs() < 0.5);
    let s = Sensor::new(&n.camera, &n.sensor).unwrap();
    assert_eq!(s.bits(), Some(10));
    assert!(s.auto_exposure().is_some());
}

#[test]
fn config_errors_name_the_field_or_file() {
    let c = cam(8, 8);
    let mut cfg = dn_config(quiet_detector(1e-3), adc(12, 1.0, 0.0));
    cfg.detector.as_mut().unwrap().full_well_e = Some(-1.0);
    let e = Sensor::new(&c, &cfg).unwrap_err();
    assert!(e.to_string().starts_with("sensor.detector.full_well_e:"), "{e}");
    let mut cfg = dn_config(quiet_detector(1e-3), adc(17, 1.0, 0.0));
    assert!(Sensor::new(&c, &cfg).unwrap_err().to_string().starts_with("sensor.adc.bits:"));
    cfg.adc = None;
    cfg.output = Some(OutputKind::Dn);
    assert!(Sensor::new(&c, &cfg).unwrap_err().to_string().starts_with("sensor.output:"),);
    let mut cfg = dn_config(quiet_detector(1e-3), adc(12, 1.0, 0.0));
    cfg.band = None;
    assert!(matches!(
        Sensor::new(&c, &cfg),
        Err(SensorError::Invalid { field, .. }) if field == "sensor.band"
    ));
    // Unknown keys are errors, with the file name and the line.
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bad.toml");
    std::fs::write(
        &f,
        "[camera]\nwidth = 8\nheight = 8\npitch_um = 5.5\nfocal_mm = 16.0\n\n[sensor.optics]\ncos5 = true\n",
    )
    .unwrap();
    let e = CameraPreset::load(&f).unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("cos5") && e.contains("line 8"), "{e}");
    // Typos inside inline tables are caught too.
    for bad in [
        "psf = { kind = \"airy\", wavelength = 0.6 }",
        "psf = { kind = \"box\", sigma_px = 1.0 }",
        "distortion = { k1 = 0.1, k4 = 0.0 }",
    ] {
        std::fs::write(
            &f,
            format!("[camera]\nwidth = 8\nheight = 8\npitch_um = 5.5\nfocal_mm = 16.0\n\n[sensor.optics]\nf_number = 2.0\n{bad}\n"),
        )
        .unwrap();
        assert!(CameraPreset::load(&f).is_err(), "{bad} accepted");
    }
    // Size mismatch between the image and the camera.
    let s = Sensor::new(&c, &SensorConfig::default()).unwrap();
    assert!(matches!(s.apply(&RadianceImage::new(4, 8, 0.0), 0), Err(SensorError::SizeMismatch { .. })));
}

// ---------------------------------------------------------------- outputs and CLI

#[test]
fn dn_frames_write_to_png_and_tiff_and_read_back_unchanged() {
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    let cfg = dn_config(det, adc(12, 3.0, 64.0));
    let s = Sensor::new(&cam(40, 30), &cfg).unwrap();
    let mut img = RadianceImage::new(40, 30, 0.0);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = i as f32 * 0.05;
    }
    let out = s.apply(&img, 9).unwrap();
    let Pixels::Mono16 { data, bits: 12 } = &out.pixels else { panic!("12-bit in 16") };
    assert!(data.iter().all(|v| *v <= 4095));
    let dir = tempfile::tempdir().unwrap();
    for name in ["a.png", "a.tif"] {
        let p = dir.path().join(name);
        hilcam_core::render::film::write_pixels(&p, 40, 30, &out.pixels).unwrap();
        let back = image::open(&p).unwrap().into_luma16();
        assert_eq!(back.as_raw(), data);
    }
}

#[test]
fn cli_applies_a_preset_to_a_pfm() {
    let dir = tempfile::tempdir().unwrap();
    let cam_file = dir.path().join("cam.toml");
    std::fs::write(
        &cam_file,
        "[camera]\nwidth = 16\nheight = 8\npitch_um = 5.5\nfocal_mm = 16.0\n\n\
         [sensor]\nradiance_scale = 2.0\n[sensor.adc]\nbits = 8\n",
    )
    .unwrap();
    let mut img = RadianceImage::new(16, 8, 0.0);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = i as f32;
    }
    let pfm = dir.path().join("in.pfm");
    hilcam_core::render::film::write_radiance(&pfm, &img, None, false).unwrap();
    let out = dir.path().join("out.png");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["sensor", "--camera"])
        .arg(&cam_file)
        .arg(&pfm)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(status.status.success(), "hilcam sensor: {}", String::from_utf8_lossy(&status.stderr));
    let back = image::open(&out).unwrap().into_luma8();
    let want: Vec<u8> = (0..128).map(|i| (2 * i).min(255) as u8).collect();
    assert_eq!(back.as_raw(), &want);
}
