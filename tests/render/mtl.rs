//! OBJ + MTL as authored: a material without a `[materials.NAME]` table is built from
//! the MTL's own keys, its unused keys are reported by file and line, and a table still
//! overrides it. Radiance against the analytic Lambert plate, ρ·E·cosθ/π.

use crate::common;
use common::logs::load_logged;
use hilcam_core::render::bsdf::Bsdf;
use hilcam_core::render::{RenderOptions, render};
use std::path::Path;

const E: f64 = 593.1;

/// A 1 m plate facing the camera at 10 m (200 px across at 256²), sun at 30°, depth 1.
fn write_plate(dir: &Path, mtl: &str, materials: &str) -> std::path::PathBuf {
    std::fs::write(
        dir.join("panel.obj"),
        "mtllib panel.mtl\nv -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0.5 0.5 0\nv -0.5 0.5 0\nusemtl panel\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    std::fs::write(dir.join("panel.mtl"), mtl).unwrap();
    let scene = format!(
        "[camera]\nwidth = 256\nheight = 256\npitch_um = 20.0\nfocal_mm = 40.0\n\
         [[mesh]]\nobj = \"panel.obj\"\n{materials}\n[sun]\nirradiance = {E}\n\
         [pose]\nposition = [0.0, 0.0, 10.0]\nsun = [0.5, 0.0, -0.8660254037844386]\n\
         [render]\nspp = 2\ndepth = 1\n"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    path
}

/// The mean over pixels 2 px inside the plate's 200 px image.
fn plate_mean(scene: &hilcam_core::scene::Scene) -> (f64, f64) {
    let settings = scene.render;
    let (img, _) = render(scene, &scene.view(&scene.camera, &scene.pose), &RenderOptions::new(settings, 0));
    let v: Vec<f64> = (0..img.height)
        .flat_map(|r| (0..img.width).map(move |c| (c, r)))
        .filter(|&(c, r)| (c as f64 + 0.5 - 128.0).abs() < 98.0 && (r as f64 + 0.5 - 128.0).abs() < 98.0)
        .map(|(c, r)| f64::from(img.get(c, r)))
        .collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let spread = v.iter().fold(0.0f64, |m, x| m.max((x - mean).abs()));
    (mean, spread)
}

#[test]
fn an_mtl_plate_without_a_materials_table_renders_its_kd() {
    // Kd's band value is the mean of its three: (0.3 + 0.5 + 0.7)/3 = 0.5.
    let dir = tempfile::tempdir().unwrap();
    let path = write_plate(dir.path(), "newmtl panel\nKd 0.3 0.5 0.7\nPs 0.2\nillum 2\nmap_Kd cells.png\n", "");
    let (scene, log) = load_logged(&path);
    let scene = scene.unwrap();
    let want = 0.5 * E * 30f64.to_radians().cos() / std::f64::consts::PI;
    let (mean, spread) = plate_mean(&scene);
    assert!(((mean - want) / want).abs() < 1e-4, "mean {mean} vs ρ·E·cosθ/π = {want}");
    assert!(spread / want < 1e-4, "direct light on a flat plate is exact per pixel: spread {spread}");
    // Every key the MTL has and hilcam does not use is in the load log, by file and line.
    // `map_Kd` on faces without `vt`: a warning naming it, and the plate renders its `Kd`.
    for want in [
        "`Ps` ignored: panel.mtl:3",
        "`illum` ignored: panel.mtl:4",
        "cells.png` ignored:",
        "has no texture coordinates (`vt`, TEXCOORD_0) for it; its factor is used: panel.mtl:5",
    ] {
        assert!(log.contains(want), "log lacks {want}:\n{log}");
    }
    assert!(log.contains("material from the model file"), "{log}");
}

#[test]
fn a_materials_table_overrides_the_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_plate(
        dir.path(),
        "newmtl panel\nKd 0.3 0.5 0.7\nPs 0.2\n",
        "[materials.panel]\nmodel = \"lambert\"\nrho = 0.2\n",
    );
    let (scene, log) = load_logged(&path);
    let scene = scene.unwrap();
    assert_eq!(scene.target.materials.len(), 1);
    assert_eq!(scene.target.materials[0].bsdf, Bsdf::Lambert(hilcam_core::render::bsdf::Lambert::new(0.2).unwrap()));
    let want = 0.2 * E * 30f64.to_radians().cos() / std::f64::consts::PI;
    let (mean, _) = plate_mean(&scene);
    assert!(((mean - want) / want).abs() < 1e-4, "mean {mean} vs {want}");
    // The MTL's material was not used, so its keys are not reported.
    assert!(!log.contains("`Ps`"), "{log}");
}

#[test]
fn a_pbr_mtl_material_is_ggx_and_a_bad_value_names_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_plate(dir.path(), "newmtl panel\nKd 0.9 0.9 0.9\nPr 0.4\nPm 1\n", "");
    let (scene, _) = load_logged(&path);
    let scene = scene.unwrap();
    assert_eq!(scene.target.materials[0].bsdf.model_name(), "ggx_conductor");
    let path = write_plate(dir.path(), "newmtl panel\nKd 0.9 0.9 0.9\nPr 0.4\nPm 7\n", "");
    let e = load_logged(&path).0.err().unwrap();
    assert!(e.contains("panel.mtl:4: Pm: 7 must be in [0, 1]") && e.contains("scene.toml"), "{e}");
}

#[test]
fn a_name_two_files_define_differently_uses_the_first_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = write_plate(d, "newmtl panel\nKd 0.3 0.5 0.7\n", "");
    std::fs::write(d.join("b.obj"), "mtllib b.mtl\nv 2 0 0\nv 3 0 0\nv 2 1 0\nusemtl panel\nf 1 2 3\n").unwrap();
    std::fs::write(d.join("b.mtl"), "newmtl panel\nKd 0.9 0.9 0.9\n").unwrap();
    let text = std::fs::read_to_string(&path).unwrap().replace("[sun]", "[[mesh]]\nobj = \"b.obj\"\n[sun]");
    std::fs::write(&path, text).unwrap();
    let (scene, log) = load_logged(&path);
    let scene = scene.unwrap();
    assert_eq!(scene.target.materials.len(), 1);
    assert_eq!(scene.target.materials[0].bsdf.is_lambertian(), Some(0.5));
    assert!(log.contains("b.obj differs from the one") && log.contains("panel.obj defines"), "{log}");
}
