//! Base-colour and emission textures: per-triangle UVs, mip-mapped band images, and the footprint
//! rule that keeps a frame the pixel's box average of its texture (docs/brdf.md,
//! "Textures").
//!
//! - A texture holds the material's base colour at hilcam's band, linear, already
//!   multiplied by the material's factor (`Kd`, `baseColorFactor`): the value replaces the
//!   BRDF's base (`Bsdf::with_base`). An emission texture holds the emitted radiance's
//!   multiplier (linear, times the material's emission factor), which scales
//!   `Material::emission`.
//! - Texture coordinates `(s, t)` have `t = 0` at the image's top row (glTF's UV as is;
//!   OBJ's `v` flipped at load).
//! - Camera hits are prefiltered over the pixel's footprint on the surface scaled by
//!   `max(1/8, 1/√spp)` (pbrt-v4's rule): at low spp a fine texture does not alias into
//!   noise, and as spp grows the prefilter shrinks, so the converged frame is the box
//!   average over the pixel of the bilinear texture. Bounces look up the finest level
//!   (no blur, so no bias; their noise is the bounce's own).
//! - Only a scene with a textured material has a [`Texturing`]; others pay one `None`
//!   test per hit.

pub mod mip;
pub mod sample;

use glam::{Vec2, Vec3};
pub use mip::MipMap;
use serde::Deserialize;

/// How camera hits look textures up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TextureFilter {
    /// Trilinear over the spp-scaled pixel footprint (the default).
    #[default]
    Mip,
    /// Bilinear at full resolution everywhere (aliases at low spp; for comparisons).
    Bilinear,
}

/// A decoded texture and where it came from (for the load report).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub mip: MipMap,
}

/// The scene's textures and the UVs of its triangles.
#[derive(Clone, Debug, PartialEq)]
pub struct Texturing {
    pub textures: Vec<Texture>,
    /// Per scene material: the texture holding its base colour, if any.
    pub base: Vec<Option<u32>>,
    /// Per scene material: the texture scaling its emission, if any.
    pub emission: Vec<Option<u32>>,
    /// Per scene material: the textures giving its GGX roughness and metallic weight, and
    /// the coating tables a varying roughness needs (an index into `coatings`).
    pub roughness: Vec<Option<u32>>,
    pub metallic: Vec<Option<u32>>,
    pub coating: Vec<Option<u32>>,
    pub coatings: Vec<crate::render::bsdf::CoatingFamily>,
    /// Per scene material: its tangent-space normal map, if any.
    pub normal: Vec<Option<NormalMap>>,
    /// Per triangle (the mesh's order): `(s, t)` at its three corners; zero for triangles
    /// of untextured materials.
    pub uv: Vec<[Vec2; 3]>,
    pub filter: TextureFilter,
}

/// A tangent-space normal map (glTF `normalTexture`, MTL `norm`): three value textures,
/// the image's r g b read linearly, and glTF's `scale` of the tangent-plane components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalMap {
    pub xyz: [u32; 3],
    pub scale: f32,
}

/// A material's roughness and metallic textures (either may be absent) and its coating
/// tables ([`Texturing::roughness_metallic_of`]).
pub struct RoughnessMetallic<'a> {
    pub roughness: Option<&'a MipMap>,
    pub metallic: Option<&'a MipMap>,
    pub coating: Option<&'a crate::render::bsdf::CoatingFamily>,
}

/// The pixel footprint's scale for `spp` samples per pixel: `max(1/8, 1/√spp)`.
pub fn spp_scale(spp: f64) -> f32 {
    (1.0 / spp.max(1.0).sqrt()).max(0.125) as f32
}

impl Texturing {
    /// The base-colour texture of material `material`, if it has one.
    #[inline]
    pub fn base_of(&self, material: u32) -> Option<&MipMap> {
        self.texture(&self.base, material)
    }

    /// The emission texture of material `material`, if it has one.
    #[inline]
    pub fn emission_of(&self, material: u32) -> Option<&MipMap> {
        self.texture(&self.emission, material)
    }

    /// The shading normal at point `p` of triangle `tri` (corners `corners`) whose front
    /// face has unit normal `n_front`, from material `material`'s normal map, if it has one:
    /// `normalize(x·T + y·B + z·N)` with `(x, y, z) = (2·texel − 1)·(scale, scale, 1)`,
    /// T the direction of increasing s and B of decreasing t (the image's "up", glTF's
    /// and OpenGL's convention), both made orthonormal to N. `texel` looks a texture up.
    #[inline]
    pub fn shading_normal(
        &self,
        material: u32,
        tri: u32,
        corners: [Vec3; 3],
        n_front: Vec3,
        texel: impl Fn(&MipMap) -> f32,
    ) -> Option<Vec3> {
        let map = (*self.normal.get(material as usize)?)?;
        let [ta, tb, tc] = self.uv[tri as usize];
        let (e1, e2) = (corners[1] - corners[0], corners[2] - corners[0]);
        let (d1, d2) = (tb - ta, tc - ta);
        let det = d1.perp_dot(d2);
        if det == 0.0 {
            return None;
        }
        // ∂p/∂s and ∂p/∂t from the triangle's edges and their UV differences.
        let dpds = (e1 * d2.y - e2 * d1.y) / det;
        let dpdt = (e2 * d1.x - e1 * d2.x) / det;
        let t = (dpds - n_front * n_front.dot(dpds)).normalize_or_zero();
        let b = -(dpdt - n_front * n_front.dot(dpdt) - t * t.dot(dpdt)).normalize_or_zero();
        let [x, y, z] = map.xyz.map(|i| 2.0 * texel(&self.textures[i as usize].mip) - 1.0);
        let n = (t * (x * map.scale) + b * (y * map.scale) + n_front * z).normalize_or_zero();
        (n != Vec3::ZERO && t != Vec3::ZERO && b != Vec3::ZERO).then_some(n)
    }

    /// The roughness and metallic textures of material `material` and its coating tables,
    /// if it has any of them.
    #[inline]
    pub fn roughness_metallic_of(&self, material: u32) -> Option<RoughnessMetallic<'_>> {
        let (r, m) = (self.texture(&self.roughness, material), self.texture(&self.metallic, material));
        if r.is_none() && m.is_none() {
            return None;
        }
        let coating = self.coating.get(material as usize).copied().flatten().map(|i| &self.coatings[i as usize]);
        Some(RoughnessMetallic { roughness: r, metallic: m, coating })
    }

    #[inline]
    fn texture(&self, slots: &[Option<u32>], material: u32) -> Option<&MipMap> {
        match slots.get(material as usize) {
            Some(Some(t)) => Some(&self.textures[*t as usize].mip),
            _ => None,
        }
    }

    /// The texture `mip`'s value at point `p` of triangle `tri` (corners `corners`, same
    /// frame as `p`), prefiltered over a footprint `footprint_m` metres wide on the
    /// surface (`None`: the finest level).
    #[inline]
    pub fn value_at(&self, mip: &MipMap, tri: u32, corners: [Vec3; 3], p: Vec3, footprint_m: Option<f32>) -> f32 {
        let [a, b, c] = corners;
        let (e1, e2, ep) = (b - a, c - a, p - a);
        let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let (dp1, dp2) = (ep.dot(e1), ep.dot(e2));
        let det = d11 * d22 - d12 * d12;
        let (u, v) =
            if det > 0.0 { ((d22 * dp1 - d12 * dp2) / det, (d11 * dp2 - d12 * dp1) / det) } else { (0.0, 0.0) };
        let [ta, tb, tc] = self.uv[tri as usize];
        let st = ta + (tb - ta) * u + (tc - ta) * v;
        match (footprint_m, self.filter) {
            (Some(w), TextureFilter::Mip) if det > 0.0 => {
                // Texture-coordinate width per metre: √(UV area / surface area).
                let uv_area2 = (tb - ta).perp_dot(tc - ta).abs();
                let width = w * (uv_area2 / det.sqrt()).sqrt();
                sample::trilinear(mip, st.x, st.y, width)
            }
            _ => sample::bilinear(&mip.levels[0], st.x, st.y),
        }
    }

    /// Bytes held: every level of every texture, and the UVs.
    pub fn bytes(&self) -> usize {
        self.textures.iter().map(|t| t.mip.bytes()).sum::<usize>()
            + self.uv.len() * std::mem::size_of::<[Vec2; 3]>()
            + self.coatings.len() * crate::render::bsdf::CoatingFamily::BYTES
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentrics_interpolate_the_corner_uvs() {
        // A 2×2 texture with one bright texel (top-left); a triangle mapping the unit
        // square's lower-left half onto the whole image.
        let mip = MipMap::new(2, 2, vec![1.0, 0.0, 0.0, 0.0]);
        let t = Texturing {
            textures: vec![Texture { name: "t".into(), mip: mip.clone() }],
            base: vec![Some(0)],
            emission: vec![None],
            roughness: vec![None],
            metallic: vec![None],
            coating: vec![None],
            coatings: Vec::new(),
            normal: vec![None],
            uv: vec![[Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)]],
            filter: TextureFilter::Mip,
        };
        let corners = [Vec3::ZERO, Vec3::X * 2.0, Vec3::Y * 2.0];
        // (0.5, 0.5) m is (s, t) = (0.25, 0.25): the bright texel's centre.
        assert_eq!(t.value_at(&mip, 0, corners, Vec3::new(0.5, 0.5, 0.0), None), 1.0);
        // A footprint of the whole 2 m square: the last level, the mean.
        assert_eq!(t.value_at(&mip, 0, corners, Vec3::new(0.5, 0.5, 0.0), Some(2.0)), 0.25);
        assert_eq!(spp_scale(1.0), 1.0);
        assert_eq!(spp_scale(16.0), 0.25);
        assert_eq!(spp_scale(4096.0), 0.125);
    }
}
