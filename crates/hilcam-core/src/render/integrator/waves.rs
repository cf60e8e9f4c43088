//! A band's camera samples traced pass by pass, each pass in tiles, each tile in waves.
//!
//! A pass is one camera sample (index `s`) in every pixel of the band, cut into tiles of
//! [`TILE_PATHS`] paths. Traced camera rays are set up tile by tile, just before the tile
//! runs; the rasteriser (`cull::visibility`), when it applies, needs the whole pass's rays at
//! once and finds all its primary hits first. A tile's paths advance one interaction at a
//! time: all closest-hit rays, then all shading, then all shadow rays (parallel, toward
//! the one sun direction, from neighbouring points). Tracing one sample to the end before
//! the next interleaves primary, shadow and bounce rays, each of which walks a different
//! part of the BVH and evicts the others' nodes from the cache; measured on the shipped
//! satellite, the same rays took ~1.8× longer that way than re-traced in bulk.
//!
//! Each path keeps its own random-number stream and runs exactly the steps of
//! [`PathContext::radiance`] (shared through [`PathContext::scatter`]) in the same order,
//! and each pixel sums its samples in index order, so the image has the same bytes as
//! tracing sample by sample: the wave loop must equal the estimator of this module's
//! parent, [`PathContext::radiance`], and `tests/render/waves.rs` checks it byte for byte.

use crate::render::camera::View;
use crate::render::cull::visibility::{PrimaryRaster, RasterScratch};
use crate::render::geometry::shadow_packet::PACKET;
use crate::render::geometry::{Hit, Ray};
use crate::render::integrator::{PathContext, RayCounts, RayLog};
use crate::render::sampling::PerSample;
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

impl<S> Path<S> {
    /// A path starting at camera sample `slot` of the pass with primary ray `ray`.
    #[inline]
    fn camera(rng: S, ray: Ray, slot: usize) -> Self {
        Path { rng, ray, beta: 1.0, l: 0.0, slot: slot as u32, alive: true }
    }
}

/// Buffers reused from pass to pass (no allocation once warmed up).
pub struct Scratch<S> {
    /// The paths in flight: one tile's when the camera rays are traced, the whole pass's
    /// (one camera sample in each pixel that sees the bounds) when they are rasterised.
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
    pub(in crate::render) fn grow_like(&mut self, other: &Self) {
        use crate::heap::reserve_to;
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
    pub coverage: Option<&'a crate::render::cull::coverage::Coverage>,
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
        let scene = self.ctx.scene;
        let Scratch { paths, rays, ideal, primary, raster, active, hits, shadows, samples } = scratch;
        samples.clear();
        samples.resize(pass.len(), scene.background);
        paths.clear();
        if let Some(r) = self.raster {
            // The rasteriser wants every primary ray of the pass at once.
            rays.clear();
            ideal.clear();
            for (i, &sample) in pass.iter().enumerate() {
                let mut rng = self.sample_stream::<S>(sample);
                let (x, y) = self.position(sample, &mut rng);
                if let Some((ray, at)) = self.view.primary_ray_ideal(x, y) {
                    rays.push(ray);
                    ideal.push(at);
                    paths.push(Path::camera(rng, ray, i));
                } else if let Some(planet) = &self.ctx.planet {
                    samples[i] = planet.seen_by_camera(self.view, x, y).unwrap_or(scene.background);
                }
            }
            r.closest_hits(&scene.accel, rays, ideal, raster, primary);
            for tile in (0..paths.len()).step_by(TILE_PATHS) {
                let end = (tile + TILE_PATHS).min(paths.len());
                let waves = Waves { active, hits, shadows, primary: Some(&primary[tile..end]) };
                self.trace_tile(&mut paths[tile..end], waves, counts, log);
                for p in &paths[tile..end] {
                    samples[p.slot as usize] = p.l;
                }
            }
            return samples;
        }
        // Traced primary rays: each tile's paths are set up just before it runs, so they
        // are still in the cache (the same tiles of `TILE_PATHS` paths as setting up the
        // whole pass first, and so the same packets).
        let mut next = 0;
        while next < pass.len() {
            paths.clear();
            while paths.len() < TILE_PATHS && next < pass.len() {
                let sample = pass[next];
                let mut rng = self.sample_stream::<S>(sample);
                let (x, y) = self.position(sample, &mut rng);
                let ray = match self.view.motion {
                    None => self.view.primary_ray(x, y),
                    Some(_) => self.view.primary_ray_at(x, y, sample.row, self.exposure_time::<S>(sample)),
                };
                // A ray that misses the bounding sphere sees the background (already set), or
                // the planet (from the exposure start's camera).
                if let Some(ray) = ray {
                    paths.push(Path::camera(rng, ray, next));
                } else if let Some(planet) = &self.ctx.planet {
                    samples[next] = planet.seen_by_camera(self.view, x, y).unwrap_or(scene.background);
                }
                next += 1;
            }
            let waves = Waves { active, hits, shadows, primary: None };
            self.trace_tile(paths, waves, counts, log);
            for p in paths.iter() {
                samples[p.slot as usize] = p.l;
            }
        }
        samples
    }

    /// The random-number stream of one camera sample.
    #[inline]
    fn sample_stream<S: PerSample>(&self, CameraSample { row, col, index }: CameraSample) -> S {
        S::for_sample(self.seed, self.frame, self.view.pixel_key(row, col), index)
    }

    /// Where in its row's exposure a moving view's sample is taken, in [0, 1): from a
    /// stream of its own (the sample's key in another domain; stratified over the pixel's
    /// samples), never from the path's stream, so that the bounces draw the numbers the
    /// instant frame's draw and a zero-length exposure changes none of them (issue 42).
    #[inline]
    fn exposure_time<S: PerSample>(&self, CameraSample { row, col, index }: CameraSample) -> f32 {
        const EXPOSURE_TIME_DOMAIN: u64 = 0x7e3a_11c0_5e9d_0042;
        S::for_sample(self.seed ^ EXPOSURE_TIME_DOMAIN, self.frame, self.view.pixel_key(row, col), index).next_1d()
    }

    /// The sample's position in the image (its stream's first 2-D point within the pixel).
    #[inline]
    fn position<S: PerSample>(&self, CameraSample { row, col, .. }: CameraSample, rng: &mut S) -> (f64, f64) {
        let j = rng.next_2d();
        (f64::from(col) + f64::from(j.x), f64::from(row) + f64::from(j.y))
    }

    /// Advance one tile's paths one interaction at a time until every one has ended.
    fn trace_tile<S: PerSample, L: RayLog>(
        &self,
        paths: &mut [Path<S>],
        waves: Waves<'_>,
        counts: &mut RayCounts,
        log: &mut L,
    ) {
        let ctx = self.ctx;
        let scene = ctx.scene;
        let Waves { active, hits, shadows, primary } = waves;
        active.clear();
        active.extend(0..paths.len() as u32);
        for bounce in 0..ctx.depth {
            if active.is_empty() {
                break;
            }
            // Wave 1: closest hits (the primary ones rasterised, when they are).
            hits.clear();
            match primary {
                Some(primary) if bounce == 0 => {
                    for &i in active.iter() {
                        log.closest(&paths[i as usize].ray);
                        hits.push(primary[i as usize]);
                    }
                }
                None if bounce == 0 => {
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
                }
                _ => {
                    for &i in active.iter() {
                        let p = &paths[i as usize];
                        log.closest(&p.ray);
                        hits.push(scene.accel.intersect(&p.ray));
                    }
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
                    p.l += p.beta * ctx.escaped(&p.ray);
                    p.alive = false;
                    continue;
                };
                let sc = ctx.scatter(&p.ray, hit, p.beta, bounce, &mut p.rng);
                p.l += sc.emitted;
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
    }
}

/// A tile's per-wave buffers (from [`Scratch`]) and its rasterised primary hits, if any.
struct Waves<'a> {
    active: &'a mut Vec<u32>,
    hits: &'a mut Vec<Option<Hit>>,
    shadows: &'a mut Vec<(u32, Ray, f32)>,
    primary: Option<&'a [Option<Hit>]>,
}
