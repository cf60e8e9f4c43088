//! A camera rig through the real renderer: each camera's mount turns one chaser-body pose
//! into what that camera sees, checked against plain pinhole geometry computed here
//! (rotation matrices and x/z projection; no quaternion code of the crate's).

use crate::common;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::rig::{BodyPose, Mount};

/// Direct sunlight only, enough samples that edge pixels' coverage is close to exact.
fn settings() -> RenderSettings {
    RenderSettings { spp: Spp::whole(16), depth: 1, sampler: SamplerKind::Cosine, seed: 5, ..Default::default() }
}

/// A square Lambert plate of side `side` (target frame, z = 0) seen by `cam` on `mount`.
fn render_plate(cam: &CameraModel, mount: &Mount, body: &BodyPose, side: f32) -> RadianceImage {
    let pose = mount.camera_pose(body);
    let s = scene(square(0.0, 0.0, 0.0, side, 0), vec![lambert("paint", 0.5)], cam.clone(), pose, settings());
    render(&s, &s.view(cam, &pose), &RenderOptions::new(settings(), 0)).0
}

/// Radiance-weighted centroid, in continuous pixel coordinates (a pixel spans [c, c + 1)).
fn centroid(img: &RadianceImage) -> (f64, f64) {
    let (mut sum, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for row in 0..img.height {
        for col in 0..img.width {
            let v = f64::from(img.get(col, row));
            sum += v;
            sx += v * (f64::from(col) + 0.5);
            sy += v * (f64::from(row) + 0.5);
        }
    }
    assert!(sum > 0.0, "the target is not in view");
    (sx / sum, sy / sum)
}

/// The plate's left edge, in continuous columns, averaged over the rows well inside it: in
/// each, the first lit pixel's unlit share added to its column (the box filter's coverage).
fn left_edge(img: &RadianceImage, lit: f32) -> f64 {
    let rows: Vec<u32> =
        (0..img.height).filter(|&r| (0..img.width).filter(|&c| img.get(c, r) >= lit * 0.999).count() > 4).collect();
    let inner = &rows[2..rows.len() - 2];
    let edge = |row: u32| {
        let first = (0..img.width).find(|&c| img.get(c, row) > 0.0).unwrap();
        f64::from(first) + 1.0 - f64::from(img.get(first, row) / lit)
    };
    inner.iter().map(|&r| edge(r)).sum::<f64>() / inner.len() as f64
}

/// R = Rz·Ry·Rx for rotations about fixed body X, then Y, then Z (degrees), as a matrix.
fn euler_matrix(deg: [f64; 3]) -> [[f64; 3]; 3] {
    let [x, y, z] = deg.map(f64::to_radians);
    let rx = [[1.0, 0.0, 0.0], [0.0, x.cos(), -x.sin()], [0.0, x.sin(), x.cos()]];
    let ry = [[y.cos(), 0.0, y.sin()], [0.0, 1.0, 0.0], [-y.sin(), 0.0, y.cos()]];
    let rz = [[z.cos(), -z.sin(), 0.0], [z.sin(), z.cos(), 0.0], [0.0, 0.0, 1.0]];
    let mul = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| {
        let mut m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
            }
        }
        m
    };
    mul(rz, mul(ry, rx))
}

/// Where a body-frame point lands in a camera mounted at `position` with Euler angles
/// `deg` (camera → body): Rᵀ(p − t), then the pinhole x/z.
fn predicted_pixel(cam: &CameraModel, position: [f64; 3], deg: [f64; 3], point: [f64; 3]) -> Option<(f64, f64)> {
    let r = euler_matrix(deg);
    let d: Vec<f64> = (0..3).map(|i| point[i] - position[i]).collect();
    let c: Vec<f64> = (0..3).map(|j| (0..3).map(|i| r[i][j] * d[i]).sum()).collect();
    let f = cam.focal_mm * 1e3 / cam.pitch_um;
    let (u, v) = (f64::from(cam.width) / 2.0 + f * c[0] / c[2], f64::from(cam.height) / 2.0 + f * c[1] / c[2]);
    let inside = c[2] > 0.0 && (0.0..f64::from(cam.width)).contains(&u) && (0.0..f64::from(cam.height)).contains(&v);
    inside.then_some((u, v))
}

#[test]
fn stereo_disparity_is_focal_times_baseline_over_range() {
    // 256² px of 20 µm behind 40 mm (f = 2000 px); baseline 0.25 m along body x; a 0.5 m
    // plate 9 m ahead: f·B/(z·pitch) = 55.556 px.
    let cam = camera(256, 256, 20.0, 40.0);
    let (baseline, range) = (0.25, 9.0);
    let expected = cam.focal_mm * 1e-3 * baseline / (range * cam.pitch_um * 1e-6);
    let body = BodyPose(Pose { sun_dir: DVec3::NEG_Z, ..Pose::ahead(range) });
    let left = Mount { position: DVec3::new(-baseline / 2.0, 0.0, 0.0), attitude: DQuat::IDENTITY };
    let right = Mount { position: DVec3::new(baseline / 2.0, 0.0, 0.0), attitude: DQuat::IDENTITY };
    let (l, r) = (render_plate(&cam, &left, &body, 0.5), render_plate(&cam, &right, &body, 0.5));
    let lit = (0.5 * 593.1 / std::f64::consts::PI) as f32;
    let by_centroid = centroid(&l).0 - centroid(&r).0;
    let by_edge = left_edge(&l, lit) - left_edge(&r, lit);
    eprintln!("disparity: expected {expected:.4} px, centroid {by_centroid:.4} px, left edge {by_edge:.4} px");
    assert!((by_centroid - expected).abs() < 0.05, "centroid disparity {by_centroid} vs {expected}");
    assert!((by_edge - expected).abs() < 0.05, "edge disparity {by_edge} vs {expected}");
    // A horizontal baseline shifts nothing vertically.
    assert!((centroid(&l).1 - centroid(&r).1).abs() < 0.02);
}

/// Each camera of a wide + narrow pair sees a target only where its mount puts it.
#[test]
fn a_target_lands_where_the_mounts_put_it() {
    let wide = hilcam_core::scene::file::camera_by_name_or_file("config/rig/wide512.toml").unwrap().camera;
    let narrow = hilcam_core::scene::file::camera_preset("nav1024").unwrap().camera;
    // The wide camera tilted a little, the narrow one turned 35° toward body +x.
    let (wide_at, wide_deg) = ([-0.1, 0.05, 0.0], [4.0, -6.0, 10.0]);
    let (narrow_at, narrow_deg) = ([0.1, 0.0, 0.2], [0.0, 35.0, 0.0]);
    let wide_mount = Mount::from_euler_deg(DVec3::from_array(wide_at), wide_deg);
    let narrow_mount = Mount::from_euler_deg(DVec3::from_array(narrow_at), narrow_deg);
    for (seen_by, target) in [("wide", [-6.0, 2.0, 20.0]), ("narrow", [12.0, 0.8, 17.0])] {
        let (seer, seer_mount, other, other_mount) = match seen_by {
            "wide" => (&wide, &wide_mount, &narrow, &narrow_mount),
            _ => (&narrow, &narrow_mount, &wide, &wide_mount),
        };
        // The plate parallel to the seeing camera's image plane, so that its image is a
        // square whose centroid is its centre's projection.
        let body = BodyPose(Pose {
            position: DVec3::from_array(target),
            attitude: seer_mount.attitude,
            sun_dir: seer_mount.attitude * DVec3::NEG_Z,
            ..Pose::ahead(1.0)
        });
        let (seer_at, seer_deg, other_at, other_deg) = match seen_by {
            "wide" => (wide_at, wide_deg, narrow_at, narrow_deg),
            _ => (narrow_at, narrow_deg, wide_at, wide_deg),
        };
        let want = predicted_pixel(seer, seer_at, seer_deg, target).expect("in the seeing camera's field");
        assert!(predicted_pixel(other, other_at, other_deg, target).is_none(), "{seen_by}: in both fields");
        let got = centroid(&render_plate(seer, seer_mount, &body, 0.8));
        eprintln!("{seen_by}: predicted ({:.3}, {:.3}), centroid ({:.3}, {:.3})", want.0, want.1, got.0, got.1);
        assert!((got.0 - want.0).abs() < 0.05 && (got.1 - want.1).abs() < 0.05, "{seen_by}: {got:?} vs {want:?}");
        let unseen = render_plate(other, other_mount, &body, 0.8);
        assert!(unseen.data.iter().all(|&v| v == 0.0), "{seen_by}: the other camera sees it too");
    }
}
