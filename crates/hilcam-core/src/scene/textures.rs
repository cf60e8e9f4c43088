//! The scene's textures: each textured material's images (base colour, emission) decoded once (a failure is a
//! warning and the material keeps its factor), the load report (size and memory of each),
//! and the UVs kept only if some material ended up textured.

use super::Material;
use super::texture_file::{TextureRef, load_texture};
use crate::render::bsdf::{Bsdf, CoatingFamily};
use crate::render::texture::{NormalMap, TextureFilter, Texturing};

/// What a texture gives its material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// The BRDF's base colour.
    Base,
    /// The emission's multiplier.
    Emission,
    /// GGX roughness (α = roughness²).
    Roughness,
    /// GGX metallic weight.
    Metallic,
    /// Component `axis` (0 x, 1 y, 2 z) of a tangent-space normal map, whose tangent-plane
    /// components are scaled by `scale`.
    Normal { axis: usize, scale: f32 },
}

impl Slot {
    fn describe(self) -> &'static str {
        match self {
            Slot::Base => "base-colour texture",
            Slot::Emission => "emission texture",
            Slot::Roughness => "roughness texture",
            Slot::Metallic => "metallic texture",
            Slot::Normal { .. } => "normal map component",
        }
    }
}

/// `Some` when at least one of `textured` (scene material index, slot, texture) decodes.
pub fn build(
    materials: &[Material],
    textured: Vec<(u32, Slot, TextureRef)>,
    uv: Vec<[glam::Vec2; 3]>,
    filter: TextureFilter,
) -> Option<Texturing> {
    let n = materials.len();
    let mut t = Texturing {
        textures: Vec::new(),
        base: vec![None; n],
        emission: vec![None; n],
        roughness: vec![None; n],
        metallic: vec![None; n],
        coating: vec![None; n],
        coatings: Vec::new(),
        normal: vec![None; n],
        uv,
        filter,
    };
    let mut normal_parts = vec![[None; 3]; n];
    let mut normal_scale = vec![1.0f32; n];
    let mut loaded: Vec<(TextureRef, u32)> = Vec::new();
    for (mat, slot, r) in textured {
        // The same image with the same factor and channel is decoded once.
        let same = loaded
            .iter()
            .find(|(l, _)| l.source == r.source && l.factor == r.factor && l.channel == r.channel)
            .map(|(_, i)| *i);
        let index = match same {
            Some(i) => i,
            None => match load_texture(&r) {
                Ok(tex) => {
                    let (w, h) = tex.mip.size();
                    tracing::info!(
                        material = %materials[mat as usize].name,
                        texture = %tex.name,
                        width = w,
                        height = h,
                        levels = tex.mip.levels.len(),
                        bytes = tex.mip.bytes(),
                        "{}",
                        slot.describe()
                    );
                    t.textures.push(tex);
                    let i = (t.textures.len() - 1) as u32;
                    loaded.push((r, i));
                    i
                }
                Err(e) => {
                    let instead = match slot {
                        Slot::Base => "the material's factor is used",
                        Slot::Emission => "the emission's factor is used",
                        Slot::Roughness => "the material's roughness factor is used",
                        Slot::Metallic => "the material's metallic factor is used",
                        Slot::Normal { .. } => "the surface's own normal is used",
                    };
                    tracing::warn!(material = %materials[mat as usize].name, "{e}; {instead}");
                    continue;
                }
            },
        };
        let slots = match slot {
            Slot::Base => &mut t.base,
            Slot::Emission => &mut t.emission,
            Slot::Roughness => &mut t.roughness,
            Slot::Metallic => &mut t.metallic,
            Slot::Normal { axis, scale } => {
                normal_parts[mat as usize][axis] = Some(index);
                normal_scale[mat as usize] = scale;
                continue;
            }
        };
        slots[mat as usize] = Some(index);
    }
    // A normal map needs all three of its components.
    for (i, parts) in normal_parts.iter().enumerate() {
        if let [Some(x), Some(y), Some(z)] = *parts {
            t.normal[i] = Some(NormalMap { xyz: [x, y, z], scale: normal_scale[i] });
        }
    }
    coating_tables(materials, &mut t);
    if t.textures.is_empty() {
        return None;
    }
    tracing::info!(textures = t.textures.len(), bytes = t.bytes(), "textures and UVs in memory");
    Some(t)
}

/// The coating tables of each GGX material whose textured roughness or metallic weight
/// lets its base show through a coating of varying roughness (one family per index).
fn coating_tables(materials: &[Material], t: &mut Texturing) {
    for (i, m) in materials.iter().enumerate() {
        let Bsdf::Ggx(g) = &m.bsdf else { continue };
        let (rough, metal) = (t.roughness[i].is_some(), t.metallic[i].is_some());
        // The base shows where metallic < 1 (the factor, or a texel under it).
        let base_shows = g.rho > 0.0 && (g.metallic < 1.0 || metal);
        if !(rough || metal) || !base_shows {
            continue;
        }
        let family = match t.coatings.iter().position(|f| f.eta == g.eta) {
            Some(k) => k,
            None => {
                t.coatings.push(CoatingFamily::new(g.eta));
                tracing::info!(eta = g.eta, "coating tables for textured roughness");
                t.coatings.len() - 1
            }
        };
        t.coating[i] = Some(family as u32);
    }
}
