//! The tree's leaves as the frame's pixel coverage reads them (`render::cull::coverage`):
//! each leaf's box and its range of primitives.

use glam::Vec3;
use obvhs::bvh2::Bvh2;

/// A leaf of the tree: its bounding box and its primitives `first..first + count` (BVH
/// order, as [`Accel::vertex_indices`]).
#[derive(Clone, Copy, Debug)]
pub struct Leaf {
    pub min: Vec3,
    pub max: Vec3,
    pub first: u32,
    pub count: u32,
}

/// The leaves of a `Bvh2` (which the wide trees keep).
pub(super) fn bvh2_leaves(b: &Bvh2) -> Vec<Leaf> {
    let leaf = |n: &obvhs::bvh2::node::Bvh2Node| Leaf {
        min: n.aabb().min.into(),
        max: n.aabb().max.into(),
        first: n.first_index,
        count: n.prim_count,
    };
    b.nodes.iter().filter(|n| n.is_leaf()).map(leaf).collect()
}
