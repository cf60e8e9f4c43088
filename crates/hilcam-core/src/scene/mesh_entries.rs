//! A scene file's `[[mesh]]` entries (model files placed in the body frame, their materials
//! mapped to the scene's) and `[[wrap]]` entries (a material's faces folded).

use super::Material;
use super::limits::{self, SceneLimits};
use super::model::ModelMesh;
use super::scene_error::{At, SceneError};
use super::texture_file::TextureRef;
use super::textures::Slot;
use crate::render::geometry::TriMesh;
use crate::scene::fold::{
    FoldLevel, FoldTarget, MAX_WRAP_TRIANGLES, fit_for_edge, fit_panel_triangle_estimate, wrap_faces_report,
    wrap_triangle_estimate,
};
use glam::{DQuat, DVec3, EulerRot};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct WrapEntry {
    material: String,
    /// slight | medium | severe (the paper's levels), or give e_plane and var.
    level: Option<String>,
    e_plane: Option<f64>,
    var: Option<f64>,
    /// Target edge length of the subdivided faces, metres.
    #[serde(default = "default_edge")]
    edge_m: Spanned<f32>,
    #[serde(default)]
    seed: u64,
}

fn default_edge() -> Spanned<f32> {
    Spanned::new(0..0, 0.02)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshEntry {
    obj: Spanned<PathBuf>,
    #[serde(default = "zero3")]
    translate: Spanned<[f64; 3]>,
    #[serde(default = "zero3")]
    rotate_deg: Spanned<[f64; 3]>,
    #[serde(default = "one")]
    scale: Spanned<f64>,
    /// Use this scene material for every face, whatever the MTL says.
    material: Option<Spanned<String>>,
}

fn zero3() -> Spanned<[f64; 3]> {
    Spanned::new(0..0, [0.0; 3])
}

fn one() -> Spanned<f64> {
    Spanned::new(0..0, 1.0)
}

/// Added to a range or scale refusal: where the limit is set.
const LIMITS_HINT: &str = " (raise it with [limits] max_scale, docs/scene.md)";

/// The meshes of every `[[mesh]]`, in the body frame, with what their model files bring.
pub(super) struct Meshes {
    pub mesh: TriMesh,
    /// Textured materials: scene index, what the texture gives, the texture.
    pub textures: Vec<(u32, Slot, TextureRef)>,
    /// Every triangle's UVs (empty when no model file has any: textureless scenes store none).
    pub uv: Vec<[glam::Vec2; 3]>,
}

/// Load each `[[mesh]]`'s model file, check and apply its placement, and map its material
/// names to scene materials (a `[materials.NAME]` table, else the model file's own
/// definition, appended to `materials`). `sunlit_white` scales a model's emission.
pub(super) fn load_meshes(
    entries: &[MeshEntry],
    dir: &Path,
    scene_limits: &SceneLimits,
    sunlit_white: f64,
    materials: &mut Vec<Material>,
    at: At,
) -> Result<Meshes, SceneError> {
    if entries.is_empty() {
        return Err(at.missing("mesh", "a scene needs at least one [[mesh]]".into()));
    }
    let mut out = Meshes { mesh: TriMesh::default(), textures: Vec::new(), uv: Vec::new() };
    // Materials built from a model file, and which file: a later file's different
    // definition of the same name is reported.
    let mut authored_from: Vec<(u32, PathBuf)> = Vec::new();
    for (k, entry) in entries.iter().enumerate() {
        let obj_path = dir.join(entry.obj.get_ref());
        let loaded = load_model(&obj_path).map_err(|m| at.field(entry.obj.span(), &format!("mesh[{k}].obj"), m))?;
        for note in &loaded.notes {
            tracing::warn!(mesh = %obj_path.display(), "{note}");
        }
        let place = placement(entry, k, scene_limits, at)?;
        let mut ctx = MaterialContext {
            entry,
            k,
            obj_path: &obj_path,
            loaded: &loaded,
            sunlit_white,
            materials: &mut *materials,
            authored_from: &mut authored_from,
            textures: &mut out.textures,
            at,
        };
        let map = loaded.material_names.iter().map(|name| ctx.scene_material(name)).collect::<Result<Vec<_>, _>>()?;
        let mut m = loaded.mesh;
        for p in &mut m.positions {
            *p = place.apply(p.as_dvec3()).as_vec3();
        }
        for mat in &mut m.material {
            *mat = map[*mat as usize];
        }
        if !loaded.uv.is_empty() {
            out.uv.resize(out.mesh.indices.len(), [glam::Vec2::ZERO; 3]);
            out.uv.extend_from_slice(&loaded.uv);
        }
        out.mesh.append(&m);
    }
    if !out.uv.is_empty() {
        out.uv.resize(out.mesh.indices.len(), [glam::Vec2::ZERO; 3]);
    }
    Ok(out)
}

/// A `[[mesh]]`'s scale, rotation and translation into the body frame, each checked.
struct Placement {
    scale: f64,
    rot: DQuat,
    translate: DVec3,
}

impl Placement {
    fn apply(&self, p: DVec3) -> DVec3 {
        self.rot * (p * self.scale) + self.translate
    }
}

fn placement(entry: &MeshEntry, k: usize, scene_limits: &SceneLimits, at: At) -> Result<Placement, SceneError> {
    let scale = *entry.scale.get_ref();
    limits::in_range(scale, (limits::SCALE.0, scene_limits.max_scale), "").map_err(|m| {
        let hint = if scale > scene_limits.max_scale { LIMITS_HINT } else { "" };
        at.field(entry.scale.span(), &format!("mesh[{k}].scale"), m + hint)
    })?;
    let translate = *entry.translate.get_ref();
    for v in translate {
        limits::in_range(v, (-limits::TRANSLATE_M, limits::TRANSLATE_M), " m")
            .map_err(|m| at.field(entry.translate.span(), &format!("mesh[{k}].translate"), m))?;
    }
    let rotate_deg = *entry.rotate_deg.get_ref();
    for v in rotate_deg {
        limits::in_range(v, (-limits::ROTATE_DEG, limits::ROTATE_DEG), "°")
            .map_err(|m| at.field(entry.rotate_deg.span(), &format!("mesh[{k}].rotate_deg"), m))?;
    }
    let [rx, ry, rz] = rotate_deg.map(f64::to_radians);
    Ok(Placement { scale, rot: DQuat::from_euler(EulerRot::ZYX, rz, ry, rx), translate: DVec3::from_array(translate) })
}

fn index_of(materials: &[Material], name: &str) -> Option<u32> {
    materials.iter().position(|m| m.name == name).map(|i| i as u32)
}

/// What mapping one model file's material names needs.
struct MaterialContext<'a> {
    entry: &'a MeshEntry,
    k: usize,
    obj_path: &'a Path,
    loaded: &'a ModelMesh,
    sunlit_white: f64,
    materials: &'a mut Vec<Material>,
    authored_from: &'a mut Vec<(u32, PathBuf)>,
    textures: &'a mut Vec<(u32, Slot, TextureRef)>,
    at: At<'a>,
}

impl MaterialContext<'_> {
    /// The scene material for the model's material `name`: the entry's `material` or
    /// `[materials.NAME]`, else the model file's own definition (added once).
    fn scene_material(&mut self, name: &str) -> Result<u32, SceneError> {
        let (entry, obj_path) = (self.entry, self.obj_path);
        let target = entry.material.as_ref().map(|m| m.get_ref().as_str()).unwrap_or(name);
        if let Some(i) = index_of(self.materials, target) {
            // A name two model files define differently: the first definition is used, and said.
            if let Some((_, first)) = self.authored_from.iter().find(|(j, f)| *j == i && *f != obj_path)
                && entry.material.is_none()
                && let Some(Ok(mine)) = self.loaded.authored(name)
                && mine.bsdf != self.materials[i as usize].bsdf
            {
                tracing::warn!(
                    material = %name,
                    "material `{name}` of {} differs from the one {} defines: the first is used (rename one, or give [materials.{name}])",
                    obj_path.display(),
                    first.display()
                );
            }
            return Ok(i);
        }
        if entry.material.is_none()
            && let Some(built) = self.loaded.authored(name)
        {
            let built = built.map_err(|m| self.at.field(entry.obj.span(), &format!("mesh[{}].obj", self.k), m))?;
            return Ok(self.add_authored(name, built));
        }
        let (span, what) = match &entry.material {
            Some(m) => (m.span(), format!("mesh[{}].material", self.k)),
            None => (entry.obj.span(), format!("mesh[{}].obj", self.k)),
        };
        let known: Vec<&str> = self.materials.iter().map(|m| m.name.as_str()).collect();
        Err(self.at.field(
            span,
            &what,
            format!(
                "material `{target}` used by {} has no [materials.{target}] entry and no definition in the model file (scene has: {})",
                obj_path.display(),
                known.join(", ")
            ),
        ))
    }

    /// A material the model file defines, added to the scene's with its textures.
    fn add_authored(&mut self, name: &str, built: super::authored::AuthoredBsdf) -> u32 {
        let obj_path = self.obj_path;
        for note in &built.notes {
            tracing::warn!(material = %name, "{note}");
        }
        tracing::info!(material = %name, file = %obj_path.display(), bsdf = %super::authored::describe(&built.bsdf), "material from the model file");
        let emission = built.emission.as_ref().map_or(0.0, |e| (f64::from(e.relative) * self.sunlit_white) as f32);
        if emission > 0.0 {
            tracing::info!(material = %name, radiance = emission, "emitting surface (W·sr⁻¹·m⁻²)");
        }
        self.materials.push(Material { name: name.to_string(), bsdf: built.bsdf, emission });
        let mat = (self.materials.len() - 1) as u32;
        let textures = [
            (Slot::Base, built.base_texture),
            (Slot::Emission, built.emission.and_then(|e| e.texture)),
            (Slot::Roughness, built.roughness_texture),
            (Slot::Metallic, built.metallic_texture),
        ];
        let normal = built.normal_texture.into_iter().flat_map(|(t, scale)| {
            (0..3)
                .map(move |axis| (Slot::Normal { axis, scale }, Some(TextureRef { channel: Some(axis), ..t.clone() })))
        });
        for (slot, t) in textures.into_iter().chain(normal) {
            let Some(t) = t else { continue };
            if self.loaded.uv.is_empty() {
                tracing::warn!(material = %name, "texture `{}` ignored: {} has no texture coordinates (`vt`, TEXCOORD_0) for it; its factor is used: {}", t.name(), obj_path.display(), t.at);
            } else {
                self.textures.push((mat, slot, t));
            }
        }
        self.authored_from.push((mat, obj_path.to_path_buf()));
        mat
    }
}

/// Apply each `[[wrap]]` in turn: fold every face of its material (the fit's parameters
/// for its level, or its own), bounded in triangles before subdividing.
pub(super) fn apply_wraps(
    wraps: &[Spanned<WrapEntry>],
    mut mesh: TriMesh,
    materials: &[Material],
    at: At,
) -> Result<TriMesh, SceneError> {
    for (k, w) in wraps.iter().enumerate() {
        let e = w.get_ref();
        let fail = |m: String| at.field(w.span(), "wrap", m);
        let edge_m = *e.edge_m.get_ref();
        let edge_span = if e.edge_m.span().is_empty() { w.span() } else { e.edge_m.span() };
        let Some(mat) = index_of(materials, &e.material) else {
            return Err(fail(format!("material `{}` is not in [materials]", e.material)));
        };
        let target = match (&e.level, e.e_plane, e.var) {
            (Some(l), None, None) => l.parse::<FoldLevel>().map_err(|x| fail(x.to_string()))?.target(),
            (None, Some(e_plane), Some(var)) => FoldTarget { e_plane, var },
            _ => return Err(fail("give either level or both e_plane and var".into())),
        };
        // Bound the subdivision before doing it (the fit subdivides a test panel too).
        let would_make = wrap_triangle_estimate(&mesh, &[mat], edge_m) + fit_panel_triangle_estimate(edge_m);
        if !(edge_m.is_finite() && edge_m > 0.0 && would_make <= MAX_WRAP_TRIANGLES as f64) {
            return Err(at.field(
                edge_span,
                &format!("wrap[{k}].edge_m"),
                format!(
                    "{edge_m} m would subdivide into {would_make:.3e} triangles (limit {MAX_WRAP_TRIANGLES}); \
                     use a larger edge_m"
                ),
            ));
        }
        let fit = fit_for_edge(target, e.seed, edge_m).map_err(|x| fail(x.to_string()))?;
        let (wrapped, report) = wrap_faces_report(&mesh, &[mat], &fit.params, e.seed, edge_m);
        tracing::info!(material = %e.material, e_plane = fit.e_plane, var = fit.var, triangles = wrapped.indices.len(), ?report, "folded");
        mesh = wrapped;
    }
    Ok(mesh)
}

/// Load an OBJ, or a glTF file by its extension (`.gltf`, `.glb`, any case).
///
/// # Errors
/// A message naming the file (and line or place where there is one).
pub fn load_model(path: &Path) -> Result<ModelMesh, String> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("gltf" | "glb") => super::gltf::load_gltf(path),
        _ => super::obj::load_obj(path),
    }
}
