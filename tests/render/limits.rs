//! `[limits]` (issue 38): the pose range and mesh scale gates as scene settings, refused
//! by name beyond their defaults and ceilings, and a target rendered at the ceilings
//! (100 AU, scale 10⁹) where the pinhole puts it, with the radiance the algebra gives.

use hilcam_core::pipeline::FramePipeline;
use hilcam_core::scene::limits::{MAX_RANGE_CEILING_M, MAX_SCALE_CEILING};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A scene file in `dir`: the 1 m plate scaled by `scale` at `position`, a 64² camera
/// with 16 µm pixels and a 6 m focal length (IFOV 2.67 µrad, the paper's camera), sun at
/// 30° incidence, depth 1, and `extra` TOML.
fn plate_scene(dir: &Path, scale: f64, position: [f64; 3], extra: &str) -> PathBuf {
    let plate = std::fs::canonicalize("scenes/meshes/plate.obj").unwrap();
    let text = format!(
        "{extra}\n[camera]\nwidth = 64\nheight = 64\npitch_um = 16.0\nfocal_mm = 6000.0\n\
         [[mesh]]\nobj = {plate:?}\nscale = {scale:e}\n\
         [materials.white_paint]\nmodel = \"lambert\"\nrho = 0.522\n\
         [pose]\nposition = [{:e}, {:e}, {:e}]\nsun = [0.5, 0.0, -0.8660254037844386]\n\
         [render]\nspp = 64\ndepth = 1\n",
        position[0], position[1], position[2]
    );
    let p = dir.join("s.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn load_err(p: &Path) -> String {
    match hilcam_core::scene::load(p) {
        Ok(_) => panic!("{} loaded", p.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn range_and_scale_beyond_the_defaults_are_refused_by_name_and_accepted_with_limits() {
    let dir = tempfile::tempdir().unwrap();
    let far = [0.0, 0.0, 2.0e7];
    let e = load_err(&plate_scene(dir.path(), 1.0, far, ""));
    assert!(e.contains("pose.position") && e.contains("[limits] max_range_m") && e.contains("1e7 m"), "{e}");
    assert!(hilcam_core::scene::load(&plate_scene(dir.path(), 1.0, far, "[limits]\nmax_range_m = 3e7")).is_ok());
    let e = load_err(&plate_scene(dir.path(), 1.0e7, [0.0, 0.0, 1e5], ""));
    assert!(e.contains("mesh[0].scale") && e.contains("[limits] max_scale") && e.contains("1000000]"), "{e}");
    assert!(
        hilcam_core::scene::load(&plate_scene(
            dir.path(),
            1.0e7,
            [0.0, 0.0, 1e9],
            "[limits]\nmax_scale = 1e7\nmax_range_m = 1e10"
        ))
        .is_ok()
    );
    // Above the ceilings (and non-numbers) the limits themselves are refused, by key.
    for (extra, key) in [
        ("[limits]\nmax_range_m = 1e14", "limits.max_range_m"),
        ("[limits]\nmax_scale = 1e10", "limits.max_scale"),
        ("[limits]\nmax_range_m = nan", "limits.max_range_m"),
        ("[limits]\nmax_range = 1e8", "unknown field `max_range`"),
    ] {
        let e = load_err(&plate_scene(dir.path(), 1.0, [0.0, 0.0, 10.0], extra));
        assert!(e.contains(key), "{extra}: {e}");
    }
    let e = load_err(&plate_scene(dir.path(), 1.0, [0.0, 0.0, 10.0], "[limits]\nmax_range_m = 1e14"));
    assert!(e.contains("15000000000000"), "the ceiling is named: {e}");
}

#[test]
fn a_target_at_the_ceilings_lands_where_the_pinhole_puts_it_with_its_radiance() {
    // A plate 10⁹ m across (scale at its ceiling) facing the camera at z = 1.49·10¹³ m,
    // 8.3 px right of and 5.1 px above the axis: range < 1.5·10¹³ m (the range ceiling).
    let dir = tempfile::tempdir().unwrap();
    let (f_px, z): (f64, f64) = (6.0 / 16e-6, 1.49e13);
    let (dx, dy) = (8.3, -5.1);
    let pos = [dx * z / f_px, dy * z / f_px, z];
    let range = (pos[0] * pos[0] + pos[1] * pos[1] + z * z).sqrt();
    assert!(range < MAX_RANGE_CEILING_M);
    let extra = format!("[limits]\nmax_range_m = {MAX_RANGE_CEILING_M:e}\nmax_scale = {MAX_SCALE_CEILING:e}");
    let scene = hilcam_core::scene::load(&plate_scene(dir.path(), MAX_SCALE_CEILING, pos, &extra)).unwrap();
    let (pose, settings, camera) = (scene.pose, scene.render, scene.camera.clone());
    let pipeline = FramePipeline::new(Arc::new(scene), camera).unwrap();
    let (img, _) = pipeline.radiance(&pose, &settings, 0);
    assert!(img.data.iter().all(|v| v.is_finite() && *v >= 0.0), "a non-finite or negative pixel");
    // L = ρ·E·cos 30°/π on every pixel the plate covers.
    let l = 0.522 * 593.1 * 0.8660254037844386 / std::f64::consts::PI;
    let side_px = MAX_SCALE_CEILING * f_px / z; // 25.2 px
    let (cx, cy) = (32.0 + dx, 32.0 + dy);
    let (mut sx, mut sy, mut s, mut inner) = (0.0, 0.0, 0.0, 0);
    for (i, &v) in img.data.iter().enumerate() {
        let (x, y) = ((i % 64) as f64 + 0.5, (i / 64) as f64 + 0.5);
        sx += x * v as f64;
        sy += y * v as f64;
        s += v as f64;
        // Pixels wholly inside the plate's square (a pixel's reach is ±0.5 px).
        if (x - cx).abs() < side_px / 2.0 - 0.5 && (y - cy).abs() < side_px / 2.0 - 0.5 {
            assert!((v as f64 / l - 1.0).abs() < 1e-5, "pixel ({x}, {y}): {v} vs {l}");
            inner += 1;
        }
    }
    assert!(inner > 400, "{inner} inner pixels");
    // A square perpendicular to the boresight projects to a square: its centroid is the
    // projection of its centre, its flux L·side².
    let (gx, gy) = (sx / s, sy / s);
    println!(
        "ceiling: centroid off by ({:.4}, {:.4}) px, flux {:.5} of L·side², {inner} inner pixels",
        gx - cx,
        gy - cy,
        s / (l * side_px * side_px)
    );
    assert!((gx - cx).abs() < 0.02 && (gy - cy).abs() < 0.02, "centroid ({gx:.4}, {gy:.4}) vs pinhole ({cx}, {cy})");
    assert!((s / (l * side_px * side_px) - 1.0).abs() < 2e-3, "flux {s} vs {}", l * side_px * side_px);
}
