//! Brown–Conrady lens distortion (radial k1, k2, k3; tangential p1, p2).
//!
//! Coordinates are *normalised*: `x = (u − cx) / f`, `y = (v − cy) / f`, where `(u, v)` is
//! a focal-plane position in pixels, `(cx, cy)` the principal point and `f` the focal
//! length in pixels. With `r² = x² + y²`,
//!
//! ```text
//! x_d = x (1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2 x²)
//! y_d = y (1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2 y²) + 2 p2 x y
//! ```
//!
//! maps the *ideal* (pinhole) image point to where the real lens puts it (`distort`).
//! The renderer needs the opposite direction: for each sample position on the real,
//! distorted focal plane it asks which ideal ray lands there (`undistort`), and traces
//! that ray. This renders distortion in the forward direction: a point of the scene
//! appears where the real lens images it. `k1 < 0` is barrel, `k1 > 0` pincushion.

use glam::DVec2;
use serde::Deserialize;

mod lanes;

/// Brown–Conrady coefficients in normalised coordinates (x / f). All zero: no distortion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Distortion {
    /// Radial coefficient of r².
    pub k1: f64,
    /// Radial coefficient of r⁴.
    pub k2: f64,
    /// Radial coefficient of r⁶.
    pub k3: f64,
    /// Tangential (decentring) coefficient p1.
    pub p1: f64,
    /// Tangential (decentring) coefficient p2.
    pub p2: f64,
}

/// Why a distortion model cannot be used over a field of view.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DistortionError {
    #[error("distortion coefficients must be finite")]
    NotFinite,
    /// The forward map folds over (its Jacobian is not positive) inside the field, so
    /// two ideal points land on one image point and `undistort` has no unique answer.
    #[error("distortion folds over inside the field: Jacobian determinant {det:.3e} at normalised ({x:.4}, {y:.4})")]
    FoldsOver { x: f64, y: f64, det: f64 },
    #[error("undistort did not converge at normalised ({x:.6}, {y:.6}): residual {residual:.3e}")]
    NoConvergence { x: f64, y: f64, residual: f64 },
}

/// Newton iterations allowed in `undistort`; realistic lenses need 3–5.
const MAX_ITER: usize = 30;
/// Convergence threshold on the normalised residual (1e-14 × f px ≪ 1e-6 px for any f).
const TOL: f64 = 1e-14;

impl Distortion {
    /// True when all coefficients are zero (`distort` and `undistort` are the identity).
    pub fn is_identity(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0 && self.k3 == 0.0 && self.p1 == 0.0 && self.p2 == 0.0
    }

    /// The radial factor `1 + k1 r² + k2 r⁴ + k3 r⁶` at `r2` = r².
    #[inline]
    fn radial(&self, r2: f64) -> f64 {
        1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
    }

    /// Ideal (pinhole) normalised point → where the real lens images it.
    #[inline]
    pub fn distort(&self, ideal: DVec2) -> DVec2 {
        let (x, y) = (ideal.x, ideal.y);
        let r2 = x * x + y * y;
        let radial = self.radial(r2);
        DVec2::new(
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Jacobian of `distort` at `p`, as columns (∂d/∂x, ∂d/∂y).
    fn jacobian(&self, p: DVec2) -> (DVec2, DVec2) {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = self.radial(r2);
        // d(radial)/d(r²)
        let dr = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
        let dxdx = radial + 2.0 * x * x * dr + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
        let dxdy = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let dydx = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let dydy = radial + 2.0 * y * y * dr + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
        (DVec2::new(dxdx, dydx), DVec2::new(dxdy, dydy))
    }

    /// Real (distorted) normalised point → the ideal point the lens maps onto it, by
    /// Newton's method from [`Distortion::first_guess`]. Returns an error instead of a wrong
    /// answer.
    pub fn try_undistort(&self, distorted: DVec2) -> Result<DVec2, DistortionError> {
        if self.is_identity() {
            return Ok(distorted);
        }
        if self.p1 == 0.0
            && self.p2 == 0.0
            && let Some(p) = self.undistort_radial(distorted)
        {
            return Ok(p);
        }
        self.undistort_2d(distorted)
    }

    /// Newton's method on both coordinates (any Brown–Conrady model).
    fn undistort_2d(&self, distorted: DVec2) -> Result<DVec2, DistortionError> {
        let mut p = self.first_guess(distorted);
        // Squared residuals against a squared bound: no square root per iteration (with
        // 1 + |d|² ≤ (1 + |d|)² the bound is the stricter one).
        let bound2 = TOL * TOL * (1.0 + distorted.length_squared());
        let mut residual2 = f64::INFINITY;
        for _ in 0..MAX_ITER {
            let e = self.distort(p) - distorted;
            residual2 = e.length_squared();
            if residual2 <= bound2 {
                return Ok(p);
            }
            let (cx, cy) = self.jacobian(p);
            let det = cx.x * cy.y - cy.x * cx.y;
            if det.abs() < 1e-300 || !det.is_finite() {
                break;
            }
            // Solve J · step = e (Cramer's rule), one division.
            let inv = 1.0 / det;
            p -= DVec2::new((e.x * cy.y - cy.x * e.y) * inv, (cx.x * e.y - e.x * cx.y) * inv);
        }
        // Newton stalls at rounding level; accept if that level is tiny.
        let residual = residual2.sqrt();
        if residual <= 1e-12 {
            return Ok(p);
        }
        Err(DistortionError::NoConvergence { x: distorted.x, y: distorted.y, residual })
    }

    /// A radial lens moves points along their radius only, so inverting it is a problem in
    /// one unknown: the ideal radius `r` with `r (1 + k1 r² + k2 r⁴ + k3 r⁶) = r_d`, by
    /// Newton on that polynomial (a third of the 2-D iteration's work). `None` when it does
    /// not converge, for the 2-D iteration (and its error) to decide.
    #[inline]
    fn undistort_radial(&self, distorted: DVec2) -> Option<DVec2> {
        let rd2 = distorted.length_squared();
        if rd2 == 0.0 {
            return Some(distorted);
        }
        let rd = rd2.sqrt();
        let (k1, k2, k3) = (self.k1, self.k2, self.k3);
        let mut r = rd / self.start_divisor(rd2);
        for _ in 0..MAX_ITER {
            let r2 = r * r;
            let e = r * self.radial(r2) - rd;
            if e.abs() <= TOL * (1.0 + rd) {
                return Some(distorted * (r / rd));
            }
            let slope = 1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3));
            if !slope.is_finite() || slope <= 0.0 {
                return None;
            }
            r -= e / slope;
        }
        None
    }

    /// Where Newton starts: the distorted point divided by [`Distortion::start_divisor`].
    #[inline]
    fn first_guess(&self, distorted: DVec2) -> DVec2 {
        distorted / self.start_divisor(distorted.length_squared())
    }

    /// The radial factor at the distorted radius² `rd2`, or 1 when it is not a plausible
    /// one (strong models far out). Dividing by it is one fixed-point step: off by
    /// O(k1² r⁵) instead of O(k1 r³), which saves one iteration of every ray's inversion.
    #[inline]
    fn start_divisor(&self, rd2: f64) -> f64 {
        let radial = self.radial(rd2);
        if (0.5..=2.0).contains(&radial) { radial } else { 1.0 }
    }

    /// Like [`Distortion::try_undistort`] but infallible for validated models: on
    /// non-convergence (only possible outside the validated field) returns the best
    /// estimate. This is what ray generation calls for every sample.
    #[inline]
    pub fn undistort(&self, distorted: DVec2) -> DVec2 {
        match self.try_undistort(distorted) {
            Ok(p) => p,
            Err(_) => self.undistort_best_effort(distorted),
        }
    }

    fn undistort_best_effort(&self, distorted: DVec2) -> DVec2 {
        // Fixed-point iteration (the classic OpenCV loop) as a fallback.
        let mut p = distorted;
        for _ in 0..MAX_ITER {
            let e = self.distort(p) - distorted;
            p -= e;
        }
        p
    }

    /// Pixel position (relative to the array's top-left corner, continuous) → distorted
    /// pixel position, for a camera with `focal_px` and principal point `(cx, cy)` in
    /// absolute pixel coordinates.
    pub fn distort_px(&self, ideal_px: DVec2, principal_px: DVec2, focal_px: f64) -> DVec2 {
        principal_px + self.distort((ideal_px - principal_px) / focal_px) * focal_px
    }

    /// Inverse of [`Distortion::distort_px`].
    pub fn undistort_px(&self, distorted_px: DVec2, principal_px: DVec2, focal_px: f64) -> DVec2 {
        principal_px + self.undistort((distorted_px - principal_px) / focal_px) * focal_px
    }

    /// Check that the model is usable over a field whose corners are at normalised
    /// radius `max_r` (e.g. the image diagonal / 2 / f, with a margin): coefficients
    /// finite, the forward map does not fold over (positive Jacobian), and `undistort`
    /// converges, on a polar grid covering the disc of radius `max_r`.
    pub fn validate(&self, max_r: f64) -> Result<(), DistortionError> {
        let c = [self.k1, self.k2, self.k3, self.p1, self.p2];
        if c.iter().any(|v| !v.is_finite()) {
            return Err(DistortionError::NotFinite);
        }
        if self.is_identity() {
            return Ok(());
        }
        const NR: usize = 64;
        const NA: usize = 64;
        for i in 0..=NR {
            let r = max_r * i as f64 / NR as f64;
            for j in 0..NA {
                let a = std::f64::consts::TAU * j as f64 / NA as f64;
                let p = DVec2::new(r * a.cos(), r * a.sin());
                let (cx, cy) = self.jacobian(p);
                let det = cx.x * cy.y - cy.x * cx.y;
                if det <= 0.0 || !det.is_finite() {
                    return Err(DistortionError::FoldsOver { x: p.x, y: p.y, det });
                }
                self.try_undistort(self.distort(p))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radial_inversion_agrees_with_the_2d_newton() {
        for d in [
            Distortion { k1: -0.08, k2: 0.01, ..Default::default() },
            Distortion { k1: 0.3, k2: -0.05, k3: 0.02, ..Default::default() },
            Distortion { k1: -0.25, ..Default::default() },
        ] {
            for i in -20..=20 {
                for j in -20..=20 {
                    let q = DVec2::new(f64::from(i), f64::from(j)) * 0.02;
                    let (radial, full) = (d.undistort_radial(q).expect("converges"), d.undistort_2d(q).unwrap());
                    // Both stop within TOL · (1 + |q|) of the point (the map's slope is ~1).
                    assert!((radial - full).length() < 4.0 * TOL, "{d:?} at {q}: {radial} vs {full}");
                    assert!((d.distort(radial) - q).length() <= 2.0 * TOL);
                }
            }
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let d = Distortion { k1: -0.3, k2: 0.1, k3: -0.02, p1: 1e-3, p2: -2e-3 };
        let p = DVec2::new(0.21, -0.13);
        let h = 1e-6;
        let (cx, cy) = d.jacobian(p);
        let fx = (d.distort(p + DVec2::X * h) - d.distort(p - DVec2::X * h)) / (2.0 * h);
        let fy = (d.distort(p + DVec2::Y * h) - d.distort(p - DVec2::Y * h)) / (2.0 * h);
        assert!((cx - fx).length() < 1e-8 && (cy - fy).length() < 1e-8);
    }

    #[test]
    fn identity_is_identity() {
        let d = Distortion::default();
        assert!(d.is_identity());
        let p = DVec2::new(0.3, -0.4);
        assert_eq!(d.distort(p), p);
        assert_eq!(d.undistort(p), p);
        assert!(d.validate(1.0).is_ok());
    }

    #[test]
    fn folding_model_is_rejected_by_validate() {
        // r(1 + k1 r²) has dr_d/dr = 1 + 3 k1 r² = 0 at r = 1/sqrt(3·0.5) ≈ 0.816.
        let d = Distortion { k1: -0.5, ..Default::default() };
        assert!(d.validate(0.5).is_ok());
        assert!(matches!(d.validate(1.0), Err(DistortionError::FoldsOver { .. })));
    }
}
