//! Geometry: triangle meshes, bounds and the obvhs BVH.

pub mod bvh;
pub mod bvh4;
pub mod mesh;

pub use bvh::{Accel, BvhLayout, Hit, Ray};
pub use mesh::TriMesh;
