//! The scene's textures: each textured material's image decoded once (a failure is a
//! warning and the material keeps its factor), the load report (size and memory of each),
//! and the UVs kept only if some material ended up textured.

use super::Material;
use super::texture_file::{TextureRef, load_texture};
use crate::render::texture::{TextureFilter, Texturing};

/// `Some` when at least one of `textured` (scene material index, texture) decodes.
pub fn build(
    materials: &[Material],
    textured: Vec<(u32, TextureRef)>,
    uv: Vec<[glam::Vec2; 3]>,
    filter: TextureFilter,
) -> Option<Texturing> {
    let mut t = Texturing { textures: Vec::new(), base: vec![None; materials.len()], uv, filter };
    let mut loaded: Vec<(TextureRef, u32)> = Vec::new();
    for (mat, r) in textured {
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
                        "base-colour texture"
                    );
                    t.textures.push(tex);
                    let i = (t.textures.len() - 1) as u32;
                    loaded.push((r, i));
                    i
                }
                Err(e) => {
                    tracing::warn!(material = %materials[mat as usize].name, "{e}; the material's factor is used");
                    continue;
                }
            },
        };
        t.base[mat as usize] = Some(index);
    }
    if t.textures.is_empty() {
        return None;
    }
    tracing::info!(textures = t.textures.len(), bytes = t.bytes(), "textures and UVs in memory");
    Some(t)
}
