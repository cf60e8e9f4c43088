//! A 4-wide BVH collapsed from obvhs's `Bvh2`, traversed four child boxes per step (SSE on
//! x86_64, a scalar loop elsewhere).
//!
//! Only the tree changes: leaves are the `Bvh2` leaves (ranges of the same primitive order)
//! and every triangle is tested with obvhs's own `RtTriangle::intersect` on the same
//! prepared ray, with obvhs's closest-hit rule (`t < current`). The box test is therefore
//! the only new arithmetic, and it is made conservative (a relative slack on the exit
//! distance; a ray lying in a box's face plane is not culled) so it never culls a box
//! holding a triangle the triangle test would accept: the closest `t` equals the
//! brute-force minimum bit for bit (up to the sign of a zero `t` when two triangles tie
//! at the origin; which of exactly tied triangles is reported depends on visit order).
//!
//! Zero direction components: the reciprocal is ±inf, and `(bound - origin) * inv` is NaN
//! exactly when the origin lies on that bound's plane. Such an axis must not constrain the
//! interval (the ray runs inside the slab's face), so the NaN is dropped by the
//! min/max order (`_mm_max_ps(x, acc)` returns `acc` when `x` is NaN, as `f32::max`
//! ignores NaN). Clamping the direction (Embree's `rcp_safe`, obvhs's `safe_inverse`)
//! would instead make the face plane an exit at `t = 0` for one sign of zero and cull
//! the box (obvhs's `Bvh2` misses such a hit; see `tests/render/bvh_wide.rs`'s axis rays). Not
//! covered: a tiny non-zero component with the origin exactly on a face, where the
//! triangle test's rounding could accept a point just outside the box.

use super::wide::{Entry, Node, collapse};
use obvhs::{bvh2::Bvh2, ray::Ray as ObRay, rt_triangle::RtTriangle};
use std::mem::MaybeUninit;

/// Exit distances are scaled by this before `entry <= exit`: covers the few roundings of
/// the slab test and of the triangle's own `t` (a hit on a box face must not be culled).
const SLACK: f32 = 1.0 + 1.0 / (1u32 << 20) as f32;
/// Traversal stack entries kept on the machine stack; deeper trees use a heap stack.
const STACK: usize = 256;

/// A node of four children (`wide::Node`).
type Node4 = Node<4>;
#[cfg(test)]
const EMPTY: Node4 = Node4::EMPTY;

/// The 4-wide tree. Leaf ranges index the primitive order of the `Bvh2` it was made from.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    nodes: Vec<Node4>,
    /// Depth in 4-wide nodes (root = 1).
    depth: usize,
}

/// Per-ray constants of the slab test.
struct Prep {
    org: [f32; 3],
    inv: [f32; 3],
    /// 0 when the direction component is positive (near plane = min), else 1.
    near: [usize; 3],
}

impl Prep {
    fn new(ray: &ObRay) -> Self {
        let d = ray.direction.to_array();
        let inv = d.map(|x| 1.0 / x);
        Prep { org: ray.origin.to_array(), inv, near: d.map(|x| x.is_sign_negative() as usize) }
    }
}

impl Bvh4 {
    /// Collapse a `Bvh2`: each 4-wide node takes a binary node's two children and keeps
    /// opening its largest-area inner child until it has four.
    pub fn from_bvh2(b: &Bvh2) -> Self {
        let (nodes, depth) = collapse::<4>(b);
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

    /// Stack entries a traversal can need: each level leaves at most three siblings behind.
    fn stack_need(&self) -> usize {
        3 * self.depth + 2
    }

    /// Closest hit within `[ray.tmin, ray.tmax)`: `(primitive index, t)`. A triangle
    /// replaces the current hit only when its `t` is strictly smaller (as obvhs's `Bvh2`).
    #[inline]
    pub fn intersect(&self, ray: &ObRay, tris: &[RtTriangle]) -> Option<(u32, f32)> {
        if self.stack_need() <= STACK {
            self.traverse::<false>(ray, tris, &mut [MaybeUninit::uninit(); STACK])
        } else {
            self.traverse::<false>(ray, tris, &mut vec![MaybeUninit::uninit(); self.stack_need()])
        }
    }

    /// True when any triangle is hit within `[ray.tmin, ray.tmax)` (stops at the first).
    #[inline]
    pub fn occluded(&self, ray: &ObRay, tris: &[RtTriangle]) -> bool {
        let found = if self.stack_need() <= STACK {
            self.traverse::<true>(ray, tris, &mut [MaybeUninit::uninit(); STACK])
        } else {
            self.traverse::<true>(ray, tris, &mut vec![MaybeUninit::uninit(); self.stack_need()])
        };
        found.is_some()
    }

    /// Occlusion of up to eight rays sharing one direction (bit `i`: ray `i` is blocked),
    /// in one walk (`shadow_packet`); the same answers as [`Bvh4::occluded`] ray by ray.
    /// `None` where the packet walk does not apply (ask the rays one by one).
    pub fn occluded_packet(&self, rays: &[ObRay], tris: &[RtTriangle]) -> Option<u32> {
        super::shadow_packet::occluded(&self.nodes, tris, rays, SLACK, self.stack_need())
    }

    #[inline(always)]
    /// `stack` is left uninitialised (zeroing it costs as much as a short traversal): only
    /// entries below `sp` are read, and each was written first.
    fn traverse<const ANY: bool>(
        &self,
        ray: &ObRay,
        tris: &[RtTriangle],
        stack: &mut [MaybeUninit<Entry>],
    ) -> Option<(u32, f32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let p = Prep::new(ray);
        let boxes = Boxes::new(&p, ray.tmin);
        let mut ray = *ray;
        let mut best: Option<(u32, f32)> = None;
        // Tests a leaf's triangles in order; true when one was hit.
        let leaf = |c: &Entry, ray: &mut ObRay, best: &mut Option<(u32, f32)>| {
            if c.t > ray.tmax * SLACK {
                return false;
            }
            let mut found = false;
            for k in c.index..c.index + c.count {
                let t = tris[k as usize].intersect(ray);
                if t < ray.tmax {
                    ray.tmax = t;
                    *best = Some((k, t));
                    found = true;
                    if ANY {
                        break;
                    }
                }
            }
            found
        };
        let mut sp = 0;
        let mut node = &self.nodes[0];
        loop {
            let (mut mask, tnear) = boxes.test(node, &p, ray.tmax);
            if ANY {
                // A yes/no answer does not depend on the order, so nothing is sorted: leaves
                // are tested as they come and inner children pushed as they come (`tmax`
                // changes only when the walk ends). Sorting cost 25 % of a shadow ray.
                let mut next = None;
                while mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if node.is_empty_slot(slot) {
                        continue; // entered only by a ray with a NaN coordinate
                    }
                    let c = Entry { index: node.child[slot], count: node.count[slot], t: tnear[slot] };
                    if c.count > 0 {
                        if leaf(&c, &mut ray, &mut best) {
                            return best;
                        }
                    } else if let Some(i) = next.replace(c.index) {
                        stack[sp] = MaybeUninit::new(Entry { index: i, count: 0, t: 0.0 });
                        sp += 1;
                    }
                }
                let next = match next {
                    Some(i) => i,
                    None if sp == 0 => return best,
                    None => {
                        sp -= 1;
                        // SAFETY: `stack[..sp]` has been written (pushed children).
                        unsafe { stack[sp].assume_init() }.index
                    }
                };
                node = &self.nodes[next as usize];
                continue;
            }
            // Hit children sorted far to near (`hit[n - 1]` is the nearest).
            let mut hit = [Entry::default(); 4];
            let mut n = 0;
            while mask != 0 {
                let slot = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if node.is_empty_slot(slot) {
                    continue;
                }
                let c = Entry { index: node.child[slot], count: node.count[slot], t: tnear[slot] };
                let mut j = n;
                while j > 0 && hit[j - 1].t < c.t {
                    hit[j] = hit[j - 1];
                    j -= 1;
                }
                hit[j] = c;
                n += 1;
            }
            // Leaves first, near to far (as obvhs's Bvh2): a hit shortens the ray before the
            // inner children are visited. Only the leaves nearer than every inner child;
            // farther ones wait on the stack in distance order.
            let mut rest = n;
            while rest > 0 && hit[rest - 1].count > 0 {
                leaf(&hit[rest - 1], &mut ray, &mut best);
                rest -= 1;
            }
            // The nearest of the rest next; the others pushed far to near. All three slots
            // are copied, saving a branch per child (-7 % per ray); `rest - 1` of them count.
            // In bounds: at tree level L at most 3(L - 1) entries are held, and the stack
            // has room for 3·depth + 2.
            let mut next = None;
            if rest > 0 {
                for (k, &e) in hit[..3].iter().enumerate() {
                    stack[sp + k] = MaybeUninit::new(e);
                }
                sp += rest - 1;
                next = Some(hit[rest - 1]);
            }
            let mut next = next.filter(|c| c.t <= ray.tmax * SLACK);
            while next.is_none() {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                // SAFETY: `stack[..sp]` has been written (pushed children).
                let e = unsafe { stack[sp].assume_init() };
                if e.count > 0 {
                    leaf(&e, &mut ray, &mut best);
                } else {
                    next = Some(e).filter(|c| c.t <= ray.tmax * SLACK);
                }
            }
            node = &self.nodes[next.map_or(0, |c| c.index) as usize];
        }
    }
}

/// The 4-box slab test for one ray.
struct Boxes {
    #[cfg(target_arch = "x86_64")]
    v: sse::Ray4,
    tmin: f32,
}

impl Boxes {
    #[inline(always)]
    fn new(p: &Prep, tmin: f32) -> Self {
        Boxes {
            #[cfg(target_arch = "x86_64")]
            v: sse::Ray4::new(p),
            tmin,
        }
    }

    /// Bit `i` set when child `i`'s box overlaps `[tmin, tmax]` (conservatively); the
    /// entry distance of each child.
    #[inline(always)]
    fn test(&self, node: &Node4, p: &Prep, tmax: f32) -> (u32, [f32; 4]) {
        #[cfg(target_arch = "x86_64")]
        {
            let _ = p;
            self.v.test(node, p, self.tmin, tmax)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            scalar_test(node, p, self.tmin, tmax)
        }
    }
}

/// Reference (and non-x86_64) form of the slab test; the SSE form does the same operations
/// in the same order, lane by lane.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn scalar_test(node: &Node4, p: &Prep, tmin: f32, tmax: f32) -> (u32, [f32; 4]) {
    let mut mask = 0;
    let mut tnear = [0.0; 4];
    for (slot, entry) in tnear.iter_mut().enumerate() {
        let t = |axis: usize, side: usize| (node.bounds[axis][side][slot] - p.org[axis]) * p.inv[axis];
        let (nx, ny, nz) = (t(0, p.near[0]), t(1, p.near[1]), t(2, p.near[2]));
        let (fx, fy, fz) = (t(0, 1 - p.near[0]), t(1, 1 - p.near[1]), t(2, 1 - p.near[2]));
        // `f32::max`/`min` ignore a NaN operand (see the module comment).
        let near = nx.max(ny.max(nz.max(tmin)));
        let far = fx.min(fy.min(fz.min(tmax))) * SLACK;
        mask |= ((near <= far) as u32) << slot;
        *entry = near;
    }
    (mask, tnear)
}

#[cfg(target_arch = "x86_64")]
mod sse {
    use super::{Node4, Prep, SLACK};
    use std::arch::x86_64::*;

    /// The ray's origin and reciprocal direction broadcast to four lanes.
    pub(super) struct Ray4 {
        org: [__m128; 3],
        inv: [__m128; 3],
    }

    impl Ray4 {
        #[inline(always)]
        pub(super) fn new(p: &Prep) -> Self {
            // SAFETY: SSE is part of the x86_64 baseline.
            let splat = |x: f32| unsafe { _mm_set1_ps(x) };
            Ray4 { org: p.org.map(splat), inv: p.inv.map(splat) }
        }

        #[inline(always)]
        pub(super) fn test(&self, node: &Node4, p: &Prep, tmin: f32, tmax: f32) -> (u32, [f32; 4]) {
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
                let near = _mm_max_ps(nx, _mm_max_ps(ny, _mm_max_ps(nz, _mm_set1_ps(tmin))));
                let far = _mm_min_ps(fx, _mm_min_ps(fy, _mm_min_ps(fz, _mm_set1_ps(tmax))));
                let far = _mm_mul_ps(far, _mm_set1_ps(SLACK));
                let mask = _mm_movemask_ps(_mm_cmple_ps(near, far)) as u32;
                let mut out = [0.0f32; 4];
                _mm_storeu_ps(out.as_mut_ptr(), near);
                (mask, out)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SSE slab test agrees with the scalar one bit for bit on random boxes and rays,
    /// including zero direction components and empty slots.
    #[test]
    fn sse_matches_scalar() {
        let mut rng = crate::render::sampling::Rng::from_state(7);
        let mut f = |s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
        for i in 0..20_000 {
            let mut node = EMPTY;
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
            let b = Boxes::new(&p, ray.tmin);
            let (m1, t1) = b.test(&node, &p, ray.tmax);
            let (m2, t2) = scalar_test(&node, &p, ray.tmin, ray.tmax);
            assert_eq!(m1, m2, "case {i}");
            for s in 0..4 {
                if m1 & (1 << s) != 0 {
                    // == rather than bits: max(-0, +0) may pick either zero; both order alike.
                    assert_eq!(t1[s], t2[s], "case {i} slot {s}");
                }
            }
            assert_eq!(m1 >> (i % 4 + 1), 0, "case {i}: an empty slot was hit");
        }
    }
}
