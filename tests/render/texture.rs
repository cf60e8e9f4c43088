//! Base-colour textures (`render::texture`, `scene::texture_file`) against answers
//! computed here from the texture and the pinhole geometry:
//! - a fine texture at high spp converges to each pixel's box average of the
//!   bilinear texture (integrated exactly, texel by texel), and the mip-mapped 1-spp
//!   frame varies far less over seeds than the unfiltered one; so does the shipped
//!   scenes/textured_plate.toml, the scene compared with Mitsuba's `bitmap`, from its PNG;
//! - orientation: OBJ's `v = 0` is the image's bottom row, glTF's UV origin its top-left,
//!   and the same textured plate as OBJ + MTL and as GLB renders the same;
//! - an sRGB 128 texel is albedo 0.2158 × `Kd`.

use crate::common;
use hilcam_core::render::texture::TextureFilter;
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::Scene;
use std::path::{Path, PathBuf};

const E: f64 = 593.1;
/// 48² px, f = 2000 px: at 10 m a pixel is 5 mm and the 0.2 m plate 40 px.
pub(super) const SIDE: u32 = 48;
const F_PX: f64 = 2000.0;
const RANGE: f64 = 10.0;
const HALF: f64 = 0.1;

/// The plate facing the camera, sun at 30°: ρ·E·cos 30°/π per unit albedo.
fn lambert_unit() -> f64 {
    E * 30f64.to_radians().cos() / std::f64::consts::PI
}

pub(super) fn png(w: u32, h: u32, texel: impl Fn(u32, u32) -> u8) -> Vec<u8> {
    let img = image::GrayImage::from_fn(w, h, |x, y| image::Luma([texel(x, y)]));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    out
}

/// The plate as OBJ + MTL: corner (x, y) has `vt` ((x + h)/2h, (y + h)/2h).
pub(super) fn write_obj(dir: &Path, mtl: &str) {
    let obj = format!(
        "mtllib panel.mtl\nv -{HALF} -{HALF} 0\nv {HALF} -{HALF} 0\nv {HALF} {HALF} 0\nv -{HALF} {HALF} 0\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl panel\nf 1/1 3/3 2/2\nf 1/1 4/4 3/3\n"
    );
    std::fs::write(dir.join("panel.obj"), obj).unwrap();
    std::fs::write(dir.join("panel.mtl"), mtl).unwrap();
}

fn write_scene(dir: &Path, name: &str, mesh: &str, spp: u32) -> PathBuf {
    write_scene_lit(dir, name, mesh, spp, "[0.5, 0.0, -0.8660254037844386]")
}

/// [`write_scene`] with the sun toward `sun` (camera frame).
pub(super) fn write_scene_lit(dir: &Path, name: &str, mesh: &str, spp: u32, sun: &str) -> PathBuf {
    let text = format!(
        "[camera]\nwidth = {SIDE}\nheight = {SIDE}\npitch_um = 20.0\nfocal_mm = 40.0\n\
         [[mesh]]\nobj = \"{mesh}\"\n[sun]\nirradiance = {E}\n\
         [pose]\nposition = [0.0, 0.0, {RANGE}]\nsun = {sun}\n\
         [render]\nspp = {spp}\ndepth = 1\nadaptive = false\n"
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

pub(super) fn frame(s: &Scene) -> Vec<f64> {
    let (img, _) = render(s, &s.view(&s.camera, &s.pose), &RenderOptions::new(s.render, 0));
    img.data.iter().map(|&v| f64::from(v)).collect()
}

/// Pixels at least 2 px inside the plate's image.
pub(super) fn inner() -> impl Iterator<Item = (u32, u32)> {
    let lo = (f64::from(SIDE) / 2.0 - HALF * F_PX / RANGE) as u32 + 2;
    let hi = SIDE - lo;
    (lo..hi).flat_map(move |r| (lo..hi).map(move |c| (c, r)))
}

/// ∫_{-∞}^{z} of the unit tent (bilinear interpolation's kernel).
fn tent_cdf(z: f64) -> f64 {
    if z <= -1.0 {
        0.0
    } else if z < 0.0 {
        (z + 1.0) * (z + 1.0) / 2.0
    } else if z < 1.0 {
        1.0 - (1.0 - z) * (1.0 - z) / 2.0
    } else {
        1.0
    }
}

/// Weights of texels along one axis for the average over texel coordinates [a, b]
/// (texel i centred at i), wrapped into `n`.
fn axis_weights(a: f64, b: f64, n: usize) -> Vec<(usize, f64)> {
    let (a, b) = (a.min(b), a.max(b));
    ((a.floor() as i64 - 1)..=(b.ceil() as i64 + 1))
        .map(|i| (i.rem_euclid(n as i64) as usize, (tent_cdf(b - i as f64) - tent_cdf(a - i as f64)) / (b - a)))
        .collect()
}

/// A square plate of half-side `half` facing a pinhole camera (`side`² px, focal length
/// `f_px` pixels, no principal-point offset) at `range`, its corner (x, y) at OBJ `vt`
/// ((x + h)/2h, (y + h)/2h).
#[derive(Clone, Copy)]
struct PlateView {
    half: f64,
    side: u32,
    f_px: f64,
    range: f64,
}

/// The test plate of `write_obj` and `write_scene`.
const VIEW: PlateView = PlateView { half: HALF, side: SIDE, f_px: F_PX, range: RANGE };

/// Each pixel's box average of the bilinear texture `lin` (n × n, linear, row 0 at the
/// image top) mapped by the OBJ's `vt`: s = (x + h)/2h, t = 1 − (y + h)/2h.
fn box_average(lin: &[f64], n: usize, c: u32, r: u32) -> f64 {
    box_average_in(&VIEW, lin, n, c, r)
}

fn box_average_in(view: &PlateView, lin: &[f64], n: usize, c: u32, r: u32) -> f64 {
    let PlateView { half, side, f_px, range } = *view;
    let to_texel = |p: f64| (p + half) / (2.0 * half) * n as f64 - 0.5;
    let edge = |i: u32| (f64::from(i) - f64::from(side) / 2.0) / f_px * range;
    let xs = axis_weights(to_texel(edge(c)), to_texel(edge(c + 1)), n);
    // t = 1 − v: texel row coordinate n − 1 − (v·n − 0.5).
    let ys = axis_weights(n as f64 - 1.0 - to_texel(edge(r)), n as f64 - 1.0 - to_texel(edge(r + 1)), n);
    ys.iter().flat_map(|&(j, wy)| xs.iter().map(move |&(i, wx)| wx * wy * lin[j * n + i])).sum()
}

/// 256²: checks of 5 texels (a pixel spans 6.4 texels, 1.3 checks), the white ones
/// themselves a checkerboard of single texels (6.4 per pixel: much finer than a pixel).
fn checker_scene(dir: &Path, spp: u32) -> (Scene, Vec<f64>) {
    let n = 256;
    let on = |x: u32, y: u32| (x / 5 + y / 5).is_multiple_of(2) && (x + y).is_multiple_of(2);
    std::fs::write(dir.join("checks.png"), png(n, n, |x, y| if on(x, y) { 255 } else { 0 })).unwrap();
    write_obj(dir, "newmtl panel\nKd 0.8 0.8 0.8\nmap_Kd checks.png\n");
    let s = hilcam_core::scene::load(&write_scene(dir, "s.toml", "panel.obj", spp)).unwrap();
    let lin: Vec<f64> = (0..n * n).map(|k| if on(k % n, k / n) { 0.8 } else { 0.0 }).collect();
    let want = inner().map(|(c, r)| box_average(&lin, n as usize, c, r) * lambert_unit()).collect();
    (s, want)
}

fn inner_of(img: &[f64]) -> Vec<f64> {
    inner().map(|(c, r)| img[(r * SIDE + c) as usize]).collect()
}

/// How a frame's pixels `got` agree with the answer `want`: both means, the answer's
/// largest departure from its mean (relative: a flat answer tests nothing), the RMS and the
/// largest difference relative to the answer's mean.
struct Agreement {
    mean_got: f64,
    mean_want: f64,
    spread: f64,
    err: f64,
    worst: f64,
}

impl Agreement {
    fn of(got: &[f64], want: &[f64]) -> Self {
        let mean_want = want.iter().sum::<f64>() / want.len() as f64;
        let mean_got = got.iter().sum::<f64>() / got.len() as f64;
        Agreement {
            mean_got,
            mean_want,
            spread: want.iter().fold(0.0f64, |m, w| m.max((w - mean_want).abs())) / mean_want,
            err: rel_rms(got, want),
            worst: got.iter().zip(want).map(|(g, w)| (g - w).abs()).fold(0.0, f64::max) / mean_want,
        }
    }
}

/// Root-mean-square of `a − b` relative to the mean of `b`.
fn rel_rms(a: &[f64], b: &[f64]) -> f64 {
    let mean = b.iter().sum::<f64>() / b.len() as f64;
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt() / mean
}

#[test]
fn a_fine_checkerboard_converges_to_each_pixels_box_average_of_the_texture() {
    let dir = tempfile::tempdir().unwrap();
    let (s, want) = checker_scene(dir.path(), 4096);
    let got = inner_of(&frame(&s));
    let Agreement { mean_got, mean_want, spread, err, worst } = Agreement::of(&got, &want);
    eprintln!(
        "checker 4096 spp: mean {mean_got} vs {mean_want}, rms {err:.2e}, worst {worst:.2e}, pixel spread ±{spread:.3}"
    );
    // The box averages differ from pixel to pixel by tens of per cent: a flat answer fails.
    assert!(spread > 0.2, "the reference is too flat to test anything: ±{spread}");
    // Measured: mean +1e-5, rms 3.4e-4, worst 1.4e-3 (at 1024 spp: 2.4e-3, 8.5e-3 — the
    // residual is the samples' noise, not a bias).
    assert!(((mean_got - mean_want) / mean_want).abs() < 1e-4, "mean {mean_got} vs {mean_want}");
    assert!(err < 1e-3 && worst < 5e-3, "rms {err}, worst {worst} (relative to the mean)");

    // A one-pixel footprint at every spp (spp 1 averaged over seeds) converges elsewhere:
    // the mip-map's blur stays in the answer.
    let (mut s1, _) = checker_scene(dir.path(), 1);
    let mut sum = vec![0.0; want.len()];
    let seeds = 64;
    for seed in 0..seeds {
        s1.render.seed = seed;
        for (a, v) in sum.iter_mut().zip(inner_of(&frame(&s1))) {
            *a += v / seeds as f64;
        }
    }
    let blurred = rel_rms(&sum, &want);
    eprintln!("one-pixel footprint, 64 × 1 spp: rms {blurred:.3e} off the box average");
    assert!(blurred > 5.0 * err, "{blurred} vs {err}");
}

#[test]
fn the_shipped_textured_plate_converges_to_the_box_average_of_its_png() {
    // scenes/textured_plate.toml, the scene benches/vs_mitsuba.py compares with Mitsuba's
    // `bitmap` (docs/brdf.md, "Textures"), at the 128² of that comparison: the answer from
    // the PNG itself, sRGB-decoded here, and the pinhole geometry.
    let mut s = hilcam_core::scene::load(Path::new("scenes/textured_plate.toml")).unwrap_or_else(|e| panic!("{e}"));
    s.camera = s.camera.scaled(Some(128), None);
    // 256 spp: the footprint is already its floor, 1/8 px (0.35 texel: level 0, no blur).
    s.render.spp = hilcam_core::render::integrator::Spp::whole(256);
    s.render.adaptive = false;
    let png = image::open("scenes/textured/checks.png").unwrap().to_luma8();
    let n = png.width() as usize;
    assert_eq!(png.height() as usize, n);
    let srgb = |v: u8| {
        let c = f64::from(v) / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    };
    // `Kd 1`: ρ is the linear texel.
    let lin: Vec<f64> = png.pixels().map(|p| srgb(p.0[0])).collect();
    assert!(s.pose.attitude.abs_diff_eq(glam::DQuat::IDENTITY, 1e-12), "the plate faces the camera");
    let view = PlateView {
        half: 0.5,
        side: s.camera.width,
        f_px: s.camera.focal_mm * 1e3 / s.camera.pitch_um,
        range: s.pose.position.z,
    };
    // Face normal −Z toward the camera; sun_dir points toward the sun.
    let unit = f64::from(s.target.sun_irradiance) * -s.pose.sun_dir.z / std::f64::consts::PI;
    let lo = (f64::from(view.side) / 2.0 - view.half * view.f_px / view.range) as u32 + 2;
    let pixels: Vec<(u32, u32)> =
        (lo..view.side - lo).flat_map(|r| (lo..view.side - lo).map(move |c| (c, r))).collect();
    let want: Vec<f64> = pixels.iter().map(|&(c, r)| box_average_in(&view, &lin, n, c, r) * unit).collect();
    let img = frame(&s);
    let got: Vec<f64> = pixels.iter().map(|&(c, r)| img[(r * view.side + c) as usize]).collect();
    let Agreement { mean_got, mean_want, spread, err, worst } = Agreement::of(&got, &want);
    eprintln!(
        "textured plate 128² 256 spp, {} px: mean {mean_got} vs {mean_want}, rms {err:.2e}, worst {worst:.2e}, \
         pixel spread ±{spread:.3}",
        pixels.len()
    );
    assert!(spread > 0.5, "the reference is too flat to test anything: ±{spread}");
    // Measured: mean +1e-6, rms 3.0e-4, worst 3.3e-3: the samples' noise (the frame's own,
    // seed to seed, is 5e-4 rms in benches/vs_mitsuba.py at this spp).
    assert!(((mean_got - mean_want) / mean_want).abs() < 1e-4, "mean {mean_got} vs {mean_want}");
    assert!(err < 1e-3 && worst < 1e-2, "rms {err}, worst {worst} (relative to the mean)");
}

#[test]
fn the_shipped_textured_targets_are_what_the_script_writes() {
    crate::common::shipped::assert_script_writes(
        "scripts/make_textured_targets.py",
        "scenes/textured",
        &["plate.obj", "sphere.obj", "checks.mtl", "checks.png"],
    );
}

#[test]
fn the_mip_mapped_one_spp_frame_varies_far_less_than_the_unfiltered_one() {
    let dir = tempfile::tempdir().unwrap();
    let (mut s, want) = checker_scene(dir.path(), 1);
    let mut variance = |filter: TextureFilter| {
        s.target.texturing.as_mut().unwrap().filter = filter;
        let frames: Vec<Vec<f64>> = (0..8)
            .map(|seed| {
                s.render.seed = seed;
                inner_of(&frame(&s))
            })
            .collect();
        let per_pixel = (0..want.len()).map(|k| {
            let m = frames.iter().map(|f| f[k]).sum::<f64>() / 8.0;
            frames.iter().map(|f| (f[k] - m).powi(2)).sum::<f64>() / 7.0
        });
        per_pixel.sum::<f64>() / want.len() as f64
    };
    let mip = variance(TextureFilter::Mip);
    let bilinear = variance(TextureFilter::Bilinear);
    let unit = lambert_unit().powi(2);
    eprintln!("1 spp variance over seeds: mip {:.3e}, bilinear {:.3e} (× (E cosθ/π)²)", mip / unit, bilinear / unit);
    assert!(bilinear > 0.0 && mip < 0.05 * bilinear, "mip {mip} vs bilinear {bilinear}");
}

/// 64² with its top-left quadrant white: where the quadrant lands says how UVs are read.
fn quadrant_png() -> Vec<u8> {
    png(64, 64, |x, y| if x < 32 && y < 32 { 255 } else { 0 })
}

/// Mean of each image quadrant's pixels 3 px inside the plate and its quadrant.
pub(super) fn quadrant_means(img: &[f64]) -> [[f64; 2]; 2] {
    let mut q = [[(0.0, 0usize); 2]; 2];
    let mid = SIDE / 2;
    for (c, r) in inner() {
        if c.abs_diff(mid) < 3 || r.abs_diff(mid) < 3 {
            continue;
        }
        let e = &mut q[usize::from(r >= mid)][usize::from(c >= mid)];
        e.0 += img[(r * SIDE + c) as usize];
        e.1 += 1;
    }
    q.map(|row| row.map(|(s, n)| s / n as f64))
}

/// The plate as GLB: the same corners and triangles; TEXCOORD_0 = (u, 1 − v) of the OBJ's
/// `vt` (an exporter's flip to glTF's top-left origin); the PNG in the binary chunk.
fn plate_glb(image: &[u8]) -> Vec<u8> {
    plate_glb_with(
        image,
        r#"{"name":"panel","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.8,0.8,1.0],
"baseColorTexture":{"index":0},"metallicFactor":0.0,"roughnessFactor":0.5},"doubleSided":true}"#,
    )
}

/// [`plate_glb`] with the glTF `material` (its texture 0 is the PNG).
pub(super) fn plate_glb_with(image: &[u8], material: &str) -> Vec<u8> {
    let mut bin = Vec::new();
    let corners = [[-HALF, -HALF], [HALF, -HALF], [HALF, HALF], [-HALF, HALF]];
    for [x, y] in corners {
        for v in [x as f32, y as f32, 0.0] {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    for [x, y] in corners {
        let (u, v) = ((x + HALF) / (2.0 * HALF), (y + HALF) / (2.0 * HALF));
        for c in [u as f32, 1.0 - v as f32] {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 2, 1, 0, 3, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let img_at = bin.len();
    bin.extend_from_slice(image);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
"materials":[{material}],
"textures":[{{"source":0}}],"images":[{{"bufferView":3,"mimeType":"image/png"}}],
"buffers":[{{"byteLength":{len}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},
{{"buffer":0,"byteOffset":80,"byteLength":12}},{{"buffer":0,"byteOffset":{img_at},"byteLength":{img_len}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-{HALF},-{HALF},0],"max":[{HALF},{HALF},0]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},
{{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}]}}"#,
        len = bin.len(),
        img_len = image.len()
    );
    let mut j = json.into_bytes();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + j.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[test]
fn obj_v_zero_is_the_bottom_row_and_the_glb_renders_the_same() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("quad.png"), quadrant_png()).unwrap();
    // Lambert first: where the quadrant lands and how bright it is.
    write_obj(dir.path(), "newmtl panel\nKd 0.8 0.8 0.8\nmap_Kd quad.png\n");
    let s = hilcam_core::scene::load(&write_scene(dir.path(), "obj.toml", "panel.obj", 4)).unwrap();
    let q = quadrant_means(&frame(&s));
    // The image's top-left (u < ½, v > ½ in OBJ terms) is body x < 0, y > 0: the camera
    // sees it left (column < centre) and below (row > centre, +Y toward increasing row).
    let lit = 0.8 * lambert_unit();
    eprintln!("quadrant means / lit: {:?}", q.map(|r| r.map(|v| v / lit)));
    assert!((q[1][0] / lit - 1.0).abs() < 1e-4, "bottom-left {} vs {lit}", q[1][0]);
    for (r, c) in [(0, 0), (0, 1), (1, 1)] {
        assert!(q[r][c] < 1e-6 * lit, "quadrant ({r}, {c}) should be dark: {}", q[r][c]);
    }

    // GGX plastic both ways (glTF's material model): the same pixels.
    write_obj(dir.path(), "newmtl panel\nKd 0.8 0.8 0.8\nPr 0.5\nPm 0\nmap_Kd quad.png\n");
    std::fs::write(dir.path().join("plate.glb"), plate_glb(&quadrant_png())).unwrap();
    let a = frame(&hilcam_core::scene::load(&write_scene(dir.path(), "obj.toml", "panel.obj", 4)).unwrap());
    let b = frame(&hilcam_core::scene::load(&write_scene(dir.path(), "glb.toml", "plate.glb", 4)).unwrap());
    let q = quadrant_means(&b);
    // (The dark quadrants keep the plastic's coating reflection.)
    assert!(q[1][0] > 10.0 * q[0][0].max(q[0][1]).max(q[1][1]), "GLB quadrants {q:?}");
    let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / lit;
    eprintln!("OBJ vs GLB textured plate: largest difference {worst:e} of the lit value");
    assert!(worst < 1e-5, "OBJ and GLB differ by {worst}");
}

#[test]
fn an_emission_texture_lands_as_the_base_colour_s_does_and_scales_sunlit_white() {
    // A black plate lit from behind: the camera sees only `Ke` × texel × E/π, where the
    // quadrant image puts it (the base-colour test's bottom-left), OBJ and GLB alike.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("quad.png"), quadrant_png()).unwrap();
    write_obj(dir.path(), "newmtl panel\nKd 0 0 0\nKe 0.5 0.5 0.5\nmap_Ke quad.png\n");
    let behind = "[0.5, 0.0, 0.8660254037844386]";
    let s = hilcam_core::scene::load(&write_scene_lit(dir.path(), "obj.toml", "panel.obj", 4, behind)).unwrap();
    let a = frame(&s);
    let q = quadrant_means(&a);
    let lit = 0.5 * E / std::f64::consts::PI;
    assert!((q[1][0] / lit - 1.0).abs() < 1e-4, "bottom-left {} vs {lit}", q[1][0]);
    for (r, c) in [(0, 0), (0, 1), (1, 1)] {
        assert!(q[r][c] < 1e-6 * lit, "quadrant ({r}, {c}) should be dark: {}", q[r][c]);
    }
    let glow = r#"{"name":"panel","pbrMetallicRoughness":{"baseColorFactor":[0,0,0,1],"metallicFactor":0.0},
"emissiveFactor":[0.5,0.5,0.5],"emissiveTexture":{"index":0},"doubleSided":true}"#;
    std::fs::write(dir.path().join("plate.glb"), plate_glb_with(&quadrant_png(), glow)).unwrap();
    let b = frame(&hilcam_core::scene::load(&write_scene_lit(dir.path(), "glb.toml", "plate.glb", 4, behind)).unwrap());
    let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / lit;
    assert!(worst < 1e-5, "OBJ and GLB emission differ by {worst} of the lit value");
}

#[test]
fn an_srgb_128_texel_is_albedo_0_2158_times_kd() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("grey.png"), png(4, 4, |_, _| 128)).unwrap();
    write_obj(dir.path(), "newmtl panel\nKd 0.6 0.6 0.6\nmap_Kd grey.png\n");
    let s = hilcam_core::scene::load(&write_scene(dir.path(), "s.toml", "panel.obj", 2)).unwrap();
    let img = frame(&s);
    // IEC 61966-2-1: ((128/255 + 0.055)/1.055)^2.4.
    let albedo = ((128.0 / 255.0 + 0.055) / 1.055f64).powf(2.4);
    assert!((albedo - 0.2158).abs() < 1e-4);
    let want = albedo * 0.6 * lambert_unit();
    for (c, r) in inner() {
        let v = img[(r * SIDE + c) as usize];
        assert!(((v - want) / want).abs() < 1e-5, "pixel ({c}, {r}): {v} vs {want}");
    }
}

/// Load with the log captured (the scene must load).
fn load_logged(path: &Path) -> (Scene, String) {
    let (scene, log) = common::logs::load_logged(path);
    (scene.unwrap(), log)
}

#[test]
fn unusable_textures_warn_naming_file_and_line_and_render_the_factor() {
    for (map, why) in
        [("$texture.png", "unresolved placeholder"), ("missing.png", "cannot be read"), ("junk.png", "does not decode")]
    {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("junk.png"), b"not a png").unwrap();
        write_obj(dir.path(), &format!("newmtl panel\nKd 0.5 0.5 0.5\nmap_Kd {map}\n"));
        let (s, log) = load_logged(&write_scene(dir.path(), "s.toml", "panel.obj", 1));
        assert!(s.target.texturing.is_none(), "{map}");
        assert!(
            log.contains(why)
                && log.contains(&format!("{map}`"))
                && log.contains("panel.mtl:3; the material's factor is used"),
            "{map}: {log}"
        );
        let img = frame(&s);
        for (c, r) in inner() {
            let v = img[(r * SIDE + c) as usize];
            assert!((v / (0.5 * lambert_unit()) - 1.0).abs() < 1e-5, "{map}: {v}");
        }
    }
}

#[test]
fn the_load_report_gives_each_textures_size_and_memory() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("grey.png"), png(8, 4, |_, _| 128)).unwrap();
    write_obj(dir.path(), "newmtl panel\nKd 0.6 0.6 0.6\nmap_Kd grey.png\n");
    let (s, log) = load_logged(&write_scene(dir.path(), "s.toml", "panel.obj", 1));
    // Levels 8×4, 4×2, 2×1, 1×1 of f32: 43 texels, 172 bytes.
    assert!(log.contains("width=8 height=4 levels=4 bytes=172"), "{log}");
    let t = s.target.texturing.as_ref().unwrap();
    assert_eq!(t.bytes(), 172 + 2 * 24, "textures and the two triangles' UVs");
}

#[test]
fn the_shipped_textured_satellite_renders_the_same_from_its_glb_and_its_obj() {
    // scenes/textured_satellite{,_obj}.toml: one model written both ways by
    // scripts/make_textured_satellite.py, the panels textured with its cell pattern.
    let render_at = |p: &str| {
        let mut s = hilcam_core::scene::load(Path::new(p)).unwrap_or_else(|e| panic!("{e}"));
        s.camera = s.camera.scaled(Some(256), None);
        let t = s.target.texturing.as_ref().expect("the panels are textured");
        assert_eq!((t.textures.len(), t.textures[0].mip.size()), (1, (512, 192)), "{p}");
        let (img, _) = render(&s, &s.view(&s.camera, &s.pose), &RenderOptions::new(s.render, 0));
        img.data
    };
    let a = render_at("scenes/textured_satellite.toml");
    let b = render_at("scenes/textured_satellite_obj.toml");
    assert!(a.iter().filter(|&&v| v > 0.0).count() > 1000, "the satellite is in view");
    let peak = a.iter().fold(0.0f32, |m, &v| m.max(v));
    let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    eprintln!("textured satellite GLB vs OBJ: largest difference {worst:e} (peak {peak})");
    assert!(worst <= 1e-5 * peak, "GLB and OBJ + MTL renders differ by {worst}");
}

#[test]
fn the_shipped_textured_satellite_files_are_what_the_script_writes() {
    crate::common::shipped::assert_script_writes(
        "scripts/make_textured_satellite.py",
        "scenes/textured_satellite",
        &["sat.glb", "sat.obj", "sat.mtl", "cells.png"],
    );
}

#[test]
fn a_gltf_base_colour_texture_on_another_uv_set_is_reported_not_used() {
    let dir = tempfile::tempdir().unwrap();
    let glb = plate_glb(&quadrant_png());
    // The plate's GLB with `texCoord` 1 on its texture: the JSON chunk rewritten, its
    // length and the file's total updated.
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = String::from_utf8(glb[20..20 + json_len].to_vec()).unwrap();
    let edited =
        json.replacen(r#""baseColorTexture":{"index":0}"#, r#""baseColorTexture":{"index":0,"texCoord":1}"#, 1);
    let mut out = glb[..12].to_vec();
    let mut j = edited.into_bytes();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&glb[20 + json_len..]);
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    std::fs::write(dir.path().join("plate.glb"), out).unwrap();
    let (s, log) = load_logged(&write_scene(dir.path(), "s.toml", "plate.glb", 1));
    assert!(s.target.texturing.is_none());
    assert!(
        log.contains("`baseColorTexture` (texture 0) ignored: it uses texCoord 1, hilcam reads TEXCOORD_0 only: plate.glb, material `panel`"),
        "{log}"
    );
}

#[test]
fn the_hybrid_method_path_traces_a_textured_target() {
    // Its fragments would shade with the material's own BRDF: the frame falls back to the
    // path tracer (docs/render.md), the same bytes as `method = "path"`.
    let dir = tempfile::tempdir().unwrap();
    let (mut s, _) = checker_scene(dir.path(), 4);
    let path = frame(&s);
    s.render.method = hilcam_core::render::integrator::Method::Hybrid;
    assert!(frame(&s) == path, "a hybrid frame of a textured target is not the path-traced one");
    // The control: without its texture the same plate is rasterised, other bytes.
    s.target.texturing = None;
    let hybrid = frame(&s);
    s.render.method = hilcam_core::render::integrator::Method::Path;
    assert!(frame(&s) != hybrid, "the hybrid method did not run on the untextured plate");
}

#[test]
fn a_textured_frame_is_the_same_bytes_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let (s, _) = checker_scene(dir.path(), 3);
    let at = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| frame(&s))
    };
    let one = at(1);
    assert!(one.iter().any(|&v| v > 0.0));
    assert!(at(2) == one && at(3) == one, "the frame depends on the thread count");
}
