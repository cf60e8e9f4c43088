//! Emitting surfaces (`Material::emission`) against answers computed here:
//! - a plate emitting L in the dark is L at every pixel, at any depth and with the hybrid
//!   method asked for; lit by the sun it is L + ρ·E·cosθ/π;
//! - an emitting square lights a Lambert floor as Lambert's polygon formula says
//!   (irradiance (L/2)·Σ γᵢ n·ĝᵢ over the square's edges, Arvo 1995), seen through one
//!   bounce;
//! - an MTL `Ke` is relative to sunlit white: `Ke` × E/π.

use crate::common::scenes::polygon_irradiance;
use glam::DVec3;
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::Scene;
use std::f64::consts::PI;
use std::path::Path;

const E: f64 = 593.1;
/// Toward the sun from behind the camera-facing plate (it lights the back face only),
/// and from in front of it at 30°.
const SUN_BEHIND: &str = "[0.5, 0.0, 0.8660254037844386]";
const SUN_FRONT: &str = "[0.5, 0.0, -0.8660254037844386]";

/// The frame to render: size (pixels, square), spp, depth, method.
struct Shot {
    side: u32,
    spp: u32,
    depth: u32,
    method: &'static str,
}

/// Load a scene of `obj` + `mtl` with `tables` (`[materials.*]`), the sun toward `sun`
/// (camera frame) and the camera of `texture.rs` (f = 2000 px, target 10 m ahead).
fn load(dir: &Path, obj: &str, mtl: &str, tables: &str, sun: &str, shot: &Shot) -> Scene {
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    let Shot { side, spp, depth, method } = shot;
    let text = format!(
        "[camera]\nwidth = {side}\nheight = {side}\npitch_um = 20.0\nfocal_mm = 40.0\n\
         [[mesh]]\nobj = \"m.obj\"\n{tables}\n[sun]\nirradiance = {E}\n\
         [pose]\nposition = [0.0, 0.0, 10.0]\nsun = {sun}\n\
         [render]\nspp = {spp}\ndepth = {depth}\nadaptive = false\nmethod = \"{method}\"\n"
    );
    std::fs::write(dir.join("s.toml"), text).unwrap();
    hilcam_core::scene::load(&dir.join("s.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn frame(s: &Scene) -> Vec<f64> {
    let (img, _) = render(s, &s.view(&s.camera, &s.pose), &RenderOptions::new(s.render, 0));
    img.data.iter().map(|&v| f64::from(v)).collect()
}

/// A 4 m plate facing the camera at 10 m: it fills a 64² frame (f = 2000 px).
const PLATE: &str = "mtllib m.mtl\nv -2 -2 0\nv 2 -2 0\nv 2 2 0\nv -2 2 0\nusemtl panel\nf 1 3 2\nf 1 4 3\n";

#[test]
fn an_emitting_plate_is_its_radiance_in_the_dark_and_adds_to_sunlight() {
    let dir = tempfile::tempdir().unwrap();
    let table = "[materials.panel]\nmodel = \"lambert\"\nrho = 0.3\nemission = 100.0\n";
    let mtl = "newmtl panel\nKd 0.3 0.3 0.3\n";
    for (method, depth) in [("path", 1), ("path", 3), ("hybrid", 1), ("hybrid", 3)] {
        let s = load(dir.path(), PLATE, mtl, table, SUN_BEHIND, &Shot { side: 64, spp: 4, depth, method });
        let worst = frame(&s).iter().map(|v| (v - 100.0).abs()).fold(0.0, f64::max);
        assert!(worst <= 1e-4, "{method}, depth {depth}: a pixel is off 100 by {worst}");
    }
    let s = load(dir.path(), PLATE, mtl, table, SUN_FRONT, &Shot { side: 64, spp: 4, depth: 2, method: "hybrid" });
    let want = 100.0 + 0.3 * E * 30f64.to_radians().cos() / PI;
    let worst = frame(&s).iter().map(|v| (v / want - 1.0).abs()).fold(0.0, f64::max);
    assert!(worst <= 1e-5, "emission + sunlight: off {want} by {worst} (relative)");
}

#[test]
fn an_mtl_ke_is_relative_to_sunlit_white() {
    let dir = tempfile::tempdir().unwrap();
    let shot = Shot { side: 16, spp: 1, depth: 1, method: "path" };
    let s = load(dir.path(), PLATE, "newmtl panel\nKd 0 0 0\nKe 0.2 0.4 0.6\n", "", SUN_BEHIND, &shot);
    assert!(s.target.texturing.is_none());
    let want = 0.4 * E / PI;
    let worst = frame(&s).iter().map(|v| (v / want - 1.0).abs()).fold(0.0, f64::max);
    assert!(worst <= 1e-5, "Ke 0.2 0.4 0.6: off {want} by {worst} (relative)");
}

#[test]
fn an_emitting_square_lights_a_lambert_floor_as_lambert_s_polygon_formula_says() {
    // Camera frame = body frame (identity attitude), target origin 10 m ahead. The floor
    // (20 m, ρ 0.5) faces the camera at 45°; a 1 m square emitting L hangs 1 m above its
    // centre, out of the central pixels' line of sight. The sun lights only the floor's
    // back and the square (ρ 0), so the floor's radiance is ρ/π × the square's irradiance.
    let n = DVec3::new(0.0, -1.0, -1.0).normalize();
    let (u, w) = (DVec3::X, DVec3::new(0.0, 1.0, -1.0).normalize());
    let quad = |c: DVec3, h: f64| [c - u * h - w * h, c + u * h - w * h, c + u * h + w * h, c - u * h + w * h];
    let floor = quad(DVec3::ZERO, 10.0);
    let lamp = quad(n, 0.5);
    let mut obj = String::from("mtllib m.mtl\n");
    for v in floor.iter().chain(&lamp) {
        obj += &format!("v {} {} {}\n", v.x, v.y, v.z);
    }
    obj += "usemtl floor\nf 1 2 3\nf 1 3 4\nusemtl lamp\nf 5 6 7\nf 5 7 8\n";
    const L: f64 = 1000.0;
    let tables = format!(
        "[materials.floor]\nmodel = \"lambert\"\nrho = 0.5\n[materials.lamp]\nmodel = \"lambert\"\nrho = 0.0\nemission = {L}\n"
    );
    let sun = format!("[{}, {}, {}]", -n.x, -n.y, -n.z);
    let (side, spp) = (32u32, 1024u32);
    let dir = tempfile::tempdir().unwrap();
    let shot = Shot { side, spp, depth: 3, method: "path" };
    let s = load(dir.path(), &obj, "newmtl floor\nnewmtl lamp\n", &tables, &sun, &shot);
    let img = frame(&s);

    // The central 16² pixels: each pixel centre's ray meets the floor at p (body frame).
    let f_px = 2000.0;
    let (mut got, mut want) = (0.0, 0.0);
    for r in side / 4..3 * side / 4 {
        for c in side / 4..3 * side / 4 {
            let d = DVec3::new(
                (f64::from(c) + 0.5 - f64::from(side) / 2.0) / f_px,
                (f64::from(r) + 0.5 - f64::from(side) / 2.0) / f_px,
                1.0,
            );
            let eye = DVec3::new(0.0, 0.0, -10.0);
            let t = -n.dot(eye) / n.dot(d);
            let p = eye + d * t;
            want += 0.5 / PI * L * polygon_irradiance(p, n, &lamp);
            got += img[(r * side + c) as usize];
        }
    }
    let count = f64::from(side * side / 4);
    let (got, want) = (got / count, want / count);
    // Each cosine-sampled bounce either meets the square (worth ρL) or escapes: a
    // Bernoulli of p = E/(πL); the mean over the pixels' samples has σ = ρL·√(p(1−p)/N).
    let p = want / (0.5 * L);
    let sigma = 0.5 * L * (p * (1.0 - p) / (count * f64::from(spp))).sqrt();
    eprintln!(
        "floor under the lamp: {got:.4} vs Lambert's formula {want:.4} ({:+.3} σ, σ = {:.2e} relative)",
        (got - want) / sigma,
        sigma / want
    );
    assert!((got - want).abs() < 5.0 * sigma, "floor {got} vs {want} (σ {sigma})");
    // The whole floor beyond the lamp's neighbourhood is dark only where the lamp is out
    // of its hemisphere; every pixel here sees some light.
    assert!(img.iter().all(|v| v.is_finite() && *v >= 0.0));
}
