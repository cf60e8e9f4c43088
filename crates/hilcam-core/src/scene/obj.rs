//! OBJ/MTL loading with tobj: triangles plus the MTL material name of each.

use crate::render::geometry::TriMesh;
use glam::{Vec2, Vec3};
use std::path::Path;

use super::model::{AuthoredMaterials, ModelMesh};

/// Load an OBJ file: its triangles, each face's MTL material name (`default` for faces
/// without one) and every material its MTL libraries define, with their keys and lines.
/// The error names the file (and the line, for a bad vertex).
pub fn load_obj(path: &Path) -> Result<ModelMesh, String> {
    load_obj_unnamed(path).map_err(|m| format!("{}{m}", path.display()))
}

/// Largest vertex coordinate accepted, OBJ units (see `scene::limits::OBJ_COORD`).
const MAX_COORD: f64 = crate::scene::limits::OBJ_COORD;

/// Every `v` line's coordinates finite and within ±[`MAX_COORD`] (tobj reads them as f32,
/// so `1e39` would become infinite and `nan` would pass, making triangles vanish).
fn check_vertices(text: &str) -> Result<(), String> {
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            continue;
        }
        for (axis, word) in ["x", "y", "z"].iter().zip(words) {
            let ok = word.parse::<f64>().is_ok_and(|v| v.is_finite() && v.abs() <= MAX_COORD);
            if !ok {
                return Err(format!(
                    ":{}: v: vertex {axis} `{word}` must be a finite number within ±{MAX_COORD:e}",
                    i + 1
                ));
            }
        }
    }
    Ok(())
}

/// A note for each `usemtl` name (first use) that no MTL library defines: tobj gives its
/// faces the material `default` without a word.
fn undefined_usemtl(path: &Path, text: &str, defs: &[super::mtl::MtlMaterial]) -> Vec<String> {
    let file = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into());
    let mut seen: Vec<&str> = Vec::new();
    let mut notes = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let Some(name) = line.trim_start().strip_prefix("usemtl").filter(|r| r.starts_with(char::is_whitespace)) else {
            continue;
        };
        let name = name.trim();
        if !seen.contains(&name) && !defs.iter().any(|d| d.name == name) {
            notes.push(format!(
                "`usemtl {name}` names no material of its MTL: its faces are `default`: {file}:{}",
                i + 1
            ));
        }
        seen.push(name);
    }
    notes
}

fn load_obj_unnamed(path: &Path) -> Result<ModelMesh, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!(": {e}"))?;
    check_vertices(&text)?;
    let mtl_defs = super::mtl::libraries_of_obj(path.parent().unwrap_or(Path::new(".")), &text);
    let mut notes = undefined_usemtl(path, &text, &mtl_defs);
    let file = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into());
    notes.extend(super::obj_faces::folded_fan_notes(&file, &text));
    let (models, materials) = tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS).map_err(|e| format!(": {e}"))?;
    // A missing or broken .mtl still loads the geometry; the names come from `usemtl`
    // only through the material list, so without it every face is `default`.
    let mtl: Vec<String> = match materials {
        Ok(m) => m.into_iter().map(|m| m.name).collect(),
        Err(e) => {
            if models.iter().any(|m| m.mesh.material_id.is_some()) {
                return Err(format!(": its material library could not be read: {e}"));
            }
            Vec::new()
        }
    };
    // UVs only when a material has a texture: OBJ's `v` = 0 is the image's bottom row.
    let textured =
        mtl_defs.iter().any(|d| ["map_Kd", "map_Ke", "map_Pr", "map_Pm", "norm"].iter().any(|k| d.get(k).is_some()));
    let mut uv: Vec<[Vec2; 3]> = Vec::new();
    let mut names: Vec<String> = Vec::new();
    let mut out = TriMesh::default();
    for model in &models {
        let m = &model.mesh;
        let name = m.material_id.and_then(|i| mtl.get(i)).cloned().unwrap_or_else(|| "default".to_string());
        let mat = match names.iter().position(|n| *n == name) {
            Some(i) => i,
            None => {
                names.push(name);
                names.len() - 1
            }
        } as u32;
        let base = out.positions.len() as u32;
        out.positions.extend(m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        for t in m.indices.chunks_exact(3) {
            out.indices.push([t[0] + base, t[1] + base, t[2] + base]);
            out.material.push(mat);
        }
        // tobj lists a `vt` only for vertices that have one: faces mixing both leave
        // them misaligned, so such a mesh's UVs are not used (and said).
        let whole = m.texcoords.len() == m.positions.len() / 3 * 2;
        if textured && !m.texcoords.is_empty() && !whole {
            notes.push(format!(
                "{file}: object `{}` mixes faces with and without `vt`: its texture coordinates are not used",
                model.name
            ));
        }
        if textured && !m.texcoords.is_empty() && whole {
            let st = |i: u32| Vec2::new(m.texcoords[2 * i as usize], 1.0 - m.texcoords[2 * i as usize + 1]);
            uv.resize(out.indices.len() - m.indices.len() / 3, [Vec2::ZERO; 3]);
            uv.extend(m.indices.chunks_exact(3).map(|t| [st(t[0]), st(t[1]), st(t[2])]));
        }
    }
    if !uv.is_empty() {
        uv.resize(out.indices.len(), [Vec2::ZERO; 3]);
    }
    if out.indices.is_empty() {
        return Err(": no triangles".to_string());
    }
    Ok(ModelMesh { mesh: out, material_names: names, authored: AuthoredMaterials::Mtl(mtl_defs), notes, uv })
}

#[cfg(test)]
mod tests {
    use super::{Path, check_vertices, undefined_usemtl};

    #[test]
    fn a_usemtl_no_library_defines_is_noted_once_with_its_line() {
        let defs = crate::scene::mtl::parse_mtl(Path::new("p.mtl"), "newmtl paint\nKd 1 1 1\n");
        let obj = "mtllib p.mtl\nv 0 0 0\nusemtl paint\nf 1 1 1\nusemtl gold\nf 1 1 1\nusemtl gold\n";
        let notes = undefined_usemtl(Path::new("/m/sat.obj"), obj, &defs);
        assert_eq!(notes, ["`usemtl gold` names no material of its MTL: its faces are `default`: sat.obj:5"]);
    }

    #[test]
    fn bad_vertices_are_named_by_line_and_axis() {
        assert!(check_vertices("# c\nv 0 0 0\nv 1 2 3\nvn 0 0 nan\nf 1 2 3\n").is_ok());
        for (bad, axis) in [("nan", "x"), ("inf", "x"), ("1e39", "x")] {
            let e = check_vertices(&format!("v 0 0 0\nv {bad} 0 0\n")).unwrap_err();
            assert!(e.starts_with(":2: v: vertex") && e.contains(axis) && e.contains(bad), "{e}");
        }
        assert!(check_vertices("v 0 0 -inf\n").unwrap_err().contains("vertex z"));
        assert!(check_vertices("v 0 0 zz\n").unwrap_err().contains("`zz`"));
    }
}
