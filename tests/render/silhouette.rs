//! Per-row spans of the target's bounds (cull::Silhouette) against a brute-force check:
//! every pixel the renderer skips must be one where no sample position can reach the
//! target's box (independent slab test in f64), over random poses, boxes and cameras.

use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::distortion::Distortion;
use hilcam_core::render::camera::{CameraModel, TargetBounds, View};
use hilcam_core::render::cull::Silhouette;
use hilcam_core::render::sampling::Rng;

/// Ray (origin, dir) against the box [min, max]: true if they meet at t ≥ 0.
fn ray_meets_box(o: DVec3, d: DVec3, min: DVec3, max: DVec3) -> bool {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((min[a] - o[a]) * inv, (max[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    t0 <= t1
}

fn random_unit(rng: &mut Rng) -> DVec3 {
    loop {
        let v = DVec3::new(rng.next_f32() as f64, rng.next_f32() as f64, rng.next_f32() as f64) * 2.0 - 1.0;
        if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

#[test]
fn skipped_pixels_cannot_see_the_box_and_spans_are_tight() {
    check_spans(false);
}

/// Through random Brown–Conrady lenses (barrel and pincushion, decentred), validated
/// over the field as the sensor config does; samples are undistorted as the renderer does.
#[test]
fn through_a_lens_skipped_pixels_cannot_see_the_box_either() {
    check_spans(true);
}

fn random_lens(rng: &mut Rng, cam: &CameraModel) -> Option<Distortion> {
    let mut s = || (rng.next_f32() as f64 - 0.5) * 2.0;
    let d = Distortion { k1: 0.25 * s(), k2: 0.1 * s(), k3: 0.02 * s(), p1: 0.004 * s(), p2: 0.004 * s() };
    let hw = cam.width as f64 / 2.0 + cam.principal_point_px[0].abs();
    let hh = cam.height as f64 / 2.0 + cam.principal_point_px[1].abs();
    d.validate(1.05 * (hw * hw + hh * hh).sqrt() / cam.focal_px()).ok().map(|_| d)
}

fn check_spans(with_lens: bool) {
    let cam = CameraModel { width: 96, height: 80, pitch_um: 10.0, focal_mm: 1.2, principal_point_px: [3.5, -6.25] };
    let mut rng = Rng::for_sample(7 + with_lens as u64, 0, 0, 0);
    let (mut skipped_total, mut rect_total, mut views_with_spans) = (0u64, 0u64, 0);
    for case in 0..400 {
        // A box elongated along a random axis mix, centred near the render-frame origin.
        let half = DVec3::new(
            0.2 + 3.0 * rng.next_f32() as f64,
            0.1 + rng.next_f32() as f64,
            0.05 + 0.5 * rng.next_f32() as f64,
        );
        let centre = (random_unit(&mut rng) * 0.1) * half.length();
        let bounds = TargetBounds { centre, radius: half.length(), min: centre - half, max: centre + half };
        // Range from just outside the sphere to far; direction off the boresight so the
        // target also sits on image edges and corners.
        let range = half.length() * (1.02 + 30.0 * (rng.next_f32() as f64).powi(2));
        let off = DVec3::new(0.7 * (rng.next_f32() as f64 - 0.5), 0.7 * (rng.next_f32() as f64 - 0.5), 1.0);
        let attitude = DQuat::from_axis_angle(random_unit(&mut rng), 6.3 * rng.next_f32() as f64);
        let pose = Pose {
            position: off.normalize() * range + attitude * centre,
            attitude,
            sun_dir: DVec3::Z,
            ..Pose::ahead(range)
        };
        let lens = if with_lens { random_lens(&mut rng, &cam) } else { None };
        if with_lens && lens.is_none() {
            continue;
        }
        let view = View::new(&cam, &pose, DVec3::ZERO, bounds).with_distortion(lens);
        let Some(rect) = view.pixel_rect() else { continue };
        let Some(sil) = Silhouette::new(&view) else { continue };
        views_with_spans += 1;
        let cam_centre = -(attitude.inverse() * pose.position);
        for row in rect.row0..rect.row1 {
            let span = sil.columns(row);
            for col in rect.col0..rect.col1 {
                rect_total += 1;
                if span.is_some_and(|(a, b)| (a..b).contains(&col)) {
                    continue;
                }
                skipped_total += 1;
                // 7×7 positions over the pixel's closed area, corners and edges included.
                for i in 0..7 {
                    for j in 0..7 {
                        let (x, y) = (col as f64 + i as f64 / 6.0, row as f64 + j as f64 / 6.0);
                        // The renderer's own mapping (undistortion included) to a direction.
                        let d = attitude.inverse() * view.camera_dir(x, y);
                        assert!(
                            !ray_meets_box(cam_centre, d, bounds.min, bounds.max),
                            "case {case}: pixel ({col}, {row}) skipped but its sample ({x:.3}, {y:.3}) sees the box"
                        );
                    }
                }
            }
        }
    }
    assert!(views_with_spans > 60, "only {views_with_spans} views had spans");
    // Oblique elongated boxes leave much of their bounding rectangle empty.
    let frac = skipped_total as f64 / rect_total as f64;
    eprintln!("{views_with_spans} views, {:.1} % of rectangle pixels skipped", frac * 100.0);
    assert!(frac > 0.15, "spans skipped only {:.1} % of the rectangles' pixels", frac * 100.0);
}
