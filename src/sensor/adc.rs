//! Analogue-to-digital conversion: electrons → digital numbers.

use super::config::AdcConfig;

/// A resolved ADC: `DN = clamp(round(offset + e / gain), 0, 2^bits − 1)`.
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
    /// nearest code, so an input of exactly k·gain reads k + offset.
    #[inline]
    pub fn convert(&self, electrons: f64) -> Conversion {
        let v = (self.offset_dn + electrons / self.gain_e_per_dn).round();
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
