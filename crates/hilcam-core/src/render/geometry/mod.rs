//! Geometry: triangle meshes, bounds and the BVH (the lab's alternative layouts behind the
//! `alt-bvh` feature).

#[cfg(feature = "alt-bvh")]
mod alt;
pub mod bvh;
#[cfg(feature = "alt-bvh")]
pub mod bvh4;
pub mod bvh8;
pub mod closest_packet;
mod lane_triangle;
mod leaves;
pub mod mesh;
pub mod parts;
pub mod shadow_packet;
pub mod spawn;
mod wide;

pub use bvh::{Accel, BvhLayout, Hit, Ray, TestRay};
pub use mesh::TriMesh;
