//! The renderer against answers computed independently (radiometry, projection).

use crate::common;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::View;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind};
use hilcam_core::render::{RenderOptions, render};

const E: f64 = 593.1;

fn plate_pose(range: f64, incidence_deg: f64) -> Pose {
    Pose { sun_dir: sun_at_incidence(incidence_deg), ..Pose::ahead(range) }
}

#[test]
fn lambert_plate_radiance_is_rho_e_cos_over_pi() {
    // 1 m plate at 10 m; 256 px, 20 µm, 40 mm: 1 m spans 200 px.
    let cam = camera(256, 256, 20.0, 40.0);
    for (incidence, sampler) in [(30.0, SamplerKind::Cosine), (60.0, SamplerKind::Uniform), (0.0, SamplerKind::Brdf)] {
        let settings = RenderSettings { spp: Spp::whole(2), depth: 1, sampler, seed: 1, ..Default::default() };
        let s = scene(
            square(0.0, 0.0, 0.0, 1.0, 0),
            vec![lambert("paint", 0.522)],
            cam.clone(),
            plate_pose(10.0, incidence),
            settings,
        );
        let (img, stats) = render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 0));
        let expected = 0.522 * E * incidence.to_radians().cos() / std::f64::consts::PI;
        let inner = inner_pixels(&img, 100.0, 2.0);
        let m = mean(&inner);
        assert!(((m - expected) / expected).abs() < 0.005, "incidence {incidence}: mean {m}, expected {expected}");
        // Direct light on a flat plate has no variance: every inner pixel is exact.
        for v in &inner {
            assert!(((*v as f64 - expected) / expected).abs() < 1e-4, "pixel {v} vs {expected}");
        }
        // Total flux: the plate covers 200×200 px of 256² (partial edge pixels included).
        let total: f64 = img.data.iter().map(|&x| x as f64).sum();
        assert!(((total / expected - 40_000.0) / 40_000.0).abs() < 0.005, "covered-pixel sum {}", total / expected);
        assert_eq!(stats.rays.nonfinite, 0);
    }
}

#[test]
fn half_shadowed_plate_is_exactly_zero_in_shadow_at_depth_1() {
    // A 1 m plate at z = 0 and a 0.5 m blocker over x ∈ [0.25, 0.75] at z = −2 m (body
    // frame). The sun shines along the plate normal, so the blocker's shadow falls straight
    // onto x ∈ [0.25, 0.75]. The camera looks from 40° off the normal so it sees the
    // shadowed plate area beside the blocker. Pixels are classified by independent
    // ray/plane maths on their centre rays.
    let cam = camera(256, 256, 20.0, 40.0);
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    mesh.append(&square(0.5, 0.0, -2.0, 0.5, 0));
    let settings =
        RenderSettings { spp: Spp::whole(4), depth: 1, sampler: SamplerKind::Cosine, seed: 3, ..Default::default() };
    let q = DQuat::from_rotation_y(40f64.to_radians());
    let pose = Pose { attitude: q, sun_dir: q * DVec3::new(0.0, 0.0, -1.0), ..Pose::ahead(10.0) };
    let s = scene(mesh, vec![lambert("paint", 0.522)], cam.clone(), pose, settings);
    let (img, _) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));

    let eye = -(q.inverse() * pose.position); // camera centre, body frame
    let f = cam.focal_px();
    let (mut lit, mut shadow) = (Vec::new(), Vec::new());
    for row in 0..cam.height {
        for col in 0..cam.width {
            let d = q.inverse() * DVec3::new((col as f64 + 0.5 - 128.0) / f, (row as f64 + 0.5 - 128.0) / f, 1.0);
            let on_blocker = eye + d * ((-2.0 - eye.z) / d.z);
            if (on_blocker.x - 0.5).abs() <= 0.27 && on_blocker.y.abs() <= 0.27 {
                continue; // the blocker hides the plate here
            }
            let p = eye + d * (-eye.z / d.z);
            // Keep 2 cm (≈ 1.5 px) from every edge so the whole pixel is in one class.
            if p.x.abs() > 0.48 || p.y.abs() > 0.23 {
                continue;
            }
            if p.x > 0.27 && p.x < 0.73 {
                shadow.push(img.get(col, row));
            } else if p.x < 0.23 {
                lit.push(img.get(col, row));
            }
        }
    }
    assert!(shadow.len() > 50 && lit.len() > 50, "{} shadow, {} lit pixels", shadow.len(), lit.len());
    assert!(shadow.iter().all(|&v| v == 0.0), "shadowed pixels must be exactly 0 at depth 1");
    let expected = 0.522 * E / std::f64::consts::PI; // sun along the plate normal
    let m = mean(&lit);
    assert!(((m - expected) / expected).abs() < 0.005, "lit mean {m} vs {expected}");
}

#[test]
fn same_bytes_whatever_the_thread_count() {
    let cam = camera(128, 96, 20.0, 30.0);
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    mesh.append(&square(0.2, 0.1, -0.3, 0.4, 0));
    let settings =
        RenderSettings { spp: Spp::whole(3), depth: 4, sampler: SamplerKind::Cosine, seed: 9, ..Default::default() };
    let s = scene(mesh, vec![lambert("paint", 0.8)], cam.clone(), plate_pose(3.0, 20.0), settings);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 7)).0)
    };
    let (a, b) = (run(1), run(2));
    let bytes = |img: &hilcam_core::render::film::RadianceImage| {
        img.data.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()
    };
    assert_eq!(bytes(&a), bytes(&b));
    assert!(a.data.iter().any(|&v| v > 0.0));
    // A different frame index gives different noise (the key includes it).
    let c = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 8)).0);
    assert_ne!(bytes(&a), bytes(&c));
}

#[test]
fn a_vertex_lands_on_the_pixel_the_pinhole_model_predicts() {
    // A tiny triangle (6 mm) around a body point; rotate and place the target; the lit
    // pixel must be the one the pinhole projection of that point predicts.
    // f = 500 px: the 6 mm triangle at 6 m spans half a pixel.
    let cam = camera(200, 150, 10.0, 5.0);
    let point = glam::Vec3::new(0.4, -0.3, 0.2);
    let tri = hilcam_core::render::geometry::TriMesh {
        positions: vec![
            point + glam::Vec3::new(-3e-3, -3e-3, 0.0),
            point + glam::Vec3::new(3e-3, -3e-3, 0.0),
            point + glam::Vec3::new(0.0, 3e-3, 0.0),
        ],
        indices: vec![[0, 1, 2]],
        material: vec![0],
    };
    // Plus a far-away dummy so the bounds are not centred on the point.
    let mut mesh = tri;
    mesh.append(&square(-0.5, 0.5, -0.5, 0.01, 0));
    let q = DQuat::from_euler(glam::EulerRot::ZYX, 0.3, -0.2, 0.1);
    let pose = Pose {
        position: DVec3::new(0.05, -0.04, 6.0),
        attitude: q,
        sun_dir: q * DVec3::new(0.0, 0.0, -1.0),
        ..Pose::ahead(6.0)
    };
    let settings =
        RenderSettings { spp: Spp::whole(64), depth: 1, sampler: SamplerKind::Cosine, seed: 0, ..Default::default() };
    let s = scene(mesh, vec![lambert("paint", 0.5)], cam.clone(), pose, settings);
    let (img, _) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
    let p_cam = q * point.as_dvec3() + pose.position;
    let [x, y] = View::project_camera_point(&cam, p_cam).unwrap();
    // Brightest pixel in the neighbourhood of the prediction.
    let (mut best, mut at) = (0.0f32, (0u32, 0u32));
    for row in 0..cam.height {
        for col in 0..cam.width {
            if (col as f64 - x).abs() < 20.0 && (row as f64 - y).abs() < 20.0 && img.get(col, row) > best {
                best = img.get(col, row);
                at = (col, row);
            }
        }
    }
    assert!(best > 0.0, "triangle not seen");
    assert_eq!(at, (x.floor() as u32, y.floor() as u32), "predicted ({x:.3}, {y:.3})");
}

/// Render `mesh` at `near` and `far` range with the focal length scaled by far/near (same
/// image size) and return the relative L1 difference of the two images.
fn range_difference(mesh: hilcam_core::render::geometry::TriMesh, attitude: DQuat, near: f64, far: f64) -> f64 {
    let cam_near = camera(96, 96, 20.0, 40.0);
    let cam_far = camera(96, 96, 20.0, 40.0 * far / near);
    let settings =
        RenderSettings { spp: Spp::whole(4), depth: 2, sampler: SamplerKind::Cosine, seed: 5, ..Default::default() };
    let near_pose = Pose { attitude, sun_dir: sun_at_incidence(35.0), ..Pose::ahead(near) };
    let far_pose = Pose { position: DVec3::new(0.0, 0.0, far), ..near_pose };
    let s = scene(mesh, vec![lambert("paint", 0.7), lambert("dark", 0.1)], cam_near.clone(), near_pose, settings);
    let (a, _) = render(&s, &s.view(&cam_near, &near_pose), &RenderOptions::new(settings, 0));
    let (b, _) = render(&s, &s.view(&cam_far, &far_pose), &RenderOptions::new(settings, 0));
    let total: f64 = a.data.iter().map(|&v| v as f64).sum();
    assert!(total > 0.0 && b.data.iter().all(|v| v.is_finite()));
    a.data.iter().zip(&b.data).map(|(x, y)| (*x as f64 - *y as f64).abs()).sum::<f64>() / total
}

#[test]
fn range_10m_and_1e6m_give_the_same_image() {
    // A fronto-parallel pattern images identically at any range once the focal length
    // scales with it (x = f·X/Z), so any difference is numerical.
    // The dark square lies 0.1 mm in front of the bright one (toward the camera at −z):
    // coplanar overlapping triangles would tie in depth to within rounding, and which of
    // the two a ray then reports depends on the last bit of its distances.
    let mut flat = square(0.0, 0.0, 0.0, 1.0, 0);
    flat.append(&square(0.2, -0.1, -1e-4, 0.3, 1));
    let d = range_difference(flat, DQuat::IDENTITY, 10.0, 1e6);
    assert!(d < 1e-3, "fronto-parallel, 10 m vs 1e6 m: relative L1 difference {d}");
    // A 3-D target (tilted, with a shadow caster and inter-reflections) changes with
    // perspective at 10 m, so compare 1 km with 1000 km: both effectively orthographic.
    let mut solid = square(0.0, 0.0, 0.0, 1.0, 0);
    solid.append(&square(0.1, 0.1, -0.2, 0.3, 1));
    let d = range_difference(solid, DQuat::from_rotation_y(0.3), 1e3, 1e6);
    assert!(d < 1e-3, "3-D target, 1 km vs 1000 km: relative L1 difference {d}");
}

#[test]
fn target_out_of_view_costs_nothing_and_is_background() {
    let cam = camera(64, 64, 20.0, 40.0);
    let settings = RenderSettings::default();
    let behind = Pose { position: DVec3::new(0.0, 0.0, -10.0), ..Pose::ahead(10.0) };
    let aside = Pose { position: DVec3::new(50.0, 0.0, 10.0), ..Pose::ahead(10.0) };
    let s = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam.clone(), behind, settings);
    for pose in [behind, aside] {
        let (img, stats) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
        assert!(img.data.iter().all(|&v| v == 0.0));
        assert_eq!(stats.rays.total(), 0);
        assert_eq!(stats.traced_pixels, 0);
    }
}

#[test]
fn far_small_target_traces_only_the_pixels_near_it() {
    let cam = camera(512, 512, 20.0, 40.0);
    let settings = RenderSettings { spp: Spp::whole(1), depth: 1, ..Default::default() };
    let s =
        scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam.clone(), Pose::ahead(100.0), settings);
    let (_, stats) = render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 0));
    // 1 m at 100 m with a 2000 px focal length: 20 px; its bounding sphere ≈ 28 px wide.
    assert!(stats.traced_pixels < 40 * 40, "{} pixels traced", stats.traced_pixels);
    assert!(stats.traced_pixels >= 20 * 20);
}

#[test]
fn lambert_furnace_returns_albedo_times_background_for_every_sampler() {
    // A convex (flat, two-sided) Lambert plate under a uniform sky of radiance 1 and no
    // sun: every bounce ray escapes, so the plate's radiance is exactly ρ·L_sky.
    let cam = camera(64, 64, 20.0, 40.0);
    let rho = 0.8;
    for sampler in [SamplerKind::Uniform, SamplerKind::Cosine, SamplerKind::Brdf] {
        let settings = RenderSettings { spp: Spp::whole(64), depth: 3, sampler, seed: 11, ..Default::default() };
        let mut s =
            scene(square(0.0, 0.0, 0.0, 2.0, 0), vec![lambert("paint", rho)], cam.clone(), Pose::ahead(5.0), settings);
        s.sun_irradiance = 0.0;
        s.background = 1.0;
        let (img, _) = render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 0));
        // The plate fills the frame (2 m at 5 m with a 2000 px focal length = 800 px).
        let m = mean(&img.data);
        // Uniform sampling has the most variance: σ/√N ≈ 0.57·ρ/√(64·4096) ≈ 1e-3.
        assert!((m - rho as f64).abs() < 0.01, "{sampler:?}: mean {m}, expected {rho}");
        if sampler == SamplerKind::Cosine {
            // Cosine sampling of a Lambert BRDF has zero variance: every sample is ρ.
            assert!(img.data.iter().all(|&v| (v - rho).abs() < 1e-5));
        }
    }
}

#[test]
fn grazing_and_hidden_sun_give_finite_images() {
    let cam = camera(64, 64, 20.0, 40.0);
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    mesh.append(&square(0.1, 0.1, -0.2, 0.3, 0));
    // 89.9° grazing; exactly in the plates' plane; straight behind the target.
    for (sun, expect_lit) in [(sun_at_incidence(89.9), true), (DVec3::X, false), (DVec3::Z, false)] {
        let deg = sun.angle_between(-DVec3::Z).to_degrees();
        let settings = RenderSettings {
            spp: Spp::whole(4),
            depth: 4,
            sampler: SamplerKind::Cosine,
            seed: 2,
            ..Default::default()
        };
        let pose = Pose { sun_dir: sun, ..Pose::ahead(5.0) };
        let s = scene(mesh.clone(), vec![lambert("paint", 0.9)], cam.clone(), pose, settings);
        let (img, stats) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
        assert!(img.data.iter().all(|v| v.is_finite() && *v >= 0.0), "sun at {deg}°");
        assert_eq!(stats.rays.nonfinite, 0);
        // Sun behind the target: the camera-facing sides see no sunlight at all.
        assert_eq!(img.data.iter().any(|&v| v > 0.0), expect_lit, "sun at {deg}°");
    }
}

#[test]
fn sobol_and_independent_sequences_agree_in_the_mean_and_sobol_converges_faster() {
    use hilcam_core::render::sampling::Sequence;
    // Uniform sky, uniform hemisphere sampling (the noisiest estimator): the exact answer
    // is ρ·L on every plate pixel, so per-pixel error is measurable.
    let cam = camera(64, 64, 20.0, 40.0);
    let rho = 0.6f32;
    let run = |sequence, spp| {
        let settings = RenderSettings {
            spp: Spp::whole(spp),
            depth: 2,
            sampler: SamplerKind::Uniform,
            sequence,
            roulette: true,
            adaptive: false,
            quality: hilcam_core::render::integrator::QualityGoal::FIXED,
            method: Default::default(),
            seed: 21,
        };
        let mut s =
            scene(square(0.0, 0.0, 0.0, 2.0, 0), vec![lambert("paint", rho)], cam.clone(), Pose::ahead(5.0), settings);
        s.sun_irradiance = 0.0;
        s.background = 1.0;
        render(&s, &s.view(&cam, &s.pose), &RenderOptions::new(settings, 0)).0
    };
    let rmse = |img: &hilcam_core::render::film::RadianceImage| {
        (img.data.iter().map(|&v| ((v - rho) as f64).powi(2)).sum::<f64>() / img.data.len() as f64).sqrt()
    };
    let (ind, sob) = (run(Sequence::Independent, 16), run(Sequence::Sobol, 16));
    // Unbiased: both means within 4σ of ρ (σ of the image mean ≈ 0.57ρ/√(16·4096)).
    let sigma = 0.577 * rho as f64 / (16.0f64 * 4096.0).sqrt();
    for (name, img) in [("independent", &ind), ("sobol", &sob)] {
        let m = mean(&img.data);
        assert!((m - rho as f64).abs() < 4.0 * sigma, "{name}: mean {m}, expected {rho} ± {sigma}");
    }
    // Stratification pays: at 16 spp the Sobol error is well below the independent one.
    let (e_ind, e_sob) = (rmse(&ind), rmse(&sob));
    assert!(e_sob < 0.6 * e_ind, "rmse sobol {e_sob} vs independent {e_ind}");
}

#[test]
fn russian_roulette_is_unbiased() {
    // A V-shaped pair of bright plates: most energy after the first bounce comes from
    // inter-reflection, where roulette acts. Means with and without it must agree.
    let cam = camera(48, 48, 20.0, 30.0);
    let mut mesh = square(0.0, 0.0, 0.0, 1.0, 0);
    let mut wall = square(0.0, 0.0, 0.0, 1.0, 0);
    for p in &mut wall.positions {
        *p = glam::Vec3::new(0.5, p.y, -(p.x + 0.5)); // the plane x = 0.5, from z = 0 to −1
    }
    mesh.append(&wall);
    let run = |roulette| {
        let settings = RenderSettings {
            spp: Spp::whole(64),
            depth: 4,
            sampler: SamplerKind::Cosine,
            roulette,
            seed: 8,
            ..Default::default()
        };
        let pose = Pose {
            attitude: DQuat::from_rotation_y(-0.4),
            sun_dir: DVec3::new(-0.6, 0.2, -0.77).normalize(),
            ..Pose::ahead(3.0)
        };
        let s = scene(mesh.clone(), vec![lambert("paint", 0.9)], cam.clone(), pose, settings);
        let (img, stats) = render(&s, &s.view(&cam, &pose), &RenderOptions::new(settings, 0));
        (mean(&img.data), stats.rays.bounce)
    };
    let ((with, rays_with), (without, rays_without)) = (run(true), run(false));
    assert!(with > 0.0);
    assert!(((with - without) / without).abs() < 0.01, "mean with roulette {with}, without {without}");
    assert!(rays_with < rays_without, "roulette must save bounce rays: {rays_with} vs {rays_without}");
}
