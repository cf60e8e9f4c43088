//! Point spread functions and their energy-preserving convolution with the image.
//!
//! Kernels are integrated over each pixel's area and normalised to sum 1. The image
//! border reflects (the light a kernel would spread past the edge is folded back onto
//! the array), written as a *gather* whose weights are exactly those of the scatter
//! "every input pixel spreads its signal with the kernel": the total signal is
//! preserved to rounding, also at the borders.

use rayon::prelude::*;

/// A 2D kernel of radii `(rx, ry)`, row-major `(2ry+1) × (2rx+1)`, summing to 1.
/// `weights[(my + ry) * (2rx+1) + (mx + rx)]` is the fraction of an input pixel's signal
/// that lands `(mx, my)` pixels away.
#[derive(Clone, Debug, PartialEq)]
pub struct Kernel {
    pub rx: usize,
    pub ry: usize,
    pub weights: Vec<f32>,
}

impl Kernel {
    fn normalised(rx: usize, ry: usize, w: Vec<f64>) -> Kernel {
        let sum: f64 = w.iter().sum();
        Kernel { rx, ry, weights: w.iter().map(|v| (v / sum) as f32).collect() }
    }

    /// A separable Gaussian as its two 1D passes (horizontal, vertical): each pixel-
    /// integrated, `w[m] = Φ((m+½)/σ) − Φ((m−½)/σ)`, truncated at 5σ and renormalised.
    pub fn gaussian(sigma_px: f64) -> (Kernel, Kernel) {
        let r = (5.0 * sigma_px).ceil().max(1.0) as usize;
        let w: Vec<f64> = (-(r as i64)..=r as i64)
            .map(|m| {
                let m = m as f64;
                normal_cdf((m + 0.5) / sigma_px) - normal_cdf((m - 0.5) / sigma_px)
            })
            .collect();
        (Kernel::normalised(r, 0, w.clone()), Kernel::normalised(0, r, w))
    }

    /// Diffraction-limited Airy PSF of a circular aperture at f-number `n`, for pixels
    /// of `pitch_um`, averaged over `wavelengths_um` (each monochromatic PSF normalised
    /// to unit energy before averaging). Each pixel integrates 8 × 8 sub-samples.
    /// `radius_px` defaults to 8 first-zero radii (1.22 λ N) of the longest wavelength,
    /// at least 3 px.
    pub fn airy(n: f64, pitch_um: f64, wavelengths_um: &[f64], radius_px: Option<u32>) -> Kernel {
        let lmax = wavelengths_um.iter().copied().fold(0.0, f64::max);
        let r = radius_px
            .map(|r| r as usize)
            .unwrap_or_else(|| ((8.0 * 1.22 * lmax * n / pitch_um).ceil() as usize).max(3));
        let side = 2 * r + 1;
        const SUB: usize = 8;
        let mut w = vec![0.0f64; side * side];
        for &l in wavelengths_um {
            // Continuous PSF per unit focal-plane area: (π / (4 λ² N²)) · (2 J1(v)/v)²,
            // with v = π ρ / (λ N); here in pixel units (ρ in µm).
            let norm = std::f64::consts::PI / (4.0 * l * l * n * n) * pitch_um * pitch_um;
            for (idx, wv) in w.iter_mut().enumerate() {
                let (my, mx) = (idx / side, idx % side);
                let (cx, cy) = (mx as f64 - r as f64, my as f64 - r as f64);
                let mut acc = 0.0;
                for sy in 0..SUB {
                    for sx in 0..SUB {
                        let x = cx - 0.5 + (sx as f64 + 0.5) / SUB as f64;
                        let y = cy - 0.5 + (sy as f64 + 0.5) / SUB as f64;
                        let rho_um = x.hypot(y) * pitch_um;
                        acc += airy_intensity(std::f64::consts::PI * rho_um / (l * n));
                    }
                }
                *wv += norm * acc / (SUB * SUB) as f64 / wavelengths_um.len() as f64;
            }
        }
        Kernel::normalised(r, r, w)
    }

    #[inline]
    pub(super) fn at(&self, mx: i64, my: i64) -> f32 {
        let side = 2 * self.rx + 1;
        self.weights[(my + self.ry as i64) as usize * side + (mx + self.rx as i64) as usize]
    }
}

/// The Airy intensity pattern normalised to 1 at the centre: (2 J1(v) / v)².
#[inline]
pub fn airy_intensity(v: f64) -> f64 {
    if v.abs() < 1e-8 {
        return 1.0;
    }
    let a = 2.0 * bessel_j1(v) / v;
    a * a
}

/// Bessel function of the first kind, order 1 (rational approximations after
/// Numerical Recipes §6.5, absolute error < 1e-8).
pub fn bessel_j1(x: f64) -> f64 {
    let ax = x.abs();
    if ax < 8.0 {
        let y = x * x;
        let a1 = x
            * (72362614232.0
                + y * (-7895059235.0
                    + y * (242396853.1 + y * (-2972611.439 + y * (15704.48260 + y * (-30.16036606))))));
        let a2 = 144725228442.0 + y * (2300535178.0 + y * (18583304.74 + y * (99447.43394 + y * (376.9991397 + y))));
        a1 / a2
    } else {
        let z = 8.0 / ax;
        let y = z * z;
        let xx = ax - 3.0 * std::f64::consts::FRAC_PI_4;
        let a1 = 1.0 + y * (0.183105e-2 + y * (-0.3516396496e-4 + y * (0.2457520174e-5 + y * (-0.240337019e-6))));
        let a2 =
            0.04687499995 + y * (-0.2002690873e-3 + y * (0.8449199096e-5 + y * (-0.88228987e-6 + y * 0.105787412e-6)));
        let ans = (std::f64::consts::FRAC_2_PI / ax).sqrt() * (xx.cos() * a1 - z * xx.sin() * a2);
        if x < 0.0 { -ans } else { ans }
    }
}

/// Standard normal CDF via erfc (Numerical Recipes `erfcc`, relative error < 1.2e-7).
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * erfc(-x / std::f64::consts::SQRT_2)
}

fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let ans = t
        * (-z * z - 1.26551223
            + t * (1.00002368
                + t * (0.37409196
                    + t * (0.09678418
                        + t * (-0.18628806
                            + t * (0.27886807
                                + t * (-1.13520398 + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277)))))))))
            .exp();
    if x >= 0.0 { ans } else { 2.0 - ans }
}

/// Reflecting index map with period 2n: −1 → 0, −2 → 1, n → n−1, …
#[inline]
fn reflect(j: i64, n: usize) -> usize {
    let p = j.rem_euclid(2 * n as i64) as usize;
    if p < n { p } else { 2 * n - 1 - p }
}

/// For each output index o along an axis of length n, the (input index, kernel offset)
/// pairs whose scatter lands on o (`of(o)`); every (i, m) pair occurs exactly once. Kept
/// flat (one list and its offsets) so an axis costs three allocations, not one per index.
pub(super) struct Gather {
    start: Vec<usize>,
    pairs: Vec<(usize, i64)>,
}

impl Gather {
    pub(super) fn new(n: usize, r: usize) -> Gather {
        let target = |i: usize, m: i64| reflect(i as i64 + m, n);
        let offsets = || (0..n).flat_map(|i| (-(r as i64)..=r as i64).map(move |m| (i, m)));
        // Counting sort by output index, keeping each list in (i, m) order.
        let mut start = vec![0usize; n + 1];
        for (i, m) in offsets() {
            start[target(i, m) + 1] += 1;
        }
        for o in 0..n {
            start[o + 1] += start[o];
        }
        let mut fill = start.clone();
        let mut pairs = vec![(0usize, 0i64); start[n]];
        for (i, m) in offsets() {
            let o = target(i, m);
            pairs[fill[o]] = (i, m);
            fill[o] += 1;
        }
        Gather { start, pairs }
    }

    pub(super) fn of(&self, o: usize) -> &[(usize, i64)] {
        &self.pairs[self.start[o]..self.start[o + 1]]
    }
}

/// Convolve a row-major `width × height` image with `k` (energy-preserving, reflecting
/// borders). Parallel over output rows; the result does not depend on the thread count.
pub fn convolve(img: &[f32], width: usize, height: usize, k: &Kernel) -> Vec<f32> {
    assert_eq!(img.len(), width * height, "image size");
    let lx = Gather::new(width, k.rx);
    let ly = Gather::new(height, k.ry);
    // Columns where every kernel offset reads a direct (unreflected) input.
    let (lo, hi) = if width > 2 * k.rx { (k.rx, width - k.rx) } else { (0, 0) };
    let mut out = vec![0.0f32; width * height];
    out.par_chunks_mut(width).enumerate().for_each(|(oy, orow)| {
        for &(iy, my) in ly.of(oy) {
            let src = &img[iy * width..(iy + 1) * width];
            // An image no wider than the kernel has no interior: every column gathers.
            for mx in (-(k.rx as i64)..=k.rx as i64).filter(|_| hi > lo) {
                let w = k.at(mx, my);
                // out[ox] += w · src[ox − mx] over the interior, as one slice axpy.
                let s0 = (lo as i64 - mx) as usize;
                for (o, s) in orow[lo..hi].iter_mut().zip(&src[s0..s0 + (hi - lo)]) {
                    *o += w * s;
                }
            }
            for ox in (0..lo).chain(hi.max(lo)..width) {
                let mut acc = 0.0f32;
                for &(ix, mx) in lx.of(ox) {
                    acc += k.at(mx, my) * src[ix];
                }
                orow[ox] += acc;
            }
        }
    });
    out
}

/// The variance image of [`convolve`]`(img)` when the input pixels carry independent
/// errors of variance `var` (a Monte Carlo render's): `Var(out[o]) = Σᵢ W(o,i)² var[i]`,
/// `W(o,i)` the total weight input `i` has at output `o`. In the interior that is the
/// convolution with the squared kernel; at a reflecting border one input can reach one
/// output through two kernel offsets, and their weights add before squaring. Accumulated
/// in f64; parallel over output rows, the result does not depend on the thread count.
pub fn convolve_variance(var: &[f32], width: usize, height: usize, k: &Kernel) -> Vec<f32> {
    assert_eq!(var.len(), width * height, "image size");
    let lx = Gather::new(width, k.rx);
    let ly = Gather::new(height, k.ry);
    let (lo, hi) = if width > 2 * k.rx { (k.rx, width - k.rx) } else { (0, 0) };
    let rx = k.rx as i64;
    let mut out = vec![0.0f32; width * height];
    out.par_chunks_mut(width).enumerate().for_each(|(oy, orow)| {
        let mut acc = vec![0.0f64; width];
        let mut col_w = vec![0.0f64; 2 * k.rx + 1];
        // The gather lists are sorted by input index: one chunk per distinct input row.
        for rows in ly.of(oy).chunk_by(|a, b| a.0 == b.0) {
            let src = &var[rows[0].0 * width..(rows[0].0 + 1) * width];
            // This input row's weight at each horizontal offset, its vertical offsets summed.
            for (i, cw) in col_w.iter_mut().enumerate() {
                *cw = rows.iter().map(|&(_, my)| k.at(i as i64 - rx, my) as f64).sum();
            }
            if hi > lo {
                for (i, cw) in col_w.iter().enumerate() {
                    let w2 = cw * cw;
                    let s0 = (lo as i64 - (i as i64 - rx)) as usize;
                    for (o, s) in acc[lo..hi].iter_mut().zip(&src[s0..s0 + (hi - lo)]) {
                        *o += w2 * *s as f64;
                    }
                }
            }
            for ox in (0..lo).chain(hi.max(lo)..width) {
                for cols in lx.of(ox).chunk_by(|a, b| a.0 == b.0) {
                    let w: f64 = cols.iter().map(|&(_, mx)| col_w[(mx + rx) as usize]).sum();
                    acc[ox] += w * w * src[cols[0].0] as f64;
                }
            }
        }
        for (o, a) in orow.iter_mut().zip(&acc) {
            *o = *a as f32;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bessel_j1_known_values() {
        // Abramowitz & Stegun table 9.1 / the first zero j1,1 = 3.831705970.
        assert!((bessel_j1(1.0) - 0.440_050_585_7).abs() < 1e-8);
        assert!((bessel_j1(10.0) - 0.043_472_746_2).abs() < 1e-7);
        assert!(bessel_j1(3.831_705_970).abs() < 1e-7);
        assert!((bessel_j1(-1.0) + 0.440_050_585_7).abs() < 1e-8);
    }

    #[test]
    fn normal_cdf_known_values() {
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7);
        assert!((normal_cdf(1.0) - 0.841_344_746).abs() < 1e-7);
        assert!((normal_cdf(-2.0) - 0.022_750_132).abs() < 1e-7);
    }

    #[test]
    fn reflect_is_half_sample_symmetric() {
        let n = 4;
        let got: Vec<usize> = (-5..9).map(|j| reflect(j, n)).collect();
        assert_eq!(got, vec![3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]);
    }

    #[test]
    fn delta_kernel_is_identity_and_shift_kernel_shifts() {
        let img: Vec<f32> = (0..20).map(|v| v as f32).collect();
        let id = Kernel { rx: 1, ry: 1, weights: vec![0., 0., 0., 0., 1., 0., 0., 0., 0.] };
        assert_eq!(convolve(&img, 5, 4, &id), img);
        // All signal moves one column right (mx = +1); the last column reflects onto itself.
        let right = Kernel { rx: 1, ry: 0, weights: vec![0., 0., 1.] };
        let out = convolve(&img, 5, 4, &right);
        assert_eq!(&out[0..5], &[0., 0., 1., 2., 3. + 4.]);
        // An image narrower than the kernel (a preview of a big camera): all reflected,
        // the signal kept.
        let wide = Kernel { rx: 3, ry: 0, weights: vec![0., 0., 0., 0., 0., 0., 1.] };
        let out = convolve(&img[..4], 2, 2, &wide);
        assert_eq!(out.iter().sum::<f32>(), img[..4].iter().sum::<f32>());
    }
}
