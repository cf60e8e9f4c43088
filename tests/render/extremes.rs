//! Stability at the extremes (issue 7): every output finite, every expectation checked
//! against an independent computation.

use crate::common;
use common::scenes::*;
use glam::{DQuat, DVec3, Vec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::geometry::TriMesh;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind};
use hilcam_core::render::{RenderOptions, render};

fn finite(img: &hilcam_core::render::film::RadianceImage) -> bool {
    img.data.iter().all(|v| v.is_finite() && *v >= 0.0)
}

/// A closed unit cube (12 triangles, outward winding), side `s`, centred at the origin.
fn cube(s: f32) -> TriMesh {
    let h = s * 0.5;
    let p = |x: f32, y: f32, z: f32| Vec3::new(x * h, y * h, z * h);
    let positions = vec![
        p(-1., -1., -1.),
        p(1., -1., -1.),
        p(1., 1., -1.),
        p(-1., 1., -1.),
        p(-1., -1., 1.),
        p(1., -1., 1.),
        p(1., 1., 1.),
        p(-1., 1., 1.),
    ];
    let indices = vec![
        [0, 2, 1],
        [0, 3, 2],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [2, 3, 7],
        [2, 7, 6],
        [1, 2, 6],
        [1, 6, 5],
        [0, 4, 7],
        [0, 7, 3],
    ];
    TriMesh { positions, material: vec![0; indices.len()], indices }
}

#[test]
fn ranges_from_half_a_metre_to_a_million_metres_image_the_same() {
    // Fronto-parallel pattern, focal length scaled with range: identical images.
    let mut flat = square(0.0, 0.0, 0.0, 0.2, 0);
    flat.append(&square(0.03, -0.02, 0.0, 0.05, 1));
    let settings =
        RenderSettings { spp: Spp::whole(2), depth: 2, sampler: SamplerKind::Cosine, seed: 1, ..Default::default() };
    let base = 0.5;
    let cam0 = camera(64, 64, 20.0, 20.0);
    let s = scene(flat, vec![lambert("a", 0.7), lambert("b", 0.2)], cam0.clone(), Pose::ahead(base), settings);
    let pose = |r: f64| Pose { sun_dir: sun_at_incidence(25.0), ..Pose::ahead(r) };
    let (reference, _) = render(&s, &s.view(&cam0, &pose(base)), &RenderOptions::new(settings, 0));
    let total: f64 = reference.data.iter().map(|&v| v as f64).sum();
    assert!(total > 0.0);
    for range in [5.0, 1e2, 1e4, 1e6] {
        let cam = camera(64, 64, 20.0, 20.0 * range / base);
        let (img, _) = render(&s, &s.view(&cam, &pose(range)), &RenderOptions::new(settings, 0));
        assert!(finite(&img));
        let d: f64 =
            img.data.iter().zip(&reference.data).map(|(a, b)| (*a as f64 - *b as f64).abs()).sum::<f64>() / total;
        assert!(d < 1e-3, "range {range} m: relative L1 difference {d}");
    }
}

#[test]
fn camera_inside_the_targets_bounding_box() {
    // Inside a closed cube lit from outside: no sunlight reaches the inside faces (they
    // are shadowed by the cube itself), so every pixel is exactly 0 — and finite.
    let cam = camera(64, 64, 20.0, 10.0);
    let settings =
        RenderSettings { spp: Spp::whole(2), depth: 4, sampler: SamplerKind::Cosine, seed: 1, ..Default::default() };
    let pose = Pose {
        position: DVec3::new(0.1, -0.2, 0.3),
        sun_dir: DVec3::new(0.3, 0.4, -0.866).normalize(),
        ..Pose::ahead(0.0)
    };
    let s = scene(cube(2.0), vec![lambert("a", 0.9)], cam.clone(), pose, settings);
    let (img, stats) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
    assert!(finite(&img));
    assert_eq!(stats.traced_pixels, 64 * 64, "inside the bounds every pixel is traced");
    assert!(img.data.iter().all(|&v| v == 0.0));
    // Remove the faces that face the sun: sunlight now enters and lights the inside.
    let mut open = cube(2.0);
    let sun_body = pose.sun_dir.as_vec3();
    let keep: Vec<usize> =
        (0..open.indices.len()).filter(|&i| open.face_normal_area2(i).normalize().dot(sun_body) < 0.5).collect();
    open.indices = keep.iter().map(|&i| open.indices[i]).collect();
    open.material = vec![0; open.indices.len()];
    let s = scene(open, vec![lambert("a", 0.9)], cam.clone(), pose, settings);
    let (img, _) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
    assert!(finite(&img) && img.data.iter().any(|&v| v > 0.0));
}

#[test]
fn target_on_the_image_edge_and_off_it() {
    let cam = camera(100, 80, 20.0, 40.0);
    let settings =
        RenderSettings { spp: Spp::whole(4), depth: 1, sampler: SamplerKind::Cosine, seed: 1, ..Default::default() };
    let f = cam.focal_px();
    // Put the plate's centre exactly on the left image edge (x = 0 px) at 10 m.
    let x_edge = (0.0 - 50.0) / f * 10.0;
    let pose = Pose { position: DVec3::new(x_edge, 0.0, 10.0), sun_dir: -DVec3::Z, ..Pose::ahead(10.0) };
    let s = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("a", 0.5)], cam.clone(), pose, settings);
    let (img, _) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
    assert!(finite(&img));
    // The plate spans ±100 px around x = 0: columns 0..99 see it (rows within ±100 px: all).
    let expected = 0.5 * 593.1 / std::f64::consts::PI;
    for row in 0..80 {
        for col in 0..99 {
            assert!(((img.get(col, row) as f64 - expected) / expected).abs() < 1e-4, "({col}, {row})");
        }
    }
    // Entirely off the image: exactly one plate width beyond the edge.
    let off = Pose { position: DVec3::new(x_edge - 0.6 - 1e-3, 0.0, 10.0), ..pose };
    let (img, stats) = render(&s, &s.view(&cam, &off), &RenderOptions::new(settings, 0));
    assert!(img.data.iter().all(|&v| v == 0.0));
    assert!(stats.rays.total() < 1000, "{} rays for an off-image target", stats.rays.total());
}

#[test]
fn near_degenerate_triangles_stay_finite() {
    // Slivers (one vertex 1e-7 m off the opposite edge) and a zero-area triangle.
    let mut m = square(0.0, 0.0, 0.0, 1.0, 0);
    let base = m.positions.len() as u32;
    m.positions.extend([Vec3::new(-0.5, 0.0, -0.1), Vec3::new(0.5, 0.0, -0.1), Vec3::new(0.0, 1e-7, -0.1)]);
    m.positions.extend([Vec3::new(0.0, 0.2, -0.2), Vec3::new(0.0, 0.2, -0.2), Vec3::new(0.1, 0.2, -0.2)]);
    m.indices.extend([[base, base + 1, base + 2], [base + 3, base + 4, base + 5]]);
    m.material.extend([0, 0]);
    let cam = camera(64, 64, 20.0, 30.0);
    let settings =
        RenderSettings { spp: Spp::whole(4), depth: 4, sampler: SamplerKind::Cosine, seed: 1, ..Default::default() };
    let pose = Pose { sun_dir: sun_at_incidence(40.0), ..Pose::ahead(3.0) };
    let s = scene(m, vec![lambert("a", 0.9)], cam.clone(), pose, settings);
    let (img, stats) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
    assert!(finite(&img) && stats.rays.nonfinite == 0);
}

#[test]
fn quaternions_at_plus_and_minus_180_degrees_are_the_same_attitude() {
    let cam = camera(48, 48, 20.0, 30.0);
    let settings =
        RenderSettings { spp: Spp::whole(2), depth: 2, sampler: SamplerKind::Cosine, seed: 4, ..Default::default() };
    let mut m = square(0.0, 0.0, 0.0, 1.0, 0);
    m.append(&square(0.2, 0.1, -0.2, 0.3, 0));
    let axis = DVec3::new(1.0, 1.0, 0.2).normalize();
    let q_plus = DQuat::from_axis_angle(axis, std::f64::consts::PI);
    let q_minus = DQuat::from_axis_angle(axis, -std::f64::consts::PI);
    let q_neg = -q_plus; // the same rotation with the opposite sign
    let pose = |q: DQuat| Pose { attitude: q, sun_dir: DVec3::new(0.2, 0.1, -1.0).normalize(), ..Pose::ahead(4.0) };
    let s = scene(m, vec![lambert("a", 0.6)], cam.clone(), pose(q_plus), settings);
    let (a, _) = render(&s, &s.view(&cam, &pose(q_plus)), &RenderOptions::new(settings, 0));
    for q in [q_minus, q_neg] {
        let (b, _) = render(&s, &s.view(&cam, &pose(q)), &RenderOptions::new(settings, 0));
        let d: f64 = a.data.iter().zip(&b.data).map(|(x, y)| (*x - *y).abs() as f64).sum();
        let t: f64 = a.data.iter().map(|&x| x as f64).sum();
        assert!(t > 0.0 && d / t < 1e-4, "relative difference {}", d / t);
    }
}

/// Constant-rate motion sampled at 10 kHz: pose k is the exact state at k·100 µs.
fn pose_at_10_khz(k: u32) -> Pose {
    let t = f64::from(k) * 1e-4;
    let (v, w) = (DVec3::new(0.4, -0.3, -2.0), DVec3::new(0.2, -0.5, 0.3));
    Pose {
        seq: k,
        t_ns: u64::from(k) * 100_000,
        position: DVec3::new(0.1, 0.05, 12.0) + v * t,
        attitude: DQuat::from_axis_angle(w.normalize(), w.length() * t) * DQuat::from_rotation_x(0.3),
        sun_dir: DVec3::new(0.3, 0.2, -1.0).normalize(),
        velocity: Some(v),
        angular_rate: Some(w),
        camera_to_inertial: None,
        planet_centre: None,
    }
}

/// The attitude at time t as a matrix, by Rodrigues' formula (no quaternion code).
fn attitude_matrix(t: f64) -> glam::DMat3 {
    use glam::DMat3;
    let w = DVec3::new(0.2, -0.5, 0.3);
    let (k, theta) = (w.normalize(), w.length() * t);
    let kx = DMat3::from_cols(DVec3::new(0.0, k.z, -k.y), DVec3::new(-k.z, 0.0, k.x), DVec3::new(k.y, -k.x, 0.0));
    let r = DMat3::IDENTITY + kx * theta.sin() + kx * kx * (1.0 - theta.cos());
    let (c, s) = (0.3f64.cos(), 0.3f64.sin());
    r * DMat3::from_cols(DVec3::X, DVec3::new(0.0, c, s), DVec3::new(0.0, -s, c))
}

fn matrix_error(q: DQuat, m: glam::DMat3) -> f64 {
    let d = glam::DMat3::from_quat(q) - m;
    d.x_axis.length() + d.y_axis.length() + d.z_axis.length()
}

#[test]
fn poses_at_10_khz_extrapolate_over_100_us_to_the_next_pose() {
    use hilcam_core::serve::extrapolate::extrapolate;
    // One second at 10 kHz: every pose moved 100 µs ahead lands on the next one, and
    // 10 000 chained 100 µs steps land on the pose 1 s later.
    let mut chained = pose_at_10_khz(0);
    for k in 1..=10_000u32 {
        let t = f64::from(k) * 1e-4;
        let (e, moved) = extrapolate(&pose_at_10_khz(k - 1), 1e-4);
        assert!(moved && e.position.is_finite() && e.attitude.is_finite());
        assert_eq!(e.t_ns, u64::from(k) * 100_000, "t_ns exact at step {k}");
        let want_pos = DVec3::new(0.1, 0.05, 12.0) + DVec3::new(0.4, -0.3, -2.0) * t;
        assert!((e.position - want_pos).length() < 1e-12, "step {k}");
        assert!(matrix_error(e.attitude, attitude_matrix(t)) < 1e-12, "step {k}");
        chained = extrapolate(&chained, 1e-4).0;
        assert!((chained.attitude.length() - 1.0).abs() < 1e-12);
    }
    assert_eq!(chained.t_ns, 1_000_000_000);
    let want_pos = DVec3::new(0.1, 0.05, 12.0) + DVec3::new(0.4, -0.3, -2.0);
    assert!((chained.position - want_pos).length() < 1e-9, "{}", chained.position);
    assert!(matrix_error(chained.attitude, attitude_matrix(1.0)) < 1e-9);
}

#[test]
fn poses_at_10_khz_survive_the_serial_codec_and_validation() {
    use hilcam_core::pose::Message;
    use hilcam_core::pose::serial::{DecodeEvent, SerialDecoder, encode_frame};
    use hilcam_core::pose::validate::{PoseLimits, PoseValidator};
    // One second of 10 kHz poses as one byte stream, fed in odd-sized chunks.
    let bytes: Vec<u8> = (1..=10_000u32).flat_map(|k| encode_frame(&Message::Pose(pose_at_10_khz(k)))).collect();
    let mut dec = SerialDecoder::new();
    let mut validator = PoseValidator::new(PoseLimits::default());
    let mut next = 1u32;
    for chunk in bytes.chunks(997) {
        dec.push(chunk);
        while let Some(ev) = dec.next_event() {
            let DecodeEvent::Message(Message::Pose(p)) = ev else { panic!("{ev:?}") };
            let p = validator.check(&p).expect("a 100 µs step is a valid pose");
            let sent = pose_at_10_khz(next);
            assert_eq!((p.seq, p.t_ns, p.position, p.velocity), (sent.seq, sent.t_ns, sent.position, sent.velocity));
            next += 1;
        }
    }
    assert_eq!(next, 10_001, "every pose decoded");
    // A pose 100 µs in the past is refused.
    assert!(validator.check(&pose_at_10_khz(9_999)).is_err());
}
