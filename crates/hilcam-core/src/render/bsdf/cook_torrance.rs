//! Cook-Torrance microfacet model for comparison with the paper's Table 2:
//! `f_r = ρd/π + k_s · D(h) G(wo, wi) F(wi·h) / (4 cosθo cosθi)` with
//! - D: Beckmann, `exp(−tan²θh/m²) / (π m² cos⁴θh)` (RMS slope m);
//! - G: separable Smith, `G1(wo) G1(wi)`, with Walter et al. 2007's rational
//!   approximation of the Beckmann Λ (`a = 1/(m tanθ)`);
//! - F: Schlick, `F0 + (1 − F0)(1 − wi·h)^5`.
//!
//! Reciprocal. Sampled by drawing `h` from `D(h) cosθh` (`tan²θh = −m² ln(1−u)`) mixed
//! with the cosine warp by one-sample MIS (see `mixture`).

use super::lobe::{Half, max_albedo, reflect, stratified_albedo};
use super::mixture::{self, SpecularLobe};
use super::{BsdfError, BsdfSample, check_finite_nonneg, check_unit};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

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
}

/// Cook-Torrance with a Lambertian diffuse term `ρd/π`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CookTorrance {
    /// Diffuse albedo ρd.
    pub rho_d: f32,
    /// The microfacet lobe, k_s already scaled by `normalization`.
    pub lobe: BeckmannLobe,
    /// Factor applied to k_s by [`CookTorrance::normalized`] (1 otherwise).
    pub normalization: f32,
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
        Ok(CookTorrance { rho_d, lobe: BeckmannLobe { m, f0, k_s }, normalization: 1.0 })
    }

    /// Energy-normalised variant: k_s scaled so the directional albedo is ≤ 1 everywhere.
    pub fn normalized(mut self) -> Self {
        let k = super::normalization_factor(self.rho_d, |c| self.spec_albedo(c, 48));
        self.lobe.k_s *= k;
        self.normalization *= k;
        self
    }

    /// Largest directional albedo over view angles (deterministic quadrature).
    pub fn max_albedo(&self) -> f32 {
        self.rho_d + max_albedo(|c| self.spec_albedo(c, 48))
    }

    fn spec_albedo(&self, cos_o: f32, n: u32) -> f32 {
        let l = self.lobe;
        stratified_albedo(cos_o, n, |o, u| l.sample(o, u), |o, i| l.eval_cos(o, i), |o, i| l.pdf(o, i))
    }

    /// `f_r`, finite (cosθi clamped to ≥ 1e-30 in the denominator).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        (self.rho_d * FRAC_1_PI + self.lobe.eval_cos(wo, wi) / wi.z.max(1e-30)).min(f32::MAX)
    }

    /// `f_r cosθi`.
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        mixture::eval_cos(self.rho_d, &self.lobe, wo, wi)
    }

    /// One-sample MIS of the Beckmann lobe and the cosine warp.
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        mixture::sample(self.rho_d, &self.lobe, wo, u, u_lobe)
    }

    /// Mixture density of [`CookTorrance::sample`].
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        mixture::pdf(self.rho_d, &self.lobe, wo, wi)
    }

    /// ρd + specular albedo at `cos_theta_o` (stratified quadrature of the lobe).
    pub fn directional_albedo(&self, cos_theta_o: f32, samples: u32) -> f32 {
        self.rho_d + self.spec_albedo(cos_theta_o, super::grid_side(samples))
    }
}
