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

mod tile;
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
    let t0 = Instant::now();
    let mut img = RadianceImage::new(camera.width, camera.height, scene.background);
    let rect = if scene.accel.is_empty() { None } else { view.pixel_rect() };
    let mut rays = RayCounts::default();
    let mut logs = Vec::new();
    let mut traced = 0u64;
    if let Some(rect) = rect {
        let ctx = PathContext::new(scene, view.sun, settings);
        let job = TileJob {
            view,
            ctx: &ctx,
            seed: settings.seed,
            frame,
            spp: settings.spp.max(1),
            width: camera.width as usize,
        };
        let silhouette = Silhouette::new(view);
        // Columns of a row that can see the target's bounds; the rest keep the background
        // without costing a sample.
        let span = |row: u32| -> (u32, u32) {
            match &silhouette {
                Some(s) => s.columns(row).map_or((0, 0), |(a, b)| (a.max(rect.col0), b.min(rect.col1))),
                None => (rect.col0, rect.col1),
            }
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
    let stats = RenderStats { time: t0.elapsed(), rays, traced_pixels: traced, rect };
    (img, stats, logs)
}

/// Rows per band: a band is one rayon task; its pixels are cut into tiles of a few
/// columns × all its rows, so a tile is compact on the image.
const BAND_ROWS: usize = 8;

/// Render the rectangle's rows band by band (rayon over bands), each band tile by tile.
fn render_bands<S: PerSample + Send, L: RayLog + Default + Send>(
    job: &TileJob,
    img: &mut RadianceImage,
    rect: PixelRect,
    span: &(dyn Fn(u32) -> (u32, u32) + Sync),
) -> Vec<(RayCounts, L, u64)> {
    let w = job.width;
    let spp = job.spp as usize;
    let inv_spp = 1.0 / job.spp as f32;
    // Tile width in columns: about TILE_PATHS camera samples per tile.
    let tile_cols = (TILE_PATHS / (BAND_ROWS * spp)).max(1) as u32;
    let (row0, row1) = (rect.row0 as usize, rect.row1 as usize);
    img.data[row0 * w..row1 * w]
        .par_chunks_mut(w * BAND_ROWS)
        .enumerate()
        .map_init(
            || (Scratch::<S>::default(), Vec::new()),
            |(scratch, pixels), (band, out)| {
                let first_row = row0 + band * BAND_ROWS;
                let rows = (first_row..first_row + out.len() / w).map(|r| r as u32);
                let spans: Vec<(u32, u32)> = rows.clone().map(span).collect();
                let mut counts = RayCounts::default();
                let mut log = L::default();
                let n: u64 = spans.iter().map(|&(a, b)| u64::from(b.saturating_sub(a))).sum();
                let c_min = spans.iter().filter(|s| s.0 < s.1).map(|s| s.0).min().unwrap_or(0);
                let c_max = spans.iter().filter(|s| s.0 < s.1).map(|s| s.1).max().unwrap_or(0);
                let mut c0 = c_min;
                while c0 < c_max {
                    let c1 = (c0 + tile_cols).min(c_max);
                    pixels.clear();
                    for (row, &(a, b)) in rows.clone().zip(&spans) {
                        pixels.extend((a.max(c0)..b.min(c1)).map(|col| (row, col)));
                    }
                    let samples = job.trace(pixels, scratch, &mut counts, &mut log);
                    for (&(row, col), v) in pixels.iter().zip(samples.chunks_exact(spp)) {
                        let mut sum = 0.0f32;
                        for &v in v {
                            if v.is_finite() {
                                sum += v;
                            } else {
                                counts.nonfinite += 1;
                            }
                        }
                        out[(row as usize - first_row) * w + col as usize] = sum * inv_spp;
                    }
                    c0 = c1;
                }
                (counts, log, n)
            },
        )
        .collect()
}
