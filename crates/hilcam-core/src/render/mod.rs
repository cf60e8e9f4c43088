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
use crate::render::sampling::{Rng, Sequence, SobolStream};
use crate::render::sensor_plan::SensorPlan;
use crate::render::stars::StarStats;
use crate::render::target::Target;
use adaptive::Adaptive;
use bands::{BAND_ROWS, FrameParts, Plan, render_bands};
use buffers::Band;
pub use buffers::FrameBuffers;
use integrator::waves::TileJob;

pub mod adaptive;
mod bands;
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
    let RenderOptions { settings, frame, planet: frame_planet, .. } = options;
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
    let rect = if target.accel.is_empty() { None } else { view.pixel_rect() };
    // Pixels not sampled are exact (background, or a planet whose own sampling noise is
    // not estimated): variance 0.
    buffers.variance_valid = options.variance;
    if options.variance {
        buffers.variance.clear();
        buffers.variance.resize(width as usize * height as usize, 0.0);
    }
    buffers.coverage_of = None;
    // The hybrid method where it applies (an instant view, no planet): no bands, no
    // per-pixel variance (its frames carry no Monte Carlo report yet).
    let hybrid_frame = match (rect, settings.method) {
        (Some(rect), Method::Hybrid) if planet.is_none() => {
            crate::render::hybrid::render(&mut buffers.image, &mut buffers.hybrid, target, view, rect, settings, *frame)
        }
        _ => None,
    };
    let traced = match (&hybrid_frame, rect) {
        (Some(h), _) => hybrid_tally(buffers, h, rect),
        (None, Some(rect)) => render_traced(buffers, target, view, options, rect, planet),
        (None, None) => Tally::default(),
    };
    if planet.is_some() {
        buffers.written_rows = 0..height as usize;
    }
    let mut stars = StarStats::default();
    if let Some(field) = &target.stars {
        stars = field.deposit(&mut buffers.image, view, &target.accel, planet.as_ref());
        // The next frame clears the rows this one wrote; stars widen them.
        let (r0, r1) = (stars.rows.0 as usize, stars.rows.1 as usize);
        if r0 < r1 {
            let w = &mut buffers.written_rows;
            *w = if w.start >= w.end { r0..r1 } else { w.start.min(r0)..w.end.max(r1) };
        }
    }
    let Tally { rays, pixels: traced_pixels, samples, primary_rasterised } = traced;
    RenderStats { time: t0.elapsed(), rays, traced_pixels, rect, primary_rasterised, samples, stars }
}

/// What a frame's sampling did.
#[derive(Default)]
struct Tally {
    rays: RayCounts,
    pixels: u64,
    samples: u64,
    primary_rasterised: bool,
}

/// A hybrid frame's tally (it wrote the rectangle's rows, and used no bands).
fn hybrid_tally<L>(buffers: &mut FrameBuffers<L>, h: &hybrid::HybridStats, rect: Option<PixelRect>) -> Tally {
    buffers.variance_valid = false;
    buffers.written_rows = rect.map_or(0..0, |r| r.row0 as usize..r.row1 as usize);
    buffers.bands_used = 0;
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
    Tally {
        rays: h.rays,
        pixels: h.covered_pixels,
        samples: h.covered_pixels * crate::render::hybrid::pattern::SAMPLES as u64,
        primary_rasterised: false,
    }
}

/// A path-traced frame's rectangle: the pixels that can see the target (silhouette
/// spans, then coverage), their primary hits rasterised or traced, sampled band by band.
fn render_traced<L: RayLog + Default + Send + Sync>(
    buffers: &mut FrameBuffers<L>,
    target: &Target,
    view: &View,
    options: &RenderOptions,
    rect: PixelRect,
    planet: Option<planet::PlacedPlanet>,
) -> Tally {
    let RenderOptions { settings, frame, primary, noise, variance, .. } = options;
    let width = view.size().0;
    let FrameBuffers {
        image: img,
        written_rows,
        raster: raster_buffers,
        coverage: box_coverage,
        coverage_of,
        bands: band_buffers,
        stat,
        variance: variance_buffer,
        silhouette: spans,
        bands_used,
        sobol,
        independent,
        ..
    } = buffers;
    let (mut rays, mut traced, mut samples) = (RayCounts::default(), 0u64, 0u64);
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
    let primary_rasterised = rasterise && raster_buffers.rebuild(target, view, rect);
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
    Tally { rays, pixels: traced, samples, primary_rasterised }
}

/// Camera samples per triangle from which primary hits are rasterised rather than traced.
const RASTER_SAMPLES_PER_TRIANGLE: u64 = 2;
