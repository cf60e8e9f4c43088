//! The three indirect samplers (uniform, cosine, the BRDF's MIS) are unbiased at the
//! renderer level, against an answer computed here by our own quadrature; and the
//! `bench sampling` pipeline runs end to end on a tiny image.

use glam::Vec3;
use hilcam_core::render::bsdf::{Bsdf, ImprovedBlinnPhong, Lambert};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind};
use hilcam_core::render::sampling::Sequence;
use hilcam_core::scene::fold::FoldLevel;
use hilcam_core::scene::fold::disk::reference_disk;
use hilcam_lab::bench::sampling::PlaneCase;
use hilcam_lab::bench::table1::{Table1Config, run_table1};

const SIZE: u32 = 24;

/// Values of the pixels whose 3×3 neighbourhood lies on the disk (fully covered pixels).
fn interior(case: &PlaneCase, img: &RadianceImage) -> Vec<f64> {
    let n = SIZE as i32;
    let on = |c: i32, r: i32| (0..n).contains(&c) && (0..n).contains(&r) && case.mask[(r * n + c) as usize];
    let mut v = Vec::new();
    for r in 0..n {
        for c in 0..n {
            if (-1..=1).all(|dr| (-1..=1).all(|dc| on(c + dc, r + dr))) {
                v.push(f64::from(img.data[(r * n + c) as usize]));
            }
        }
    }
    v
}

fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// ∫ f_r(wo, wi) cosθi dωi for wo = +Z by the midpoint rule on a (θ, φ) grid: no
/// importance sampling, nothing shared with the renderer's samplers.
fn albedo_by_quadrature(bsdf: &Bsdf) -> f64 {
    let (nt, np) = (6000, 96);
    let (dt, dp) = (std::f64::consts::FRAC_PI_2 / nt as f64, std::f64::consts::TAU / np as f64);
    let wo = Vec3::Z;
    let mut s = 0.0;
    for i in 0..nt {
        let t = (i as f64 + 0.5) * dt;
        for j in 0..np {
            let p = (j as f64 + 0.5) * dp;
            let wi = Vec3::new((t.sin() * p.cos()) as f32, (t.sin() * p.sin()) as f32, t.cos() as f32).normalize();
            s += f64::from(bsdf.eval_cos(wo, wi)) * t.sin() * dt * dp;
        }
    }
    s
}

/// Flat plate under a uniform sky of radiance 1, sun off, seen along its normal: every
/// pixel's expected value is the directional albedo at θo = 0.
fn sky_case(bsdf: Bsdf) -> PlaneCase {
    let mut case = PlaneCase::new(reference_disk(), bsdf, 0.0, 10.0, SIZE);
    case.scene.background = 1.0;
    case
}

fn check_unbiased(bsdf: Bsdf, spp: u32) {
    let want = albedo_by_quadrature(&bsdf);
    let case = sky_case(bsdf);
    for sampler in [SamplerKind::Uniform, SamplerKind::Cosine, SamplerKind::Brdf] {
        let s = RenderSettings {
            spp: Spp::whole(spp),
            depth: 2,
            sampler,
            sequence: Sequence::Independent,
            roulette: false,
            adaptive: false,
            quality: hilcam_core::render::integrator::QualityGoal::FIXED,
            method: Default::default(),
            seed: 7,
        };
        let (img, _) = case.render(&s);
        let v = interior(&case, &img);
        assert!(v.len() > 250, "{}", v.len());
        let (m, se) = mean_se(&v);
        // 5 standard errors, plus 0.2 % for the f32 radiance sums and the quadrature.
        assert!((m - want).abs() < 5.0 * se + 2e-3 * want, "{sampler:?}: mean {m:.5} ± {se:.5}, quadrature {want:.5}");
    }
}

#[test]
fn gold_polyimide_paper_fit_all_samplers_unbiased() {
    check_unbiased(Bsdf::ImprovedBlinnPhong(ImprovedBlinnPhong::gold_polyimide()), 256);
}

#[test]
fn gold_polyimide_normalized_all_samplers_unbiased() {
    check_unbiased(Bsdf::ImprovedBlinnPhong(ImprovedBlinnPhong::gold_polyimide().normalized()), 256);
}

#[test]
fn cosine_is_exact_for_lambert_under_uniform_sky() {
    // f cosθ / pdf = ρ for every cosine sample: zero variance, where uniform has some.
    let case = sky_case(Bsdf::Lambert(Lambert::new(0.3717).unwrap()));
    let render = |sampler| {
        let s = RenderSettings {
            spp: Spp::whole(8),
            depth: 2,
            sampler,
            sequence: Sequence::Independent,
            roulette: false,
            adaptive: false,
            quality: hilcam_core::render::integrator::QualityGoal::FIXED,
            method: Default::default(),
            seed: 3,
        };
        mean_se(&interior(&case, &case.render(&s).0))
    };
    let (mc, sec) = render(SamplerKind::Cosine);
    assert!((mc - 0.3717).abs() < 1e-5 && sec < 1e-6, "{mc} ± {sec}");
    let (mu, seu) = render(SamplerKind::Uniform);
    assert!(seu > 1e-3 && (mu - 0.3717).abs() < 5.0 * seu, "{mu} ± {seu}");
}

#[test]
fn bench_sampling_runs_on_a_tiny_image() {
    let cfg = Table1Config {
        levels: vec![FoldLevel::Slight],
        size: 16,
        spps: vec![1, 64],
        ref_half_spp: 256,
        depth: 4,
        seed: 0,
        fold_seed: 0,
        sobol: false,
        sun: 100.0,
        sky: 0.0,
        out: None,
    };
    let res = run_table1(&cfg).unwrap();
    assert_eq!(res.len(), 1);
    let r = &res[0];
    assert_eq!(r.cells.len(), 6);
    for s in [SamplerKind::Uniform, SamplerKind::Cosine, SamplerKind::Brdf] {
        let at = |n| r.cells.iter().find(|c| c.sampler == s && c.spp == n).unwrap();
        // Monte Carlo: RMSE ∝ 1/√N, so 64× the samples cut it ~8× (reference noise aside).
        let ratio = at(1).rmse / at(64).rmse;
        assert!((4.0..12.0).contains(&ratio), "{s:?}: RMSE(1)/RMSE(64) = {ratio}");
        assert!(at(64).rmse > r.ref_noise, "{s:?}: below the reference's own noise");
    }
}
