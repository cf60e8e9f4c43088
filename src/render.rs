//! The frame loop: (scene, camera, pose, settings, frame index) → radiance image.
//!
//! Synchronous and pure; rayon parallelises over rows. Only pixels whose area can see the
//! target's bounds are traced (the rest get the background radiance without any work),
//! so a far, small target costs in proportion to the pixels it covers. Every random
//! number is keyed by (seed, frame, pixel, sample): the same inputs give the same bytes
//! whatever the thread count.

use crate::camera::{CameraModel, PixelRect, Silhouette, View};
use crate::film::RadianceImage;
use crate::integrator::{PathContext, RayCounts, RayLog, RenderSettings};
use crate::pose::Pose;
use crate::sampling::{Rng, SampleSource, Sequence, SobolStream};
use crate::scene::Scene;
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
        let w = camera.width as usize;
        let spp = settings.spp.max(1);
        let inv_spp = 1.0 / spp as f32;
        let silhouette = Silhouette::new(view);
        let per_row: Vec<(RayCounts, L, u64)> = img
            .data
            .par_chunks_mut(w)
            .enumerate()
            .skip(rect.row0 as usize)
            .take((rect.row1 - rect.row0) as usize)
            .map(|(row, line)| {
                let mut counts = RayCounts::default();
                let mut log = L::default();
                // Columns of this row that can see the bounding sphere; the rest keep the
                // background without costing a sample.
                let (col0, col1) = match &silhouette {
                    Some(s) => match s.columns(row as u32) {
                        Some((a, b)) => (a.max(rect.col0), b.min(rect.col1)),
                        None => (0, 0),
                    },
                    None => (rect.col0, rect.col1),
                };
                for col in col0..col1 {
                    let pixel = (row * w + col as usize) as u64;
                    let mut sum = 0.0f32;
                    for s in 0..spp {
                        let v = match settings.sequence {
                            Sequence::Independent => {
                                let mut rng = Rng::for_sample(settings.seed, frame, pixel, s);
                                sample(view, &ctx, col, row, &mut rng, &mut counts, &mut log)
                            }
                            Sequence::Sobol => {
                                let mut rng = SobolStream::new(settings.seed, frame, pixel, s);
                                sample(view, &ctx, col, row, &mut rng, &mut counts, &mut log)
                            }
                        };
                        if v.is_finite() {
                            sum += v;
                        } else {
                            counts.nonfinite += 1;
                        }
                    }
                    line[col as usize] = sum * inv_spp;
                }
                (counts, log, u64::from(col1.saturating_sub(col0)))
            })
            .collect();
        for (c, l, n) in per_row {
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

/// One camera sample: a random position inside pixel (col, row), traced.
#[inline(always)]
fn sample<S: SampleSource, L: RayLog>(
    view: &View,
    ctx: &PathContext,
    col: u32,
    row: usize,
    rng: &mut S,
    counts: &mut RayCounts,
    log: &mut L,
) -> f32 {
    let j = rng.next_2d();
    let x = f64::from(col) + f64::from(j.x);
    let y = row as f64 + f64::from(j.y);
    match view.primary_ray(x, y) {
        Some(ray) => ctx.radiance(ray, rng, counts, log),
        None => ctx.scene.background,
    }
}
