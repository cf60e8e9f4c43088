//! Geometry: triangle meshes and (later) the obvhs BVH.

pub mod mesh;
pub use mesh::TriMesh;
