//! An 8-wide BVH collapsed from obvhs's `Bvh2`, traversed eight child boxes per step (AVX2
//! when the CPU has it, detected once when the tree is built; a scalar loop otherwise): the
//! product's tree. Its node layout, walk and the argument that its answers are obvhs's are
//! `wide`'s; this file adds the AVX2 box test and chooses it per CPU.
//!
//! Why eight: traversal is branch-bound (`docs/performance.md`), and an 8-wide
//! tree has two thirds of the levels of a 4-wide one (`log 8 / log 4`), so a ray makes
//! about two thirds of the node visits (and their mispredicted branches) with one box
//! test of eight lanes per visit (measured: 7.2 → 4.85 visits per closest-hit ray).

use super::wide::{Entry, Node, SLACK, Scalar, collapse, stack_need, walk, with_stack};
use obvhs::{bvh2::Bvh2, ray::Ray as ObRay, rt_triangle::RtTriangle};
use std::mem::MaybeUninit;

/// Children per node.
const W: usize = 8;

/// A node of eight children (`wide::Node`).
type Node8 = Node<W>;
#[cfg(test)]
const EMPTY: Node8 = Node8::EMPTY;

/// The 8-wide tree. Leaf ranges index the primitive order of the `Bvh2` it was made from.
#[derive(Clone, Debug, Default)]
pub struct Bvh8 {
    nodes: Vec<Node8>,
    /// Depth in 8-wide nodes (root = 1).
    depth: usize,
    /// The box test runs in AVX2 (checked once, in `from_bvh2`).
    avx2: bool,
}

impl Bvh8 {
    /// Collapse a `Bvh2`: each 8-wide node takes a binary node's two children and keeps
    /// opening its largest-area inner child until it has eight.
    pub fn from_bvh2(b: &Bvh2) -> Self {
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        let (nodes, depth) = collapse::<W>(b);
        Bvh8 { nodes, depth, avx2 }
    }

    /// Number of 8-wide nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Depth in 8-wide nodes.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Whether the box test runs in AVX2 (else the scalar loop).
    pub fn uses_avx2(&self) -> bool {
        self.avx2
    }

    /// The same tree with the scalar box test (for tests: both must give the same answers).
    #[doc(hidden)]
    pub fn scalar(mut self) -> Self {
        self.avx2 = false;
        self
    }

    /// Stack entries a traversal can need: each level leaves at most seven siblings behind.
    fn stack_need(&self) -> usize {
        stack_need(W, self.depth)
    }

    /// Closest hit within `[ray.tmin, ray.tmax)`: `(primitive index, t)` (`wide::walk`).
    #[inline]
    pub fn intersect(&self, ray: &ObRay, tris: &[RtTriangle]) -> Option<(u32, f32)> {
        with_stack(self.stack_need(), |stack| self.dispatch::<false>(ray, tris, stack))
    }

    /// True when any triangle is hit within `[ray.tmin, ray.tmax)` (stops at the first).
    #[inline]
    pub fn occluded(&self, ray: &ObRay, tris: &[RtTriangle]) -> bool {
        with_stack(self.stack_need(), |stack| self.dispatch::<true>(ray, tris, stack)).is_some()
    }

    /// Occlusion of up to eight rays sharing one direction (bit `i`: ray `i` is blocked),
    /// in one walk (`shadow_packet`); the same answers as [`Bvh8::occluded`] ray by ray.
    /// `None` where the packet walk does not apply, or the scalar box test is forced (ask
    /// the rays one by one).
    pub fn occluded_packet(&self, rays: &[ObRay], tris: &[RtTriangle]) -> Option<u32> {
        if !self.avx2 {
            return None;
        }
        super::shadow_packet::occluded(&self.nodes, tris, rays, SLACK, self.stack_need())
    }

    /// Closest hits of up to eight rays in one walk (`closest_packet`): per lane the
    /// primitive (`closest_packet::MISS` for none) and `t`, the same `t` as
    /// [`Bvh8::intersect`] ray by ray. `None` where the packet walk does not apply (trace the
    /// rays one by one).
    pub fn intersect_packet(
        &self,
        rays: &[ObRay],
        tris: &[RtTriangle],
    ) -> Option<([u32; super::shadow_packet::PACKET], [f32; super::shadow_packet::PACKET])> {
        if !self.avx2 {
            return None;
        }
        super::closest_packet::closest(&self.nodes, tris, rays, SLACK, self.stack_need())
    }

    #[inline(always)]
    fn dispatch<const ANY: bool>(
        &self,
        ray: &ObRay,
        tris: &[RtTriangle],
        stack: &mut [MaybeUninit<Entry>],
    ) -> Option<(u32, f32)> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2 (`from_bvh2`).
            return unsafe { self.walk_avx2::<ANY>(ray, tris, stack) };
        }
        // SAFETY: the scalar test needs no CPU feature.
        unsafe { walk::<W, ANY, Scalar>(&self.nodes, ray, tris, stack) }
    }

    /// The whole walk compiled with AVX2 (the box test inlines into it).
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn walk_avx2<const ANY: bool>(
        &self,
        ray: &ObRay,
        tris: &[RtTriangle],
        stack: &mut [MaybeUninit<Entry>],
    ) -> Option<(u32, f32)> {
        // SAFETY: the caller guarantees AVX2.
        unsafe { walk::<W, ANY, avx2::Ray8>(&self.nodes, ray, tris, stack) }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::super::wide::{Prep, SLACK, Slab};
    use super::{Node8, W};
    use std::arch::x86_64::*;

    /// The ray's origin and reciprocal direction broadcast to eight lanes.
    pub(super) struct Ray8 {
        org: [__m256; 3],
        inv: [__m256; 3],
        tmin: __m256,
    }

    impl Slab<W> for Ray8 {
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn new(p: &Prep, tmin: f32) -> Self {
            Ray8 {
                org: p.org.map(|x| _mm256_set1_ps(x)),
                inv: p.inv.map(|x| _mm256_set1_ps(x)),
                tmin: _mm256_set1_ps(tmin),
            }
        }

        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn test(&self, node: &Node8, p: &Prep, tmax: f32) -> (u32, [f32; W]) {
            // SAFETY: the loads read `[f32; 8]` fields of a 64-byte-aligned node, so they are
            // in bounds and 32-byte aligned.
            let t = |axis: usize, side: usize| {
                let b = unsafe { _mm256_load_ps(node.bounds[axis][side].as_ptr()) };
                _mm256_mul_ps(_mm256_sub_ps(b, self.org[axis]), self.inv[axis])
            };
            let (nx, ny, nz) = (t(0, p.near[0]), t(1, p.near[1]), t(2, p.near[2]));
            let (fx, fy, fz) = (t(0, 1 - p.near[0]), t(1, 1 - p.near[1]), t(2, 1 - p.near[2]));
            // The accumulator is the second operand: a NaN lane of the first is dropped.
            let near = _mm256_max_ps(nx, _mm256_max_ps(ny, _mm256_max_ps(nz, self.tmin)));
            let far = _mm256_min_ps(fx, _mm256_min_ps(fy, _mm256_min_ps(fz, _mm256_set1_ps(tmax))));
            let far = _mm256_mul_ps(far, _mm256_set1_ps(SLACK));
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            let mut out = [0.0f32; W];
            // SAFETY: `out` has room for eight floats (unaligned store).
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), near) };
            (mask, out)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::wide::{Prep, Slab, scalar_test};
    use super::*;

    /// The AVX2 slab test agrees with the scalar one bit for bit on random boxes and rays,
    /// including zero and negative-zero direction components and empty slots.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn avx2_matches_scalar() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let mut rng = crate::render::sampling::Rng::from_state(7);
        let mut f = |s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
        let mut hits = 0;
        for i in 0..40_000 {
            let used = i % W + 1;
            let mut node = EMPTY;
            for slot in 0..used {
                for axis in 0..3 {
                    let (a, b) = (f(2.0), f(2.0));
                    node.bounds[axis][0][slot] = a.min(b);
                    node.bounds[axis][1][slot] = a.max(b);
                }
            }
            let mut o = glam::Vec3A::new(f(3.0), f(3.0), f(3.0));
            let mut d = glam::Vec3A::new(f(1.0), f(1.0), f(1.0));
            if i % 2 == 1 {
                // Aimed at the centre of one of the boxes (plus a little), so that many hit.
                let s = (i / 2) % used;
                let c = glam::Vec3A::from_array(std::array::from_fn(|a| {
                    0.5 * (node.bounds[a][0][s] + node.bounds[a][1][s]) + f(0.3)
                }));
                d = c - o;
            }
            if i % 3 == 0 {
                d[i % 3] = 0.0;
            }
            if i % 5 == 0 {
                d[(i + 1) % 3] = -0.0;
            }
            if i % 7 == 0 {
                d[(i + 2) % 3] = if i % 2 == 0 { 0.0 } else { -0.0 };
            }
            if i % 11 == 0 {
                // Origin on a box's face plane, along a zero direction component: the NaN case.
                let axis = (i / 11) % 3;
                d[axis] = if i % 2 == 0 { 0.0 } else { -0.0 };
                o[axis] = node.bounds[axis][(i / 33) % 2][0];
            }
            let ray = ObRay::new(o, d, 0.0, if i % 4 < 2 { f32::INFINITY } else { f(4.0).abs() });
            let p = Prep::new(&ray);
            // SAFETY: AVX2 was detected above.
            let (m1, t1) = unsafe {
                let b = avx2::Ray8::new(&p, ray.tmin);
                b.test(&node, &p, ray.tmax)
            };
            let (m2, t2) = scalar_test(&node, &p, ray.tmin, ray.tmax);
            assert_eq!(m1, m2, "case {i}");
            for s in 0..W {
                if m1 & (1 << s) != 0 {
                    // == rather than bits: max(-0, +0) may pick either zero; both order alike.
                    assert_eq!(t1[s], t2[s], "case {i} slot {s}");
                    if t1[s] != 0.0 {
                        assert_eq!(t1[s].to_bits(), t2[s].to_bits(), "case {i} slot {s}");
                    }
                }
            }
            assert_eq!(m1 >> used, 0, "case {i}: an empty slot was hit");
            hits += m1.count_ones();
        }
        assert!(hits > 10_000, "{hits} boxes hit: the comparison is too thin");
    }

    /// AVX2 and scalar walks give the same answers (primitive and `t`) on a random soup.
    #[test]
    fn avx2_and_scalar_walks_agree() {
        use obvhs::{BvhBuildParams, bvh2::builder::build_bvh2_from_tris, triangle::Triangle};
        let mut rng = crate::render::sampling::Rng::from_state(11);
        let mut v = |s: f32| glam::Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 * s - s;
        let tris: Vec<Triangle> = (0..3000)
            .map(|_| {
                let c = v(1.0);
                Triangle { v0: c + v(0.05), v1: c + v(0.05), v2: c + v(0.05) }
            })
            .collect();
        let mut core = std::time::Duration::ZERO;
        let b = build_bvh2_from_tris(&tris, BvhBuildParams::medium_build(), &mut core);
        let rt: Vec<RtTriangle> = b.primitive_indices.iter().map(|&i| RtTriangle::from(&tris[i as usize])).collect();
        let fast = Bvh8::from_bvh2(&b);
        let slow = fast.clone().scalar();
        assert!(fast.depth() >= 2 && fast.node_count() > 1);
        let mut hits = 0;
        for i in 0..20_000 {
            let o = v(2.0);
            let mut d = (v(0.5) - o).normalize();
            if i % 4 == 0 {
                d[i % 3] = if i % 8 == 0 { 0.0 } else { -0.0 };
            }
            let ray = ObRay::new(o, d, 0.0, if i % 3 == 0 { 2.0 } else { f32::INFINITY });
            let (a, s) = (fast.intersect(&ray, &rt), slow.intersect(&ray, &rt));
            assert_eq!(a.map(|h| h.1), s.map(|h| h.1), "ray {i}");
            assert_eq!(fast.occluded(&ray, &rt), slow.occluded(&ray, &rt), "ray {i}");
            hits += a.is_some() as u32;
        }
        assert!(hits > 1000, "{hits} hits");
    }
}
