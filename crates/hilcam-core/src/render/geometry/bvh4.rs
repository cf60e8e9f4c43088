//! A 4-wide BVH collapsed from obvhs's `Bvh2`, traversed four child boxes per step (SSE on
//! x86_64, a scalar loop elsewhere). A lab layout (feature `alt-bvh`): `bvh8` walks the
//! same way with twice the lanes and a third fewer levels, and is ~15 % cheaper on the
//! bounce and shadow rays that dominate (`docs/performance.md`). Its node layout, walk and
//! the argument that its answers are obvhs's are `wide`'s; this file adds the SSE box test.

use super::wide::{Node, SLACK, collapse, stack_need, walk, with_stack};
use obvhs::{bvh2::Bvh2, ray::Ray as ObRay, rt_triangle::RtTriangle};

/// Children per node.
const W: usize = 4;

/// A node of four children (`wide::Node`).
type Node4 = Node<W>;

/// The box test: SSE is part of the x86_64 baseline.
#[cfg(target_arch = "x86_64")]
type Boxes = sse::Ray4;
#[cfg(not(target_arch = "x86_64"))]
type Boxes = super::wide::Scalar;

/// The 4-wide tree. Leaf ranges index the primitive order of the `Bvh2` it was made from.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    nodes: Vec<Node4>,
    /// Depth in 4-wide nodes (root = 1).
    depth: usize,
}

impl Bvh4 {
    /// Collapse a `Bvh2`: each 4-wide node takes a binary node's two children and keeps
    /// opening its largest-area inner child until it has four.
    pub fn from_bvh2(b: &Bvh2) -> Self {
        let (nodes, depth) = collapse::<W>(b);
        Bvh4 { nodes, depth }
    }

    /// Number of 4-wide nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Depth in 4-wide nodes.
    pub fn depth(&self) -> usize {
        self.depth
    }

    fn stack_need(&self) -> usize {
        stack_need(W, self.depth)
    }

    /// Closest hit within `[ray.tmin, ray.tmax)`: `(primitive index, t)` (`wide::walk`).
    #[inline]
    pub fn intersect(&self, ray: &ObRay, tris: &[RtTriangle]) -> Option<(u32, f32)> {
        // SAFETY: `Boxes` needs only the target's baseline features.
        with_stack(self.stack_need(), |stack| unsafe { walk::<W, false, Boxes>(&self.nodes, ray, tris, stack) })
    }

    /// True when any triangle is hit within `[ray.tmin, ray.tmax)` (stops at the first).
    #[inline]
    pub fn occluded(&self, ray: &ObRay, tris: &[RtTriangle]) -> bool {
        // SAFETY: as in `intersect`.
        with_stack(self.stack_need(), |stack| unsafe { walk::<W, true, Boxes>(&self.nodes, ray, tris, stack) })
            .is_some()
    }

    /// Occlusion of up to eight rays sharing one direction (bit `i`: ray `i` is blocked),
    /// in one walk (`shadow_packet`); the same answers as [`Bvh4::occluded`] ray by ray.
    /// `None` where the packet walk does not apply (ask the rays one by one).
    pub fn occluded_packet(&self, rays: &[ObRay], tris: &[RtTriangle]) -> Option<u32> {
        super::shadow_packet::occluded(&self.nodes, tris, rays, SLACK, self.stack_need())
    }
}

#[cfg(target_arch = "x86_64")]
mod sse {
    use super::super::wide::{Prep, SLACK, Slab};
    use super::{Node4, W};
    use std::arch::x86_64::*;

    /// The ray's origin, reciprocal direction and `tmin` broadcast to four lanes.
    pub(super) struct Ray4 {
        org: [__m128; 3],
        inv: [__m128; 3],
        tmin: __m128,
    }

    impl Slab<W> for Ray4 {
        #[inline(always)]
        unsafe fn new(p: &Prep, tmin: f32) -> Self {
            // SAFETY: SSE is part of the x86_64 baseline.
            let splat = |x: f32| unsafe { _mm_set1_ps(x) };
            Ray4 { org: p.org.map(splat), inv: p.inv.map(splat), tmin: splat(tmin) }
        }

        #[inline(always)]
        unsafe fn test(&self, node: &Node4, p: &Prep, tmax: f32) -> (u32, [f32; W]) {
            // SAFETY: SSE is part of the x86_64 baseline; the loads read `[f32; 4]` fields
            // of a 64-byte-aligned node, so they are in bounds and 16-byte aligned.
            unsafe {
                let t = |axis: usize, side: usize| {
                    let b = _mm_load_ps(node.bounds[axis][side].as_ptr());
                    _mm_mul_ps(_mm_sub_ps(b, self.org[axis]), self.inv[axis])
                };
                let (nx, ny, nz) = (t(0, p.near[0]), t(1, p.near[1]), t(2, p.near[2]));
                let (fx, fy, fz) = (t(0, 1 - p.near[0]), t(1, 1 - p.near[1]), t(2, 1 - p.near[2]));
                // The accumulator is the second operand: a NaN lane of the first is dropped.
                let near = _mm_max_ps(nx, _mm_max_ps(ny, _mm_max_ps(nz, self.tmin)));
                let far = _mm_min_ps(fx, _mm_min_ps(fy, _mm_min_ps(fz, _mm_set1_ps(tmax))));
                let far = _mm_mul_ps(far, _mm_set1_ps(SLACK));
                let mask = _mm_movemask_ps(_mm_cmple_ps(near, far)) as u32;
                let mut out = [0.0f32; W];
                _mm_storeu_ps(out.as_mut_ptr(), near);
                (mask, out)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::wide::{Prep, Slab, scalar_test};
    use super::*;

    /// The SSE slab test agrees with the scalar one bit for bit on random boxes and rays,
    /// including zero direction components and empty slots.
    #[test]
    fn sse_matches_scalar() {
        let mut rng = crate::render::sampling::Rng::from_state(7);
        let mut f = |s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
        for i in 0..20_000 {
            let mut node = Node4::EMPTY;
            for slot in 0..(i % 4 + 1) {
                for axis in 0..3 {
                    let (a, b) = (f(2.0), f(2.0));
                    node.bounds[axis][0][slot] = a.min(b);
                    node.bounds[axis][1][slot] = a.max(b);
                }
            }
            let mut d = glam::Vec3A::new(f(1.0), f(1.0), f(1.0));
            if i % 3 == 0 {
                d[i % 3] = 0.0;
            }
            if i % 5 == 0 {
                d[(i + 1) % 3] = -0.0;
            }
            let ray = ObRay::new(
                glam::Vec3A::new(f(3.0), f(3.0), f(3.0)),
                d,
                0.0,
                if i % 2 == 0 { f32::INFINITY } else { f(4.0).abs() },
            );
            let p = Prep::new(&ray);
            // SAFETY: `Boxes` needs only the target's baseline features.
            let (m1, t1) = unsafe { Boxes::new(&p, ray.tmin).test(&node, &p, ray.tmax) };
            let (m2, t2) = scalar_test(&node, &p, ray.tmin, ray.tmax);
            assert_eq!(m1, m2, "case {i}");
            for s in 0..W {
                if m1 & (1 << s) != 0 {
                    // == rather than bits: max(-0, +0) may pick either zero; both order alike.
                    assert_eq!(t1[s], t2[s], "case {i} slot {s}");
                }
            }
            assert_eq!(m1 >> (i % 4 + 1), 0, "case {i}: an empty slot was hit");
        }
    }
}
