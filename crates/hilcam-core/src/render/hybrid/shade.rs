//! A pixel's radiance from its fragments: the sun's light on each fragment evaluated
//! once (flat facets under a parallel sun: the BRDF term is constant over a fragment but
//! for the view direction, whose change across a pixel enters only at second order), and
//! the indirect light of one path from one of the pixel's coverage samples.

use super::pattern::SAMPLES;
use super::tile::Fragment;
use crate::render::camera::View;
use crate::render::geometry::{Hit, Ray};
use crate::render::integrator::{PathContext, RayCounts};
use crate::render::sampling::{Rng, ShadingBasis};

/// The frame's constants for shading.
pub struct Shader<'a> {
    pub view: &'a View,
    pub ctx: &'a PathContext<'a>,
    /// The paths' continuation after their first surface (depth − 1), when depth > 1.
    pub rest: Option<&'a PathContext<'a>>,
    pub seed: u64,
    pub frame: u64,
}

/// A surface point seen through pixel coordinate (`x`, `y`) on triangle `tri`.
pub struct Surface {
    pub ray: Ray,
    pub hit: Hit,
}

impl Shader<'_> {
    /// The point of triangle `tri` that the camera ray through pixel coordinate (`x`, `y`)
    /// meets (on the triangle's plane: the coverage test already said it is inside).
    #[inline]
    pub fn surface(&self, tri: u32, x: f64, y: f64) -> Option<Surface> {
        let target = self.ctx.scene;
        let ray = self.view.primary_ray(x, y)?;
        let n = target.normals[tri as usize];
        let v0 = target.mesh.positions[target.mesh.indices[tri as usize][0] as usize];
        let denom = n.dot(ray.dir);
        let t = n.dot(v0 - ray.origin) / denom;
        if !(t.is_finite() && t > 0.0) {
            return None;
        }
        let hit = Hit { tri, t, normal: n, material: target.mesh.material[tri as usize] };
        Some(Surface { ray, hit })
    }

    /// The sun's light leaving `s` toward the camera (one shadow ray).
    #[inline]
    pub fn direct(&self, s: &Surface, counts: &mut RayCounts) -> f32 {
        let ctx = self.ctx;
        let wo = -s.ray.dir;
        let mut n = s.hit.normal;
        if n.dot(wo) < 0.0 {
            n = -n;
        }
        if n.dot(ctx.sun) <= 0.0 {
            return 0.0;
        }
        let bsdf = &ctx.scene.materials[s.hit.material as usize].bsdf;
        let basis = ShadingBasis::from_normal(n);
        let f_cos = bsdf.eval_cos(basis.to_local(wo), basis.to_local(ctx.sun));
        if f_cos <= 0.0 {
            return 0.0;
        }
        let p = s.ray.origin + s.ray.dir * s.hit.t;
        let origin = p + n * ctx.offset(p);
        counts.shadow += 1;
        if ctx.occluded(&Ray { origin, dir: ctx.sun, tmax: f32::INFINITY }) {
            return 0.0;
        }
        f_cos * ctx.scene.sun_irradiance
    }

    /// Indirect light leaving `s` toward the camera: one bounce sampled from its BRDF and
    /// the rest of a path (its direct light is the fragment's, not counted here).
    #[inline]
    pub fn indirect(&self, s: &Surface, key: u64, counts: &mut RayCounts) -> f32 {
        let Some(rest) = self.rest else { return 0.0 };
        let mut rng = Rng::for_sample(self.seed, self.frame, key, 0x1_0000);
        let sc = self.ctx.scatter(&s.ray, &s.hit, 1.0, 0, &mut rng);
        match sc.next {
            Some((ray, beta)) => beta * rest.radiance(ray, &mut rng, counts, &mut ()),
            None => 0.0,
        }
    }
}

/// The radiance of one pixel (`row`, `col`) from its `fragments` (of `setups`' triangles),
/// `background` samples that see no triangle, and the triangle its sample 0 sees at
/// offset `first` (indirect light).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub fn pixel(
    shader: &Shader,
    tri_of: &dyn Fn(u32) -> u32,
    fragments: &[Fragment],
    background: u32,
    row: u32,
    col: u32,
    first: Option<(u32, [f32; 2])>,
    counts: &mut RayCounts,
) -> f32 {
    let inv = 1.0 / SAMPLES as f32;
    let mut l = background as f32 * inv * shader.ctx.scene.background;
    for f in fragments {
        let (x, y) = (f64::from(col) + f64::from(f.mean[0]), f64::from(row) + f64::from(f.mean[1]));
        if let Some(s) = shader.surface(tri_of(f.setup), x, y) {
            l += f.count as f32 * inv * shader.direct(&s, counts);
        }
    }
    if let Some((setup, [ox, oy])) = first {
        let (x, y) = (f64::from(col) + f64::from(ox), f64::from(row) + f64::from(oy));
        if let Some(s) = shader.surface(tri_of(setup), x, y) {
            l += shader.indirect(&s, shader.view.pixel_key(row, col), counts);
        }
    }
    l
}
