//! Blinn-Phong as the paper's Eq. (4): `f_r = ρd/π + ρs · (n·h)^α / (n·l)`.
//!
//! `l` is the direction toward the light (`wi`). The `1/(n·l)` makes `f_r` diverge at
//! grazing incidence, but `f_r · cosθi = ρd cosθi/π + ρs (n·h)^α` is bounded, and that
//! product is what [`BlinnPhong::eval_cos`] returns. It is Eq. (5) with `a = 1, b = 0`.
//! Not reciprocal (the `1/(n·l)` is not symmetric in `wo`, `wi`).

use super::BsdfError;
use super::diffuse_lobe::DiffuseLobe;
use super::lobe::BlinnLobe;
use super::{check_finite_nonneg, check_unit};

/// Eq. (4) with a Lambertian diffuse term `ρd/π` (ρd is the diffuse albedo); the specular
/// lobe has `a = 1`, `b = 0`. Sampling, albedo and normalisation are [`DiffuseLobe`]'s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlinnPhong(pub DiffuseLobe<BlinnLobe>);

impl std::ops::Deref for BlinnPhong {
    type Target = DiffuseLobe<BlinnLobe>;
    fn deref(&self) -> &DiffuseLobe<BlinnLobe> {
        &self.0
    }
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
        Ok(BlinnPhong(DiffuseLobe::new(rho_d, BlinnLobe { rho_s, alpha, a: 1.0, b: 0.0 })))
    }

    /// The energy-normalised variant ([`DiffuseLobe::normalized`]: ρs scaled).
    pub fn normalized(self) -> Self {
        BlinnPhong(self.0.normalized())
    }
}
