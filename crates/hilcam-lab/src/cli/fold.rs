//! `hilcam fold generate|measure`: fold planes at the paper's levels, and their statistics.

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use glam::DVec3;
use hilcam_core::scene::fold::{self, FoldLevel, FoldTarget};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct FoldArgs {
    #[command(subcommand)]
    pub command: FoldCommand,
}

#[derive(Subcommand, Debug)]
pub enum FoldCommand {
    /// Generate a folded 1 m-radius disk (YZ plane, normal +X) at a fold level.
    Generate(GenerateArgs),
    /// Print E_PLANE, Var, triangle count and the normal-angle histogram of a mesh.
    Measure(MeasureArgs),
}

#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// Paper level: slight (0.9803/0.0046), medium (0.9680/0.0077), severe (0.9435/0.0124).
    #[arg(long, conflicts_with_all = ["e_plane", "var"])]
    pub level: Option<String>,
    /// Target E_PLANE (mean cosine of triangle normals with +X); needs --var.
    #[arg(long, requires = "var")]
    pub e_plane: Option<f64>,
    /// Target Var (variance of that cosine); needs --e-plane.
    #[arg(long, requires = "e_plane")]
    pub var: Option<f64>,
    /// Seed of the crease pattern.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output OBJ file.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a shaded preview PNG (looking down −X).
    #[arg(long)]
    pub preview: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct MeasureArgs {
    /// Mesh file (OBJ).
    pub mesh: PathBuf,
    /// Plane normal, `x,y,z` (need not be unit).
    #[arg(long, default_value = "1,0,0")]
    pub normal: String,
    /// Also write the histogram as a PNG bar chart.
    #[arg(long)]
    pub histogram_png: Option<PathBuf>,
}

pub fn run(args: FoldArgs) -> anyhow::Result<()> {
    match args.command {
        FoldCommand::Generate(a) => generate(a),
        FoldCommand::Measure(a) => measure(a),
    }
}

fn generate(a: GenerateArgs) -> anyhow::Result<()> {
    let target = match (&a.level, a.e_plane, a.var) {
        (Some(l), None, None) => l.parse::<FoldLevel>()?.target(),
        (None, Some(e_plane), Some(var)) => FoldTarget { e_plane, var },
        _ => bail!("give either --level slight|medium|severe or both --e-plane and --var"),
    };
    let t0 = std::time::Instant::now();
    let plane = fold::generate_plane(target, a.seed)?;
    let elapsed = t0.elapsed();
    let name = format!("fold_plane_seed{}", a.seed);
    crate::obj::write_obj_file(&a.out, &plane.mesh, &["fold"], None, &name)?;
    if let Some(p) = &a.preview {
        crate::preview::preview_png(&plane.mesh, 1024, p)?;
    }
    let p = &plane.fit.params;
    println!(
        "wrote {} ({} vertices, {} triangles) in {:.2} s",
        a.out.display(),
        plane.mesh.positions.len(),
        plane.mesh.indices.len(),
        elapsed.as_secs_f64()
    );
    println!(
        "target E_PLANE {:.4} Var {:.4}; fitted slope {:.4} density {:.4} in {} iterations",
        target.e_plane, target.var, p.slope, p.density, plane.fit.iterations
    );
    print!("{}", plane.stats.report());
    Ok(())
}

fn parse_normal(s: &str) -> anyhow::Result<DVec3> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--normal {s:?}: expected x,y,z"))?;
    if v.len() != 3 || v.iter().all(|c| *c == 0.0) || v.iter().any(|c| !c.is_finite()) {
        bail!("--normal {s:?}: expected three finite numbers, not all zero");
    }
    Ok(DVec3::new(v[0], v[1], v[2]))
}

fn measure(a: MeasureArgs) -> anyhow::Result<()> {
    let normal = parse_normal(&a.normal)?;
    let mesh = crate::obj::read_obj(&a.mesh)?;
    let stats = fold::measure(&mesh, normal)?;
    println!("{} (normal {:?})", a.mesh.display(), normal.normalize().to_array());
    print!("{}", stats.report());
    if let Some(p) = &a.histogram_png {
        stats.histogram_png(p)?;
    }
    Ok(())
}
