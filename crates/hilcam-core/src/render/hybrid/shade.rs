//! A pixel's radiance from its fragments: the sun's light on each fragment evaluated
//! once (flat facets under a parallel sun: the BRDF term is constant over a fragment but
//! for the view direction, whose change across a pixel enters only at second order), its
//! visibility from the cell's class ([`super::shadow`]) or, over a partly shadowed cell,
//! sample by sample; the diffuse part of indirect light per fragment from the body-frame
//! cache ([`super::indirect_cache`]); and the rest of the indirect light (a glossy lobe's,
//! or a whole GGX surface's) from `spp` paths at the pixel's first coverage samples.

use super::cells::barycentric;
use super::indirect_cache::IndirectCache;
use super::pattern::SAMPLES;
use super::shadow::{Class, ShadowMemo};
use super::tile::{Fragment, NONE};
use crate::render::bsdf::Bsdf;
use crate::render::camera::View;
use crate::render::geometry::shadow_packet::PACKET;
use crate::render::geometry::{Hit, Ray};
use crate::render::integrator::{PathContext, RayCounts};
use crate::render::sampling::{Rng, SampleSource, ShadingBasis};
use glam::{DVec3, Vec3};

/// The frame's constants for shading.
pub struct Shader<'a> {
    pub view: &'a View,
    pub ctx: &'a PathContext<'a>,
    /// The paths' continuation after their first surface (depth − 1), when depth > 1.
    pub rest: Option<&'a PathContext<'a>>,
    pub memo: &'a ShadowMemo,
    /// The diffuse parts' indirect light, when `rest` is some.
    pub cache: Option<&'a IndirectCache>,
    /// Paths per pixel for the indirect light the cache does not hold (`spp`, ≤ 64).
    pub paths: u32,
    pub seed: u64,
    pub frame: u64,
}

/// A surface point seen by the camera.
pub struct Surface {
    /// Render frame.
    pub p: Vec3,
    /// Unit direction from the camera to `p`.
    pub dir: Vec3,
    pub tri: u32,
}

/// One pixel's coverage: its samples' triangles (setup indices) and offsets, and its
/// affine map to the ideal image plane ([`super::tile::TileBuffers`]).
pub struct PixelSamples<'a> {
    pub ids: &'a [u32; SAMPLES],
    pub sx: &'a [f32; SAMPLES],
    pub sy: &'a [f32; SAMPLES],
    pub map: &'a [f64; 6],
}

impl PixelSamples<'_> {
    /// The ideal image point of offset (`x`, `y`) in the pixel.
    #[inline]
    fn ideal(&self, x: f32, y: f32) -> [f64; 2] {
        let m = self.map;
        let (x, y) = (f64::from(x), f64::from(y));
        [m[0] + m[2] * x + m[4] * y, m[1] + m[3] * x + m[5] * y]
    }
}

impl Shader<'_> {
    /// The point of triangle `tri`'s plane that the camera sees at ideal image point `i`
    /// (in f64 from the camera centre: exact at any range).
    #[inline]
    pub fn surface(&self, tri: u32, i: [f64; 2]) -> Option<Surface> {
        let (target, view) = (self.ctx.scene, self.view);
        let d = view.cam_to_render
            * DVec3::new((i[0] - view.pp[0]) * view.inv_focal_px, (i[1] - view.pp[1]) * view.inv_focal_px, 1.0);
        let n = target.normals[tri as usize].as_dvec3();
        let v0 = target.mesh.positions[target.mesh.indices[tri as usize][0] as usize].as_dvec3();
        let t = n.dot(v0 - view.origin) / n.dot(d);
        let p = view.origin + d * t;
        (t.is_finite() && t > 0.0).then(|| Surface { p: p.as_vec3(), dir: d.normalize().as_vec3(), tri })
    }

    /// The normal of `s` facing the camera, and whether the sun is on that side.
    #[inline]
    fn facing(&self, s: &Surface) -> (Vec3, bool) {
        let mut n = self.ctx.scene.normals[s.tri as usize];
        if n.dot(s.dir) > 0.0 {
            n = -n;
        }
        (n, n.dot(self.ctx.sun) > 0.0)
    }

    /// `f_r·cosθ·E` of the sun at `s` (no shadowing), 0 when the sun is behind it.
    #[inline]
    fn sun_term(&self, s: &Surface) -> f32 {
        let (n, lit_side) = self.facing(s);
        if !lit_side {
            return 0.0;
        }
        let target = self.ctx.scene;
        let bsdf = &target.materials[target.mesh.material[s.tri as usize] as usize].bsdf;
        let basis = ShadingBasis::from_normal(n);
        bsdf.eval_cos(basis.to_local(-s.dir), basis.to_local(self.ctx.sun)).max(0.0) * target.sun_irradiance
    }

    /// The class shared by every cell of triangle `tri` that pixel `px`'s footprint may
    /// reach (the barycentric box of the pixel's corners on the triangle's plane), or
    /// `Partial` when they differ: a fragment whose mean point lies in a lit cell may
    /// still reach into a shadowed one.
    fn class_over(&self, tri: u32, px: &PixelSamples) -> Class {
        /// More cells than this under one pixel (a grazing view): test sample by sample.
        const MAX_CELLS: u32 = 16;
        let cells = &self.memo.cells;
        let n = cells.res(tri);
        if n == 1 {
            return self.memo.class(cells.of(tri).start);
        }
        let mesh = &self.ctx.scene.mesh;
        let v = mesh.indices[tri as usize].map(|i| mesh.positions[i as usize]);
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let Some(s) = self.surface(tri, px.ideal(x, y)) else { return Class::Partial };
            let (u, w) = barycentric(s.p, v);
            (lo, hi) = ([lo[0].min(u), lo[1].min(w)], [hi[0].max(u), hi[1].max(w)]);
        }
        let nf = n as f32;
        let index = |b: f32| (b * nf).floor().clamp(0.0, nf - 1.0) as u32;
        let ((i0, i1), (j0, j1)) = ((index(lo[0]), index(hi[0])), (index(lo[1]), index(hi[1])));
        if (i1 - i0 + 1) * (j1 - j0 + 1) > MAX_CELLS {
            return Class::Partial;
        }
        let mut seen = None;
        for j in j0..=j1 {
            for i in i0..=i1 {
                for upper in [false, true] {
                    let Some(c) = cells.cell(tri, i, j, upper) else { continue };
                    let class = self.memo.class(c);
                    if seen.is_some_and(|k| k != class) {
                        return Class::Partial;
                    }
                    seen = Some(class);
                }
            }
        }
        seen.unwrap_or(Class::Partial)
    }

    /// The share of `setup`'s coverage samples in `px` that see the sun, one shadow ray
    /// each (packets of eight); the fragment's mean point `mean` when none of its samples
    /// yields a surface point.
    fn lit_share(&self, px: &PixelSamples, setup: u32, tri: u32, mean: &Surface, counts: &mut RayCounts) -> f32 {
        let mut rays = [Ray { origin: Vec3::ZERO, dir: self.ctx.sun, tmax: f32::INFINITY }; PACKET];
        let (mut n_rays, mut tested, mut lit) = (0usize, 0u32, 0u32);
        let flush = |rays: &[Ray], tested: &mut u32, lit: &mut u32| {
            let blocked = self.ctx.occluded_packet(rays);
            *tested += rays.len() as u32;
            *lit += rays.len() as u32 - blocked.count_ones();
        };
        let (n, _) = self.facing(mean);
        let n_face = self.ctx.scene.normals[tri as usize];
        for k in (0..SAMPLES).filter(|&k| px.ids[k] == setup) {
            let Some(s) = self.surface(tri, px.ideal(px.sx[k], px.sy[k])) else { continue };
            rays[n_rays].origin = self.ctx.spawn(s.p, tri, n_face, n);
            n_rays += 1;
            if n_rays == PACKET {
                flush(&rays, &mut tested, &mut lit);
                n_rays = 0;
            }
        }
        if n_rays > 0 {
            flush(&rays[..n_rays], &mut tested, &mut lit);
        }
        if tested == 0 {
            let ray = Ray { origin: self.ctx.spawn(mean.p, tri, n_face, n), dir: self.ctx.sun, tmax: f32::INFINITY };
            counts.shadow += 1;
            return if self.ctx.occluded(&ray) { 0.0 } else { 1.0 };
        }
        counts.shadow += u64::from(tested);
        lit as f32 / tested as f32
    }

    /// The sun's light leaving fragment `f` (of triangle `tri`, seen at its mean point
    /// `s`) toward the camera.
    #[inline]
    fn direct(&self, px: &PixelSamples, f: &Fragment, tri: u32, s: &Surface, counts: &mut RayCounts) -> f32 {
        let l = self.sun_term(s);
        if l <= 0.0 {
            return 0.0;
        }
        match self.class_over(tri, px) {
            Class::Lit => l,
            Class::Dark => 0.0,
            Class::Partial => l * self.lit_share(px, f.setup, tri, s, counts),
        }
    }

    /// The indirect light the diffuse part of `s`'s material reflects toward the camera:
    /// ρd times the cache's mean incoming radiance at `s`'s cell. 0 without a cache or for
    /// a material with no separable diffuse part (GGX: its path carries all of it).
    #[inline]
    fn cached_diffuse(&self, s: &Surface) -> f32 {
        let (Some(cache), Some(rest)) = (self.cache, self.rest) else { return 0.0 };
        let target = self.ctx.scene;
        let bsdf = &target.materials[target.mesh.material[s.tri as usize] as usize].bsdf;
        let Some((rho_d, _)) = bsdf.diffuse_split().filter(|d| d.0 > 0.0) else { return 0.0 };
        let (n, _) = self.facing(s);
        rho_d * cache.radiance_over_pi(rest, s.tri, s.p, target.normals[s.tri as usize], n)
    }

    /// Indirect light leaving `s` toward the camera that the cache does not hold: one
    /// bounce sampled from the BRDF (or, with the cache, from the BRDF less its diffuse
    /// part) and the rest of a path (its direct light is the fragment's, not counted here).
    #[inline]
    fn indirect(&self, s: &Surface, key: u64, path: u32, counts: &mut RayCounts) -> f32 {
        let Some(rest) = self.rest else { return 0.0 };
        let mut rng = Rng::for_sample(self.seed, self.frame, key, 0x1_0000 + path);
        let ray = Ray { origin: s.p, dir: s.dir, tmax: f32::INFINITY };
        let target = self.ctx.scene;
        let material = target.mesh.material[s.tri as usize];
        let split = self.cache.and_then(|_| target.materials[material as usize].bsdf.diffuse_split());
        let next = match split {
            Some((_, None)) => return 0.0, // Lambert: the cache holds all of it
            Some((_, Some(lobe))) => self.lobe_bounce(s, &lobe, &mut rng),
            None => {
                let hit = Hit { tri: s.tri, t: 0.0, normal: target.normals[s.tri as usize], material };
                self.ctx.scatter(&ray, &hit, 1.0, 0, &mut rng).next
            }
        };
        match next {
            Some((ray, beta)) => {
                counts.bounce += 1;
                beta * rest.radiance(ray, &mut rng, counts, &mut ())
            }
            None => 0.0,
        }
    }

    /// Whether the cache holds all of triangle `tri`'s indirect light (a Lambert
    /// material): its pixels' paths need not find their surface point.
    #[inline]
    fn cache_holds_all(&self, tri: u32) -> bool {
        let target = self.ctx.scene;
        let bsdf = &target.materials[target.mesh.material[tri as usize] as usize].bsdf;
        self.cache.is_some() && matches!(bsdf.diffuse_split(), Some((_, None)))
    }

    /// The next ray and weight of a path leaving `s` by `lobe` (a BRDF's specular part),
    /// drawn from its own sampler; None when the sample carries nothing.
    fn lobe_bounce(&self, s: &Surface, lobe: &Bsdf, rng: &mut Rng) -> Option<(Ray, f32)> {
        let (n, _) = self.facing(s);
        let basis = ShadingBasis::from_normal(n);
        let sample = lobe.sample(basis.to_local(-s.dir), rng.next_2d(), rng.next_1d())?;
        let weight = sample.f_cos / sample.pdf;
        if !(sample.pdf > 0.0 && weight > 0.0 && weight.is_finite()) {
            return None;
        }
        let origin = self.ctx.spawn(s.p, s.tri, self.ctx.scene.normals[s.tri as usize], n);
        Some((Ray { origin, dir: basis.to_world(sample.wi), tmax: f32::INFINITY }, weight))
    }
}

/// The radiance of pixel (`row`, `col`) from its `fragments` (setup indices mapped to
/// mesh triangles by `tri_of`, each with its share) and the `background`'s share;
/// indirect light from the cache per fragment and from paths at its first coverage samples.
pub fn pixel(
    shader: &Shader,
    tri_of: &dyn Fn(u32) -> u32,
    px: &PixelSamples,
    fragments: &[Fragment],
    background: f32,
    (row, col): (u32, u32),
    counts: &mut RayCounts,
) -> f32 {
    let mut l = background * shader.ctx.scene.background;
    for f in fragments {
        let tri = tri_of(f.setup);
        let Some(s) = shader.surface(tri, px.ideal(f.mean[0], f.mean[1])) else { continue };
        l += f.weight * (shader.direct(px, f, tri, &s, counts) + shader.cached_diffuse(&s));
    }
    // The rest of the indirect light: the mean of paths from the pixel's first `paths`
    // coverage samples (a random subset of its strata); a sample on the background adds 0.
    if shader.rest.is_some() {
        let n = shader.paths.clamp(1, SAMPLES as u32);
        let key = shader.view.pixel_key(row, col);
        let mut sum = 0.0;
        for k in 0..n as usize {
            if px.ids[k] == NONE {
                continue;
            }
            let tri = tri_of(px.ids[k]);
            if shader.cache_holds_all(tri) {
                continue;
            }
            if let Some(s) = shader.surface(tri, px.ideal(px.sx[k], px.sy[k])) {
                sum += shader.indirect(&s, key, k as u32, counts);
            }
        }
        l += sum / n as f32;
    }
    l
}
