//! Four lens inversions at once: the radial Newton of [`Distortion::undistort`] in the
//! four f64 lanes of an AVX register.
//!
//! The truth pass inverts the lens once per covered pixel centre, a dependent chain of a
//! square root and three or four divisions each; four lanes share those instructions. Each
//! lane runs the scalar path's operations in its order (no fused multiply-add, the same
//! constants), stops at the same test and keeps its value from then on, so every answer
//! is [`Distortion::undistort`]'s bit for bit. A lane the scalar radial path would leave
//! (the centre point, a failing slope, no convergence) is redone by the scalar code.

use super::{Distortion, MAX_ITER, TOL};
use glam::DVec2;

impl Distortion {
    /// [`Distortion::undistort`] of four points, each the same bits.
    pub fn undistort4(&self, p: [DVec2; 4]) -> [DVec2; 4] {
        #[cfg(target_arch = "x86_64")]
        if self.p1 == 0.0 && self.p2 == 0.0 && !self.is_identity() && avx() {
            // SAFETY: AVX was detected.
            let lanes = unsafe { avx::radial(self, p) };
            return std::array::from_fn(|i| lanes[i].unwrap_or_else(|| self.undistort(p[i])));
        }
        p.map(|q| self.undistort(q))
    }
}

/// Whether this CPU has AVX (checked once).
#[cfg(target_arch = "x86_64")]
fn avx() -> bool {
    static AVX: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX.get_or_init(|| std::arch::is_x86_feature_detected!("avx"))
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{Distortion, MAX_ITER, TOL};
    use glam::DVec2;
    use std::arch::x86_64::*;

    /// `undistort_radial` per lane; `None` in a lane the scalar code must decide.
    #[target_feature(enable = "avx")]
    pub(super) fn radial(d: &Distortion, p: [DVec2; 4]) -> [Option<DVec2>; 4] {
        let x = _mm256_setr_pd(p[0].x, p[1].x, p[2].x, p[3].x);
        let y = _mm256_setr_pd(p[0].y, p[1].y, p[2].y, p[3].y);
        let (mul, add, sub, div) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd, _mm256_div_pd);
        let s = _mm256_set1_pd;
        let (one, k1, k2, k3) = (s(1.0), s(d.k1), s(d.k2), s(d.k3));
        // `Distortion::radial`: 1 + r2 (k1 + r2 (k2 + r2 k3)).
        let radial = |r2| add(one, mul(r2, add(k1, mul(r2, add(k2, mul(r2, k3))))));
        let rd2 = add(mul(x, x), mul(y, y));
        let rd = _mm256_sqrt_pd(rd2);
        // `start_divisor`: the radial factor where it lies in 0.5..=2, else 1.
        let f = radial(rd2);
        let plausible = _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(f, s(0.5)), _mm256_cmp_pd::<_CMP_LE_OQ>(f, s(2.0)));
        let mut r = div(rd, _mm256_blendv_pd(one, f, plausible));
        let tol = mul(s(TOL), add(one, rd));
        let (c1, c2, c7) = (s(3.0 * d.k1), s(5.0 * d.k2), s(7.0));
        let sign = s(-0.0);
        // Lanes still iterating; the centre point (rd² = 0) is left to the scalar code.
        let mut active = _mm256_cmp_pd::<_CMP_NEQ_UQ>(rd2, _mm256_setzero_pd());
        let mut done = _mm256_setzero_pd();
        for _ in 0..MAX_ITER {
            if _mm256_movemask_pd(active) == 0 {
                break;
            }
            let r2 = mul(r, r);
            let e = sub(mul(r, radial(r2)), rd);
            let converged = _mm256_and_pd(active, _mm256_cmp_pd::<_CMP_LE_OQ>(_mm256_andnot_pd(sign, e), tol));
            done = _mm256_or_pd(done, converged);
            active = _mm256_andnot_pd(converged, active);
            // 1 + r2 (3 k1 + r2 (5 k2 + r2 · 7 · k3)); a lane whose slope is not finite
            // and positive stops (not done).
            let slope = add(one, mul(r2, add(c1, mul(r2, add(c2, mul(mul(r2, c7), k3))))));
            let usable = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(slope, _mm256_setzero_pd()),
                _mm256_cmp_pd::<_CMP_LT_OQ>(slope, s(f64::INFINITY)),
            );
            active = _mm256_and_pd(active, usable);
            r = _mm256_blendv_pd(r, sub(r, div(e, slope)), active);
        }
        let scale = div(r, rd);
        let (mut xs, mut ys, mut ok) = ([0.0; 4], [0.0; 4], [0.0; 4]);
        // SAFETY: each array holds four f64, what an unaligned 256-bit store writes.
        unsafe {
            _mm256_storeu_pd(xs.as_mut_ptr(), mul(x, scale));
            _mm256_storeu_pd(ys.as_mut_ptr(), mul(y, scale));
            _mm256_storeu_pd(ok.as_mut_ptr(), done);
        }
        std::array::from_fn(|i| (ok[i].to_bits() != 0).then(|| DVec2::new(xs[i], ys[i])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_lanes_give_the_scalar_inversion_bit_for_bit() {
        let models = [
            Distortion { k1: -0.08, k2: 0.01, ..Default::default() },
            Distortion { k1: 0.3, k2: -0.05, k3: 0.02, ..Default::default() },
            Distortion { k1: -0.25, ..Default::default() },
            Distortion { k1: -0.1, p1: 1e-3, ..Default::default() },
        ];
        for d in models {
            for i in -40..=40 {
                for j in -10..=10 {
                    // Four neighbours along a row, the centre point among them.
                    let p: [DVec2; 4] =
                        std::array::from_fn(|k| DVec2::new(f64::from(4 * i + k as i32) * 0.0031, f64::from(j) * 0.017));
                    let got = d.undistort4(p);
                    for k in 0..4 {
                        let want = d.undistort(p[k]);
                        assert_eq!(
                            got[k].to_array().map(f64::to_bits),
                            want.to_array().map(f64::to_bits),
                            "{d:?} {}",
                            p[k]
                        );
                    }
                }
            }
        }
    }
}
