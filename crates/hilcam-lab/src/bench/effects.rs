//! `hilcam bench effects`: what each optional effect (motion blur, rolling shutter, star
//! field, planet) costs on the shipped satellite, as a ratio to the plain frame.
//!
//! Every case is a scene file that differs from the first (the reference) only by its
//! effect. Each frame goes through the frame pipeline (render + sensor), as a served or
//! replayed frame does; the cases are rendered in turn, round after round, so all see the
//! same machine load, and per-case medians are compared.

use super::median;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::scene::Scene;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// One measured scene.
#[derive(Clone, Debug)]
pub struct EffectRow {
    pub scene: PathBuf,
    /// Median wall time of a frame (render + sensor), seconds.
    pub frame_s: f64,
    /// Median of the renderer's own time, seconds.
    pub render_s: f64,
    /// Fraction of the pixels that were sampled (the rest keep the background).
    pub traced: f64,
}

struct Case {
    path: PathBuf,
    scene: Arc<Scene>,
    pipeline: FramePipeline,
    frame: Vec<f64>,
    render: Vec<f64>,
    traced: f64,
}

/// Render every scene of `scenes` `rounds` times (after one untimed frame each), in turn.
pub fn measure(scenes: &[PathBuf], width: Option<u32>, rounds: usize) -> anyhow::Result<Vec<EffectRow>> {
    let mut cases = scenes.iter().map(|p| case(p, width)).collect::<anyhow::Result<Vec<_>>>()?;
    for round in 0..=rounds {
        for (k, c) in cases.iter_mut().enumerate() {
            let t0 = Instant::now();
            let f = c.pipeline.frame(&c.scene.pose, &c.scene.render, k as u64)?;
            let wall = t0.elapsed().as_secs_f64();
            if round > 0 {
                c.frame.push(wall);
                c.render.push(f.render.time.as_secs_f64());
                c.traced = f.render.traced_pixels as f64 / (f64::from(f.width) * f64::from(f.height));
            }
        }
    }
    Ok(cases
        .into_iter()
        .map(|c| EffectRow { scene: c.path, frame_s: median(c.frame), render_s: median(c.render), traced: c.traced })
        .collect())
}

fn case(path: &Path, width: Option<u32>) -> anyhow::Result<Case> {
    let scene = Arc::new(hilcam_core::scene::load(path)?);
    let camera = scene.camera.scaled(width, None);
    let pipeline = FramePipeline::new(scene.clone(), camera)?;
    Ok(Case { path: path.to_path_buf(), scene, pipeline, frame: Vec::new(), render: Vec::new(), traced: 0.0 })
}

/// The table: each scene's median frame time and its ratio to the first's.
pub fn print_table(rows: &[EffectRow]) {
    let Some(base) = rows.first() else { return };
    println!("| scene | frame (render + sensor) | render | ratio to {} | pixels sampled |", name(&base.scene));
    println!("|---|---:|---:|---:|---:|");
    for r in rows {
        println!(
            "| {} | {:.0} ms | {:.0} ms | {:.2}× | {:.1} % |",
            name(&r.scene),
            r.frame_s * 1e3,
            r.render_s * 1e3,
            r.frame_s / base.frame_s,
            r.traced * 100.0
        );
    }
}

fn name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}
