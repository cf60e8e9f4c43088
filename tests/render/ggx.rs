//! The GGX models against answers computed here, independently of hilcam's code: the
//! white furnace of a conductor sphere (an f64 quadrature of the separable Smith GGX
//! BRDF written out below), a chi-square test of each sampler against its pdf with the
//! p-values printed, and the metal presets' normal-incidence reflectance.
//! `cargo test --test render ggx:: -- --nocapture` prints the measured numbers.

use crate::common;
use common::scenes::*;
use glam::{DVec3, Vec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::bsdf::{Bsdf, ConductorFresnel, Coupling, Ggx, Metal};
use hilcam_core::render::geometry::TriMesh;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::sampling::Rng;
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::Material;
use std::f64::consts::PI;

/// `f_r cosθi` of a white (F = 1) GGX conductor, separable Smith, in f64:
/// `D = 1/(π α² cos⁴θh (1 + tan²θh/α²)²)`, `Λ = (√(1 + α² tan²θ) − 1)/2`, `G1 = 1/(1 + Λ)`.
fn white_ggx_f_cos(alpha: f64, wo: DVec3, wi: DVec3) -> f64 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    let c2 = h.z * h.z;
    let tan2_h = (1.0 - c2) / c2;
    let d = 1.0 / (PI * alpha * alpha * c2 * c2 * (1.0 + tan2_h / (alpha * alpha)).powi(2));
    let g1 = |v: DVec3| {
        let tan2 = (1.0 - v.z * v.z) / (v.z * v.z);
        1.0 / (1.0 + 0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0))
    };
    d * g1(wo) * g1(wi) / (4.0 * wo.z * wi.z) * wi.z
}

/// Directional albedo `E(μo)` of the white conductor by midpoint quadrature in (cosθi, φi)
/// (the integrand is symmetric in φ: half the circle, doubled).
fn white_ggx_albedo(alpha: f64, mu_o: f64) -> f64 {
    let wo = DVec3::new((1.0 - mu_o * mu_o).sqrt(), 0.0, mu_o);
    let (nz, np) = (400, 400);
    let mut s = 0.0;
    for i in 0..nz {
        let z = (i as f64 + 0.5) / nz as f64;
        let r = (1.0 - z * z).sqrt();
        for j in 0..np {
            let phi = PI * (j as f64 + 0.5) / np as f64;
            s += white_ggx_f_cos(alpha, wo, DVec3::new(r * phi.cos(), r * phi.sin(), z));
        }
    }
    2.0 * s / nz as f64 * PI / np as f64
}

/// `E(μ)` on a grid of `n + 1` nodes in μ, for linear interpolation.
fn albedo_table(alpha: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|i| white_ggx_albedo(alpha, (i as f64 / n as f64).max(1e-4))).collect()
}

fn lerp_table(t: &[f64], mu: f64) -> f64 {
    let n = t.len() - 1;
    let x = mu.clamp(0.0, 1.0) * n as f64;
    let i = (x as usize).min(n - 1);
    t[i] + (x - i as f64) * (t[i + 1] - t[i])
}

/// The disc average over a smooth sphere seen from far away: `2∫ E(μ) μ dμ`.
fn disc_average(alpha: f64) -> f64 {
    let n = 200;
    let mut s = 0.0;
    for i in 0..n {
        let mu = (i as f64 + 0.5) / n as f64;
        s += white_ggx_albedo(alpha, mu) * mu;
    }
    2.0 * s / n as f64
}

fn white_conductor(alpha: f32) -> Bsdf {
    Bsdf::Ggx(Ggx::conductor(alpha.sqrt(), ConductorFresnel::Schlick { f0: 1.0 }).unwrap())
}

#[test]
fn white_furnace_of_a_smooth_sphere_is_the_issues_number() {
    // Issue 44: 0.689 at α 0.5 and 0.377 at α 1.0 with the separable form.
    for (alpha, want) in [(0.5, 0.689), (1.0, 0.377)] {
        let reference = disc_average(alpha);
        // hilcam's own BSDF, integrated by the same quadrature (its eval_cos) and by its
        // stratified visible-normal estimate (its sampler and pdf).
        let b = white_conductor(alpha as f32);
        let n = 200;
        let (mut by_eval, mut by_sampler) = (0.0, 0.0);
        for i in 0..n {
            let mu = (i as f64 + 0.5) / n as f64;
            let wo = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let (nz, np) = (200, 200);
            let mut e = 0.0;
            for zi in 0..nz {
                let z = (zi as f64 + 0.5) / nz as f64;
                let r = (1.0 - z * z).sqrt();
                for j in 0..np {
                    let phi = PI * (j as f64 + 0.5) / np as f64;
                    let wi = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                    e += f64::from(b.eval_cos(wo.as_vec3(), wi.as_vec3()));
                }
            }
            by_eval += 2.0 * e / nz as f64 * PI / np as f64 * mu;
            by_sampler += f64::from(b.directional_albedo(mu as f32, 4096)) * mu;
        }
        let (by_eval, by_sampler) = (2.0 * by_eval / n as f64, 2.0 * by_sampler / n as f64);
        eprintln!(
            "white GGX conductor sphere, α {alpha}: reference {reference:.5}, hilcam eval_cos {by_eval:.5}, \
             hilcam sampler {by_sampler:.5} (issue: {want})"
        );
        assert!((reference - want).abs() < 5e-4, "α {alpha}: reference {reference} vs the issue's {want}");
        assert!((by_eval - reference).abs() < 1e-3, "α {alpha}: {by_eval} vs {reference}");
        assert!((by_sampler - reference).abs() < 1e-3, "α {alpha}: {by_sampler} vs {reference}");
    }
}

/// A latitude–longitude sphere of radius `r` (`nl` bands, `2 nl` sectors), outward winding.
fn sphere(r: f32, nl: usize) -> TriMesh {
    let np = 2 * nl;
    let mut positions = Vec::new();
    for i in 0..=nl {
        let th = std::f32::consts::PI * i as f32 / nl as f32;
        for j in 0..np {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / np as f32;
            positions.push(Vec3::new(th.sin() * phi.cos(), th.sin() * phi.sin(), th.cos()) * r);
        }
    }
    let mut indices = Vec::new();
    for i in 0..nl {
        for j in 0..np {
            let (a, b) = ((i * np + j) as u32, (i * np + (j + 1) % np) as u32);
            let (c, d) = (a + np as u32, b + np as u32);
            if i > 0 {
                indices.push([a, c, b]);
            }
            if i + 1 < nl {
                indices.push([b, c, d]);
            }
        }
    }
    let n = indices.len();
    TriMesh { positions, indices, material: vec![0; n] }
}

#[test]
fn white_furnace_render_of_a_faceted_sphere_matches_quadrature() {
    // A white GGX conductor sphere under a sky of radiance 1, no sun, depth 2: each pixel
    // sees E(μ) of its facet. Σ over pixels of (1 − L) is Σ_f (1 − E(μ_f)) × the facet's
    // projected area in pixels, so the disc average of E is 1 − that sum / the disc's
    // projected area — both from the mesh, E from the f64 quadrature above.
    let (range, f_px) = (200.0f64, 20_000.0f64); // 2 m across = 200 px
    let cam = camera(256, 256, 5.0, 100.0);
    let mesh = sphere(1.0, 48);
    for (alpha, sampler) in [(0.5f32, SamplerKind::Brdf), (1.0, SamplerKind::Brdf), (0.5, SamplerKind::Cosine)] {
        let settings = RenderSettings { spp: Spp::whole(32), depth: 2, sampler, seed: 3, ..Default::default() };
        let mat = Material::new("white", white_conductor(alpha));
        let mut s = scene(mesh.clone(), vec![mat], cam.clone(), Pose::ahead(range), settings);
        s.sun_irradiance = 0.0;
        s.background = 1.0;
        let (img, stats) = render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 0));
        assert_eq!(stats.rays.nonfinite, 0);
        let table = albedo_table(f64::from(alpha), 400);
        let camera_body = DVec3::new(0.0, 0.0, -range); // identity attitude: body = camera axes
        let (mut area, mut dark) = (0.0f64, 0.0f64);
        for t in 0..mesh.indices.len() {
            let [a, b, c] = mesh.triangle(t).map(|v| v.as_dvec3());
            let centre = (a + b + c) / 3.0;
            // Outward, whatever the winding (surfaces are two-sided).
            let cross = (b - a).cross(c - a) * (b - a).cross(c - a).dot(centre).signum();
            let to_cam = camera_body - centre;
            let mu = cross.normalize().dot(to_cam.normalize());
            if mu <= 0.0 {
                continue;
            }
            let w = 0.5 * cross.length() * mu * (f_px / to_cam.length()).powi(2);
            area += w;
            dark += w * (1.0 - lerp_table(&table, mu));
        }
        let reference = 1.0 - dark / area;
        let measured = 1.0 - img.data.iter().map(|&v| 1.0 - f64::from(v)).sum::<f64>() / area;
        eprintln!(
            "faceted sphere α {alpha} {sampler:?}: rendered disc average {measured:.5}, quadrature {reference:.5}"
        );
        assert!((measured - reference).abs() < 1.5e-3, "α {alpha} {sampler:?}: {measured} vs {reference}");
    }
}

/// Regularised upper incomplete gamma `Q(a, x)` (Numerical Recipes' series and continued
/// fraction): the chi-square p-value is `Q(dof/2, χ²/2)`.
fn gamma_q(a: f64, x: f64) -> f64 {
    let ln_gamma = |z: f64| {
        // Lanczos (g = 7, n = 9).
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
        let z = z - 1.0;
        let t = z + 7.5;
        let s: f64 = C[0] + (1..9).map(|i| C[i] / (z + i as f64)).sum::<f64>();
        0.5 * (2.0 * PI).ln() + (z + 0.5) * t.ln() - t + s.ln()
    };
    if x < a + 1.0 {
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - ln_gamma(a)).exp()
    } else {
        let tiny = 1e-300;
        let (mut b, mut c, mut d) = (x + 1.0 - a, 1.0 / tiny, 1.0 / (x + 1.0 - a));
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - ln_gamma(a)).exp() * h
    }
}

#[test]
fn gamma_q_matches_known_chi_square_quantiles() {
    // χ² upper 5 % points: dof 1 → 3.841, dof 10 → 18.307, dof 100 → 124.342.
    for (dof, x) in [(1.0, 3.841_459), (10.0, 18.307_038), (100.0, 124.342_113)] {
        let p = gamma_q(dof / 2.0, x / 2.0);
        assert!((p - 0.05).abs() < 1e-5, "dof {dof}: {p}");
    }
}

/// χ² of `sample` against `pdf` over half-vector bins (s = (θh/(π/2))^⅓ × φh, so narrow
/// lobes spread over many bins), expected counts by quadrature of `pdf` (12 × 12 nodes per
/// bin, Jacobian `4 wo·h`); cells expected below 5 are pooled (pbrt does the same), "no
/// sample" is one more cell. Returns (χ², dof, p).
fn chi_square(b: &Bsdf, wo: Vec3, n_samples: usize, seed: u64) -> (f64, usize, f64) {
    const NS: usize = 24;
    const NP: usize = 24;
    const SUB: usize = 12;
    let wo64 = wo.as_dvec3();
    // ∫ pdf dω over the h-space rectangle [s0, s1] × [p0, p1], `n × n` midpoints (s as above).
    let cell = |s0: f64, s1: f64, p0: f64, p1: f64, n: usize| {
        let mut sum = 0.0;
        for i in 0..n {
            let s = s0 + (s1 - s0) * (i as f64 + 0.5) / n as f64;
            let thh = 0.5 * PI * s.powi(3);
            let dth = 1.5 * PI * s * s * (s1 - s0) / n as f64;
            for j in 0..n {
                let phi = p0 + (p1 - p0) * (j as f64 + 0.5) / n as f64;
                let h = DVec3::new(thh.sin() * phi.cos(), thh.sin() * phi.sin(), thh.cos());
                let d = wo64.dot(h);
                let wi = 2.0 * d * h - wo64;
                if d <= 0.0 || wi.z <= 0.0 {
                    continue;
                }
                let dw = thh.sin() * dth * (p1 - p0) / n as f64 * 4.0 * d;
                sum += f64::from(b.pdf(wo, wi.normalize().as_vec3())) * dw;
            }
        }
        sum
    };
    // Whether h at (s, φ) reflects wo above the horizon.
    let above = |s: f64, phi: f64| {
        let thh = 0.5 * PI * s.powi(3);
        let h = DVec3::new(thh.sin() * phi.cos(), thh.sin() * phi.sin(), thh.cos());
        let d = wo64.dot(h);
        d > 0.0 && (2.0 * d * h - wo64).z > 0.0
    };
    let mut expected = vec![0.0f64; NS * NP];
    let (ds, dp) = (1.0 / (NS * SUB) as f64, 2.0 * PI / (NP * SUB) as f64);
    for i in 0..NS * SUB {
        for j in 0..NP * SUB {
            let (s0, p0) = (i as f64 * ds, j as f64 * dp);
            let corners = [(s0, p0), (s0 + ds, p0), (s0, p0 + dp), (s0 + ds, p0 + dp)].map(|(s, p)| above(s, p));
            // Sub-cells the horizon crosses get a 16 × 16 quadrature: a midpoint alone
            // would count or drop the whole sub-cell.
            let n = if corners.iter().all(|&c| c == corners[0]) { 1 } else { 16 };
            expected[(i / SUB) * NP + j / SUB] += cell(s0, s0 + ds, p0, p0 + dp, n);
        }
    }
    let mut observed = vec![0.0f64; NS * NP];
    let mut none = 0usize;
    let mut rng = Rng::from_state(seed);
    for _ in 0..n_samples {
        match b.sample(wo, rng.next_2d(), rng.next_f32()) {
            Some(s) => {
                let h = wo64 + s.wi.as_dvec3();
                let thh = h.x.hypot(h.y).atan2(h.z);
                let si = ((thh / (0.5 * PI)).cbrt() * NS as f64).min(NS as f64 - 1.0) as usize;
                let pj = ((h.y.atan2(h.x).rem_euclid(2.0 * PI) / (2.0 * PI)) * NP as f64).min(NP as f64 - 1.0) as usize;
                observed[si * NP + pj] += 1.0;
            }
            None => none += 1,
        }
    }
    let total_e: f64 = expected.iter().sum();
    let mut cells: Vec<(f64, f64)> = expected.iter().map(|e| e * n_samples as f64).zip(observed).collect();
    cells.push(((1.0 - total_e).max(0.0) * n_samples as f64, none as f64));
    let (mut chi2, mut dof, mut pool_e, mut pool_o) = (0.0, 0usize, 0.0, 0.0);
    for (e, o) in cells {
        if e < 5.0 {
            pool_e += e;
            pool_o += o;
            continue;
        }
        chi2 += (o - e) * (o - e) / e;
        dof += 1;
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e.max(1.0);
        dof += 1;
    }
    let dof = (dof - 1).max(1);
    (chi2, dof, gamma_q(dof as f64 / 2.0, chi2 / 2.0))
}

fn ggx_cases() -> Vec<(&'static str, Bsdf)> {
    vec![
        (
            "conductor Au r0.2",
            Bsdf::Ggx(Ggx::conductor(0.2, ConductorFresnel::Complex { n: 0.3804, k: 2.4792 }).unwrap()),
        ),
        ("conductor white α0.5", white_conductor(0.5)),
        ("conductor white α1", white_conductor(1.0)),
        ("plastic r0.3 ρ0.5", Bsdf::Ggx(Ggx::plastic(0.3, 0.5, 1.5).unwrap())),
        ("plastic r0.8 ρ0.9 η2", Bsdf::Ggx(Ggx::plastic(0.8, 0.9, 2.0).unwrap())),
        ("metallic 0.5 r0.4", Bsdf::Ggx(Ggx::metallic_roughness(0.7, 0.5, 0.4).unwrap())),
    ]
}

#[test]
fn ggx_samplers_match_their_pdf_chi_square() {
    let angles = [0.0f64, 45.0, 80.0];
    let cases: Vec<(&str, Bsdf, f64)> =
        ggx_cases().into_iter().flat_map(|(n, b)| angles.map(move |t| (n, b, t))).collect();
    // 1 % overall significance, Šidák-corrected over the cases (as bsdf.rs).
    let alpha = 1.0 - (1.0f64 - 0.01).powf(1.0 / cases.len() as f64);
    for (k, (name, b, th)) in cases.into_iter().enumerate() {
        let t = th.to_radians();
        let wo = DVec3::new(t.sin(), 0.0, t.cos()).as_vec3();
        let (chi2, dof, p) = chi_square(&b, wo, 500_000, 1000 + k as u64);
        eprintln!("χ² {name:<22} θo {th:>4}: χ² = {chi2:8.1}, dof {dof:4}, p = {p:.3}");
        assert!(p > alpha, "{name} θo {th}: χ² {chi2:.1} (dof {dof}), p = {p:.2e} < {alpha:.2e}");
    }
}

#[test]
fn reciprocal_and_never_more_than_one() {
    let mut rng = Rng::from_state(77);
    for (name, b) in ggx_cases() {
        for _ in 0..20_000 {
            let wo = hilcam_core::render::sampling::uniform_hemisphere(rng.next_2d());
            let wi = hilcam_core::render::sampling::uniform_hemisphere(rng.next_2d());
            let (f1, f2) = (b.eval(wo, wi), b.eval(wi, wo));
            assert!((f1 - f2).abs() <= 1e-4 * f1.abs().max(1e-3), "{name}: {f1} vs {f2}");
        }
        for th in [0.0f64, 30.0, 60.0, 80.0, 89.0] {
            let mu = th.to_radians().cos() as f32;
            let a = b.directional_albedo(mu, 65_536);
            assert!(a <= 1.0 + 1e-3, "{name} θo {th}: albedo {a}");
        }
    }
    // A white base under the coating gives back exactly what the coating lets through:
    // the plastic's white furnace is 1 at every angle (the coupling's normalisation).
    let white = Bsdf::Ggx(Ggx::plastic(0.5, 1.0, 1.5).unwrap());
    for th in [0.0f64, 45.0, 75.0] {
        let a = white.directional_albedo(th.to_radians().cos() as f32, 65_536);
        assert!((a - 1.0).abs() < 2e-3, "white plastic θo {th}: {a}");
    }
    // In Mitsuba's coupling the same white plastic returns what Mitsuba 3.9.1's
    // roughplastic returns under a white furnace (α 0.25, η 1.5): its own `eval` over a
    // 512² cosine-stratified grid, 0.7407 / 0.7338 / 0.7049 at θo = 0° / 45° / 75°
    // (docs/brdf.md, "Plastic").
    let mitsuba = Bsdf::Ggx(Ggx::plastic_coupled(0.5, 1.0, 1.5, Coupling::Mitsuba).unwrap());
    for (th, want) in [(0.0f64, 0.7407f32), (45.0, 0.7338), (75.0, 0.7049)] {
        let a = mitsuba.directional_albedo(th.to_radians().cos() as f32, 65_536);
        eprintln!("white plastic, Mitsuba's coupling, θo {th}: albedo {a:.4} (Mitsuba {want})");
        assert!((a - want).abs() < 3e-3, "white plastic (Mitsuba's coupling) θo {th}: {a} vs {want}");
    }
}

#[test]
fn metal_presets_reflect_their_documented_f0() {
    // F0 = ((n − 1)² + k²)/((n + 1)² + k²), the numbers docs/brdf.md lists.
    for (m, f0) in [(Metal::Au, 0.811), (Metal::Al, 0.915), (Metal::Ag, 0.962), (Metal::Cu, 0.791)] {
        let [n, k] = m.nk();
        let (n, k) = (f64::from(n), f64::from(k));
        let want = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        assert!((want - f0).abs() < 1e-3, "{m:?}: {want}");
        // A mirror-smooth conductor at normal incidence reflects F0 of the light: its
        // albedo at θo = 0 tends to F0 as the roughness falls.
        let b = Bsdf::Ggx(Ggx::conductor(0.01, ConductorFresnel::Complex { n: n as f32, k: k as f32 }).unwrap());
        let a = f64::from(b.directional_albedo(1.0, 4096));
        assert!((a - want).abs() < 1e-3, "{m:?}: smooth albedo {a} vs F0 {want}");
    }
}

#[test]
fn ggx_matches_mitsuba_pointwise() {
    // Mitsuba 3.9.1's roughconductor / roughplastic (GGX, visible-normal sampling) at 60
    // direction pairs each, written by scripts/ggx_mitsuba_reference.py.
    let csv = include_str!("data/ggx_mitsuba.csv");
    let build = |case: &str| -> Bsdf {
        let c = |r: f32, m: Metal| {
            let [n, k] = m.nk();
            Bsdf::Ggx(Ggx::conductor(r, ConductorFresnel::Complex { n, k }).unwrap())
        };
        match case {
            "conductor_au_a0.09" => c(0.3, Metal::Au),
            "conductor_al_a0.5" => c(0.5f32.sqrt(), Metal::Al),
            "conductor_ag_a1" => c(1.0, Metal::Ag),
            "plastic_spec_a0.25" => Bsdf::Ggx(Ggx::plastic(0.5, 0.0, 1.5).unwrap()),
            // Mitsuba's diffuse coupling (docs/brdf.md, "Plastic"): compared in full.
            "plastic_rho0.5_a0.25" => Bsdf::Ggx(Ggx::plastic_coupled(0.5, 0.5, 1.5, Coupling::Mitsuba).unwrap()),
            // hilcam's default coupling at the same points: the difference is printed.
            "plastic_rho0.5_a0.25 (energy coupling)" => Bsdf::Ggx(Ggx::plastic(0.5, 0.5, 1.5).unwrap()),
            _ => panic!("unknown case {case}"),
        }
    };
    let mut worst: Vec<(String, f64, f64)> = Vec::new();
    let energy = |l: &str| {
        l.strip_prefix("plastic_rho0.5_a0.25,").map(|r| format!("plastic_rho0.5_a0.25 (energy coupling),{r}"))
    };
    let lines: Vec<String> =
        csv.lines().skip(1).flat_map(|l| std::iter::once(l.to_string()).chain(energy(l))).collect();
    for line in &lines {
        let w: Vec<&str> = line.split(',').collect();
        let v: Vec<f64> = w[1..].iter().map(|x| x.parse().unwrap()).collect();
        let wo = DVec3::new(v[0], v[1], v[2]).as_vec3();
        let wi = DVec3::new(v[3], v[4], v[5]).as_vec3();
        let b = build(w[0]);
        let f = f64::from(b.eval_cos(wo, wi));
        let p = f64::from(b.pdf(wo, wi));
        let rel = |a: f64, r: f64| (a - r).abs() / r.abs().max(1e-6);
        let (ef, ep) = (rel(f, v[6]), rel(p, v[7]));
        match worst.iter_mut().find(|(c, ..)| c == w[0]) {
            Some(e) => {
                e.1 = e.1.max(ef);
                e.2 = e.2.max(ep);
            }
            None => worst.push((w[0].to_string(), ef, ep)),
        }
    }
    for (case, ef, ep) in &worst {
        eprintln!("vs Mitsuba {case:<22}: largest relative difference f·cos {ef:.2e}, pdf {ep:.2e}");
    }
    // The default (energy) coupling's diffuse term is not Mitsuba's (docs/brdf.md:
    // Mitsuba's is 25–43 % lower here and returns ~73 % of a white furnace): printed only.
    // With `coupling = "mitsuba"` the whole plastic is compared; its tables are computed
    // by a different quadrature than Mitsuba's (hence the looser bound).
    for (case, ef, ep) in &worst {
        if case.starts_with("conductor") || case == "plastic_spec_a0.25" {
            assert!(*ef < 1e-4, "{case}: f·cos differs from Mitsuba by {ef:e}");
        }
        if case == "plastic_rho0.5_a0.25" {
            assert!(*ef < 2e-3, "{case}: f·cos differs from Mitsuba by {ef:e}");
        }
        if case.starts_with("conductor") {
            assert!(*ep < 1e-4, "{case}: pdf differs from Mitsuba by {ep:e}");
        }
    }
}
