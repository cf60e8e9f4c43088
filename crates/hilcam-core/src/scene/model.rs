//! A `[[mesh]]` file of either kind — OBJ + MTL or glTF 2.0 (`.gltf`, `.glb`) — as the
//! scene builder needs it (`obj` and `gltf` load one): triangles, a material name per triangle, and the materials
//! as the file's author defined them.

use super::authored::AuthoredBsdf;
use super::mtl::MtlMaterial;
use crate::render::geometry::TriMesh;

/// The materials a model file defines itself.
pub enum AuthoredMaterials {
    /// An OBJ's MTL blocks, built on demand (only materials without a table are).
    Mtl(Vec<MtlMaterial>),
    /// A glTF file's materials, each already built (or the error that building gave).
    Gltf(Vec<(String, Result<AuthoredBsdf, String>)>),
}

/// Triangles of one model file; `mesh.material` indexes `material_names`.
pub struct ModelMesh {
    pub mesh: TriMesh,
    pub material_names: Vec<String>,
    pub authored: AuthoredMaterials,
    /// What the file has and hilcam does not use, file-wide (each names the file).
    pub notes: Vec<String>,
    /// Texture coordinates `(s, t)` (t = 0 at an image's top row) at each triangle's
    /// corners, in `mesh.indices` order; empty unless the file has a textured material
    /// and coordinates for it.
    pub uv: Vec<[glam::Vec2; 3]>,
}

impl ModelMesh {
    /// The file's own definition of material `name`, built, if it has one.
    pub fn authored(&self, name: &str) -> Option<Result<AuthoredBsdf, String>> {
        match &self.authored {
            AuthoredMaterials::Mtl(defs) => defs.iter().find(|m| m.name == name).map(super::mtl_bsdf::bsdf_from_mtl),
            AuthoredMaterials::Gltf(defs) => defs.iter().find(|(n, _)| n == name).map(|(_, b)| b.clone()),
        }
    }
}
