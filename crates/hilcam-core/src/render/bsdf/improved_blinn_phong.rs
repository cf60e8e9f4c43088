//! The paper's improved Blinn-Phong, Eq. (5):
//! `f_r = ρd/π + ρs · (n·h)^α / (n·l)^a · exp(−b · (1 − n·h)^(1/π))`.
//!
//! With the paper's gold-polyimide fit (ρd 0.3717, ρs 283.9, α 3865.7, a 0.9665,
//! b 1.3965) the directional albedo is about 2 at normal incidence: the model is a curve
//! fit, not an energy-conserving BRDF. [`ImprovedBlinnPhong::normalized`] keeps the shape
//! and scales ρs so the albedo is ≤ 1 at every view angle. `(n·l)^-a` diverges at grazing
//! incidence, so `f_r cosθi` is evaluated as `… · cosθi^(1−a)` (bounded for a ≤ 1).
//! Not reciprocal: `(n·l)^-a` depends on `wi` alone.

use super::lobe::{BlinnLobe, max_albedo, pow_pos, stratified_albedo};
use super::{BsdfError, BsdfSample, check_finite_nonneg, check_unit, mixture};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Eq. (5) with a Lambertian diffuse term `ρd/π` (ρd is the diffuse albedo).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImprovedBlinnPhong {
    /// Diffuse albedo ρd (the Lambert term is ρd/π).
    pub rho_d: f32,
    /// The specular lobe, with ρs already scaled by `normalization`.
    pub lobe: BlinnLobe,
    /// Factor applied to ρs by [`ImprovedBlinnPhong::normalized`] (1 for the paper's model).
    pub normalization: f32,
}

impl ImprovedBlinnPhong {
    /// The paper's fit to gold polyimide (Sun & Ding 2023, §3.3).
    pub const GOLD_POLYIMIDE: [f32; 5] = [0.3717, 283.9, 3865.7, 0.9665, 1.3965];

    /// # Errors
    /// [`BsdfError::Invalid`] naming the field: `rho_d ∈ [0,1]`, `rho_s ≥ 0`, `alpha ≥ 0`,
    /// `a ∈ [0,1]` (for a > 1, `f_r cosθi ∝ cosθi^(1−a)` is unbounded at grazing
    /// incidence), `b ≥ 0`; all finite.
    pub fn new(rho_d: f32, rho_s: f32, alpha: f32, a: f32, b: f32) -> Result<Self, BsdfError> {
        const M: &str = "improved_blinn_phong";
        check_unit(M, "rho_d", rho_d)?;
        check_finite_nonneg(M, "rho_s", rho_s)?;
        check_finite_nonneg(M, "alpha", alpha)?;
        check_unit(M, "a", a)?;
        check_finite_nonneg(M, "b", b)?;
        Ok(ImprovedBlinnPhong { rho_d, lobe: BlinnLobe { rho_s, alpha, a, b }, normalization: 1.0 })
    }

    /// The paper's gold-polyimide parameters.
    pub fn gold_polyimide() -> Self {
        let [rd, rs, al, a, b] = Self::GOLD_POLYIMIDE;
        Self::new(rd, rs, al, a, b).expect("paper parameters are valid")
    }

    /// The energy-normalised variant: ρs scaled by `min(1, (1 − ρd)/max_θo A_s(θo))` so
    /// that the directional albedo is ≤ 1 at every view angle (shape unchanged).
    pub fn normalized(mut self) -> Self {
        let k = super::normalization_factor(self.rho_d, |c| self.spec_albedo(c, 48));
        self.lobe.rho_s *= k;
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

    /// `f_r`; at grazing `wi`, `(n·l)^-a` is evaluated with `n·l ≥ 1e-30` (finite).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let spec_cos = self.lobe.eval_cos(wo, wi); // ρs·shape·cos^(1−a)
        let spec = spec_cos * pow_pos(wi.z.max(1e-30), -1.0);
        (self.rho_d * FRAC_1_PI + spec).min(f32::MAX)
    }

    /// `f_r cosθi` as one bounded product.
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        mixture::eval_cos(self.rho_d, &self.lobe, wo, wi)
    }

    /// One-sample MIS of the Blinn lobe and the cosine warp.
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        mixture::sample(self.rho_d, &self.lobe, wo, u, u_lobe)
    }

    /// Mixture density of [`ImprovedBlinnPhong::sample`].
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        mixture::pdf(self.rho_d, &self.lobe, wo, wi)
    }

    /// ρd + specular albedo at `cos_theta_o` (stratified quadrature of the lobe).
    pub fn directional_albedo(&self, cos_theta_o: f32, samples: u32) -> f32 {
        self.rho_d + self.spec_albedo(cos_theta_o, super::grid_side(samples))
    }
}
