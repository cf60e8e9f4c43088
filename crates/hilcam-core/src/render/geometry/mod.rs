//! Geometry: triangle meshes, bounds and the obvhs BVH.

pub mod bvh;
pub mod bvh4;
pub mod bvh8;
pub mod closest_packet;
mod lane_triangle;
pub mod mesh;
pub mod shadow_packet;
mod wide;

pub use bvh::{Accel, BvhLayout, Hit, Ray, TestRay};
pub use mesh::TriMesh;
