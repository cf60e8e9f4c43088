//! Lambert: `f_r = ρ/π`, sampled with the cosine warp (pdf `cosθ/π`, so `f cos / pdf = ρ`).

use super::{BsdfError, BsdfSample, check_unit};
use crate::render::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// An ideal diffuse reflector with albedo ρ ∈ [0, 1] (the fraction of incident flux
/// reflected, at every incidence angle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Albedo ρ.
    pub rho: f32,
}

/// Where `f_r` is zero: `wo` or `wi` not strictly above the surface.
#[inline]
fn either_below(wo: Vec3, wi: Vec3) -> bool {
    wo.z <= 0.0 || wi.z <= 0.0
}

impl Lambert {
    /// # Errors
    /// [`BsdfError::Invalid`] naming `rho` unless 0 ≤ ρ ≤ 1.
    pub fn new(rho: f32) -> Result<Self, BsdfError> {
        check_unit("lambert", "rho", rho)?;
        Ok(Lambert { rho })
    }

    /// `f_r = ρ/π` above the surface, 0 otherwise.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if either_below(wo, wi) { 0.0 } else { self.rho * FRAC_1_PI }
    }

    /// `f_r cosθi / pdf` for a `wi` from the cosine warp: ρ above the surface (the cosines
    /// and π cancel, so no division and no rounding through them), 0 otherwise.
    #[inline]
    pub fn cosine_weight(&self, wo: Vec3, wi: Vec3) -> f32 {
        if either_below(wo, wi) { 0.0 } else { self.rho }
    }

    /// `ρ cosθi / π`.
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi) * wi.z.max(0.0)
    }

    /// Cosine-weighted sample; `None` only if the result is not strictly above the surface.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi.z);
        (wi.z > 0.0 && pdf > 0.0).then(|| BsdfSample { wi, f_cos: self.eval_cos(wo, wi), pdf })
    }

    /// `cosθi/π` above the surface.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 { 0.0 } else { cosine_hemisphere_pdf(wi.z) }
    }
}
