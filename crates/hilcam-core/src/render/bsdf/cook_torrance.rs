//! Cook-Torrance microfacet model for comparison with the paper's Table 2:
//! `f_r = ρd/π + k_s · D(h) G(wo, wi) F(wi·h) / (4 cosθo cosθi)` with
//! - D: Beckmann, `exp(−tan²θh/m²) / (π m² cos⁴θh)` (RMS slope m);
//! - G: separable Smith, `G1(wo) G1(wi)`, with Walter et al. 2007's rational
//!   approximation of the Beckmann Λ (`a = 1/(m tanθ)`);
//! - F: Schlick, `F0 + (1 − F0)(1 − wi·h)^5`.
//!
//! Reciprocal. Sampled by drawing `h` from `D(h) cosθh` (`tan²θh = −m² ln(1−u)`) mixed
//! with the cosine warp by one-sample MIS (see `diffuse_lobe`).

use super::diffuse_lobe::{DiffuseLobe, SpecularLobe};
use super::lobe::{Half, reflect};
use super::{BsdfError, check_finite_nonneg, check_unit};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The Beckmann/Smith/Schlick specular lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeckmannLobe {
    /// Beckmann RMS slope m (roughness), 1e-3 ≤ m ≤ 1.
    pub m: f32,
    /// Fresnel reflectance at normal incidence, [0, 1].
    pub f0: f32,
    /// Specular scale k_s ≥ 0 (1 = a physical microfacet surface).
    pub k_s: f32,
}

impl BeckmannLobe {
    /// Beckmann normal distribution from the half vector.
    #[inline]
    fn d(&self, hv: &Half) -> f32 {
        let cos2 = hv.cos * hv.cos;
        let tan2 = hv.sin2 / cos2;
        let e = tan2 / (self.m * self.m);
        if e.is_nan() || e >= 80.0 {
            return 0.0; // exp(−80) ≈ 2e−35: below anything that matters, avoids 0/0
        }
        (-e).exp() / (PI * self.m * self.m * cos2 * cos2)
    }

    /// Smith G1 for Beckmann, Walter et al. 2007 eq. (27).
    #[inline]
    fn g1(&self, v: Vec3) -> f32 {
        let sin = (v.x * v.x + v.y * v.y).sqrt();
        if sin == 0.0 {
            return 1.0;
        }
        let a = v.z / (self.m * sin);
        if a >= 1.6 { 1.0 } else { (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a) }
    }

    #[inline]
    fn fresnel(&self, cos_d: f32) -> f32 {
        let c = (1.0 - cos_d).clamp(0.0, 1.0);
        let c2 = c * c;
        self.f0 + (1.0 - self.f0) * c2 * c2 * c
    }
}

impl SpecularLobe for BeckmannLobe {
    fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        let Some(hv) = Half::new(wo, wi) else {
            return 0.0;
        };
        let d = self.d(&hv);
        if d == 0.0 {
            return 0.0;
        }
        // DGF/(4 cosθo cosθi) · cosθi: G1(wo) ∝ cosθo at grazing, so the ratio is finite.
        self.k_s * d * self.g1(wo) * self.g1(wi) * self.fresnel(hv.wo_dot_h) / (4.0 * wo.z)
    }

    fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let tan2 = -self.m * self.m * (1.0 - u.x).ln();
        let cos = 1.0 / (1.0 + tan2).sqrt();
        let sin = (tan2 / (1.0 + tan2)).sqrt();
        let phi = 2.0 * PI * u.y;
        let h = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos);
        let wi = reflect(wo, h);
        (wi.z > 0.0).then(|| wi.normalize())
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let Some(hv) = Half::new(wo, wi) else {
            return 0.0;
        };
        (self.d(&hv) * hv.cos / (4.0 * hv.wo_dot_h)).min(f32::MAX)
    }

    fn albedo_hint(&self, cos_o: f32) -> f32 {
        self.k_s * self.fresnel(cos_o.clamp(0.0, 1.0))
    }

    fn scale(&mut self, k: f32) {
        self.k_s *= k;
    }

    fn is_black(&self) -> bool {
        self.k_s == 0.0
    }
}

/// Cook-Torrance with a Lambertian diffuse term `ρd/π`. Sampling, albedo and
/// normalisation are [`DiffuseLobe`]'s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CookTorrance(pub DiffuseLobe<BeckmannLobe>);

impl std::ops::Deref for CookTorrance {
    type Target = DiffuseLobe<BeckmannLobe>;
    fn deref(&self) -> &DiffuseLobe<BeckmannLobe> {
        &self.0
    }
}

impl CookTorrance {
    /// Our least-squares fit to the paper's Eq. (5) gold-polyimide curves at θi = 30° and
    /// 60° (docs/brdf.md): `[ρd, m, F0, k_s]`.
    pub const GOLD_POLYIMIDE_FIT: [f32; 4] = [0.3717, 0.02201, 0.8734, 1.0];

    /// # Errors
    /// [`BsdfError::Invalid`] naming the field: `rho_d, f0 ∈ [0,1]`, `1e-3 ≤ m ≤ 1`,
    /// `k_s ≥ 0`; all finite.
    pub fn new(rho_d: f32, m: f32, f0: f32, k_s: f32) -> Result<Self, BsdfError> {
        const M: &str = "cook_torrance";
        check_unit(M, "rho_d", rho_d)?;
        check_unit(M, "f0", f0)?;
        check_finite_nonneg(M, "k_s", k_s)?;
        if !(1e-3..=1.0).contains(&m) {
            return Err(BsdfError::Invalid {
                model: M,
                field: "roughness",
                value: m,
                reason: "must be in [0.001, 1] (Beckmann RMS slope)",
            });
        }
        Ok(CookTorrance(DiffuseLobe::new(rho_d, BeckmannLobe { m, f0, k_s })))
    }

    /// Energy-normalised variant ([`DiffuseLobe::normalized`]: k_s scaled).
    pub fn normalized(self) -> Self {
        CookTorrance(self.0.normalized())
    }
}
