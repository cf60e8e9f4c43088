//! Analogue-to-digital conversion: electrons → digital numbers.

use super::config::AdcConfig;

/// A resolved ADC: `DN = clamp(⌊offset + e / gain + ½⌋, 0, 2^bits − 1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adc {
    pub bits: u8,
    pub gain_e_per_dn: f64,
    pub offset_dn: f64,
    /// 2^bits − 1.
    pub max_dn: u32,
    /// `1 / gain`, for the fast path of [`Adc::convert`].
    inv_gain: f64,
}

/// One converted value and whether it clipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Conversion {
    InRange(u32),
    /// Below 0 (possible with read noise on a zero offset): reported as 0.
    ClippedLow,
    /// At or above the ADC maximum: reported as `max_dn`.
    ClippedHigh(u32),
}

impl Conversion {
    #[inline]
    pub fn dn(self) -> u32 {
        match self {
            Conversion::InRange(v) | Conversion::ClippedHigh(v) => v,
            Conversion::ClippedLow => 0,
        }
    }
}

/// `x.floor()` without the libm call that baseline x86-64 (no SSE4.1 `roundsd`) makes,
/// and without the range checks of a saturating integer cast: `|x| + 2⁵²` rounds `|x|`
/// to an integer (the spacing of doubles there is 1), `− 2⁵²` gives it back exactly, and
/// a nearest integer above `x` steps down by one. Exact for every finite `x` (from 2⁵²
/// on, `x` is an integer and is returned); branch-free.
#[inline(always)]
pub fn floor(x: f64) -> f64 {
    const TWO52: f64 = 4_503_599_627_370_496.0;
    let a = x.abs();
    let r = if a < TWO52 { ((a + TWO52) - TWO52).copysign(x) } else { x };
    if r > x { r - 1.0 } else { r }
}

impl Adc {
    pub fn new(cfg: &AdcConfig) -> Self {
        Adc {
            bits: cfg.bits,
            gain_e_per_dn: cfg.gain_e_per_dn,
            offset_dn: cfg.offset_dn,
            max_dn: (1u32 << cfg.bits) - 1,
            inv_gain: 1.0 / cfg.gain_e_per_dn,
        }
    }

    /// Convert a charge (in electrons; may be negative after read noise). Rounds to the
    /// nearest code (halves up), so an input of exactly k·gain reads k + offset.
    #[inline]
    pub fn convert(&self, electrons: f64) -> Conversion {
        let (v, sure) = self.round_fast(electrons);
        let v = if sure { v } else { floor(self.offset_dn + electrons / self.gain_e_per_dn + 0.5) };
        self.clip(v)
    }

    /// `⌊offset + e·(1/gain) + ½⌋`, and whether it is surely the quotient's code.
    /// `electrons · (1/gain)` differs from the quotient by a few ulp, and the sum by at
    /// most 8·2⁻⁵³·(|q| + offset + 1); only when it lies that close to an integer can
    /// the floors differ, and then the quotient decides (tolerance 2⁻⁴⁰·(…)). The same
    /// code as the division, bit for bit, without its latency on nearly every call.
    #[inline(always)]
    pub fn round_fast(&self, electrons: f64) -> (f64, bool) {
        let q = electrons * self.inv_gain;
        let x = self.offset_dn + q + 0.5;
        let v = floor(x);
        let tol = (q.abs() + self.offset_dn.abs() + 1.0) * (1.0 / 1_099_511_627_776.0);
        (v, !(x - v < tol || v + 1.0 - x < tol))
    }

    /// The code of an integer `v` (before clipping).
    #[inline(always)]
    pub fn clip(&self, v: f64) -> Conversion {
        if v < 0.0 {
            Conversion::ClippedLow
        } else if v >= self.max_dn as f64 {
            Conversion::ClippedHigh(self.max_dn)
        } else {
            Conversion::InRange(v as u32)
        }
    }

    /// The largest DN above the offset: the usable range auto-exposure aims into.
    pub fn usable_range_dn(&self) -> f64 {
        self.max_dn as f64 - self.offset_dn
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_floor_matches_floor() {
        for x in [
            -2.5,
            -1.0,
            -0.5,
            -1e-300,
            0.0,
            0.3,
            0.5,
            1.0,
            2.999,
            4095.5,
            1e15 + 0.5,
            -7.25,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            9.1e15,
            -9.1e15,
            1e300,
            -1e300,
        ] {
            assert_eq!(floor(x), x.floor(), "{x}");
        }
        // Every half-integer and its neighbours across a wide range.
        let mut r = crate::render::sampling::Rng::from_state(3);
        for _ in 0..100_000 {
            let k = (r.next_u32() as i64 - (1 << 31)) as f64 * f64::from(1 + r.next_u32() % 1000);
            for x in
                [k + 0.5, k - 0.5, k, f64::from_bits((k + 0.5).to_bits() + 1), f64::from_bits((k + 0.5).to_bits() - 1)]
            {
                assert_eq!(floor(x), x.floor(), "{x}");
            }
        }
    }

    #[test]
    fn the_fast_path_is_the_division_bit_for_bit() {
        // Gains without an exact reciprocal, inputs on and near every rounding boundary.
        for (gain, offset) in [(6.0, 0.0), (11.5, 32.0), (3.3, 64.0), (0.7, 10.0), (2.0, 0.0)] {
            let a = Adc::new(&AdcConfig { bits: 16, gain_e_per_dn: gain, offset_dn: offset });
            let slow = |e: f64| floor(offset + e / gain + 0.5);
            for k in -200..2000 {
                let half = (k as f64 - offset - 0.5) * gain;
                for e in [
                    half,
                    f64::from_bits(half.to_bits() + 1),
                    f64::from_bits(half.to_bits().wrapping_sub(1)),
                    k as f64,
                    k as f64 * 0.37,
                ] {
                    let want = slow(e);
                    let want = if want < 0.0 { 0 } else { (want as u32).min(a.max_dn) };
                    assert_eq!(a.convert(e).dn(), want, "gain {gain} offset {offset} e {e}");
                }
            }
        }
    }

    #[test]
    fn conversion_rounds_half_up_and_clips() {
        let a = Adc::new(&AdcConfig { bits: 8, gain_e_per_dn: 2.0, offset_dn: 10.0 });
        assert_eq!(a.convert(4.0), Conversion::InRange(12));
        assert_eq!(a.convert(5.0), Conversion::InRange(13)); // 12.5 → 13
        assert_eq!(a.convert(-21.0), Conversion::InRange(0)); // −0.5 rounds up to 0
        assert_eq!(a.convert(-22.0), Conversion::ClippedLow); // −1
        assert_eq!(a.convert(1e9), Conversion::ClippedHigh(255));
    }
}
