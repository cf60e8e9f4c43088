//! Closest hits of up to eight rays through one walk of a wide BVH: the primary rays of
//! neighbouring pixels.
//!
//! Eight neighbouring camera rays start a few millimetres apart on the target's bounding
//! sphere and point almost the same way, so they enter nearly the same nodes. Walked
//! together, a node's boxes are tested against all eight rays at once (AVX2 lanes) and
//! the walk's branches, sorting and stack traffic — what a single-ray walk is bound by
//! (docs/performance.md) — are paid once per packet.
//!
//! Each lane's answer is the single-ray walk's closest hit: the box test is `bvh8`'s slab
//! test per lane (the near plane picked by the direction's sign bit, the same operations in
//! the same order, the same NaN rule and slack), so it culls no box holding a triangle the
//! triangle test accepts; the triangle test is obvhs's `RtTriangle::intersect` per lane in
//! glam's operation order (`lane_triangle`, shared with `shadow_packet`), and a lane's
//! hit is replaced only by a strictly smaller `t`, as obvhs's. So each lane's `t` is the
//! brute-force minimum bit for bit. Only which of several triangles tied at exactly the
//! same `t` is reported may differ from the single-ray walk (the visit order differs);
//! `tests/render/closest_packet.rs` counts such ties.

use super::shadow_packet::{PACKET, avx2};
use super::wide::Node;
use obvhs::{ray::Ray as ObRay, rt_triangle::RtTriangle};

/// No hit in a lane of [`closest`]'s answer.
pub const MISS: u32 = u32::MAX;

/// Closest hits of up to [`PACKET`] rays: per lane the primitive index ([`MISS`] for none)
/// and `t`; `None` when the AVX2 walk does not apply (no AVX2, or a stack of `stack_need`
/// entries would not fit) and the caller must trace the rays one by one.
pub(super) fn closest<const W: usize>(
    nodes: &[Node<W>],
    tris: &[RtTriangle],
    rays: &[ObRay],
    slack: f32,
    stack_need: usize,
) -> Option<([u32; PACKET], [f32; PACKET])> {
    if rays.is_empty() || nodes.is_empty() {
        return Some(([MISS; PACKET], [f32::INFINITY; PACKET]));
    }
    if rays.len() > PACKET || stack_need > avx::STACK || !avx2() {
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
    use super::{MISS, Node, PACKET};
    use obvhs::{ray::Ray as ObRay, rt_triangle::RtTriangle};
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    /// Stack entries kept on the machine stack.
    pub(super) const STACK: usize = 256;

    /// A child waiting to be visited: inner node (`count == 0`) or leaf range, the lanes
    /// that entered it, and the nearest of their entry distances.
    #[derive(Clone, Copy)]
    struct Entry {
        index: u32,
        count: u32,
        lanes: u32,
        t: f32,
    }

    /// The walk: children in order of their nearest lane's entry distance, leaves nearer than
    /// every inner child first (as `bvh8`'s single-ray walk), each lane's `t` shrinking as
    /// its hits are found.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn walk<const W: usize>(
        nodes: &[Node<W>],
        tris: &[RtTriangle],
        rays: &[ObRay],
        slack: f32,
    ) -> ([u32; PACKET], [f32; PACKET]) {
        let n = rays.len();
        let all = (1u32 << n) - 1;
        // Lanes beyond `n` repeat ray 0 and are masked out.
        let mut v = [[0.0f32; PACKET]; 11];
        for i in 0..PACKET {
            let r = &rays[if i < n { i } else { 0 }];
            let (o, d) = (r.origin, r.direction);
            // As `wide::Prep`: the exact reciprocal, ±inf for a zero component.
            let row = [o.x, o.y, o.z, d.x, d.y, d.z, 1.0 / d.x, 1.0 / d.y, 1.0 / d.z, r.tmin, r.tmax];
            for (k, x) in row.into_iter().enumerate() {
                v[k][i] = x;
            }
        }
        // SAFETY: AVX2 is enabled on this function; the loads read `[f32; 8]` arrays.
        let v = v.map(|a| unsafe { _mm256_loadu_ps(a.as_ptr()) });
        let lanes = Lanes { org: [v[0], v[1], v[2]], dir: [v[3], v[4], v[5]], tmin: v[9] };
        let inv = [v[6], v[7], v[8]];
        let mut tmax = v[10];
        let mut prim = _mm256_set1_epi32(MISS as i32);
        let slack = _mm256_set1_ps(slack);

        // Lanes of `bits` whose current `t` (times the slack) is not below `t`.
        let reach = |t: f32, bits: u32, tmax: __m256| {
            bits & _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_set1_ps(t), _mm256_mul_ps(tmax, slack))) as u32
        };
        // Tests a leaf's triangles for the lanes `bits`, shrinking their `t`.
        let leaf = |e: &Entry, tmax: &mut __m256, prim: &mut __m256i| {
            let bits = reach(e.t, e.lanes, *tmax);
            if bits == 0 {
                return;
            }
            let want = lane_mask(bits);
            for k in e.index..e.index + e.count {
                // SAFETY: AVX2 is enabled here as in `triangle`.
                let (t, valid) = unsafe { triangle(&tris[k as usize], &lanes) };
                // obvhs's rule: a hit replaces the current one only when strictly nearer.
                let take = _mm256_and_ps(_mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_LT_OQ>(t, *tmax)), want);
                *tmax = _mm256_blendv_ps(*tmax, t, take);
                *prim = _mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(*prim),
                    _mm256_castsi256_ps(_mm256_set1_epi32(k as i32)),
                    take,
                ));
            }
        };

        let mut stack = [MaybeUninit::<Entry>::uninit(); STACK];
        let mut sp = 0usize;
        let (mut node, mut mask) = (0u32, all);
        loop {
            let nd = &nodes[node as usize];
            // Hit children sorted far to near (`hit[k - 1]` the nearest).
            let mut hit = [MaybeUninit::<Entry>::uninit(); PACKET];
            let mut k = 0;
            for slot in 0..W {
                let mut tn = lanes.tmin;
                let mut tf = tmax;
                // z, then y, then x, accumulator second (a NaN lane of the first is dropped):
                // `bvh8`'s order. The near plane per lane by the direction's sign bit.
                for axis in [2, 1, 0] {
                    let lo = _mm256_set1_ps(nd.bounds[axis][0][slot]);
                    let hi = _mm256_set1_ps(nd.bounds[axis][1][slot]);
                    let t_lo = _mm256_mul_ps(_mm256_sub_ps(lo, lanes.org[axis]), inv[axis]);
                    let t_hi = _mm256_mul_ps(_mm256_sub_ps(hi, lanes.org[axis]), inv[axis]);
                    let d = lanes.dir[axis];
                    tn = _mm256_max_ps(_mm256_blendv_ps(t_lo, t_hi, d), tn);
                    tf = _mm256_min_ps(_mm256_blendv_ps(t_hi, t_lo, d), tf);
                }
                let tf = _mm256_mul_ps(tf, slack);
                let bits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf)) as u32 & mask;
                if bits == 0 || nd.is_empty_slot(slot) {
                    continue;
                }
                let c = Entry { index: nd.child[slot], count: nd.count[slot], lanes: bits, t: nearest(tn, bits) };
                let mut j = k;
                // SAFETY: `j - 1 < k`: written.
                while j > 0 && unsafe { hit[j - 1].assume_init() }.t < c.t {
                    hit[j] = hit[j - 1];
                    j -= 1;
                }
                hit[j] = MaybeUninit::new(c);
                k += 1;
            }
            // SAFETY: `i < k`: written.
            let hit_at = |i: usize| unsafe { hit[i].assume_init() };
            let mut rest = k;
            while rest > 0 && hit_at(rest - 1).count > 0 {
                leaf(&hit_at(rest - 1), &mut tmax, &mut prim);
                rest -= 1;
            }
            // The nearest inner child next, the rest pushed far to near. In bounds: at tree
            // level L at most (W − 1)(L − 1) entries are held (the caller's `stack_need`).
            let mut next = None;
            if rest > 0 {
                stack[sp..sp + rest - 1].copy_from_slice(&hit[..rest - 1]);
                sp += rest - 1;
                next = Some(hit_at(rest - 1));
            }
            let mut next = next.and_then(|c| {
                let lanes = reach(c.t, c.lanes, tmax);
                (lanes != 0).then_some(Entry { lanes, ..c })
            });
            while next.is_none() {
                if sp == 0 {
                    let mut p = [0u32; PACKET];
                    let mut t = [0.0f32; PACKET];
                    // SAFETY: both arrays hold eight 32-bit lanes (unaligned stores).
                    unsafe {
                        _mm256_storeu_si256(p.as_mut_ptr().cast(), prim);
                        _mm256_storeu_ps(t.as_mut_ptr(), tmax);
                    }
                    for i in n..PACKET {
                        (p[i], t[i]) = (MISS, f32::INFINITY);
                    }
                    for i in 0..n {
                        if p[i] == MISS {
                            t[i] = f32::INFINITY;
                        }
                    }
                    return (p, t);
                }
                sp -= 1;
                // SAFETY: `stack[..sp]` has been written (pushed children).
                let e = unsafe { stack[sp].assume_init() };
                if e.count > 0 {
                    leaf(&e, &mut tmax, &mut prim);
                } else {
                    let lanes = reach(e.t, e.lanes, tmax);
                    next = (lanes != 0).then_some(Entry { lanes, ..e });
                }
            }
            let e = next.unwrap_or(Entry { index: 0, count: 0, lanes: 0, t: 0.0 });
            (node, mask) = (e.index, e.lanes);
        }
    }

    /// All-ones in the lanes whose bit is set in `bits`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn lane_mask(bits: u32) -> __m256 {
        let sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let on = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits as i32), sel), sel);
        _mm256_castsi256_ps(on)
    }

    /// The smallest of `tn` over the lanes `bits` (never NaN: `tn` starts at `tmin` and the
    /// max drops NaN operands).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn nearest(tn: __m256, bits: u32) -> f32 {
        let x = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), tn, lane_mask(bits));
        let a = _mm256_min_ps(x, _mm256_permute2f128_ps::<1>(x, x));
        let b = _mm256_min_ps(a, _mm256_shuffle_ps::<0b01_00_11_10>(a, a));
        let c = _mm256_min_ps(b, _mm256_shuffle_ps::<0b10_11_00_01>(b, b));
        _mm256_cvtss_f32(c)
    }
}
