//! The lab's sun-aligned shadow grid (`hilcam_lab::sun_shadow`) against the brute-force any-hit
//! test over every triangle (`geometry::bvh::brute_force::occluded`, the same obvhs
//! triangle test): identical answers on shadow rays logged from real renders of the
//! shipped satellite (its own sun, grazing on the solar wings, exactly in their plane,
//! along body axes), on origins of those renders with exact axis directions, and on
//! random triangle soups at millimetre and 10 km scales.

use glam::{DVec3, Vec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::geometry::bvh::brute_force;
use hilcam_core::render::geometry::spawn::TrianglePlane;
use hilcam_core::render::geometry::{Ray, TriMesh};
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::integrator::{RecordedRays, RenderSettings, SamplerKind};
use hilcam_core::render::sampling::Rng;
use hilcam_core::render::{FrameBuffers, RenderOptions, render_into};
use hilcam_core::scene::Scene;
use hilcam_lab::sun_shadow::SunShadow;
use rayon::prelude::*;
use std::sync::OnceLock;

fn satellite() -> &'static Scene {
    static S: OnceLock<Scene> = OnceLock::new();
    S.get_or_init(|| hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap())
}

fn small_camera(scene: &Scene, w: u32) -> CameraModel {
    let nav = &scene.camera;
    CameraModel {
        width: w,
        height: w,
        pitch_um: nav.pitch_um * f64::from(nav.width) / f64::from(w),
        focal_mm: nav.focal_mm,
        principal_point_px: [0.0, 0.0],
    }
}

/// Shadow rays of a small render at `pose` with the render-frame sun `sun_body`.
fn logged_shadow_rays(scene: &Scene, pose: &Pose, sun_body: DVec3, w: u32) -> (Vec3, Vec<Ray>) {
    let mut pose = *pose;
    pose.sun_dir = pose.attitude * sun_body.normalize();
    let cam = small_camera(scene, w);
    let settings = RenderSettings {
        spp: Spp::whole(2),
        depth: 3,
        sampler: SamplerKind::Cosine,
        roulette: false,
        ..Default::default()
    };
    let view = scene.view(&cam, &pose);
    let mut buffers = FrameBuffers::<RecordedRays>::default();
    let stats = render_into(&mut buffers, scene, &view, &RenderOptions::new(settings, 3));
    let rays: Vec<Ray> = buffers.take_ray_logs().into_iter().flat_map(|l| l.shadow).collect();
    assert_eq!(rays.len() as u64, stats.rays.shadow);
    (view.sun, rays)
}

/// About `n` rays spread evenly over `rays`.
fn subsample(rays: &[Ray], n: usize) -> Vec<Ray> {
    let step = rays.len().div_ceil(n).max(1);
    rays.iter().step_by(step).copied().collect()
}

/// Grid answer == brute force for every ray; returns (rays, occluded). Every ray must be
/// answered by the grid itself (no fallback), or the test would not test it.
fn check(mesh: &TriMesh, grid: &SunShadow, rays: &[Ray], case: &str) -> (usize, usize) {
    let bad: Vec<(usize, Option<bool>, bool)> = rays
        .par_iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let g = grid.occluded(r);
            let b = brute_force::occluded(mesh, r);
            (g != Some(b)).then_some((i, g, b))
        })
        .collect();
    assert!(
        bad.is_empty(),
        "{case}: {} of {} rays differ, first {:?}",
        bad.len(),
        rays.len(),
        &bad[..bad.len().min(5)]
    );
    let occluded = rays.iter().filter(|r| grid.occluded(r) == Some(true)).count();
    (rays.len(), occluded)
}

/// Unit normal of the largest solar-cell triangle (a wing's plane), render frame.
fn wing_normal(scene: &Scene) -> Vec3 {
    let solar = scene.materials.iter().position(|m| m.name == "solar_cell").unwrap() as u32;
    let i = (0..scene.mesh.indices.len())
        .filter(|&i| scene.mesh.material[i] == solar)
        .max_by(|&a, &b| scene.mesh.face_normal_area2(a).length().total_cmp(&scene.mesh.face_normal_area2(b).length()))
        .unwrap();
    scene.normals[i]
}

#[test]
fn satellite_rendered_shadow_rays_match_brute_force() {
    let scene = satellite();
    let n = wing_normal(scene).as_dvec3();
    let along = n.any_orthonormal_vector();
    let turned = Pose { attitude: glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.7, -1.1, 0.3), ..scene.pose };
    let cases = [
        ("scene pose and sun", scene.pose, scene.pose.attitude.inverse() * scene.pose.sun_dir),
        ("turned, sun 1e-3 rad above the wings", turned, along + n * 1e-3),
        ("sun in the wings' plane", scene.pose, along),
        ("sun along body +x", turned, DVec3::X),
        ("sun along body -z", scene.pose, DVec3::NEG_Z),
    ];
    for (name, pose, sun) in cases {
        let (s, rays) = logged_shadow_rays(scene, &pose, sun, 96);
        assert!(rays.len() > 100, "{name}: only {} shadow rays", rays.len());
        let grid = SunShadow::build(&scene.mesh, s);
        // Every logged ray against the BVH (fast), a subsample against brute force.
        let vs_bvh = rays.iter().filter(|r| grid.occluded(r) != Some(scene.accel.occluded(r))).count();
        assert_eq!(vs_bvh, 0, "{name}: differs from the BVH");
        let (tested, occ) = check(&scene.mesh, &grid, &subsample(&rays, 600), name);
        println!("{name}: {} rays, {tested} vs brute force, {occ} occluded; {:?}", rays.len(), grid.stats);
    }
}

#[test]
fn satellite_origins_with_exact_axis_directions_match_brute_force() {
    let scene = satellite();
    let (_, rays) = logged_shadow_rays(scene, &scene.pose, scene.pose.attitude.inverse() * scene.pose.sun_dir, 64);
    let origins = subsample(&rays, 400);
    let dirs = [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::new(1.0, 1.0, 0.0).normalize(), wing_normal(scene)];
    for s in dirs {
        let grid = SunShadow::build(&scene.mesh, s);
        let rays: Vec<Ray> = origins.iter().map(|r| Ray { origin: r.origin, dir: s, tmax: f32::INFINITY }).collect();
        let (tested, occ) = check(&scene.mesh, &grid, &rays, &format!("dir {s}"));
        assert!(occ > 0 && occ < tested, "dir {s}: {occ} of {tested} occluded (want a mix)");
    }
}

/// Random triangles in a cube of half-side `scale`: ordinary ones, slivers, ones with an
/// edge along `s`, ones containing `s`, and nearly edge-on ones.
fn soup(rng: &mut Rng, scale: f32, s: Vec3, n: usize) -> TriMesh {
    let mut r3 =
        |k: f32| Vec3::new(rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0) * k;
    let mut mesh = TriMesh::default();
    let t = s.any_orthonormal_vector();
    for i in 0..n {
        let p = r3(scale * 0.8);
        let size = scale * 0.1;
        let (a, b) = (r3(size), r3(size));
        let tri = match i % 6 {
            0 | 1 => [p, p + a, p + b],
            2 => [p, p + a, p + a * 1.001 + b * 1e-4],
            3 => [p, p + s * size, p + b],
            4 => [p, p + s * size, p + t * size],
            _ => [p, p + t * size + s * (size * 1e-5), p + s * size + t.cross(s) * (size * 1e-6)],
        };
        let base = mesh.positions.len() as u32;
        mesh.positions.extend_from_slice(&tri);
        mesh.indices.push([base, base + 1, base + 2]);
        mesh.material.push(0);
    }
    mesh
}

#[test]
fn random_soups_at_millimetre_and_10_km_scales_match_brute_force() {
    let mut rng = Rng::from_state(0x5eed);
    for scale in [1e-3f32, 1e4] {
        for round in 0..4 {
            let s = loop {
                let v = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5);
                if v.length() > 0.1 {
                    break v.normalize();
                }
            };
            let mesh = soup(&mut rng, scale, s, 1500);
            // Origins on triangles, offset off the surface as `PathContext` offsets them, to
            // either side.
            let rays: Vec<Ray> = (0..3000)
                .map(|_| {
                    let i = (rng.next_u32() as usize) % mesh.indices.len();
                    let [a, b, c] = mesh.triangle(i);
                    let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
                    if u + v > 1.0 {
                        (u, v) = (1.0 - u, 1.0 - v);
                    }
                    let p = a + (b - a) * u + (c - a) * v;
                    let face = mesh.face_normal_area2(i).normalize_or_zero();
                    let nrm = if rng.next_f32() < 0.5 { -face } else { face };
                    let origin = TrianglePlane::of(&mesh, i, face).spawn(p, face, nrm);
                    Ray { origin, dir: s, tmax: f32::INFINITY }
                })
                .collect();
            let grid = SunShadow::build(&mesh, s);
            let (tested, occ) = check(&mesh, &grid, &rays, &format!("scale {scale}, round {round}"));
            assert!(occ > 0 && occ < tested, "scale {scale}: {occ} of {tested} occluded (want a mix)");
            assert!(grid.stats.strips > 0, "the soup should contain nearly edge-on triangles");
        }
    }
}

#[test]
fn rays_the_grid_does_not_answer_fall_back() {
    let scene = satellite();
    let s = Vec3::new(0.3, -0.5, 0.8).normalize();
    let grid = SunShadow::build(&scene.mesh, s);
    let o = Vec3::new(0.01, 0.02, 0.03);
    // Another direction (one ulp off), an origin far outside the mesh, a non-finite origin.
    let off = Vec3::new(f32::from_bits(s.x.to_bits() + 1), s.y, s.z);
    assert_eq!(grid.occluded(&Ray { origin: o, dir: off, tmax: f32::INFINITY }), None);
    assert_eq!(grid.occluded(&Ray { origin: Vec3::splat(1e4), dir: s, tmax: f32::INFINITY }), None);
    assert_eq!(grid.occluded(&Ray { origin: Vec3::NAN, dir: s, tmax: f32::INFINITY }), None);
    // A finite tmax is honoured exactly like the brute-force test.
    let r = Ray { origin: o, dir: s, tmax: 0.5 };
    assert_eq!(grid.occluded(&r), Some(brute_force::occluded(&scene.mesh, &r)));
}
