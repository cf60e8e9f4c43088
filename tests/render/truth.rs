//! Ground-truth channels (`render::truth`) against analytic answers: two tilted squares
//! (a 0.2 m plate and a 5 cm tab in front of it, two materials) seen from 3 m, each pixel
//! centre's line of sight intersected with their planes in f64 here, independently of the
//! renderer's BVH and its f64 refinement.

use crate::common::scenes::*;
use glam::{DMat3, DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::{CameraModel, View};
use hilcam_core::render::integrator::{RenderSettings, Spp};
use hilcam_core::render::truth::{TruthChannels, TruthImage, render_truth};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::Scene;

const ALL: &str = "depth,mask,normal,body_xyz";

/// (side, centre in the body frame, material) of the two squares; planes z = const.
const SQUARES: [(f64, [f64; 3], u32); 2] = [(0.2, [0.0, 0.0, 0.0], 0), (0.05, [0.03, 0.02, -0.05], 1)];

fn pose() -> Pose {
    Pose {
        // Tilted 30° about y and 10° about x: range varies across the plate.
        attitude: DQuat::from_rotation_y(30f64.to_radians()) * DQuat::from_rotation_x(10f64.to_radians()),
        position: DVec3::new(0.01, -0.02, 3.0),
        sun_dir: DVec3::new(0.3, -0.2, -1.0).normalize(),
        ..Pose::ahead(3.0)
    }
}

/// 96×80 pixels, f = 1000 px, principal point off centre: the plate spans ~60 px.
fn cam() -> CameraModel {
    CameraModel { width: 96, height: 80, pitch_um: 10.0, focal_mm: 10.0, principal_point_px: [1.5, -2.25] }
}

fn plates() -> Scene {
    let mut mesh = square(0.0, 0.0, 0.0, 0.2, 0);
    let (s, c, m) = SQUARES[1];
    mesh.append(&square(c[0] as f32, c[1] as f32, c[2] as f32, s as f32, m));
    let settings = RenderSettings { spp: Spp::whole(4), depth: 1, ..Default::default() };
    scene(mesh, vec![lambert("plate", 0.5), lambert("tab", 0.3)], cam(), pose(), settings)
}

/// The analytic truth of pixel (col, row): the nearest square crossed by the pixel
/// centre's line (range, material, body point), and whether the crossing lies within
/// 1e-6 m of a square's edge (where f32 geometry may decide either way).
fn analytic(col: u32, row: u32) -> (Option<(f64, u32, DVec3)>, bool) {
    let (c, p) = (cam(), pose());
    let f = c.focal_px();
    let d = DVec3::new((f64::from(col) + 0.5 - 48.0 - 1.5) / f, (f64::from(row) + 0.5 - 40.0 + 2.25) / f, 1.0);
    let r = DMat3::from_quat(p.attitude);
    let mut best: Option<(f64, u32, DVec3)> = None;
    let mut near_edge = false;
    for (side, centre, material) in SQUARES {
        // Body plane z = centre.z: camera point s·d = R b + P  ⇒  b = Rᵀ(s·d − P).
        let (rd, rp) = (r.transpose() * d, r.transpose() * p.position);
        let s = (centre[2] + rp.z) / rd.z;
        let b = rd * s - rp;
        let (ex, ey) = ((b.x - centre[0]).abs() - side / 2.0, (b.y - centre[1]).abs() - side / 2.0);
        near_edge |= ex.abs() < 1e-6 || ey.abs() < 1e-6;
        if s > 0.0 && ex < 0.0 && ey < 0.0 && best.is_none_or(|(range, ..)| s * d.length() < range) {
            best = Some((s * d.length(), material, b));
        }
    }
    (best, near_edge)
}

fn truth(scene: &Scene) -> TruthImage {
    let view = scene.view(&scene.camera, &scene.pose);
    render_truth(scene, &view, TruthChannels::parse(ALL).unwrap())
}

#[test]
fn depth_mask_and_body_point_match_the_analytic_tilted_plates_per_pixel() {
    let t = truth(&plates());
    let (mut hits, mut checked) = (0, 0);
    for row in 0..80u32 {
        for col in 0..96u32 {
            let i = (row * 96 + col) as usize;
            let (want, near_edge) = analytic(col, row);
            if near_edge {
                continue;
            }
            checked += 1;
            match want {
                None => {
                    assert_eq!(t.mask[i], 0, "({col}, {row})");
                    assert_eq!(t.depth[i], f32::INFINITY);
                    assert!(t.normal[0][i].is_nan() && t.body_xyz[2][i].is_nan());
                }
                Some((range, material, body)) => {
                    hits += 1;
                    assert_eq!(t.mask[i], material + 1, "({col}, {row})");
                    // The range is the f64 line–plane crossing stored as f32: relative
                    // rounding 6e-8; 1e-6 leaves room and still catches any f32 ray error
                    // (~1e-7 rad × 3 m would be 1e-7 relative... and a wrong plane far more).
                    let rel = (f64::from(t.depth[i]) - range).abs() / range;
                    assert!(rel < 1e-6, "({col}, {row}): depth {} vs {range} (rel {rel:e})", t.depth[i]);
                    // Body points are f32: 0.1 m × 6e-8 plus the f32 re-centring of the mesh.
                    let got = DVec3::new(
                        f64::from(t.body_xyz[0][i]),
                        f64::from(t.body_xyz[1][i]),
                        f64::from(t.body_xyz[2][i]),
                    );
                    assert!((got - body).length() < 1e-7, "({col}, {row}): body {got} vs {body}");
                }
            }
        }
    }
    assert!(hits > 1500 && checked > 7000, "{hits} hits of {checked} checked pixels");
}

#[test]
fn body_xyz_reprojects_through_the_pose_to_the_pixel_centre() {
    let scene = plates();
    let t = truth(&scene);
    let (p, c) = (scene.pose, cam());
    let r = DMat3::from_quat(p.attitude);
    let mut worst = 0.0f64;
    for i in (0..t.mask.len()).filter(|&i| t.mask[i] != 0) {
        let b = DVec3::new(f64::from(t.body_xyz[0][i]), f64::from(t.body_xyz[1][i]), f64::from(t.body_xyz[2][i]));
        let [x, y] = View::project_camera_point(&c, r * b + p.position).unwrap();
        let (col, row) = ((i % 96) as f64, (i / 96) as f64);
        worst = worst.max((x - col - 0.5).hypot(y - row - 0.5));
    }
    // f32 body coordinates (≤ 0.15 m, rounding ≤ 1e-8 m) seen from 3 m at f = 1000 px:
    // ~3e-6 px; 1e-4 px is the bound.
    assert!(worst < 1e-4, "worst reprojection error {worst:e} px");
}

#[test]
fn normals_face_the_camera_in_the_camera_frame_and_the_footprint_is_the_masks() {
    let scene = plates();
    let t = truth(&scene);
    // Both squares have body normal ±z; in the camera frame R·z turned toward the camera.
    let mut n = DMat3::from_quat(scene.pose.attitude) * DVec3::Z;
    if n.z > 0.0 {
        n = -n;
    }
    for i in (0..t.mask.len()).filter(|&i| t.mask[i] != 0) {
        let got = DVec3::new(f64::from(t.normal[0][i]), f64::from(t.normal[1][i]), f64::from(t.normal[2][i]));
        assert!((got - n).length() < 1e-6, "{got} vs {n}");
    }
    // The footprint is computed from the analytic mask independently.
    let (mut sx, mut sy, mut count, mut bbox) = (0.0, 0.0, 0u64, [u32::MAX, u32::MAX, 0, 0]);
    for row in 0..80u32 {
        for col in 0..96u32 {
            if t.mask[(row * 96 + col) as usize] != 0 {
                assert!(analytic(col, row).0.is_some() || analytic(col, row).1);
                sx += f64::from(col) + 0.5;
                sy += f64::from(row) + 0.5;
                count += 1;
                bbox = [bbox[0].min(col), bbox[1].min(row), bbox[2].max(col + 1), bbox[3].max(row + 1)];
            }
        }
    }
    let f = t.footprint().unwrap();
    assert_eq!((f.pixels, f.bbox_px), (count, bbox));
    assert!((f.centroid_px[0] - sx / count as f64).abs() < 1e-9 && (f.centroid_px[1] - sy / count as f64).abs() < 1e-9);
}

#[test]
fn mask_matches_the_lit_silhouette_of_the_rendered_frame() {
    // The plate alone (the tab would shadow it), sunlit from the camera's side at depth 1
    // onto a black sky: a pixel is lit iff a sample inside its area sees the plate. The
    // mask is the pixel centres', so the two agree up to the pixel area: a pixel whose
    // 3×3 neighbourhood of centres all hit is covered (the plate is convex) and lit; a lit
    // pixel touches the plate, whose corners (~90° wedges, ≥ 50 px long) then reach a
    // centre within 2 pixels: its 5×5 neighbourhood has a hit.
    let (s, ..) = SQUARES[0];
    let settings = RenderSettings { spp: Spp::whole(4), depth: 1, ..Default::default() };
    let scene = scene(square(0.0, 0.0, 0.0, s as f32, 0), vec![lambert("plate", 0.5)], cam(), pose(), settings);
    let t = truth(&scene);
    let view = scene.view(&scene.camera, &scene.pose);
    let (img, _) = render(&scene, &view, &RenderOptions::new(scene.render, 0));
    let hit = |c: i64, r: i64| (0..96).contains(&c) && (0..80).contains(&r) && t.mask[(r * 96 + c) as usize] != 0;
    let around = |c: i64, r: i64, k: i64| (-k..=k).flat_map(move |dr| (-k..=k).map(move |dc| (c + dc, r + dr)));
    let (mut covered, mut lit) = (0, 0);
    for r in 0..80i64 {
        for c in 0..96i64 {
            let v = img.data[(r * 96 + c) as usize];
            if around(c, r, 1).all(|(c, r)| hit(c, r)) {
                assert!(v > 0.0, "({c}, {r}): covered but radiance {v}");
                covered += 1;
            }
            if v > 0.0 {
                assert!(around(c, r, 2).any(|(c, r)| hit(c, r)), "({c}, {r}): lit, no hit centre within 2 px");
                lit += 1;
            }
        }
    }
    assert!(covered > 1500 && lit > covered, "{covered} covered, {lit} lit");
}

/// Bit patterns (NaN-safe equality) of every channel.
fn bits(t: &TruthImage) -> Vec<u32> {
    let planes = std::iter::once(&t.depth).chain(&t.normal).chain(&t.body_xyz);
    t.mask.iter().copied().chain(planes.flat_map(|p| p.iter().map(|v| v.to_bits()))).collect()
}

#[test]
fn truth_is_the_same_for_one_and_two_threads() {
    let scene = plates();
    let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
    let one = pool(1).install(|| truth(&scene));
    let two = pool(2).install(|| truth(&scene));
    assert_eq!(bits(&one), bits(&two));
}

#[test]
fn through_a_distorting_lens_body_xyz_reprojects_to_the_pixel_centre_it_was_seen_at() {
    // Truth uses the image's own lens: a body point reprojects through the pose and the
    // pinhole to its ideal image point, which the lens maps back to the pixel centre.
    use hilcam_core::render::camera::distortion::Distortion;
    let scene = plates();
    let lens = Distortion { k1: -8.0, k2: 0.0, k3: 0.0, p1: 2e-3, p2: -1e-3 };
    let view = scene.view(&scene.camera, &scene.pose).with_distortion(Some(lens));
    let t = render_truth(&scene, &view, TruthChannels::parse(ALL).unwrap());
    let pinhole = render_truth(&scene, &scene.view(&scene.camera, &scene.pose), TruthChannels::parse(ALL).unwrap());
    assert_ne!(t.mask, pinhole.mask, "the lens moves the silhouette");
    let (p, c) = (scene.pose, cam());
    let r = DMat3::from_quat(p.attitude);
    let (mut worst, mut n) = (0.0f64, 0);
    for i in (0..t.mask.len()).filter(|&i| t.mask[i] != 0) {
        let b = DVec3::new(f64::from(t.body_xyz[0][i]), f64::from(t.body_xyz[1][i]), f64::from(t.body_xyz[2][i]));
        let [xi, yi] = View::project_camera_point(&c, r * b + p.position).unwrap();
        let [x, y] = view.pixel_of_ideal(xi, yi);
        let (col, row) = ((i % 96) as f64, (i / 96) as f64);
        worst = worst.max((x - col - 0.5).hypot(y - row - 0.5));
        n += 1;
    }
    // As the pinhole case, plus the lens inversion's tolerance (Newton to ~1e-12).
    assert!(n > 1000 && worst < 1e-4, "{n} pixels, worst reprojection error {worst:e} px");
}

// The packets and the frame's shared coverage against the plain single-ray loop.
mod single_ray_reference {
    use glam::DQuat;
    use hilcam_core::pipeline::FramePipeline;
    use hilcam_core::pose::Pose;
    use hilcam_core::render::integrator::{RenderSettings, Spp};
    use hilcam_core::render::truth::{TruthChannels, TruthImage, TruthPlanes, render_truth, render_truth_reference};

    fn bits(t: &TruthImage) -> Vec<u32> {
        let f = |v: &Vec<f32>| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut b = t.mask.clone();
        b.extend(f(&t.depth));
        t.normal.iter().chain(&t.body_xyz).for_each(|p| b.extend(f(p)));
        b
    }

    /// The shipped satellite through the navigation camera's lens, at 256² and three
    /// attitudes and at its own 1024² (150 k pixels see it): every channel of every pixel
    /// the reference's, bit for bit — computed anew, with the coverage of the frame just
    /// rendered through the same view, and into planes kept from every earlier truth
    /// (other poses, sizes and channel sets).
    #[test]
    fn packets_and_shared_coverage_give_the_single_ray_truth_bit_for_bit() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/satellite.toml");
        let scene = std::sync::Arc::new(hilcam_core::scene::load(&path).unwrap());
        let mut kept = TruthPlanes::default();
        for (width, turns) in [(256, &[0.0f64, 0.7, 2.1][..]), (1024, &[0.0][..])] {
            check(&scene, width, turns, &mut kept);
        }
    }

    fn check(scene: &std::sync::Arc<hilcam_core::scene::Scene>, width: u32, turns: &[f64], kept: &mut TruthPlanes) {
        let camera = scene.camera.scaled(Some(width), None);
        let all = TruthChannels::parse("depth,mask,normal,body_xyz").unwrap();
        let settings = RenderSettings { spp: Spp::whole(1), depth: 1, ..scene.render };
        let mut pipeline = FramePipeline::new(scene.clone(), camera.clone()).unwrap();
        for (k, &turn) in turns.iter().enumerate() {
            let pose = Pose { attitude: scene.pose.attitude * DQuat::from_rotation_y(turn), ..scene.pose };
            let view = scene.view(&camera, &pose).with_distortion(scene.sensor.optics.distortion);
            assert!(view.has_distortion());
            let want = bits(&render_truth_reference(scene, &view, all));
            let hits = want[..(width * width) as usize].iter().filter(|m| **m != 0).count();
            assert!(hits > 1000, "{width}², pose {k}: {hits} pixels see the target");
            assert_eq!(bits(&render_truth(scene, &view, all)), want, "{width}², pose {k}, coverage computed");
            pipeline.frame(&pose, &settings, k as u64).unwrap();
            assert!(pipeline.buffers().coverage_for(&view).is_some(), "the frame's coverage is this view's");
            assert_eq!(
                bits(&pipeline.truth(&pose, &Default::default(), all).unwrap()),
                want,
                "{width}², pose {k}, shared"
            );
            // Kept planes: after the earlier poses and sizes, and after a truth of fewer
            // channels at a pose whose silhouette differs (the planes dropped then are
            // filled anew, the others cleared where it hit).
            let other = Pose { attitude: pose.attitude * DQuat::from_rotation_x(1.3), ..pose };
            let some = TruthChannels::parse("depth,mask").unwrap();
            let fewer = bits(pipeline.truth_into(&other, &Default::default(), some, kept).unwrap());
            assert_eq!(fewer, bits(&pipeline.truth(&other, &Default::default(), some).unwrap()), "{width}², fewer");
            let got = bits(pipeline.truth_into(&pose, &Default::default(), all, kept).unwrap());
            assert_eq!(got, want, "{width}², pose {k}, kept planes");
            let again = bits(pipeline.truth_into(&pose, &Default::default(), all, kept).unwrap());
            assert_eq!(again, want, "{width}², pose {k}, kept planes, same pose again");
        }
    }
}

// Cases built to sit on the edges of the pass's decisions (pixel centres on edges,
// grazing and near-coplanar triangles, far and near targets): every channel of every pixel the
// single-ray reference's, bit for bit, with and without a lens.
mod adversarial {
    use super::{ALL, bits};
    use crate::common::scenes::*;
    use glam::DQuat;
    use hilcam_core::pose::Pose;
    use hilcam_core::render::camera::CameraModel;
    use hilcam_core::render::camera::distortion::Distortion;
    use hilcam_core::render::geometry::TriMesh;
    use hilcam_core::render::integrator::{RenderSettings, Spp};
    use hilcam_core::render::truth::{TruthChannels, render_truth, render_truth_reference};
    use hilcam_core::scene::Scene;

    fn build(mesh: TriMesh, cam: CameraModel, pose: Pose) -> Scene {
        let settings = RenderSettings { spp: Spp::whole(1), depth: 1, ..Default::default() };
        scene(mesh, vec![lambert("a", 0.5), lambert("b", 0.3), lambert("c", 0.2)], cam, pose, settings)
    }

    /// The truth equals the reference's through a pinhole and through a lens; returns the
    /// number of pixels that see the target (pinhole).
    fn same(scene: &Scene, what: &str) -> usize {
        let all = TruthChannels::parse(ALL).unwrap();
        let lens = Distortion { k1: -0.3, k2: 0.05, k3: 0.0, p1: 1e-4, p2: -2e-4 };
        let mut seen = 0;
        for distortion in [None, Some(lens)] {
            let view = scene.view(&scene.camera, &scene.pose).with_distortion(distortion);
            let want = render_truth_reference(scene, &view, all);
            assert_eq!(bits(&render_truth(scene, &view, all)), bits(&want), "{what}, lens {distortion:?}");
            if distortion.is_none() {
                seen = want.mask.iter().filter(|m| **m != 0).count();
            }
        }
        seen
    }

    fn pose(attitude: DQuat, range: f64) -> Pose {
        Pose { attitude, ..Pose::ahead(range) }
    }

    #[test]
    fn pixel_centres_on_shared_and_outer_edges() {
        // f = 100 px, 2 m away: the square's diagonal (its two triangles' shared edge) runs
        // through the centres of the pixels with col = row, and its sides (half-size
        // 10.5 px) through columns and rows of centres.
        let cam = CameraModel { width: 64, height: 64, pitch_um: 10.0, focal_mm: 1.0, principal_point_px: [0.0, 0.0] };
        let mut mesh = square(0.0, 0.0, 0.0, 0.42, 0);
        // A second square sharing the first's plane and one of its sides' lines.
        mesh.append(&square(0.42, 0.0, 0.0, 0.42, 1));
        let seen = same(&build(mesh.clone(), cam.clone(), pose(DQuat::IDENTITY, 2.0)), "edges");
        assert!(seen > 800, "{seen}");
        // Turned by a quarter turn and by a few hundredths of a degree about the boresight.
        for turn in [90f64, 0.03, 45.0] {
            let a = DQuat::from_rotation_z(turn.to_radians());
            same(&build(mesh.clone(), cam.clone(), pose(a, 2.0)), &format!("edges turned {turn}°"));
        }
    }

    #[test]
    fn grazing_triangles() {
        let cam = CameraModel { width: 64, height: 48, pitch_um: 10.0, focal_mm: 4.0, principal_point_px: [0.3, -0.2] };
        for tilt in [60.0, 85.0, 89.0, 89.9, 89.999, 90.0] {
            let mut mesh = square(0.0, 0.0, 0.0, 0.2, 0);
            mesh.append(&square(0.01, 0.0, -0.02, 0.1, 1));
            let a = DQuat::from_rotation_y(f64::to_radians(tilt)) * DQuat::from_rotation_x(0.05);
            same(&build(mesh, cam.clone(), pose(a, 1.5)), &format!("tilt {tilt}°"));
        }
    }

    #[test]
    fn overlapping_near_coplanar_triangles_at_close_depths() {
        let cam = CameraModel { width: 64, height: 48, pitch_um: 10.0, focal_mm: 6.0, principal_point_px: [0.0, 0.0] };
        for gap in [0.0f32, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3] {
            // Two overlapping squares `gap` apart, the second turned a little in its plane
            // (their edges cross the first's); a third crossing both at a slant.
            let mut mesh = square(0.0, 0.0, 0.0, 0.2, 0);
            let mut b = square(0.013, -0.007, -gap, 0.15, 1);
            for p in &mut b.positions {
                let (x, y) = (p.x, p.y);
                (p.x, p.y) = (x * 0.999 - y * 0.0447, x * 0.0447 + y * 0.999);
            }
            mesh.append(&b);
            let mut c = square(-0.02, 0.01, 0.0, 0.12, 2);
            for p in &mut c.positions {
                p.z = 1e-4 * p.x;
            }
            mesh.append(&c);
            let a = DQuat::from_rotation_y(0.4) * DQuat::from_rotation_x(-0.2);
            let seen = same(&build(mesh, cam.clone(), pose(a, 2.0)), &format!("gap {gap}"));
            assert!(seen > 1000, "{seen}");
        }
    }

    #[test]
    fn targets_at_one_metre_and_at_a_thousand_kilometres() {
        let cam =
            CameraModel { width: 64, height: 48, pitch_um: 10.0, focal_mm: 10.0, principal_point_px: [1.5, -2.25] };
        let a = DQuat::from_rotation_y(0.5) * DQuat::from_rotation_x(0.2);
        let mut near = square(0.0, 0.0, 0.0, 0.2, 0);
        near.append(&square(0.03, 0.02, -0.05, 0.05, 1));
        let seen = same(&build(near, cam.clone(), pose(a, 1.0)), "1 m");
        assert!(seen > 1000, "{seen}");
        // 1000 km through a 1000 mm lens on 1 µm pixels (f = 10⁶ px): a 40 m plate.
        let tele = CameraModel { pitch_um: 1.0, focal_mm: 1000.0, ..cam };
        let mut far = square(0.0, 0.0, 0.0, 40.0, 0);
        far.append(&square(6.0, 4.0, -10.0, 10.0, 1));
        let seen = same(&build(far, tele, pose(a, 1.0e6)), "1000 km");
        assert!(seen > 500, "{seen}");
    }
}
