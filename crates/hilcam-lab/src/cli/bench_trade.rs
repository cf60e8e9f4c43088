//! `hilcam bench trade`: the quality/time trade of spp × depth × sampler, measured (with
//! `--sensor`, its sensor axis: `bench_trade_sensor`).

use crate::bench::trade::{
    TradeGrid, best_for_error, best_for_fps, chart, measure, pareto_front, sampler_name, to_csv,
};
use anyhow::Context;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::render::integrator::Spp;
use hilcam_core::scene::limits::checked_scaled_camera;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(clap::Args, Debug)]
pub struct TradeArgs {
    /// Scene file (default: the shipped satellite).
    #[arg(long, default_value = "scenes/satellite.toml")]
    pub scene: PathBuf,
    /// Render at this many columns (same field of view; default: the camera's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Largest spp of the grid (1, 1.25, 1.5, then powers of two from 2); the reference
    /// uses 4× this at depth 4.
    #[arg(long, default_value_t = 1024)]
    pub max_spp: u32,
    /// Reference spp (default 4 × --max-spp).
    #[arg(long)]
    pub reference_spp: Option<u32>,
    /// Timed renders per point (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub rounds: usize,
    /// Recommend the lowest-error setting that renders at this frame rate.
    #[arg(long)]
    pub fps: Option<f64>,
    /// Recommend the fastest setting with at most this relative RMSE.
    #[arg(long)]
    pub error: Option<f64>,
    /// Output prefix: writes PREFIX.csv and PREFIX.png.
    #[arg(long, default_value = "trade")]
    pub out: PathBuf,
    #[arg(long)]
    pub threads: Option<usize>,
    /// Measure the sensor axis instead of the grid: frames through render + sensor at the
    /// settled auto-exposure, fixed spp against `quality = "sensor"`, judged by the share
    /// of lit pixels whose Monte Carlo noise is above k × the camera's (docs/performance.md).
    /// Uses --scene, --width, --rounds, --reference-spp (default 1024), --out, --threads.
    #[arg(long)]
    pub sensor: bool,
    /// With --sensor: the fixed-spp rows.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4", requires = "sensor")]
    pub fixed_spp: Vec<Spp>,
    /// With --sensor: the bounds k of the `quality = "sensor"` rows.
    #[arg(long, value_delimiter = ',', default_value = "1,0.5,0.25", value_parser = hilcam_core::render::integrator::QualityGoal::parse_k, requires = "sensor")]
    pub sensor_k: Vec<f32>,
    /// With --sensor: the budget (mean spp per traced pixel) of the `quality = "sensor"` rows.
    #[arg(long, default_value_t = 256, requires = "sensor")]
    pub sensor_budget: u32,
    /// With --sensor: the largest budget the k = 0.5 frame-rate sweep tries (2, 4, 8 … up
    /// to this; it stops at the first whose frames have ≤ 1 % of lit pixels above the bound,
    /// or whose frames did not spend the budget: the bound limits them, not the budget).
    #[arg(long, default_value_t = 1024, requires = "sensor")]
    pub max_budget: u32,
}

pub fn run(a: TradeArgs) -> anyhow::Result<()> {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    if a.sensor {
        return crate::cli::bench_trade_sensor::run(&a);
    }
    let scene = hilcam_core::scene::load(&a.scene)?;
    let camera = checked_scaled_camera(&scene.camera, a.width, None).map_err(anyhow::Error::msg)?;
    let pose = scene.pose;
    let mut grid = TradeGrid::standard(a.max_spp, scene.render);
    grid.rounds = a.rounds.max(1);
    if let Some(r) = a.reference_spp {
        grid.reference_spp = r.max(1);
    }
    let pipeline = FramePipeline::new(Arc::new(scene), camera.clone())?;
    println!(
        "{}: {}x{}, reference depth {} spp {} brdf; {} rounds per point (median)",
        a.scene.display(),
        camera.width,
        camera.height,
        grid.reference_depth,
        grid.reference_spp,
        grid.rounds
    );
    println!("{:>5} {:>5} {:>8} {:>11} {:>10} {:>10}", "spp", "depth", "sampler", "time (ms)", "rel RMSE", "body");
    let (points, ref_s) = measure(&pipeline, &pose, &grid, |p| {
        println!(
            "{:>5} {:>5} {:>8} {:>11.2} {:>10.4} {:>10.4}",
            p.spp,
            p.depth,
            sampler_name(p.sampler),
            p.time_s * 1e3,
            p.rel_rmse,
            p.rel_rmse_body
        )
    });
    println!("reference rendered in {ref_s:.1} s");
    let front = pareto_front(&points);
    println!("Pareto front (time ↑, error ↓):");
    for p in &front {
        println!(
            "  {:>5} spp depth {} {:<8} {:>9.2} ms  {:.4}",
            p.spp,
            p.depth,
            sampler_name(p.sampler),
            p.time_s * 1e3,
            p.rel_rmse
        );
    }
    let csv = a.out.with_extension("csv");
    std::fs::write(&csv, to_csv(&points, &front)).with_context(|| csv.display().to_string())?;
    let png = a.out.with_extension("png");
    let title = format!("{} at {}x{}: error vs frame time", a.scene.display(), camera.width, camera.height);
    chart(&points, &front, &title).save_png(&png)?;
    println!("wrote {} and {}", csv.display(), png.display());
    if let Some(fps) = a.fps {
        match best_for_fps(&front, fps) {
            Some(p) => println!(
                "at {fps} fps ({:.1} ms): spp {} depth {} {} — {:.2} ms, rel RMSE {:.4}",
                1e3 / fps,
                p.spp,
                p.depth,
                sampler_name(p.sampler),
                p.time_s * 1e3,
                p.rel_rmse
            ),
            None => println!("at {fps} fps: no measured setting is fast enough"),
        }
    }
    if let Some(e) = a.error {
        // On the relative RMSE, then on the body error (glints left out; see `bench::trade`).
        let body: Vec<_> = points.iter().map(|p| p.by_body_error()).collect();
        for (metric, front) in [("rel RMSE", front.clone()), ("body rel RMSE", pareto_front(&body))] {
            match best_for_error(&front, e) {
                Some(p) => println!(
                    "for {metric} ≤ {e}: spp {} depth {} {} — {:.2} ms ({:.1} fps), {metric} {:.4}",
                    p.spp,
                    p.depth,
                    sampler_name(p.sampler),
                    p.time_s * 1e3,
                    1.0 / p.time_s,
                    p.rel_rmse
                ),
                None => println!("for {metric} ≤ {e}: no measured setting is accurate enough"),
            }
        }
    }
    Ok(())
}
