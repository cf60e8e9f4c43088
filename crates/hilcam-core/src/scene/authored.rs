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
    /// What the surface emits (MTL `Ke`, glTF `emissiveFactor`), if anything.
    pub emission: Option<AuthoredEmission>,
    /// GGX roughness and metallic textures (glTF `metallicRoughnessTexture`'s G and B,
    /// MTL `map_Pr`, `map_Pm`): values read linearly, times the factor.
    pub roughness_texture: Option<super::texture_file::TextureRef>,
    pub metallic_texture: Option<super::texture_file::TextureRef>,
    /// A tangent-space normal map (glTF `normalTexture`, MTL `norm`) and the scale of its
    /// tangent-plane components.
    pub normal_texture: Option<(super::texture_file::TextureRef, f32)>,
}

/// `c` over its band value (the mean of the three): the texture factor of a colour
/// whose band value is carried separately.
pub fn over_band(c: [f32; 3]) -> [f32; 3] {
    let band = (c[0] + c[1] + c[2]) / 3.0;
    if band > 0.0 { c.map(|v| v / band) } else { [1.0; 3] }
}

impl AuthoredBsdf {
    /// True when a texture is named (base colour or emission): the triangles need UVs.
    pub fn is_textured(&self) -> bool {
        self.base_texture.is_some()
            || self.emission.as_ref().is_some_and(|e| e.texture.is_some())
            || self.roughness_texture.is_some()
            || self.metallic_texture.is_some()
            || self.normal_texture.is_some()
    }
}

/// Emission as a model file gives it: relative to the radiance of a white Lambert surface
/// facing the sun (E/π), so `Ke 1 1 1` looks as bright as sunlit white paint of albedo 1,
/// as it does in the tools the model was made with (docs/brdf.md, "Emission").
#[derive(Clone, Debug, PartialEq)]
pub struct AuthoredEmission {
    /// The factor's band value times any strength (textured or not).
    pub relative: f32,
    /// The emission's texture (MTL `map_Ke`, glTF `emissiveTexture`), if it has one: its
    /// factor is the colour over its band value, so the texture holds the multiplier of
    /// `relative` (and a texture that fails to load leaves the factor's emission).
    pub texture: Option<super::texture_file::TextureRef>,
}

/// The metallic-roughness material (glTF 2.0, the MTL PBR extension) at one band: a GGX
/// conductor with Schlick F0 = `base` where `metallic` is 1, a rough plastic (index
/// `ior` over Lambert `base`) where it is 0, glTF's blend between.
///
/// # Errors
/// [`BsdfError`] naming the out-of-range parameter.
pub fn metallic_roughness(base: f32, metallic: f32, roughness: f32, ior: f32) -> Result<Bsdf, BsdfError> {
    metallic_roughness_textured(base, metallic, roughness, ior, false)
}

/// [`metallic_roughness`]; with `metallic_textured` always glTF's blend, which keeps the
/// base colour for both parts (a texel may turn a metal factor into a plastic).
///
/// # Errors
/// [`BsdfError`] naming the out-of-range parameter.
pub fn metallic_roughness_textured(
    base: f32,
    metallic: f32,
    roughness: f32,
    ior: f32,
    metallic_textured: bool,
) -> Result<Bsdf, BsdfError> {
    let g = if metallic_textured {
        Ggx::blend(base, metallic, roughness, ior)
    } else if metallic == 1.0 {
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
