//! The hybrid method's body-frame cache of diffuse indirect light against independent
//! answers: a furnace (every bounce escapes to a uniform background: the cache returns
//! it exactly), a plate lit only by the light a sunlit plate beside it reflects
//! (Lambert's polygon formula), and a glossy plate whose lobe is path-traced beside the
//! cached diffuse part (the path tracer's mean). Frames stay the same bytes whatever the
//! frame index (a Lambert target has no per-frame noise left) and follow the seed.

use crate::common;
use common::scenes::*;
use glam::DVec3;
use hilcam_core::pose::Pose;
use hilcam_core::render::bsdf::BsdfSpec;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::geometry::{BvhLayout, TriMesh};
use hilcam_core::render::integrator::{Method, RenderSettings, SamplerKind, Spp};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::{Material, Scene, SceneParts};
use std::f64::consts::PI;

const E: f64 = 593.1;

fn settings(method: Method, spp: u32, depth: u32, seed: u64) -> RenderSettings {
    RenderSettings {
        method,
        spp: Spp::whole(spp),
        depth,
        seed,
        sampler: SamplerKind::Brdf,
        adaptive: false,
        ..Default::default()
    }
}

fn with_background(mesh: TriMesh, materials: Vec<Material>, cam: &CameraModel, pose: Pose, background: f64) -> Scene {
    Scene::build(SceneParts {
        sensor: Default::default(),
        mesh,
        materials,
        sun_irradiance: E,
        background,
        camera: cam.clone(),
        pose,
        render: settings(Method::Hybrid, 1, 2, 1),
        layout: BvhLayout::Bvh2,
        stars: None,
        planet: None,
        limits: Default::default(),
        texturing: None,
    })
}

fn frame(s: &Scene, cam: &CameraModel, set: RenderSettings, index: u64) -> RadianceImage {
    render(s, &s.view(cam, &s.pose), &RenderOptions::new(set, index)).0
}

fn material(name: &str, spec: &str) -> Material {
    Material::new(name, toml::from_str::<BsdfSpec>(spec).unwrap().build().unwrap())
}

#[test]
fn in_a_furnace_the_cache_returns_the_albedo_times_the_background() {
    // A Lambert plate (ρ 0.6) filling the view, the sun behind it, under a uniform
    // background of radiance 2: every bounce escapes, so each pixel is ρ × 2 at any depth.
    let cam = camera(32, 32, 20.0, 40.0);
    let pose = Pose { sun_dir: DVec3::new(0.0, 0.3, 1.0).normalize(), ..Pose::ahead(3.0) };
    let s = with_background(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.6)], &cam, pose, 2.0);
    for depth in [2, 3] {
        let img = frame(&s, &cam, settings(Method::Hybrid, 1, depth, 5), 0);
        for &v in &img.data {
            assert!((v - 1.2).abs() <= 1.2 * 1e-6, "depth {depth}: {v} ≠ 1.2");
        }
    }
}

/// Plate B (z = 0, 1 m, facing the camera 4 m away, its front away from the sun) and
/// plate A (y = −0.6, 1 m × 1 m from z = −0.1 to −1.1, out of view) lit by the sun at
/// 2.9° from its normal; B's front is lit only by what A reflects. Returns the scene, the
/// camera (64², 250 px focal length: B fills 62 px) and A's corners.
fn lit_neighbour(b_spec: &str) -> (Scene, CameraModel, [DVec3; 4]) {
    let a = [
        DVec3::new(-0.5, -0.6, -0.1),
        DVec3::new(0.5, -0.6, -0.1),
        DVec3::new(0.5, -0.6, -1.1),
        DVec3::new(-0.5, -0.6, -1.1),
    ];
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    let base = mesh.positions.len() as u32;
    mesh.positions.extend(a.iter().map(|v| v.as_vec3()));
    mesh.indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    mesh.material.extend([1, 1]);
    let cam = camera(64, 64, 40.0, 10.0);
    let pose = Pose { sun_dir: DVec3::new(0.0, 1.0, 0.05).normalize(), ..Pose::ahead(4.0) };
    let materials = vec![material("b", b_spec), lambert("a", 0.9)];
    (with_background(mesh, materials, &cam, pose, 0.0), cam, a)
}

/// The central 48 × 48 pixels (all on plate B) and the point of B each pixel centre sees.
fn inner(img: &RadianceImage) -> Vec<(f64, DVec3)> {
    let mut v = Vec::new();
    for row in 8..56u32 {
        for col in 8..56u32 {
            let d = DVec3::new((f64::from(col) + 0.5 - 32.0) / 250.0, (f64::from(row) + 0.5 - 32.0) / 250.0, 1.0);
            v.push((f64::from(img.get(col, row)), DVec3::new(4.0 * d.x, 4.0 * d.y, 0.0)));
        }
    }
    v
}

#[test]
fn a_plate_lit_by_its_sunlit_neighbour_matches_lambert_s_polygon_formula() {
    let (s, cam, a) = lit_neighbour("model = \"lambert\"\nrho = 0.8");
    let img = frame(&s, &cam, settings(Method::Hybrid, 1, 2, 3), 0);
    let l_a = 0.9 * E * s.pose.sun_dir.normalize().y / PI;
    let (mut got, mut want, mut sq) = (0.0, 0.0, 0.0);
    let px = inner(&img);
    for &(v, p) in &px {
        let w = 0.8 / PI * l_a * polygon_irradiance(p, DVec3::NEG_Z, &a);
        (got, want, sq) = (got + v, want + w, sq + ((v - w) / w).powi(2));
    }
    let n = px.len() as f64;
    let (mean_err, rms) = ((got - want) / want, (sq / n).sqrt());
    println!("mean {:.5} (want {:.5}), mean error {mean_err:+.5}, rms {rms:.5}", got / n, want / n);
    // Each cell's estimate is 256 stratified paths that see A or not: ≈ 5 % rms here,
    // independent from cell to cell, so the mean over 2 304 pixels (≈ 1 cell each) is
    // ~0.1 %; a cell is 7 mm across, where the irradiance changes by < 1 % per cm.
    assert!(mean_err.abs() < 3e-3, "mean error {mean_err}");
    assert!(rms < 0.08, "per-pixel rms error {rms}");
}

#[test]
fn a_glossy_plate_s_cached_diffuse_part_and_path_traced_lobe_average_to_the_path_tracer() {
    let spec = "model = \"blinn_phong\"\nrho_d = 0.3\nrho_s = 1.0\nalpha = 8.0\nnormalized = true";
    let (s, cam, _) = lit_neighbour(spec);
    let mean = |img: &RadianceImage| inner(img).iter().map(|p| p.0).sum::<f64>() / 2304.0;
    // Means over seeds and their standard errors (the frames' own spread).
    let over = |method: Method, spp: u32, seeds: u64| {
        let m: Vec<f64> = (0..seeds).map(|seed| mean(&frame(&s, &cam, settings(method, spp, 2, seed), 0))).collect();
        let mu = m.iter().sum::<f64>() / m.len() as f64;
        let var = m.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / (m.len() - 1) as f64;
        (mu, (var / m.len() as f64).sqrt())
    };
    let (hybrid, se_h) = over(Method::Hybrid, 4, 8);
    let (path, se_p) = over(Method::Path, 128, 4);
    // Without the lobe the plate's mean: the cache alone must not account for it all.
    let lambert_only = {
        let (s, cam, _) = lit_neighbour("model = \"lambert\"\nrho = 0.3");
        mean(&frame(&s, &cam, settings(Method::Hybrid, 1, 2, 3), 0))
    };
    let z = (hybrid - path) / (se_h * se_h + se_p * se_p).sqrt();
    println!(
        "hybrid {hybrid:.5} ± {se_h:.5}, path {path:.5} ± {se_p:.5} ({z:+.2} σ), diffuse part alone {lambert_only:.5}"
    );
    assert!(hybrid > lambert_only * 1.5, "the lobe adds light: {hybrid} vs {lambert_only}");
    assert!(z.abs() < 4.0, "hybrid {hybrid} vs path-traced {path}: {z} σ");
    assert!((hybrid - path).abs() < 0.01 * path, "hybrid {hybrid} vs path-traced {path}");
}

#[test]
fn a_lambert_target_s_frames_follow_the_seed_not_the_frame_index() {
    let (s, cam, _) = lit_neighbour("model = \"lambert\"\nrho = 0.8");
    let bytes = |img: RadianceImage| img.data.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    let a = bytes(frame(&s, &cam, settings(Method::Hybrid, 1, 2, 3), 0));
    assert_eq!(a, bytes(frame(&s, &cam, settings(Method::Hybrid, 1, 2, 3), 9)));
    assert_ne!(a, bytes(frame(&s, &cam, settings(Method::Hybrid, 1, 2, 4), 0)));
}
