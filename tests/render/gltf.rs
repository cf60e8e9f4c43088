//! glTF 2.0 meshes: GLB files written byte by byte here (JSON chunk + binary chunk, the
//! format's own layout) render as the equivalent OBJ + MTL, land where their node
//! transforms put them, and bad files are refused naming the file.

use crate::common;
use hilcam_core::render::{RenderOptions, render};
use std::path::{Path, PathBuf};

/// A GLB container: 12-byte header, a JSON chunk padded with spaces, a BIN chunk padded
/// with zeros (glTF 2.0 spec, "Binary glTF Layout").
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// The 1 m plate of `mtl.rs` (OBJ `panel.obj`): four corners, triangles (1 3 2), (1 4 3).
fn plate_bin() -> Vec<u8> {
    let mut bin = Vec::new();
    for v in [[-0.5f32, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]] {
        for c in v {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 2, 1, 0, 3, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin
}

/// The plate's glTF JSON with `nodes` (mesh 0 is the plate), primitive `extra` fields and
/// top-level `top` fields spliced in.
fn plate_json(nodes: &str, material: &str, prim_extra: &str, top: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
"meshes":[{{"name":"plate","primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0{prim_extra}}}]}}],
"materials":[{material}],
"buffers":[{{"byteLength":60}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-0.5,-0.5,0],"max":[0.5,0.5,0]}},
{{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}}]{top}}}"#
    )
}

const PANEL: &str = r#"{"name":"panel","pbrMetallicRoughness":{"baseColorFactor":[0.3,0.5,0.7,1.0],
"metallicFactor":0.0,"roughnessFactor":0.5},"doubleSided":true}"#;

/// A scene with the camera of `mtl.rs` (256², 1 m = 200 px at 10 m), sun at 30°.
fn scene_file(dir: &Path, name: &str, mesh: &str, depth: u32) -> PathBuf {
    let text = format!(
        "[camera]\nwidth = 256\nheight = 256\npitch_um = 20.0\nfocal_mm = 40.0\n\
         [[mesh]]\nobj = \"{mesh}\"\n[sun]\nirradiance = 593.1\n\
         [pose]\nposition = [0.0, 0.0, 10.0]\nsun = [0.5, 0.0, -0.8660254037844386]\n\
         [render]\nspp = 4\ndepth = {depth}\n"
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn render_file(path: &Path) -> Vec<f32> {
    let s = hilcam_core::scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    render(&s, &s.view(&s.camera, &s.pose), &RenderOptions::new(s.render, 0)).0.data
}

#[test]
fn a_plate_glb_renders_as_the_same_plate_in_obj_and_mtl() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("plate.glb"), glb(&plate_json("[{\"mesh\":0}]", PANEL, "", ""), &plate_bin()))
        .unwrap();
    std::fs::write(
        dir.path().join("panel.obj"),
        "mtllib panel.mtl\nv -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0.5 0.5 0\nv -0.5 0.5 0\nusemtl panel\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    // The same material: base colour (0.3, 0.5, 0.7), metallic 0, roughness 0.5.
    std::fs::write(dir.path().join("panel.mtl"), "newmtl panel\nKd 0.3 0.5 0.7\nPr 0.5\nPm 0\n").unwrap();
    // Depth 2: the GGX plastic's sampled bounce runs too (it escapes to a black sky).
    let a = render_file(&scene_file(dir.path(), "glb.toml", "plate.glb", 2));
    let b = render_file(&scene_file(dir.path(), "obj.toml", "panel.obj", 2));
    let lit = a.iter().filter(|&&v| v > 0.0).count();
    assert!(lit > 39_000, "the plate covers ~200² px: {lit} lit");
    let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs() / x.abs().max(1e-6)).fold(0.0f32, f32::max);
    eprintln!("GLB vs OBJ plate: largest relative pixel difference {worst:e}");
    assert!(worst <= 1e-6, "GLB and OBJ differ by {worst} (relative)");
}

#[test]
fn a_non_indexed_plate_renders_as_the_indexed_one() {
    // The same two triangles as six vertices and no `indices`: glTF's non-indexed form.
    let dir = tempfile::tempdir().unwrap();
    let c = [[-0.5f32, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]];
    let mut bin = Vec::new();
    for i in [0usize, 2, 1, 0, 3, 2] {
        for x in c[i] {
            bin.extend_from_slice(&x.to_le_bytes());
        }
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}}],"materials":[{PANEL}],
"buffers":[{{"byteLength":72}}],"bufferViews":[{{"buffer":0,"byteLength":72}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":6,"type":"VEC3","min":[-0.5,-0.5,0],"max":[0.5,0.5,0]}}]}}"#
    );
    std::fs::write(dir.path().join("flat.glb"), glb(&json, &bin)).unwrap();
    std::fs::write(dir.path().join("plate.glb"), glb(&plate_json("[{\"mesh\":0}]", PANEL, "", ""), &plate_bin()))
        .unwrap();
    let a = render_file(&scene_file(dir.path(), "a.toml", "flat.glb", 2));
    let b = render_file(&scene_file(dir.path(), "b.toml", "plate.glb", 2));
    assert!(a.iter().filter(|&&v| v > 0.0).count() > 39_000);
    assert_eq!(a, b, "non-indexed and indexed plates differ");
}

#[test]
fn node_transforms_place_the_plate_where_the_analytic_answer_says() {
    // Parent: 90° about +Z; child: translate (0.3, 0, 0), scale (0.5, 0.5, 1). The plate's
    // centre goes to R_z(90°)·(0.3, 0, 0) = (0, 0.3, 0) m, its side to 0.5 m. At 10 m with
    // a 2000 px focal length (body axes = camera axes), that is a 100 px square centred
    // 60 px below the image centre: columns 78…178, rows 138…238.
    let dir = tempfile::tempdir().unwrap();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = format!(
        r#"[{{"children":[1],"rotation":[0,0,{s},{s}]}},{{"mesh":0,"translation":[0.3,0,0],"scale":[0.5,0.5,1]}}]"#
    );
    std::fs::write(dir.path().join("moved.glb"), glb(&plate_json(&nodes, PANEL, "", ""), &plate_bin())).unwrap();
    let img = render_file(&scene_file(dir.path(), "s.toml", "moved.glb", 1));
    let (mut n, mut sc, mut sr) = (0.0f64, 0.0f64, 0.0f64);
    for (i, &v) in img.iter().enumerate() {
        if v > 0.0 {
            let (c, r) = ((i % 256) as f64 + 0.5, (i / 256) as f64 + 0.5);
            n += 1.0;
            sc += c;
            sr += r;
        }
    }
    let (cc, cr) = (sc / n, sr / n);
    eprintln!("moved plate: {n} lit pixels, centroid ({cc:.3}, {cr:.3}) px");
    assert!((cc - 128.0).abs() < 0.5 && (cr - 188.0).abs() < 0.5, "centroid ({cc}, {cr}) vs (128, 188)");
    // 100² fully covered, plus at most the one-pixel ring the edges touch.
    assert!((10_000.0..=102.0 * 102.0).contains(&n), "{n} lit pixels vs 100² … 102²");
}

fn load_error(dir: &Path, file: &str, bytes: &[u8]) -> String {
    std::fs::write(dir.join(file), bytes).unwrap();
    let scene = scene_file(dir, "bad.toml", file, 1);
    match hilcam_core::scene::load(&scene) {
        Ok(_) => panic!("{file}: expected a refusal"),
        Err(e) => {
            eprintln!("{e}");
            e.to_string()
        }
    }
}

#[test]
fn bad_glb_files_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let e = load_error(d, "garbage.glb", b"this is not a GLB");
    assert!(e.contains("garbage.glb") && e.contains("bad.toml") && e.contains("mesh[0].obj"), "{e}");
    let draco =
        r#","extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]"#;
    let e = load_error(d, "draco.glb", &glb(&plate_json("[{\"mesh\":0}]", PANEL, "", draco), &plate_bin()));
    assert!(e.contains("draco.glb") && e.contains("Draco"), "{e}");
    let quant = r#","extensionsUsed":["KHR_mesh_quantization"],"extensionsRequired":["KHR_mesh_quantization"]"#;
    let e = load_error(d, "quant.glb", &glb(&plate_json("[{\"mesh\":0}]", PANEL, "", quant), &plate_bin()));
    assert!(e.contains("quant.glb") && e.contains("quantized"), "{e}");
    let e = load_error(d, "lines.glb", &glb(&plate_json("[{\"mesh\":0}]", PANEL, ",\"mode\":1", ""), &plate_bin()));
    assert!(e.contains("lines.glb") && e.contains("primitive 0") && e.contains("triangles only"), "{e}");
    // Indices past the vertices: a 5 where there are 4.
    let mut bin = plate_bin();
    bin[48..50].copy_from_slice(&5u16.to_le_bytes());
    let e = load_error(d, "index.glb", &glb(&plate_json("[{\"mesh\":0}]", PANEL, "", ""), &bin));
    assert!(e.contains("index.glb") && e.contains("index 5"), "{e}");
    // A truncated binary chunk.
    let mut short = glb(&plate_json("[{\"mesh\":0}]", PANEL, "", ""), &plate_bin());
    short.truncate(short.len() - 20);
    let e = load_error(d, "short.glb", &short);
    assert!(e.contains("short.glb"), "{e}");
}

#[test]
fn textures_and_unused_material_properties_are_reported_by_file_and_material() {
    let dir = tempfile::tempdir().unwrap();
    let textured = r#"{"name":"cells","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1.0],
"baseColorTexture":{"index":0},"metallicFactor":1.0,"roughnessFactor":0.3},"emissiveFactor":[1,0,0]}"#;
    let top = r#","textures":[{"source":0}],"images":[{"uri":"cells.png"}]"#;
    std::fs::write(dir.path().join("cells.glb"), glb(&plate_json("[{\"mesh\":0}]", textured, "", top), &plate_bin()))
        .unwrap();
    let scene = scene_file(dir.path(), "s.toml", "cells.glb", 1);
    let (s, log) = common::logs::with_log(|| hilcam_core::scene::load(&scene));
    let s = s.unwrap();
    assert_eq!(s.target.materials[0].bsdf.model_name(), "ggx_conductor");
    // emissiveFactor (1, 0, 0): a third of sunlit white in the band.
    let want = 593.1 / std::f64::consts::PI / 3.0;
    assert!((f64::from(s.target.materials[0].emission) / want - 1.0).abs() < 1e-6);
    assert!(!log.contains("emissiveFactor"), "emission is used:\n{log}");
    for want in [
        // The texture is used, but its file is missing: a warning, and the factor renders.
        "cells.png` cannot be read",
        ": cells.glb, material `cells`; the material's factor is used",
        "mesh `plate` primitive 0: its material is textured but it has no TEXCOORD_0",
        "`doubleSided` false ignored",
    ] {
        assert!(log.contains(want), "log lacks {want}:\n{log}");
    }
}

#[test]
fn emissive_strength_scales_the_emissive_factor_relative_to_sunlit_white() {
    // Base colour black, sun behind the plate: all the camera sees is the emission,
    // emissiveFactor 0.5 × KHR_materials_emissive_strength 4 = 2 × E/π.
    let dir = tempfile::tempdir().unwrap();
    let glow = r#"{"name":"glow","pbrMetallicRoughness":{"baseColorFactor":[0,0,0,1],"metallicFactor":0.0},
"emissiveFactor":[0.25,0.5,0.75],"extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":4.0}},"doubleSided":true}"#;
    let top = r#","extensionsUsed":["KHR_materials_emissive_strength"]"#;
    std::fs::write(dir.path().join("glow.glb"), glb(&plate_json("[{\"mesh\":0}]", glow, "", top), &plate_bin()))
        .unwrap();
    let path = scene_file(dir.path(), "s.toml", "glow.glb", 1);
    let text = std::fs::read_to_string(&path).unwrap().replace("-0.8660254037844386", "0.8660254037844386");
    std::fs::write(&path, text).unwrap();
    let (s, log) = common::logs::with_log(|| hilcam_core::scene::load(&path));
    let s = s.unwrap();
    assert!(!log.contains("KHR_materials_emissive_strength` ignored"), "{log}");
    let img = render(&s, &s.view(&s.camera, &s.pose), &RenderOptions::new(s.render, 0)).0.data;
    let want = 2.0 * 593.1 / std::f64::consts::PI;
    // The plate's inner 150² pixels (it covers 200² around the centre).
    for r in 53..203 {
        for c in 53..203 {
            let v = f64::from(img[r * 256 + c]);
            assert!((v / want - 1.0).abs() < 1e-5, "pixel ({c}, {r}): {v} vs {want}");
        }
    }
}

#[test]
fn the_shipped_satellite_renders_the_same_from_its_glb_and_its_obj() {
    // scenes/gltf_satellite{,_obj}.toml: one model written both ways by
    // scripts/make_gltf_satellite.py (node hierarchy with a mirrored panel, four GGX
    // materials, no [materials] table), rendered at 256 px.
    let render_at = |p: &str| {
        let mut s = hilcam_core::scene::load(Path::new(p)).unwrap_or_else(|e| panic!("{e}"));
        s.camera = s.camera.scaled(Some(256), None);
        let (img, _) = render(&s, &s.view(&s.camera, &s.pose), &RenderOptions::new(s.render, 0));
        (img.data, s.target.materials.iter().map(|m| (m.name.clone(), m.bsdf)).collect::<Vec<_>>())
    };
    let (a, ma) = render_at("scenes/gltf_satellite.toml");
    let (b, mb) = render_at("scenes/gltf_satellite_obj.toml");
    assert_eq!(ma, mb, "the two files give different materials");
    assert_eq!(ma.len(), 4);
    assert!(a.iter().filter(|&&v| v > 0.0).count() > 1000, "the satellite is in view");
    assert!(a == b, "GLB and OBJ + MTL renders differ");
}

#[test]
fn the_shipped_satellite_files_are_what_the_script_writes() {
    crate::common::shipped::assert_script_writes(
        "scripts/make_gltf_satellite.py",
        "scenes/gltf_satellite",
        &["sat.glb", "sat.obj", "sat.mtl"],
    );
}

/// Standard base64 with padding, for a data-URI buffer.
fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n =
            (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn a_gltf_with_a_bin_file_or_a_data_uri_renders_as_the_glb() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nodes = "[{\"mesh\":0}]";
    std::fs::write(d.join("plate.glb"), glb(&plate_json(nodes, PANEL, "", ""), &plate_bin())).unwrap();
    std::fs::write(d.join("plate.bin"), plate_bin()).unwrap();
    let with_uri = |uri: &str| {
        plate_json(nodes, PANEL, "", "")
            .replace(r#""buffers":[{"byteLength":60}]"#, &format!(r#""buffers":[{{"byteLength":60,"uri":"{uri}"}}]"#))
    };
    std::fs::write(d.join("file.gltf"), with_uri("plate.bin")).unwrap();
    let data = format!("data:application/octet-stream;base64,{}", base64(&plate_bin()));
    std::fs::write(d.join("data.gltf"), with_uri(&data)).unwrap();
    let reference = render_file(&scene_file(d, "glb.toml", "plate.glb", 1));
    assert!(reference.iter().filter(|&&v| v > 0.0).count() > 39_000);
    for f in ["file.gltf", "data.gltf"] {
        assert!(render_file(&scene_file(d, "g.toml", f, 1)) == reference, "{f} differs from the GLB");
    }
    // A missing .bin is refused naming the glTF and the buffer's file.
    std::fs::remove_file(d.join("plate.bin")).unwrap();
    let e = load_error(d, "file.gltf", with_uri("plate.bin").as_bytes());
    assert!(e.contains("file.gltf") && e.contains("plate.bin"), "{e}");
}
