//! `hilcam model satellite`: write the Jason-like satellite as OBJ + MTL.

use crate::model::satellite::{self, MATERIALS, MLI_GOLD};
use anyhow::Context;
use clap::{Args, Subcommand};
use glam::DVec3;
use hilcam_core::scene::fold::{self, FoldLevel, measure::measure};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ModelArgs {
    #[command(subcommand)]
    pub command: ModelCommand,
}

#[derive(Subcommand, Debug)]
pub enum ModelCommand {
    /// The Jason-like satellite (bus in folded gold MLI, two wings, altimeter dish).
    Satellite(SatelliteArgs),
}

#[derive(Args, Debug)]
pub struct SatelliteArgs {
    /// Output directory (gets satellite.obj and satellite.mtl).
    #[arg(long)]
    pub out: PathBuf,
    /// Fold level of the MLI: slight, medium, severe, or none.
    #[arg(long, default_value = "medium")]
    pub level: String,
    /// Fold seed (the fold parameters are fitted at --edge-m on a reference panel with it).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Target edge length of the folded MLI (m).
    #[arg(long, default_value_t = 0.02)]
    pub edge_m: f32,
    /// Also write shaded orthographic previews (`<dir>/satellite_*.png`) into this directory.
    #[arg(long)]
    pub preview: Option<PathBuf>,
}

pub fn run(args: ModelArgs) -> anyhow::Result<()> {
    match args.command {
        ModelCommand::Satellite(a) => write_satellite(a),
    }
}

fn write_satellite(a: SatelliteArgs) -> anyhow::Result<()> {
    let mesh = if a.level == "none" {
        satellite::satellite_flat()
    } else {
        let level: FoldLevel = a.level.parse()?;
        let fit = fold::fit_for_edge(level.target(), a.seed, a.edge_m)?;
        println!("fold params fitted at edge {} m: {:?}", a.edge_m, fit.params);
        satellite::satellite(&fit.params, a.seed, a.edge_m)?
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let obj = a.out.join("satellite.obj");
    let mtl = a.out.join("satellite.mtl");
    crate::obj::write_obj_file(&obj, &mesh, &MATERIALS, Some("satellite.mtl"), "jason_like")?;
    crate::obj::write_mtl_file(&mtl, &satellite::mtl_entries())?;
    println!(
        "wrote {} ({} vertices, {} triangles) and {}",
        obj.display(),
        mesh.positions.len(),
        mesh.indices.len(),
        mtl.display()
    );
    for (m, name) in MATERIALS.iter().enumerate() {
        let n = mesh.material.iter().filter(|&&x| x == m as u32).count();
        println!("  {name:12} {n:7} triangles");
    }
    if let Some(dir) = &a.preview {
        write_previews(&mesh, dir)?;
    }
    // Fold statistics of the MLI on each bus side, against that side's normal.
    for (label, n) in [("+X", DVec3::X), ("+Y", DVec3::Y), ("-Y", -DVec3::Y), ("-Z", -DVec3::Z)] {
        let side = side_faces(&mesh, n);
        if let Ok(s) = measure(&side, n) {
            println!("  MLI {label}: E_PLANE {:.4} Var {:.4} ({} triangles)", s.e_plane, s.var, s.triangles);
        }
    }
    Ok(())
}

/// MLI triangles of the bus side facing `n`: those whose centroid is nearest that side
/// (largest |c|/half along the axis of `n`; folds can misfile a few near the box edges).
fn side_faces(mesh: &hilcam_core::render::geometry::TriMesh, n: DVec3) -> hilcam_core::render::geometry::TriMesh {
    let half = satellite::BUS_HALF.as_dvec3();
    let indices = (0..mesh.indices.len())
        .filter(|&t| mesh.material[t] == MLI_GOLD)
        .filter(|&t| {
            let c = mesh.triangle(t).iter().fold(DVec3::ZERO, |s, p| s + p.as_dvec3()) / 3.0;
            let r = c / half;
            let axis = r.abs().max_position();
            n[axis] != 0.0 && r[axis].signum() == n[axis].signum()
        })
        .map(|t| mesh.indices[t])
        .collect::<Vec<_>>();
    hilcam_core::render::geometry::TriMesh {
        material: vec![MLI_GOLD; indices.len()],
        indices,
        positions: mesh.positions.clone(),
    }
}

/// Oblique whole-satellite view and a close-up of the +X bus side, sun from +X+Y+Z.
fn write_previews(mesh: &hilcam_core::render::geometry::TriMesh, dir: &std::path::Path) -> anyhow::Result<()> {
    use crate::preview::{View, preview_view};
    use glam::Vec3;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let albedo = [0.9, 1.0, 0.35, 0.6, 1.0, 0.8];
    let light = Vec3::new(0.8, 0.35, 0.5).normalize();
    let whole = View { dir: Vec3::new(-1.0, -0.45, -0.35), up: Vec3::Z, centre: Vec3::ZERO, half: 5.0, light };
    preview_view(mesh, whole, &albedo, 1024, &dir.join("satellite_whole.png"))?;
    let bus =
        View { dir: Vec3::new(-1.0, -0.25, -0.2), up: Vec3::Z, centre: Vec3::new(0.0, 0.0, 0.2), half: 1.3, light };
    preview_view(mesh, bus, &albedo, 1024, &dir.join("satellite_bus.png"))?;
    Ok(())
}
