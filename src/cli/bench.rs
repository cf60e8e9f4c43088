//! `hilcam bench …`: measurements that print ratios side by side in one run.

use crate::bench::render::{measure, pose_for_coverage, print_table};
use crate::geometry::BvhLayout;
use crate::integrator::{RenderSettings, SamplerKind};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub kind: BenchKind,
}

#[derive(clap::Subcommand, Debug)]
pub enum BenchKind {
    /// Frame time and ray rate against obvhs's raw traversal on the same rays, for a
    /// target covering ~30 % and ~1 % of the frame.
    Render(RenderBenchArgs),
    /// Frame time and relative error over spp × depth × sampler; Pareto front, CSV, plot.
    Trade(crate::cli::bench_trade::TradeArgs),
}

#[derive(clap::Args, Debug)]
pub struct RenderBenchArgs {
    /// Scene file (default: the shipped satellite).
    #[arg(long, default_value = "scenes/satellite.toml")]
    pub scene: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    #[arg(long, default_value_t = 2)]
    pub depth: u32,
    /// Alternating renderer / raw rounds per case (medians are reported).
    #[arg(long, default_value_t = 5)]
    pub rounds: usize,
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Frame coverages to measure, as fractions.
    #[arg(long, value_delimiter = ',', default_values_t = [0.30, 0.01])]
    pub coverage: Vec<f64>,
    /// BVH layouts to measure.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [BvhLayout::Bvh2, BvhLayout::Cwbvh])]
    pub bvh: Vec<BvhLayout>,
}

pub fn run(a: BenchArgs) -> anyhow::Result<()> {
    match a.kind {
        BenchKind::Render(r) => render(r),
        BenchKind::Trade(t) => crate::cli::bench_trade::run(t),
    }
}

fn render(a: RenderBenchArgs) -> anyhow::Result<()> {
    rayon::ThreadPoolBuilder::new().num_threads(a.threads).build_global().ok();
    let settings = RenderSettings { spp: a.spp, depth: a.depth, sampler: SamplerKind::Cosine, ..Default::default() };
    let mut rows = Vec::new();
    for layout in &a.bvh {
        let scene = crate::scene::file::load_with_layout(&a.scene, Some(*layout))?;
        let cam = scene.camera.clone();
        println!(
            "{}: {} triangles, {:?} built in {:.0} ms; {}x{} camera; spp {} depth {}; {} threads",
            a.scene.display(),
            scene.mesh.indices.len(),
            layout,
            scene.accel.build_time.as_secs_f64() * 1e3,
            cam.width,
            cam.height,
            a.spp,
            a.depth,
            a.threads
        );
        for &c in &a.coverage {
            let pose = pose_for_coverage(&scene, &cam, &scene.pose, c);
            rows.push(measure(
                &scene,
                &cam,
                &pose,
                &settings,
                a.rounds,
                &format!("{layout:?}, ~{:.0} % of frame", c * 100.0),
            ));
        }
    }
    print_table(&rows);
    // Cost against covered pixels, per layout: the far case should cost about its share.
    for pair in rows.chunks(a.coverage.len()) {
        if let [near, far, ..] = pair {
            println!(
                "{}: covered pixels ×{:.3}, frame time ×{:.3} (far/near)",
                near.label.split(',').next().unwrap_or(""),
                far.coverage / near.coverage,
                far.frame_s / near.frame_s
            );
        }
    }
    Ok(())
}
