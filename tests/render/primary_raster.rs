//! Rasterised primary visibility (`render::cull::visibility`) against tracing every primary ray
//! through the BVH: the same image bytes and the same rays, on the shipped satellite, from
//! near and far, rotated, with and without the navigation camera's lens distortion; and
//! the fall-back to tracing when the camera is among the triangles.

use crate::common;
use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::{CameraModel, View};
use hilcam_core::render::cull::coverage::Coverage;
use hilcam_core::render::cull::visibility::{PrimaryRaster, RasterScratch};
use hilcam_core::render::geometry::bvh::brute_force;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind};
use hilcam_core::render::sampling::{PerSample, Sequence, SobolStream};
use hilcam_core::render::{PrimaryVisibility, RenderOptions, RenderStats, render};
use hilcam_core::scene::Scene;

fn small_nav(scene: &Scene, width: u32, height: u32) -> CameraModel {
    common::scenes::scaled_camera(scene, width, height, [1.5, -2.25])
}

const FRAME: u64 = 3;

/// Render `view` both ways; return the number of pixels that differ although the BVH
/// found the right primary hits, and both stats. Where the two differ, every camera
/// sample of the pixel is re-checked against brute force: a pixel may differ only
/// because the BVH traversal missed a triangle that the exact test hits (obvhs's box test
/// can miss a zero-thickness leaf box by rounding), never because the rasteriser did.
fn compare(
    scene: &Scene,
    cam: &CameraModel,
    view: &View,
    settings: &RenderSettings,
) -> (usize, RenderStats, RenderStats) {
    let (a, sa) = render(scene, view, &RenderOptions::new(*settings, FRAME).with_primary(PrimaryVisibility::Raster));
    let (b, sb) = render(scene, view, &RenderOptions::new(*settings, FRAME).with_primary(PrimaryVisibility::Trace));
    let raster = PrimaryRaster::new(scene, view, view.pixel_rect().unwrap());
    let mut scratch = RasterScratch::default();
    let mut hits = Vec::new();
    let mut unexplained = 0;
    for (i, (x, y)) in a.data.iter().zip(&b.data).enumerate() {
        if x.to_bits() == y.to_bits() {
            continue;
        }
        let (row, col) = (i / cam.width as usize, i % cam.width as usize);
        let mut bvh_wrong = false;
        for s in 0..settings.spp.floor() {
            let mut rng = SobolStream::for_sample(settings.seed, FRAME, i as u64, s);
            let j = rng.next_2d();
            let Some(ray) = view.primary_ray(col as f64 + f64::from(j.x), row as f64 + f64::from(j.y)) else {
                continue;
            };
            let exact = brute_force::intersect(&scene.mesh, &ray).map(|h| h.t.to_bits());
            bvh_wrong |= scene.accel.intersect(&ray).map(|h| h.t.to_bits()) != exact;
            if let Some(r) = &raster {
                let at = view.ideal_of_pixel(col as f64 + f64::from(j.x), row as f64 + f64::from(j.y));
                r.closest_hits(&scene.accel, &[ray], &[at], &mut scratch, &mut hits);
                assert_eq!(hits[0].map(|h| h.t.to_bits()), exact, "rasterised hit of pixel ({col}, {row}) sample {s}");
            }
        }
        if !bvh_wrong {
            unexplained += 1;
        }
    }
    (unexplained, sa, sb)
}

#[test]
fn rasterised_primary_hits_give_the_same_bytes_as_tracing() {
    let scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    let cam = small_nav(&scene, 160, 120);
    let settings = RenderSettings {
        spp: Spp::whole(3),
        depth: 3,
        sampler: SamplerKind::Brdf,
        sequence: Sequence::Sobol,
        roulette: true,
        // Uniform counts: one sample that differs (where the BVH itself is wrong) would
        // otherwise move its neighbours' adaptive counts too.
        adaptive: false,
        quality: hilcam_core::render::integrator::QualityGoal::FIXED,
        method: Default::default(),
        seed: 5,
    };
    let base = scene.pose;
    let range = base.position.length();
    let turn = DQuat::from_euler(glam::EulerRot::XYZ, 0.7, -0.4, 1.1);
    let cases: Vec<(&str, Pose, bool)> = vec![
        ("scene pose", base, false),
        ("scene pose through the lens", base, true),
        ("rotated", Pose { attitude: turn * base.attitude, ..base }, false),
        ("rotated through the lens", Pose { attitude: turn * base.attitude, ..base }, true),
        ("close, off-centre", Pose { position: base.position * 0.35 + DVec3::new(1.0, -0.5, 0.0), ..base }, false),
        ("1000 km", Pose { position: base.position.normalize() * 1.0e6, ..base }, false),
    ];
    for (label, pose, lens) in cases {
        // At 1000 km the target is sub-pixel: zoom in so that it still covers pixels.
        let cam = if pose.position.length() > 1e5 {
            CameraModel { focal_mm: cam.focal_mm * 1.0e6 / range, ..cam.clone() }
        } else {
            cam.clone()
        };
        let view = View::new(&cam, &pose, scene.frame_origin_body, scene.bounds).with_distortion(if lens {
            scene.sensor.optics.distortion
        } else {
            None
        });
        let (differ, raster, trace) = compare(&scene, &cam, &view, &settings);
        assert!(raster.primary_rasterised, "{label}: the rasteriser declined");
        assert!(!trace.primary_rasterised, "{label}");
        assert!(trace.rays.primary > 500, "{label}: the target must be in view ({:?})", trace.rays);
        // Each way skips the pixels that cannot see a triangle by its own rule
        // (`coverage`); a pixel one samples and the other skips sees only background, so
        // only the number of primary rays may differ; every other ray is the same.
        assert_eq!((raster.rays.shadow, raster.rays.bounce), (trace.rays.shadow, trace.rays.bounce), "{label}");
        assert_eq!(differ, 0, "{label}: pixels differ where the BVH agrees with brute force");
    }
}

#[test]
fn camera_among_the_triangles_falls_back_to_tracing() {
    let scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    let cam = small_nav(&scene, 64, 48);
    let settings = RenderSettings { spp: Spp::whole(2), depth: 2, ..RenderSettings::default() };
    // Camera at the centre of the target's bounds, looking along its boresight.
    // (camera centre in the body frame −Rᵀp = the render frame's origin ⇒ p = −R·origin)
    let pose = Pose { position: scene.pose.attitude * -scene.frame_origin_body, ..scene.pose };
    let view = View::new(&cam, &pose, scene.frame_origin_body, scene.bounds);
    let (differ, raster, trace) = compare(&scene, &cam, &view, &settings);
    assert!(!raster.primary_rasterised, "a vertex behind the camera must make the rasteriser decline");
    assert!(trace.rays.primary > 0);
    assert_eq!(differ, 0);
}

#[test]
fn auto_traces_packets_or_rasterises_with_enough_samples_per_triangle() {
    use hilcam_core::render::geometry::{Accel, BvhLayout};
    let settings = RenderSettings { spp: Spp::whole(1), depth: 1, ..RenderSettings::default() };
    let mut plate = hilcam_core::scene::file::load(std::path::Path::new("scenes/plate.toml")).unwrap();
    let cam = small_nav(&plate, 64, 64);
    let view = View::new(&cam, &plate.pose, plate.frame_origin_body, plate.bounds);
    // Where the 8-wide tree walks primary rays in packets, they are traced: faster than
    // rasterising at any number of samples (docs/performance.md).
    let (_, packets) = render(&plate, &view, &RenderOptions::new(settings, 0));
    assert_eq!(packets.primary_rasterised, !plate.accel.walks_packets());
    // With single-ray walks: rasterised where enough samples share the per-frame binning.
    // The 2-triangle plate: a handful of samples already pays.
    plate.accel = Accel::build(&plate.mesh, BvhLayout::Bvh4);
    let (_, many) = render(&plate, &view, &RenderOptions::new(settings, 0));
    assert!(many.primary_rasterised);
    // ~7 000 samples for 145 616 triangles: the per-frame binning would cost more.
    let mut scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    scene.accel = Accel::build(&scene.mesh, BvhLayout::Bvh4);
    let cam = small_nav(&scene, 160, 120);
    let view = View::new(&cam, &scene.pose, scene.frame_origin_body, scene.bounds);
    let (_, few) = render(&scene, &view, &RenderOptions::new(settings, 0));
    assert!(!few.primary_rasterised);
}

/// Every point of a pixel from which the BVH finds a triangle is in a pixel the coverage
/// marks as possibly hit, for both sources of it (the rasteriser's triangles and the
/// traced frames' leaf boxes), through the shipped camera's lens and without: dense
/// random points (64 per pixel, far more than a frame's samples) at the shipped pose, near
/// (large triangles, whose images bend most), and off-centre, where the distortion is
/// strongest.
/// Whether pixel (row, col) may see a triangle.
type MayHit<'a> = dyn Fn(u32, u32) -> bool + 'a;

#[test]
fn coverage_never_skips_a_pixel_that_can_see_the_target() {
    let scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    let cam = small_nav(&scene, 160, 120);
    let base = scene.pose;
    let poses = [
        base,
        Pose { position: base.position * 0.45, ..base },
        Pose { position: base.position * 0.6 + DVec3::new(1.0, -0.5, 0.0), ..base },
    ];
    let mut rng = hilcam_core::render::sampling::Rng::from_state(11);
    for (p, pose) in poses.iter().enumerate() {
        for lens in [true, false] {
            let distortion = if lens { scene.sensor.optics.distortion } else { None };
            let view = View::new(&cam, pose, scene.frame_origin_body, scene.bounds).with_distortion(distortion);
            let rect = view.pixel_rect().unwrap();
            let raster = PrimaryRaster::new(&scene, &view, rect).expect("rasterises");
            let mut boxes = Coverage::default();
            assert!(boxes.from_leaf_boxes(&scene, &view, rect), "pose {p}: no leaf-box coverage");
            let sources: [(&str, &MayHit); 2] =
                [("raster", &|r, c| raster.may_hit(r, c)), ("leaf boxes", &|r, c| boxes.may_hit(r, c))];
            let mut kept = [0u32; 2];
            for (s, (name, may_hit)) in sources.iter().enumerate() {
                let label = format!("pose {p}, lens {lens}, {name}");
                let (mut hits, mut skipped) = (0, 0);
                for row in rect.row0..rect.row1 {
                    for col in rect.col0..rect.col1 {
                        if may_hit(row, col) {
                            hits += 1;
                            continue;
                        }
                        skipped += 1;
                        for _ in 0..64 {
                            let (x, y) = (
                                f64::from(col) + f64::from(rng.next_f32()),
                                f64::from(row) + f64::from(rng.next_f32()),
                            );
                            if let Some(ray) = view.primary_ray(x, y) {
                                // The BVH (brute force would take hours here); it only errs by missing.
                                let hit = scene.accel.intersect(&ray);
                                assert!(
                                    hit.is_none(),
                                    "{label}: pixel ({col}, {row}) was skipped, but ({x}, {y}) sees the target"
                                );
                            }
                        }
                    }
                }
                assert!(
                    skipped > 1000 && hits > 1000,
                    "{label}: {skipped} pixels skipped, {hits} kept: nothing was tested"
                );
                kept[s] = hits;
            }
            // The leaf boxes are looser than the triangles, but not by much: a loose coverage
            // spends camera samples (and an adaptive frame's budget) on empty pixels.
            let [raster_kept, boxes_kept] = kept.map(f64::from);
            assert!(
                boxes_kept <= 1.06 * raster_kept,
                "pose {p}, lens {lens}: {boxes_kept} pixels kept by leaf boxes, {raster_kept} by the raster"
            );
            eprintln!("pose {p}, lens {lens}: raster keeps {raster_kept} pixels, leaf boxes {boxes_kept}");
        }
    }
}
