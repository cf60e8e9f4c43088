//! `hilcam bench render`: renderer throughput against obvhs's raw traversal rate on the
//! same rays, and how frame cost follows the pixels the target covers.
//!
//! The renderer runs with a ray recorder once; the recorded rays (closest-hit: primary and
//! bounce; any-hit: shadow) are then re-traced through the bare BVH with the same rayon
//! split. Renderer and raw runs alternate, and medians are compared, so both see the same
//! machine load.

use super::median;
use crate::sun_shadow::SunShadow;
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::geometry::Ray;
use hilcam_core::render::integrator::{RecordedRays, RenderSettings};
use hilcam_core::render::{FrameBuffers, PrimaryVisibility, RenderOptions, render, render_into};
use hilcam_core::scene::Scene;
use rayon::prelude::*;
use std::time::Instant;

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct RenderBenchRow {
    pub label: String,
    pub range_m: f64,
    /// Fraction of pixels whose centre ray hits the target.
    pub coverage: f64,
    pub traced_pixels: u64,
    pub frame_s: f64,
    pub rays: u64,
    pub render_mrays: f64,
    pub raw_mrays: f64,
    /// Shadow rays toward the sun, re-traced through the sun grid and through the BVH.
    pub shadow_rays: u64,
    pub grid_mrays: f64,
    pub bvh_shadow_mrays: f64,
    /// Building the sun grid for this frame's sun (median), milliseconds.
    pub grid_build_ms: f64,
    /// Rebuilding it in place for another direction (buffers reused), milliseconds.
    pub grid_rebuild_ms: f64,
    pub grid_entries: usize,
    /// Frame times with every primary ray traced through the BVH (in packets where the tree
    /// walks them), and with all rasterised (`frame_s`: the default, `auto`).
    pub frame_traced_s: f64,
    pub frame_raster_s: f64,
    pub traced_pixels_traced: u64,
    pub traced_pixels_raster: u64,
    /// Whether the default rasterised this frame.
    pub rasterised: bool,
    /// Mean cell entries read and triangle tests run per shadow ray by the grid.
    pub grid_reads: f64,
    pub grid_tests: f64,
}

impl RenderBenchRow {
    pub fn ratio(&self) -> f64 {
        self.render_mrays / self.raw_mrays
    }
}

/// Fraction of pixels (centre rays, on a coarse grid) whose ray hits the target.
pub fn coverage(scene: &Scene, camera: &CameraModel, pose: &Pose) -> f64 {
    let view = scene.view(camera, pose);
    let step = (camera.width.max(camera.height) / 256).max(1);
    let (mut n, mut hit) = (0u64, 0u64);
    for row in (0..camera.height).step_by(step as usize) {
        for col in (0..camera.width).step_by(step as usize) {
            n += 1;
            if let Some(r) = view.primary_ray(f64::from(col) + 0.5, f64::from(row) + 0.5) {
                hit += scene.accel.intersect(&r).is_some() as u64;
            }
        }
    }
    hit as f64 / n as f64
}

/// The pose moved along its line of sight so the target covers `fraction` of the frame
/// (coverage scales as 1/range² for a target well inside the field of view).
pub fn pose_for_coverage(scene: &Scene, camera: &CameraModel, pose: &Pose, fraction: f64) -> Pose {
    let mut p = *pose;
    for _ in 0..6 {
        let c = coverage(scene, camera, &p);
        if c <= 0.0 {
            p.position *= 0.5;
            continue;
        }
        let k = (c / fraction).sqrt().clamp(0.25, 4.0);
        p.position *= k;
        if (c / fraction - 1.0).abs() < 0.03 {
            break;
        }
    }
    p
}

fn trace_raw(scene: &Scene, logs: &[RecordedRays]) -> f64 {
    let closest: Vec<&Ray> = logs.iter().flat_map(|l| l.closest.iter()).collect();
    let shadow: Vec<&Ray> = logs.iter().flat_map(|l| l.shadow.iter()).collect();
    let t0 = Instant::now();
    let hits: usize =
        closest.par_chunks(4096).map(|c| c.iter().filter(|r| scene.accel.intersect(r).is_some()).count()).sum();
    let occluded: usize = shadow.par_chunks(4096).map(|c| c.iter().filter(|r| scene.accel.occluded(r)).count()).sum();
    std::hint::black_box((hits, occluded));
    t0.elapsed().as_secs_f64()
}

/// Shadow rays re-traced through the sun grid (`Some`) or the BVH (`None`), seconds.
fn trace_shadow(scene: &Scene, grid: Option<&SunShadow>, rays: &[Ray]) -> f64 {
    let t0 = Instant::now();
    let occluded: usize = rays
        .par_chunks(4096)
        .map(|c| match grid {
            Some(g) => c.iter().filter(|r| g.occluded(r).unwrap_or_else(|| scene.accel.occluded(r))).count(),
            None => c.iter().filter(|r| scene.accel.occluded(r)).count(),
        })
        .sum();
    std::hint::black_box(occluded);
    t0.elapsed().as_secs_f64()
}

/// Measure one configuration: `rounds` alternating renderer / raw-traversal runs.
pub fn measure(
    scene: &Scene,
    camera: &CameraModel,
    pose: &Pose,
    settings: &RenderSettings,
    rounds: usize,
    label: &str,
) -> RenderBenchRow {
    // The defaults (primary hits as `auto` finds them) with every ray recorded.
    let view = scene.view(camera, pose);
    let options = RenderOptions::new(*settings, 0);
    let mut buffers = FrameBuffers::<RecordedRays>::default();
    let stats = render_into(&mut buffers, scene, &view, &options);
    let logs = buffers.take_ray_logs();
    let recorded: u64 = logs.iter().map(|l| (l.closest.len() + l.shadow.len()) as u64).sum();
    // Every ray the renderer traced must be re-traced, or the ratio compares different work.
    assert_eq!(recorded, stats.rays.total(), "ray log incomplete");
    let with = |p| render(scene, &view, &options.with_primary(p)).1;
    let traced_pixels_traced = with(PrimaryVisibility::Trace).traced_pixels;
    let traced_pixels_raster = with(PrimaryVisibility::Raster).traced_pixels;
    // Alternating: the defaults, the raw re-trace, every primary ray traced, all rasterised.
    let (mut t_render, mut t_raw) = (Vec::new(), Vec::new());
    let (mut t_render_traced, mut t_render_raster) = (Vec::new(), Vec::new());
    for _ in 0..rounds.max(1) {
        let (_, s) = render(scene, &view, &options);
        t_render.push(s.time.as_secs_f64());
        t_raw.push(trace_raw(scene, &logs));
        t_render_traced.push(with(PrimaryVisibility::Trace).time.as_secs_f64());
        t_render_raster.push(with(PrimaryVisibility::Raster).time.as_secs_f64());
    }
    let (tr, tw) = (median(t_render), median(t_raw));
    // Shadow rays: sun grid and BVH alternately on the same rays; the grid's build time.
    let shadow: Vec<Ray> = logs.iter().flat_map(|l| l.shadow.iter().copied()).collect();
    let sun = shadow.first().map_or(glam::Vec3::Z, |r| r.dir);
    let (mut t_grid, mut t_bvh, mut t_build, mut t_rebuild) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut grid = SunShadow::build(&scene.mesh, sun);
    for _ in 0..rounds.max(1) {
        let g = SunShadow::build(&scene.mesh, sun);
        t_build.push(g.stats.build_time.as_secs_f64());
        // In place for a slightly different sun and back, as consecutive frames would.
        grid.rebuild(glam::Vec3::new(sun.x, sun.y + 1e-3, sun.z).normalize());
        grid.rebuild(sun);
        t_rebuild.push(grid.stats.build_time.as_secs_f64());
        t_grid.push(trace_shadow(scene, Some(&grid), &shadow));
        t_bvh.push(trace_shadow(scene, None, &shadow));
    }
    let n_shadow = shadow.len() as f64;
    let (read, tests) = shadow.iter().filter_map(|r| grid.cost_of(r)).fold((0, 0), |(a, b), (r, t)| (a + r, b + t));
    RenderBenchRow {
        label: label.to_string(),
        range_m: pose.position.length(),
        coverage: coverage(scene, camera, pose),
        traced_pixels: stats.traced_pixels,
        frame_s: tr,
        rays: recorded,
        render_mrays: recorded as f64 / tr / 1e6,
        raw_mrays: recorded as f64 / tw / 1e6,
        shadow_rays: shadow.len() as u64,
        grid_mrays: n_shadow / median(t_grid) / 1e6,
        bvh_shadow_mrays: n_shadow / median(t_bvh) / 1e6,
        grid_build_ms: median(t_build) * 1e3,
        grid_rebuild_ms: median(t_rebuild) * 1e3,
        grid_entries: grid.stats.entries,
        frame_traced_s: median(t_render_traced),
        frame_raster_s: median(t_render_raster),
        traced_pixels_traced,
        traced_pixels_raster,
        rasterised: stats.primary_rasterised,
        grid_reads: read as f64 / n_shadow,
        grid_tests: tests as f64 / n_shadow,
    }
}

pub fn print_table(rows: &[RenderBenchRow]) {
    println!(
        "{:<28} {:>9} {:>8} {:>9} {:>9} {:>7} {:>10} {:>10} {:>10} {:>7}",
        "case", "range m", "cover %", "traced px", "frame ms", "fps", "rays", "hilcam Mr/s", "obvhs Mr/s", "ratio"
    );
    for r in rows {
        println!(
            "{:<28} {:>9.1} {:>8.2} {:>9} {:>9.1} {:>7.1} {:>10} {:>10.2} {:>10.2} {:>6.0}%",
            r.label,
            r.range_m,
            r.coverage * 100.0,
            r.traced_pixels,
            r.frame_s * 1e3,
            1.0 / r.frame_s,
            r.rays,
            r.render_mrays,
            r.raw_mrays,
            r.ratio() * 100.0
        );
    }
}

/// The shadow-ray table: sun grid against the BVH on the same recorded rays.
pub fn print_shadow_table(rows: &[RenderBenchRow]) {
    println!(
        "{:<28} {:>10} {:>10} {:>9} {:>7} {:>9} {:>10} {:>8} {:>9} {:>9} {:>11}",
        "shadow rays",
        "rays",
        "grid Mr/s",
        "BVH Mr/s",
        "ratio",
        "build ms",
        "rebuild ms",
        "entries",
        "reads/ray",
        "tests/ray",
        "frame ms"
    );
    for r in rows {
        println!(
            "{:<28} {:>10} {:>10.2} {:>9.2} {:>6.2}x {:>9.1} {:>10.1} {:>8} {:>9.2} {:>9.2} {:>11.1}",
            r.label,
            r.shadow_rays,
            r.grid_mrays,
            r.bvh_shadow_mrays,
            r.grid_mrays / r.bvh_shadow_mrays,
            r.grid_build_ms,
            r.grid_rebuild_ms,
            r.grid_entries,
            r.grid_reads,
            r.grid_tests,
            r.frame_s * 1e3
        );
    }
}

/// Rasterised against traced primary hits: frame times of the same frame, alternated.
pub fn print_primary_table(rows: &[RenderBenchRow]) {
    println!(
        "{:<28} {:>11} {:>11} {:>11} {:>11} {:>10} {:>16}",
        "primary hits", "raster px", "traced px", "raster ms", "traced ms", "speed-up", "default"
    );
    for r in rows {
        println!(
            "{:<28} {:>11} {:>11} {:>11.1} {:>11.1} {:>9.2}x {:>16}",
            r.label,
            r.traced_pixels_raster,
            r.traced_pixels_traced,
            r.frame_raster_s * 1e3,
            r.frame_traced_s * 1e3,
            r.frame_traced_s / r.frame_raster_s,
            if r.rasterised { "rasterises" } else { "traces" }
        );
    }
}
