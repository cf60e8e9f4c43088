//! Blinn-Phong as the paper's Eq. (4): `f_r = ρd/π + ρs · (n·h)^α / (n·l)`.
//!
//! `l` is the direction toward the light (`wi`). The `1/(n·l)` makes `f_r` diverge at
//! grazing incidence, but `f_r · cosθi = ρd cosθi/π + ρs (n·h)^α` is bounded, and that
//! product is what [`BlinnPhong::eval_cos`] returns. It is Eq. (5) with `a = 1, b = 0`.
//! Not reciprocal (the `1/(n·l)` is not symmetric in `wo`, `wi`).

use super::lobe::{BlinnLobe, max_albedo, stratified_albedo};
use super::{BsdfError, BsdfSample, check_finite_nonneg, check_unit, mixture};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Eq. (4) with a Lambertian diffuse term `ρd/π` (ρd is the diffuse albedo).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlinnPhong {
    /// Diffuse albedo ρd (the Lambert term is ρd/π).
    pub rho_d: f32,
    /// The specular lobe (`a = 1`, `b = 0`), with ρs already scaled by `normalization`.
    pub lobe: BlinnLobe,
    /// Factor applied to ρs by [`BlinnPhong::normalized`] (1 for the model as given).
    pub normalization: f32,
}

impl BlinnPhong {
    /// Our least-squares fit of Eq. (4) to the paper's Eq. (5) gold-polyimide curves at
    /// θi = 30° and 60° (docs/brdf.md): `[ρd, ρs, α]`.
    pub const GOLD_POLYIMIDE_FIT: [f32; 3] = [0.3717, 269.39, 4138.6];

    /// # Errors
    /// [`BsdfError::Invalid`] naming the field: `rho_d ∈ [0,1]`, `rho_s ≥ 0`, `alpha ≥ 0`
    /// (all finite).
    pub fn new(rho_d: f32, rho_s: f32, alpha: f32) -> Result<Self, BsdfError> {
        check_unit("blinn_phong", "rho_d", rho_d)?;
        check_finite_nonneg("blinn_phong", "rho_s", rho_s)?;
        check_finite_nonneg("blinn_phong", "alpha", alpha)?;
        Ok(BlinnPhong { rho_d, lobe: BlinnLobe { rho_s, alpha, a: 1.0, b: 0.0 }, normalization: 1.0 })
    }

    /// The energy-normalised variant: ρs scaled by `min(1, (1 − ρd)/max_θo A_s(θo))` so
    /// that the directional albedo is ≤ 1 at every view angle.
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

    /// `f_r`; at grazing `wi` the `1/(n·l)` is evaluated with `n·l ≥ 1e-30` (finite).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        (self.rho_d * FRAC_1_PI + self.lobe.eval_cos(wo, wi) / wi.z.max(1e-30)).min(f32::MAX)
    }

    /// `f_r cosθi` as one bounded product.
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        mixture::eval_cos(self.rho_d, &self.lobe, wo, wi)
    }

    /// One-sample MIS of the Blinn lobe and the cosine warp.
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        mixture::sample(self.rho_d, &self.lobe, wo, u, u_lobe)
    }

    /// Mixture density of [`BlinnPhong::sample`].
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        mixture::pdf(self.rho_d, &self.lobe, wo, wi)
    }

    /// ρd + specular albedo at `cos_theta_o` (stratified quadrature of the lobe).
    pub fn directional_albedo(&self, cos_theta_o: f32, samples: u32) -> f32 {
        self.rho_d + self.spec_albedo(cos_theta_o, super::grid_side(samples))
    }
}
