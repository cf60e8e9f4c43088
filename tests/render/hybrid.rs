//! `method = "hybrid"` against answers computed independently: a plate's pixels are its
//! radiance times the exact area of the pixel it covers, shadow edges and occlusion
//! match a dense supersampling of ray/plane maths, and frames are the same bytes for any
//! thread count and any history of earlier frames.

use crate::common;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{Method, RenderSettings, SamplerKind, Spp};
use hilcam_core::render::{FrameBuffers, RenderOptions, render, render_into};

const E: f64 = 593.1;

fn hybrid(depth: u32, seed: u64) -> RenderSettings {
    RenderSettings { method: Method::Hybrid, spp: Spp::whole(1), depth, seed, ..Default::default() }
}

fn bytes(img: &RadianceImage) -> Vec<u8> {
    img.data.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Area of the convex polygon `poly` inside the unit pixel at (`col`, `row`): the polygon
/// clipped by the pixel's four half-planes in turn, then the shoelace formula.
fn area_in_pixel(poly: &[[f64; 2]], col: f64, row: f64) -> f64 {
    let mut p: Vec<[f64; 2]> = poly.to_vec();
    // (axis, bound, keep below?)
    for (axis, bound, below) in [(0, col, false), (0, col + 1.0, true), (1, row, false), (1, row + 1.0, true)] {
        let inside = |q: &[f64; 2]| if below { q[axis] <= bound } else { q[axis] >= bound };
        let mut out = Vec::new();
        for i in 0..p.len() {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        p = out;
        if p.is_empty() {
            return 0.0;
        }
    }
    let mut twice = 0.0;
    for i in 0..p.len() {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        twice += a[0] * b[1] - b[0] * a[1];
    }
    twice.abs() * 0.5
}

#[test]
fn a_turned_plate_is_its_radiance_times_each_pixels_covered_area() {
    // A 1 m plate at 10 m turned 17° about the boresight: every edge pixel is cut at a
    // slant. With the sun at 30° every point has radiance ρ·E·cosθ/π, so each pixel is
    // that times the area of the pixel the plate's image covers (exact, no sampling).
    let cam = camera(256, 256, 20.0, 40.0);
    let q = DQuat::from_rotation_z(17f64.to_radians());
    let pose = Pose { attitude: q, sun_dir: q * sun_at_incidence(30.0), ..Pose::ahead(10.0) };
    let settings = hybrid(1, 1);
    let s = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.522)], cam.clone(), pose, settings);
    let (img, _) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));

    let l = 0.522 * E * 30f64.to_radians().cos() / std::f64::consts::PI;
    let f = cam.focal_px();
    let corners: Vec<[f64; 2]> = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
        .iter()
        .map(|&(x, y)| {
            let p = q * DVec3::new(x, y, 0.0) + pose.position;
            [p.x / p.z * f + 128.0, p.y / p.z * f + 128.0]
        })
        .collect();
    let (mut edge, mut worst) = (0, 0.0f64);
    for row in 0..cam.height {
        for col in 0..cam.width {
            let a = area_in_pixel(&corners, f64::from(col), f64::from(row));
            let got = f64::from(img.get(col, row));
            worst = worst.max((got - l * a).abs() / l);
            edge += usize::from(a > 0.0 && a < 1.0);
        }
    }
    assert!(edge > 700, "only {edge} edge pixels");
    assert!(worst < 2e-4, "a pixel is {worst} of the radiance away from radiance × covered area");
}

/// What the line of sight from `eye` along `d` (body frame) sees in the shadow scene:
/// the blocker (lit), the plate (lit, or in the blocker's shadow), or nothing.
fn shadow_scene_sample(eye: DVec3, d: DVec3) -> f64 {
    let on_blocker = eye + d * ((-2.0 - eye.z) / d.z);
    if (on_blocker.x - 0.5).abs() <= 0.25 && on_blocker.y.abs() <= 0.25 {
        return 1.0;
    }
    let p = eye + d * (-eye.z / d.z);
    if p.x.abs() > 0.5 || p.y.abs() > 0.5 {
        return 0.0;
    }
    if (p.x - 0.5).abs() <= 0.25 && p.y.abs() <= 0.25 { 0.0 } else { 1.0 }
}

#[test]
fn shadow_edges_and_occlusion_match_a_dense_supersampling() {
    // The plate and blocker of analytic.rs's half-shadow test: the sun along the plate
    // normal casts the blocker's shadow straight down; the camera looks 40° off the normal.
    // Reference: each pixel's mean over a 64 × 64 grid of independent ray/plane tests.
    let cam = camera(256, 256, 20.0, 40.0);
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    mesh.append(&square(0.5, 0.0, -2.0, 0.5, 0));
    let q = DQuat::from_rotation_y(40f64.to_radians());
    let pose = Pose { attitude: q, sun_dir: q * DVec3::new(0.0, 0.0, -1.0), ..Pose::ahead(10.0) };
    let settings = RenderSettings { sampler: SamplerKind::Cosine, ..hybrid(1, 3) };
    let s = scene(mesh, vec![lambert("paint", 0.522)], cam.clone(), pose, settings);
    let (img, _) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));

    let l = 0.522 * E / std::f64::consts::PI;
    let eye = -(q.inverse() * pose.position);
    let f = cam.focal_px();
    const N: usize = 64;
    let (mut mixed, mut abs_err, mut signed, mut worst) = (0usize, 0.0, 0.0, 0.0f64);
    let (mut sum_got, mut sum_ref) = (0.0, 0.0);
    for row in 0..cam.height {
        for col in 0..cam.width {
            let mut share = 0.0;
            for j in 0..N {
                for i in 0..N {
                    let x = f64::from(col) + (i as f64 + 0.5) / N as f64 - 128.0;
                    let y = f64::from(row) + (j as f64 + 0.5) / N as f64 - 128.0;
                    share += shadow_scene_sample(eye, q.inverse() * DVec3::new(x / f, y / f, 1.0));
                }
            }
            share /= (N * N) as f64;
            let got = f64::from(img.get(col, row)) / l;
            (sum_got, sum_ref) = (sum_got + got, sum_ref + share);
            if share == 0.0 || share == 1.0 {
                // Wholly one thing on the grid; an edge may still clip a sliver between
                // the grid's points (< 1/64 of the pixel wide).
                assert!((got - share).abs() < 1.0 / 64.0, "pixel ({col}, {row}) is {got}, wholly {share}");
            } else {
                mixed += 1;
                abs_err += (got - share).abs();
                signed += got - share;
                worst = worst.max((got - share).abs());
            }
        }
    }
    assert!(mixed > 500, "only {mixed} mixed pixels");
    let (abs_err, signed) = (abs_err / mixed as f64, signed / mixed as f64);
    // 64 stratified samples per pixel decide the occluded and shadowed shares; the
    // reference's own grid is good to ~1/64 of a pixel along an edge.
    eprintln!(
        "{mixed} mixed pixels: mean |error| {abs_err:.4}, mean error {signed:.4}, flux ratio {:.6}",
        sum_got / sum_ref
    );
    assert!(worst < 0.1, "worst mixed pixel off by {worst}");
    assert!(abs_err < 0.02, "mixed pixels off by {abs_err} on average");
    assert!(signed.abs() < 0.005, "mixed pixels biased by {signed}");
    assert!((sum_got / sum_ref - 1.0).abs() < 1e-3, "flux {sum_got} vs {sum_ref}");
}

/// A Lambert plate and a smaller glossy plate in front: at depth 2 the cache holds the
/// diffuse parts' indirect light and a path per pixel the glossy lobe's.
fn two_plates(depth: u32) -> (hilcam_core::scene::Scene, hilcam_core::render::camera::CameraModel) {
    let cam = camera(128, 96, 20.0, 30.0);
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    mesh.append(&square(0.2, 0.1, -0.3, 0.4, 1));
    let pose = Pose { sun_dir: sun_at_incidence(20.0), ..Pose::ahead(3.0) };
    let glossy = hilcam_core::scene::Material::new(
        "glossy",
        toml::from_str::<hilcam_core::render::bsdf::BsdfSpec>(
            "model = \"blinn_phong\"\nrho_d = 0.3\nrho_s = 1.0\nalpha = 20.0\nnormalized = true",
        )
        .unwrap()
        .build()
        .unwrap(),
    );
    (scene(mesh, vec![lambert("paint", 0.8), glossy], cam.clone(), pose, hybrid(depth, 9)), cam)
}

#[test]
fn same_bytes_whatever_the_thread_count() {
    let (s, cam) = two_plates(2);
    let settings = s.render;
    let run = |threads, frame| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, frame)).0)
    };
    let a = run(1, 7);
    assert_eq!(bytes(&a), bytes(&run(2, 7)));
    assert_eq!(bytes(&a), bytes(&run(3, 7)));
    assert!(a.data.iter().any(|&v| v > 0.0));
    // The glossy lobe's path follows the frame index.
    assert_ne!(bytes(&a), bytes(&run(2, 8)));
}

#[test]
fn same_bytes_whatever_came_before() {
    // The shadow classes and the indirect cache are kept from frame to frame; a frame
    // after other poses and suns must equal the same frame rendered first.
    let (s, cam) = two_plates(2);
    let settings = s.render;
    let options = RenderOptions::new(settings, 3);
    let fresh = render(&s, &s.view(&cam, &s.pose), &options).0;
    let mut buffers = FrameBuffers::<()>::default();
    for (incidence, turn) in [(50.0, 0.3), (-35.0, -0.2), (20.0, 0.0)] {
        let q = DQuat::from_rotation_y(turn);
        let pose = Pose { attitude: q, sun_dir: q * sun_at_incidence(incidence), ..Pose::ahead(3.0) };
        render_into(&mut buffers, &s, &s.view(&cam, &pose), &options);
    }
    assert_eq!(bytes(&fresh), bytes(&buffers.take_image()));
}

/// The `square` plate cut into `n × n` quads (2n² triangles, the same orientation).
fn tessellated_square(s: f32, n: u32) -> hilcam_core::render::geometry::TriMesh {
    let h = s * 0.5;
    let step = s / n as f32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(glam::Vec3::new(-h + i as f32 * step, -h + j as f32 * step, 0.0));
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            indices.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
            indices.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
        }
    }
    let material = vec![0; indices.len()];
    hilcam_core::render::geometry::TriMesh { positions, indices, material }
}

#[test]
fn many_triangles_bin_the_same_whatever_the_thread_count_and_leave_no_hole() {
    // 12 800 triangles: the setup and the binning run in parallel chunks of 2048.
    let cam = camera(128, 96, 20.0, 30.0);
    let pose = Pose { sun_dir: sun_at_incidence(20.0), ..Pose::ahead(3.0) };
    let settings = hybrid(1, 5);
    let frame = |mesh, threads| {
        let s = scene(mesh, vec![lambert("paint", 0.8)], cam.clone(), pose, settings);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 1)).0)
    };
    let fine = frame(tessellated_square(1.0, 80), 1);
    assert_eq!(bytes(&fine), bytes(&frame(tessellated_square(1.0, 80), 2)));
    assert_eq!(bytes(&fine), bytes(&frame(tessellated_square(1.0, 80), 3)));
    // The same plate as two triangles: every pixel the same radiance (the covered area is
    // the same, summed over more fragments).
    let coarse = frame(square(0.0, 0.0, 0.0, 1.0, 0), 2);
    let lit = coarse.data.iter().filter(|&&v| v > 0.0).count();
    assert!(lit > 1000, "{lit} lit pixels");
    let peak = coarse.data.iter().copied().fold(0.0f32, f32::max);
    for (i, (a, b)) in fine.data.iter().zip(&coarse.data).enumerate() {
        assert!((a - b).abs() <= 1e-4 * peak, "pixel {i}: {a} tessellated, {b} as two triangles");
    }
}
