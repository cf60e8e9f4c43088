//! OBJ faces as exporters write them: quads and n-gons (cut into fans), negative
//! (relative) indices and `v/vt/vn` vertices render the plate the triangles would, to the
//! analytic Lambert radiance ρ·E·cosθ/π; a face whose fan folds is reported by file and
//! line at load.

use hilcam_core::render::{RenderOptions, render};
use std::path::Path;

const E: f64 = 593.1;

/// A scene of `obj` (the 1 m plate facing the camera at 10 m, sun at 30°, Lambert 0.5).
fn plate_scene(dir: &Path, obj: &str) -> hilcam_core::scene::Scene {
    std::fs::write(dir.join("plate.obj"), obj).unwrap();
    let scene = format!(
        "[camera]\nwidth = 128\nheight = 128\npitch_um = 20.0\nfocal_mm = 40.0\n\
         [[mesh]]\nobj = \"plate.obj\"\n[materials.default]\nmodel = \"lambert\"\nrho = 0.5\n\
         [sun]\nirradiance = {E}\n[pose]\nposition = [0.0, 0.0, 10.0]\nsun = [0.5, 0.0, -0.8660254037844386]\n\
         [render]\nspp = 1\ndepth = 1\nmethod = \"hybrid\"\n"
    );
    std::fs::write(dir.join("s.toml"), scene).unwrap();
    hilcam_core::scene::load(&dir.join("s.toml")).unwrap()
}

fn image(scene: &hilcam_core::scene::Scene) -> Vec<f32> {
    render(scene, &scene.view(&scene.camera, &scene.pose), &RenderOptions::new(scene.render, 0)).0.data
}

const CORNERS: &str = "v -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0.5 0.5 0\nv -0.5 0.5 0\nvt 0 0\nvn 0 0 1\n";

#[test]
fn a_quad_a_pentagon_and_relative_indices_render_the_triangles_plate() {
    let dir = tempfile::tempdir().unwrap();
    let triangles = plate_scene(dir.path(), &format!("{CORNERS}f 1 3 2\nf 1 4 3\n"));
    let reference = image(&triangles);
    let want = 0.5 * E * 30f64.to_radians().cos() / std::f64::consts::PI;
    let centre = reference[64 * 128 + 64];
    assert!((f64::from(centre) - want).abs() < 1e-4 * want, "{centre} vs ρ·E·cosθ/π = {want}");
    // The same plate as one quad, as a quad of relative indices with texture and normal
    // indices, and as a pentagon with a vertex on an edge.
    for (what, obj, tris) in [
        ("quad", format!("{CORNERS}f 1 4 3 2\n"), 2),
        ("relative quad", format!("{CORNERS}f -4/1/1 -1/1/1 -2//1 -3\n"), 2),
        ("pentagon", format!("{CORNERS}v 0 -0.5 0\nf 1 4 3 2 5\n"), 3),
    ] {
        let scene = plate_scene(dir.path(), &obj);
        assert_eq!(scene.mesh.indices.len(), tris, "{what}");
        let img = image(&scene);
        for (i, (a, b)) in img.iter().zip(&reference).enumerate() {
            assert!((a - b).abs() <= 1e-5 * centre, "{what}: pixel {i}: {a} against {b} as triangles");
        }
    }
}

#[test]
fn a_face_whose_fan_folds_is_reported_by_file_and_line() {
    // An L-shaped hexagon that starts at a corner which does not see the notch.
    let obj = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 2 3 4 5 6 1\n";
    let ok = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 1 2 3 4 5 6\n";
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("l.obj"), obj).unwrap();
    std::fs::write(dir.path().join("ok.obj"), ok).unwrap();
    let folded = hilcam_core::scene::load_model(&dir.path().join("l.obj")).unwrap();
    assert_eq!(folded.notes.len(), 1, "{:?}", folded.notes);
    assert!(folded.notes[0].contains("folds over itself") && folded.notes[0].ends_with("l.obj:7"));
    let fine = hilcam_core::scene::load_model(&dir.path().join("ok.obj")).unwrap();
    assert!(fine.notes.is_empty(), "{:?}", fine.notes);
}
