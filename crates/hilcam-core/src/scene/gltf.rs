//! glTF 2.0 (`.gltf` with its buffers, `.glb`) through the `gltf` crate: the default
//! scene's node hierarchy with its transforms, every triangle primitive, and each
//! material's metallic-roughness factors as hilcam's GGX model (docs/scene.md, "glTF").
//!
//! - Units are metres and glTF's axes are the body frame's unchanged (+Y up stays +Y, as
//!   an OBJ exported Y-up): the same model exported both ways lands in the same place.
//! - Refused, naming the file: primitives other than triangles, Draco
//!   (`KHR_draco_mesh_compression`) and quantized (`KHR_mesh_quantization`, or any
//!   non-float position) meshes, indices past the vertex count, unreadable buffers.
//! - `baseColorTexture`, `metallicRoughnessTexture` (G roughness, B metallic, linear) and
//!   `emissiveTexture` with texture coordinate set 0 are used (UV origin the image's
//!   top-left, times their factors; colours sRGB; `scene::texture_file`); emission is `emissiveFactor` × `KHR_materials_emissive_strength`
//!   relative to sunlit white (`authored::AuthoredEmission`); `KHR_materials_ior` sets the
//!   dielectric's index.
//! - Reported (a note naming the file and the material), never silently dropped: every
//!   other texture reference and texture set, alpha, single-sided materials, every other
//!   extension used, animations and skins.

use super::authored::{
    AuthoredBsdf, AuthoredEmission, MIN_ROUGHNESS, metallic_roughness, metallic_roughness_textured, over_band,
};
use super::model::{AuthoredMaterials, ModelMesh};
use super::texture_file::{ImageSource, TextureRef};
use crate::render::bsdf::GLTF_DIELECTRIC_IOR;
use crate::render::geometry::TriMesh;
use glam::{DMat4, DVec3, Vec3};
use gltf::mesh::Mode;
use gltf::texture::WrappingMode;
use std::path::Path;

/// Extensions whose properties are read.
const USED_EXTENSIONS: [&str; 2] = ["KHR_materials_emissive_strength", "KHR_materials_ior"];

/// Largest vertex coordinate accepted, metres after the node transforms (as OBJ's).
const MAX_COORD: f64 = crate::scene::limits::OBJ_COORD;

/// Load a glTF or GLB file; every error names the file.
pub fn load_gltf(path: &Path) -> Result<ModelMesh, String> {
    let file = path.display().to_string();
    load(path).map_err(|m| format!("{file}: {m}"))
}

fn load(path: &Path) -> Result<ModelMesh, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    // Parsed once unvalidated to name the unsupported compression extensions before the
    // crate's validation refuses them with a generic "unsupported extension".
    let raw = gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| format!("not a glTF 2.0 file: {e}"))?;
    for ext in raw.extensions_required().chain(raw.extensions_used()) {
        match ext {
            "KHR_draco_mesh_compression" => {
                return Err("Draco-compressed meshes (KHR_draco_mesh_compression) are not supported; \
                            export without Draco compression"
                    .into());
            }
            "KHR_mesh_quantization" => {
                return Err("quantized meshes (KHR_mesh_quantization) are not supported; export float positions".into());
            }
            _ => {}
        }
    }
    drop(raw);
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("invalid glTF 2.0: {e}"))?;
    let buffers = read_buffers(path, &gltf)?;
    let doc = &gltf.document;

    let mut notes = Vec::new();
    for ext in doc.extensions_used() {
        if !USED_EXTENSIONS.contains(&ext) {
            notes.push(format!("extension `{ext}` ignored"));
        }
    }
    if doc.animations().len() > 0 {
        notes.push(format!("{} animation(s) ignored: the rest pose is rendered", doc.animations().len()));
    }
    if doc.skins().len() > 0 {
        notes.push(format!("{} skin(s) ignored: the rest pose is rendered", doc.skins().len()));
    }

    let (materials, names) = materials(doc, path, &buffers);
    // UVs (TEXCOORD_0) only when some material is textured.
    let textured: Vec<bool> = materials.iter().map(|m| m.as_ref().is_ok_and(AuthoredBsdf::is_textured)).collect();
    let mut uv: Vec<[glam::Vec2; 3]> = Vec::new();
    let mut mesh = TriMesh::default();
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => return Err("no scene to render (the file has no `scenes`)".into()),
    };
    // Depth-first, each node before its children, siblings in document order: the order
    // an exporter writes the same model's OBJ faces in, so both give the same triangles.
    let mut stack: Vec<(gltf::Node, DMat4)> = roots.into_iter().rev().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let m = parent * DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        if let Some(gmesh) = node.mesh() {
            let want_uv =
                textured.iter().any(|&t| t).then_some(UvOut { textured: &textured, uv: &mut uv, notes: &mut notes });
            append_mesh(&mut mesh, &gmesh, m, &buffers, names.len() - 1, want_uv)?;
        }
        let children: Vec<gltf::Node> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, m)));
    }
    if mesh.indices.is_empty() {
        return Err("no triangles in its default scene".into());
    }
    // Keep only the materials the scene's triangles use, renumbered in first-use order.
    let mut remap = vec![u32::MAX; names.len()];
    let mut material_names = Vec::new();
    let mut authored = Vec::new();
    for m in &mut mesh.material {
        let i = *m as usize;
        if remap[i] == u32::MAX {
            remap[i] = material_names.len() as u32;
            material_names.push(names[i].clone());
            authored.push((names[i].clone(), materials[i].clone()));
        }
        *m = remap[i];
    }
    if !uv.is_empty() {
        uv.resize(mesh.indices.len(), [glam::Vec2::ZERO; 3]);
    }
    Ok(ModelMesh { mesh, material_names, authored: AuthoredMaterials::Gltf(authored), notes, uv })
}

/// Each buffer's bytes: the GLB's binary chunk, a base64 data URI, or a file beside the
/// glTF.
fn read_buffers(path: &Path, gltf: &gltf::Gltf) -> Result<Vec<Vec<u8>>, String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for b in gltf.document.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => {
                gltf.blob.clone().ok_or_else(|| format!("buffer {} refers to a missing GLB binary chunk", b.index()))?
            }
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let (_, payload) = uri
                    .split_once(";base64,")
                    .ok_or_else(|| format!("buffer {}: only base64 data URIs are read", b.index()))?;
                super::base64::decode(payload).map_err(|e| format!("buffer {}: {e}", b.index()))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let p = dir.join(uri);
                std::fs::read(&p).map_err(|e| format!("buffer {} `{}`: {e}", b.index(), p.display()))?
            }
        };
        if data.len() < b.length() {
            return Err(format!("buffer {} holds {} bytes, its byteLength says {}", b.index(), data.len(), b.length()));
        }
        out.push(data);
    }
    Ok(out)
}

/// Every material of the file built (index `len` is glTF's default material, for
/// primitives without one), and their unique names.
fn materials(
    doc: &gltf::Document,
    path: &Path,
    buffers: &[Vec<u8>],
) -> (Vec<Result<AuthoredBsdf, String>>, Vec<String>) {
    let file = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into());
    let mut built = Vec::new();
    let mut names: Vec<String> = Vec::new();
    for m in doc.materials() {
        let i = m.index().unwrap_or(0);
        let mut name = m.name().map_or_else(|| format!("material{i}"), str::to_string);
        if names.contains(&name) || name == "default" {
            name = format!("{name}#{i}");
        }
        built.push(material(&m, &name, &file, path, buffers));
        names.push(name);
    }
    // glTF's default material: base colour 1, metallic 1, roughness 1.
    let bsdf = metallic_roughness(1.0, 1.0, 1.0, GLTF_DIELECTRIC_IOR).map_err(|e| e.to_string());
    built.push(bsdf.map(|bsdf| AuthoredBsdf {
        bsdf,
        notes: Vec::new(),
        base_texture: None,
        emission: None,
        roughness_texture: None,
        metallic_texture: None,
        normal_texture: None,
    }));
    names.push("default".to_string());
    (built, names)
}

/// One material: the factors as GGX, every texture and unused property a note.
fn material(
    m: &gltf::Material,
    name: &str,
    file: &str,
    path: &Path,
    buffers: &[Vec<u8>],
) -> Result<AuthoredBsdf, String> {
    let at = format!("{file}, material `{name}`");
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, a] = pbr.base_color_factor();
    let base = (r + g + b) / 3.0;
    let mut roughness = pbr.roughness_factor();
    let metallic = pbr.metallic_factor();
    let mut notes = Vec::new();
    if roughness < MIN_ROUGHNESS {
        notes.push(format!(
            "roughnessFactor {roughness} raised to {MIN_ROUGHNESS}, the smoothest GGX hilcam takes: {at}"
        ));
        roughness = MIN_ROUGHNESS;
    }
    // The base colour's and the emission's textures, with TEXCOORD_0.
    let base_texture = pbr.base_color_texture().and_then(|info| {
        texture_ref("baseColorTexture", (info.texture(), info.tex_coord()), [r, g, b], &at, path, buffers, &mut notes)
    });
    // Roughness from G, metallic from B, read linearly, times the factors.
    let mr = pbr.metallic_roughness_texture().and_then(|info| {
        texture_ref(
            "metallicRoughnessTexture",
            (info.texture(), info.tex_coord()),
            [1.0; 3],
            &at,
            path,
            buffers,
            &mut notes,
        )
    });
    let value = |t: &TextureRef, channel: usize, factor: f32| TextureRef {
        factor: [factor; 3],
        channel: Some(channel),
        ..t.clone()
    };
    let roughness_texture = mr.as_ref().map(|t| value(t, 1, pbr.roughness_factor()));
    let metallic_texture = mr.as_ref().map(|t| value(t, 2, metallic));
    // The normal map's r g b, linear; `scale` multiplies its tangent-plane components.
    let normal_texture = m.normal_texture().and_then(|n| {
        let scale = n.scale();
        texture_ref("normalTexture", (n.texture(), n.tex_coord()), [1.0; 3], &at, path, buffers, &mut notes)
            .map(|t| (t, scale))
    });
    if let Some(t) = m.occlusion_texture() {
        notes.push(format!(
            "`occlusionTexture` (texture {}) ignored: the path tracer computes occlusion itself: {at}",
            t.texture().index()
        ));
    }
    let emission = emission(m, &at, path, buffers, &mut notes)?;
    let mut ior = GLTF_DIELECTRIC_IOR;
    if let Some(v) = m.ior() {
        if (1.0..=4.0).contains(&v) {
            ior = v;
        } else {
            notes.push(format!("KHR_materials_ior `ior` {v} is outside [1, 4]: {GLTF_DIELECTRIC_IOR} used: {at}"));
        }
    }
    if a != 1.0 || m.alpha_mode() != gltf::material::AlphaMode::Opaque {
        notes.push(format!("alpha ({:?}, base colour alpha {a}) ignored: surfaces are opaque: {at}", m.alpha_mode()));
    }
    if !m.double_sided() {
        notes.push(format!("`doubleSided` false ignored: hilcam's surfaces are two-sided: {at}"));
    }
    let bsdf = metallic_roughness_textured(base, metallic, roughness, ior, metallic_texture.is_some())
        .map_err(|e| format!("{at}: {e}"))?;
    Ok(AuthoredBsdf { bsdf, notes, base_texture, emission, roughness_texture, metallic_texture, normal_texture })
}

/// Largest emissive strength taken (`KHR_materials_emissive_strength`): 1e6 × sunlit
/// white, as MTL's `Ke`.
const MAX_EMISSIVE_STRENGTH: f32 = 1.0e6;

/// `emissiveFactor` × `KHR_materials_emissive_strength`, and `emissiveTexture`.
fn emission(
    m: &gltf::Material,
    at: &str,
    path: &Path,
    buffers: &[Vec<u8>],
    notes: &mut Vec<String>,
) -> Result<Option<AuthoredEmission>, String> {
    let factor = m.emissive_factor();
    let strength = m.emissive_strength().unwrap_or(1.0);
    if !(strength.is_finite() && (0.0..=MAX_EMISSIVE_STRENGTH).contains(&strength)) {
        return Err(format!("{at}: emissive_strength {strength} must be in [0, {MAX_EMISSIVE_STRENGTH:e}]"));
    }
    let info = m.emissive_texture();
    if factor == [0.0; 3] || strength == 0.0 {
        if let Some(info) = info {
            notes.push(format!(
                "`emissiveTexture` (texture {}) ignored: the emission factor is black: {at}",
                info.texture().index()
            ));
        }
        return Ok(None);
    }
    let texture = info.and_then(|info| {
        texture_ref("emissiveTexture", (info.texture(), info.tex_coord()), over_band(factor), at, path, buffers, notes)
    });
    let relative = strength * (factor[0] + factor[1] + factor[2]) / 3.0;
    Ok(Some(AuthoredEmission { relative, texture }))
}

/// A material's texture reference (`what` names it in notes), with its colour `factor`;
/// `None` with a note when it cannot be used (another texture set, an unreadable image
/// source).
fn texture_ref(
    what: &str,
    (t, tex_coord): (gltf::Texture, u32),
    factor: [f32; 3],
    at: &str,
    path: &Path,
    buffers: &[Vec<u8>],
    notes: &mut Vec<String>,
) -> Option<TextureRef> {
    if tex_coord != 0 {
        notes.push(format!(
            "`{what}` (texture {}) ignored: it uses texCoord {tex_coord}, hilcam reads TEXCOORD_0 only: {at}",
            t.index()
        ));
        return None;
    }
    let s = t.sampler();
    if s.wrap_s() != WrappingMode::Repeat || s.wrap_t() != WrappingMode::Repeat {
        notes.push(format!(
            "`{what}` sampler wrap ({:?}, {:?}) ignored: textures repeat: {at}",
            s.wrap_s(),
            s.wrap_t()
        ));
    }
    match image_source(&t.source(), path, buffers) {
        Ok(source) => Some(TextureRef { source, factor, channel: None, at: at.to_string() }),
        Err(e) => {
            notes.push(format!("`{what}` (texture {}) ignored: {e}: {at}", t.index()));
            None
        }
    }
}

/// Where an image's encoded bytes are: a buffer view (GLB), a base64 data URI, or a file
/// beside the glTF.
fn image_source(img: &gltf::Image, path: &Path, buffers: &[Vec<u8>]) -> Result<ImageSource, String> {
    let name = img.name().map_or_else(|| format!("image {}", img.index()), |n| format!("image `{n}`"));
    match img.source() {
        gltf::image::Source::View { view, .. } => {
            let data = buffers.get(view.buffer().index()).ok_or_else(|| format!("{name}: buffer missing"))?;
            let bytes = data
                .get(view.offset()..view.offset() + view.length())
                .ok_or_else(|| format!("{name}: buffer view past its buffer"))?;
            Ok(ImageSource::Bytes { name, data: bytes.into() })
        }
        gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
            let (_, payload) =
                uri.split_once(";base64,").ok_or_else(|| format!("{name}: only base64 data URIs are read"))?;
            let data = super::base64::decode(payload).map_err(|e| format!("{name}: {e}"))?;
            Ok(ImageSource::Bytes { name, data: data.into() })
        }
        gltf::image::Source::Uri { uri, .. } => {
            Ok(ImageSource::File(path.parent().unwrap_or(Path::new(".")).join(percent_decoded(uri))))
        }
    }
}

/// A URI's `%XX` escapes decoded (glTF file names are URIs: `solar%20cells.png`).
fn percent_decoded(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b.get(i + 1..i + 3).and_then(|h| u8::from_str_radix(std::str::from_utf8(h).ok()?, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Where [`append_mesh`] puts texture coordinates: which materials are textured (by
/// glTF index), the UVs per triangle so far, and the file's notes.
struct UvOut<'a> {
    textured: &'a [bool],
    uv: &'a mut Vec<[glam::Vec2; 3]>,
    notes: &'a mut Vec<String>,
}

/// Append a mesh's triangle primitives, transformed by `m` (node to body frame);
/// primitives without a material get material `default`.
fn append_mesh(
    out: &mut TriMesh,
    gmesh: &gltf::Mesh,
    m: DMat4,
    buffers: &[Vec<u8>],
    default: usize,
    mut uv: Option<UvOut>,
) -> Result<(), String> {
    let mname = gmesh.name().map_or_else(|| format!("{}", gmesh.index()), |n| format!("`{n}`"));
    // A mirroring transform reverses the winding; swap two corners to keep it.
    let flip = m.determinant() < 0.0;
    for (k, prim) in gmesh.primitives().enumerate() {
        let at = format!("mesh {mname} primitive {k}");
        if prim.mode() != Mode::Triangles {
            return Err(format!("{at}: mode {:?} is not supported (triangles only)", prim.mode()));
        }
        let pos = prim.get(&gltf::Semantic::Positions).ok_or_else(|| format!("{at}: no POSITION"))?;
        if pos.data_type() != gltf::accessor::DataType::F32 || pos.dimensions() != gltf::accessor::Dimensions::Vec3 {
            return Err(format!(
                "{at}: POSITION is {:?} {:?}; quantized positions are not supported (float VEC3 only)",
                pos.dimensions(),
                pos.data_type()
            ));
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|v| &v[..]));
        let positions: Vec<[f32; 3]> =
            reader.read_positions().ok_or_else(|| format!("{at}: POSITION unreadable"))?.collect();
        let n = positions.len() as u32;
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n).collect(),
        };
        if !indices.len().is_multiple_of(3) {
            return Err(format!("{at}: {} indices is not a whole number of triangles", indices.len()));
        }
        if let Some(bad) = indices.iter().find(|&&i| i >= n) {
            return Err(format!("{at}: index {bad} past its {n} vertices"));
        }
        let mat = prim.material().index().unwrap_or(default);
        let base = out.positions.len() as u32;
        for p in positions {
            let v = m.transform_point3(DVec3::from_array(p.map(f64::from)));
            if !(v.is_finite() && v.abs().max_element() <= MAX_COORD) {
                return Err(format!("{at}: vertex {v} must be finite and within ±{MAX_COORD:e} m"));
            }
            out.positions.push(Vec3::new(v.x as f32, v.y as f32, v.z as f32));
        }
        // glTF's UV origin is the image's top-left: (s, t) = (u, v) as they are.
        if let Some(UvOut { textured, uv, notes }) = uv.as_mut()
            && textured.get(mat).copied().unwrap_or(false)
        {
            let coords: Vec<glam::Vec2> = match reader.read_tex_coords(0) {
                Some(c) => c.into_f32().map(glam::Vec2::from).collect(),
                None => {
                    notes.push(format!("{at}: its material is textured but it has no TEXCOORD_0: texel (0, 0) used"));
                    vec![glam::Vec2::ZERO; n as usize]
                }
            };
            if coords.len() != n as usize {
                return Err(format!("{at}: {} TEXCOORD_0 for {n} vertices", coords.len()));
            }
            uv.resize(out.indices.len(), [glam::Vec2::ZERO; 3]);
            for t in indices.chunks_exact(3) {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| coords[i as usize]);
                uv.push(if flip { [a, c, b] } else { [a, b, c] });
            }
        }
        for t in indices.chunks_exact(3) {
            let [a, b, c] = [t[0] + base, t[1] + base, t[2] + base];
            out.indices.push(if flip { [a, c, b] } else { [a, b, c] });
            out.material.push(mat as u32);
        }
    }
    Ok(())
}
