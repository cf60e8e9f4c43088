//! The DN of an empty well: read noise through the ADC, drawn from its exact discrete
//! distribution in one table look-up.
//!
//! Most pixels of a navigation frame see black sky: their charge is a Poisson count of
//! a dark current of a few 1e-3 e⁻, nearly always 0, and their DN is then
//! `⌊offset + σ_r z / g + ½⌋` clipped to the ADC's range, z standard normal — a
//! distribution over a few codes that depends on the camera alone. Its probabilities
//! (Gaussian integrals over each code's interval of z, by Gauss–Legendre quadrature to
//! ~1e-16) are tabulated once; a frame draws a pixel's code by inverting the table's
//! cumulative sums with 32 random bits (each code's probability within 2⁻³² of the exact
//! one, the resolution of a 32-bit uniform): the top 12 bits index a table that holds
//! the code outright for all but the few ranges a code boundary cuts, which a guide table
//! and the sums settle. That replaces a normal variate, a division and a rounding per
//! dark pixel.

use super::adc::{Adc, Conversion};

/// Codes with less probability than this (2⁻³³) are left out: a 32-bit draw would
/// rarely reach them at all.
const NEGLIGIBLE: f64 = 1.0 / 8_589_934_592.0;

/// More codes than this (read noise of hundreds of DN): the normal variate is cheaper.
const MAX_CODES: usize = 4096;

/// The empty well's codes and their cumulative probabilities.
#[derive(Clone, Debug, PartialEq)]
pub struct EmptyWell {
    /// The ADC's answers, in increasing order of the noise.
    codes: Vec<Conversion>,
    /// `cum[j]`: 2³² × P(code ≤ j), rounded; the last is 2³².
    cum: Vec<u64>,
    /// `guide[k]`: the first code whose `cum` exceeds `k · 2²⁴`.
    guide: [u32; 256],
    /// `fine[k]`: the code of every draw in `[k · 2²⁰, (k + 1) · 2²⁰)`, or [`STRADDLES`]
    /// when a code boundary cuts that range (a few of the 4096) or there are 255 codes
    /// or more.
    fine: Vec<u8>,
    /// Per code, what a run of draws sums ([`EmptyWell::tally`]).
    tally: Vec<u64>,
}

/// A [`EmptyWell::fine`] entry that does not decide the code.
const STRADDLES: u8 = u8::MAX;

/// Draws summed into one `u64` by [`EmptyWell::tally`] before [`Tally::add`] takes them
/// apart: the DN sum stays below 2³² (2¹⁶ × 2¹⁶) and each count below 2¹⁶.
pub const TALLY_RUN: usize = 1 << 15;

/// The counts a run of empty-well draws adds to a row's sums.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tally {
    /// Sum of the codes.
    pub dn: u64,
    /// Draws clipped at 0 and at the ADC maximum.
    pub low: u64,
    pub high: u64,
}

impl Tally {
    /// Add a sum of at most [`TALLY_RUN`] [`EmptyWell::tally`] values.
    #[inline(always)]
    pub fn add(&mut self, packed: u64) {
        self.dn += packed & 0xffff_ffff;
        self.low += (packed >> 32) & 0xffff;
        self.high += packed >> 48;
    }
}

impl EmptyWell {
    /// The table for read noise `read_noise_e` (e⁻ rms) through `adc`; None when it would
    /// have more than [`MAX_CODES`] codes.
    pub fn new(read_noise_e: f64, adc: &Adc) -> Option<EmptyWell> {
        let (g, off, max) = (adc.gain_e_per_dn, adc.offset_dn, adc.max_dn);
        let probs: Vec<(Conversion, f64)> = if read_noise_e <= 0.0 {
            vec![(adc.convert(0.0), 1.0)]
        } else {
            // Code v (before clipping) for z in [(v − ½ − offset)·g/σ, (v + ½ − offset)·g/σ).
            let s = g / read_noise_e;
            let z = |v: f64| (v - 0.5 - off) * s;
            let (z_lo, z_hi) = (-40.0, 40.0);
            let v_lo = (z_lo / s + off + 0.5).floor().max(-1.0);
            let v_hi = (z_hi / s + off + 0.5).floor().min(max as f64);
            if v_hi - v_lo > MAX_CODES as f64 {
                return None;
            }
            let mut p = Vec::new();
            let mut v = v_lo;
            while v <= v_hi {
                let (a, b) = (if v <= -1.0 { z_lo } else { z(v) }, if v >= max as f64 { z_hi } else { z(v + 1.0) });
                let code = if v < 0.0 {
                    Conversion::ClippedLow
                } else if v >= max as f64 {
                    Conversion::ClippedHigh(max)
                } else {
                    Conversion::InRange(v as u32)
                };
                p.push((code, gaussian_mass(a.max(z_lo), b.min(z_hi))));
                v += 1.0;
            }
            p.retain(|(_, m)| *m > NEGLIGIBLE);
            p
        };
        let total: f64 = probs.iter().map(|(_, m)| m).sum();
        let mut acc = 0.0;
        let mut cum: Vec<u64> = probs
            .iter()
            .map(|(_, m)| {
                acc += m / total;
                (acc * 4_294_967_296.0).round() as u64
            })
            .collect();
        *cum.last_mut().expect("one code at least") = 1 << 32;
        let mut guide = [0u32; 256];
        for (k, g) in guide.iter_mut().enumerate() {
            *g = cum.partition_point(|&c| c <= (k as u64) << 24) as u32;
        }
        let fine = (0..4096u64)
            .map(|k| {
                let at = |u: u64| cum.partition_point(|&c| c <= u);
                let (a, b) = (at(k << 20), at(((k + 1) << 20) - 1));
                if a == b && a < STRADDLES as usize { a as u8 } else { STRADDLES }
            })
            .collect();
        let tally = probs
            .iter()
            .map(|(c, _)| {
                let (low, high) = match c {
                    Conversion::InRange(_) => (0, 0),
                    Conversion::ClippedLow => (1, 0),
                    Conversion::ClippedHigh(_) => (0, 1),
                };
                u64::from(c.dn()) | low << 32 | high << 48
            })
            .collect();
        Some(EmptyWell { codes: probs.into_iter().map(|(c, _)| c).collect(), cum, guide, fine, tally })
    }

    /// The index of the code of 32 uniform random bits `u`.
    #[inline(always)]
    fn index(&self, u: u32) -> usize {
        match self.fine[(u >> 20) as usize] {
            STRADDLES => self.search(u),
            j => j as usize,
        }
    }

    /// [`EmptyWell::index`] through the guide table and the cumulative sums.
    #[inline(never)]
    fn search(&self, u: u32) -> usize {
        let mut j = self.guide[(u >> 24) as usize] as usize;
        while u as u64 >= self.cum[j] {
            j += 1;
        }
        j
    }

    /// The code of 32 uniform random bits `u`.
    #[inline(always)]
    pub fn draw(&self, u: u32) -> Conversion {
        self.codes[self.index(u)]
    }

    /// [`EmptyWell::draw`] packed for summing: the code's DN in the low 32 bits, 1 in
    /// bit 32 when it clipped low, 1 in bit 48 when it clipped high (so that a sum of up
    /// to [`TALLY_RUN`] of them is taken apart by [`Tally::add`]).
    #[inline(always)]
    pub fn tally(&self, u: u32) -> u64 {
        self.tally[self.index(u)]
    }

    /// Each code with its probability (as tabulated, a multiple of 2⁻³²).
    pub fn codes(&self) -> impl Iterator<Item = (Conversion, f64)> + '_ {
        let mut prev = 0;
        self.codes.iter().zip(&self.cum).map(move |(c, &cum)| {
            let p = (cum - prev) as f64 / 4_294_967_296.0;
            prev = cum;
            (*c, p)
        })
    }
}

/// `∫_a^b φ(z) dz`, φ the standard normal density: 16-point Gauss–Legendre on pieces at
/// most ¼ wide (error far below 1e-16 on a function this smooth).
fn gaussian_mass(a: f64, b: f64) -> f64 {
    if b <= a {
        return 0.0;
    }
    const X: [f64; 8] = [
        0.095_012_509_837_637_44,
        0.281_603_550_779_258_9,
        0.458_016_777_657_227_4,
        0.617_876_244_402_643_8,
        0.755_404_408_355_003,
        0.865_631_202_387_831_8,
        0.944_575_023_073_232_6,
        0.989_400_934_991_649_9,
    ];
    const W: [f64; 8] = [
        0.189_450_610_455_068_5,
        0.182_603_415_044_923_6,
        0.169_156_519_395_002_5,
        0.149_595_988_816_576_7,
        0.124_628_971_255_533_9,
        0.095_158_511_682_492_78,
        0.062_253_523_938_647_89,
        0.027_152_459_411_754_1,
    ];
    let pieces = ((b - a) / 0.25).ceil().max(1.0) as usize;
    let h = (b - a) / pieces as f64;
    let phi = |z: f64| (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt();
    (0..pieces)
        .map(|k| {
            let (c, r) = (a + (k as f64 + 0.5) * h, 0.5 * h);
            X.iter().zip(&W).map(|(x, w)| w * (phi(c - r * x) + phi(c + r * x))).sum::<f64>() * r
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::config::AdcConfig;

    #[test]
    fn gaussian_masses_match_known_values() {
        // Φ(1) − Φ(−1), Φ(3) − Φ(2), and the whole line.
        assert!((gaussian_mass(-1.0, 1.0) - 0.682_689_492_137_085_9).abs() < 1e-15);
        assert!((gaussian_mass(2.0, 3.0) - 0.021_400_233_916_549_1).abs() < 1e-15);
        assert!((gaussian_mass(-40.0, 40.0) - 1.0).abs() < 1e-14);
    }

    #[test]
    fn the_table_holds_every_likely_code_and_inverts_its_sums() {
        let adc = Adc::new(&AdcConfig { bits: 10, gain_e_per_dn: 11.5, offset_dn: 32.0 });
        let t = EmptyWell::new(12.0, &adc).unwrap();
        let total: f64 = t.codes().map(|(_, p)| p).sum();
        assert_eq!(total, 1.0);
        // The offset code: z within ±½·11.5/12 of 0.
        let p32 = t.codes().find(|(c, _)| *c == Conversion::InRange(32)).unwrap().1;
        assert!((p32 - gaussian_mass(-0.479_166_666_666_666_7, 0.479_166_666_666_666_7)).abs() < 3e-10);
        // Every 32-bit draw lands on the code whose interval holds it (spot checks at the
        // boundaries).
        let mut lo = 0u64;
        for (j, &c) in t.cum.iter().enumerate().filter(|(_, c)| **c > 0) {
            if c > lo {
                assert_eq!(t.draw(lo as u32), t.codes[j]);
                assert_eq!(t.draw((c - 1) as u32), t.codes[j]);
            }
            lo = c;
        }
        // The fine table and the guided search agree on every 2²⁰-wide range's ends, and
        // the tally packs each code.
        for k in 0..4096u64 {
            for u in [k << 20, ((k + 1) << 20) - 1, (k << 20) + 12345] {
                assert_eq!(t.index(u as u32), t.search(u as u32), "{u}");
            }
        }
        assert!(t.fine.iter().filter(|&&j| j == STRADDLES).count() < t.codes.len());
        let mut sum = Tally::default();
        sum.add(t.tally(0) + t.tally(u32::MAX) + t.tally(1 << 31));
        let dn: u32 = [0, u32::MAX, 1 << 31].iter().map(|&u| t.draw(u).dn()).sum();
        assert_eq!(sum, Tally { dn: u64::from(dn), low: 0, high: 0 });
        // No read noise: one code; an offset of 0 clips half the draws low.
        assert_eq!(EmptyWell::new(0.0, &adc).unwrap().codes, vec![Conversion::InRange(32)]);
        let zero = Adc::new(&AdcConfig { bits: 8, gain_e_per_dn: 1.0, offset_dn: 0.0 });
        let t = EmptyWell::new(3.0, &zero).unwrap();
        let low: f64 = t.codes().filter(|(c, _)| *c == Conversion::ClippedLow).map(|(_, p)| p).sum();
        assert!((low - gaussian_mass(-40.0, -0.5 / 3.0)).abs() < 3e-10, "{low}");
        let mut sum = Tally::default();
        sum.add(t.tally(0) + t.tally(0));
        assert_eq!(sum, Tally { dn: 0, low: 2, high: 0 });
    }
}
