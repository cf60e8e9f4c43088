//! Sunlight that a glossy part reflects onto the target (caustics), per surface cell.
//!
//! The cache's paths ([`super::indirect_cache`]) find the sun's light on the surface they
//! reach by a shadow ray and that surface's BRDF. Where the BRDF has a sharp lobe (MLI's
//! α ≈ 3900), the lobe reflects the sun toward a cell only from a tiny set of directions,
//! which a cosine-distributed path almost never draws: that light arrives as rare, huge
//! samples — the noise the cache would freeze into the frame. Here it is followed from
//! the sun instead: parallel rays on a jittered grid across the target's bounding disc
//! (each carrying the sun's irradiance times its grid square) meet the lit surface, leave
//! it by its lobe's own sampler, and the flux lands in the cell side they meet next. The
//! cache's paths then take only the diffuse part of the sun's light at their first
//! surface, so every term is counted once.
//!
//! Deterministic: photon `i` draws its numbers from (seed, `i`), and the flux is summed
//! in 32.32 fixed point, whose sums do not depend on the order the threads add them. A
//! cell's value is its mean irradiance (flat over the cell, like the rest of the cache);
//! its Monte Carlo error is that of the photons that land in it.

use super::cells::{Cells, barycentric};
use crate::render::bsdf::Bsdf;
use crate::render::geometry::Ray;
use crate::render::integrator::PathContext;
use crate::render::sampling::{Rng, SampleSource, ShadingBasis};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Photons along a cache cell's edge, on the plane facing the sun: ~8 M for the satellite
/// at 16, ~32 M at 32. On the gold satellite at 256², the photons alone (every other part's
/// seed held) left 13.2 % of lit pixels above half the camera's noise at 16 and 5.3 % at 32;
/// 48 gains 2 points more for 2.25 × the photons (docs/render.md).
const PER_CELL_EDGE: f32 = 32.0;

/// A caustic cell's edge, in cache cells: the photons' flux is gathered over cells this
/// much coarser (a mirrored sun at 8 photons per cache-cell edge left a cache cell of a
/// large triangle ~11 photons, 28 % rms; `tests/render/hybrid_caustics.rs`). Coarser still
/// (8) took the gold satellite's photon share from 13.2 % to 10.6 % only, and blurs more.
const COARSER: f32 = 4.0;

/// Most photons along the disc's diameter (bounds a frame's cost where the target's
/// bounding sphere is much larger than its detail, e.g. parts far apart).
const MAX_GRID: u32 = 8192;

/// Lobe strata along each side of a block of photons.
const STRATA: u32 = 8;

/// The random stream of photons, apart from every camera sample's and cache path's.
const STREAM: u64 = 0xcac4_e000_0000_0002;

/// 32.32 fixed point for the flux sums.
const ONE: f64 = 4_294_967_296.0;

/// The part of a BRDF that photons carry: a diffuse-plus-lobe model's lobe, all of a GGX
/// (its parts are coupled); None for Lambert (and a black lobe).
pub fn photon_part(bsdf: &Bsdf) -> Option<Bsdf> {
    match bsdf.diffuse_split() {
        Some((_, lobe)) => lobe,
        None => (!bsdf.is_black()).then_some(*bsdf),
    }
}

/// The diffuse reflectance whose sunlight the cache's paths still take where photons
/// carry the rest: ρd, or 0 for a GGX.
pub fn path_diffuse(bsdf: &Bsdf) -> f32 {
    bsdf.diffuse_split().map_or(0.0, |d| d.0)
}

/// The caustic flux per cell side, for one sun direction.
pub struct Caustics {
    /// Cells [`COARSER`] times the cache's.
    cells: Cells,
    /// Per cell side (`2·cell + side`): the flux landed, in photons' worth (32.32).
    sums: Vec<AtomicU64>,
    /// Flux one photon carries at weight 1, W.
    photon_flux: f64,
    pub photons: u64,
    pub rays: u64,
}

impl Caustics {
    /// Follow the sun's photons over `ctx`'s target into `cells`. None when no material
    /// has a part that photons carry (a Lambert target pays nothing).
    pub fn trace(ctx: &PathContext, cache_cells: &Cells, seed: u64) -> Option<Caustics> {
        let target = ctx.scene;
        let parts: Vec<Option<Bsdf>> = target.materials.iter().map(|m| photon_part(&m.bsdf)).collect();
        if parts.iter().all(Option::is_none) {
            return None;
        }
        let radius = target.bounds.radius as f32;
        let centre = target.bounds.centre.as_vec3();
        let step_wanted = cache_cells.size / PER_CELL_EDGE;
        let cells = Cells::new(&target.mesh, cache_cells.size * COARSER);
        let grid = ((2.0 * radius / step_wanted).ceil() as u32).clamp(1, MAX_GRID);
        let step = 2.0 * radius / grid as f32;
        let basis = ShadingBasis::from_normal(ctx.sun);
        let (e1, e2) = (basis.to_world(Vec3::X), basis.to_world(Vec3::Y));
        let start = centre + ctx.sun * (2.0 * radius);
        let sums: Vec<AtomicU64> = (0..2 * cells.len()).map(|_| AtomicU64::new(0)).collect();
        let mesh = &target.mesh;
        let (photons, rays) = (0..grid)
            .into_par_iter()
            .map(|j| {
                let (mut photons, mut rays) = (0u64, 0u64);
                for i in 0..grid {
                    let mut rng = Rng::for_sample(seed, STREAM, u64::from(j) * u64::from(grid) + u64::from(i), 0);
                    let a = -radius + (i as f32 + rng.next_f32()) * step;
                    let b = -radius + (j as f32 + rng.next_f32()) * step;
                    if a * a + b * b > radius * radius {
                        continue;
                    }
                    photons += 1;
                    rays += 1;
                    let ray = Ray { origin: start + e1 * a + e2 * b, dir: -ctx.sun, tmax: f32::INFINITY };
                    let Some(hit) = target.accel.intersect(&ray) else { continue };
                    let Some(lobe) = &parts[hit.material as usize] else { continue };
                    // The lit side of the surface; the lobe leaves from it.
                    let n = if hit.normal.dot(ctx.sun) < 0.0 { -hit.normal } else { hit.normal };
                    let at = ShadingBasis::from_normal(n);
                    // The lobe's square stratified over each block of STRATA × STRATA
                    // neighbouring photons (a quarter of a cache cell's edge), shifted at random
                    // per block: what lands in a cell comes from many blocks' evenly
                    // spread fans rather than independent draws.
                    let u = (glam::Vec2::new((i % STRATA) as f32, (j % STRATA) as f32) + rng.next_2d()) / STRATA as f32;
                    let u = (u + block_shift(seed, i / STRATA, j / STRATA, grid)).fract();
                    let sun = at.to_local(ctx.sun);
                    let Some(s) = lobe.sample(sun, u, rng.next_1d()) else { continue };
                    // The radiance the lobe sends toward `wi` is f_r(wi, sun)·cosθsun·E (what
                    // a path's shadow ray from there finds; the paper's models are not
                    // reciprocal), so the photon's flux reflected per solid angle is
                    // f_r(wi, sun)·cosθwi (its own flux already has the sun's cosine).
                    let weight = lobe.eval_cos(s.wi, sun) * s.wi.z / (sun.z * s.pdf);
                    if !(s.pdf > 0.0 && weight > 0.0 && weight.is_finite()) {
                        continue;
                    }
                    let p = ray.origin + ray.dir * hit.t;
                    let out = Ray {
                        origin: ctx.spawn(p, hit.tri, hit.normal, n),
                        dir: at.to_world(s.wi),
                        tmax: f32::INFINITY,
                    };
                    rays += 1;
                    let Some(land) = target.accel.intersect(&out) else { continue };
                    let q = out.origin + out.dir * land.t;
                    let (u, w) = barycentric(q, mesh.triangle(land.tri as usize));
                    let cell = cells.cell_of(land.tri, u, w);
                    // The side the photon arrives on: the one facing back along its ray.
                    let side = u32::from(out.dir.dot(land.normal) > 0.0);
                    let fixed = (f64::from(weight) * ONE).round().min(1e18) as u64;
                    sums[(2 * cell + side) as usize].fetch_add(fixed, Ordering::Relaxed);
                }
                (photons, rays)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        let photon_flux = f64::from(target.sun_irradiance) * f64::from(step) * f64::from(step);
        Some(Caustics { cells, sums, photon_flux, photons, rays })
    }

    /// The mean caustic irradiance over π at the centre of cache cell `corners` of
    /// triangle `tri` (vertices `v`, normal `n_face`), on the side of `n_out`.
    pub fn radiance_over_pi(&self, tri: u32, corners: [Vec3; 3], v: [Vec3; 3], n_face: Vec3, n_out: Vec3) -> f32 {
        let (u, w) = barycentric((corners[0] + corners[1] + corners[2]) / 3.0, v);
        let side = u32::from(n_out.dot(n_face) < 0.0);
        let sum = self.sums[(2 * self.cells.cell_of(tri, u, w) + side) as usize].load(Ordering::Relaxed);
        if sum == 0 {
            return 0.0;
        }
        let n = f64::from(self.cells.res(tri));
        let area = 0.5 * f64::from((v[1] - v[0]).cross(v[2] - v[0]).length()) / (n * n);
        (sum as f64 / ONE * self.photon_flux / (area * std::f64::consts::PI)) as f32
    }
}

/// Block (`bi`, `bj`)'s random shift of the lobe's strata (a Cranley–Patterson rotation).
fn block_shift(seed: u64, bi: u32, bj: u32, grid: u32) -> glam::Vec2 {
    Rng::for_sample(seed, STREAM, u64::from(bj) * u64::from(grid) + u64::from(bi), 1).next_2d()
}
