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

/// `x.floor()` without the libm call that baseline x86-64 (no SSE4.1 `roundsd`) makes;
/// it was a tenth of the frame time. Exact for |x| < 2^52; beyond, returns `x` clamped
/// to the i64 range, which every caller clips anyway.
#[inline]
pub fn floor(x: f64) -> f64 {
    let i = x as i64 as f64; // truncates toward zero (saturating)
    if i > x { i - 1.0 } else { i }
}

impl Adc {
    pub fn new(cfg: &AdcConfig) -> Self {
        Adc {
            bits: cfg.bits,
            gain_e_per_dn: cfg.gain_e_per_dn,
            offset_dn: cfg.offset_dn,
            max_dn: (1u32 << cfg.bits) - 1,
        }
    }

    /// Convert a charge (in electrons; may be negative after read noise). Rounds to the
    /// nearest code (halves up), so an input of exactly k·gain reads k + offset.
    #[inline]
    pub fn convert(&self, electrons: f64) -> Conversion {
        let v = floor(self.offset_dn + electrons / self.gain_e_per_dn + 0.5);
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
        for x in [-2.5, -1.0, -0.5, -1e-300, 0.0, 0.3, 0.5, 1.0, 2.999, 4095.5, 1e15 + 0.5, -7.25] {
            assert_eq!(floor(x), x.floor(), "{x}");
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
