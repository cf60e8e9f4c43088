//! The scene's textures: each textured material's images (base colour, emission) decoded once (a failure is a
//! warning and the material keeps its factor), the load report (size and memory of each),
//! and the UVs kept only if some material ended up textured.

use super::Material;
use super::texture_file::{TextureRef, load_texture};
use crate::render::texture::{TextureFilter, Texturing};

/// What a texture gives its material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// The BRDF's base colour.
    Base,
    /// The emission's multiplier.
    Emission,
}

impl Slot {
    fn describe(self) -> &'static str {
        match self {
            Slot::Base => "base-colour texture",
            Slot::Emission => "emission texture",
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
    let mut t = Texturing { textures: Vec::new(), base: vec![None; n], emission: vec![None; n], uv, filter };
    let mut loaded: Vec<(TextureRef, u32)> = Vec::new();
    for (mat, slot, r) in textured {
        // The same image with the same factor is decoded once.
        let same = loaded.iter().find(|(l, _)| l.source == r.source && l.factor == r.factor).map(|(_, i)| *i);
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
                    };
                    tracing::warn!(material = %materials[mat as usize].name, "{e}; {instead}");
                    continue;
                }
            },
        };
        match slot {
            Slot::Base => t.base[mat as usize] = Some(index),
            Slot::Emission => t.emission[mat as usize] = Some(index),
        }
    }
    if t.textures.is_empty() {
        return None;
    }
    tracing::info!(textures = t.textures.len(), bytes = t.bytes(), "textures and UVs in memory");
    Some(t)
}
