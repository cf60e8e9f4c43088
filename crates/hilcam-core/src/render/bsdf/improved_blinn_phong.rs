//! The paper's improved Blinn-Phong, Eq. (5):
//! `f_r = ρd/π + ρs · (n·h)^α / (n·l)^a · exp(−b · (1 − n·h)^(1/π))`.
//!
//! With the paper's gold-polyimide fit (ρd 0.3717, ρs 283.9, α 3865.7, a 0.9665,
//! b 1.3965) the directional albedo is about 2 at normal incidence: the model is a curve
//! fit, not an energy-conserving BRDF. [`ImprovedBlinnPhong::normalized`] keeps the shape
//! and scales ρs so the albedo is ≤ 1 at every view angle. `(n·l)^-a` diverges at grazing
//! incidence, so `f_r cosθi` is evaluated as `… · cosθi^(1−a)` (bounded for a ≤ 1).
//! Not reciprocal: `(n·l)^-a` depends on `wi` alone.

use super::BsdfError;
use super::diffuse_lobe::DiffuseLobe;
use super::lobe::{BlinnLobe, pow_pos};
use super::{check_finite_nonneg, check_unit};
use glam::Vec3;

/// Eq. (5) with a Lambertian diffuse term `ρd/π` (ρd is the diffuse albedo). Sampling,
/// albedo and normalisation are [`DiffuseLobe`]'s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImprovedBlinnPhong(pub DiffuseLobe<BlinnLobe>);

impl std::ops::Deref for ImprovedBlinnPhong {
    type Target = DiffuseLobe<BlinnLobe>;
    fn deref(&self) -> &DiffuseLobe<BlinnLobe> {
        &self.0
    }
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
        Ok(ImprovedBlinnPhong(DiffuseLobe::new(rho_d, BlinnLobe { rho_s, alpha, a, b })))
    }

    /// The paper's gold-polyimide parameters.
    pub fn gold_polyimide() -> Self {
        let [rd, rs, al, a, b] = Self::GOLD_POLYIMIDE;
        Self::new(rd, rs, al, a, b).expect("paper parameters are valid")
    }

    /// The energy-normalised variant ([`DiffuseLobe::normalized`]: ρs scaled, shape
    /// unchanged).
    pub fn normalized(self) -> Self {
        ImprovedBlinnPhong(self.0.normalized())
    }

    /// `f_r`; at grazing `wi`, `(n·l)^-a` is evaluated with `n·l ≥ 1e-30` (finite).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        // The lobe gives ρs·shape·cos^(1−a).
        self.0.eval_with(wo, wi, |spec_cos, cos_i| spec_cos * pow_pos(cos_i, -1.0))
    }
}
