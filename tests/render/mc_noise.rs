//! The renderer's Monte Carlo noise through the sensor (issue 27): the camera's noise
//! bound, the variance carried through the chain, shot-noise substitution and the
//! per-frame report, each against an independent computation.

use super::sensor::quiet_detector;
use hilcam_core::render::camera::{CameraModel, Window};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::sampling::Rng;
use hilcam_core::sensor::config::{AdcConfig, BandConfig, DetectorConfig, NoiseMode, PsfConfig};
use hilcam_core::sensor::detector::Detector;
use hilcam_core::sensor::stream::{PixelNoise, frame_key};
use hilcam_core::sensor::{CameraPreset, OutputKind, Sensor, SensorConfig, SensorError, noise, optics, psf, ptc};

/// A DN sensor: band 0.45–0.75 µm, f/4, τ = 0.8, 16-bit ADC.
fn config(det: DetectorConfig, gain: f64) -> SensorConfig {
    let mut c = SensorConfig {
        band: Some(BandConfig { min_um: 0.45, max_um: 0.75 }),
        detector: Some(det),
        adc: Some(AdcConfig { bits: 16, gain_e_per_dn: gain, offset_dn: 100.0 }),
        ..Default::default()
    };
    c.optics.f_number = Some(4.0);
    c.optics.transmittance = Some(0.8);
    c
}

/// A camera whose 36-px focal length puts the corners 40° off axis (cos⁴ ≈ 0.3), with the
/// principal point off centre.
fn wide_cam(w: u32, h: u32) -> CameraModel {
    CameraModel { width: w, height: h, pitch_um: 5.5, focal_mm: 0.198, principal_point_px: [3.0, -2.0] }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

// ---------------------------------------------------------------- the noise bound

#[test]
fn noise_bound_gives_the_detectors_photo_charge_per_radiance_at_every_pixel() {
    let (w, h, t, l) = (40u32, 30u32, 1e-3, 7.0);
    let cam = wide_cam(w, h);
    let mut det = quiet_detector(t);
    det.shot_noise = true;
    det.read_noise_e = Some(5.0);
    det.dark_current_e_per_s = Some(50.0);
    for cos4 in [false, true] {
        let mut cfg = config(det.clone(), 2.0);
        cfg.optics.cos4 = cos4;
        let s = Sensor::new(&cam, &cfg).unwrap();
        let b = s.noise_bound(t, 0.5).unwrap();
        assert_eq!((b.k, b.shot, b.cos4.is_some()), (0.5, true, cos4));
        // Dark charge 50 e⁻/s × 1 ms, plus read noise².
        assert!(rel(b.floor_e2, 0.05 + 25.0) < 1e-12, "{}", b.floor_e2);
        // The detector's own expected photo-charge under the optics' own factors.
        let d = Detector::new(&det, s.electrons_per_radiance_second().unwrap(), t, None);
        for row in 0..h {
            for col in 0..w {
                let f = 0.8 * if cos4 { optics::cos4(&cam, col, row) } else { 1.0 };
                let want = d.expected_parts(l * f, (row * w + col) as u64).0;
                let got = b.e_per_radiance_at(row, col) * l;
                assert!(rel(got, want) < 1e-9, "cos4 {cos4} ({row},{col}): {got} vs {want}");
            }
        }
        // A window converts pixels of the same array: the bound (in sensor pixels) is the
        // full array's, and the window's expected charge is the bound's at its sensor pixels
        // (f32 radiance after the optics: 1e-6).
        let win = Window { x: 11, y: 7, width: 20, height: 15 };
        let sw = s.windowed(win);
        assert_eq!(sw.noise_bound(t, 0.5), Some(b));
        let out = sw.apply_with_integration(&RadianceImage::new(20, 15, l as f32), 3, t).unwrap();
        let mut want = 0.0;
        for r in 0..15 {
            for c in 0..20 {
                want += b.e_per_radiance_at(win.y + r, win.x + c) * l as f32 as f64;
            }
        }
        let got = out.stats.mean_expected_e - 0.05; // minus the dark charge
        assert!(rel(got, want / 300.0) < 1e-6, "window: {got} vs {}", want / 300.0);
    }
    // No bound without a detector, or when the output is radiance.
    let cam = wide_cam(8, 8);
    assert_eq!(Sensor::new(&cam, &SensorConfig::default()).unwrap().noise_bound(t, 0.5), None);
    let mut cfg = config(det.clone(), 2.0);
    cfg.output = Some(OutputKind::Float32);
    assert_eq!(Sensor::new(&cam, &cfg).unwrap().noise_bound(t, 0.5), None);
    // Without shot noise the camera has no dark-charge noise either: the floor is read².
    let mut quiet = det.clone();
    quiet.shot_noise = false;
    let b = Sensor::new(&cam, &config(quiet, 2.0)).unwrap().noise_bound(t, 0.5).unwrap();
    assert_eq!((b.floor_e2, b.shot), (25.0, false));
}

// ---------------------------------------------------------------- the chain

/// Reflecting index map of `sensor::psf` (half-sample symmetric), written out again.
fn reflect(j: i64, n: usize) -> usize {
    let p = j.rem_euclid(2 * n as i64) as usize;
    if p < n { p } else { 2 * n - 1 - p }
}

/// The dense matrix `W[o][i]` of one PSF pass on a `w × h` image: every input pixel
/// scatters its signal with the kernel, reflected at the borders.
fn pass_matrix(k: &psf::Kernel, w: usize, h: usize) -> Vec<Vec<f64>> {
    pass_matrix_of(k, w, h, |x| x)
}

/// The same with `f` applied to each kernel weight before the contributions are summed.
fn pass_matrix_of(k: &psf::Kernel, w: usize, h: usize, f: impl Fn(f64) -> f64) -> Vec<Vec<f64>> {
    let n = w * h;
    let mut m = vec![vec![0.0; n]; n];
    for iy in 0..h {
        for ix in 0..w {
            for my in -(k.ry as i64)..=k.ry as i64 {
                for mx in -(k.rx as i64)..=k.rx as i64 {
                    let wt = k.weights[(my + k.ry as i64) as usize * (2 * k.rx + 1) + (mx + k.rx as i64) as usize];
                    let o = reflect(iy as i64 + my, h) * w + reflect(ix as i64 + mx, w);
                    m[o][iy * w + ix] += f(wt as f64);
                }
            }
        }
    }
    m
}

fn mat_mul(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = a.len();
    let mut c = vec![vec![0.0; n]; n];
    for (ci, ai) in c.iter_mut().zip(a) {
        for (k, aik) in ai.iter().enumerate().filter(|(_, v)| **v != 0.0) {
            for (cij, bkj) in ci.iter_mut().zip(&b[k]) {
                *cij += aik * bkj;
            }
        }
    }
    c
}

#[test]
fn monte_carlo_variance_follows_the_chain_exactly() {
    // Small enough for the dense matrices; the 9-px Gaussian and 7-px Airy kernels reach
    // every border, where reflected weights add before they are squared.
    let (w, h, t, gain) = (24usize, 20usize, 2e-3, 3.0);
    let cam = wide_cam(w as u32, h as u32);
    let mut det = quiet_detector(t);
    det.shot_noise = true;
    let mut var = vec![0.0f32; w * h];
    for (i, v) in var.iter_mut().enumerate() {
        *v = ((i * 7919) % 101) as f32 * 0.013 + 1e-3;
    }
    var[5] = 0.0; // an exact pixel
    let psfs = [
        (PsfConfig::Gaussian { sigma_px: 0.9 }, {
            let (kh, kv) = psf::Kernel::gaussian(0.9);
            mat_mul(&pass_matrix(&kv, w, h), &pass_matrix(&kh, w, h))
        }),
        (
            PsfConfig::Airy { wavelength_um: Some(0.6), radius_px: Some(3) },
            pass_matrix(&psf::Kernel::airy(4.0, 5.5, &[0.6], Some(3)), w, h),
        ),
    ];
    for (psf_cfg, m) in psfs {
        let mut cfg = config(det.clone(), gain);
        cfg.optics.cos4 = true;
        cfg.optics.psf = Some(psf_cfg.clone());
        let s = Sensor::new(&cam, &cfg).unwrap();
        let e_per_l = s.electrons_per_radiance_second().unwrap() * t;
        // Var(Σᵢ Wₒᵢ (τ cos⁴ᵢ) Lᵢ) = Σᵢ Wₒᵢ² (τ cos⁴ᵢ)² vᵢ, then × (electrons per radiance)².
        let scaled: Vec<f64> = (0..w * h)
            .map(|i| {
                let f = 0.8 * optics::cos4(&cam, (i % w) as u32, (i / w) as u32);
                var[i] as f64 * f * f
            })
            .collect();
        let got_e2 = s.mc_variance_e2(&var, t).unwrap().unwrap();
        let got_dn2 = s.mc_variance_output(&var, t).unwrap();
        for o in 0..w * h {
            let want: f64 = m[o].iter().zip(&scaled).map(|(wt, v)| wt * wt * v).sum::<f64>() * e_per_l * e_per_l;
            // f32 storage after the optics and after each pass: a few 1e-7.
            assert!(rel(got_e2[o], want) < 1e-6, "{psf_cfg:?} pixel {o}: {} vs {want}", got_e2[o]);
            assert!(rel(got_dn2[o], want / (gain * gain)) < 1e-6, "DN² at {o}");
        }
    }
    // An interior pixel among neighbours of equal variance: v · Σ W² (the 0.7 px Gaussian
    // of nav1024.toml: Σ W² = 0.1400, from the pixel-integrated weights).
    let (s, img, _) = small_nav();
    let flat = vec![1.0f32; img.data.len()];
    let f = s.psf_variance_factor();
    assert!((f - 0.1400).abs() < 1e-4, "{f}");
    let centre = s.optics_variance(&flat).unwrap()[32 * 96 + 48] as f64;
    let cos4 = optics::cos4(s.camera(), 48, 32);
    let tau = s.config().optics.transmittance.unwrap();
    assert!(rel(centre, f * (tau * cos4).powi(2)) < 1e-3, "{centre}");
    // Squaring each kernel weight separately (no merging at the reflecting border) would
    // be wrong at the corner, where one input reaches the output through several offsets.
    let airy = psf::Kernel::airy(4.0, 5.5, &[0.6], Some(3));
    let mut cfg = config(det.clone(), gain);
    cfg.optics.transmittance = None;
    cfg.optics.psf = Some(PsfConfig::Airy { wavelength_um: Some(0.6), radius_px: Some(3) });
    let s = Sensor::new(&cam, &cfg).unwrap();
    let naive: f64 = pass_matrix_of(&airy, w, h, |x| x * x)[0].iter().zip(&var).map(|(k2, v)| k2 * *v as f64).sum();
    let got = s.optics_variance(&var).unwrap()[0] as f64;
    assert!(rel(got, naive) > 0.1, "corner {got} vs naive {naive}");
    // Float output: the variance in (radiance · radiance_scale)², after the optics.
    let mut cfg = SensorConfig { radiance_scale: Some(3.0), ..Default::default() };
    cfg.optics.transmittance = Some(0.5);
    let s = Sensor::new(&cam, &cfg).unwrap();
    let out = s.mc_variance_output(&var, t).unwrap();
    assert!(s.mc_variance_e2(&var, t).unwrap().is_none());
    for (o, v) in out.iter().zip(&var) {
        assert!(rel(*o, *v as f64 * 0.25 * 9.0) < 1e-6 || *v == 0.0);
    }
    assert!(matches!(s.mc_variance_output(&var[1..], t), Err(SensorError::VarianceSize { .. })));
}

// ---------------------------------------------------------------- photon transfer

/// A flat field of radiance `l` with Monte Carlo noise of variance `v` (radiance²) drawn
/// by this test per pixel and frame, from its own stream (not the sensor's).
fn noisy_flat(n: u32, l: f64, v: f64, frame: u64) -> RadianceImage {
    let mut img = RadianceImage::new(n, n, 0.0);
    for (p, x) in img.data.iter_mut().enumerate() {
        let z = noise::normal_pair(&mut Rng::for_sample(0x4d43_5445_5354, frame, p as u64, 0)).0;
        *x = (l + v.sqrt() * z) as f32;
    }
    img
}

#[test]
fn photon_transfer_with_monte_carlo_noise_substituted_is_the_cameras() {
    let (n, gain, read, l) = (256u32, 2.0, 6.0, 20.0);
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    det.read_noise_e = Some(read);
    det.prnu = Some(0.01); // fixed pattern: the frame difference cancels it
    det.fpn_seed = 5;
    let add = Sensor::new(&wide_cam(n, n), &{
        let mut c = config(det.clone(), gain);
        c.optics.cos4 = false;
        c
    })
    .unwrap();
    let mut sub_cfg = add.config().clone();
    sub_cfg.detector.as_mut().unwrap().noise = NoiseMode::Substitute;
    let sub = Sensor::new(add.camera(), &sub_cfg).unwrap();
    let e_per_l_s = add.electrons_per_radiance_second().unwrap() * 0.8;
    let dark = ptc::measure(&add, 0.0, 10).unwrap();
    let (mut pts_sub, mut pts_add) = (vec![], vec![]);
    // Levels by integration time at a fixed radiance; at each, Monte Carlo variance of
    // half the shot-noise variance (v_e = λ/2). Substitution can take away at most the
    // whole shot noise (v_e ≤ λ), and the remaining Gaussian draw needs λ − v_e ≫ 1;
    // λ/2 ≥ 250 e⁻² keeps every level well inside both.
    for (i, lambda) in [500.0, 2000.0, 5000.0, 10000.0, 20000.0, 40000.0].into_iter().enumerate() {
        let t = lambda / (l * e_per_l_s);
        let c = e_per_l_s * t;
        let v = 0.5 * lambda / (c * c);
        let var = vec![v as f32; (n * n) as usize];
        let frames: Vec<RadianceImage> = (0..2).map(|f| noisy_flat(n, l, v, 2 * i as u64 + f)).collect();
        let run = |s: &Sensor, f: usize| {
            s.apply_with_variance(&frames[f], Some(&var), 20 + 2 * i as u64 + f as u64, t, 1.0).unwrap()
        };
        let (a, b) = (run(&sub, 0), run(&sub, 1));
        let mc = a.stats.mc.unwrap();
        assert_eq!(mc.lit_pixels, (n * n) as u64);
        assert_eq!(mc.above_shot, 0);
        pts_sub.push(ptc::point_from_frames(l, &a.pixels, &b.pixels));
        let (a, b) = (run(&add, 0), run(&add, 1));
        pts_add.push((ptc::point_from_frames(l, &a.pixels, &b.pixels), lambda, var, t));
    }
    let fit = ptc::fit(&dark, &pts_sub);
    assert!(rel(fit.gain_e_per_dn, gain) < 0.03, "gain {}", fit.gain_e_per_dn);
    assert!(rel(fit.read_noise_e, read) < 0.03, "read noise {}", fit.read_noise_e);
    for p in &pts_sub {
        let slope = (p.var_dn - dark.var_dn) / (p.mean_dn - dark.mean_dn);
        assert!((slope * gain - 1.0).abs() < 0.05, "{p:?}");
    }
    // Added on top, the Monte Carlo variance shows as excess over the camera's
    // σ² = (λ + read²)/g² + 1/12, equal to its value in DN² (v_e / g², PRNU included).
    // The variance of 65 536 differences has a relative standard error √(2/65536) =
    // 0.55 %; on σ² ≈ 1.5× the camera's that is 1.7 % of the excess: 6 % is 3.5 SE.
    let mut ratios = vec![];
    for (p, lambda, var, t) in &pts_add {
        let camera = (lambda + read * read) / (gain * gain) + 1.0 / 12.0;
        let want = add.mc_variance_output(var, *t).unwrap().iter().sum::<f64>() / var.len() as f64;
        let excess = p.var_dn - camera;
        ratios.push(excess / want);
        assert!(rel(excess, want) < 0.06, "λ {lambda}: excess {excess} DN² vs {want}");
    }
    // Over the six levels the standard error is 0.7 %: 2.5 % is 3.5 SE.
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!((mean - 1.0).abs() < 0.025, "excess / Monte Carlo variance {mean} ({ratios:?})");
}

// ---------------------------------------------------------------- the report

#[test]
fn the_report_counts_exactly_the_pixels_above_the_bound() {
    // No optics factors, PSF or PRNU: the radiance reaches the detector unchanged, so the
    // expected counts and ratios can be computed here from the same f32 inputs.
    let (w, h, t, read) = (16usize, 8usize, 1e-3, 5.0);
    let cam =
        CameraModel { width: w as u32, height: h as u32, pitch_um: 5.5, focal_mm: 16.0, principal_point_px: [0.0; 2] };
    let mut det = quiet_detector(t);
    det.shot_noise = true;
    det.read_noise_e = Some(read);
    det.dark_current_e_per_s = Some(1000.0); // 1 e⁻ over 1 ms
    let mut cfg = config(det, 2.0);
    cfg.optics.transmittance = None;
    let s = Sensor::new(&cam, &cfg).unwrap();
    let c = s.electrons_per_radiance_second().unwrap() * t;
    // Row 0 is dark, row 1 holds 0.5 e⁻ (not lit); the rest are lit at 100 + 37·i e⁻ with
    // σ_mc / σ_cam cycling through these ratios.
    let ratios = [0.1, 0.3, 0.7, 1.3, 3.0];
    let mut img = RadianceImage::new(w as u32, h as u32, 0.0);
    let mut var = vec![0.0f32; w * h];
    for i in w..w * h {
        let photo = if i < 2 * w { 0.5 } else { 100.0 + 37.0 * i as f64 };
        img.data[i] = (photo / c) as f32;
        let cam_e2 = photo + 1.0 + read * read;
        let r = ratios[i % ratios.len()];
        var[i] = (r * r * cam_e2 / (c * c)) as f32;
    }
    for k in [1.0, 0.5] {
        let out = s.apply_with_variance(&img, Some(&var), 9, t, k).unwrap();
        let mc = out.stats.mc.unwrap();
        let (mut lit, mut above, mut above_shot, mut ratio, mut ratio2, mut v_sum) = (0u64, 0u64, 0u64, 0.0, 0.0, 0.0);
        for (l, v) in img.data.iter().zip(&var) {
            let photo = *l as f64 * c;
            let v_e = *v as f64 * c * c;
            if photo >= 1.0 {
                let cam_e2 = photo + 1.0 + read * read;
                lit += 1;
                above += (v_e.sqrt() > k * cam_e2.sqrt()) as u64;
                above_shot += (v_e > photo + 1.0) as u64;
                ratio += (v_e / cam_e2).sqrt();
                ratio2 += v_e / cam_e2;
                v_sum += v_e;
            }
        }
        assert_eq!(lit, ((h - 2) * w) as u64);
        // Ratios 1.3 and 3.0 exceed k = 1; with k = 0.5, 0.7 too.
        let set_above = (2 * w..w * h).filter(|i| ratios[i % ratios.len()] > k).count() as u64;
        assert_eq!(above, set_above);
        assert_eq!((mc.k, mc.lit_pixels, mc.above_bound, mc.above_shot), (k, lit, above, above_shot));
        assert!(rel(mc.mean_ratio, ratio / lit as f64) < 1e-12, "{} vs {}", mc.mean_ratio, ratio / lit as f64);
        assert!(rel(mc.rms_ratio, (ratio2 / lit as f64).sqrt()) < 1e-12, "{mc:?}");
        assert!(rel(mc.mc_variance_e2_mean, v_sum / lit as f64) < 1e-12);
        // The mean ratio is the mean of the ratios set, to f32 rounding of the inputs.
        let set: f64 = (2 * w..w * h).map(|i| ratios[i % ratios.len()]).sum::<f64>() / lit as f64;
        assert!(rel(mc.mean_ratio, set) < 1e-6, "{} vs {set}", mc.mean_ratio);
    }
    // No variance image, no report; a radiance output has no electrons to compare.
    assert_eq!(s.apply_with_integration(&img, 9, t).unwrap().stats.mc, None);
    let mut fcfg = cfg.clone();
    fcfg.output = Some(OutputKind::Float32);
    let f = Sensor::new(&cam, &fcfg).unwrap();
    assert_eq!(f.apply_with_variance(&img, Some(&var), 9, t, 1.0).unwrap().stats.mc, None);
}

#[test]
fn the_report_and_the_renderers_bound_are_the_same_bound() {
    // Each pixel's Monte Carlo variance set at 0.98× or 1.02× what the bound allows (the
    // renderer's `allowed_radiance_variance`): the report finds exactly the 1.02× pixels
    // above it, on a camera with τ, cos⁴ (40° corners) and dark charge; no PSF or PRNU.
    let (w, h, t, k) = (40u32, 30u32, 1e-3, 0.5);
    let cam = wide_cam(w, h);
    let mut det = quiet_detector(t);
    det.shot_noise = true;
    det.read_noise_e = Some(5.0);
    det.dark_current_e_per_s = Some(3000.0);
    let mut cfg = config(det, 2.0);
    cfg.optics.cos4 = true;
    let s = Sensor::new(&cam, &cfg).unwrap();
    let b = s.noise_bound(t, k).unwrap();
    let mut img = RadianceImage::new(w, h, 0.0);
    let mut var = vec![0.0f32; (w * h) as usize];
    let (mut above, mut ratio) = (0u64, 0.0);
    for row in 0..h {
        for col in 0..w {
            let i = (row * w + col) as usize;
            // From 2 e⁻ to ≈ 4000 e⁻ on axis.
            let l = (2.0 + 13.0 * i as f64) / b.e_per_radiance;
            let f = if i.is_multiple_of(3) { 1.02 } else { 0.98 };
            img.data[i] = l as f32;
            var[i] = (f * b.allowed_radiance_variance(img.data[i] as f64, row, col)) as f32;
            if b.e_per_radiance_at(row, col) * img.data[i] as f64 >= 1.0 {
                above += (f > 1.0) as u64;
                ratio += k * f64::sqrt(f);
            }
        }
    }
    let mc = s.apply_with_variance(&img, Some(&var), 1, t, k).unwrap().stats.mc.unwrap();
    assert!(mc.lit_pixels > 1000, "{mc:?}");
    assert_eq!(mc.above_bound, above);
    // f32 radiance after the optics and f32 variances: 1e-6.
    assert!(rel(mc.mean_ratio, ratio / mc.lit_pixels as f64) < 1e-6, "{mc:?}");
}

// ---------------------------------------------------------------- bytes and config

fn small_nav() -> (Sensor, RadianceImage, Vec<f32>) {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/cameras/nav1024.toml")).unwrap();
    let mut p: CameraPreset = toml::from_str(&text).unwrap();
    p.camera.width = 96;
    p.camera.height = 64;
    p.camera.focal_mm = 16.0 * 96.0 / 1024.0;
    let s = Sensor::new(&p.camera, &p.sensor).unwrap();
    let mut img = RadianceImage::new(96, 64, 0.0);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = (i % 97) as f32 * 0.8;
    }
    let var: Vec<f32> = (0..96 * 64).map(|i| (i % 89) as f32 * 0.01).collect();
    (s, img, var)
}

/// `Sensor::mc_noise_stats` judges a frame at any bound without converting it: the
/// report `apply_with_variance` gives at that bound, on the nav camera's full chain
/// (τ, cos⁴, PSF, PRNU, DSNU), for bounds that split the pixels differently.
#[test]
fn the_report_at_another_bound_is_the_converted_frames_report_there() {
    let (s, img, var) = small_nav();
    let t = 25e-6;
    let mut above = Vec::new();
    for k in [0.05, 0.25, 0.5, 1.0] {
        let got = s.mc_noise_stats(&img, &var, t, k).unwrap().unwrap();
        assert_eq!(Some(got), s.apply_with_variance(&img, Some(&var), 42, t, k).unwrap().stats.mc, "k {k}");
        above.push(got.above_bound);
    }
    // The bounds split them differently: fewer above as k grows, with some above at
    // k = 1 and some below at k = 0.25.
    assert!(above.windows(2).all(|w| w[0] > w[1]), "{above:?}");
    let lit = s.mc_noise_stats(&img, &var, t, 1.0).unwrap().unwrap().lit_pixels;
    assert!(above[3] > 0 && above[1] < lit, "{above:?} of {lit}");
    assert!(matches!(
        s.mc_noise_stats(&img, &var[1..], t, 0.5),
        Err(SensorError::VarianceSize { got: 6143, want: 6144 })
    ));
    let mut fcfg = s.config().clone();
    fcfg.output = Some(OutputKind::Float32);
    fcfg.auto_exposure = None;
    assert_eq!(Sensor::new(s.camera(), &fcfg).unwrap().mc_noise_stats(&img, &var, t, 0.5).unwrap(), None);
}

#[test]
fn without_variance_or_with_noise_add_the_bytes_are_unchanged() {
    let (s, img, var) = small_nav();
    assert_eq!(s.config().detector.as_ref().unwrap().noise, NoiseMode::Add);
    let t = 25e-6;
    let base = s.apply_with_integration(&img, 42, t).unwrap();
    assert_eq!(s.apply_with_variance(&img, None, 42, t, 0.5).unwrap(), base);
    // "add": the same pixels and counters, plus the report.
    let mut with = s.apply_with_variance(&img, Some(&var), 42, t, 0.5).unwrap();
    assert!(with.stats.mc.unwrap().lit_pixels > 0);
    with.stats.mc = None;
    assert_eq!(with, base);
    // "substitute": where the variance is 0 the draw is today's; elsewhere it differs,
    // with the same bytes for any thread count.
    let mut cfg = s.config().clone();
    cfg.detector.as_mut().unwrap().noise = NoiseMode::Substitute;
    let sub = Sensor::new(s.camera(), &cfg).unwrap();
    let zeros = vec![0.0f32; var.len()];
    assert_eq!(sub.apply_with_variance(&img, Some(&zeros), 42, t, 0.5).unwrap().pixels, base.pixels);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| sub.apply_with_variance(&img, Some(&var), 42, t, 0.5).unwrap())
    };
    let one = run(1);
    assert_ne!(one.pixels, base.pixels);
    assert_eq!(one, run(3));
    assert!(matches!(
        s.apply_with_variance(&img, Some(&var[1..]), 42, t, 0.5),
        Err(SensorError::VarianceSize { got: 6143, want: 6144 })
    ));
}

#[test]
fn noise_substitute_parses_and_is_refused_without_shot_noise_or_dn_output() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/cameras/nav1024.toml")).unwrap();
    let p: CameraPreset =
        toml::from_str(&text.replace("shot_noise = true", "shot_noise = true\nnoise = \"substitute\"")).unwrap();
    assert_eq!(p.sensor.detector.as_ref().unwrap().noise, NoiseMode::Substitute);
    assert!(Sensor::new(&p.camera, &p.sensor).is_ok());
    let field_of = |cfg: &SensorConfig| match Sensor::new(&p.camera, cfg) {
        Err(SensorError::Invalid { field, message }) => (field, message),
        other => panic!("{other:?}"),
    };
    let mut no_shot = p.sensor.clone();
    no_shot.detector.as_mut().unwrap().shot_noise = false;
    let (field, message) = field_of(&no_shot);
    assert_eq!(field, "sensor.detector.noise");
    assert!(message.contains("shot_noise"), "{message}");
    let mut float = p.sensor.clone();
    float.output = Some(OutputKind::Float32);
    float.auto_exposure = None;
    let (field, message) = field_of(&float);
    assert_eq!(field, "sensor.detector.noise");
    assert!(message.contains("DN output"), "{message}");
    assert!(
        toml::from_str::<CameraPreset>(&text.replace("shot_noise = true", "shot_noise = true\nnoise = \"mix\""))
            .is_err()
    );
}

#[test]
fn substituted_shot_noise_has_the_remaining_variance() {
    // One pixel's draw, many times: mean λ, variance λ − v (Gaussian plus rounding).
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    let d = Detector::new(&det, 1.0, 1.0, None);
    for (lambda, v) in [(1000.0, 400.0), (40.0, 10.0), (100.0, 250.0)] {
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let e = d.sample_substituted(lambda, v, &mut PixelNoise::new(frame_key(7), i)).collected_e;
            s += e;
            s2 += e * e;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        let want = lambda - v;
        // Standard errors: mean √(var/n) ≤ 0.07; variance √(2/n) = 0.32 % relative.
        assert!((mean - lambda).abs() < 0.3, "λ {lambda}: mean {mean}");
        if v < lambda {
            assert!(rel(var, want) < 0.015, "λ {lambda} v {v}: var {var} vs {want}");
        } else {
            // v ≥ λ: no shot noise at all; λ = 100 is an integer, so the rounding is exact.
            assert_eq!(var, 0.0);
        }
    }
}

#[test]
fn heavy_tailed_monte_carlo_noise_keeps_the_cameras_variance_not_its_tails() {
    // A firefly model: each pixel's Monte Carlo mean is L + D with probability p = 1 %,
    // else L − D·p/(1 − p) (mean L, variance D²·p/(1 − p)), with v_e = λ/2. Substitution
    // restores the camera's variance, but 1 % of the pixels sit √(0.5·99) ≈ 7σ high.
    let (n, gain, read, lambda, p) = (256u32, 1.0, 6.0, 10_000.0, 0.01);
    let mut det = quiet_detector(1e-3);
    det.shot_noise = true;
    det.read_noise_e = Some(read);
    det.noise = NoiseMode::Substitute;
    let mut cfg = config(det, gain);
    cfg.optics.transmittance = None;
    let cam = CameraModel { width: n, height: n, pitch_um: 5.5, focal_mm: 16.0, principal_point_px: [0.0; 2] };
    let s = Sensor::new(&cam, &cfg).unwrap();
    let c = s.electrons_per_radiance_second().unwrap() * 1e-3;
    let (l, v) = (lambda / c, 0.5 * lambda / (c * c));
    let d = (v * (1.0 - p) / p).sqrt();
    let mut img = RadianceImage::new(n, n, 0.0);
    for (i, x) in img.data.iter_mut().enumerate() {
        let u = noise::uniform_open(&mut Rng::for_sample(0x4649_5245, 0, i as u64, 0));
        *x = (if u < p { l + d } else { l - d * p / (1.0 - p) }) as f32;
    }
    let var = vec![v as f32; (n * n) as usize];
    let out = s.apply_with_variance(&img, Some(&var), 3, 1e-3, 1.0).unwrap();
    let dn: Vec<f64> = match &out.pixels {
        hilcam_core::render::film::Pixels::Mono16 { data, .. } => data.iter().map(|v| *v as f64 - 100.0).collect(),
        other => panic!("{other:?}"),
    };
    let m = dn.len() as f64;
    let mean = dn.iter().sum::<f64>() / m;
    let sd = (dn.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
    let camera_sd = (lambda + read * read + 1.0 / 12.0).sqrt();
    let tail = dn.iter().filter(|x| **x > lambda + 3.0 * camera_sd).count() as f64 / m;
    eprintln!(
        "firefly p = {p}: σ {sd:.1} e⁻ (camera {camera_sd:.1}), P(> +3σ_cam) {:.3} % (Gaussian 0.135 %)",
        100.0 * tail
    );
    // The variance is the camera's (σ's standard error 0.3 %) ...
    assert!(rel(sd, camera_sd) < 0.015, "σ {sd} vs {camera_sd}");
    // ... but the upper tail holds the fireflies: ≈ 1 % instead of 0.135 %.
    assert!(tail > 5.0 * 0.00135, "tail {tail}");
}
