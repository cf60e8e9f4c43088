//! Hit-local numerics (#44): shading of a body does not change when unrelated geometry far
//! away is added, and the shadows inside its creases are those of exact geometry.
//!
//! The body is a 1 m plate of 2 cm V-grooves (45° walls), lit at 60° incidence across the
//! grooves. Independent answer: a wall facing the sun sees it at cos 15°; the opposite
//! ridge shades the part of it below `tan 15°` of its width (the sun rises at 30° above
//! the plate, the walls at 45°: the boundary is where the ray toward the sun clears the
//! next ridge); the other wall faces away. Seen from along the normal each wall covers
//! half the plate, so at depth 1 the plate's mean radiance is
//! `ρE/π · cos 15° · (1 − tan 15°) / 2`.

use crate::common;
use common::scenes::*;
use glam::{DVec3, Vec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::{CameraModel, PixelRect};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::geometry::{BvhLayout, TriMesh};
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::{Scene, SceneParts};

const E: f64 = 593.1;
const RHO: f32 = 0.5;
/// Groove period and depth (m): 45° walls.
const PERIOD: f32 = 0.02;

/// The grooved plate: x, y ∈ [−0.5, 0.5], grooves along y, ridges at z = −PERIOD/2 (toward
/// the camera and the sun, which sit on the −z side), valleys at z = 0.
fn grooved_plate() -> TriMesh {
    let n = (1.0 / PERIOD).round() as u32;
    let mut m = TriMesh::default();
    let depth = PERIOD * 0.5;
    for i in 0..n {
        let x0 = -0.5 + i as f32 * PERIOD;
        let (ridge_a, valley, ridge_b) = (x0, x0 + PERIOD * 0.5, x0 + PERIOD);
        for (xa, za, xb, zb) in [(ridge_a, -depth, valley, 0.0), (valley, 0.0, ridge_b, -depth)] {
            let base = m.positions.len() as u32;
            m.positions.extend([
                Vec3::new(xa, -0.5, za),
                Vec3::new(xb, -0.5, zb),
                Vec3::new(xb, 0.5, zb),
                Vec3::new(xa, 0.5, za),
            ]);
            m.indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            m.material.extend([0, 0]);
        }
    }
    m
}

/// A 1 mm triangle at `distance` from the plate (off the camera's view and the sun's path).
fn far_triangle(distance: f32) -> TriMesh {
    let p = Vec3::new(0.0, -distance, 0.0);
    TriMesh {
        positions: vec![p, p + Vec3::new(1e-3, 0.0, 0.0), p + Vec3::new(0.0, 1e-3, 0.0)],
        indices: vec![[0, 1, 2]],
        material: vec![0],
    }
}

fn grooved_scene(mesh: TriMesh, cam: &CameraModel, range: f64, settings: RenderSettings, layout: BvhLayout) -> Scene {
    let pose = Pose { sun_dir: sun_at_incidence(60.0), ..Pose::ahead(range) };
    Scene::build(SceneParts {
        sensor: Default::default(),
        mesh,
        materials: vec![lambert("paint", RHO)],
        sun_irradiance: E,
        background: 0.0,
        camera: cam.clone(),
        pose,
        render: settings,
        layout,
        stars: None,
        planet: None,
        limits: Default::default(),
        texturing: None,
    })
}

fn frame(s: &Scene, cam: &CameraModel, settings: RenderSettings) -> RadianceImage {
    render(s, &s.view(cam, &s.pose), &RenderOptions::new(settings, 0)).0
}

/// The pixel rectangle a frame traces.
fn rect(s: &Scene, cam: &CameraModel, settings: RenderSettings) -> Option<PixelRect> {
    render(s, &s.view(cam, &s.pose), &RenderOptions::new(settings, 0)).1.rect
}

/// The mean of the pixels inside the plate's image (`half_px` its half width), 4 px in.
fn plate_mean(img: &RadianceImage, half_px: f64) -> f64 {
    mean(&common::scenes::inner_pixels(img, half_px, 4.0))
}

/// A far triangle at 1e3 m and at 1e5 m changes no pixel of the grooved plate beyond
/// 1e-6 of its mean (depth 2, the set-up), with the product's BVH and a lab one.
#[test]
fn a_far_triangle_changes_no_pixel_of_the_grooved_plate() {
    let cam = camera(256, 256, 20.0, 40.0); // the plate spans 200 px at 10 m
    let settings = RenderSettings {
        spp: Spp::whole(4),
        depth: 2,
        sampler: SamplerKind::Cosine,
        adaptive: false,
        seed: 7,
        ..Default::default()
    };
    for layout in [BvhLayout::Bvh8, BvhLayout::Bvh2] {
        let alone = frame(&grooved_scene(grooved_plate(), &cam, 10.0, settings, layout), &cam, settings);
        let lit: Vec<f32> = alone.data.iter().copied().filter(|&v| v > 0.0).collect();
        let m = mean(&lit);
        assert!(lit.len() > 30_000, "{} lit pixels", lit.len());
        for distance in [1e3f32, 1e5] {
            let mut mesh = grooved_plate();
            mesh.append(&far_triangle(distance));
            let with = frame(&grooved_scene(mesh, &cam, 10.0, settings, layout), &cam, settings);
            let diff: Vec<f64> =
                alone.data.iter().zip(&with.data).map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs()).collect();
            let changed = diff.iter().filter(|&&d| d > 1e-6 * m).count();
            let worst = diff.iter().copied().fold(0.0, f64::max);
            let mean_with = mean(&with.data.iter().copied().filter(|&v| v > 0.0).collect::<Vec<_>>());
            println!(
                "{layout:?}, far triangle at {distance} m: {changed} of {} lit pixels change by more than 1e-6 of the \
                 mean {m:.4}; largest change {worst:e}; lit mean {mean_with:.4} ({:+.2e} relative)",
                lit.len(),
                mean_with / m - 1.0
            );
            assert_eq!(changed, 0, "{layout:?}, {distance} m: largest change {worst}");
        }
    }
}

/// The lit share of the crease walls is the analytic one at 10 m and at 300 m, with and
/// without a far triangle: no shadow ray starts above the ridges and skips them.
#[test]
fn crease_shadows_match_the_analytic_lit_fraction() {
    let t15 = 15f64.to_radians();
    let expected = f64::from(RHO) * E / std::f64::consts::PI * t15.cos() * (1.0 - t15.tan()) * 0.5;
    let settings = RenderSettings {
        spp: Spp::whole(16),
        depth: 1,
        sampler: SamplerKind::Cosine,
        adaptive: false,
        seed: 3,
        ..Default::default()
    };
    // The plate spans 200 px at either range.
    for (range, focal_mm) in [(10.0, 40.0), (300.0, 1200.0)] {
        let cam = camera(256, 256, 20.0, focal_mm);
        for far in [None, Some(1e5f32)] {
            let mut mesh = grooved_plate();
            if let Some(d) = far {
                mesh.append(&far_triangle(d));
            }
            let img = frame(&grooved_scene(mesh, &cam, range, settings, BvhLayout::Bvh8), &cam, settings);
            let m = plate_mean(&img, 100.0);
            println!("range {range} m, far triangle {far:?}: plate mean {m:.4}, analytic {expected:.4}");
            assert!(((m - expected) / expected).abs() < 0.005, "range {range}, far {far:?}: {m} vs {expected}");
        }
    }
}

/// The render frame is centred on the plate whatever lies far away: the plate's
/// coordinates are the same bits, so is its bounding sphere (the camera rays' start).
#[test]
fn far_geometry_does_not_move_the_render_frame() {
    let cam = camera(256, 256, 20.0, 40.0);
    let settings = RenderSettings { spp: Spp::whole(1), depth: 1, ..Default::default() };
    let alone = grooved_scene(grooved_plate(), &cam, 10.0, settings, BvhLayout::Bvh8);
    let mut mesh = grooved_plate();
    mesh.append(&far_triangle(1e5));
    let with = grooved_scene(mesh, &cam, 10.0, settings, BvhLayout::Bvh8);
    assert_eq!(alone.frame_origin_body, with.frame_origin_body);
    let n = alone.mesh.positions.len();
    assert_eq!(alone.mesh.positions[..], with.mesh.positions[..n]);
    assert!(alone.parts.is_empty());
    assert_eq!(with.parts.len(), 2);
    let plate = with.parts.iter().find(|p| p.radius > 0.1).expect("the plate's sphere");
    assert_eq!((plate.centre, plate.radius), (DVec3::ZERO, alone.bounds.radius));
    // Each triangle's spawn scale is its own: the plate's stay about 0.5 m.
    assert_eq!(alone.planes[..], with.planes[..alone.planes.len()]);
    // The far part is off the image: the frame traces the plate's pixels only, though the
    // whole target's bounding sphere holds the camera.
    assert_eq!(rect(&with, &cam, settings), rect(&alone, &cam, settings));
    assert!(rect(&alone, &cam, settings).is_some_and(|r| r.area() < 220 * 220));
}

/// A ray spawned from any point of a triangle, leaving on either side in any direction
/// (down to 0.06° above the surface), never hits that triangle again — at coordinates from
/// a millimetre to 100 km from the render origin, and whatever error the hit point had
/// along the normal (up to a thousand ulps: a long ray's rounding).
#[test]
fn spawned_rays_do_not_hit_their_own_triangle() {
    use hilcam_core::render::geometry::Ray;
    use hilcam_core::render::geometry::bvh::brute_force;
    use hilcam_core::render::geometry::spawn::TrianglePlane;
    use hilcam_core::render::sampling::Rng;
    let mut rng = Rng::from_state(44);
    let unit = |rng: &mut Rng| Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 2.0;
    let mut tested = 0;
    for scale in [1e-3f32, 1.0, 1e3, 1e5] {
        for _ in 0..200 {
            let centre = unit(&mut rng) * scale;
            let size = scale * (0.01 + rng.next_f32());
            let positions =
                vec![centre + unit(&mut rng) * size, centre + unit(&mut rng) * size, centre + unit(&mut rng) * size];
            let mesh = TriMesh { positions, indices: vec![[0, 1, 2]], material: vec![0] };
            let face = mesh.face_normal_area2(0).normalize_or_zero();
            if face == Vec3::ZERO {
                continue;
            }
            let plane = TrianglePlane::of(&mesh, 0, face);
            let [a, b, c] = mesh.triangle(0);
            for _ in 0..20 {
                let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let ulps = plane.scale * f32::EPSILON * 1000.0 * (rng.next_f32() - 0.5);
                let p = a + (b - a) * u + (c - a) * v + face * ulps;
                let out = if rng.next_f32() < 0.5 { face } else { -face };
                let dir = loop {
                    let d = unit(&mut rng).normalize_or_zero();
                    if d.dot(out) > 1e-3 {
                        break d;
                    }
                };
                let ray = Ray { origin: plane.spawn(p, face, out), dir, tmax: f32::INFINITY };
                assert!(
                    !brute_force::occluded(&mesh, &ray),
                    "scale {scale}: {ray:?} hits its own triangle {:?}",
                    mesh.positions
                );
                tested += 1;
            }
        }
    }
    assert!(tested > 15_000, "{tested} rays");
}
