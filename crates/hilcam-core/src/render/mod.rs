//! The frame loop: (target, view, options) → radiance image. Two entry points:
//! [`render_into`] (reused buffers, what the pipeline calls) and [`render`] (a new image).
//!
//! Synchronous and pure; rayon parallelises over bands of rows, each band is traced tile
//! by tile in waves (`integrator::waves`). Only pixels whose area can see the target's bounds are
//! sampled (per-row spans, `cull::Silhouette`; the rest get the background radiance
//! without any work), so a far, small target costs in proportion to the pixels it
//! covers. Every random
//! number is keyed by (seed, frame, pixel, sample): the same inputs give the same bytes
//! whatever the thread count. A target's star field (`stars`) is drawn last, over the
//! background, where the target does not hide it.

use crate::render::camera::{PixelRect, View};
use crate::render::cull::Silhouette;
use crate::render::film::RadianceImage;
use crate::render::integrator::{Method, PathContext, RayCounts, RayLog, RenderSettings};
use crate::render::noise_bound::NoiseBound;
use crate::render::sampling::{PerSample, Rng, Sequence, SobolStream, mix64};
use crate::render::sensor_plan::SensorPlan;
use crate::render::stars::StarStats;
use crate::render::target::Target;
use adaptive::Adaptive;
pub use buffers::FrameBuffers;
use buffers::{WorkerScratch, Workers};
use integrator::waves::{CameraSample, TILE_PATHS, TileJob};

pub mod adaptive;
pub mod bsdf;
mod buffers;
pub mod camera;
pub mod cull;
pub mod film;
pub mod geometry;
pub mod hybrid;
pub mod integrator;
pub mod noise_bound;
pub mod planet;
pub mod sampling;
pub mod sensor_plan;
pub mod stars;
pub mod target;
pub mod texture;
pub mod truth;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// What a frame cost.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderStats {
    pub time: Duration,
    pub rays: RayCounts,
    /// Pixels sampled: inside the traced rectangle and the bounding sphere's image (0 when
    /// the target is out of view).
    pub traced_pixels: u64,
    pub rect: Option<PixelRect>,
    /// True when the primary hits were rasterised (`cull::visibility`), false when traced.
    pub primary_rasterised: bool,
    /// Camera samples traced (`spp` × traced pixels on average; per pixel it varies
    /// when sampling is adaptive).
    pub samples: u64,
    /// Stars drawn and hidden (all zero without a star field).
    pub stars: StarStats,
}

/// How primary hits are found. Both give the same hits (see `cull::visibility`,
/// `geometry::closest_packet`); both skip the pixels that cannot see a triangle
/// (`cull::coverage`), each by its own conservative rule, so a uniform frame has the same bytes
/// either way, and an adaptive one (whose budget is spp × sampled pixels) nearly so.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PrimaryVisibility {
    /// Trace where the tree walks neighbouring primary rays eight at a time (8-wide tree,
    /// AVX2: faster than rasterising); else rasterise when that is exact and pays (enough
    /// camera samples per triangle), else trace.
    #[default]
    Auto,
    /// Rasterise whenever that is exact.
    Raster,
    /// Trace every primary ray through the BVH (in packets of eight where the tree can).
    Trace,
}

impl RenderStats {
    pub fn mrays_per_s(&self) -> f64 {
        self.rays.total() as f64 / self.time.as_secs_f64().max(1e-12) / 1e6
    }
}

/// How one frame is rendered: everything but what is seen (the target through a view)
/// and where the pixels go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    pub settings: RenderSettings,
    /// Frame index: keys every random number together with `settings.seed`.
    pub frame: u64,
    pub primary: PrimaryVisibility,
    /// The camera's noise per pixel: what `quality = "sensor"` samples against (ignored in
    /// a fixed-quality frame; a sensor-quality frame without it is an adaptive one).
    pub noise: Option<NoiseBound>,
    /// Estimate every sampled pixel's Monte Carlo variance (`FrameBuffers::variance`).
    pub variance: bool,
    /// A planet for this frame in place of the target's own (`Target::planet`): one that
    /// moves from frame to frame (Python's `Renderer.render(planet=…)`). None: the target's.
    pub planet: Option<planet::Planet>,
}

impl RenderOptions {
    /// Frame `frame` with `settings`, primary hits found the default way.
    pub fn new(settings: RenderSettings, frame: u64) -> RenderOptions {
        RenderOptions {
            settings,
            frame,
            primary: PrimaryVisibility::default(),
            noise: None,
            variance: false,
            planet: None,
        }
    }

    /// These options with `planet` in place of the target's own (None: the target's).
    pub fn with_planet(self, planet: Option<planet::Planet>) -> RenderOptions {
        RenderOptions { planet, ..self }
    }

    /// These options with the camera's noise bound (for `quality = "sensor"`) and, when
    /// `variance`, each pixel's Monte Carlo variance estimated.
    pub fn with_noise(self, noise: Option<NoiseBound>, variance: bool) -> RenderOptions {
        RenderOptions { noise, variance, ..self }
    }

    /// These options with primary hits found the `primary` way.
    pub fn with_primary(self, primary: PrimaryVisibility) -> RenderOptions {
        RenderOptions { primary, ..self }
    }
}

/// Render one frame of `target` through `view` into a new image.
pub fn render(target: &Target, view: &View, options: &RenderOptions) -> (RadianceImage, RenderStats) {
    let mut buffers = FrameBuffers::<()>::default();
    let stats = render_into(&mut buffers, target, view, options);
    (buffers.take_image(), stats)
}

/// Render one frame of `target` through `view` into reused buffers: the image is
/// `buffers.image()`, the samples each pixel got `buffers.sample_counts()`, and every
/// traced ray went to the per-band logs `buffers.take_ray_logs()`. Once the buffers have grown
/// to the frame's size this allocates nothing (the loop of `hilcam serve` and replay,
/// through `FramePipeline`; `tests/zero_alloc.rs` counts).
pub fn render_into<L: RayLog + Default + Send + Sync>(
    buffers: &mut FrameBuffers<L>,
    target: &Target,
    view: &View,
    options: &RenderOptions,
) -> RenderStats {
    let RenderOptions { settings, frame, primary, noise, variance, planet: frame_planet } = options;
    let t0 = Instant::now();
    let (width, height) = view.size();
    buffers.reset_image(width, height, target.background);
    // A planet is the background of every pixel the tracer does not sample.
    let planet = frame_planet.or(target.planet).map(|p| p.place(view, target.sun_irradiance));
    if let Some(p) = &planet {
        let (img, samples, key) = (&mut buffers.image, settings.spp.floor(), (settings.seed, *frame));
        match settings.sequence {
            Sequence::Independent => planet::background::fill::<Rng>(img, view, p, target.background, samples, key),
            Sequence::Sobol => planet::background::fill::<SobolStream>(img, view, p, target.background, samples, key),
        }
    }
    let FrameBuffers {
        image: img,
        written_rows,
        fill: _,
        raster: raster_buffers,
        coverage: box_coverage,
        coverage_of,
        bands: band_buffers,
        stat,
        variance: variance_buffer,
        variance_valid,
        silhouette: spans,
        bands_used,
        size: _,
        sobol,
        independent,
        hybrid,
    } = buffers;
    let rect = if target.accel.is_empty() { None } else { view.pixel_rect() };
    // Pixels not sampled are exact (background, or a planet whose own sampling noise is
    // not estimated): variance 0.
    *variance_valid = *variance;
    if *variance {
        variance_buffer.clear();
        variance_buffer.resize(width as usize * height as usize, 0.0);
    }
    let mut rays = RayCounts::default();
    let mut traced = 0u64;
    let mut samples = 0u64;
    let mut primary_rasterised = false;
    *coverage_of = None;
    // The hybrid method where it applies (an instant view, no planet): no bands, no
    // per-pixel variance (its frames carry no Monte Carlo report yet).
    let hybrid_frame = match (rect, settings.method) {
        (Some(rect), Method::Hybrid) if planet.is_none() => {
            crate::render::hybrid::render(img, hybrid, target, view, rect, settings, *frame)
        }
        _ => None,
    };
    if let Some(h) = &hybrid_frame {
        *variance_valid = false;
        *written_rows = rect.map_or(0..0, |r| r.row0 as usize..r.row1 as usize);
        *bands_used = 0;
        rays = h.rays;
        traced = h.covered_pixels;
        if h.cache_cells > 0 || h.classify_rays > 0 {
            // Why this frame is slower than the next ones (the sun moved in the body frame,
            // the seed changed, or the view reached cells not yet estimated).
            tracing::debug!(
                classify_rays = h.classify_rays,
                cache_cells = h.cache_cells,
                cache_rays = h.cache_rays,
                caustic_photons = h.caustic_photons,
                "hybrid: body-frame cells filled"
            );
        }
        samples = h.covered_pixels * crate::render::hybrid::pattern::SAMPLES as u64;
    }
    if let Some(rect) = rect.filter(|_| hybrid_frame.is_none()) {
        let ctx = PathContext::new(target, view.sun, settings).with_view(view, settings);
        // The silhouette spans and the rasteriser hold for one camera position: a moving
        // view skips only the pixels no leaf box reaches at any instant of its exposure
        // (`Coverage::from_leaf_boxes`), each primary ray traced from where the camera is
        // at that sample's time.
        let moving = view.motion.is_some();
        let silhouette = if moving { None } else { Silhouette::new_reusing(view, spans) };
        // Columns of a row that can see the target's bounds; the rest keep the background
        // without costing a sample.
        let span = |row: u32| -> (u32, u32) {
            match &silhouette {
                Some(s) => s.columns(row).map_or((0, 0), |(a, b)| (a.max(rect.col0), b.min(rect.col1))),
                None => (rect.col0, rect.col1),
            }
        };
        let ctx = ctx.with_planet(planet);
        // Rasterising costs a pass over every triangle per frame (projection, binning) and
        // saves part of each camera sample's traversal: with single-ray walks it paid from
        // about two samples per triangle on (`hilcam bench render`, "primary hits").
        // Neighbouring primary rays walked eight at a time (`Accel::intersect_packet`) cost
        // less than the rasteriser's per-sample work alone, so where the tree walks
        // packets, primary rays are traced (docs/performance.md).
        let planned = (rect.row0..rect.row1)
            .map(|r| {
                let (a, b) = span(r);
                u64::from(b.saturating_sub(a))
            })
            .sum::<u64>() as f64
            * settings.spp.get();
        let pays = planned >= (RASTER_SAMPLES_PER_TRIANGLE * target.accel.len() as u64) as f64;
        let rasterise = !moving
            && match primary {
                PrimaryVisibility::Auto => pays && !target.accel.walks_packets(),
                PrimaryVisibility::Raster => true,
                PrimaryVisibility::Trace => false,
            };
        primary_rasterised = rasterise && raster_buffers.rebuild(target, view, rect);
        // Traced frames skip the pixels no leaf box projects onto.
        let coverage = if primary_rasterised {
            Some(&raster_buffers.coverage)
        } else {
            box_coverage.from_leaf_boxes(target, view, rect).then_some(&*box_coverage)
        };
        // Kept for the frame's ground truth: an instant view's coverage holds for its
        // pixel centres too.
        *coverage_of = coverage.filter(|_| !moving).map(|_| (view.clone(), primary_rasterised));
        let job = TileJob {
            view,
            ctx: &ctx,
            raster: primary_rasterised.then_some(&*raster_buffers),
            coverage,
            seed: settings.seed,
            frame: *frame,
            width: width as usize,
        };
        let spp = settings.spp.floor();
        let sensor = match (settings.quality.is_sensor(), noise) {
            (true, Some(bound)) => Some(SensorPlan { bound: *bound, budget: settings.spp, keys: view.keys }),
            _ => None,
        };
        // A sensor-quality frame starts as an adaptive one: a pilot of
        // `SensorPlan::PILOT` samples everywhere.
        let adaptive = match sensor {
            Some(_) => Some(Adaptive { pilot: SensorPlan::PILOT, spp_milli: settings.spp.milli(), uniform: false }),
            None => Adaptive::new(settings.spp, settings.adaptive),
        };
        let n_bands = (rect.row1 as usize).saturating_sub(rect.row0 as usize).div_ceil(BAND_ROWS);
        if band_buffers.len() < n_bands {
            band_buffers.resize_with(n_bands, Band::default);
        }
        let bands = &mut band_buffers[..n_bands];
        *written_rows = rect.row0 as usize..rect.row1 as usize;
        *bands_used = n_bands;
        let variance_out = variance.then_some(&mut variance_buffer[..]);
        let frame_buffers = FrameParts { img, bands, stat, variance: variance_out };
        let plan = Plan { spp, adaptive, sensor: sensor.as_ref() };
        match settings.sequence {
            Sequence::Independent => render_bands(&job, frame_buffers, independent, rect, &span, plan),
            Sequence::Sobol => render_bands(&job, frame_buffers, sobol, rect, &span, plan),
        }
        for band in &band_buffers[..n_bands] {
            rays.add(&band.rays);
            traced += band.pixels.len() as u64;
            samples += band.counts.iter().map(|&n| u64::from(n)).sum::<u64>();
        }
        if let Some(s) = silhouette {
            s.recycle(spans);
        }
        if rays.nonfinite > 0 {
            tracing::warn!(samples = rays.nonfinite, "non-finite radiance samples dropped");
        }
    }
    if planet.is_some() {
        *written_rows = 0..height as usize;
    }
    let mut stars = StarStats::default();
    if let Some(field) = &target.stars {
        stars = field.deposit(img, view, &target.accel, planet.as_ref());
        // The next frame clears the rows this one wrote; stars widen them.
        let (r0, r1) = (stars.rows.0 as usize, stars.rows.1 as usize);
        if r0 < r1 {
            let w = &mut *written_rows;
            *w = if w.start >= w.end { r0..r1 } else { w.start.min(r0)..w.end.max(r1) };
        }
    }
    RenderStats { time: t0.elapsed(), rays, traced_pixels: traced, rect, primary_rasterised, samples, stars }
}

/// Camera samples per triangle from which primary hits are rasterised rather than traced.
const RASTER_SAMPLES_PER_TRIANGLE: u64 = 2;

/// Rows per band: a band is one rayon task; its pixels are cut into tiles of a few
/// columns × all its rows, so a tile is compact on the image.
const BAND_ROWS: usize = 8;

/// Camera samples traced in one call in the adaptive stage (bounds its buffers).
const PASS_SAMPLES: usize = 16 * 1024;

/// One band of rows during a frame: its pixels and their running sums. Its buffers are
/// kept from frame to frame ([`FrameBuffers`]).
pub(crate) struct Band<L> {
    first_row: usize,
    /// Pixels in tile order: blocks of `tile_cols` columns × all rows.
    pixels: Vec<(u32, u32)>,
    sums: Vec<f32>,
    /// Pilot sums of squares (adaptive frames only).
    sum_sq: Vec<f32>,
    /// Samples per pixel.
    counts: Vec<u32>,
    /// Adaptive stage: each pixel's weight and frame pixel index.
    weight: Vec<f32>,
    index: Vec<u64>,
    rays: RayCounts,
    log: L,
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

/// The parts of [`FrameBuffers`] the bands write.
struct FrameParts<'a, L> {
    img: &'a mut RadianceImage,
    bands: &'a mut [Band<L>],
    stat: &'a mut Vec<[f32; 2]>,
    /// Each pixel's Monte Carlo variance, when asked for (frame-sized, zeroed).
    variance: Option<&'a mut [f32]>,
}

/// How a frame's samples are shared out.
#[derive(Clone, Copy)]
struct Plan<'a> {
    /// Samples in every pixel without a second stage.
    spp: u32,
    /// The two-stage plan (also the pilot of a sensor-quality frame).
    adaptive: Option<Adaptive>,
    /// The second stage follows the camera's noise, not the pilot's weights.
    sensor: Option<&'a SensorPlan>,
}

impl<L> Band<L> {
    /// Add sample value `v` to pixel `i` (and its square, in the pilot of an adaptive
    /// frame); a non-finite value is dropped and counted.
    fn add_sample(&mut self, i: usize, v: f32, square: bool) {
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

/// Render the rectangle's rows band by band (rayon over bands), each band pass by pass:
/// `spp` samples in every pixel, or (`adaptive`) a pilot in every pixel and the rest of
/// the budget where the pilot saw variance (or, `uniform`, evenly; or, `sensor`, where the
/// camera's noise asks for it). Then, when asked, each pixel's Monte Carlo variance.
fn render_bands<S: PerSample + Send, L: RayLog + Default + Send + Sync>(
    job: &TileJob,
    parts: FrameParts<L>,
    workers: &mut Workers<S>,
    rect: PixelRect,
    span: &(dyn Fn(u32) -> (u32, u32) + Sync),
    plan: Plan,
) {
    let FrameParts { img, bands, stat, variance } = parts;
    let w = job.width;
    let (row0, row1) = (rect.row0 as usize, rect.row1 as usize);
    let first_stage = plan.adaptive.map_or(plan.spp, |a| a.pilot);
    let weighted = plan.adaptive.is_some_and(|a| !a.uniform);
    // Sums of squares: the pilot's for the second stage's weights, every sample's for the
    // variance.
    let squares = weighted || variance.is_some();
    workers.ensure();
    let shared = &*workers;
    bands.par_iter_mut().enumerate().for_each(|(b, band)| {
        shared.with(|WorkerScratch { tile, pass, .. }| {
            let first_row = row0 + b * BAND_ROWS;
            let rows = first_row as u32..(first_row + BAND_ROWS).min(row1) as u32;
            band.first_row = first_row;
            band_pixels(job, rows, span, &mut band.pixels);
            let n = band.pixels.len();
            band.sums.clear();
            band.sums.resize(n, 0.0);
            band.sum_sq.clear();
            if squares {
                band.sum_sq.resize(n, 0.0);
            }
            band.counts.clear();
            band.counts.resize(n, first_stage);
            band.rays = RayCounts::default();
            band.log = L::default();
            for s in 0..first_stage {
                pass.clear();
                pass.extend(band.pixels.iter().map(|&(row, col)| CameraSample { row, col, index: s }));
                let values = job.trace_pass(pass, tile, &mut band.rays, &mut band.log);
                for (i, &v) in values.iter().enumerate() {
                    band.add_sample(i, v, squares);
                }
            }
        })
    });
    // The pilot statistics: what the second stage's weights read, and the variance of a
    // pixel left with one sample.
    let statistics = (weighted || (variance.is_some() && first_stage == 1)).then(|| {
        // With a planet the pixels left unsampled are not one constant: their statistic is
        // their value in the image (which holds no traced pixel yet).
        let backdrop = job.ctx.planet.is_some().then_some(&img.data[..]);
        pilot_statistics(job, bands, (stat, backdrop), first_stage, img.height as usize)
    });
    if let Some(adaptive) = plan.adaptive {
        let pilot = statistics.map(|(base, rows)| PilotView { stat: &stat[..], base, rows });
        add_second_stage::<S, L>(job, bands, shared, pilot, adaptive, plan.sensor, variance.is_some());
    }
    workers.equalise();
    img.data[row0 * w..row1 * w].par_chunks_mut(w * BAND_ROWS).zip(bands.par_iter()).for_each(|(out, band)| {
        for ((&(row, col), &sum), &n) in band.pixels.iter().zip(&band.sums).zip(&band.counts) {
            out[(row as usize - band.first_row) * w + col as usize] = sum * (1.0 / n as f32);
        }
    });
    if let Some(var) = variance {
        let pilot = statistics.map(|(base, rows)| PilotView { stat: &stat[..], base, rows });
        mean_variances(w, bands, pilot, &mut var[row0 * w..row1 * w]);
    }
}

/// The pilot statistics of a frame: `stat` holds rows `base..base + rows` of the image.
#[derive(Clone, Copy)]
struct PilotView<'a> {
    stat: &'a [[f32; 2]],
    base: usize,
    rows: usize,
}

/// Each sampled pixel's Monte Carlo variance of its mean into `out` (the bands' rows):
/// s²/N from its own N ≥ 2 samples (unbiased whatever N is, since N never depends on the
/// pixel's own samples), or, with one sample, its neighbours' estimate
/// ([`adaptive::neighbour_estimate`]; unbiased where the radiance is flat across them,
/// larger where it varies).
fn mean_variances<L: Send + Sync>(w: usize, bands: &[Band<L>], pilot: Option<PilotView>, out: &mut [f32]) {
    out.par_chunks_mut(w * BAND_ROWS).zip(bands.par_iter()).for_each(|(out, band)| {
        for (i, &(row, col)) in band.pixels.iter().enumerate() {
            let n = band.counts[i];
            let v = if n >= 2 {
                adaptive::sample_variance(band.sums[i], band.sum_sq[i], n) / n as f32
            } else {
                pilot.map_or(0.0, |p| {
                    adaptive::neighbour_estimate(p.stat, w, p.rows, row as usize - p.base, col as usize).variance
                })
            };
            out[(row as usize - band.first_row) * w + col as usize] = v;
        }
    });
}

/// The second stage of a two-stage frame: share out the rest of the budget — by what the
/// pilot saw around each pixel (`adaptive`), evenly (`uniform`), or by what the camera's
/// noise asks for (`sensor`) — and trace those samples.
fn add_second_stage<S: PerSample + Send, L: RayLog + Send + Sync>(
    job: &TileJob,
    bands: &mut [Band<L>],
    workers: &Workers<S>,
    pilot: Option<PilotView>,
    plan: Adaptive,
    sensor: Option<&SensorPlan>,
    squares: bool,
) {
    let w = job.width;
    match (sensor, pilot) {
        (Some(sensor), Some(p)) => {
            bands.par_iter_mut().for_each(|b| {
                b.counts.clear();
                b.counts.extend(b.pixels.iter().map(|&(r, c)| sensor.need(p.stat, w, p.rows, p.base, r, c)));
            });
            let cap = sensor.cap(bands.par_iter().map(|b| &b.counts[..]));
            let key = mix64(job.seed ^ mix64(job.frame ^ 0x7365_6e73_6f72_6361)); // "sensorca"
            bands.par_iter_mut().for_each(|b| {
                for (n, &(r, c)) in b.counts.iter_mut().zip(&b.pixels) {
                    let u = (mix64(key ^ (u64::from(r) * w as u64 + u64::from(c))) >> 11) as f64 / (1u64 << 53) as f64;
                    *n = cap.apply(*n, u);
                }
            });
        }
        _ => {
            match pilot {
                Some(p) if !plan.uniform => bands.par_iter_mut().for_each(|b| {
                    b.weight.clear();
                    b.weight.extend(
                        b.pixels.iter().map(|&(r, c)| plan.weight(p.stat, w, p.rows, r as usize - p.base, c as usize)),
                    );
                }),
                // An even share of a fraction: no pilot statistics to read.
                _ => bands.par_iter_mut().for_each(|b| {
                    b.weight.clear();
                    b.weight.resize(b.pixels.len(), 0.0);
                }),
            }
            let shares = plan.shares(bands.iter().map(|b| &b.weight[..]));
            bands.par_iter_mut().for_each(|band| {
                band.index.clear();
                band.index.extend(band.pixels.iter().map(|&(r, c)| u64::from(r) * w as u64 + u64::from(c)));
                plan.counts_into(&shares, &band.weight, &band.index, job.seed, job.frame, &mut band.counts);
            });
        }
    }
    bands.par_iter_mut().for_each(|band| {
        workers.with(|WorkerScratch { tile, pass, owner }| {
            // Pixel by pixel (in the band's tile order), each pixel's extra samples one after
            // the other: a packet of neighbouring paths is then mostly one pixel's, whose
            // rays start together, and each pixel's samples are summed in index order.
            pass.clear();
            owner.clear();
            for (i, (&(row, col), &n)) in band.pixels.iter().zip(&band.counts).enumerate() {
                for s in plan.pilot..n {
                    pass.push(CameraSample { row, col, index: s });
                    owner.push(i as u32);
                }
            }
            for (chunk, owners) in pass.chunks(PASS_SAMPLES).zip(owner.chunks(PASS_SAMPLES)) {
                let values = job.trace_pass(chunk, tile, &mut band.rays, &mut band.log);
                for (&i, &v) in owners.iter().zip(values) {
                    band.add_sample(i as usize, v, squares);
                }
            }
        })
    });
}

/// Every sampled pixel's pilot statistic (`[mean, variance]` of its first `pilot`
/// samples) into `stat`, for the sampled rows and the row on either side (what the
/// neighbour estimates read; unsampled pixels hold the background or `backdrop`'s value).
/// Returns the image row of `stat`'s first row and how many rows it holds.
fn pilot_statistics<L: Send + Sync>(
    job: &TileJob,
    bands: &[Band<L>],
    (stat, backdrop): (&mut Vec<[f32; 2]>, Option<&[f32]>),
    pilot: u32,
    height: usize,
) -> (usize, usize) {
    let w = job.width;
    let statistic = |sum: f32, sq: f32| [sum / pilot as f32, adaptive::sample_variance(sum, sq, pilot)];
    let background = |v: f32| [v, 0.0];
    let first = bands.first().map_or(0, |b| b.first_row);
    let (base, end) = (first.saturating_sub(1), (first + bands.len() * BAND_ROWS + 1).min(height));
    // Every entry is written below; resizing keeps last frame's values only to overwrite
    // them. The row on either side of the bands is background.
    stat.resize((end - base) * w, background(job.ctx.scene.background));
    let inside = (first - base) * w..((first + bands.len() * BAND_ROWS).min(end) - base) * w;
    // What an unsampled pixel's statistic is: the background, or its value in `backdrop`
    // (entry `i` of `stat` is the image's pixel `base·w + i`).
    let unsampled = |dst: &mut [[f32; 2]], at: usize| match backdrop {
        None => dst.fill(background(job.ctx.scene.background)),
        Some(img) => {
            for (d, &v) in dst.iter_mut().zip(&img[base * w + at..]) {
                *d = background(v);
            }
        }
    };
    let (before, after) = (inside.start, inside.end);
    unsampled(&mut stat[..before], 0);
    unsampled(&mut stat[after..], after);
    // Bands own disjoint rows: each clears and writes its own while they are in cache
    // (one pass over the statistics instead of a frame-wide fill and then a scatter).
    stat[inside].par_chunks_mut(BAND_ROWS * w).zip(bands.par_iter()).enumerate().for_each(|(b, (mine, band))| {
        unsampled(mine, before + b * BAND_ROWS * w);
        for ((&(row, col), &sum), &sq) in band.pixels.iter().zip(&band.sums).zip(&band.sum_sq) {
            mine[(row as usize - band.first_row) * w + col as usize] = statistic(sum, sq);
        }
    });
    (base, end - base)
}

/// A band's pixels that may see the target, in tile order: blocks of about
/// `TILE_PATHS / BAND_ROWS` columns × all the band's rows, so a tile is compact.
fn band_pixels(
    job: &TileJob,
    rows: std::ops::Range<u32>,
    span: &(dyn Fn(u32) -> (u32, u32) + Sync),
    pixels: &mut Vec<(u32, u32)>,
) {
    let tile_cols = (TILE_PATHS / BAND_ROWS).max(1) as u32;
    let mut spans = [(0u32, 0u32); BAND_ROWS];
    for (s, row) in spans.iter_mut().zip(rows.clone()) {
        *s = span(row);
    }
    let spans = &spans[..rows.len()];
    pixels.clear();
    let c_min = spans.iter().filter(|s| s.0 < s.1).map(|s| s.0).min().unwrap_or(0);
    let c_max = spans.iter().filter(|s| s.0 < s.1).map(|s| s.1).max().unwrap_or(0);
    for c0 in (c_min..c_max).step_by(tile_cols as usize) {
        let c1 = (c0 + tile_cols).min(c_max);
        for (row, &(a, b)) in rows.clone().zip(spans) {
            let cols = a.max(c0)..b.min(c1);
            match job.coverage {
                Some(c) => pixels.extend(cols.filter(|&col| c.may_hit(row, col)).map(|col| (row, col))),
                None => pixels.extend(cols.map(|col| (row, col))),
            }
        }
    }
}
