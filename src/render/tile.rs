//! Tiles traced in waves: all paths of a tile take their next step together.
//!
//! Tracing one sample to the end before the next interleaves primary, shadow and bounce
//! rays, each of which walks a different part of the BVH and evicts the others' nodes
//! from the cache; measured on the shipped satellite, the same rays took ~1.8× longer
//! inside the renderer than re-traced in bulk. Here a tile's paths advance one
//! interaction at a time: all closest-hit rays, then all shading, then all shadow rays
//! (parallel, toward the one sun direction, from neighbouring points). Each path keeps its
//! own random-number stream and runs exactly the steps of [`PathContext::radiance`]
//! (shared through [`PathContext::scatter`]) in the same order, so the image has the same
//! bytes as tracing sample by sample.

use crate::camera::View;
use crate::geometry::{Hit, Ray};
use crate::integrator::{PathContext, RayCounts, RayLog};
use crate::sampling::PerSample;

/// Paths per tile: enough for coherent waves, few enough to stay in the L1/L2 caches.
pub const TILE_PATHS: usize = 256;

/// One path in flight.
struct Path<S> {
    rng: S,
    ray: Ray,
    beta: f32,
    l: f32,
    /// Index of this sample's result in the tile's sample buffer.
    slot: u32,
    alive: bool,
}

/// Buffers reused from tile to tile (no allocation per tile once warmed up).
pub struct Scratch<S> {
    paths: Vec<Path<S>>,
    hits: Vec<Option<Hit>>,
    shadows: Vec<(u32, Ray, f32)>,
    /// Radiance of each camera sample of the tile, `pixel_in_tile × spp + sample`.
    samples: Vec<f32>,
}

impl<S> Default for Scratch<S> {
    fn default() -> Self {
        Scratch { paths: Vec::new(), hits: Vec::new(), shadows: Vec::new(), samples: Vec::new() }
    }
}

/// Where a tile's pixels are and how they are sampled.
pub struct TileJob<'a> {
    pub view: &'a View,
    pub ctx: &'a PathContext<'a>,
    pub seed: u64,
    pub frame: u64,
    pub spp: u32,
    pub width: usize,
}

impl TileJob<'_> {
    /// Trace the camera samples of `pixels` (`(row, col)`, image coordinates) and return
    /// each sample's radiance in `scratch.samples`, `spp` per pixel in pixel order.
    pub fn trace<'s, S: PerSample, L: RayLog>(
        &self,
        pixels: &[(u32, u32)],
        scratch: &'s mut Scratch<S>,
        counts: &mut RayCounts,
        log: &mut L,
    ) -> &'s [f32] {
        let ctx = self.ctx;
        let scene = ctx.scene;
        let Scratch { paths, hits, shadows, samples } = scratch;
        samples.clear();
        samples.resize(pixels.len() * self.spp as usize, scene.background);
        paths.clear();
        for (i, &(row, col)) in pixels.iter().enumerate() {
            let pixel = row as u64 * self.width as u64 + u64::from(col);
            for s in 0..self.spp {
                let mut rng = S::for_sample(self.seed, self.frame, pixel, s);
                let j = rng.next_2d();
                let (x, y) = (f64::from(col) + f64::from(j.x), f64::from(row) + f64::from(j.y));
                // A ray that misses the bounding sphere sees the background (already set).
                if let Some(ray) = self.view.primary_ray(x, y) {
                    let slot = (i * self.spp as usize + s as usize) as u32;
                    paths.push(Path { rng, ray, beta: 1.0, l: 0.0, slot, alive: true });
                }
            }
        }

        for bounce in 0..ctx.depth {
            if paths.is_empty() {
                break;
            }
            // Wave 1: closest hits.
            hits.clear();
            for p in paths.iter() {
                log.closest(&p.ray);
                hits.push(scene.accel.intersect(&p.ray));
            }
            if bounce == 0 {
                counts.primary += paths.len() as u64;
            } else {
                counts.bounce += paths.len() as u64;
            }
            // Wave 2: shading, which queues shadow rays and draws the next directions.
            shadows.clear();
            for (i, (p, hit)) in paths.iter_mut().zip(hits.iter()).enumerate() {
                let Some(hit) = hit else {
                    p.l += p.beta * scene.background;
                    p.alive = false;
                    continue;
                };
                let sc = ctx.scatter(&p.ray, hit, p.beta, bounce, &mut p.rng);
                if let Some((ray, contribution)) = sc.shadow {
                    shadows.push((i as u32, ray, contribution));
                }
                match sc.next {
                    Some((ray, beta)) => (p.ray, p.beta) = (ray, beta),
                    None => p.alive = false,
                }
            }
            // Wave 3: shadow rays toward the sun.
            counts.shadow += shadows.len() as u64;
            for (i, ray, contribution) in shadows.iter() {
                log.shadow(ray);
                if !ctx.occluded(ray) {
                    paths[*i as usize].l += contribution;
                }
            }
            paths.retain(|p| {
                if !p.alive {
                    samples[p.slot as usize] = p.l;
                }
                p.alive
            });
        }
        // Paths still alive after the last interaction (depth exhausted) are finished too.
        for p in paths.iter() {
            samples[p.slot as usize] = p.l;
        }
        samples
    }
}
