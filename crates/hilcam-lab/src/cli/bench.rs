//! `hilcam bench …`: measurements that print ratios side by side in one run.

use crate::bench::render::{measure, pose_for_coverage, print_primary_table, print_shadow_table, print_table};
use crate::bench::table1::{GlintConfig, Table1Config, run_glints, run_table1};
use hilcam_core::render::geometry::BvhLayout;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind};
use hilcam_core::scene::fold::FoldLevel;
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
    /// The paper's Table 1: uniform vs cosine (vs the BRDF's MIS) indirect sampling on
    /// fold planes, RMSE against a converged reference; CSV, plots and image grids.
    Sampling(SamplingBenchArgs),
    /// The paper's Fig. 7 glint case: gold polyimide, cosine vs MIS at equal rays and time.
    Glints(GlintBenchArgs),
    /// Frame time and relative error over spp × depth × sampler; Pareto front, CSV, plot.
    /// With `--sensor`: fixed spp against `quality = "sensor"`, noise against the camera's.
    Trade(crate::cli::bench_trade::TradeArgs),
    /// Latency (pose arrival → last byte out) beside render time through the real server,
    /// at the navigation camera and the paper's camera scaled down.
    Serve(ServeBenchArgs),
    /// What each optional effect (motion blur, rolling shutter, stars, planet) costs: the
    /// shipped satellite with and without it, frames through render + sensor, in turn.
    Effects(EffectsBenchArgs),
    /// Sensor-equivalent frames judged independently: per row, many seeds of one pose
    /// through render + sensor, the share of lit pixels whose noise (and whose RMS error
    /// against a converged reference) exceeds half the camera's own, with the frame rate.
    Quality(crate::cli::bench_quality::QualityArgs),
    /// Radiance frames (PFM) through a scene camera's sensor chain to photo-charge, as
    /// `bench quality` converts its own at the held exposure: for an outside judge
    /// (benches/vs_mitsuba.py --criterion).
    Charge(crate::cli::bench_quality::ChargeArgs),
    /// The fixed per-frame costs: the sensor stage and the ground-truth pass, each beside
    /// the frame it belongs to, measured in the same rounds.
    Sensor(SensorBenchArgs),
}

#[derive(clap::Args, Debug)]
pub struct SensorBenchArgs {
    /// Scene file (its camera, sensor, pose and settings).
    #[arg(long, default_value = "scenes/satellite.toml")]
    pub scene: PathBuf,
    /// Samples per pixel of the frames.
    #[arg(long, default_value_t = 2)]
    pub spp: u32,
    /// Timed rounds (after one untimed); medians are reported.
    #[arg(long, default_value_t = 10)]
    pub rounds: usize,
    /// Conversions of each round's frame by the sensor alone (all go into its median).
    #[arg(long, default_value_t = 3)]
    pub sensor_repeat: usize,
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Truth channel sets to time, each as `depth,mask,…` (repeat the flag for more).
    #[arg(long, value_parser = hilcam_core::render::truth::TruthChannels::parse,
          default_values = ["depth,mask", "depth,mask,normal,body_xyz"])]
    pub truth: Vec<hilcam_core::render::truth::TruthChannels>,
}

#[derive(clap::Args, Debug)]
pub struct EffectsBenchArgs {
    /// Scene files; the first is the reference the others are compared with.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "scenes/satellite.toml,scenes/satellite_blur.toml,scenes/satellite_rolling.toml,scenes/satellite_stars.toml,scenes/satellite_earth.toml"
    )]
    pub scenes: Vec<std::path::PathBuf>,
    /// Camera width (default: each scene's own, 1024 for the shipped satellite).
    #[arg(long)]
    pub width: Option<u32>,
    /// Timed frames per scene (after one untimed); medians are compared.
    #[arg(long, default_value_t = 5)]
    pub rounds: usize,
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
}

#[derive(clap::Args, Debug)]
pub struct ServeBenchArgs {
    /// Frames per case.
    #[arg(long, default_value_t = 20)]
    pub frames: u64,
    /// Width of the paper camera's scaled-down case.
    #[arg(long, default_value_t = 1024)]
    pub paper_width: u32,
    /// Samples per pixel for both cases (each scene's own depth is kept).
    #[arg(long, default_value_t = 2)]
    pub spp: u32,
    /// Instead of the two cameras: the satellite's nav camera with ground truth off, then
    /// on with these channels (`depth,mask,normal,body_xyz`), and truth's share of each
    /// frame from the server's own histograms.
    #[arg(long, value_parser = hilcam_core::render::truth::TruthChannels::parse)]
    pub truth: Option<hilcam_core::render::truth::TruthChannels>,
}

#[derive(clap::Args, Debug)]
pub struct SamplingBenchArgs {
    /// slight | medium | severe | all
    #[arg(long, default_value = "all")]
    pub level: String,
    /// Image side, pixels (the disk fills the frame).
    #[arg(long, default_value_t = 64)]
    pub size: u32,
    /// Rays (samples) per pixel of the table's columns.
    #[arg(long, value_delimiter = ',', default_values_t = [1, 10, 100, 500, 1000])]
    pub spp: Vec<u32>,
    /// Samples of each of the reference's two halves (cosine, Sobol).
    #[arg(long, default_value_t = 2048)]
    pub ref_half_spp: u32,
    #[arg(long, default_value_t = 4)]
    pub depth: u32,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Seed of the fold planes.
    #[arg(long, default_value_t = 0)]
    pub fold_seed: u64,
    /// Skip the second table (all samplers again with the Sobol sequence).
    #[arg(long)]
    pub no_sobol: bool,
    /// Parallel sun's irradiance, W/m².
    #[arg(long, default_value_t = crate::bench::sampling::PAPER_IRRADIANCE)]
    pub sun: f64,
    /// Radiance of the uniform sky that escaping rays collect, W·sr⁻¹·m⁻² (0 = black sky;
    /// 100 reads the paper's "radiance 100" as also lighting escaped rays, Fig. 2 step 2).
    #[arg(long, default_value_t = 0.0)]
    pub sky: f64,
    /// Directory for table1.csv/.txt, rmse_<level>.png and grid_<level>.png.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
}

#[derive(clap::Args, Debug)]
pub struct GlintBenchArgs {
    #[arg(long, default_value_t = 64)]
    pub size: u32,
    #[arg(long, value_delimiter = ',', default_values_t = [4, 16, 64, 256])]
    pub spp: Vec<u32>,
    /// Samples of each of the reference's two halves (brdf, Sobol).
    #[arg(long, default_value_t = 2048)]
    pub ref_half_spp: u32,
    #[arg(long, default_value_t = 4)]
    pub depth: u32,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long, default_value_t = 0)]
    pub fold_seed: u64,
    /// Sun angles from the plane normal, degrees.
    #[arg(long, value_delimiter = ',', default_values_t = [3.0, 6.0])]
    pub theta_i: Vec<f64>,
    /// Directory for glints.csv/.txt and the reference images.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
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
    #[arg(long, value_parser = hilcam_core::scene::file::parse_name::<BvhLayout>, value_delimiter = ',', default_value = "bvh2,cwbvh,bvh4,bvh8")]
    pub bvh: Vec<BvhLayout>,
}

pub fn run(a: BenchArgs) -> anyhow::Result<()> {
    match a.kind {
        BenchKind::Render(r) => render(r),
        BenchKind::Sampling(s) => sampling(s),
        BenchKind::Glints(g) => glints(g),
        BenchKind::Trade(t) => crate::cli::bench_trade::run(t),
        BenchKind::Serve(s) => serve_bench(s),
        BenchKind::Effects(e) => effects(e),
        BenchKind::Quality(q) => crate::cli::bench_quality::run(q),
        BenchKind::Charge(c) => crate::cli::bench_quality::run_charge(c),
        BenchKind::Sensor(s) => fixed_costs(s),
    }
}

fn fixed_costs(a: SensorBenchArgs) -> anyhow::Result<()> {
    use crate::bench::fixed_costs::{measure, print};
    rayon::ThreadPoolBuilder::new().num_threads(a.threads).build_global().ok();
    anyhow::ensure!(a.rounds > 0 && a.spp > 0, "--rounds and --spp must be > 0");
    println!("{}: spp {}, {} rounds, {} threads, medians", a.scene.display(), a.spp, a.rounds, a.threads);
    let spp = hilcam_core::render::integrator::Spp::whole(a.spp);
    print(&measure(&a.scene, spp, a.rounds, a.sensor_repeat, &a.truth)?);
    Ok(())
}

fn effects(a: EffectsBenchArgs) -> anyhow::Result<()> {
    use crate::bench::effects::{measure, print_table};
    rayon::ThreadPoolBuilder::new().num_threads(a.threads).build_global().ok();
    anyhow::ensure!(a.rounds > 0 && !a.scenes.is_empty(), "--rounds and --scenes must not be empty");
    println!("{} rounds, {} threads; frames through render + sensor, medians", a.rounds, a.threads);
    print_table(&measure(&a.scenes, a.width, a.rounds)?);
    Ok(())
}

fn sampling(a: SamplingBenchArgs) -> anyhow::Result<()> {
    rayon::ThreadPoolBuilder::new().num_threads(a.threads).build_global().ok();
    let levels =
        if a.level.eq_ignore_ascii_case("all") { FoldLevel::ALL.to_vec() } else { vec![a.level.parse::<FoldLevel>()?] };
    anyhow::ensure!(a.size > 0 && !a.spp.is_empty() && a.spp.iter().all(|n| *n > 0), "--size and --spp must be > 0");
    anyhow::ensure!(
        a.sun.is_finite() && a.sun >= 0.0 && a.sky.is_finite() && a.sky >= 0.0,
        "--sun and --sky must be finite and ≥ 0"
    );
    let cfg = Table1Config {
        levels,
        size: a.size,
        spps: a.spp,
        ref_half_spp: a.ref_half_spp.max(1),
        depth: a.depth.max(1),
        seed: a.seed,
        fold_seed: a.fold_seed,
        sobol: !a.no_sobol,
        sun: a.sun,
        sky: a.sky,
        out: a.out,
    };
    run_table1(&cfg)?;
    Ok(())
}

fn glints(a: GlintBenchArgs) -> anyhow::Result<()> {
    rayon::ThreadPoolBuilder::new().num_threads(a.threads).build_global().ok();
    anyhow::ensure!(a.size > 0 && !a.spp.is_empty() && a.spp.iter().all(|n| *n > 0), "--size and --spp must be > 0");
    let cfg = GlintConfig {
        size: a.size,
        spps: a.spp,
        ref_half_spp: a.ref_half_spp.max(1),
        depth: a.depth.max(1),
        seed: a.seed,
        fold_seed: a.fold_seed,
        theta_i_deg: a.theta_i,
        out: a.out,
    };
    run_glints(&cfg)?;
    Ok(())
}

fn render(a: RenderBenchArgs) -> anyhow::Result<()> {
    rayon::ThreadPoolBuilder::new().num_threads(a.threads).build_global().ok();
    let settings = RenderSettings {
        spp: hilcam_core::render::integrator::Spp::whole(a.spp),
        depth: a.depth,
        sampler: SamplerKind::Cosine,
        ..Default::default()
    };
    let mut rows = Vec::new();
    for layout in &a.bvh {
        let scene = hilcam_core::scene::file::load_with_layout(&a.scene, Some(*layout))?;
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
    print_primary_table(&rows);
    print_shadow_table(&rows);
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

fn serve_bench(a: ServeBenchArgs) -> anyhow::Result<()> {
    use crate::bench::serve::{measure, print_table};
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    let spp = hilcam_core::render::integrator::Spp::whole(a.spp);
    let satellite = std::path::Path::new("scenes/satellite.toml");
    let rows = rt.block_on(async {
        if let Some(truth) = a.truth {
            let none = hilcam_core::render::truth::TruthChannels::NONE;
            let off = measure(satellite, 1024, spp, a.frames, none, "satellite 1024², truth off").await?;
            let label = format!("satellite 1024², truth {truth}");
            let on = measure(satellite, 1024, spp, a.frames, truth, &label).await?;
            return anyhow::Ok(vec![off, on]);
        }
        let nav = measure(satellite, 1024, spp, a.frames, Default::default(), "satellite, nav camera 1024²").await?;
        let label = format!("Jason, paper camera at {}²", a.paper_width);
        let paper = measure(
            std::path::Path::new("scenes/jason_paper.toml"),
            a.paper_width,
            spp,
            a.frames,
            Default::default(),
            &label,
        )
        .await?;
        anyhow::Ok(vec![nav, paper])
    })?;
    print_table(&rows);
    for r in &rows {
        println!(
            "{}: superseded poses {}, late frames {}",
            r.label, r.report.scheduler.superseded, r.report.scheduler.late
        );
    }
    Ok(())
}
