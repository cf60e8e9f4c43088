//! The hybrid cache's caustics against independent answers: a near-mirror reflecting the
//! sun onto a Lambert plate that the sun does not reach (a second sun whose irradiance is
//! the mirror's directional albedo, integrated here by quadrature of its BRDF), and a
//! rough mirror against the path tracer's mean. Frames stay the same bytes for any thread
//! count (the photons' flux sums do not depend on the order threads add them).

use crate::common;
use common::scenes::*;
use glam::{DVec3, Vec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::bsdf::{Bsdf, BsdfSpec};
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::geometry::BvhLayout;
use hilcam_core::render::integrator::{Method, RenderSettings, SamplerKind, Spp};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::{Material, Scene, SceneParts};
use std::f64::consts::PI;

const E: f64 = 593.1;

fn settings(method: Method, spp: u32, seed: u64) -> RenderSettings {
    RenderSettings {
        method,
        spp: Spp::whole(spp),
        depth: 2,
        seed,
        sampler: SamplerKind::Brdf,
        adaptive: false,
        ..Default::default()
    }
}

fn bsdf(spec: &str) -> Bsdf {
    toml::from_str::<BsdfSpec>(spec).unwrap().build().unwrap()
}

/// Half the mirror's side, m.
const HALF: f64 = 0.35;

/// The mirror's geometry: centre, normal, and the unit direction it sends the sun in.
struct Mirror {
    centre: DVec3,
    normal: DVec3,
    beam: DVec3,
    sun: DVec3,
    /// Two unit edges of the square.
    edges: [DVec3; 2],
}

fn mirror() -> Mirror {
    let sun = DVec3::new(0.0, 1.0, 0.05).normalize();
    let centre = DVec3::new(-1.5, 0.0, -1.5);
    // Toward plate B's centre; the mirror's normal halves the sun and the beam.
    let beam = (DVec3::ZERO - centre).normalize();
    let normal = (sun + beam).normalize();
    let e1 = DVec3::Y.cross(normal).normalize();
    Mirror { centre, normal, beam, sun, edges: [e1, normal.cross(e1)] }
}

/// Plate B (z = 0, 1 m, facing the camera 4 m away; the sun, nearly overhead, does not
/// reach its front) and a 0.7 m mirror 2.1 m off to the side, out of view, turned to send
/// the sun onto B's middle. Camera 64², 250 px focal length (B fills 62 px).
fn mirror_scene(mirror_spec: &str) -> (Scene, CameraModel) {
    let m = mirror();
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    let base = mesh.positions.len() as u32;
    let [e1, e2] = m.edges;
    for (a, b) in [(-HALF, -HALF), (HALF, -HALF), (HALF, HALF), (-HALF, HALF)] {
        mesh.positions.push((m.centre + e1 * a + e2 * b).as_vec3());
    }
    mesh.indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    mesh.material.extend([1, 1]);
    let cam = camera(64, 64, 40.0, 10.0);
    let pose = Pose { sun_dir: m.sun, ..Pose::ahead(4.0) };
    let materials = vec![lambert("b", 0.8), Material::new("mirror", bsdf(mirror_spec))];
    let scene = Scene::build(SceneParts {
        sensor: Default::default(),
        mesh,
        materials,
        sun_irradiance: E,
        background: 0.0,
        camera: cam.clone(),
        pose,
        render: settings(Method::Hybrid, 1, 1),
        layout: BvhLayout::Bvh2,
        stars: None,
        planet: None,
        limits: Default::default(),
        texturing: None,
    });
    (scene, cam)
}

fn frame(s: &Scene, cam: &CameraModel, set: RenderSettings) -> RadianceImage {
    render(s, &s.view(cam, &s.pose), &RenderOptions::new(set, 0)).0
}

/// Pixels on B (the central 56 × 56) with the point of B each pixel centre sees.
fn on_b() -> Vec<(u32, u32, DVec3)> {
    let mut v = Vec::new();
    for row in 4..60u32 {
        for col in 4..60u32 {
            let d = DVec3::new((f64::from(col) + 0.5 - 32.0) / 250.0, (f64::from(row) + 0.5 - 32.0) / 250.0, 1.0);
            v.push((col, row, DVec3::new(4.0 * d.x, 4.0 * d.y, 0.0)));
        }
    }
    v
}

/// Whether the beam reaching B at `p` left the mirror at least `margin` inside its edges.
fn inside_beam(m: &Mirror, p: DVec3, margin: f64) -> bool {
    let t = (m.centre - p).dot(m.normal) / (-m.beam).dot(m.normal);
    let q = p - m.beam * t - m.centre;
    m.edges.iter().all(|e| q.dot(*e).abs() <= HALF - margin)
}

/// ∫ f_r(wo, wi) cosθi dωi of `b` for light from `wo` (local), by quadrature on a polar
/// grid around the mirror direction out to `theta_max` (the lobe is negligible beyond).
fn lobe_albedo(b: &Bsdf, wo: Vec3, theta_max: f64) -> f64 {
    let (n_theta, n_phi) = (1200, 360);
    let axis = DVec3::new(-f64::from(wo.x), -f64::from(wo.y), f64::from(wo.z));
    let t1 = DVec3::Z.cross(axis).normalize();
    let t2 = axis.cross(t1);
    let (d_theta, d_phi) = (theta_max / f64::from(n_theta), 2.0 * PI / f64::from(n_phi));
    let mut sum = 0.0;
    for i in 0..n_theta {
        let theta = (f64::from(i) + 0.5) * d_theta;
        for j in 0..n_phi {
            let phi = (f64::from(j) + 0.5) * d_phi;
            let wi = axis * theta.cos() + (t1 * phi.cos() + t2 * phi.sin()) * theta.sin();
            if wi.z > 0.0 {
                // f_r(wi, wo)·cosθwi: the radiance toward wi per unit of the sun's
                // irradiance on the mirror, times the cosine of leaving (the models are
                // not reciprocal: the direction toward the light is the second argument).
                let f = f64::from(b.eval_cos(wi.as_vec3(), wo)) / f64::from(wo.z);
                sum += f * wi.z * theta.sin() * d_theta * d_phi;
            }
        }
    }
    sum
}

const SHARP: &str = "model = \"blinn_phong\"\nrho_d = 0.0\nrho_s = 0.9\nalpha = 20000.0\nnormalized = true";

#[test]
fn a_near_mirror_lights_a_plate_with_its_albedo_times_the_sun() {
    let m = mirror();
    let (s, cam) = mirror_scene(SHARP);
    let img = frame(&s, &cam, settings(Method::Hybrid, 1, 7));
    // The mirror's albedo for the sun, in its own frame (z along its normal).
    let z = m.normal;
    let x = m.edges[0];
    let y = z.cross(x);
    let wo = DVec3::new(m.sun.dot(x), m.sun.dot(y), m.sun.dot(z)).as_vec3();
    let albedo = lobe_albedo(&bsdf(SHARP), wo, 0.15);
    // A second sun of irradiance E·albedo along the beam, on B's front (normal −z).
    let want = 0.8 / PI * E * albedo * m.beam.z;
    let (mut n, mut sum, mut sq) = (0usize, 0.0, 0.0);
    for (col, row, p) in on_b() {
        if !inside_beam(&m, p, 0.1) {
            continue;
        }
        let v = f64::from(img.get(col, row));
        (n, sum, sq) = (n + 1, sum + v, sq + ((v - want) / want).powi(2));
    }
    let (mean_err, rms) = (sum / n as f64 / want - 1.0, (sq / n as f64).sqrt());
    println!(
        "albedo {albedo:.5}; {n} pixels: mean {:.4} (want {want:.4}), error {mean_err:+.5}, rms {rms:.4}",
        sum / n as f64
    );
    assert!(n > 500, "{n} pixels in the beam's interior");
    assert!(mean_err.abs() < 5e-3, "mean error {mean_err}");
    assert!(rms < 0.05, "per-pixel rms error {rms}");
    // Beyond the beam's edges by more than its blur (the lobe's core is ~0.03 rad, 6 cm
    // at 2.1 m; a caustic cell is 2 cm) only the lobe's faint tail reaches B's front.
    let dark: Vec<f64> = on_b()
        .into_iter()
        .filter(|&(_, _, p)| !inside_beam(&m, p, -0.15))
        .map(|(c, r, _)| f64::from(img.get(c, r)))
        .collect();
    let dark_mean = dark.iter().sum::<f64>() / dark.len().max(1) as f64;
    println!("{} pixels outside the beam: mean {dark_mean:.2e}", dark.len());
    assert!(dark.len() > 100 && dark_mean < 2e-3 * want, "light outside the beam: {dark_mean} of {want}");
}

#[test]
fn a_rough_mirror_s_caustic_averages_to_the_path_tracer() {
    let spec = "model = \"blinn_phong\"\nrho_d = 0.2\nrho_s = 0.9\nalpha = 100.0\nnormalized = true";
    let (s, cam) = mirror_scene(spec);
    let mean = |img: &RadianceImage| on_b().iter().map(|&(c, r, _)| f64::from(img.get(c, r))).sum::<f64>() / 3136.0;
    let over = |method: Method, spp: u32, seeds: u64| {
        let m: Vec<f64> = (0..seeds).map(|seed| mean(&frame(&s, &cam, settings(method, spp, seed)))).collect();
        let mu = m.iter().sum::<f64>() / m.len() as f64;
        let var = m.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / (m.len() - 1) as f64;
        (mu, (var / m.len() as f64).sqrt())
    };
    let (hybrid, se_h) = over(Method::Hybrid, 1, 6);
    let (path, se_p) = over(Method::Path, 256, 4);
    let z = (hybrid - path) / (se_h * se_h + se_p * se_p).sqrt();
    println!("hybrid {hybrid:.5} ± {se_h:.5}, path {path:.5} ± {se_p:.5} ({z:+.2} σ)");
    assert!(path > 0.0);
    assert!(z.abs() < 4.0, "hybrid {hybrid} vs path-traced {path}: {z} σ");
    assert!((hybrid - path).abs() < 0.01 * path, "hybrid {hybrid} vs path-traced {path}");
}

#[test]
fn caustic_frames_are_the_same_bytes_for_any_thread_count() {
    let (s, cam) = mirror_scene(SHARP);
    let bytes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let img = pool.install(|| frame(&s, &cam, settings(Method::Hybrid, 1, 3)));
        img.data.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()
    };
    assert_eq!(bytes(1), bytes(2));
    assert_eq!(bytes(2), bytes(3));
}
