//! Shadow rays toward the sun, eight at a time through one walk of a wide BVH.
//!
//! Every shadow ray of a frame runs along the same direction, and a wave's rays start at
//! the hits of neighbouring pixels, so eight consecutive ones walk nearly the same nodes.
//! Walked together, a node's boxes are tested against all eight origins at once (AVX2
//! lanes) and the traversal's branches — the cost of a single-ray walk
//! (docs/performance.md) — are taken once per packet instead of once per ray.
//!
//! The answers are those of the single-ray walk: the box test is the same conservative slab
//! test as `wide`'s (same operations in the same order per lane, so it culls no box holding
//! a triangle the triangle test accepts), and the triangle test is obvhs's
//! `RtTriangle::intersect` lane by lane (`lane_triangle`, shared with `closest_packet`),
//! so every (ray, triangle) pair gets the same yes/no (`tests/render/shadow_packet.rs` checks the
//! walk against brute force and against single rays).

use super::wide::Node;
use obvhs::{ray::Ray as ObRay, rt_triangle::RtTriangle};

/// Rays per packet.
pub const PACKET: usize = 8;

/// The packet answer asked ray by ray: bit `i` set when `blocked(rays[i])` (the fallback
/// wherever the packet walk does not apply).
pub fn one_by_one<R>(rays: &[R], blocked: impl Fn(&R) -> bool) -> u32 {
    rays.iter().enumerate().fold(0, |m, (i, r)| m | (u32::from(blocked(r)) << i))
}

/// Whether this CPU runs the AVX2 walk (checked once).
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static AVX2: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *AVX2.get_or_init(|| std::arch::is_x86_feature_detected!("avx2"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Occlusion of up to [`PACKET`] rays that share one direction (bit `i` set: ray `i` hits
/// a triangle within `[tmin, tmax]`), or `None` when the AVX2 walk does not apply (no
/// AVX2, directions differ, or a stack of `stack_need` entries would not fit) and the
/// caller must walk the rays one by one.
pub(super) fn occluded<const W: usize>(
    nodes: &[Node<W>],
    tris: &[RtTriangle],
    rays: &[ObRay],
    slack: f32,
    stack_need: usize,
) -> Option<u32> {
    if rays.is_empty() || nodes.is_empty() {
        return Some(0);
    }
    let d = rays[0].direction;
    // Bit for bit: a `0.0` and a `-0.0` component have reciprocals of opposite sign.
    let bits = |v: glam::Vec3A| v.to_array().map(f32::to_bits);
    let shared = rays.len() <= PACKET && rays.iter().all(|r| bits(r.direction) == bits(d));
    if !shared || stack_need > avx::STACK || !avx2() {
        return None;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: AVX2 was detected above.
        Some(unsafe { avx::walk(nodes, tris, rays, slack) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (tris, slack);
        None
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::super::lane_triangle::{Lanes, triangle};
    use super::{Node, PACKET};
    use obvhs::{ray::Ray as ObRay, rt_triangle::RtTriangle};
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    /// Stack entries kept on the machine stack.
    pub(super) const STACK: usize = 512;

    /// The packet walk. Unsorted, as the single-ray any-hit walk: a yes/no answer does not
    /// depend on the order. Each stack entry carries the rays that entered that child.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn walk<const W: usize>(
        nodes: &[Node<W>],
        tris: &[RtTriangle],
        rays: &[ObRay],
        slack: f32,
    ) -> u32 {
        let n = rays.len();
        let all = (1u32 << n) - 1;
        // Lanes beyond `n` repeat ray 0 and are masked out.
        let mut v = [[0.0f32; PACKET]; 5];
        for i in 0..PACKET {
            let r = &rays[if i < n { i } else { 0 }];
            for (k, x) in [r.origin.x, r.origin.y, r.origin.z, r.tmin, r.tmax].into_iter().enumerate() {
                v[k][i] = x;
            }
        }
        // SAFETY: AVX2 is enabled on this function; the loads read `[f32; 8]` arrays.
        let [ox, oy, oz, tmin, tmax] = v.map(|a| unsafe { _mm256_loadu_ps(a.as_ptr()) });
        let org = [ox, oy, oz];
        let d = rays[0].direction;
        let dir = d.to_array();
        // As `wide::Prep`: the exact reciprocal, ±inf for a zero component.
        let inv = dir.map(|x| _mm256_set1_ps(1.0 / x));
        let near = dir.map(|x| x.is_sign_negative() as usize);
        let slack = _mm256_set1_ps(slack);
        let dirv = dir.map(|x| _mm256_set1_ps(x));
        let lanes = Lanes { org, dir: dirv, tmin };

        let mut stack = [MaybeUninit::<(u32, u32)>::uninit(); STACK];
        let mut sp = 0usize;
        let mut occluded = 0u32;
        let (mut node, mut mask) = (0u32, all);
        loop {
            let live = mask & !occluded;
            if live != 0 {
                let nd = &nodes[node as usize];
                let mut next: Option<(u32, u32)> = None;
                for slot in 0..W {
                    let mut tn = tmin;
                    let mut tf = tmax;
                    // z, then y, then x: the accumulator is the second operand, so a NaN lane
                    // of the first is dropped (the same order as `wide::scalar_test`).
                    for axis in [2, 1, 0] {
                        let b_near = _mm256_set1_ps(nd.bounds[axis][near[axis]][slot]);
                        let b_far = _mm256_set1_ps(nd.bounds[axis][1 - near[axis]][slot]);
                        tn = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(b_near, org[axis]), inv[axis]), tn);
                        tf = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(b_far, org[axis]), inv[axis]), tf);
                    }
                    let tf = _mm256_mul_ps(tf, slack);
                    let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf)) as u32 & live & !occluded;
                    if hit == 0 || nd.is_empty_slot(slot) {
                        continue;
                    }
                    let count = nd.count[slot];
                    if count > 0 {
                        let first = nd.child[slot];
                        let mut open = hit;
                        for k in first..first + count {
                            // SAFETY: AVX2 is enabled here as in `triangle`.
                            let (t, valid) = unsafe { triangle(&tris[k as usize], &lanes) };
                            let within = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_LE_OQ>(t, tmax));
                            let found = _mm256_movemask_ps(within) as u32 & open;
                            open &= !found;
                            occluded |= found;
                            if open == 0 {
                                break;
                            }
                        }
                        if occluded == all {
                            return occluded;
                        }
                    } else if let Some(e) = next.replace((nd.child[slot], hit)) {
                        stack[sp] = MaybeUninit::new(e);
                        sp += 1;
                    }
                }
                if let Some((c, m)) = next {
                    (node, mask) = (c, m);
                    continue;
                }
            }
            if sp == 0 {
                return occluded;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written (pushed children).
            (node, mask) = unsafe { stack[sp].assume_init() };
        }
    }
}
