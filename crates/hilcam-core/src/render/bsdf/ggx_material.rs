//! GGX materials: a rough conductor, a rough plastic (a rough dielectric coating over a
//! Lambert base) and glTF's metallic-roughness blend of the two, one type:
//!
//! `f_r = D G F(wi·h) / (4 cosθo cosθi) + (1 − m) ρ (1 − E(cosθi))(1 − E(cosθo)) / (π (1 − Ē))`
//!
//! with `F = m F_conductor + (1 − m) F_dielectric(η)` and `m` the metallic weight (1: a
//! conductor, 0: a plastic). `E` is the coating's directional albedo and `Ē` its mean
//! ([`CoatingAlbedo`]): the base receives `1 − E(cosθi)` of the light, scatters it as
//! Lambert ρ, and `1 − E(cosθo)` leaves toward the viewer, normalised so that a white base
//! under a white furnace returns exactly 1. Both terms are reciprocal. A plastic may instead
//! take Mitsuba 3's `roughplastic` coupling ([`Coupling::Mitsuba`], in `coating`).
//!
//! Sampled like the other lobe models (`diffuse_lobe`): one-sample MIS (balance heuristic)
//! of GGX visible-normal sampling and the cosine warp, chosen by estimated albedos.

use super::coating::{CoatingAlbedo, Coupling};
use super::coating_family::CoatingFamily;
use super::diffuse_lobe::{mixture_pdf, spec_share};
use super::fresnel::{ConductorFresnel, dielectric};
use super::ggx::{GgxDistribution, MIN_ALPHA};
use super::lobe::stratified_albedo;
use super::{BsdfError, BsdfSample, check_unit};
use crate::render::sampling::cosine_hemisphere;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Index of refraction of glTF 2.0's dielectric (its F0 = 0.04).
pub const GLTF_DIELECTRIC_IOR: f32 = 1.5;

/// A GGX conductor, plastic, or their metallic-weighted blend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// The microfacet distribution (α = roughness²).
    pub dist: GgxDistribution,
    /// Weight `m` of the conductor, [0, 1] (glTF's `metallicFactor`).
    pub metallic: f32,
    /// The conductor's Fresnel reflectance (used where `metallic > 0`).
    pub conductor: ConductorFresnel,
    /// Albedo ρ of the Lambert base under the coating (used where `metallic < 1`).
    pub rho: f32,
    /// Index of refraction η of the coating.
    pub eta: f32,
    /// The coating's albedo table (only where a base shows through it).
    coating: CoatingAlbedo,
}

fn check_roughness(model: &'static str, roughness: f32) -> Result<GgxDistribution, BsdfError> {
    let alpha = roughness * roughness;
    if roughness.is_finite() && (MIN_ALPHA..=1.0).contains(&alpha) && roughness > 0.0 {
        Ok(GgxDistribution { alpha })
    } else {
        Err(BsdfError::Invalid {
            model,
            field: "roughness",
            value: roughness,
            reason: "must be in [0.01, 1] (GGX α = roughness²)",
        })
    }
}

fn check_conductor(model: &'static str, f: ConductorFresnel) -> Result<ConductorFresnel, BsdfError> {
    match f {
        ConductorFresnel::Schlick { f0 } => check_unit(model, "f0", f0)?,
        ConductorFresnel::Complex { n, k } => {
            for (field, v) in [("n", n), ("k", k)] {
                if !(v.is_finite() && (0.0..=100.0).contains(&v)) {
                    return Err(BsdfError::Invalid { model, field, value: v, reason: "must be in [0, 100]" });
                }
            }
            if n == 0.0 && k == 0.0 {
                return Err(BsdfError::Invalid { model, field: "n", value: n, reason: "and k cannot both be 0" });
            }
        }
    }
    Ok(f)
}

fn check_eta(model: &'static str, eta: f32) -> Result<f32, BsdfError> {
    if eta.is_finite() && (1.0..=4.0).contains(&eta) {
        Ok(eta)
    } else {
        Err(BsdfError::Invalid { model, field: "ior", value: eta, reason: "must be in [1, 4]" })
    }
}

impl Ggx {
    /// A rough conductor: `D G F / (4 cosθo cosθi)`, no diffuse term.
    ///
    /// # Errors
    /// [`BsdfError::Invalid`] naming `roughness` (α = roughness² in [1e-4, 1]), `f0`, `n`
    /// or `k`.
    pub fn conductor(roughness: f32, fresnel: ConductorFresnel) -> Result<Self, BsdfError> {
        const M: &str = "ggx_conductor";
        Ggx::build(
            check_roughness(M, roughness)?,
            1.0,
            check_conductor(M, fresnel)?,
            0.0,
            GLTF_DIELECTRIC_IOR,
            Coupling::Energy,
        )
    }

    /// A rough plastic: a GGX dielectric coating of index `ior` over Lambert `rho`.
    ///
    /// # Errors
    /// [`BsdfError::Invalid`] naming `roughness`, `rho` ∈ [0, 1] or `ior` ∈ [1, 4].
    pub fn plastic(roughness: f32, rho: f32, ior: f32) -> Result<Self, BsdfError> {
        Ggx::plastic_coupled(roughness, rho, ior, Coupling::Energy)
    }

    /// [`Ggx::plastic`] with the base coupled to the coating as `coupling` says
    /// ([`Coupling::Mitsuba`]: Mitsuba 3's `roughplastic`).
    ///
    /// # Errors
    /// As [`Ggx::plastic`].
    pub fn plastic_coupled(roughness: f32, rho: f32, ior: f32, coupling: Coupling) -> Result<Self, BsdfError> {
        const M: &str = "ggx_plastic";
        check_unit(M, "rho", rho)?;
        let eta = check_eta(M, ior)?;
        Ggx::build(check_roughness(M, roughness)?, 0.0, ConductorFresnel::Schlick { f0: 0.0 }, rho, eta, coupling)
    }

    /// glTF 2.0's metallic-roughness material at one band: the conductor with Schlick
    /// `F0 = base` weighted by `metallic`, the plastic with base `base` and η 1.5 by
    /// `1 − metallic`.
    ///
    /// # Errors
    /// [`BsdfError::Invalid`] naming `roughness`, `base_color` or `metallic`.
    pub fn metallic_roughness(base: f32, metallic: f32, roughness: f32) -> Result<Self, BsdfError> {
        Ggx::blend(base, metallic, roughness, GLTF_DIELECTRIC_IOR)
    }

    /// [`Ggx::metallic_roughness`] with the dielectric's index `ior` (the MTL PBR
    /// extension's `Ni`).
    ///
    /// # Errors
    /// [`BsdfError::Invalid`] naming `roughness`, `base_color`, `metallic` or `ior`.
    pub fn blend(base: f32, metallic: f32, roughness: f32, ior: f32) -> Result<Self, BsdfError> {
        const M: &str = "ggx_metallic_roughness";
        check_unit(M, "base_color", base)?;
        check_unit(M, "metallic", metallic)?;
        let dist = check_roughness(M, roughness)?;
        Ggx::build(dist, metallic, ConductorFresnel::Schlick { f0: base }, base, check_eta(M, ior)?, Coupling::Energy)
    }

    fn build(
        dist: GgxDistribution,
        metallic: f32,
        conductor: ConductorFresnel,
        rho: f32,
        eta: f32,
        coupling: Coupling,
    ) -> Result<Self, BsdfError> {
        let base_shows = metallic < 1.0 && rho > 0.0;
        let coating = if base_shows { CoatingAlbedo::coupled(dist, eta, coupling) } else { CoatingAlbedo::NONE };
        Ok(Ggx { dist, metallic, conductor, rho, eta, coating })
    }

    /// This material where textures give its roughness (α = roughness², at least the
    /// smoothest GGX) and metallic weight (glTF's `metallicRoughnessTexture`, MTL
    /// `map_Pr`/`map_Pm`); with a `family` (the material's textures need one) the coating
    /// comes from it at the hit's roughness.
    #[inline]
    pub fn with_roughness_metallic(
        &self,
        roughness: Option<f32>,
        metallic: Option<f32>,
        family: Option<&CoatingFamily>,
    ) -> Ggx {
        let mut g = *self;
        if let Some(m) = metallic {
            g.metallic = m.clamp(0.0, 1.0);
        }
        if let Some(r) = roughness {
            g.dist = GgxDistribution { alpha: (r * r).clamp(MIN_ALPHA, 1.0) };
        }
        if let Some(f) = family {
            g.coating = f.at(g.dist.alpha.sqrt());
        }
        g
    }

    /// Scene-file model name.
    pub fn model_name(&self) -> &'static str {
        if self.metallic == 1.0 {
            "ggx_conductor"
        } else if self.metallic == 0.0 {
            "ggx_plastic"
        } else {
            "ggx_metallic_roughness"
        }
    }

    /// The blended Fresnel reflectance at `cos` = wi·h.
    #[inline]
    fn fresnel(&self, cos: f32) -> f32 {
        let m = self.metallic;
        let c = if m > 0.0 { m * self.conductor.eval(cos) } else { 0.0 };
        let d = if m < 1.0 { (1.0 - m) * dielectric(cos, self.eta) } else { 0.0 };
        c + d
    }

    /// Weight of the base's diffuse term per unit `cosθi/π`, as a function of `cosθo`.
    #[inline]
    fn diffuse_factor(&self, cos_o: f32) -> f32 {
        if self.metallic >= 1.0 || self.rho == 0.0 {
            return 0.0;
        }
        (1.0 - self.metallic) * self.rho * self.coating.transmitted(cos_o) / self.coating.norm
    }

    /// The specular term `D G F / (4 cosθo cosθi) · cosθi`.
    #[inline]
    fn spec_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.dist.eval_cos_no_fresnel(wo, wi).map_or(0.0, |(v, c)| v * self.fresnel(c))
    }

    /// `f_r · cosθi` as one finite product; 0 unless both directions are above the surface.
    #[inline]
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let diffuse = self.diffuse_factor(wo.z) * self.coating.transmitted(wi.z) * FRAC_1_PI * wi.z;
        self.spec_cos(wo, wi) + diffuse
    }

    /// `f_r`, with cosθi clamped to ≥ 1e-30 (finite).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        (self.eval_cos(wo, wi) / wi.z.max(1e-30)).min(f32::MAX)
    }

    /// Probability of drawing from the GGX visible normals rather than the cosine warp.
    #[inline]
    fn spec_probability(&self, wo: Vec3) -> f32 {
        spec_share(self.fresnel(wo.z), self.diffuse_factor(wo.z))
    }

    /// The mixture density of [`Ggx::sample`].
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        mixture_pdf(self.spec_probability(wo), || self.dist.pdf(wo, wi), wi.z)
    }

    /// One-sample MIS of visible-normal sampling and the cosine warp: `u_lobe` picks the
    /// technique, `u` drives it.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let ps = self.spec_probability(wo);
        let wi = if u_lobe < ps { self.dist.sample(wo, u)? } else { cosine_hemisphere(u) };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(BsdfSample { wi, f_cos: self.eval_cos(wo, wi), pdf })
    }

    /// Directional albedo: the specular part by a stratified `√samples²` visible-normal
    /// quadrature, the diffuse part exactly (`(1 − m) ρ (1 − E(cosθo))`, by construction).
    pub fn directional_albedo(&self, cos_theta_o: f32, samples: u32) -> f32 {
        if cos_theta_o <= 0.0 {
            return 0.0;
        }
        let d = self.dist;
        let spec = stratified_albedo(
            cos_theta_o,
            super::grid_side(samples),
            |o, u| d.sample(o, u),
            |o, i| self.spec_cos(o, i),
            |o, i| d.pdf(o, i),
        );
        spec + self.diffuse_factor(cos_theta_o) * self.coating.t_mean
    }
}
