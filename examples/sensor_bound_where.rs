//! Where a `quality = "sensor"` frame's pixels above the k bound are: two frames (indices
//! 0 and 1, same settings) of a scene through its own camera at the settled auto-exposure,
//! each pixel judged as the sensor's report judges it (PRNU and DSNU off here, so the
//! recount from the frame's radiance and variance is exact). Prints how many of one
//! frame's pixels above the bound are above in the other (the rest landed above by chance:
//! a pixel's count and its variance estimate both vary from frame to frame) and how many
//! lie within 2 px of the background.
//!
//!     cargo run --example sensor_bound_where -- [scene] [k] [budget]
//!
//! (counts only: the dev build gives the same numbers as a release build, sooner to build).
//!
//! e.g. `... -- scenes/satellite.toml 0.5 256` (docs/performance.md, sensor-relative quality).

use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::render::integrator::{QualityGoal, QualityMode, RenderSettings, Spp};
use std::sync::Arc;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().map_or("scenes/satellite.toml", String::as_str);
    let k: f64 = args.get(1).map_or(Ok(0.5), |s| s.parse())?;
    let budget: u32 = args.get(2).map_or(Ok(256), |s| s.parse())?;
    let mut scene = hilcam_core::scene::load(std::path::Path::new(path))?;
    let det = scene.sensor.detector.as_mut().ok_or_else(|| anyhow::anyhow!("the scene's camera has no detector"))?;
    (det.prnu, det.dsnu_e_per_s) = (None, None);
    let floor_rate = (det.dark_current_e_per_s.unwrap_or(0.0), det.read_noise_e.unwrap_or(0.0));
    let (pose, base, camera) = (scene.pose, scene.render, scene.camera.clone());
    let mut p = FramePipeline::new(Arc::new(scene), camera.clone())?;
    // Auto-exposure: frames of the scene's own settings until the time moves < 1 %.
    let mut t = p.exposure_timing(None).integration_s;
    for i in 0..40 {
        p.frame(&pose, &base, i)?;
        let next = p.exposure_timing(None).integration_s;
        let settled = (next - t).abs() < 0.01 * t;
        t = next;
        if settled {
            break;
        }
    }
    let settings = RenderSettings {
        spp: Spp::whole(budget),
        quality: QualityGoal { mode: QualityMode::Sensor, k: k as f32 },
        ..base
    };
    let request = FrameRequest { integration_s: Some(t), roi: None };
    let w = camera.width as usize;
    let mut frames = Vec::new();
    for index in [0u64, 1] {
        let f = p.frame_requested(&pose, &settings, index, &request)?;
        let (img, var) = p.last_render();
        let s = p.sensor();
        let rad = s.optics(img)?;
        let v_e = s.mc_variance_e2(var.expect("DN frames carry a variance"), t)?.expect("a detector");
        let c = s.electrons_per_radiance_second().expect("a detector") * t;
        let floor = floor_rate.0 * t + floor_rate.1 * floor_rate.1;
        // Per pixel: None unlit, Some(above).
        let judged: Vec<Option<bool>> = rad
            .data
            .iter()
            .zip(&v_e)
            .map(|(l, v)| {
                let photo = *l as f64 * c;
                (photo >= 1.0).then_some(*v > k * k * (photo + floor))
            })
            .collect();
        let near_bg: Vec<bool> = (0..img.data.len())
            .map(|i| {
                let (r, col) = ((i / w) as i64, (i % w) as i64);
                let h = (img.data.len() / w) as i64;
                (-2..=2).any(|dr: i64| {
                    (-2..=2).any(|dc: i64| {
                        let (y, x) = (r + dr, col + dc);
                        y < 0 || x < 0 || y >= h || x >= w as i64 || img.data[y as usize * w + x as usize] == 0.0
                    })
                })
            })
            .collect();
        let report = f.mc_noise.expect("a DN frame's report");
        let above = judged.iter().filter(|j| **j == Some(true)).count();
        println!(
            "frame {index}: {above} of {} lit pixels above {k} σ_cam (the frame's report: {}), {:.2} spp per traced pixel",
            report.lit_pixels,
            report.above_bound,
            f.render.samples as f64 / f.render.traced_pixels.max(1) as f64
        );
        frames.push((judged, near_bg));
    }
    let (a, near) = (&frames[0].0, &frames[0].1);
    let b = &frames[1].0;
    let count = |f: &dyn Fn(usize) -> bool| (0..a.len()).filter(|&i| f(i)).count();
    let above = count(&|i| a[i] == Some(true));
    let both = count(&|i| a[i] == Some(true) && b[i] == Some(true));
    let lit = count(&|i| a[i].is_some());
    let lit_near = count(&|i| a[i].is_some() && near[i]);
    let above_near = count(&|i| a[i] == Some(true) && near[i]);
    let pc = |n: usize, of: usize| n as f64 / of.max(1) as f64 * 100.0;
    println!("above in frame 0 and in frame 1: {both} of {above} ({:.1} %)", pc(both, above));
    println!(
        "within 2 px of the background: {:.1} % of lit pixels, {:.1} % of those above in frame 0",
        pc(lit_near, lit),
        pc(above_near, above)
    );
    Ok(())
}
