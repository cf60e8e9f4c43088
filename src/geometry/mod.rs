//! Geometry: triangle meshes, bounds and the obvhs BVH.

pub mod bvh;
pub mod mesh;

pub use bvh::{Accel, BvhLayout, Hit, Ray, TestRay};
pub use mesh::TriMesh;
