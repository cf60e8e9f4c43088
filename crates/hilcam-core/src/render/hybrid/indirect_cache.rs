//! The diffuse part of indirect light, kept per surface cell in the body frame.
//!
//! A Lambertian part reflects ρd/π times the irradiance arriving at it, whatever the
//! view; on a rigid target with the sun fixed in its body frame, the irradiance that
//! arrives by bounces does not change from frame to frame. Each side of each cell
//! ([`super::cells`]) keeps its mean indirect irradiance (as E/π, the radiance a white
//! Lambert surface there reflects), estimated the first time a frame needs it by
//! [`SAMPLES`] paths from points spread over the cell in stratified cosine-distributed
//! directions, each traced as the rest of a camera path (depth − 1 more surfaces). The
//! estimate's random numbers depend only on (seed, cell, side): a cell's value is the same
//! whichever frame, thread or pixel asks first — a memo, not an accumulation. It is
//! cleared when the sun's direction in the body frame changes (to the bit), or the seed,
//! depth, sampler or roulette.
//!
//! What it costs in accuracy: each value carries the Monte Carlo error of [`SAMPLES`]
//! paths (1/16 of one path's), the same in every frame and pixel over that cell, and a
//! cell is flat (its mean, not the irradiance's change across it). `hilcam bench quality`
//! counts both against the camera's noise (docs/render.md).

use super::caustics::{Caustics, path_diffuse};
use super::cells::{Cells, barycentric};
use crate::render::geometry::Ray;
use crate::render::integrator::{PathContext, RayCounts, RenderSettings};
use crate::render::sampling::{Rng, ShadingBasis, cosine_hemisphere};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// Paths per cell side: a 16 × 16 stratified grid of directions.
pub const SAMPLES: u32 = 256;
const GRID: u32 = 16;

/// Cell edge as a fraction of the bounding radius of the target's largest part (twice
/// the shadow cells': indirect light changes more slowly than a shadow's edge).
pub const CELL_FRACTION: f32 = 0.01;

/// Not estimated yet (no estimate is a NaN).
const EMPTY: u32 = u32::MAX;

/// The random stream of cache paths, apart from every camera sample's.
const STREAM: u64 = 0xcac4_e000_0000_0001;

type Key = ([u32; 3], usize, usize, u64, u32, u8, bool);

/// Mean indirect irradiance (over π) per cell side, for one sun direction.
#[derive(Default)]
pub struct IndirectCache {
    key: Option<Key>,
    pub cells: Cells,
    /// Per cell side (`2·cell + side`): f32 bits of the estimate, or [`EMPTY`].
    values: Vec<AtomicU32>,
    /// The sunlight glossy parts reflect, when the target has any.
    caustics: Option<Caustics>,
    /// Cell sides estimated and rays traced since [`IndirectCache::take_counts`].
    estimated: AtomicU64,
    rays: AtomicU64,
    photons: AtomicU64,
}

impl IndirectCache {
    /// Make the cache valid for `ctx`'s target and sun under `settings`: cleared unless
    /// it already is.
    pub fn update(&mut self, ctx: &PathContext, settings: &RenderSettings) {
        let mesh = &ctx.scene.mesh;
        let key = (
            ctx.sun.to_array().map(f32::to_bits),
            mesh.indices.len(),
            mesh.positions.len(),
            settings.seed,
            settings.depth,
            settings.sampler as u8,
            settings.roulette,
        );
        if self.key == Some(key) {
            return;
        }
        let size = CELL_FRACTION * ctx.scene.detail_radius as f32;
        if self.key.is_none_or(|k| (k.1, k.2) != (key.1, key.2)) || self.cells.size != size {
            self.cells = Cells::new(mesh, size);
        }
        let n = 2 * self.cells.len();
        self.values.truncate(n);
        self.values.par_iter().for_each(|v| v.store(EMPTY, Ordering::Relaxed));
        self.values.resize_with(n, || AtomicU32::new(EMPTY));
        self.key = Some(key);
        self.caustics = Caustics::trace(ctx, &self.cells, settings.seed);
        if let Some(c) = &self.caustics {
            self.photons.fetch_add(c.photons, Ordering::Relaxed);
            self.rays.fetch_add(c.rays, Ordering::Relaxed);
        }
    }

    /// The indirect irradiance over π at point `p` of triangle `tri`, on the side of
    /// `n_out` (± the face normal `n_face`): the cell's kept estimate, made now if it is
    /// the first ask. `rest` traces the paths on from their first bounce.
    pub fn radiance_over_pi(&self, rest: &PathContext, tri: u32, p: Vec3, n_face: Vec3, n_out: Vec3) -> f32 {
        let mesh = &rest.scene.mesh;
        let v = mesh.indices[tri as usize].map(|i| mesh.positions[i as usize]);
        let (u, w) = barycentric(p, v);
        let cell = self.cells.cell_of(tri, u, w);
        let side = u32::from(n_out.dot(n_face) < 0.0);
        let slot = &self.values[(2 * cell + side) as usize];
        let kept = slot.load(Ordering::Relaxed);
        if kept != EMPTY {
            return f32::from_bits(kept);
        }
        // Two threads may both estimate a cell: they compute the same bits.
        let corners = self.cells.corners(tri, cell, v).unwrap_or(v);
        let seed = self.key.map_or(0, |k| k.3);
        let id = 2 * cell + side;
        let split = self.caustics.is_some();
        let (mut e, rays) = estimate(rest, tri, corners, n_face, n_out, seed, u64::from(id), split);
        if let Some(c) = &self.caustics {
            e += c.radiance_over_pi(tri, corners, v, n_face, n_out);
        }
        slot.store(e.to_bits(), Ordering::Relaxed);
        self.estimated.fetch_add(1, Ordering::Relaxed);
        self.rays.fetch_add(rays, Ordering::Relaxed);
        e
    }

    /// Cell sides estimated, rays traced and caustic photons followed since the last call
    /// (per frame).
    pub fn take_counts(&self) -> (u64, u64, u64) {
        let take = |a: &AtomicU64| a.swap(0, Ordering::Relaxed);
        (take(&self.estimated), take(&self.rays), take(&self.photons))
    }
}

/// One cell side's mean incoming indirect radiance, cosine-weighted (= E/π): the mean of
/// [`SAMPLES`] paths from uniform points of the cell (`corners`), directions stratified
/// on a 16 × 16 grid of the cosine warp's square. With `split` (caustic photons carry the
/// rest), the sun's light at a path's first surface is its diffuse part's alone. Returns
/// the mean and the rays traced.
#[allow(clippy::too_many_arguments)]
fn estimate(
    rest: &PathContext,
    tri: u32,
    corners: [Vec3; 3],
    n_face: Vec3,
    n_out: Vec3,
    seed: u64,
    id: u64,
    split: bool,
) -> (f32, u64) {
    let mut rng = Rng::for_sample(seed, STREAM, id, 0);
    let basis = ShadingBasis::from_normal(n_out);
    let [a, b, c] = corners;
    let mut counts = RayCounts::default();
    let mut sum = 0.0f64;
    for k in 0..SAMPLES {
        let (i, j) = (k % GRID, k / GRID);
        let u = glam::Vec2::new((i as f32 + rng.next_f32()) / GRID as f32, (j as f32 + rng.next_f32()) / GRID as f32);
        // A uniform point of the triangle (the square-root warp).
        let (r1, r2) = (rng.next_f32().sqrt(), rng.next_f32());
        let p = a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2);
        let origin = rest.spawn(p, tri, n_face, n_out);
        let ray = Ray { origin, dir: basis.to_world(cosine_hemisphere(u)), tmax: f32::INFINITY };
        let l = if split {
            diffuse_sun_first(rest, ray, &mut rng, &mut counts)
        } else {
            rest.radiance(ray, &mut rng, &mut counts, &mut ())
        };
        sum += f64::from(l);
    }
    ((sum / f64::from(SAMPLES)) as f32, counts.total())
}

/// [`PathContext::radiance`] whose first surface reflects only its diffuse part of the
/// sun's light (the caustic photons carry the rest); later surfaces reflect all of it.
fn diffuse_sun_first(rest: &PathContext, ray: Ray, rng: &mut Rng, counts: &mut RayCounts) -> f32 {
    counts.primary += 1;
    let Some(hit) = rest.scene.accel.intersect(&ray) else { return rest.escaped(&ray) };
    let sc = rest.scatter(&ray, &hit, 1.0, 0, rng);
    let mut l = sc.emitted;
    if let Some((shadow, _)) = sc.shadow {
        let rho_d = path_diffuse(&rest.scene.materials[hit.material as usize].bsdf);
        if rho_d > 0.0 && {
            counts.shadow += 1;
            !rest.occluded(&shadow)
        } {
            // The lit side's cosine: the shadow ray leaves only from a side facing the sun.
            let cos = hit.normal.dot(rest.sun).abs();
            l += rho_d * std::f32::consts::FRAC_1_PI * cos * rest.scene.sun_irradiance;
        }
    }
    match sc.next {
        Some((next, beta)) => rest.radiance_after(next, 1, beta, l, rng, counts, &mut ()),
        None => l,
    }
}
