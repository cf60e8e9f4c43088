//! The fold height field: sparse creases on a jittered grid ("sparse crease convolution").
//!
//! Space is cut into square cells of side `spacing_m`. Each cell owns one crease, drawn
//! from a hash of (seed, cell): a centre jittered inside the cell, an orientation (a
//! seed-wide preferred direction plus a spread set by `anisotropy`), a length of 1.5–3
//! cells, a slight bend, a sign (ridge or valley), an amplitude factor in [0.7, 1.3], and
//! a *rank* in [0, 1). The crease's height profile across its line is a tent of half-width
//! `width_m` and height `slope·width_m` (sharp ridge, straight flanks: film creases), and
//! it tapers to zero towards its ends with `(1 − s²)²`. Heights of overlapping creases add.
//!
//! The two fitted knobs: `slope` (the flank slope, i.e. how steep each crease is) and
//! `density` (the fraction of cells whose crease is present: a crease is present when its
//! rank is below `density`, fading in over a rank band of [`FADE`] so that the statistics
//! are continuous in `density`). The crease width, the cell spacing (the preferred scale)
//! and the anisotropy stay fixed at their defaults unless set explicitly.
//!
//! The field is a pure function of (params, seed, point), so any mesh sampled from it is
//! deterministic, and two coplanar triangles sharing an edge get identical heights there.

use super::FoldError;
use crate::render::sampling::mix64;
use glam::DVec2;
use std::f64::consts::PI;

/// Rank band over which a crease fades in as `density` grows.
pub const FADE: f64 = 0.08;

/// Shape of a fold field. Lengths in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FoldParams {
    /// Flank slope of a full-amplitude crease (tan of its flank angle).
    pub slope: f64,
    /// Fraction of cells carrying a crease, 0..=1+FADE.
    pub density: f64,
    /// Half-width of a crease's tent profile (m).
    pub width_m: f64,
    /// Cell size, the preferred scale of the crease pattern (m).
    pub spacing_m: f64,
    /// 0 = crease orientations uniform, 1 = all along the preferred direction.
    pub anisotropy: f64,
}

impl FoldParams {
    pub const DEFAULT_WIDTH_M: f64 = 0.022;
    pub const DEFAULT_SPACING_M: f64 = 0.15;
    pub const DEFAULT_ANISOTROPY: f64 = 0.4;

    /// Parameters with the default width, spacing and anisotropy.
    pub fn new(slope: f64, density: f64) -> Self {
        FoldParams {
            slope,
            density,
            width_m: Self::DEFAULT_WIDTH_M,
            spacing_m: Self::DEFAULT_SPACING_M,
            anisotropy: Self::DEFAULT_ANISOTROPY,
        }
    }

    /// Check ranges; names the offending field.
    pub fn validate(&self) -> Result<(), FoldError> {
        let bad = |field, value, why| Err(FoldError::InvalidParam { field, value, why });
        if !(self.slope.is_finite() && self.slope >= 0.0) {
            return bad("slope", self.slope, "must be finite and >= 0");
        }
        if !(self.density.is_finite() && self.density >= 0.0) {
            return bad("density", self.density, "must be finite and >= 0");
        }
        if !(self.width_m.is_finite() && self.width_m > 0.0) {
            return bad("width_m", self.width_m, "must be finite and > 0");
        }
        if !(self.spacing_m.is_finite() && self.spacing_m > 2.0 * self.width_m) {
            return bad("spacing_m", self.spacing_m, "must be > 2·width_m");
        }
        if !(0.0..=1.0).contains(&self.anisotropy) {
            return bad("anisotropy", self.anisotropy, "must be in [0, 1]");
        }
        Ok(())
    }
}

/// One crease in the plane.
#[derive(Clone, Copy, Debug)]
pub struct Crease {
    pub centre: DVec2,
    /// Unit vector along the crease line.
    pub along: DVec2,
    pub half_len: f64,
    /// Bend: the line is offset by `bend·d²` at distance d along it.
    pub bend: f64,
    /// ±amplitude factor (sign: ridge or valley).
    pub amp: f64,
    pub rank: f64,
}

impl Crease {
    /// Unit-slope, unit-amplitude shape at `p` for half-width `w`: tent × taper, in metres
    /// of height per unit slope (so height = slope·weight·amp·shape).
    #[inline]
    pub fn shape(&self, p: DVec2, w: f64) -> f64 {
        let d = p - self.centre;
        let s = d.dot(self.along);
        let s_rel = s / self.half_len;
        if s_rel.abs() >= 1.0 {
            return 0.0;
        }
        let t = (d.perp_dot(self.along) - self.bend * s * s).abs();
        if t >= w {
            return 0.0;
        }
        let taper = (1.0 - s_rel * s_rel).powi(2);
        (w - t) * taper
    }
}

/// A fold field: parameters plus seed.
#[derive(Clone, Copy, Debug)]
pub struct FoldField {
    pub params: FoldParams,
    pub seed: u64,
    /// Preferred crease direction (radians), drawn from the seed.
    pub theta0: f64,
}

fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

impl FoldField {
    pub fn new(params: FoldParams, seed: u64) -> Result<Self, FoldError> {
        params.validate()?;
        let theta0 = PI * unit(mix64(seed ^ 0x5eed_f01d));
        Ok(FoldField { params, seed, theta0 })
    }

    /// How strongly a crease of `rank` is present at the current density.
    #[inline]
    pub fn weight(&self, rank: f64) -> f64 {
        weight(self.params.density, rank)
    }

    /// The crease owned by cell (i, j).
    pub fn crease(&self, i: i64, j: i64) -> Crease {
        crease_at(self.seed, self.theta0, &self.params, i, j)
    }

    /// Cells whose crease can reach `p`: a crease centre lies in its cell and reaches
    /// at most 1.5 cells plus the width (plus bend) from it.
    #[inline]
    pub fn cell_range(&self, p: DVec2) -> (i64, i64, i64, i64) {
        let l = self.params.spacing_m;
        let reach = 1.5 * l + 2.0 * self.params.width_m + 0.2 * l;
        let lo = ((p - DVec2::splat(reach)) / l).floor();
        let hi = ((p + DVec2::splat(reach)) / l).floor();
        (lo.x as i64, hi.x as i64, lo.y as i64, hi.y as i64)
    }

    /// Height (m) at `p` (plane coordinates, m).
    pub fn height(&self, p: DVec2) -> f64 {
        let (i0, i1, j0, j1) = self.cell_range(p);
        let mut h = 0.0;
        for i in i0..=i1 {
            for j in j0..=j1 {
                let c = self.crease(i, j);
                let wgt = self.weight(c.rank);
                if wgt > 0.0 {
                    h += wgt * c.amp * c.shape(p, self.params.width_m);
                }
            }
        }
        self.params.slope * h
    }
}

/// Presence of a crease of `rank` at `density` (0 → absent, 1 → full), linear over FADE.
#[inline]
pub fn weight(density: f64, rank: f64) -> f64 {
    ((density - rank) / FADE).clamp(0.0, 1.0)
}

/// The crease of cell (i, j) for a seed; lengths scale with `params.spacing_m`.
pub fn crease_at(seed: u64, theta0: f64, params: &FoldParams, i: i64, j: i64) -> Crease {
    let l = params.spacing_m;
    let key = mix64(seed ^ mix64((i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)))
        ^ mix64((j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f).wrapping_add(0x1234_5678));
    let mut k = mix64(key);
    let mut next = || {
        k = mix64(k.wrapping_add(0x9e37_79b9_7f4a_7c15));
        unit(k)
    };
    let centre = DVec2::new((i as f64 + next()) * l, (j as f64 + next()) * l);
    let spread = (1.0 - params.anisotropy) * PI;
    let theta = theta0 + (next() - 0.5) * spread;
    let half_len = 0.5 * l * (1.5 + 1.5 * next());
    let bend = (next() - 0.5) * 0.4 / half_len;
    let sign = if next() < 0.5 { -1.0 } else { 1.0 };
    let amp = sign * (0.7 + 0.6 * next());
    let rank = next();
    Crease { centre, along: DVec2::new(theta.cos(), theta.sin()), half_len, bend, amp, rank }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_density_or_slope_is_flat() {
        for params in [FoldParams::new(1.0, 0.0), FoldParams::new(0.0, 1.0)] {
            let f = FoldField::new(params, 7).unwrap();
            for k in 0..200 {
                let p = DVec2::new(k as f64 * 0.013 - 1.3, k as f64 * 0.007 - 0.7);
                assert_eq!(f.height(p), 0.0);
            }
        }
    }

    #[test]
    fn single_crease_has_tent_profile_with_the_set_slope() {
        let c = Crease { centre: DVec2::ZERO, along: DVec2::X, half_len: 1.0, bend: 0.0, amp: 1.0, rank: 0.0 };
        let w = 0.02;
        // At the crease's middle (taper 1) the flank slope is exactly 1 per unit slope.
        let h0 = c.shape(DVec2::new(0.0, 0.0), w);
        let h1 = c.shape(DVec2::new(0.0, 0.01), w);
        assert!((h0 - 0.02).abs() < 1e-15 && (h0 - h1 - 0.01).abs() < 1e-15);
        assert_eq!(c.shape(DVec2::new(0.0, 0.021), w), 0.0);
        assert_eq!(c.shape(DVec2::new(1.0, 0.0), w), 0.0);
    }

    #[test]
    fn cell_range_covers_every_crease_that_reaches_a_point() {
        // Brute force over a wide block of cells: no crease outside cell_range reaches p.
        let f = FoldField::new(FoldParams::new(1.0, 1.1), 3).unwrap();
        let w = f.params.width_m;
        for k in 0..50 {
            let p = DVec2::new(k as f64 * 0.031 - 0.8, (k * k) as f64 * 0.0007 - 0.5);
            let (i0, i1, j0, j1) = f.cell_range(p);
            for i in -20..20 {
                for j in -20..20 {
                    if (i0..=i1).contains(&i) && (j0..=j1).contains(&j) {
                        continue;
                    }
                    assert_eq!(f.crease(i, j).shape(p, w), 0.0, "cell ({i},{j}) at {p}");
                }
            }
        }
    }

    #[test]
    fn validate_names_the_field() {
        let mut p = FoldParams::new(1.0, 0.5);
        p.width_m = -1.0;
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("width_m"), "{e}");
    }
}
