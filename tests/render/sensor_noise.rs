//! The sensor's random variates against their analytic distributions: the ziggurat's
//! normals, the Poisson shot noise, and a black frame's DN histogram (dark charge, read
//! noise and ADC together) against its exact probabilities.

use super::sensor::{adc, dn_config, quiet_detector};
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::film::{Pixels, RadianceImage};
use hilcam_core::sensor::psf::normal_cdf;
use hilcam_core::sensor::stream::{PixelNoise, PixelStream, frame_key};
use hilcam_core::sensor::{Sensor, noise, ziggurat};

/// χ² of observed counts against expected ones, pooling neighbouring bins until each
/// expects ≥ 5 (a short remainder joins the last); returns (χ², degrees of freedom).
fn chi2(observed: &[f64], expected: &[f64]) -> (f64, usize) {
    let mut bins: Vec<(f64, f64)> = Vec::new();
    let (mut o, mut e) = (0.0, 0.0);
    for (ob, ex) in observed.iter().zip(expected) {
        (o, e) = (o + ob, e + ex);
        if e >= 5.0 {
            bins.push((o, e));
            (o, e) = (0.0, 0.0);
        }
    }
    if let Some(last) = bins.last_mut() {
        (last.0, last.1) = (last.0 + o, last.1 + e);
    }
    (bins.iter().map(|(o, e)| (o - e).powi(2) / e).sum(), bins.len().saturating_sub(1))
}

/// The 99.9 % point of χ² with `dof` degrees of freedom (Wilson–Hilferty).
fn chi2_999(dof: usize) -> f64 {
    let k = dof as f64;
    let z = 3.090_232;
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

// ---------------------------------------------------------------- normal variates

/// `n` normals, one from each pixel's read stream (as the sensor draws them).
fn normals(n: u64, seed: u64) -> Vec<f64> {
    let key = frame_key(seed);
    (0..n).map(|p| ziggurat::normal(&mut PixelNoise::new(key, p).read)).collect()
}

#[test]
fn ziggurat_normals_have_the_normal_moments() {
    let n = 4_000_000;
    let z = normals(n, 11);
    let nf = n as f64;
    let m = |k: i32| z.iter().map(|v| v.powi(k)).sum::<f64>() / nf;
    // Standard errors of the sample moments of N(0, 1): √(Var zᵏ / n) with
    // Var z = 1, Var z² = 2, Var z³ = 15, Var z⁴ = 96.
    let se = |var: f64| 5.0 * (var / nf).sqrt();
    assert!(m(1).abs() < se(1.0), "mean {}", m(1));
    assert!((m(2) - 1.0).abs() < se(2.0), "E z² {}", m(2));
    assert!(m(3).abs() < se(15.0), "E z³ {}", m(3));
    assert!((m(4) - 3.0).abs() < se(96.0), "E z⁴ {}", m(4));
}

#[test]
fn ziggurat_normals_follow_the_normal_cdf_into_the_tails() {
    // 400 equal-probability bins over the body, then fixed bins through the tail the
    // ziggurat draws separately (beyond 3.654) out to 5.
    let n = 4_000_000usize;
    let z = normals(n as u64, 12);
    let mut edges: Vec<f64> = vec![-5.0, -4.5, -4.0, -3.654_152_885_361_009, -3.3];
    let lo = normal_cdf(-3.3);
    for k in 1..400 {
        // Bisection for the quantile (normal_cdf is accurate to 1.2e-7 relative).
        let p = lo + (1.0 - 2.0 * lo) * k as f64 / 400.0;
        let (mut a, mut b) = (-3.3, 3.3);
        for _ in 0..60 {
            let mid = 0.5 * (a + b);
            if normal_cdf(mid) < p { a = mid } else { b = mid }
        }
        edges.push(0.5 * (a + b));
    }
    edges.extend([3.3, 3.654_152_885_361_009, 4.0, 4.5, 5.0]);
    let mut counts = vec![0.0; edges.len() + 1];
    for v in &z {
        counts[edges.partition_point(|e| e <= v)] += 1.0;
    }
    let cdf = |i: usize| {
        if i == 0 {
            0.0
        } else if i > edges.len() {
            1.0
        } else {
            normal_cdf(edges[i - 1])
        }
    };
    let expected: Vec<f64> = (0..counts.len()).map(|i| (cdf(i + 1) - cdf(i)) * n as f64).collect();
    let (c, dof) = chi2(&counts, &expected);
    assert!(c < chi2_999(dof), "χ² {c} with {dof} degrees of freedom");
    // The tail region alone (|z| > R, probability 2.58e-4): its count within 4 σ.
    let tail = z.iter().filter(|v| v.abs() > 3.654_152_885_361_009).count() as f64;
    let want = 2.0 * normal_cdf(-3.654_152_885_361_009) * n as f64;
    assert!((tail - want).abs() < 4.0 * want.sqrt(), "{tail} beyond R, expected {want}");
}

#[test]
fn consecutive_draws_and_the_two_streams_are_uncorrelated() {
    let (n, key) = (1_000_000u64, frame_key(13));
    let (mut read_shot, mut lag, mut prev) = (0.0, 0.0, 0.0);
    let mut one = PixelStream::new(key, 99, 0);
    for p in 0..n {
        let mut s = PixelNoise::new(key, p);
        let (a, b) = (ziggurat::normal(&mut s.read), ziggurat::normal(&mut s.shot));
        read_shot += a * b;
        // Successive draws of one stream, and neighbouring pixels' first draws.
        let c = ziggurat::normal(&mut one);
        lag += c * prev;
        prev = c;
    }
    let neighbours: f64 = normals(n, 14).windows(2).map(|w| w[0] * w[1]).sum();
    let bound = 5.0 / (n as f64).sqrt();
    for (what, sum) in [("read × shot", read_shot), ("one stream, lag 1", lag), ("pixel p × p+1", neighbours)] {
        assert!((sum / n as f64).abs() < bound, "{what}: correlation {}", sum / n as f64);
    }
}

// ---------------------------------------------------------------- Poisson variates

fn poisson_pmf(lambda: f64, k: usize) -> f64 {
    let mut p = (-lambda).exp();
    for i in 1..=k {
        p *= lambda / i as f64;
    }
    p
}

fn sample_poisson(lambda: f64, n: usize, seed: u64) -> Vec<f64> {
    let key = frame_key(seed);
    (0..n as u64).map(|i| noise::poisson(lambda, &mut PixelNoise::new(key, i).shot)).collect()
}

#[test]
fn poisson_is_exact_below_the_threshold() {
    // Chi-square of sampled counts against the exact pmf (bins pooled to expect ≥ 5),
    // from a dark pixel's mean (the shortcut u ≤ 1 − λ decides almost every draw) up.
    for &lambda in &[0.002, 0.05, 0.3, 3.0, 12.0, 29.0] {
        assert!(lambda < noise::POISSON_EXACT_BELOW);
        let n = 400_000;
        let xs = sample_poisson(lambda, n, (lambda * 1e3) as u64);
        let kmax = (lambda + 10.0 * lambda.sqrt() + 10.0) as usize;
        let mut counts = vec![0f64; kmax + 1];
        for x in &xs {
            counts[(*x as usize).min(kmax)] += 1.0;
        }
        let mut expected: Vec<f64> = (0..kmax).map(|k| poisson_pmf(lambda, k) * n as f64).collect();
        expected.push(n as f64 - expected.iter().sum::<f64>());
        let (c, dof) = chi2(&counts, &expected);
        assert!(dof >= 1 && c < chi2_999(dof), "λ={lambda}: χ²={c} with {dof} degrees of freedom");
        let mean = xs.iter().sum::<f64>() / n as f64;
        assert!((mean - lambda).abs() < 5.0 * (lambda / n as f64).sqrt(), "λ={lambda}: mean {mean}");
    }
}

#[test]
fn poisson_normal_approximation_above_the_threshold_is_close_and_unbiased() {
    // At the threshold: Kolmogorov distance to the exact Poisson CDF < 0.005.
    let lambda = noise::POISSON_EXACT_BELOW;
    let n = 400_000;
    let mut xs = sample_poisson(lambda, n, 1);
    xs.sort_by(f64::total_cmp);
    let (mut cdf, mut d) = (0.0, 0.0f64);
    for k in 0..(3.0 * lambda) as usize {
        cdf += poisson_pmf(lambda, k);
        let emp = xs.partition_point(|x| *x <= k as f64) as f64 / n as f64;
        d = d.max((emp - cdf).abs());
    }
    assert!(d < 0.005, "KS distance {d}");
    // Mean and variance equal λ for large means (variance within sampling error).
    for &lambda in &[30.0, 1000.0, 1e6] {
        let xs = sample_poisson(lambda, n, 2);
        let m = xs.iter().sum::<f64>() / n as f64;
        let v = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
        assert!((m - lambda).abs() < 5.0 * (lambda / n as f64).sqrt(), "λ={lambda} mean {m}");
        assert!((v / lambda - 1.0).abs() < 0.012, "λ={lambda} var {v}");
    }
}

// ---------------------------------------------------------------- a black frame

#[test]
fn a_black_frames_dn_histogram_is_the_exact_dark_and_read_noise_distribution() {
    // Dark charge k ~ Poisson(λ), read noise σ z, ADC ⌊offset + (k + σz)/g + ½⌋:
    // P(DN = d) = Σ_k Pois(k; λ) · [Φ(((d + ½ − offset)g − k)/σ) − Φ(((d − ½ − offset)g − k)/σ)].
    let (t, lambda, sigma, gain, offset) = (0.02, 0.8, 12.0, 4.0, 32.0);
    let mut det = quiet_detector(t);
    det.dark_current_e_per_s = Some(lambda / t);
    det.shot_noise = true;
    det.read_noise_e = Some(sigma);
    let (w, h) = (512u32, 512u32);
    let cam = CameraModel { width: w, height: h, pitch_um: 5.5, focal_mm: 16.0, principal_point_px: [0.0, 0.0] };
    let sensor = Sensor::new(&cam, &dn_config(det, adc(10, gain, offset))).unwrap();
    let out = sensor.apply(&RadianceImage::new(w, h, 0.0), 5).unwrap();
    let Pixels::Mono16 { data, .. } = &out.pixels else { panic!("10-bit output") };
    let mut counts = vec![0.0; 1024];
    for v in data {
        counts[*v as usize] += 1.0;
    }
    let n = f64::from(w * h);
    let expected: Vec<f64> = (0..1024)
        .map(|d| {
            let edge = |x: f64| (x - offset) * gain;
            (0..12)
                .map(|k| {
                    let k = k as f64;
                    let hi = if d == 1023 { 1.0 } else { normal_cdf((edge(d as f64 + 0.5) - k) / sigma) };
                    let lo = if d == 0 { 0.0 } else { normal_cdf((edge(d as f64 - 0.5) - k) / sigma) };
                    poisson_pmf(lambda, k as usize) * (hi - lo)
                })
                .sum::<f64>()
                * n
        })
        .collect();
    let (c, dof) = chi2(&counts, &expected);
    assert!(dof > 10 && c < chi2_999(dof), "χ² {c} with {dof} degrees of freedom");
    assert!((out.stats.mean_collected_e - lambda).abs() < 5.0 * (lambda / n).sqrt(), "{:?}", out.stats);
}
