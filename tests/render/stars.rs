//! The star field (`render::stars`): photometry through the whole sensor chain, placement
//! by the camera's inertial attitude (through a distorting lens too), occlusion by the
//! target, determinism, and nothing changed when no star is drawn. Each against an answer
//! computed here from the catalogue's numbers and the pinhole model written out.

use crate::common::scenes::{camera, lambert, scene, square};
use glam::{DQuat, DVec2, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::camera::distortion::Distortion;
use hilcam_core::render::film::{Pixels, RadianceImage};
use hilcam_core::render::integrator::{RenderSettings, Spp};
use hilcam_core::render::stars::{Star, StarField, V_ZERO_FLUX_W_M2_NM};
use hilcam_core::render::{RenderOptions, RenderStats, render};
use hilcam_core::scene::Scene;
use hilcam_core::sensor::config::{AdcConfig, BandConfig, PsfConfig};
use hilcam_core::sensor::{Sensor, SensorConfig};

const H: f64 = 6.626_070_15e-34;
const C: f64 = 299_792_458.0;

/// 96 × 80 pixels of 5.5 µm behind a 16 mm lens: 3.44e-4 rad per pixel.
fn cam() -> CameraModel {
    CameraModel { principal_point_px: [1.25, -0.75], ..camera(96, 80, 5.5, 16.0) }
}

/// A 5 cm plate 10 m ahead (≈ 14.5 px across, at the image centre), black unless `rho`
/// is given, with `stars` behind it.
fn plate_scene(rho: f32, stars: Vec<Star>) -> Scene {
    let pose = Pose { camera_to_inertial: Some(DQuat::IDENTITY), ..Pose::ahead(10.0) };
    let settings = RenderSettings { spp: Spp::whole(2), depth: 1, ..Default::default() };
    let mut s = scene(square(0.0, 0.0, 0.0, 0.05, 0), vec![lambert("plate", rho)], cam(), pose, settings);
    s.stars = Some(StarField { stars, zero_point_w_m2: zero_point(), default_camera_to_inertial: DQuat::IDENTITY });
    s
}

/// Band irradiance of V = 0 over 0.45–0.75 µm: Bessell et al. (1998) V flux × 300 nm.
fn zero_point() -> f64 {
    3.63e-11 * 300.0
}

/// A star of magnitude `v` toward camera-frame direction `d` (identity attitude).
fn star(hr: u32, d: DVec3, v: f64) -> Star {
    Star { hr, dir: d.normalize(), vmag: v, irradiance_w_m2: zero_point() * 10f64.powf(-0.4 * v) }
}

/// Direction whose pinhole image is pixel coordinate (x, y) of `cam()`.
fn toward(x: f64, y: f64) -> DVec3 {
    let c = cam();
    let f = c.focal_px();
    DVec3::new((x - 48.0 - c.principal_point_px[0]) / f, (y - 40.0 - c.principal_point_px[1]) / f, 1.0)
}

/// Pinhole image point of camera-frame direction `d`, written out from the README's
/// convention (not through `View`).
fn pinhole(d: DVec3) -> [f64; 2] {
    let c = cam();
    let f = c.focal_px();
    [d.x / d.z * f + 48.0 + c.principal_point_px[0], d.y / d.z * f + 40.0 + c.principal_point_px[1]]
}

fn frame(s: &Scene, pose: &Pose) -> (RadianceImage, RenderStats) {
    render(s, &s.view(&s.camera, pose), &RenderOptions::new(s.render, 0))
}

/// Sum and centroid of `img` over the 6 × 6 pixels around (x, y).
fn blob(img: &RadianceImage, [x, y]: [f64; 2]) -> (f64, [f64; 2]) {
    let (mut sum, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for r in (y as i64 - 3)..(y as i64 + 3) {
        for c in (x as i64 - 3)..(x as i64 + 3) {
            let v = f64::from(img.data[(r * i64::from(img.width) + c) as usize]);
            (sum, sx, sy) = (sum + v, sx + v * (c as f64 + 0.5), sy + v * (r as f64 + 0.5));
        }
    }
    (sum, [sx / sum, sy / sum])
}

#[test]
fn zero_point_is_bessell_johnson_v() {
    assert_eq!(V_ZERO_FLUX_W_M2_NM, 3.63e-11);
}

#[test]
fn a_stars_dn_sum_is_its_irradiance_times_aperture_qe_and_integration_time() {
    // V = 2 star, off the plate; black plate, zero background: every DN is the star's.
    let v = 2.0;
    let at = [20.3, 61.8];
    let s = plate_scene(0.0, vec![star(1, toward(at[0], at[1]), v)]);
    let (img, stats) = frame(&s, &s.pose);
    assert_eq!((stats.stars.in_view, stats.stars.hidden), (1, 0));
    let (n, tau, qe, t, gain) = (4.0, 0.9, 0.5, 1.0, 0.25);
    let mut cfg = SensorConfig {
        band: Some(BandConfig { min_um: 0.45, max_um: 0.75 }),
        detector: Some(crate::sensor::quiet_detector(t)),
        adc: Some(AdcConfig { bits: 16, gain_e_per_dn: gain, offset_dn: 0.0 }),
        ..Default::default()
    };
    cfg.optics.f_number = Some(n);
    cfg.optics.transmittance = Some(tau);
    cfg.optics.psf = Some(PsfConfig::Gaussian { sigma_px: 1.0 });
    let out = Sensor::new(&s.camera, &cfg).unwrap().apply(&img, 0).unwrap();
    let Pixels::Mono16 { data, .. } = &out.pixels else { panic!("16-bit DN") };
    let dn_sum: f64 = data.iter().map(|&d| f64::from(d)).sum();
    let lit = data.iter().filter(|&&d| d > 0).count() as f64;
    // Expected: E · A · τ · QE · t photons' worth of electrons, at the band's mean
    // wavelength 0.6 µm for a flat spectrum and a constant QE, over the gain.
    let e = 3.63e-11 * 300.0 * 10f64.powf(-0.4 * v);
    let aperture = std::f64::consts::PI * (16e-3 / n / 2.0).powi(2);
    let electrons = e * aperture * tau * qe * t * 0.6e-6 / (H * C);
    let want = electrons / gain;
    // Each pixel's DN is rounded to the nearest integer (≤ 0.5 DN off); f32 radiance
    // carries ~1e-7 relative. The Gaussian kernel (radius 5σ) keeps the star far from
    // the edges, so it loses nothing.
    let tol = 0.5 * lit + 1e-6 * want;
    assert!(want > 1e5, "{want}");
    assert!((dn_sum - want).abs() <= tol, "DN sum {dn_sum}, want {want} ± {tol}");
}

#[test]
fn stars_move_exactly_with_the_cameras_inertial_attitude() {
    let points = [[10.2, 12.9], [81.7, 15.05], [15.5, 70.5], [70.01, 66.66], [47.3, 8.8]];
    let stars: Vec<Star> = points.iter().enumerate().map(|(i, p)| star(i as u32, toward(p[0], p[1]), 3.0)).collect();
    let s = plate_scene(0.0, stars.clone());
    // A turn about the boresight, then a tilt about +Y: 2.3 px and 1.7° of roll.
    let attitudes = [
        DQuat::IDENTITY,
        DQuat::from_rotation_y(2.3 * 3.4375e-4),
        DQuat::from_rotation_z(1.7f64.to_radians()) * DQuat::from_rotation_x(-0.002),
    ];
    for q in attitudes {
        let pose = Pose { camera_to_inertial: Some(q), ..s.pose };
        let (img, _) = frame(&s, &pose);
        for st in &stars {
            let want = pinhole(q.inverse() * st.dir);
            let (sum, got) = blob(&img, want);
            assert!(sum > 0.0);
            // The bilinear split's centroid is the image point; f32 weights ≈ 1e-7 of a pixel.
            for k in 0..2 {
                assert!((got[k] - want[k]).abs() < 1e-4, "star {} at {got:?}, want {want:?}", st.hr);
            }
        }
    }
}

#[test]
fn through_a_distorting_lens_a_star_lands_where_the_lens_images_its_direction() {
    // Strong coefficients: the 96-px field reaches only r ≈ 0.02 (normalised), where a
    // navigation lens's k1 ≈ −0.08 would move the star by 1e-3 px.
    let d = Distortion { k1: 200.0, k2: 0.0, k3: 0.0, p1: 0.05, p2: -0.03 };
    let ideal = [12.4, 9.7];
    let s = plate_scene(0.0, vec![star(1, toward(ideal[0], ideal[1]), 3.0)]);
    let view = s.view(&s.camera, &s.pose).with_distortion(Some(d));
    let (img, _) = render(&s, &view, &RenderOptions::new(s.render, 0));
    // Brown–Conrady forward map in normalised coordinates about the principal point.
    let c = cam();
    let (f, pp) = (c.focal_px(), DVec2::new(48.0 + c.principal_point_px[0], 40.0 + c.principal_point_px[1]));
    let want = d.distort((DVec2::from(ideal) - pp) / f) * f + pp;
    assert!((want - DVec2::from(ideal)).length() > 0.5, "the lens moves the star {want}");
    let (_, got) = blob(&img, want.to_array());
    assert!((DVec2::from(got) - want).length() < 1e-4, "{got:?} vs {want}");
}

#[test]
fn a_star_behind_the_target_is_hidden_one_beside_it_is_not() {
    // The plate spans ≈ 14.5 px about the principal point (49.25, 39.25).
    let behind = star(1, toward(50.0, 41.0), 1.0);
    let beside = star(2, toward(49.0, 52.0), 1.0);
    let s = plate_scene(0.0, vec![behind, beside]);
    let (img, stats) = frame(&s, &s.pose);
    assert_eq!((stats.stars.in_view, stats.stars.hidden), (2, 1));
    assert_eq!(blob(&img, [50.0, 41.0]).0, 0.0, "hidden star drawn");
    let want = beside.irradiance_w_m2 * cam().focal_px().powi(2);
    let got = blob(&img, [49.0, 52.0]).0;
    assert!((got / want - 1.0).abs() < 1e-6, "{got} vs {want}");
    // Without the plate in the way (turned 40 px aside) both are drawn.
    let pose = Pose { camera_to_inertial: Some(DQuat::IDENTITY), ..Pose::ahead(10.0) };
    let aside = Pose { position: DVec3::new(40.0 * 3.4375e-4 * 10.0, 0.0, 10.0), ..pose };
    assert_eq!(frame(&s, &aside).1.stars.hidden, 0);
}

#[test]
fn same_bytes_for_any_thread_count() {
    let stars: Vec<Star> =
        (0..40).map(|i| star(i, toward(3.0 + 2.3 * i as f64, 5.0 + 1.7 * i as f64), i as f64 * 0.2)).collect();
    let mut s = plate_scene(0.5, stars);
    s.pose.sun_dir = DVec3::new(0.3, 0.2, -1.0).normalize();
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| frame(&s, &s.pose).0.data)
    };
    let one = run(1);
    assert!(one.iter().any(|&v| v > 1e-3), "a lit plate and stars");
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}

#[test]
fn no_star_in_view_changes_no_byte() {
    // Stars behind the camera and far outside the field: nothing is drawn, and the frame
    // is the frame of the scene without a star field.
    let away = vec![star(1, DVec3::new(0.0, 0.3, -1.0), 0.0), star(2, DVec3::new(1.0, 0.0, 0.1), 0.0)];
    let mut s = plate_scene(0.5, away);
    s.pose.sun_dir = DVec3::new(0.3, 0.2, -1.0).normalize();
    let (with, st) = frame(&s, &s.pose);
    assert_eq!(st.stars.in_view, 0);
    s.stars = None;
    assert_eq!(with.data, frame(&s, &s.pose).0.data);
}

/// A plate scene file (next to `scenes/plate.toml`, so its paths resolve) with `extra`.
fn parse_scene(pose_extra: &str, stars: &str) -> Result<hilcam_core::scene::SceneParts, String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let src = format!(
        "camera_file = \"../config/cameras/nav1024.toml\"\n[[mesh]]\nobj = \"meshes/plate.obj\"\n\
         [materials.white_paint]\nmodel = \"lambert\"\nrho = 0.5\n\
         [pose]\nposition = [0.0, 0.0, 10.0]\nsun = [0.0, 0.0, -1.0]\n{pose_extra}\n{stars}\n"
    );
    hilcam_core::scene::file::parse(&dir.join("plate_stars.toml"), &src).map_err(|e| e.to_string())
}

#[test]
fn scene_file_stars_need_an_inertial_attitude_and_read_the_catalogue() {
    let stars = "[stars]\ncatalogue = \"stars/bsc5.csv\"\nmax_vmag = 2.0";
    let e = parse_scene("", stars).err().unwrap();
    assert!(e.contains("pose.camera_to_inertial") && e.contains("[stars] needs"), "{e}");
    let e = parse_scene("camera_to_inertial = [1.0, 0.0, 0.0, 0.1]", stars).err().unwrap();
    assert!(e.contains(":10: pose.camera_to_inertial: norm"), "{e}");
    let parts = parse_scene("camera_to_inertial = [1.0, 0.0, 0.0, 0.0]", stars).unwrap();
    let field = parts.stars.unwrap();
    // BSC5 has 50 entries with V ≤ 2.0 (Sirius at −1.46 the brightest).
    assert_eq!(field.stars.len(), 50);
    let sirius = field.stars.iter().find(|s| s.hr == 2491).unwrap();
    assert_eq!(sirius.vmag, -1.46);
    // nav1024's band is 0.45–0.75 µm.
    assert!((field.zero_point_w_m2 - 3.63e-11 * 300.0).abs() < 1e-20);
    let e = parse_scene("camera_to_inertial = [1.0, 0.0, 0.0, 0.0]", "[stars]\ncatalogue = \"stars/none.csv\"")
        .err()
        .unwrap();
    assert!(e.contains("stars.catalogue") && e.contains("none.csv"), "{e}");
}

/// Issue 37: a finite zero point whose product with the brightest star and the pixel's
/// solid angle is not a finite f32 radiance rendered +inf pixels with exit 0.
#[test]
fn a_zero_point_that_makes_an_infinite_pixel_is_refused_by_line_and_key() {
    let q = "camera_to_inertial = [1.0, 0.0, 0.0, 0.0]";
    let stars = |z: &str| format!("[stars]\ncatalogue = \"stars/bsc5.csv\"\nmax_vmag = 2.0\nzero_point_w_m2 = {z}");
    let e = parse_scene(q, &stars("1e300")).err().expect("refused");
    assert!(e.contains(":14: stars.zero_point_w_m2: zero point 1e300") && e.contains("not finite"), "{e}");
    assert!(e.contains("HR 2491"), "names the brightest star (Sirius): {e}");
    assert!(parse_scene(q, &stars("1e3")).is_ok(), "a large but finite product is fine");
}

#[test]
fn a_window_of_the_sensor_gets_the_full_frames_stars_there() {
    use hilcam_core::render::camera::Window;
    let stars: Vec<Star> =
        (0..30).map(|i| star(i, toward(2.0 + 3.1 * i as f64, 3.0 + 2.6 * i as f64), 1.0 + 0.1 * i as f64)).collect();
    let s = plate_scene(0.0, stars);
    let (full, _) = frame(&s, &s.pose);
    let win = Window { x: 17, y: 11, width: 40, height: 50 };
    let view = s.view(&s.camera, &s.pose).window(&win);
    let (part, st) = render(&s, &view, &RenderOptions::new(s.render, 0));
    assert!(st.stars.in_view > 5, "{:?}", st.stars);
    for r in 0..win.height {
        for c in 0..win.width {
            let f = full.data[((r + win.y) * full.width + c + win.x) as usize];
            assert_eq!(part.data[(r * win.width + c) as usize].to_bits(), f.to_bits(), "({c}, {r})");
        }
    }
}

#[test]
fn reused_buffers_clear_the_last_frames_stars() {
    // Stars far above and below the plate's rows: the next frame through the same buffers
    // must not keep them when the attitude moves them.
    let s = plate_scene(0.5, vec![star(1, toward(10.5, 2.5), 0.0), star(2, toward(80.5, 77.5), 0.0)]);
    let turned = Pose { camera_to_inertial: Some(DQuat::from_rotation_y(0.004)), ..s.pose };
    let mut buffers = hilcam_core::render::FrameBuffers::<()>::default();
    for pose in [s.pose, turned] {
        let opts = RenderOptions::new(s.render, 0);
        hilcam_core::render::render_into(&mut buffers, &s, &s.view(&s.camera, &pose), &opts);
        assert_eq!(buffers.image().data, frame(&s, &pose).0.data);
    }
}

#[test]
fn a_star_behind_the_planet_is_hidden_one_above_its_limb_is_not() {
    use hilcam_core::render::planet::{Planet, PlanetModel};
    // A Moon-sized sphere 17 m below the camera: its limb (the horizon) dips
    // √(2h/R) = 4.5 mrad, 13 px, below the boresight, so it covers the rows below ≈ 52.
    // The stars are far from the plate.
    let r = 1.7374e6;
    let below = star(1, toward(10.0, 70.0), 1.0);
    let above = star(2, toward(10.0, 10.0), 1.0);
    let mut s = plate_scene(0.0, vec![below, above]);
    s.planet = Some(Planet {
        centre_cam: DVec3::new(0.0, r + 17.0, 0.0),
        radius_m: r,
        albedo: 0.12,
        model: PlanetModel::Lambert,
    });
    let (img, stats) = frame(&s, &s.pose);
    assert_eq!((stats.stars.in_view, stats.stars.hidden), (2, 1));
    // The upper star is drawn on the black sky with its full irradiance.
    let want = above.irradiance_w_m2 * cam().focal_px().powi(2);
    let got = blob(&img, [10.0, 10.0]).0;
    assert!((got / want - 1.0).abs() < 1e-6, "{got} vs {want}");
}
