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
    /// The base colour's texture (MTL `map_Kd`, glTF `baseColorTexture`), if it has one.
    pub base_texture: Option<super::texture_file::TextureRef>,
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

/// A one-line description of a BRDF for the load log (the GGX coating's table left out).
pub fn describe(b: &Bsdf) -> String {
    match b {
        Bsdf::Lambert(l) => format!("lambert ρ {}", l.rho),
        Bsdf::Ggx(g) => {
            let f = match g.conductor {
                ConductorFresnel::Schlick { f0 } => format!("Schlick F0 {f0}"),
                ConductorFresnel::Complex { n, k } => format!("n {n} k {k}"),
            };
            format!(
                "{} α {} metallic {} (conductor {f}) base ρ {} coating η {}",
                g.model_name(),
                g.dist.alpha,
                g.metallic,
                g.rho,
                g.eta
            )
        }
        other => format!("{other:?}"),
    }
}
