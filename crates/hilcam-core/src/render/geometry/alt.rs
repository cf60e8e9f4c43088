//! The lab's alternative trees (feature `alt-bvh`): obvhs's own binary `Bvh2` and
//! compressed 8-wide `CwBvh` with their traversals, and our SSE 4-wide `bvh4`. Serving
//! uses `bvh8` only; these stay for `hilcam bench render` and the tests that compare
//! layouts on the same rays.

use super::BvhLayout;
use super::bvh4::Bvh4;
use super::leaves::{Leaf, bvh2_leaves};
use obvhs::{
    BvhBuildParams,
    bvh2::{Bvh2, builder::build_bvh2_from_tris},
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::{Ray as ObRay, RayHit},
    rt_triangle::RtTriangle,
    triangle::Triangle,
};
use std::time::Duration;

pub(super) enum AltTree {
    Bvh2(Bvh2),
    Cw(CwBvh),
    Bvh4(Bvh4),
}

impl AltTree {
    /// Builds `layout` (not `bvh8`) over `tris`: the tree, its primitive order (indices
    /// into `tris`) and its leaves (the `Bvh2`'s; for the CWBVH each triangle).
    pub(super) fn build(
        layout: BvhLayout,
        tris: &[Triangle],
        params: BvhBuildParams,
        core: &mut Duration,
    ) -> (Self, Vec<u32>, Vec<Leaf>) {
        match layout {
            BvhLayout::Cwbvh => {
                let b = build_cwbvh_from_tris(tris, params, core);
                let leaves = b.primitive_indices.iter().enumerate();
                let leaves = leaves.map(|(k, &i)| triangle_leaf(k as u32, &tris[i as usize])).collect();
                let order = b.primitive_indices.clone();
                (AltTree::Cw(b), order, leaves)
            }
            BvhLayout::Bvh2 => {
                let b = build_bvh2_from_tris(tris, params, core);
                let (leaves, order) = (bvh2_leaves(&b), b.primitive_indices.clone());
                (AltTree::Bvh2(b), order, leaves)
            }
            BvhLayout::Bvh4 => {
                let b = build_bvh2_from_tris(tris, params, core);
                let (tree, leaves) = (AltTree::Bvh4(Bvh4::from_bvh2(&b)), bvh2_leaves(&b));
                (tree, b.primitive_indices, leaves)
            }
            BvhLayout::Bvh8 => unreachable!("bvh8 is the product's tree, built by `Accel::build`"),
        }
    }

    /// Closest hit: `hit` updated, true when found.
    #[inline]
    pub(super) fn intersect(&self, ray: ObRay, hit: &mut RayHit, tris: &[RtTriangle]) -> bool {
        match self {
            AltTree::Bvh2(b) => b.ray_traverse(ray, hit, |ray, id| tris[id].intersect(ray)),
            AltTree::Cw(b) => b.ray_traverse(ray, hit, |ray, id| tris[id].intersect(ray)),
            AltTree::Bvh4(b) => b.intersect(&ray, tris).map(|(k, t)| (hit.primitive_id, hit.t) = (k, t)).is_some(),
        }
    }

    /// True when anything blocks the ray.
    #[inline]
    pub(super) fn occluded(&self, ray: ObRay, tris: &[RtTriangle]) -> bool {
        match self {
            AltTree::Bvh2(b) => !b.ray_traverse_miss(ray, |ray, id| tris[id].intersect(ray)),
            AltTree::Cw(b) => !b.ray_traverse_miss(ray, |ray, id| tris[id].intersect(ray)),
            AltTree::Bvh4(b) => b.occluded(&ray, tris),
        }
    }

    /// The packet walk (`shadow_packet`) where this tree has one: `bvh4`.
    pub(super) fn occluded_packet(&self, rays: &[ObRay], tris: &[RtTriangle]) -> Option<u32> {
        match self {
            AltTree::Bvh4(b) => b.occluded_packet(rays, tris),
            AltTree::Bvh2(_) | AltTree::Cw(_) => None,
        }
    }
}

/// A one-triangle leaf: primitive `k` (BVH order) and its box.
fn triangle_leaf(k: u32, t: &Triangle) -> Leaf {
    Leaf { min: t.v0.min(t.v1).min(t.v2).into(), max: t.v0.max(t.v1).max(t.v2).into(), first: k, count: 1 }
}
