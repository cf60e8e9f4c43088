//! Materials as a model file's author wrote them (MTL keys, glTF's metallic-roughness),
//! without a `[materials.NAME]` table: the BRDF, and a note for everything not used.

use crate::render::bsdf::{Bsdf, BsdfError, ConductorFresnel, Ggx};

/// Smallest GGX roughness hilcam takes (α = 1e-4); smoother authored values are raised.
pub const MIN_ROUGHNESS: f32 = 0.01;

/// A BRDF built from a model file and what of the file it did not use.
#[derive(Clone, Debug)]
pub struct AuthoredBsdf {
    pub bsdf: Bsdf,
    /// One note per unused or adjusted value, each naming its file and place.
    pub notes: Vec<String>,
}

/// The metallic-roughness material (glTF 2.0, the MTL PBR extension) at one band: a GGX
/// conductor with Schlick F0 = `base` where `metallic` is 1, a rough plastic (index
/// `ior` over Lambert `base`) where it is 0, glTF's blend between.
///
/// # Errors
/// [`BsdfError`] naming the out-of-range parameter.
pub fn metallic_roughness(base: f32, metallic: f32, roughness: f32, ior: f32) -> Result<Bsdf, BsdfError> {
    let g = if metallic == 1.0 {
        Ggx::conductor(roughness, ConductorFresnel::Schlick { f0: base })
    } else if metallic == 0.0 {
        Ggx::plastic(roughness, base, ior)
    } else {
        Ggx::blend(base, metallic, roughness, ior)
    };
    g.map(Bsdf::Ggx)
}
