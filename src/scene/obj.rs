//! OBJ/MTL loading with tobj: triangles plus the MTL material name of each.

use crate::geometry::TriMesh;
use glam::Vec3;
use std::path::Path;

/// Triangles of one OBJ file; `material` indexes `material_names`. Faces without a
/// material get the name `default`.
pub struct ObjMesh {
    pub mesh: TriMesh,
    pub material_names: Vec<String>,
}

pub fn load_obj(path: &Path) -> Result<ObjMesh, String> {
    let (models, materials) = tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS).map_err(|e| e.to_string())?;
    // A missing or broken .mtl still loads the geometry; the names come from `usemtl`
    // only through the material list, so without it every face is `default`.
    let mtl: Vec<String> = match materials {
        Ok(m) => m.into_iter().map(|m| m.name).collect(),
        Err(e) => {
            if models.iter().any(|m| m.mesh.material_id.is_some()) {
                return Err(format!("its material library could not be read: {e}"));
            }
            Vec::new()
        }
    };
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
    }
    if out.indices.is_empty() {
        return Err("no triangles".to_string());
    }
    Ok(ObjMesh { mesh: out, material_names: names })
}
