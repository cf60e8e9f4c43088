//! Random variates for the sensor noise: Poisson shot noise, and the fixed pattern's
//! normal pairs.
//!
//! A frame's noise comes from each pixel's [`PixelStream`] (counter-based, keyed by frame
//! seed and pixel), normals from the [`ziggurat`](super::ziggurat): a frame's noise is a
//! pure function of its seed whatever the thread count. The fixed pattern, drawn once per
//! sensor, keeps its own PCG streams and polar-method normals.

use super::stream::PixelStream;
use super::ziggurat::{self, Ziggurat};
use crate::render::sampling::{Rng, mix64};

/// Domain separator of the fixed pattern's streams (see [`super::stream`] for the frame's).
const FIXED_PATTERN_DOMAIN: u64 = 0x46_5058_4d41_5031; // "FPXMAP1"

/// The fixed-pattern stream of one pixel: the same in every frame for one `fpn_seed`.
#[inline]
pub fn fixed_pattern_rng(fpn_seed: u64, pixel: u64) -> Rng {
    Rng::for_sample(mix64(fpn_seed ^ FIXED_PATTERN_DOMAIN), 1, pixel, 0)
}

/// Uniform in the open interval (0, 1) with 32 random bits: never 0, so `ln` is finite.
#[inline]
pub fn uniform_open(rng: &mut Rng) -> f64 {
    (rng.next_u32() as f64 + 0.5) * (1.0 / 4_294_967_296.0)
}

/// Two independent standard normal variates (Marsaglia's polar method: Box–Muller
/// without the sine and cosine; 1.27 uniform pairs per call on average). Exact normal;
/// the rejection loop draws from the pixel's own stream, so it stays deterministic.
/// Used for the fixed pattern, drawn once per sensor.
#[inline]
pub fn normal_pair(rng: &mut Rng) -> (f64, f64) {
    loop {
        let u = 2.0 * uniform_open(rng) - 1.0;
        let v = 2.0 * uniform_open(rng) - 1.0;
        let s = u * u + v * v;
        if s < 1.0 && s > 0.0 {
            let m = (-2.0 * s.ln() / s).sqrt();
            return (u * m, v * m);
        }
    }
}

/// Below this mean, Poisson variates are drawn exactly (by inversion of the CDF);
/// at and above it, by a normal approximation with a skewness correction.
///
/// At the threshold the approximation's CDF differs from the exact Poisson CDF by less
/// than 0.005 (tested in `tests/render/sensor.rs`), and the error shrinks as 1/λ above it.
/// Its mean is exact; rounding adds 1/12 and the skew term 1/18 to the variance, so the
/// normal's variance is reduced by 5/36 to keep the sampled variance at λ.
pub const POISSON_EXACT_BELOW: f64 = 30.0;

/// A Poisson variate of mean `lambda` (≥ 0) from `s`: one uniform below
/// [`POISSON_EXACT_BELOW`], one normal at and above it; nothing for λ = 0.
pub fn poisson(lambda: f64, s: &mut PixelStream) -> f64 {
    poisson_with(ziggurat::tables(), lambda, s)
}

/// [`poisson`] with the normal's tables at hand.
#[inline(always)]
pub fn poisson_with(zig: &Ziggurat, lambda: f64, s: &mut PixelStream) -> f64 {
    if lambda <= 0.0 {
        return 0.0;
    }
    if lambda < POISSON_EXACT_BELOW {
        poisson_inversion(lambda, s.uniform_open())
    } else {
        poisson_normal(lambda, zig.normal(s))
    }
}

/// Exact Poisson by sequential search of the CDF: smallest k with F(k) ≥ u.
#[inline(always)]
pub fn poisson_inversion(lambda: f64, u: f64) -> f64 {
    // F(0) = e^−λ ≥ 1 − λ: most draws of a dark pixel's small mean end here, without
    // the exponential.
    if u <= 1.0 - lambda { 0.0 } else { poisson_search(lambda, u) }
}

#[inline(never)]
fn poisson_search(lambda: f64, u: f64) -> f64 {
    let mut p = (-lambda).exp();
    let mut f = p;
    let mut k = 0u32;
    // The CDF reaches 1 − 1e-16 well before k = λ + 40 for λ < 30; the bound only stops
    // an infinite loop if rounding keeps F below u.
    let limit = (lambda as u32) * 4 + 64;
    while f < u && k < limit {
        k += 1;
        p *= lambda / k as f64;
        f += p;
    }
    k as f64
}

/// Normal approximation with the first Cornish–Fisher (skewness) term and continuity
/// correction: `k = ⌊λ + √(λ − 5/36) z + (z² − 1)/6 + ½⌋`, at least 0.
#[inline]
pub fn poisson_normal(lambda: f64, z: f64) -> f64 {
    let sd = (lambda - 5.0 / 36.0).max(0.0).sqrt();
    super::adc::floor(lambda + sd * z + (z * z - 1.0) / 6.0 + 0.5).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inversion_matches_cdf_boundaries() {
        // u just below F(0) gives 0; just above gives 1.
        let l: f64 = 2.0;
        let f0 = (-l).exp();
        assert_eq!(poisson_inversion(l, f0 * 0.999), 0.0);
        assert_eq!(poisson_inversion(l, f0 * 1.001), 1.0);
        let f1 = f0 * (1.0 + l);
        assert_eq!(poisson_inversion(l, f1 * 1.0001), 2.0);
    }

    #[test]
    fn the_shortcut_agrees_with_the_search() {
        // u ≤ 1 − λ returns 0 without the exponential; the search gives 0 there too.
        for l in [1e-6, 1e-3, 0.1, 0.5] {
            for k in 1..1000 {
                let u = k as f64 / 1000.0 * (1.0 - l);
                let mut f = (-l).exp();
                let mut n = 0;
                let mut p = f;
                while f < u {
                    n += 1;
                    p *= l / n as f64;
                    f += p;
                }
                assert_eq!(poisson_inversion(l, u), n as f64, "λ {l} u {u}");
            }
        }
    }

    #[test]
    fn normal_pair_moments() {
        let mut r = fixed_pattern_rng(9, 0);
        let n = 200_000;
        let (mut s, mut s2, mut c) = (0.0, 0.0, 0.0);
        for _ in 0..n / 2 {
            let (a, b) = normal_pair(&mut r);
            s += a + b;
            s2 += a * a + b * b;
            c += a * b;
        }
        let n = n as f64;
        assert!((s / n).abs() < 0.01);
        // Shape: P(|z| > 1) = 0.3173, P(|z| > 2) = 0.0455, P(|z| > 3) = 0.0027.
        let mut r = fixed_pattern_rng(10, 0);
        let mut tails = [0.0; 3];
        for _ in 0..n as usize / 2 {
            let (a, b) = normal_pair(&mut r);
            for z in [a, b] {
                for (k, t) in tails.iter_mut().enumerate() {
                    *t += (z.abs() > (k + 1) as f64) as u32 as f64 / n;
                }
            }
        }
        assert!((tails[0] - 0.3173).abs() < 0.004, "{tails:?}");
        assert!((tails[1] - 0.0455).abs() < 0.0015, "{tails:?}");
        assert!((tails[2] - 0.0027).abs() < 0.0004, "{tails:?}");
        assert!((s2 / n - 1.0).abs() < 0.015);
        assert!((c / (n / 2.0)).abs() < 0.015);
    }
}
