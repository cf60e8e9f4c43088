//! The mean dark charge summed over a run of pixels without reading each pixel's DSNU
//! value: per 64-pixel chunk of the array, what the sum needs, computed once per sensor.
//!
//! A pixel's mean dark charge is `max(0, I_d·t + DSNU·t·z₂)`. Whether the clamp acts
//! does not depend on `t`, so over a chunk the sum is `n₊·I_d·t + DSNU·t·Σ₊z₂` (the
//! pixels with `I_d + DSNU·z₂ > 0`), to rounding; its largest value is that of the
//! chunk's largest `z₂`, exactly (the charge grows with `z₂`). A frame's dark runs, 84 %
//! of the satellite frame's pixels, then read 16 bytes per 64 pixels instead of 256.

/// Pixels per chunk (chunk `k` holds pixels `64k..64k + 64` of the array).
const CHUNK: usize = 64;

/// Per chunk of the array: how many pixels have a positive mean dark charge, the sum of
/// their DSNU values, and the largest DSNU value.
#[derive(Debug)]
pub struct DarkSums {
    positive: Vec<f64>,
    z_sum: Vec<f64>,
    z_max: Vec<f32>,
}

impl DarkSums {
    /// The chunks of a DSNU plane (`dsnu[p]` the value of pixel p) for dark current
    /// `i_d` and DSNU `dsnu_rate` (both e⁻/s, `dsnu_rate ≥ 0`).
    pub fn new(dsnu: &[f32], i_d: f64, dsnu_rate: f64) -> DarkSums {
        let mut s = DarkSums { positive: Vec::new(), z_sum: Vec::new(), z_max: Vec::new() };
        for c in dsnu.chunks(CHUNK) {
            let pos = || c.iter().filter(|&&z| i_d + dsnu_rate * z as f64 > 0.0);
            s.positive.push(pos().count() as f64);
            s.z_sum.push(pos().map(|&z| z as f64).sum());
            s.z_max.push(c.iter().copied().fold(f32::NEG_INFINITY, f32::max));
        }
        s
    }

    /// Σ and max of `dark(z)` over pixels `first..first + z.len()`, whose DSNU values are
    /// `z`: `dark(z) = max(0, dark_e + dsnu_e·z)`, the detector's charge at one
    /// integration time (`dsnu_e ≥ 0`). The whole chunks inside the run come from the
    /// table, the pixels at its ends from `z`.
    #[inline]
    pub fn sum(&self, first: u64, z: &[f32], dark: impl Fn(f32) -> f64, dark_e: f64, dsnu_e: f64) -> (f64, f64) {
        let (a, b) = (first as usize, first as usize + z.len());
        let (ka, kb) = (a.div_ceil(CHUNK), b / CHUNK);
        let mut sum = 0.0;
        let mut z_max = f32::NEG_INFINITY;
        let mut ends = |zs: &[f32]| {
            for &zi in zs {
                sum += dark(zi);
                z_max = z_max.max(zi);
            }
        };
        if ka >= kb {
            ends(z);
        } else {
            ends(&z[..ka * CHUNK - a]);
            ends(&z[kb * CHUNK - a..]);
            for k in ka..kb {
                sum += self.positive[k] * dark_e + dsnu_e * self.z_sum[k];
                z_max = z_max.max(self.z_max[k]);
            }
        }
        (sum, if z.is_empty() { 0.0 } else { dark(z_max) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunk_sums_agree_with_each_pixels_sum() {
        let z: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.731).sin() * 4.0).collect();
        let (i_d, rate, t) = (60.0, 20.0, 25e-6);
        let s = DarkSums::new(&z, i_d, rate);
        let (dark_e, dsnu_e) = (i_d * t, rate * t);
        let dark = |z: f32| (dark_e + dsnu_e * z as f64).max(0.0);
        for (first, n) in [(0, 1000), (3, 0), (5, 40), (60, 10), (63, 130), (64, 64), (100, 900), (999, 1)] {
            let zs = &z[first..first + n];
            let want: f64 = zs.iter().map(|&z| dark(z)).sum();
            let max = zs.iter().map(|&z| dark(z)).fold(0.0, f64::max);
            let (sum, got_max) = s.sum(first as u64, zs, dark, dark_e, dsnu_e);
            assert!((sum - want).abs() <= 1e-12 * want.max(1e-300), "{first}+{n}: {sum} {want}");
            assert_eq!(got_max, max, "{first}+{n}");
        }
    }
}
