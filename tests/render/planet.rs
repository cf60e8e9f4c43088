//! A planet behind the target (`render::planet`): its disc against the analytic Lambert
//! and Lommel–Seeliger spheres, earthshine on a plate against a quadrature of the lit
//! sphere, occlusion by the target, the eclipse, determinism.

use crate::common;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::planet::{Planet, PlanetModel};
use hilcam_core::render::{FrameBuffers, RenderOptions, render, render_into};
use hilcam_core::scene::Scene;
use std::f64::consts::PI;

const E: f64 = 593.1;
const EARTH_R: f64 = 6.371e6;

fn settings(spp: u32, depth: u32, adaptive: bool) -> RenderSettings {
    RenderSettings {
        spp: Spp::whole(spp),
        depth,
        sampler: SamplerKind::Cosine,
        seed: 5,
        adaptive,
        ..Default::default()
    }
}

fn frame(s: &Scene, settings: RenderSettings) -> RadianceImage {
    render(s, &s.view(&s.camera, &s.pose), &RenderOptions::new(settings, 0)).0
}

fn bytes(img: &RadianceImage) -> Vec<u8> {
    img.data.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Radiance of a sphere's surface point (outward unit normal `m`) toward `to_viewer`, as
/// `docs/scene.md` states the two models.
fn surface(model: PlanetModel, albedo: f64, m: DVec3, sun: DVec3, to_viewer: DVec3) -> f64 {
    let (mu0, mu) = (m.dot(sun), m.dot(to_viewer));
    if mu0 <= 0.0 {
        return 0.0;
    }
    match model {
        PlanetModel::Lambert => albedo * E * mu0 / PI,
        PlanetModel::LommelSeeliger => albedo * E / (4.0 * PI) * mu0 / (mu0 + mu),
    }
}

/// Radiance the camera (at the origin) sees along the unit camera-frame direction `d`:
/// textbook ray–sphere intersection (closest approach, half-chord), 0 on a miss.
fn seen(p: &Planet, sun: DVec3, d: DVec3) -> f64 {
    let tca = p.centre_cam.dot(d);
    let h2 = p.centre_cam.length_squared() - tca * tca;
    let r2 = p.radius_m * p.radius_m;
    if tca <= 0.0 || h2 > r2 {
        return 0.0;
    }
    let m = (d * (tca - (r2 - h2).sqrt()) - p.centre_cam) / p.radius_m;
    surface(p.model, p.albedo, m, sun, -d)
}

/// Irradiance (W/m²) at `at` on a plane of unit normal `normal`, from the sunlit sphere
/// `p` (camera frame): ∫ L cosθ_plane cosθ_sphere / r² dA over the cap visible from
/// `at`, midpoint rule in cos α (polar angle about the line to `at`) and azimuth. An
/// independent computation: over the sphere's surface, not the plate's hemisphere.
fn irradiance_from(p: &Planet, sun: DVec3, at: DVec3, normal: DVec3) -> f64 {
    let (c, r) = (p.centre_cam, p.radius_m);
    let axis = (at - c).normalize();
    let d = (at - c).length();
    let e1 = axis.any_orthonormal_vector();
    let e2 = axis.cross(e1);
    let (nu, nphi) = (4000, 96);
    let u0 = r / d; // the visible cap: cos α > R/d
    let (du, dphi) = ((1.0 - u0) / nu as f64, 2.0 * PI / nphi as f64);
    let mut sum = 0.0;
    for i in 0..nu {
        let u = u0 + (i as f64 + 0.5) * du;
        let s = (1.0 - u * u).sqrt();
        for k in 0..nphi {
            let phi = (k as f64 + 0.5) * dphi;
            let m = axis * u + (e1 * phi.cos() + e2 * phi.sin()) * s;
            let to = at - (c + m * r); // surface point → `at`
            let dist2 = to.length_squared();
            let dir = to / dist2.sqrt();
            let (cos_sphere, cos_plane) = (m.dot(dir), -normal.dot(dir));
            if cos_sphere <= 0.0 || cos_plane <= 0.0 {
                continue;
            }
            let l = surface(p.model, p.albedo, m, sun, dir);
            sum += l * cos_plane * cos_sphere / dist2 * r * r * du * dphi;
        }
    }
    sum
}

#[test]
fn quadrature_meets_the_far_field_lambert_sphere() {
    // Far away, a Lambert sphere at full phase is a point of intensity (2/3)·ρ·E·R²
    // (geometric albedo 2ρ/3): E = (2/3)·ρ·E_sun·(R/d)². At d = 10⁴ R the finite-distance
    // terms are ~R/d = 1e-4 (the cap seen is short of a hemisphere by that); the midpoint
    // rule's error is below 1e-6.
    let p = Planet {
        centre_cam: DVec3::new(0.0, 0.0, 1e4 * EARTH_R),
        radius_m: EARTH_R,
        albedo: 0.3,
        model: PlanetModel::Lambert,
    };
    let got = irradiance_from(&p, -DVec3::Z, DVec3::ZERO, DVec3::Z);
    let expected = 2.0 / 3.0 * 0.3 * E * 1e-8;
    assert!((got / expected - 1.0).abs() < 3e-4, "{got} vs {expected}");
    // Lommel–Seeliger: intensity ϖ·E·R²/8 at full phase.
    let ls = Planet { model: PlanetModel::LommelSeeliger, ..p };
    let got = irradiance_from(&ls, -DVec3::Z, DVec3::ZERO, DVec3::Z);
    let expected = 0.3 / 8.0 * E * 1e-8;
    assert!((got / expected - 1.0).abs() < 3e-4, "{got} vs {expected}");
}

/// A 128² camera (IFOV 1 mrad) and a 1 m plate `plate_at` metres ahead, with `planet`.
fn disc_scene(planet: Planet, sun: DVec3, plate: (f32, f32, f64), settings: RenderSettings) -> Scene {
    let cam = camera(128, 128, 10.0, 10.0);
    let (cx, cy, range) = plate;
    let pose = Pose { sun_dir: sun, ..Pose::ahead(range) };
    let mut s = scene(square(cx, cy, 0.0, 1.0, 0), vec![lambert("paint", 0.9)], cam, pose, settings);
    s.target.planet = Some(planet);
    s
}

/// Every pixel whose area misses `skip` must lie between the smallest and largest
/// analytic radiance over its area (a 17 × 17 grid of points on it): a pixel is the mean
/// of its samples, each of which is one of those values. Returns (pixels checked, how many
/// of them see the disc).
fn assert_disc_brackets(img: &RadianceImage, s: &Scene, sun: DVec3, skip: impl Fn(u32, u32) -> bool) -> (usize, usize) {
    let p = s.planet.unwrap();
    let inv_f = 1.0 / s.camera.focal_px();
    let (w, h) = (img.width, img.height);
    let (mut checked, mut on_disc) = (0, 0);
    for row in 0..h {
        for col in 0..w {
            if skip(row, col) {
                continue;
            }
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..=16 {
                for j in 0..=16 {
                    let x = (col as f64 + i as f64 / 16.0 - w as f64 / 2.0) * inv_f;
                    let y = (row as f64 + j as f64 / 16.0 - h as f64 / 2.0) * inv_f;
                    let l = seen(&p, sun, DVec3::new(x, y, 1.0).normalize());
                    (lo, hi) = (lo.min(l), hi.max(l));
                }
            }
            // 1e-3 of the pixel's largest value: the grid's spacing near an extremum
            // inside the pixel (second order) and f32 sums; 1e-6 absolute.
            let tol = 1e-3 * hi + 1e-6;
            let v = img.get(col, row) as f64;
            assert!(v >= lo - tol && v <= hi + tol, "pixel ({col}, {row}) = {v}, analytic range [{lo}, {hi}]");
            checked += 1;
            on_disc += usize::from(hi > 0.0);
        }
    }
    (checked, on_disc)
}

#[test]
fn disc_matches_the_analytic_sphere_at_full_and_quarter_phase() {
    // Earth at 25 Earth radii: a disc of 40 mrad = 40 px radius on the boresight. The
    // 1 m plate sits 60 m ahead in a corner of the image (0.5 m off → outside the disc);
    // its pixels are skipped.
    let centre = DVec3::new(0.0, 0.0, 25.0 * EARTH_R);
    for (model, sun) in [
        (PlanetModel::Lambert, DVec3::new(0.0, 0.0, -1.0)), // phase 0°: sun behind the camera
        (PlanetModel::Lambert, DVec3::new(1.0, 0.0, 0.0)),  // phase 90°: the right half is lit
        (PlanetModel::LommelSeeliger, DVec3::new(0.0, 0.0, -1.0)),
        (PlanetModel::LommelSeeliger, DVec3::new(1.0, 0.0, 0.0)),
    ] {
        let planet = Planet { centre_cam: centre, radius_m: EARTH_R, albedo: 0.3, model };
        let s = disc_scene(planet, sun, (-3.0, -3.0, 60.0), settings(16, 2, false));
        let img = frame(&s, settings(16, 2, false));
        // The plate: 1 m at 60 m = 16.7 px around pixel (14, 14); skip a 24 px box.
        let (checked, on_disc) = assert_disc_brackets(&img, &s, sun, |r, c| r < 26 && c < 26);
        // π·40² = 5027 pixels on the disc, half of them lit at quarter phase.
        let lit = if sun.x > 0.0 { 2_400 } else { 4_900 };
        assert!(checked > 15_000 && on_disc > lit, "{checked} checked, {on_disc} lit on the disc");
        if sun.x > 0.0 {
            // The terminator runs down the disc's centre column: left of it is night.
            let night = (0..128).flat_map(|r| (30..63).map(move |c| (r, c))).map(|(r, c)| img.get(c, r));
            assert!(night.into_iter().all(|v| v == 0.0), "{model:?}: light on the night side");
        } else {
            // Flux: Σ L·Ω·cosθ over the pixels (Ω = IFOV²·cos³θ on a pinhole) is the
            // irradiance at the camera, from the quadrature. 0.5 %: the limb pixels' sample
            // noise (~250 pixels, 16 samples, at most a few % each, averaging out).
            let ifov = 1.0 / s.camera.focal_px();
            let mut flux = 0.0;
            for row in 0..128u32 {
                for col in 0..128u32 {
                    let (x, y) = ((col as f64 + 0.5 - 64.0) * ifov, (row as f64 + 0.5 - 64.0) * ifov);
                    let cos = 1.0 / (1.0 + x * x + y * y).sqrt();
                    if row >= 26 || col >= 26 {
                        flux += img.get(col, row) as f64 * ifov * ifov * cos.powi(4);
                    }
                }
            }
            let expected = irradiance_from(&planet, sun, DVec3::ZERO, DVec3::Z);
            eprintln!("disc {model:?}: flux {flux:.6e}, quadrature {expected:.6e}");
            assert!((flux / expected - 1.0).abs() < 5e-3, "{model:?}: flux {flux} vs {expected}");
        }
    }
}

#[test]
fn the_target_hides_the_planet_behind_it() {
    // Half the 1 m plate (the triangle right of its diagonal, col > row) 20 m ahead on the
    // boresight, in front of the full disc; sun behind the camera. Pixels well inside the
    // triangle show it (ρE/π, direct sun at normal incidence: exact), all others the
    // analytic disc — the empty half of the triangle's box included, whose pixels are
    // traced and whose rays escape past the target. Adaptive sampling on.
    let centre = DVec3::new(0.0, 0.0, 25.0 * EARTH_R);
    let planet = Planet { centre_cam: centre, radius_m: EARTH_R, albedo: 0.3, model: PlanetModel::Lambert };
    let sun = DVec3::new(0.0, 0.0, -1.0);
    let st = settings(4, 1, true);
    let mut s = disc_scene(planet, sun, (0.0, 0.0, 20.0), st);
    let mut half = square(0.0, 0.0, 0.0, 1.0, 0);
    (half.indices, half.material) = (vec![[0, 2, 1]], vec![0]);
    s = {
        let mut t = scene(half, vec![lambert("paint", 0.9)], s.camera.clone(), s.pose, st);
        t.target.planet = Some(planet);
        t
    };
    let (img, stats) = render(&s, &s.view(&s.camera, &s.pose), &RenderOptions::new(st, 0));
    assert!(stats.traced_pixels > 1000, "{} pixels traced", stats.traced_pixels);
    // 1 m at 20 m = 50 px: the plate covers pixels 39..89, the disc (radius 40 px) 24..104.
    let plate = 0.9 * E / PI;
    let inner = |r: u32, c: u32| (41..87).contains(&r) && (41..87).contains(&c) && c > r + 3;
    let edge = |r: u32, c: u32| (36..92).contains(&r) && (36..92).contains(&c) && c + 3 >= r;
    for r in 0..128 {
        for c in 0..128 {
            if inner(r, c) {
                let v = img.get(c, r) as f64;
                assert!((v / plate - 1.0).abs() < 1e-4, "plate pixel ({c}, {r}) = {v}, expected {plate}");
            }
        }
    }
    let (checked, on_disc) = assert_disc_brackets(&img, &s, sun, edge);
    assert!(checked > 14_000 && on_disc > 3_000, "{checked} checked, {on_disc} on the disc");
    // Pixels on the triangle's edges mix the plate and the disc (≤ 0.3·E/π < the plate).
    for r in 36..92 {
        for c in 36..92 {
            let v = img.get(c, r) as f64;
            if edge(r, c) && !inner(r, c) {
                assert!((0.0..=plate * (1.0 + 1e-4)).contains(&v), "edge pixel ({c}, {r}) = {v}");
            }
        }
    }
}

#[test]
fn escaping_primary_rays_see_what_the_camera_sees() {
    // A primary ray that enters the target's bounding sphere and misses the target starts
    // at the sphere (f32, near the target) and meets the planet from there; a camera
    // sample that misses the bounds is followed from the camera in f64. Both must give the
    // same radiance: across the disc and its limb, to f32 rounding of the ray (1e-7 rad ×
    // 25 R ≈ 16 m on a 160 km pixel footprint: ~1e-4 of a pixel).
    let centre = DVec3::new(0.0, 0.0, 25.0 * EARTH_R);
    let planet = Planet { centre_cam: centre, radius_m: EARTH_R, albedo: 0.3, model: PlanetModel::Lambert };
    let sun = DVec3::new(0.5, 0.0, -0.8);
    let st = settings(1, 2, false);
    // A 1 m plate 1.5 m ahead, 0.55 m to the right: it covers the image's right side
    // from 1.9° on, its bounding sphere (radius 0.71 m) the whole image.
    let s = disc_scene(planet, sun, (0.55, 0.0, 1.5), st);
    let view = s.view(&s.camera, &s.pose);
    let placed = planet.place(&view, s.sun_irradiance);
    let ctx = hilcam_core::render::integrator::PathContext::new(&s, view.sun, &st).with_planet(Some(placed));
    let (mut compared, mut on_disc) = (0, 0);
    for k in 0..4000 {
        let (x, y) = (64.0 + 45.0 * (k as f64 * 0.618).sin(), 64.0 + 45.0 * (k as f64 * 0.377).cos());
        let Some(ray) = view.primary_ray(x, y) else { continue };
        if s.accel.intersect(&ray).is_some() {
            continue;
        }
        let (traced, camera) = (ctx.escaped(&ray), placed.seen_by_camera(&view, x, y).unwrap_or(0.0));
        // At the limb a 16 m shift can cross the edge: allow a few such samples.
        if (traced - camera).abs() > 1e-4 * 60.0 {
            assert!((traced == 0.0) != (camera == 0.0), "({x}, {y}): traced {traced}, camera {camera}");
            continue;
        }
        compared += 1;
        on_disc += usize::from(camera > 0.0);
    }
    assert!(compared > 2000 && on_disc > 1000, "{compared} compared, {on_disc} on the disc");
}

/// The plate facing a sunlit planet 400 km below it at full phase (the sun beyond the
/// plate: its camera side is unlit), the camera 5 m in front of it on the planet's side.
fn earthshine_scene(model: PlanetModel, st: RenderSettings) -> (Scene, Planet, DVec3) {
    let cam = camera(128, 128, 20.0, 10.0);
    let sun = DVec3::new(0.0, 0.0, 1.0);
    let pose = Pose { sun_dir: sun, ..Pose::ahead(5.0) };
    let mut s = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam, pose, st);
    // Centre 6771 km from the plate, behind the camera.
    let planet =
        Planet { centre_cam: DVec3::new(0.0, 0.0, 5.0 - (EARTH_R + 4.0e5)), radius_m: EARTH_R, albedo: 0.3, model };
    s.target.planet = Some(planet);
    (s, planet, sun)
}

#[test]
fn earthshine_on_a_plate_matches_the_lit_spheres_irradiance() {
    // Depth 2: the plate's only light is the planet, through its one bounce. Each inner
    // pixel estimates ρ_plate/π · E_es; their mean (8464 pixels × 16 samples, per-sample
    // spread ~40 %) is within ~0.2 % at 3σ, so 1 % holds with room.
    for model in [PlanetModel::Lambert, PlanetModel::LommelSeeliger] {
        let st = settings(16, 2, false);
        let (s, planet, sun) = earthshine_scene(model, st);
        let img = frame(&s, st);
        let e_es = irradiance_from(&planet, sun, DVec3::new(0.0, 0.0, 5.0), DVec3::new(0.0, 0.0, -1.0));
        let expected = 0.5 / PI * e_es;
        // 1 m at 5 m = 100 px (IFOV 2 mrad): pixels 14..114.
        let inner: Vec<f32> =
            (18..110).flat_map(|r| (18..110).map(move |c| (r, c))).map(|(r, c)| img.get(c, r)).collect();
        let m = mean(&inner);
        eprintln!(
            "earthshine {model:?}: plate {m:.4}, ρ/π·E_es = {expected:.4} ({:+.3} %)",
            (m / expected - 1.0) * 100.0
        );
        assert!((m / expected - 1.0).abs() < 0.01, "{model:?}: plate {m} vs ρ/π·E_es = {expected}");
        // Without the planet the plate is black (it faces away from the sun).
        let mut dark = earthshine_scene(model, st).0;
        dark.target.planet = None;
        assert!(frame(&dark, st).data.iter().all(|&v| v == 0.0));
    }
    // The far-field form (2/3)·ρ·E·(R/d)² is a third short at 400 km (105 vs 157 W/m²):
    // the near sphere fills most of the plate's sky, so the quadrature is needed.
    let (_, planet, sun) = earthshine_scene(PlanetModel::Lambert, settings(1, 2, false));
    let near = irradiance_from(&planet, sun, DVec3::new(0.0, 0.0, 5.0), DVec3::new(0.0, 0.0, -1.0));
    let far = 2.0 / 3.0 * 0.3 * E * (EARTH_R / (EARTH_R + 4.0e5)).powi(2);
    eprintln!("earthshine at 400 km: quadrature {near:.3} W/m², far-field form {far:.3} W/m²");
}

#[test]
fn the_planet_shadows_the_sun() {
    // A plate turned so that it faces both the camera and a sun 60° off the boresight;
    // the planet sits on the line from the plate toward the sun, 10⁴ km away. Depth 1.
    let cam = camera(128, 128, 20.0, 10.0);
    let q = DQuat::from_rotation_y(-75f64.to_radians()); // body +z → camera (−sin75, 0, cos75)…
    let n = q * DVec3::NEG_Z; // the camera-facing normal
    let sun = DVec3::new(60f64.to_radians().sin(), 0.0, 60f64.to_radians().cos());
    assert!(n.dot(sun) > 0.5 && n.z < -0.2, "n {n}");
    let st = settings(4, 1, false);
    let pose = Pose { attitude: q, sun_dir: sun, ..Pose::ahead(5.0) };
    let mut s = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam, pose, st);
    let lit = 0.5 * E * n.dot(sun) / PI;
    let plate = DVec3::new(0.0, 0.0, 5.0);
    let inner = |img: &RadianceImage| -> Vec<(u32, f64)> {
        // The plate is foreshortened in x (cos 75°): 26 px wide; rows 14..114.
        (20..108).flat_map(|r| (60..68).map(move |c| (r, c))).map(|(r, c)| (r, img.get(c, r) as f64)).collect()
    };
    for (offset_y, what) in [(0.0, "total"), (EARTH_R, "partial"), (3.0 * EARTH_R, "none")] {
        let centre = plate + sun * 1e7 + DVec3::new(0.0, offset_y, 0.0);
        s.target.planet =
            Some(Planet { centre_cam: centre, radius_m: EARTH_R, albedo: 0.3, model: PlanetModel::Lambert });
        let img = frame(&s, st);
        for (row, v) in inner(&img) {
            // Partial: the shadow's edge (the cylinder of radius R about the line through
            // the centre along the sun) crosses the plate at y = 0 (row 64): rows below
            // (y > 0) are closer to the axis, in shadow.
            let dark = match what {
                "total" => true,
                "partial" => row >= 64,
                _ => false,
            };
            if what == "partial" && (62..66).contains(&row) {
                continue;
            }
            let expected = if dark { 0.0 } else { lit };
            assert!((v - expected).abs() <= 1e-4 * lit, "{what}: row {row} = {v}, expected {expected}");
        }
    }
}

#[test]
fn same_bytes_whatever_the_thread_count_and_buffers() {
    // Earthshine, a visible disc behind the plate, adaptive sampling: one thread or two,
    // fresh or reused buffers, the same bytes.
    let centre = DVec3::new(0.0, 0.0, 25.0 * EARTH_R);
    let planet = Planet { centre_cam: centre, radius_m: EARTH_R, albedo: 0.3, model: PlanetModel::Lambert };
    let st = RenderSettings { spp: Spp::from_milli(2500), ..settings(2, 3, true) };
    let s = disc_scene(planet, DVec3::new(0.6, 0.0, -0.8), (0.2, 0.0, 8.0), st);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| frame(&s, st))
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(bytes(&a), bytes(&b));
    assert!(a.data.iter().filter(|&&v| v > 0.0).count() > 4000);
    // A frame with a planet, then one without, through the same buffers: the second is
    // the fresh render of its scene (the planet's background is cleared everywhere).
    let mut plain = disc_scene(planet, DVec3::new(0.6, 0.0, -0.8), (0.2, 0.0, 8.0), st);
    plain.target.planet = None;
    let mut buffers = FrameBuffers::<()>::default();
    let opts = RenderOptions::new(st, 0);
    render_into(&mut buffers, &s, &s.view(&s.camera, &s.pose), &opts);
    assert_eq!(bytes(buffers.image()), bytes(&a));
    render_into(&mut buffers, &plain, &plain.view(&plain.camera, &plain.pose), &opts);
    assert_eq!(bytes(buffers.image()), bytes(&frame(&plain, st)));
}

#[test]
fn a_planet_that_neither_shows_nor_lights_changes_no_byte() {
    // A black planet (albedo 0) behind the camera, and a 1 m black rock 10⁵ km ahead:
    // the code paths run (background fill, escaping rays, the eclipse classification) and
    // the frame keeps the bytes of the scene without a planet (black sky).
    let st = settings(2, 3, true);
    let s0 = disc_scene(
        Planet { centre_cam: DVec3::new(0.0, 0.0, 1e8), radius_m: 1.0, albedo: 0.0, model: PlanetModel::Lambert },
        DVec3::new(0.3, 0.0, -1.0),
        (0.0, 0.0, 10.0),
        st,
    );
    let mut none = disc_scene(s0.planet.unwrap(), DVec3::new(0.3, 0.0, -1.0), (0.0, 0.0, 10.0), st);
    none.target.planet = None;
    let black = disc_scene(
        Planet { centre_cam: DVec3::new(0.0, 0.0, -1e7), radius_m: 1e6, albedo: 0.0, model: PlanetModel::Lambert },
        DVec3::new(0.3, 0.0, -1.0),
        (0.0, 0.0, 10.0),
        st,
    );
    let reference = bytes(&frame(&none, st));
    assert_eq!(bytes(&frame(&black, st)), reference);
    assert_eq!(bytes(&frame(&s0, st)), reference, "a 1 m black rock 10⁵ km ahead");
}

#[test]
fn scene_files_place_the_planet_and_refuse_bad_keys_by_name() {
    use hilcam_core::scene::file::parse;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/plate.toml");
    let base = std::fs::read_to_string(&path).unwrap();
    let with = |table: &str| parse(&path, &format!("{base}\n[planet]\n{table}\n"));
    let p = with("body = \"moon\"\ncenter_m = [0.0, 0.0, 3.844e8]").unwrap().planet.unwrap();
    assert_eq!((p.radius_m, p.albedo, p.model), (1.7374e6, 0.11, PlanetModel::Lambert));
    let p = with("radius_m = 2e6\nalbedo = 0.5\nmodel = \"lommel-seeliger\"\ncenter_m = [0.0, 1e7, 0.0]")
        .unwrap()
        .planet
        .unwrap();
    assert_eq!((p.radius_m, p.albedo, p.model), (2e6, 0.5, PlanetModel::LommelSeeliger));
    assert!(parse(&path, &base).unwrap().planet.is_none());
    for (table, key) in [
        ("body = \"earth\"\ncenter_m = [0.0, 6.0e6, 0.0]", "planet.center_m: the camera is inside the planet"),
        ("body = \"mars\"\ncenter_m = [0.0, 0.0, 1e8]", "planet.body: unknown body `mars`"),
        ("body = \"earth\"\nalbedo = 1.5\ncenter_m = [0.0, 0.0, 1e8]", "planet.albedo: must be"),
        ("radius_m = 0.0\nalbedo = 0.3\ncenter_m = [0.0, 0.0, 1e8]", "planet.radius_m: must be"),
        ("albedo = 0.3\ncenter_m = [0.0, 0.0, 1e8]", "planet.radius_m: give radius_m or body"),
        ("body = \"earth\"\ncenter_m = [0.0, 0.0, 1e300]", "planet.center_m: must be finite"),
        ("body = \"earth\"\nmodel = \"hapke\"\ncenter_m = [0.0, 0.0, 1e8]", "unknown variant `hapke`"),
    ] {
        let e = with(table).err().expect(table).to_string();
        assert!(e.contains(key) && e.contains("plate.toml"), "{table}: {e}");
    }
}

#[test]
fn a_small_far_disc_is_not_culled() {
    // A disc of 1.5 px radius (the Moon at 1.16e9 m, IFOV 1 mrad) off-centre, between
    // pixel corners: its flux must arrive whole (the background fill skips only pixels
    // whose area cannot reach the disc). 64 samples per pixel, ~15 pixels on the limb: 3 %.
    let d = DVec3::new(10.3, -7.6, 1000.0).normalize() * (1.7374e6 / 1.5e-3);
    let planet = Planet { centre_cam: d, radius_m: 1.7374e6, albedo: 0.11, model: PlanetModel::Lambert };
    let sun = DVec3::new(0.0, 0.0, -1.0);
    let st = settings(64, 1, false);
    let s = disc_scene(planet, sun, (-3.0, -3.0, 60.0), st);
    let img = frame(&s, st);
    let ifov = 1.0 / s.camera.focal_px();
    // The plate's corner (rows and columns < 26) is left out.
    let flux: f64 = (26..128u32)
        .flat_map(|r| (26..128u32).map(move |c| (r, c)))
        .map(|(r, c)| img.get(c, r) as f64 * ifov * ifov)
        .sum();
    let expected = irradiance_from(&planet, sun, DVec3::ZERO, d.normalize());
    assert!((flux / expected - 1.0).abs() < 0.03, "flux {flux} vs {expected}");
}
