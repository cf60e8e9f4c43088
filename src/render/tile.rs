//! A band's camera samples traced pass by pass, each pass in tiles, each tile in waves.
//!
//! A pass is one camera sample (index `s`) in every pixel of the band. Its primary hits
//! come from the rasteriser (`visibility`) when it applies, all at once; then its paths
//! are cut into tiles of [`TILE_PATHS`] and a tile's paths advance one interaction at a
//! time: all closest-hit rays, then all shading, then all shadow rays (parallel, toward
//! the one sun direction, from neighbouring points). Tracing one sample to the end before
//! the next interleaves primary, shadow and bounce rays, each of which walks a different
//! part of the BVH and evicts the others' nodes from the cache; measured on the shipped
//! satellite, the same rays took ~1.8× longer that way than re-traced in bulk.
//!
//! Each path keeps its own random-number stream and runs exactly the steps of
//! [`PathContext::radiance`] (shared through [`PathContext::scatter`]) in the same order,
//! and each pixel sums its samples in index order, so the image has the same bytes as
//! tracing sample by sample.

use super::visibility::{PrimaryRaster, RasterScratch};
use crate::camera::View;
use crate::geometry::shadow_packet::PACKET;
use crate::geometry::{Hit, Ray};
use crate::integrator::{PathContext, RayCounts, RayLog};
use crate::sampling::PerSample;
use glam::Vec3;

/// Paths per tile: enough for coherent waves, few enough to stay in the L1/L2 caches.
pub const TILE_PATHS: usize = 256;

/// One camera sample: sample `index` of pixel (`row`, `col`), image coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CameraSample {
    pub row: u32,
    pub col: u32,
    pub index: u32,
}

/// One path in flight.
struct Path<S> {
    rng: S,
    ray: Ray,
    beta: f32,
    l: f32,
    /// Index of this camera sample in the pass's list.
    slot: u32,
    alive: bool,
}

/// Buffers reused from pass to pass (no allocation once warmed up).
pub struct Scratch<S> {
    /// Every path of the pass (one camera sample in each pixel that sees the bounds).
    paths: Vec<Path<S>>,
    /// Primary rays and their ideal image points, for the rasteriser.
    rays: Vec<Ray>,
    ideal: Vec<[f64; 2]>,
    primary: Vec<Option<Hit>>,
    raster: RasterScratch,
    /// Paths of the current tile still going.
    active: Vec<u32>,
    hits: Vec<Option<Hit>>,
    shadows: Vec<(u32, Ray, f32)>,
    /// Radiance of each camera sample of the pass.
    samples: Vec<f32>,
}

impl<S> Default for Scratch<S> {
    fn default() -> Self {
        Scratch {
            paths: Vec::new(),
            rays: Vec::new(),
            ideal: Vec::new(),
            primary: Vec::new(),
            raster: RasterScratch::default(),
            active: Vec::new(),
            hits: Vec::new(),
            shadows: Vec::new(),
            samples: Vec::new(),
        }
    }
}

impl<S> Scratch<S> {
    /// Grow each buffer to at least the capacity of `other`'s (see
    /// `buffers::Workers::equalise`).
    pub(super) fn grow_like(&mut self, other: &Self) {
        use super::buffers::reserve_to;
        reserve_to(&mut self.paths, other.paths.capacity());
        reserve_to(&mut self.rays, other.rays.capacity());
        reserve_to(&mut self.ideal, other.ideal.capacity());
        reserve_to(&mut self.primary, other.primary.capacity());
        reserve_to(&mut self.active, other.active.capacity());
        reserve_to(&mut self.hits, other.hits.capacity());
        reserve_to(&mut self.shadows, other.shadows.capacity());
        reserve_to(&mut self.samples, other.samples.capacity());
        self.raster.grow_like(&other.raster);
    }
}

/// Where a band's pixels are and how they are sampled.
pub struct TileJob<'a> {
    pub view: &'a View,
    pub ctx: &'a PathContext<'a>,
    /// Rasterised primary visibility for this frame, when it applies.
    pub raster: Option<&'a PrimaryRaster>,
    /// The pixels that may see a triangle (the rest are not sampled), when known.
    pub coverage: Option<&'a super::coverage::Coverage>,
    pub seed: u64,
    pub frame: u64,
    pub width: usize,
}

impl TileJob<'_> {
    /// Trace the camera samples `pass` (neighbours next to each other: tiles are cut from
    /// it in order) and return the radiance of each.
    pub fn trace_pass<'s, S: PerSample, L: RayLog>(
        &self,
        pass: &[CameraSample],
        scratch: &'s mut Scratch<S>,
        counts: &mut RayCounts,
        log: &mut L,
    ) -> &'s [f32] {
        let ctx = self.ctx;
        let scene = ctx.scene;
        let Scratch { paths, rays, ideal, primary, raster, active, hits, shadows, samples } = scratch;
        samples.clear();
        samples.resize(pass.len(), scene.background);
        paths.clear();
        rays.clear();
        ideal.clear();
        for (i, &CameraSample { row, col, index }) in pass.iter().enumerate() {
            let pixel = row as u64 * self.width as u64 + u64::from(col);
            let mut rng = S::for_sample(self.seed, self.frame, pixel, index);
            let j = rng.next_2d();
            let (x, y) = (f64::from(col) + f64::from(j.x), f64::from(row) + f64::from(j.y));
            // A ray that misses the bounding sphere sees the background (already set).
            let traced = if self.raster.is_some() {
                self.view.primary_ray_ideal(x, y).map(|(ray, at)| {
                    rays.push(ray);
                    ideal.push(at);
                    ray
                })
            } else {
                self.view.primary_ray(x, y)
            };
            if let Some(ray) = traced {
                paths.push(Path { rng, ray, beta: 1.0, l: 0.0, slot: i as u32, alive: true });
            }
        }
        if let Some(r) = self.raster {
            r.closest_hits(&scene.accel, rays, ideal, raster, primary);
        }

        for tile in (0..paths.len()).step_by(TILE_PATHS) {
            let end = (tile + TILE_PATHS).min(paths.len());
            active.clear();
            active.extend(tile as u32..end as u32);
            for bounce in 0..ctx.depth {
                if active.is_empty() {
                    break;
                }
                // Wave 1: closest hits (the primary ones rasterised, when they are).
                hits.clear();
                if bounce == 0 && self.raster.is_none() {
                    // Neighbouring primary rays eight at a time (`Accel::intersect_packet`).
                    for chunk in active.chunks(PACKET) {
                        let mut rays = [Ray { origin: Vec3::ZERO, dir: Vec3::ZERO, tmax: 0.0 }; PACKET];
                        for (&i, r) in chunk.iter().zip(rays.iter_mut()) {
                            *r = paths[i as usize].ray;
                            log.closest(r);
                        }
                        let mut found = [None; PACKET];
                        scene.accel.intersect_packet(&rays[..chunk.len()], &mut found);
                        hits.extend_from_slice(&found[..chunk.len()]);
                    }
                } else {
                    for &i in active.iter() {
                        let p = &paths[i as usize];
                        log.closest(&p.ray);
                        hits.push(if bounce == 0 { primary[i as usize] } else { scene.accel.intersect(&p.ray) });
                    }
                }
                if bounce == 0 {
                    counts.primary += active.len() as u64;
                } else {
                    counts.bounce += active.len() as u64;
                }
                // Wave 2: shading, which queues shadow rays and draws the next directions.
                shadows.clear();
                for (&i, hit) in active.iter().zip(hits.iter()) {
                    let p = &mut paths[i as usize];
                    let Some(hit) = hit else {
                        p.l += p.beta * scene.background;
                        p.alive = false;
                        continue;
                    };
                    let sc = ctx.scatter(&p.ray, hit, p.beta, bounce, &mut p.rng);
                    if let Some((ray, contribution)) = sc.shadow {
                        shadows.push((i, ray, contribution));
                    }
                    match sc.next {
                        Some((ray, beta)) => (p.ray, p.beta) = (ray, beta),
                        None => p.alive = false,
                    }
                }
                // Wave 3: shadow rays toward the sun, eight at a time (`Accel::occluded_packet`:
                // they share the sun's direction and start at neighbouring hits).
                counts.shadow += shadows.len() as u64;
                for chunk in shadows.chunks(PACKET) {
                    let mut rays = [Ray { origin: Vec3::ZERO, dir: Vec3::ZERO, tmax: 0.0 }; PACKET];
                    for ((_, ray, _), r) in chunk.iter().zip(rays.iter_mut()) {
                        log.shadow(ray);
                        *r = *ray;
                    }
                    let blocked = ctx.occluded_packet(&rays[..chunk.len()]);
                    for (k, (i, _, contribution)) in chunk.iter().enumerate() {
                        if blocked & (1 << k) == 0 {
                            paths[*i as usize].l += contribution;
                        }
                    }
                }
                active.retain(|&i| paths[i as usize].alive);
            }
            // Every path of the tile has ended (or used its last interaction).
            for p in &paths[tile..end] {
                samples[p.slot as usize] = p.l;
            }
        }
        samples
    }
}
