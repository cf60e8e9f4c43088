//! The per-sample loops of rasterisation — each of a pixel's 64 coverage samples against
//! one triangle's three edge functions and depth plane — in a portable form and in AVX2,
//! eight samples per instruction.
//!
//! The two give the same bits: the same IEEE operations in the same order (each plane
//! `e₀ + e₁·x + e₂·y` as `(e₀ + e₁x) + e₂y`, no fused multiply-add), ordered comparisons
//! (a NaN is outside and never nearer), and the same tie rule. The compiler leaves the
//! portable loop scalar (its boolean edge test defeats the vectoriser): the AVX2 form is
//! where a hybrid frame spent most of its rasterisation time.

use super::pattern::SAMPLES;

/// A pixel's samples against one triangle: edges `e[k]` = (value at the pixel's corner,
/// step per unit x, per unit y), inside on the side `pos[k]` names (`v ≥ 0` when true,
/// `v < 0` when false); depth plane `wd` likewise (larger is nearer). Each sample inside
/// and nearer than `depth` takes `wd`'s value and `id`. Returns how many are inside.
pub struct Triangle {
    pub e: [[f32; 3]; 3],
    pub pos: [bool; 3],
    pub wd: [f32; 3],
    pub id: u32,
}

/// The samples of one pixel: positions and the nearest depth and triangle so far.
pub struct PixelSamples<'a> {
    pub sx: &'a [f32; SAMPLES],
    pub sy: &'a [f32; SAMPLES],
    pub depth: &'a mut [f32; SAMPLES],
    pub ids: &'a mut [u32; SAMPLES],
}

/// Keep `w` and `id` where `hit`, branch-free.
#[inline(always)]
fn keep(hit: bool, w: f32, id: u32, depth: &mut f32, ids: &mut u32) {
    let m = 0u32.wrapping_sub(u32::from(hit));
    *depth = f32::from_bits((w.to_bits() & m) | (depth.to_bits() & !m));
    *ids = (id & m) | (*ids & !m);
}

/// Edge tests and depth test, portable.
#[inline(always)]
pub fn edges_portable(t: &Triangle, px: PixelSamples) -> u32 {
    let e = &t.e;
    let inside = |k: usize, x: f32, y: f32| {
        let v = e[k][0] + e[k][1] * x + e[k][2] * y;
        (v >= 0.0) == t.pos[k]
    };
    let mut n = 0;
    for j in 0..SAMPLES {
        let (x, y) = (px.sx[j], px.sy[j]);
        let w = t.wd[0] + t.wd[1] * x + t.wd[2] * y;
        let ins = inside(0, x, y) & inside(1, x, y) & inside(2, x, y);
        n += u32::from(ins);
        keep(ins & (w > px.depth[j]), w, t.id, &mut px.depth[j], &mut px.ids[j]);
    }
    n
}

/// The depth test alone (a pixel wholly inside the triangle), portable.
#[inline(always)]
pub fn depth_portable(t: &Triangle, px: PixelSamples) {
    for j in 0..SAMPLES {
        let w = t.wd[0] + t.wd[1] * px.sx[j] + t.wd[2] * px.sy[j];
        keep(w > px.depth[j], w, t.id, &mut px.depth[j], &mut px.ids[j]);
    }
}

#[cfg(target_arch = "x86_64")]
pub use avx::{depth_avx2, edges_avx2};

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{PixelSamples, SAMPLES, Triangle};
    use std::arch::x86_64::*;

    /// `a + b·x + c·y` on eight lanes, in the portable loop's order.
    #[inline(always)]
    unsafe fn plane(p: [f32; 3], x: __m256, y: __m256) -> __m256 {
        // SAFETY: the caller runs with AVX2 (this is only inlined into AVX2 functions).
        unsafe {
            _mm256_add_ps(
                _mm256_add_ps(_mm256_set1_ps(p[0]), _mm256_mul_ps(_mm256_set1_ps(p[1]), x)),
                _mm256_mul_ps(_mm256_set1_ps(p[2]), y),
            )
        }
    }

    /// [`super::edges_portable`] in AVX2: the same bits.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub unsafe fn edges_avx2(t: &Triangle, px: PixelSamples) -> u32 {
        let zero = _mm256_setzero_ps();
        // `v ≥ 0` (ordered: NaN false), flipped for an edge whose inside is `v < 0`.
        let flip = t.pos.map(|p| _mm256_castsi256_ps(_mm256_set1_epi32(if p { 0 } else { -1 })));
        let id = _mm256_castsi256_ps(_mm256_set1_epi32(t.id as i32));
        let mut n = 0;
        for j in (0..SAMPLES).step_by(8) {
            // SAFETY: j + 8 ≤ SAMPLES, so every 8-lane load and store is in bounds.
            unsafe {
                let x = _mm256_loadu_ps(px.sx.as_ptr().add(j));
                let y = _mm256_loadu_ps(px.sy.as_ptr().add(j));
                let mut ins = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
                for (e, flip) in t.e.iter().zip(flip) {
                    let ge = _mm256_cmp_ps::<_CMP_GE_OQ>(plane(*e, x, y), zero);
                    ins = _mm256_and_ps(ins, _mm256_xor_ps(ge, flip));
                }
                n += (_mm256_movemask_ps(ins) as u32).count_ones();
                let w = plane(t.wd, x, y);
                let d = _mm256_loadu_ps(px.depth.as_ptr().add(j));
                let hit = _mm256_and_ps(ins, _mm256_cmp_ps::<_CMP_GT_OQ>(w, d));
                _mm256_storeu_ps(px.depth.as_mut_ptr().add(j), _mm256_blendv_ps(d, w, hit));
                let ids = px.ids.as_mut_ptr().add(j) as *mut __m256;
                _mm256_storeu_ps(ids as *mut f32, _mm256_blendv_ps(_mm256_loadu_ps(ids as *const f32), id, hit));
            }
        }
        n
    }

    /// [`super::depth_portable`] in AVX2: the same bits.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub unsafe fn depth_avx2(t: &Triangle, px: PixelSamples) {
        let id = _mm256_castsi256_ps(_mm256_set1_epi32(t.id as i32));
        for j in (0..SAMPLES).step_by(8) {
            // SAFETY: j + 8 ≤ SAMPLES, so every 8-lane load and store is in bounds.
            unsafe {
                let x = _mm256_loadu_ps(px.sx.as_ptr().add(j));
                let y = _mm256_loadu_ps(px.sy.as_ptr().add(j));
                let w = plane(t.wd, x, y);
                let d = _mm256_loadu_ps(px.depth.as_ptr().add(j));
                let hit = _mm256_cmp_ps::<_CMP_GT_OQ>(w, d);
                _mm256_storeu_ps(px.depth.as_mut_ptr().add(j), _mm256_blendv_ps(d, w, hit));
                let ids = px.ids.as_mut_ptr().add(j) as *mut f32;
                _mm256_storeu_ps(ids, _mm256_blendv_ps(_mm256_loadu_ps(ids), id, hit));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::Rng;

    /// Random triangles (edges through the pixel, both windings, some exactly through
    /// samples, a NaN plane) against random samples: the AVX2 loops give the portable
    /// loops' bits.
    #[test]
    fn avx2_loops_give_the_portable_bits() {
        #[cfg(target_arch = "x86_64")]
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::from_state(7);
        let mut f = |s: f32| (rng.next_f32() - 0.5) * s;
        let mut checked = 0;
        for case in 0..4000 {
            let sx: [f32; SAMPLES] = std::array::from_fn(|_| f(2.0) + 0.5);
            let sy: [f32; SAMPLES] = std::array::from_fn(|_| f(2.0) + 0.5);
            let mut e = [[f(2.0), f(4.0), f(4.0)], [f(2.0), f(4.0), f(4.0)], [f(2.0), f(4.0), f(4.0)]];
            if case % 7 == 0 {
                // An edge through sample 3 exactly (v = 0 there in some rounding).
                e[1] = [-(sx[3] + sy[3]), 1.0, 1.0];
            }
            if case % 97 == 0 {
                e[2][0] = f32::NAN;
            }
            let t = Triangle {
                e,
                pos: [case % 2 == 0, case % 3 == 0, case % 5 != 0],
                wd: [f(1.0), f(1.0), f(1.0)],
                id: case,
            };
            let depth0: [f32; SAMPLES] = std::array::from_fn(|j| if j % 5 == 0 { f32::NEG_INFINITY } else { f(1.0) });
            let ids0: [u32; SAMPLES] = std::array::from_fn(|j| 1_000_000 + j as u32);
            let run = |avx: bool, edges: bool| {
                let (mut d, mut i) = (depth0, ids0);
                let px = PixelSamples { sx: &sx, sy: &sy, depth: &mut d, ids: &mut i };
                let n = match (avx, edges) {
                    (false, true) => edges_portable(&t, px),
                    (false, false) => {
                        depth_portable(&t, px);
                        0
                    }
                    // SAFETY: AVX2 was detected above.
                    #[cfg(target_arch = "x86_64")]
                    (true, true) => unsafe { edges_avx2(&t, px) },
                    #[cfg(target_arch = "x86_64")]
                    (true, false) => {
                        unsafe { depth_avx2(&t, px) };
                        0
                    }
                    #[cfg(not(target_arch = "x86_64"))]
                    _ => unreachable!(),
                };
                (n, d.map(f32::to_bits), i)
            };
            for edges in [true, false] {
                let p = run(false, edges);
                if cfg!(target_arch = "x86_64") {
                    assert_eq!(run(true, edges), p, "case {case}, edges {edges}");
                    checked += 1;
                }
            }
        }
        assert!(checked == 8000 || !cfg!(target_arch = "x86_64"));
    }
}
