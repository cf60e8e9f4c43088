//! Everything a frame needs besides the scene, kept from frame to frame.
//!
//! A frame of the goal scene fills ~10 MB of buffers: the image, the rasteriser's boxes,
//! edges and coverage bits, each band's pixels and sums, the adaptive stage's statistics
//! and the tiles' path arrays. Allocated afresh, that is page faults and zeroing in every
//! frame, and a server's heap keeps moving. Held in a [`FrameBuffers`] (which
//! `FramePipeline` owns), they grow to the largest frame seen and are then only cleared
//! and refilled: rendering allocates nothing (`tests/zero_alloc.rs` counts).

use super::cull::SilhouetteBuffers;
use super::cull::coverage::Coverage;
use super::cull::visibility::PrimaryRaster;
use super::integrator::RayCounts;
use super::integrator::waves::{CameraSample, Scratch};
use crate::heap::reserve_to;
use crate::render::camera::View;
use crate::render::film::RadianceImage;
use crate::render::sampling::{Rng, SobolStream};
use std::sync::Mutex;

/// The buffers of one frame at a time; `L` logs rays (`()` logs nothing).
pub struct FrameBuffers<L = ()> {
    pub(super) image: RadianceImage,
    /// Rows of `image` the last frame may have written (the others hold `fill`, the last
    /// frame's background): only they are cleared for the next frame of the same size.
    pub(super) written_rows: std::ops::Range<usize>,
    pub(super) fill: f32,
    pub(super) raster: PrimaryRaster,
    /// The pixels a traced frame samples (`cull::coverage::Coverage::from_leaf_boxes`).
    pub(super) coverage: Coverage,
    /// The instant view whose pixels the last frame's coverage marks (None after a moving
    /// frame, or one without coverage), and whether it is the rasteriser's.
    pub(super) coverage_of: Option<(View, bool)>,
    /// One per band of rows; a frame uses the first `rows / BAND_ROWS` (the rest keep their
    /// capacity for larger frames).
    pub(super) bands: Vec<Band<L>>,
    /// How many of `bands` the last frame used.
    pub(super) bands_used: usize,
    /// Width and height of the last frame (also once its image has been taken).
    pub(super) size: (u32, u32),
    /// Pilot statistic of every pixel (adaptive frames).
    pub(super) stat: Vec<[f32; 2]>,
    /// Monte Carlo variance of every pixel's mean (when the frame's options asked for it).
    pub(super) variance: Vec<f32>,
    /// Whether `variance` belongs to the last frame.
    pub(super) variance_valid: bool,
    /// Per-row spans through a distorting lens.
    pub(super) silhouette: SilhouetteBuffers,
    pub(super) sobol: Workers<SobolStream>,
    pub(super) independent: Workers<Rng>,
    /// The hybrid method's triangle set-up (`hybrid`).
    pub(super) hybrid: crate::render::hybrid::HybridBuffers,
}

impl<L> Default for FrameBuffers<L> {
    fn default() -> Self {
        FrameBuffers {
            image: RadianceImage { width: 0, height: 0, data: Vec::new() },
            written_rows: 0..0,
            fill: 0.0,
            raster: PrimaryRaster::default(),
            coverage: Coverage::default(),
            coverage_of: None,
            bands: Vec::new(),
            bands_used: 0,
            size: (0, 0),
            stat: Vec::new(),
            variance: Vec::new(),
            variance_valid: false,
            silhouette: SilhouetteBuffers::default(),
            sobol: Workers::default(),
            independent: Workers::default(),
            hybrid: Default::default(),
        }
    }
}

impl<L> FrameBuffers<L> {
    /// The last frame's coverage (the pixels whose samples may hit a triangle), when it
    /// marks `view`'s pixels: the same instant view. A pixel it leaves out cannot see the
    /// target from anywhere in its area, so the ground truth's pixel-centre rays may skip
    /// it too.
    pub fn coverage_for(&self, view: &View) -> Option<&Coverage> {
        match &self.coverage_of {
            Some((v, raster)) if v.same_rays(view) => {
                Some(if *raster { &self.raster.coverage } else { &self.coverage })
            }
            _ => None,
        }
    }

    /// The image of the last frame rendered into these buffers.
    pub fn image(&self) -> &RadianceImage {
        &self.image
    }

    /// The image of the last frame, leaving an empty one (its buffer is then allocated
    /// again by the next frame).
    pub fn take_image(&mut self) -> RadianceImage {
        std::mem::replace(&mut self.image, RadianceImage { width: 0, height: 0, data: Vec::new() })
    }

    /// The Monte Carlo variance of each pixel's radiance mean in the last frame,
    /// (W·sr⁻¹·m⁻²)², row-major like the image: 0 where the pixel was not sampled (it is
    /// exact). `None` unless the frame's options asked for it (`RenderOptions::with_noise`).
    pub fn variance(&self) -> Option<&[f32]> {
        self.variance_valid.then_some(&self.variance[..])
    }

    /// How many camera samples each pixel of the last frame got (row-major, 0 where none
    /// was needed): with adaptive sampling, where the budget went.
    pub fn sample_counts(&self) -> Vec<u32> {
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        let mut counts = vec![0; w * h];
        for band in &self.bands[..self.bands_used] {
            for (&(row, col), &n) in band.pixels.iter().zip(&band.counts) {
                counts[row as usize * w + col as usize] = n;
            }
        }
        counts
    }

    /// The rays the last frame traced, one log per band of rows (none when the target was
    /// out of view); the bands' logs are left empty.
    pub fn take_ray_logs(&mut self) -> Vec<L>
    where
        L: Default,
    {
        self.bands[..self.bands_used].iter_mut().map(|b| std::mem::take(&mut b.log)).collect()
    }

    /// Set the image to `width` × `height` pixels of `fill`, reusing its buffer: the whole
    /// of it when its size or fill changed, else only the rows the last frame wrote (a
    /// full 1024² clear is ~0.6 ms, one thread; the target covers ~40 % of the rows).
    pub(super) fn reset_image(&mut self, width: u32, height: u32, fill: f32) {
        let img = &mut self.image;
        let n = width as usize * height as usize;
        let same =
            (img.width, img.height) == (width, height) && img.data.len() == n && self.fill.to_bits() == fill.to_bits();
        if same {
            let w = width as usize;
            img.data[self.written_rows.start * w..self.written_rows.end * w].fill(fill);
        } else {
            (img.width, img.height) = (width, height);
            img.data.clear();
            img.data.resize(n, fill);
            self.fill = fill;
        }
        self.written_rows = 0..0;
        self.bands_used = 0;
        self.size = (width, height);
    }
}

/// What one worker thread uses while tracing a band: the tiles' path buffers and the list
/// of camera samples of the current pass (and whose they are).
pub(super) struct WorkerScratch<S> {
    pub tile: Scratch<S>,
    pub pass: Vec<CameraSample>,
    pub owner: Vec<u32>,
}

impl<S> WorkerScratch<S> {
    /// Grow each buffer to at least the capacity of `other`'s.
    fn grow_like(&mut self, other: &Self) {
        self.tile.grow_like(&other.tile);
        reserve_to(&mut self.pass, other.pass.capacity());
        reserve_to(&mut self.owner, other.owner.capacity());
    }
}

impl<S> Default for WorkerScratch<S> {
    fn default() -> Self {
        WorkerScratch { tile: Scratch::default(), pass: Vec::new(), owner: Vec::new() }
    }
}

/// One [`WorkerScratch`] per rayon worker thread. rayon's `map_init` would create one per
/// split job, i.e. many per frame; here a band takes its thread's own, behind a lock that
/// no other thread touches (so it never waits).
pub(super) struct Workers<S>(Vec<Mutex<WorkerScratch<S>>>);

impl<S> Default for Workers<S> {
    fn default() -> Self {
        Workers(Vec::new())
    }
}

impl<S> Workers<S> {
    /// One scratch per thread of the current rayon pool (call outside the parallel part).
    pub fn ensure(&mut self) {
        let n = rayon::current_num_threads().max(1);
        if self.0.len() < n {
            self.0.resize_with(n, Default::default);
        }
    }

    /// Grow every worker's buffers to the largest any of them has. Which thread traces
    /// which band depends on scheduling, so without this a thread could meet a band larger
    /// than any it had seen frames after the others, and allocate then; with it the
    /// buffers stop growing once every band has been traced once.
    pub fn equalise(&mut self) {
        let Some((first, rest)) = self.0.split_first_mut() else { return };
        let first = first.get_mut().unwrap_or_else(|e| e.into_inner());
        // The first takes the largest of every buffer, then every other takes the first's.
        for w in rest.iter_mut() {
            first.grow_like(w.get_mut().unwrap_or_else(|e| e.into_inner()));
        }
        for w in rest.iter_mut() {
            w.get_mut().unwrap_or_else(|e| e.into_inner()).grow_like(first);
        }
    }

    /// Run `f` with the calling worker thread's scratch.
    pub fn with<R>(&self, f: impl FnOnce(&mut WorkerScratch<S>) -> R) -> R {
        let i = rayon::current_thread_index().unwrap_or(0) % self.0.len();
        // A panic while tracing poisons only that band's scratch; its contents are
        // cleared before use anyway.
        let mut scratch = self.0[i].lock().unwrap_or_else(|e| e.into_inner());
        f(&mut scratch)
    }
}

/// One band of rows during a frame: its pixels and their running sums. Its buffers are
/// kept from frame to frame ([`FrameBuffers`]).
pub(crate) struct Band<L> {
    pub(super) first_row: usize,
    /// Pixels in tile order: blocks of `tile_cols` columns × all rows.
    pub(super) pixels: Vec<(u32, u32)>,
    pub(super) sums: Vec<f32>,
    /// Pilot sums of squares (adaptive frames only).
    pub(super) sum_sq: Vec<f32>,
    /// Samples per pixel.
    pub(super) counts: Vec<u32>,
    /// Adaptive stage: each pixel's weight and frame pixel index.
    pub(super) weight: Vec<f32>,
    pub(super) index: Vec<u64>,
    pub(super) rays: RayCounts,
    pub(super) log: L,
}

impl<L: Default> Default for Band<L> {
    fn default() -> Self {
        Band {
            first_row: 0,
            pixels: Vec::new(),
            sums: Vec::new(),
            sum_sq: Vec::new(),
            counts: Vec::new(),
            weight: Vec::new(),
            index: Vec::new(),
            rays: RayCounts::default(),
            log: L::default(),
        }
    }
}

impl<L> Band<L> {
    /// Add sample value `v` to pixel `i` (and its square, in the pilot of an adaptive
    /// frame); a non-finite value is dropped and counted.
    pub(super) fn add_sample(&mut self, i: usize, v: f32, square: bool) {
        if !v.is_finite() {
            self.rays.nonfinite += 1;
            return;
        }
        self.sums[i] += v;
        if square {
            self.sum_sq[i] += v * v;
        }
    }
}
