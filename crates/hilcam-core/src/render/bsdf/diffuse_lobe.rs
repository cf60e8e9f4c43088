//! A Lambertian diffuse term plus one specular lobe, `f_r = ρd/π + f_s`: the shape of
//! Blinn-Phong, the improved Blinn-Phong and Cook-Torrance, which differ only in the lobe
//! (and in how `f_r` alone is formed, for plots).
//!
//! Sampled by one-sample multiple importance sampling of the two parts: one technique is
//! chosen per sample with probability proportional to the parts' estimated albedos (`p_s`,
//! `1 − p_s`); the returned pdf is the mixture `p_s · pdf_spec + (1 − p_s) · cosθi/π`,
//! which is exactly the balance heuristic's one-sample estimator `f / Σ_k p_k pdf_k`
//! (Veach 1997, §9.2.4). It is unbiased as long as the mixture pdf is positive wherever
//! `f` is, which holds because the cosine technique covers the whole hemisphere whenever
//! `ρd > 0`, and the specular technique covers every direction with a finite half vector
//! when it is the only one.

use super::BsdfSample;
use super::lobe::{max_albedo, stratified_albedo};
use crate::render::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// What the diffuse-plus-lobe BRDF needs from a specular lobe (local frame, n = +Z).
pub trait SpecularLobe: Copy {
    /// `f_s · cosθi`, finite, 0 outside the upper hemisphere.
    fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32;
    /// A direction from the lobe's sampler, `None` if it falls below the horizon.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3>;
    /// Solid-angle density of [`SpecularLobe::sample`].
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;
    /// Rough directional albedo, for the lobe-selection probability only.
    fn albedo_hint(&self, cos_o: f32) -> f32;
    /// Multiply the lobe's scale (ρs, k_s) by `k`.
    fn scale(&mut self, k: f32);
    /// True if the lobe's scale is zero (it reflects nothing).
    fn is_black(&self) -> bool;
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
    fn scale(&mut self, k: f32) {
        self.rho_s *= k;
    }
    fn is_black(&self) -> bool {
        self.rho_s == 0.0
    }
}

/// `ρd/π` plus the specular lobe `L`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseLobe<L> {
    /// Diffuse albedo ρd (the Lambert term is ρd/π).
    pub rho_d: f32,
    /// The specular lobe, its scale already multiplied by `normalization`.
    pub lobe: L,
    /// Factor applied to the lobe's scale by [`DiffuseLobe::normalized`] (1 for the model
    /// as given).
    pub normalization: f32,
}

impl<L: SpecularLobe> DiffuseLobe<L> {
    /// `ρd/π` plus `lobe`, as given (not normalised).
    pub fn new(rho_d: f32, lobe: L) -> Self {
        DiffuseLobe { rho_d, lobe, normalization: 1.0 }
    }

    /// The energy-normalised variant: the lobe's scale multiplied by
    /// `min(1, (1 − ρd)/max_θo A_s(θo))` so that the directional albedo is ≤ 1 at every
    /// view angle (shape unchanged).
    pub fn normalized(mut self) -> Self {
        let k = super::normalization_factor(self.rho_d, |c| self.spec_albedo(c, 48));
        self.lobe.scale(k);
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

    /// ρd + specular albedo at `cos_theta_o` (stratified quadrature of the lobe).
    pub fn directional_albedo(&self, cos_theta_o: f32, samples: u32) -> f32 {
        self.rho_d + self.spec_albedo(cos_theta_o, super::grid_side(samples))
    }

    /// True if `f_r` is zero everywhere.
    pub fn is_black(&self) -> bool {
        self.rho_d == 0.0 && self.lobe.is_black()
    }

    /// `Some(ρd)` when the lobe reflects nothing (`f_r = ρd/π`).
    pub fn lambertian(&self) -> Option<f32> {
        self.lobe.is_black().then_some(self.rho_d)
    }

    /// `f_r`, with `f_s = f_s cosθi / cosθi` and cosθi clamped to ≥ 1e-30 (finite).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_with(wo, wi, |spec_cos, cos_i| spec_cos / cos_i)
    }

    /// `f_r` with `f_s` formed from `f_s cosθi` and the clamped cosθi by `spec`, 0 unless
    /// both directions are above the surface.
    pub(crate) fn eval_with(&self, wo: Vec3, wi: Vec3, spec: impl Fn(f32, f32) -> f32) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        (self.rho_d * FRAC_1_PI + spec(self.lobe.eval_cos(wo, wi), wi.z.max(1e-30))).min(f32::MAX)
    }

    /// `(ρd/π)·cosθi + f_s·cosθi`, one bounded product.
    #[inline]
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        self.rho_d * FRAC_1_PI * wi.z + self.lobe.eval_cos(wo, wi)
    }

    /// Probability of choosing the specular technique for this `wo`.
    #[inline]
    fn spec_probability(&self, wo: Vec3) -> f32 {
        spec_share(self.lobe.albedo_hint(wo.z), self.rho_d)
    }

    /// The mixture density of [`DiffuseLobe::sample`].
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        mixture_pdf(self.spec_probability(wo), || self.lobe.pdf(wo, wi), wi.z)
    }

    /// One-sample MIS of the lobe and the cosine warp: `u_lobe` picks the technique, `u`
    /// drives it.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let ps = self.spec_probability(wo);
        if ps <= 0.0 && self.rho_d <= 0.0 {
            return None;
        }
        let wi = if u_lobe < ps { self.lobe.sample(wo, u)? } else { cosine_hemisphere(u) };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(BsdfSample { wi, f_cos: self.eval_cos(wo, wi), pdf })
    }
}

/// The probability of the specular technique in a one-sample mixture of a lobe (weight
/// `ws`) and the cosine warp (weight `wd`). Both techniques stay alive: a small floor on
/// each costs nothing and protects the estimator against a poor weight (e.g. an albedo
/// hint near grazing).
#[inline]
pub(super) fn spec_share(ws: f32, wd: f32) -> f32 {
    let (ws, wd) = (ws.max(0.0), wd.max(0.0));
    if ws + wd <= 0.0 {
        return 0.0;
    }
    (ws / (ws + wd)).clamp(if ws > 0.0 { 0.05 } else { 0.0 }, if wd > 0.0 { 0.95 } else { 1.0 })
}

/// The mixture's density at `wi` (cosine `wi_z`), the lobe's density `spec_pdf` evaluated
/// only when its technique can be picked (`ps` > 0).
#[inline]
pub(super) fn mixture_pdf(ps: f32, spec_pdf: impl FnOnce() -> f32, wi_z: f32) -> f32 {
    let spec = if ps > 0.0 { spec_pdf() } else { 0.0 };
    ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wi_z)
}
