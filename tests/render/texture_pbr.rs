//! Textured GGX roughness and metallic weight (glTF `metallicRoughnessTexture`, MTL
//! `map_Pr`/`map_Pm`) against untextured plates whose factors are the texels: each half
//! of a plate textured metal | plastic renders as the untextured plate of that half's
//! values, and the same texture given both ways renders the same.

use super::texture::{SIDE, frame, inner, plate_glb_with, png, write_obj, write_scene_lit};
use hilcam_core::scene::Scene;

const SUN: &str = "[0.5, 0.0, -0.8660254037844386]";
/// The texture's halves: (roughness, metallic) codes of the left and right.
const LEFT: (u8, u8) = (64, 255);
const RIGHT: (u8, u8) = (200, 0);

/// 64² RGB: G roughness, B metallic (glTF's packing), left half `LEFT`, right `RIGHT`.
fn metallic_roughness_png() -> Vec<u8> {
    let img = image::RgbImage::from_fn(64, 64, |x, _| {
        let (g, b) = if x < 32 { LEFT } else { RIGHT };
        image::Rgb([0, g, b])
    });
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    out
}

fn load(dir: &std::path::Path, name: &str, mesh: &str) -> Scene {
    hilcam_core::scene::load(&write_scene_lit(dir, name, mesh, 4, SUN)).unwrap_or_else(|e| panic!("{e}"))
}

/// A plate material of base colour 0.8 with the given factors and, if `textured`, the
/// metallic-roughness texture (texture 0).
fn material(roughness: f64, metallic: f64, textured: bool) -> String {
    let tex = if textured { r#","metallicRoughnessTexture":{"index":0}"# } else { "" };
    format!(
        r#"{{"name":"panel","pbrMetallicRoughness":{{"baseColorFactor":[0.8,0.8,0.8,1.0],"metallicFactor":{metallic},"roughnessFactor":{roughness}{tex}}},"doubleSided":true}}"#
    )
}

/// The plate's pixels 3 px or more from the texture's vertical midline: (left, right).
fn halves() -> (Vec<usize>, Vec<usize>) {
    let mid = SIDE / 2;
    let (mut l, mut r) = (Vec::new(), Vec::new());
    for (c, row) in inner().filter(|(c, _)| c.abs_diff(mid) >= 3) {
        let i = (row * SIDE + c) as usize;
        if c < mid { l.push(i) } else { r.push(i) }
    }
    (l, r)
}

fn worst(a: &[f64], b: &[f64], pixels: &[usize]) -> f64 {
    pixels.iter().map(|&i| (a[i] / b[i] - 1.0).abs()).fold(0.0, f64::max)
}

#[test]
fn each_half_of_a_metallic_roughness_texture_renders_as_the_plate_of_its_texels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let image = metallic_roughness_png();
    std::fs::write(d.join("mr.glb"), plate_glb_with(&image, &material(1.0, 1.0, true))).unwrap();
    let code = |v: u8| f64::from(v) / 255.0;
    let (lr, lm) = (code(LEFT.0), code(LEFT.1));
    let (rr, rm) = (code(RIGHT.0), code(RIGHT.1));
    std::fs::write(d.join("left.glb"), plate_glb_with(&image, &material(lr, lm, false))).unwrap();
    std::fs::write(d.join("right.glb"), plate_glb_with(&image, &material(rr, rm, false))).unwrap();
    let (tex, log) = crate::common::logs::with_log(|| load(d, "t.toml", "mr.glb"));
    assert!(log.contains("roughness texture") && log.contains("metallic texture"), "{log}");
    assert!(!log.contains("metallicRoughnessTexture"), "the texture is used, not reported:\n{log}");
    let tex = frame(&tex);
    let left = frame(&load(d, "l.toml", "left.glb"));
    let right = frame(&load(d, "r.toml", "right.glb"));
    let (l, r) = halves();
    let mean = |img: &[f64], px: &[usize]| px.iter().map(|&i| img[i]).sum::<f64>() / px.len() as f64;
    eprintln!(
        "metal half {:.3} (plate {:.3}), plastic half {:.3} (plate {:.3}); worst pixel {:e}, {:e}",
        mean(&tex, &l),
        mean(&left, &l),
        mean(&tex, &r),
        mean(&right, &r),
        worst(&tex, &left, &l),
        worst(&tex, &right, &r)
    );
    // The two halves are different materials (a 25 % or larger difference).
    assert!((mean(&tex, &l) / mean(&tex, &r) - 1.0).abs() > 0.25);
    // The metal half: the same BRDF exactly (no coating under a conductor).
    assert!(worst(&tex, &left, &l) < 1e-5, "metal half");
    // The plastic half: its coating is blended from roughness nodes (within 1e-3).
    assert!(worst(&tex, &right, &r) < 1e-3, "plastic half");

    // The same texture as MTL `map_Pr` and `map_Pm` (grey images): the same pixels.
    std::fs::write(d.join("rough.png"), png(64, 64, |x, _| if x < 32 { LEFT.0 } else { RIGHT.0 })).unwrap();
    std::fs::write(d.join("metal.png"), png(64, 64, |x, _| if x < 32 { LEFT.1 } else { RIGHT.1 })).unwrap();
    write_obj(d, "newmtl panel\nKd 0.8 0.8 0.8\nPr 1\nPm 1\nmap_Pr rough.png\nmap_Pm metal.png\n");
    let obj = frame(&load(d, "o.toml", "panel.obj"));
    let all: Vec<usize> = l.iter().chain(&r).copied().collect();
    assert!(worst(&obj, &tex, &all) < 1e-6, "MTL and glTF differ by {}", worst(&obj, &tex, &all));
}

/// A constant tangent-space normal map tilting the normal by `deg` toward +s (the
/// image's right), 8-bit, and the unit normal its texel decodes to, (x, y, z).
fn tilted_normal_png(deg: f64) -> (Vec<u8>, [f64; 3]) {
    let (s, c) = deg.to_radians().sin_cos();
    let code = |v: f64| ((v + 1.0) / 2.0 * 255.0).round() as u8;
    let texel = [code(s), code(0.0), code(c)];
    let img = image::RgbImage::from_pixel(16, 16, image::Rgb(texel));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    let v = texel.map(|t| 2.0 * f64::from(t) / 255.0 - 1.0);
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (out, v.map(|x| x / len))
}

#[test]
fn a_tilted_normal_map_shades_a_lambert_plate_as_the_tilted_normal_says() {
    // The plate of `texture.rs`: s runs along body +x, the image's "up" along body +y,
    // and its front face looks at the camera (−z). A texel (x, y, z) therefore shades
    // with n = normalize(x·x̂ + y·ŷ − z·ẑ), and a Lambert plate of ρ 0.5 under the sun
    // toward (0.5, 0, −0.866) is ρ·E·max(0, n·sun)/π at every pixel.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sun = [0.5, 0.0, -0.8660254037844386f64];
    let mut seen = Vec::new();
    for deg in [20.0, -20.0, 0.0] {
        let (image, [x, y, z]) = tilted_normal_png(deg);
        std::fs::write(d.join("n.png"), &image).unwrap();
        write_obj(d, "newmtl panel\nKd 0.5 0.5 0.5\nnorm n.png\n");
        let (s, log) = crate::common::logs::with_log(|| load(d, "o.toml", "panel.obj"));
        assert!(!log.contains("`norm` ignored"), "{log}");
        let img = frame(&s);
        let cos = (x * sun[0] + y * sun[1] - z * sun[2]).max(0.0);
        let want = 0.5 * 593.1 * cos / std::f64::consts::PI;
        let all: Vec<usize> = inner().map(|(c, r)| (r * SIDE + c) as usize).collect();
        let worst = all.iter().map(|&i| (img[i] / want - 1.0).abs()).fold(0.0, f64::max);
        eprintln!("tilt {deg}°: cos {cos:.5}, every pixel within {worst:e} of {want:.3}");
        assert!(worst < 1e-5, "tilt {deg}°: off by {worst}");
        seen.push(want);

        // The same map as a glTF normalTexture on glTF's material, and on the same
        // material from an MTL (`Pr 1`, `Pm 0`): the same pixels.
        let m = r#"{"name":"panel","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1.0],"metallicFactor":0.0,"roughnessFactor":1.0},"normalTexture":{"index":0},"doubleSided":true}"#;
        std::fs::write(d.join("n.glb"), plate_glb_with(&image, m)).unwrap();
        let glb = frame(&load(d, "g.toml", "n.glb"));
        write_obj(d, "newmtl panel\nKd 0.5 0.5 0.5\nPr 1\nPm 0\nnorm n.png\n");
        let obj = frame(&load(d, "o.toml", "panel.obj"));
        let worst = all.iter().map(|&i| (glb[i] / obj[i] - 1.0).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-6, "tilt {deg}°: GLB and OBJ differ by {worst}");
        seen.push(all.iter().map(|&i| glb[i]).sum::<f64>());
    }
    // +20° toward the sun is brighter than 0°, which is brighter than −20°.
    assert!(seen[0] > seen[4] && seen[4] > seen[2], "{seen:?}");
    assert!(seen[1] > seen[5] && seen[5] > seen[3], "GLB: {seen:?}");
}
