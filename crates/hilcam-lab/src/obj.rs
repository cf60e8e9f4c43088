//! A minimal, deterministic OBJ/MTL writer, and OBJ reading through `tobj`.
//!
//! Writing: `v x y z` with 6 decimals (1 µm), then faces grouped by material in material
//! index order (`usemtl name`), 1-based indices. The output is a pure function of the mesh,
//! so regenerating a model gives byte-identical files.

use glam::Vec3;
use hilcam_core::render::geometry::TriMesh;
use hilcam_core::scene::fold::FoldError;
use std::io::Write;
use std::path::Path;

/// One MTL material: a name and its diffuse colour (for viewers; hilcam maps materials
/// by name in the scene file).
#[derive(Clone, Debug, PartialEq)]
pub struct MtlEntry {
    pub name: String,
    pub kd: [f32; 3],
    /// A comment line written above the material (what it stands for).
    pub comment: String,
}

/// Write `mesh` as OBJ. `material_names[m]` names material index `m`; `mtllib` adds a
/// `mtllib` line. Triangles are written grouped by material, stably.
pub fn write_obj<W: Write>(
    w: &mut W,
    mesh: &TriMesh,
    material_names: &[&str],
    mtllib: Option<&str>,
    object: &str,
) -> std::io::Result<()> {
    writeln!(w, "# hilcam OBJ: {} vertices, {} triangles", mesh.positions.len(), mesh.indices.len())?;
    if let Some(lib) = mtllib {
        writeln!(w, "mtllib {lib}")?;
    }
    writeln!(w, "o {object}")?;
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", fmt(p.x), fmt(p.y), fmt(p.z))?;
    }
    let mut order: Vec<usize> = (0..mesh.indices.len()).collect();
    order.sort_by_key(|&i| mesh.material[i]);
    let mut current = None;
    for i in order {
        let m = mesh.material[i];
        if current != Some(m) {
            let name = material_names.get(m as usize).copied().unwrap_or("default");
            writeln!(w, "usemtl {name}")?;
            current = Some(m);
        }
        let [a, b, c] = mesh.indices[i];
        writeln!(w, "f {} {} {}", a + 1, b + 1, c + 1)?;
    }
    Ok(())
}

/// Fixed 6 decimals, with negative zero written as zero.
fn fmt(x: f32) -> String {
    let s = format!("{x:.6}");
    if s == "-0.000000" { "0.000000".to_string() } else { s }
}

/// Write an MTL file body.
pub fn write_mtl<W: Write>(w: &mut W, materials: &[MtlEntry]) -> std::io::Result<()> {
    writeln!(w, "# hilcam MTL: colours for viewers; BRDFs are assigned by name in the scene")?;
    for m in materials {
        writeln!(w)?;
        if !m.comment.is_empty() {
            writeln!(w, "# {}", m.comment)?;
        }
        writeln!(w, "newmtl {}", m.name)?;
        writeln!(w, "Kd {:.4} {:.4} {:.4}", m.kd[0], m.kd[1], m.kd[2])?;
        writeln!(w, "Ka 0 0 0")?;
        writeln!(w, "Ks 0 0 0")?;
        writeln!(w, "illum 1")?;
    }
    Ok(())
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> FoldError + '_ {
    move |source| FoldError::Io { path: path.display().to_string(), source }
}

/// Write an OBJ file (buffered).
pub fn write_obj_file(
    path: &Path,
    mesh: &TriMesh,
    material_names: &[&str],
    mtllib: Option<&str>,
    object: &str,
) -> Result<(), FoldError> {
    let f = std::fs::File::create(path).map_err(io_err(path))?;
    let mut w = std::io::BufWriter::new(f);
    write_obj(&mut w, mesh, material_names, mtllib, object).map_err(io_err(path))?;
    w.flush().map_err(io_err(path))
}

/// Write an MTL file.
pub fn write_mtl_file(path: &Path, materials: &[MtlEntry]) -> Result<(), FoldError> {
    let f = std::fs::File::create(path).map_err(io_err(path))?;
    let mut w = std::io::BufWriter::new(f);
    write_mtl(&mut w, materials).map_err(io_err(path))?;
    w.flush().map_err(io_err(path))
}

/// Read an OBJ (all models merged; material index = tobj's material id, or 0) with tobj.
/// Materials are not needed for measuring, so a missing MTL is not an error.
pub fn read_obj(path: &Path) -> Result<TriMesh, FoldError> {
    let (models, _materials) = tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS)
        .map_err(|source| FoldError::Obj { path: path.display().to_string(), source })?;
    let mut mesh = TriMesh::default();
    for m in models {
        let part = TriMesh {
            positions: m.mesh.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect(),
            indices: m.mesh.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            material: vec![m.mesh.material_id.unwrap_or(0) as u32; m.mesh.indices.len() / 3],
        };
        mesh.append(&part);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_tobj() {
        let mesh = TriMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(-0.0, 0.5, -1.25)],
            indices: vec![[0, 1, 2], [1, 3, 2]],
            material: vec![1, 0],
        };
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.obj");
        write_obj_file(&p, &mesh, &["a", "b"], None, "t").unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(!text.contains("-0.000000"));
        let back = read_obj(&p).unwrap();
        assert_eq!(back.indices.len(), 2);
        // Same triangle set (written grouped by material: [1,3,2] first).
        let tri = |m: &TriMesh, i: usize| m.triangle(i);
        assert_eq!(tri(&back, 0), tri(&mesh, 1));
        assert_eq!(tri(&back, 1), tri(&mesh, 0));
    }
}
