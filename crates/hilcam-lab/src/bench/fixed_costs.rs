//! `hilcam bench sensor`: the two fixed per-frame costs beside the frame they belong to —
//! the sensor stage (optics, PSF, detector, ADC, the Monte Carlo report) and the
//! ground-truth pass — measured in the same rounds as the render, so each share is a
//! ratio of times taken side by side under the same machine load.
//!
//! The scene's camera and sensor, its own pose and settings (at `spp`), the auto-exposure
//! settled first. Each round renders one frame through [`FramePipeline::frame`] (render and
//! sensor, as `serve` does), converts that frame's radiance and variance again with the
//! sensor alone (the stage without the render's cache state around it), and computes the
//! truth of each channel set. Times are medians over the rounds.

use super::median;
use super::trade_sensor::settle;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::truth::{TruthChannels, TruthPlanes};
use hilcam_core::scene::Scene;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// What one run measured (medians over the rounds, seconds).
#[derive(Clone, Debug)]
pub struct FixedCosts {
    pub width: u32,
    pub height: u32,
    pub integration_s: f64,
    /// The renderer's own time for the frame.
    pub render_s: f64,
    /// The sensor stage inside the frame (`RenderedFrame::sensor_time`: conversion and
    /// auto-exposure update).
    pub sensor_s: f64,
    /// The sensor alone on the same frame's radiance and variance, again.
    pub sensor_alone_s: f64,
    /// Per channel set: its truth pass.
    pub truth_s: Vec<(TruthChannels, f64)>,
    pub lit_pixels: u64,
    pub traced: f64,
}

impl FixedCosts {
    /// Render + sensor: the frame `serve` sends without truth.
    pub fn frame_s(&self) -> f64 {
        self.render_s + self.sensor_s
    }
}

/// Measure `rounds` rounds of `scene` at `spp`, the sensor alone `repeat` times a round,
/// truth for each of `truth`.
pub fn measure(
    scene: &Path,
    spp: Spp,
    rounds: usize,
    repeat: usize,
    truth: &[TruthChannels],
) -> anyhow::Result<FixedCosts> {
    let scene: Arc<Scene> = Arc::new(hilcam_core::scene::load(scene)?);
    let mut pipeline = FramePipeline::new(scene.clone(), scene.camera.clone())?;
    let (pose, settings) = (scene.pose, hilcam_core::render::integrator::RenderSettings { spp, ..scene.render });
    let settled = settle(&mut pipeline, &pose, &settings, 12, 0.02)?;
    let (mut render, mut sensor, mut alone) = (Vec::new(), Vec::new(), Vec::new());
    let mut truth_t: Vec<Vec<f64>> = vec![Vec::new(); truth.len()];
    let (mut lit, mut traced) = (0, 0.0);
    // One set of planes per channel set, kept from round to round as a frame loop keeps
    // them (`replay --truth`).
    let mut planes: Vec<TruthPlanes> = truth.iter().map(|_| TruthPlanes::default()).collect();
    for round in 0..=rounds {
        let index = 1000 + round as u64;
        let f = pipeline.frame(&pose, &settings, index)?;
        let t_s = f.integration_s.unwrap_or(0.0);
        let (radiance, variance) = pipeline.last_render();
        let k = f64::from(settings.quality.k);
        let mut alone_s = Vec::new();
        for _ in 0..repeat.max(1) {
            let t0 = Instant::now();
            std::hint::black_box(pipeline.sensor().apply_with_variance(radiance, variance, index, t_s, k)?);
            alone_s.push(t0.elapsed().as_secs_f64());
        }
        let mut truths = Vec::new();
        for (ch, planes) in truth.iter().zip(&mut planes) {
            let t0 = Instant::now();
            std::hint::black_box(pipeline.truth_into(&pose, &Default::default(), *ch, planes)?);
            truths.push(t0.elapsed().as_secs_f64());
        }
        // Round 0 warms the truth pass's and the sensor's first use.
        if round > 0 {
            render.push(f.render.time.as_secs_f64());
            sensor.push(f.sensor_time.as_secs_f64());
            alone.extend(alone_s);
            for (v, t) in truth_t.iter_mut().zip(truths) {
                v.push(t);
            }
            lit = f.mc_noise.map_or(0, |m| m.lit_pixels);
            traced = f.render.traced_pixels as f64 / (f64::from(f.width) * f64::from(f.height));
        }
    }
    Ok(FixedCosts {
        width: pipeline.camera().width,
        height: pipeline.camera().height,
        integration_s: settled.integration_s,
        render_s: median(render),
        sensor_s: median(sensor),
        sensor_alone_s: median(alone),
        truth_s: truth.iter().copied().zip(truth_t.into_iter().map(median)).collect(),
        lit_pixels: lit,
        traced,
    })
}

/// The table: each fixed cost and its share of the frame it belongs to.
pub fn print(c: &FixedCosts) {
    let ms = |s: f64| s * 1e3;
    println!(
        "{}×{}, integration {:.1} µs, {:.1} % of pixels traced, {} lit pixels",
        c.width,
        c.height,
        c.integration_s * 1e6,
        c.traced * 100.0,
        c.lit_pixels
    );
    println!("| stage | time | share |");
    println!("|---|---:|---:|");
    println!("| render | {:.1} ms | |", ms(c.render_s));
    println!(
        "| sensor stage (in the frame) | {:.1} ms | {:.1} % of render + sensor |",
        ms(c.sensor_s),
        100.0 * c.sensor_s / c.frame_s()
    );
    println!(
        "| sensor alone (same radiance, again) | {:.1} ms | {:.1} % of render + sensor |",
        ms(c.sensor_alone_s),
        100.0 * c.sensor_alone_s / c.frame_s()
    );
    for (ch, t) in &c.truth_s {
        println!(
            "| truth `{ch}` | {:.1} ms | {:.1} % of render + sensor + truth |",
            ms(*t),
            100.0 * t / (c.frame_s() + t)
        );
    }
}
