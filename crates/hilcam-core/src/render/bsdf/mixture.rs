//! Diffuse + specular: one-sample multiple importance sampling of the two lobes.
//!
//! One technique is chosen per sample with probability proportional to the parts'
//! estimated albedos (`p_s`, `1 − p_s`); the returned pdf is the mixture
//! `p_s · pdf_spec + (1 − p_s) · cosθi/π`, which is exactly the balance heuristic's
//! one-sample estimator `f / Σ_k p_k pdf_k` (Veach 1997, §9.2.4). It is unbiased as long as
//! the mixture pdf is positive wherever `f` is, which holds because the cosine technique
//! covers the whole hemisphere whenever `ρd > 0`, and the specular technique covers every
//! direction with a finite half vector when it is the only one.

use super::BsdfSample;
use crate::render::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// What the mixture needs from a specular lobe (local frame, n = +Z).
pub(crate) trait SpecularLobe {
    /// `f_s · cosθi`, finite, 0 outside the upper hemisphere.
    fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32;
    /// A direction from the lobe's sampler, `None` if it falls below the horizon.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3>;
    /// Solid-angle density of [`SpecularLobe::sample`].
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;
    /// Rough directional albedo, for the lobe-selection probability only.
    fn albedo_hint(&self, cos_o: f32) -> f32;
}

impl SpecularLobe for super::lobe::BlinnLobe {
    fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        super::lobe::BlinnLobe::eval_cos(self, wo, wi)
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        super::lobe::BlinnLobe::sample(self, wo, u)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        super::lobe::BlinnLobe::pdf(self, wo, wi)
    }
    fn albedo_hint(&self, cos_o: f32) -> f32 {
        super::lobe::BlinnLobe::albedo_hint(self, cos_o)
    }
}

/// Probability of choosing the specular technique for this `wo`.
#[inline]
fn spec_probability(rho_d: f32, lobe: &impl SpecularLobe, wo: Vec3) -> f32 {
    let ws = lobe.albedo_hint(wo.z).max(0.0);
    let wd = rho_d.max(0.0);
    if ws + wd <= 0.0 {
        return 0.0;
    }
    // Keep both techniques alive: a tiny floor on each costs nothing and protects the
    // estimator against a poor albedo hint (e.g. near grazing).
    (ws / (ws + wd)).clamp(if ws > 0.0 { 0.05 } else { 0.0 }, if wd > 0.0 { 0.95 } else { 1.0 })
}

/// `(ρd/π)·cosθi + f_s·cosθi`.
#[inline]
pub(crate) fn eval_cos(rho_d: f32, lobe: &impl SpecularLobe, wo: Vec3, wi: Vec3) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    rho_d * FRAC_1_PI * wi.z + lobe.eval_cos(wo, wi)
}

/// The mixture density of [`sample`].
#[inline]
pub(crate) fn pdf(rho_d: f32, lobe: &impl SpecularLobe, wo: Vec3, wi: Vec3) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let ps = spec_probability(rho_d, lobe, wo);
    let spec = if ps > 0.0 { lobe.pdf(wo, wi) } else { 0.0 };
    ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wi.z)
}

/// One-sample MIS: `u_lobe` picks the technique, `u` drives it.
#[inline]
pub(crate) fn sample(rho_d: f32, lobe: &impl SpecularLobe, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
    if wo.z <= 0.0 {
        return None;
    }
    let ps = spec_probability(rho_d, lobe, wo);
    if ps <= 0.0 && rho_d <= 0.0 {
        return None;
    }
    let wi = if u_lobe < ps { lobe.sample(wo, u)? } else { cosine_hemisphere(u) };
    if wi.z <= 0.0 {
        return None;
    }
    let pdf = pdf(rho_d, lobe, wo, wi);
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    Some(BsdfSample { wi, f_cos: eval_cos(rho_d, lobe, wo, wi), pdf })
}
