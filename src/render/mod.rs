//! The frame loop: (scene, camera, pose, settings, frame index) → radiance image.
//!
//! Synchronous and pure; rayon parallelises over bands of rows, each band is traced tile
//! by tile in waves (`tile`). Only pixels whose area can see the target's bounds are
//! sampled (per-row spans, `camera::Silhouette`; the rest get the background radiance
//! without any work), so a far, small target costs in proportion to the pixels it
//! covers. Every random
//! number is keyed by (seed, frame, pixel, sample): the same inputs give the same bytes
//! whatever the thread count.

use crate::camera::{CameraModel, PixelRect, Silhouette, View};
use crate::film::RadianceImage;
use crate::integrator::{PathContext, RayCounts, RayLog, RenderSettings};
use crate::pose::Pose;
use crate::sampling::{PerSample, Rng, Sequence, SobolStream};
use crate::scene::Scene;
use tile::{Scratch, TILE_PATHS, TileJob};
use visibility::PrimaryRaster;

mod tile;
pub mod visibility;
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
    /// True when the primary hits were rasterised (`visibility`), false when traced.
    pub primary_rasterised: bool,
}

/// How primary hits are found. Both give the same hits (see `visibility`); tracing is
/// kept for comparison and for views the rasteriser declines.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum PrimaryVisibility {
    /// Rasterise when that is exact and pays (enough camera samples per triangle), else
    /// trace.
    #[default]
    Auto,
    /// Rasterise whenever that is exact.
    Raster,
    /// Trace every primary ray through the BVH.
    Trace,
}

impl RenderStats {
    pub fn mrays_per_s(&self) -> f64 {
        self.rays.total() as f64 / self.time.as_secs_f64().max(1e-12) / 1e6
    }
}

/// Render one frame through an already placed view (e.g. with lens distortion).
pub fn render_view(
    scene: &Scene,
    camera: &CameraModel,
    view: &View,
    settings: &RenderSettings,
    frame: u64,
) -> (RadianceImage, RenderStats) {
    let (img, stats, _) = render_view_logged::<()>(scene, camera, view, settings, frame);
    (img, stats)
}

/// Render one frame.
pub fn render(
    scene: &Scene,
    camera: &CameraModel,
    pose: &Pose,
    settings: &RenderSettings,
    frame: u64,
) -> (RadianceImage, RenderStats) {
    let (img, stats, _) = render_logged::<()>(scene, camera, pose, settings, frame);
    (img, stats)
}

/// Render one frame and hand every traced ray to a per-row `L` (benchmarks).
pub fn render_logged<L: RayLog + Default + Send>(
    scene: &Scene,
    camera: &CameraModel,
    pose: &Pose,
    settings: &RenderSettings,
    frame: u64,
) -> (RadianceImage, RenderStats, Vec<L>) {
    let view = View::new(camera, pose, scene.frame_origin_body, scene.bounds);
    render_view_logged(scene, camera, &view, settings, frame)
}

fn render_view_logged<L: RayLog + Default + Send>(
    scene: &Scene,
    camera: &CameraModel,
    view: &View,
    settings: &RenderSettings,
    frame: u64,
) -> (RadianceImage, RenderStats, Vec<L>) {
    render_view_with(scene, camera, view, settings, frame, PrimaryVisibility::default())
}

/// Render one frame through `view`, choosing how primary hits are found, and hand every
/// traced ray to a per-band `L` (benchmarks and tests).
pub fn render_view_with<L: RayLog + Default + Send>(
    scene: &Scene,
    camera: &CameraModel,
    view: &View,
    settings: &RenderSettings,
    frame: u64,
    primary: PrimaryVisibility,
) -> (RadianceImage, RenderStats, Vec<L>) {
    let t0 = Instant::now();
    let mut img = RadianceImage::new(camera.width, camera.height, scene.background);
    let rect = if scene.accel.is_empty() { None } else { view.pixel_rect() };
    let mut rays = RayCounts::default();
    let mut logs = Vec::new();
    let mut traced = 0u64;
    let mut primary_rasterised = false;
    if let Some(rect) = rect {
        let ctx = PathContext::new(scene, view.sun, settings);
        let silhouette = Silhouette::new(view);
        // Columns of a row that can see the target's bounds; the rest keep the background
        // without costing a sample.
        let span = |row: u32| -> (u32, u32) {
            match &silhouette {
                Some(s) => s.columns(row).map_or((0, 0), |(a, b)| (a.max(rect.col0), b.min(rect.col1))),
                None => (rect.col0, rect.col1),
            }
        };
        // Rasterising costs a pass over every triangle per frame (projection, binning) and
        // saves part of each camera sample's traversal; measured on the shipped satellite
        // (`hilcam bench render`, "primary hits") it pays from about two samples per
        // triangle on (30 % of the frame: 1.15× faster; 1 %: 0.5×, i.e. slower).
        let samples: u64 = (rect.row0..rect.row1)
            .map(|r| {
                let (a, b) = span(r);
                u64::from(b.saturating_sub(a))
            })
            .sum::<u64>()
            * u64::from(settings.spp.max(1));
        let pays = samples >= RASTER_SAMPLES_PER_TRIANGLE * scene.accel.len() as u64;
        let raster = match primary {
            PrimaryVisibility::Auto if pays => PrimaryRaster::new(scene, view, rect),
            PrimaryVisibility::Raster => PrimaryRaster::new(scene, view, rect),
            PrimaryVisibility::Auto | PrimaryVisibility::Trace => None,
        };
        primary_rasterised = raster.is_some();
        let job = TileJob {
            view,
            ctx: &ctx,
            raster: raster.as_ref(),
            seed: settings.seed,
            frame,
            spp: settings.spp.max(1),
            width: camera.width as usize,
        };
        let per_band: Vec<(RayCounts, L, u64)> = match settings.sequence {
            Sequence::Independent => render_bands::<Rng, L>(&job, &mut img, rect, &span),
            Sequence::Sobol => render_bands::<SobolStream, L>(&job, &mut img, rect, &span),
        };
        for (c, l, n) in per_band {
            rays.add(&c);
            logs.push(l);
            traced += n;
        }
        if rays.nonfinite > 0 {
            tracing::warn!(samples = rays.nonfinite, "non-finite radiance samples dropped");
        }
    }
    let stats = RenderStats { time: t0.elapsed(), rays, traced_pixels: traced, rect, primary_rasterised };
    (img, stats, logs)
}

/// Camera samples per triangle from which primary hits are rasterised rather than traced.
const RASTER_SAMPLES_PER_TRIANGLE: u64 = 2;

/// Rows per band: a band is one rayon task; its pixels are cut into tiles of a few
/// columns × all its rows, so a tile is compact on the image.
const BAND_ROWS: usize = 8;

/// Render the rectangle's rows band by band (rayon over bands), each band pass by pass.
fn render_bands<S: PerSample + Send, L: RayLog + Default + Send>(
    job: &TileJob,
    img: &mut RadianceImage,
    rect: PixelRect,
    span: &(dyn Fn(u32) -> (u32, u32) + Sync),
) -> Vec<(RayCounts, L, u64)> {
    let w = job.width;
    let inv_spp = 1.0 / job.spp as f32;
    // Tile width in columns: about TILE_PATHS pixels per tile.
    let tile_cols = (TILE_PATHS / BAND_ROWS).max(1) as u32;
    let (row0, row1) = (rect.row0 as usize, rect.row1 as usize);
    img.data[row0 * w..row1 * w]
        .par_chunks_mut(w * BAND_ROWS)
        .enumerate()
        .map_init(
            || (Scratch::<S>::default(), Vec::new(), Vec::new()),
            |(scratch, pixels, sums), (band, out)| {
                let first_row = row0 + band * BAND_ROWS;
                let rows = (first_row..first_row + out.len() / w).map(|r| r as u32);
                let spans: Vec<(u32, u32)> = rows.clone().map(span).collect();
                let mut counts = RayCounts::default();
                let mut log = L::default();
                // The band's pixels in tile order: blocks of `tile_cols` columns × all rows.
                pixels.clear();
                let c_min = spans.iter().filter(|s| s.0 < s.1).map(|s| s.0).min().unwrap_or(0);
                let c_max = spans.iter().filter(|s| s.0 < s.1).map(|s| s.1).max().unwrap_or(0);
                for c0 in (c_min..c_max).step_by(tile_cols as usize) {
                    let c1 = (c0 + tile_cols).min(c_max);
                    for (row, &(a, b)) in rows.clone().zip(&spans) {
                        let cols = a.max(c0)..b.min(c1);
                        match job.raster {
                            Some(r) => pixels.extend(cols.filter(|&col| r.may_hit(row, col)).map(|col| (row, col))),
                            None => pixels.extend(cols.map(|col| (row, col))),
                        }
                    }
                }
                sums.clear();
                sums.resize(pixels.len(), 0.0f32);
                for s in 0..job.spp {
                    let samples = job.trace_pass(pixels, s, scratch, &mut counts, &mut log);
                    for (sum, &v) in sums.iter_mut().zip(samples) {
                        if v.is_finite() {
                            *sum += v;
                        } else {
                            counts.nonfinite += 1;
                        }
                    }
                }
                for (&(row, col), &sum) in pixels.iter().zip(sums.iter()) {
                    out[(row as usize - first_row) * w + col as usize] = sum * inv_spp;
                }
                (counts, log, pixels.len() as u64)
            },
        )
        .collect()
}
