//! BRDF models: Lambert, Blinn-Phong (the paper's Eq. 4), the paper's improved
//! Blinn-Phong (Eq. 5), Cook-Torrance (Beckmann) and the GGX conductor / plastic /
//! metallic-roughness models ([`Ggx`]), behind one closed [`Bsdf`] enum.
//!
//! Conventions (all models):
//! - Vectors are unit and in the **local shading frame**, normal = +Z. `wo` points toward
//!   the viewer / previous path vertex, `wi` toward the light / next vertex. The
//!   integrator flips the normal of two-sided surfaces so that `wo.z ≥ 0`.
//! - Monochrome: one band, `f_r` in sr⁻¹.
//! - **ρd is a diffuse albedo**: the diffuse term is `ρd/π`, not the `ρd` the paper writes
//!   in Eq. (4)/(5). Read literally, the paper's gold-polyimide ρd = 0.3717 sr⁻¹ alone
//!   would reflect π·0.3717 = 1.17 of the incident flux; the paper also uses the same
//!   number as the "reflectance" of its Lambertian fold planes (§3.2). See docs/brdf.md.
//! - `eval_cos` returns `f_r · cosθi` as one finite product: models whose `f_r` has a
//!   `1/(n·l)^a` factor never form the divergent `f_r` first.
//! - `sample` draws `wi` by importance sampling the BRDF (for the lobe models: one-sample
//!   MIS of the specular lobe and the cosine warp, balance heuristic); `pdf` is its
//!   solid-angle density, so `f_cos / pdf` is an unbiased weight.

mod blinn_phong;
mod coating;
mod coating_family;
mod cook_torrance;
mod diffuse_lobe;
pub mod fresnel;
mod ggx;
mod ggx_material;
mod improved_blinn_phong;
mod lambert;
pub(crate) mod lobe;
mod spec;

pub use blinn_phong::BlinnPhong;
pub use coating::Coupling;
pub use coating_family::CoatingFamily;
pub use cook_torrance::{BeckmannLobe, CookTorrance};
pub use diffuse_lobe::{DiffuseLobe, SpecularLobe};
pub use fresnel::{ConductorFresnel, Metal};
pub use ggx::GgxDistribution;
pub use ggx_material::{GLTF_DIELECTRIC_IOR, Ggx};
pub use improved_blinn_phong::ImprovedBlinnPhong;
pub use lambert::Lambert;
pub use lobe::BlinnLobe;
pub use spec::{BsdfSpec, Preset};

use glam::{Vec2, Vec3};

/// A sampled incident direction with its weight's two factors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled direction toward the light / next vertex (local frame, unit, `wi.z > 0`).
    pub wi: Vec3,
    /// `f_r(wo, wi) · cosθi` (finite).
    pub f_cos: f32,
    /// Solid-angle density of `wi` (finite, > 0); equals [`Bsdf::pdf`] at `wi`.
    pub pdf: f32,
}

/// Invalid BRDF parameters; names the model and the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BsdfError {
    /// A parameter is out of its range.
    #[error("material model `{model}`: field `{field}` = {value} {reason}")]
    Invalid { model: &'static str, field: &'static str, value: f32, reason: &'static str },
    /// A parameter has neither an explicit value nor a preset to take it from.
    #[error("material model `{model}`: field `{field}` is required (or give a `preset`)")]
    Missing { model: &'static str, field: &'static str },
}

/// A surface's BRDF (closed set, enum dispatch).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    Lambert(Lambert),
    BlinnPhong(BlinnPhong),
    ImprovedBlinnPhong(ImprovedBlinnPhong),
    CookTorrance(CookTorrance),
    Ggx(Ggx),
}

macro_rules! dispatch {
    ($self:ident, $b:ident => $e:expr) => {
        match $self {
            Bsdf::Lambert($b) => $e,
            Bsdf::BlinnPhong($b) => $e,
            Bsdf::ImprovedBlinnPhong($b) => $e,
            Bsdf::CookTorrance($b) => $e,
            Bsdf::Ggx($b) => $e,
        }
    };
}

impl Bsdf {
    /// `f_r(wo, wi)` in sr⁻¹ (for plots and tests); finite, 0 unless both are above the
    /// surface. Prefer [`Bsdf::eval_cos`] in estimators.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.eval(wo, wi))
    }

    /// `f_r(wo, wi) · cosθi` as one finite product; 0 if `wi.z ≤ 0` or `wo.z ≤ 0`.
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.eval_cos(wo, wi))
    }

    /// `f_r cosθi / pdf` for a `wi` drawn with the cosine warp (pdf `cosθi/π`): the path
    /// throughput's factor under `--sampler cosine`. Lambert's is ρ itself
    /// ([`Lambert::cosine_weight`]); other models divide.
    #[inline]
    pub fn cosine_weight(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::Lambert(b) => b.cosine_weight(wo, wi),
            _ => {
                let pdf = crate::render::sampling::cosine_hemisphere_pdf(wi.z);
                if pdf > 0.0 { self.eval_cos(wo, wi) / pdf } else { 0.0 }
            }
        }
    }

    /// Importance-sample `wi` for this `wo`. `u` drives the warp, `u_lobe` the choice of
    /// lobe. `None` when the sample carries no energy (e.g. reflected below the horizon);
    /// the caller then ends the path, which keeps the estimator unbiased.
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        match self {
            Bsdf::Lambert(b) => b.sample(wo, u),
            Bsdf::BlinnPhong(b) => b.sample(wo, u, u_lobe),
            Bsdf::ImprovedBlinnPhong(b) => b.sample(wo, u, u_lobe),
            Bsdf::CookTorrance(b) => b.sample(wo, u, u_lobe),
            Bsdf::Ggx(b) => b.sample(wo, u, u_lobe),
        }
    }

    /// Solid-angle density with which [`Bsdf::sample`] returns `wi`. It integrates to the
    /// probability that `sample` returns `Some` (1 for Lambert and near-normal `wo`).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.pdf(wo, wi))
    }

    /// This BRDF with its base colour replaced by `base` (a texel, [0, 1]): Lambert's ρ;
    /// GGX's plastic ρ and Schlick conductor F0, as glTF's metallic-roughness uses its
    /// base colour for both. The lobe models have no base colour and stay as they are.
    #[inline]
    pub fn with_base(&self, base: f32) -> Bsdf {
        match *self {
            Bsdf::Lambert(_) => Bsdf::Lambert(Lambert { rho: base }),
            Bsdf::Ggx(mut g) => {
                g.rho = base;
                if let ConductorFresnel::Schlick { f0 } = &mut g.conductor {
                    *f0 = base;
                }
                Bsdf::Ggx(g)
            }
            other => other,
        }
    }

    /// True if `f_r` is zero everywhere (no indirect work needed).
    pub fn is_black(&self) -> bool {
        match self {
            Bsdf::Lambert(b) => b.rho == 0.0,
            Bsdf::BlinnPhong(b) => b.is_black(),
            Bsdf::ImprovedBlinnPhong(b) => b.is_black(),
            Bsdf::CookTorrance(b) => b.is_black(),
            // Every Fresnel reflectance here reaches 1 at grazing incidence.
            Bsdf::Ggx(_) => false,
        }
    }

    /// `f_r = ρd/π + f_rest`: the Lambertian part's ρd and the rest (None when the rest
    /// reflects nothing), for estimators that take the view-independent diffuse part
    /// apart (the hybrid frame's irradiance cache). None for GGX, whose diffuse and
    /// specular parts are coupled through the coating's Fresnel terms.
    pub fn diffuse_split(&self) -> Option<(f32, Option<Bsdf>)> {
        fn rest<L: SpecularLobe>(d: &DiffuseLobe<L>) -> Option<DiffuseLobe<L>> {
            (!d.lobe.is_black()).then_some(DiffuseLobe { rho_d: 0.0, ..*d })
        }
        match self {
            Bsdf::Lambert(b) => Some((b.rho, None)),
            Bsdf::BlinnPhong(b) => Some((b.rho_d, rest(b).map(|d| Bsdf::BlinnPhong(BlinnPhong(d))))),
            Bsdf::ImprovedBlinnPhong(b) => {
                Some((b.rho_d, rest(b).map(|d| Bsdf::ImprovedBlinnPhong(ImprovedBlinnPhong(d)))))
            }
            Bsdf::CookTorrance(b) => Some((b.rho_d, rest(b).map(|d| Bsdf::CookTorrance(CookTorrance(d))))),
            Bsdf::Ggx(_) => None,
        }
    }

    /// `Some(ρ)` if this is a pure Lambertian BRDF (`f_r = ρ/π`), for fast paths.
    pub fn is_lambertian(&self) -> Option<f32> {
        match self {
            Bsdf::Lambert(b) => Some(b.rho),
            Bsdf::BlinnPhong(b) => b.lambertian(),
            Bsdf::ImprovedBlinnPhong(b) => b.lambertian(),
            Bsdf::CookTorrance(b) => b.lambertian(),
            Bsdf::Ggx(_) => None,
        }
    }

    /// Directional albedo `∫ f_r(wo, wi) cosθi dωi` for a `wo` at `cos_theta_o`
    /// (deterministic: ρd exactly plus a stratified `√samples × √samples` estimate of the
    /// specular lobe by its own sampler). May exceed 1 for the paper's fits.
    pub fn directional_albedo(&self, cos_theta_o: f32, samples: u32) -> f32 {
        match self {
            Bsdf::Lambert(b) => {
                if cos_theta_o > 0.0 {
                    b.rho
                } else {
                    0.0
                }
            }
            Bsdf::BlinnPhong(b) => b.directional_albedo(cos_theta_o, samples),
            Bsdf::ImprovedBlinnPhong(b) => b.directional_albedo(cos_theta_o, samples),
            Bsdf::CookTorrance(b) => b.directional_albedo(cos_theta_o, samples),
            Bsdf::Ggx(b) => b.directional_albedo(cos_theta_o, samples),
        }
    }

    /// Short model name as used in scene files (`model = "…"`).
    pub fn model_name(&self) -> &'static str {
        match self {
            Bsdf::Lambert(_) => "lambert",
            Bsdf::BlinnPhong(_) => "blinn_phong",
            Bsdf::ImprovedBlinnPhong(_) => "improved_blinn_phong",
            Bsdf::CookTorrance(_) => "cook_torrance",
            Bsdf::Ggx(b) => b.model_name(),
        }
    }
}

/// `√samples` rounded, at least 1: the side of the stratified grid.
pub(crate) fn grid_side(samples: u32) -> u32 {
    (f64::from(samples).sqrt().round() as u32).max(1)
}

/// Scale for the specular part so that `ρd + k·A_s(θo) ≤ 1` at every view angle, with a
/// 0.2 % margin for the quadrature error of `A_s`.
pub(crate) fn normalization_factor(rho_d: f32, spec_albedo: impl Fn(f32) -> f32) -> f32 {
    let a = lobe::max_albedo(spec_albedo);
    if a <= 0.0 {
        return 1.0;
    }
    ((1.0 - rho_d) * 0.998 / a).clamp(0.0, 1.0)
}

pub(crate) fn check_unit(model: &'static str, field: &'static str, v: f32) -> Result<(), BsdfError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(BsdfError::Invalid { model, field, value: v, reason: "must be in [0, 1]" })
    }
}

pub(crate) fn check_finite_nonneg(model: &'static str, field: &'static str, v: f32) -> Result<(), BsdfError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(BsdfError::Invalid { model, field, value: v, reason: "must be finite and ≥ 0" })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The diffuse part and the rest add up to the whole BRDF in every direction, and the
    /// rest alone samples only its lobe.
    #[test]
    fn the_diffuse_split_adds_up_to_the_brdf() {
        let models = [
            Bsdf::Lambert(Lambert { rho: 0.6 }),
            Bsdf::BlinnPhong(BlinnPhong::new(0.05, 2.0, 2000.0).unwrap().normalized()),
            Bsdf::ImprovedBlinnPhong(ImprovedBlinnPhong::gold_polyimide().normalized()),
            Bsdf::CookTorrance(CookTorrance::new(0.1, 0.15, 0.9, 1.0).unwrap().normalized()),
        ];
        let mut rng = crate::render::sampling::Rng::from_state(3);
        for b in models {
            let (rho_d, rest) = b.diffuse_split().expect("a diffuse-plus-lobe model");
            for _ in 0..2000 {
                let wo = crate::render::sampling::cosine_hemisphere(rng.next_2d());
                let wi = crate::render::sampling::cosine_hemisphere(rng.next_2d());
                let parts = rho_d * std::f32::consts::FRAC_1_PI * wi.z + rest.map_or(0.0, |r| r.eval_cos(wo, wi));
                let whole = b.eval_cos(wo, wi);
                assert!((parts - whole).abs() <= 1e-5 * whole.max(1.0), "{b:?}: {parts} ≠ {whole}");
                if let Some(s) = rest.and_then(|r| r.sample(wo, rng.next_2d(), rng.next_f32())) {
                    assert!(s.pdf > 0.0 && s.f_cos >= 0.0);
                }
            }
            assert_eq!(rest.is_none(), matches!(b, Bsdf::Lambert(_)));
        }
        assert!(Bsdf::Ggx(Ggx::plastic(0.3, 0.5, 1.5).unwrap()).diffuse_split().is_none());
    }
}
