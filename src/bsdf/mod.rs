//! BRDF models. TEMPORARY STUB (Lambert only) until the bsdf branch lands; the contract
//! (names, local shading frame with n = +Z, `wo` toward the viewer) is the real one.

use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3};
use serde::Deserialize;
use std::f32::consts::FRAC_1_PI;

pub struct BsdfSample {
    pub wi: Vec3,
    pub f_cos: f32,
    pub pdf: f32,
}

#[derive(Clone, Debug)]
pub struct Lambert {
    pub rho: f32,
}

#[derive(Clone, Debug)]
pub enum Bsdf {
    Lambert(Lambert),
}

impl Bsdf {
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let Bsdf::Lambert(l) = self;
        if wo.z <= 0.0 || wi.z <= 0.0 { 0.0 } else { l.rho * FRAC_1_PI }
    }
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi) * wi.z.max(0.0)
    }
    pub fn sample(&self, wo: Vec3, u: Vec2, _u_lobe: f32) -> Option<BsdfSample> {
        let wi = cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi.z);
        (pdf > 0.0).then(|| BsdfSample { wi, f_cos: self.eval_cos(wo, wi), pdf })
    }
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 { 0.0 } else { cosine_hemisphere_pdf(wi.z) }
    }
    pub fn is_black(&self) -> bool {
        let Bsdf::Lambert(l) = self;
        l.rho == 0.0
    }
    pub fn is_lambertian(&self) -> Option<f32> {
        let Bsdf::Lambert(l) = self;
        Some(l.rho)
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum BsdfSpec {
    Lambert { rho: f32 },
}

#[derive(Debug, thiserror::Error)]
pub enum BsdfError {
    #[error("{field}: {message}")]
    Invalid { field: &'static str, message: String },
}

impl BsdfSpec {
    pub fn build(&self) -> Result<Bsdf, BsdfError> {
        match self {
            BsdfSpec::Lambert { rho } if (0.0..=1.0).contains(rho) => Ok(Bsdf::Lambert(Lambert { rho: *rho })),
            BsdfSpec::Lambert { rho } => {
                Err(BsdfError::Invalid { field: "rho", message: format!("must be in [0, 1], got {rho}") })
            }
        }
    }
}
