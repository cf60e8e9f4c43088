//! obvhs's ray–triangle test for eight rays at once (AVX2 lanes), bit for bit: the packet
//! walks (`shadow_packet`, `closest_packet`) give each lane the single-ray walk's answer
//! only if every (ray, triangle) pair gets the same `t` and yes/no as
//! `RtTriangle::intersect` on that ray. So the operations are the scalar test's, in its
//! order, through glam's SSE `cross` and `dot3` (`dot3` is `(x·x' + y·y') + z·z'`), with
//! obvhs's sign-bit rule; products commute bit for bit, sums and differences are kept in
//! their order (`tests/render/shadow_packet.rs` and `tests/render/closest_packet.rs` check it, and fail
//! when `w = 1 − (u + v)` replaces `(1 − u) − v`).

#![cfg(target_arch = "x86_64")]

use obvhs::rt_triangle::RtTriangle;
use std::arch::x86_64::*;

/// Eight rays, one per lane.
pub(super) struct Lanes {
    pub org: [__m256; 3],
    pub dir: [__m256; 3],
    pub tmin: __m256,
}

/// obvhs's `RtTriangle::intersect` for eight rays: per lane `t` and all-ones where the
/// hit is valid and within `[tmin, ∞)` (the caller compares with each lane's current
/// `t`). Same operations in the same order as the scalar test through glam's SSE
/// `cross` and `dot3`: `dot3` is `(x·x' + y·y') + z·z'`.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn triangle(tri: &RtTriangle, l: &Lanes) -> (__m256, __m256) {
    let s = |x: f32| _mm256_set1_ps(x);
    let (v0, e1, e2, ng) = (tri.v0, tri.e1, tri.e2, tri.ng);
    let [dx, dy, dz] = l.dir;
    let [ox, oy, oz] = l.org;
    let dot = |ax: __m256, ay: __m256, az: __m256, b: glam::Vec3A| {
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ax, s(b.x)), _mm256_mul_ps(ay, s(b.y))), _mm256_mul_ps(az, s(b.z)))
    };
    // c = v0 − origin
    let (cx, cy, cz) = (_mm256_sub_ps(s(v0.x), ox), _mm256_sub_ps(s(v0.y), oy), _mm256_sub_ps(s(v0.z), oz));
    // r = d × c, as glam: x = d.y·c.z − c.y·d.z, y = d.z·c.x − c.z·d.x, z = d.x·c.y − c.x·d.y
    let rx = _mm256_sub_ps(_mm256_mul_ps(dy, cz), _mm256_mul_ps(cy, dz));
    let ry = _mm256_sub_ps(_mm256_mul_ps(dz, cx), _mm256_mul_ps(cz, dx));
    let rz = _mm256_sub_ps(_mm256_mul_ps(dx, cy), _mm256_mul_ps(cx, dy));
    // 1 / ng·d per lane (`ng.dot(d)`; the products commute bit for bit).
    let inv = _mm256_div_ps(s(1.0), dot(dx, dy, dz, ng));
    let u = _mm256_mul_ps(dot(rx, ry, rz, e2), inv);
    let v = _mm256_mul_ps(dot(rx, ry, rz, e1), inv);
    let w = _mm256_sub_ps(_mm256_sub_ps(s(1.0), u), v);
    // Valid when `inv_det != 0` (true for NaN, as in Rust) and no sign bit is set among
    // u, v, w (obvhs's rule, NaN included).
    let nonzero = _mm256_cmp_ps::<_CMP_NEQ_UQ>(inv, _mm256_setzero_ps());
    let signs = _mm256_castsi256_ps(_mm256_srai_epi32::<31>(_mm256_castps_si256(_mm256_or_ps(_mm256_or_ps(u, v), w))));
    // t = n·c / (n·d), `ng.dot(c)` with `ng` on the left as the scalar test.
    let t = _mm256_mul_ps(dot(cx, cy, cz, ng), inv);
    let valid = _mm256_andnot_ps(signs, _mm256_and_ps(nonzero, _mm256_cmp_ps::<_CMP_GE_OQ>(t, l.tmin)));
    (t, valid)
}
