//! `hilcam bench serve`: per-frame latency (pose arrival → last byte written to a client)
//! beside the render time, measured in the same run through the real server.
//!
//! Poses go in one at a time through the input channel (the next one only after the
//! previous frame has arrived, so nothing is superseded); a loopback client reads every
//! frame. The difference between the two p99s is what the scheduler, encoder and stream
//! add to the render.
//!
//! With ground truth on (`[output] truth`), the server's own histograms give the truth
//! time and the whole frame time of the same frames (`hilcam_truth_seconds`,
//! `hilcam_render_seconds`, read off `/metrics` before it stops): their ratio is the cost
//! of truth measured side by side, whatever the machine's load.

use hilcam_core::link::InputEvent;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::serve::config::ServeConfig;
use hilcam_core::serve::{Embed, ServeReport, run};
use hilcam_core::sink::{ImageFormat, RecvOptions, receive};
use std::path::Path;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot};

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct ServeBenchRow {
    pub label: String,
    pub frames: u64,
    pub report: ServeReport,
    /// With truth on: mean truth time and mean frame time (render + sensor + truth +
    /// encode) of the same frames, ms.
    pub truth_ms: Option<(f64, f64)>,
    /// Bytes the client received per frame (header, payload and truth block).
    pub bytes_per_frame: u64,
}

/// Serve `frames` frames of `scene` (scaled to `width`) and measure. Poses are paced at
/// 1.5× the render time of a warm-up frame, so none waits behind another (superseded
/// poses, if the machine slows down, are reported).
pub async fn measure(
    scene: &Path,
    width: u32,
    spp: Spp,
    frames: u64,
    truth: TruthChannels,
    label: &str,
) -> anyhow::Result<ServeBenchRow> {
    let text = "scene = \"x\"\n[stream]\nlisten = \"127.0.0.1:0\"\n[metrics]\nprint_interval_s = 3600.0\n";
    let mut cfg: ServeConfig = toml::from_str(text)?;
    cfg.output.truth = truth;
    if !truth.is_empty() {
        cfg.metrics.listen = Some("127.0.0.1:0".parse()?);
    }
    cfg.scene = scene.to_path_buf();
    cfg.width = Some(width);
    cfg.render.spp = Some(spp);
    // Warm-up: the same frame through the same pipeline, to pace the poses.
    let loaded = std::sync::Arc::new(hilcam_core::scene::load(scene)?);
    let base = loaded.pose;
    let camera = loaded.camera.scaled(Some(width), None);
    let settings = hilcam_core::render::integrator::RenderSettings { spp, ..loaded.render };
    let period = tokio::task::spawn_blocking(move || -> anyhow::Result<Duration> {
        let mut p = hilcam_core::pipeline::FramePipeline::new(loaded, camera)?;
        let t0 = Instant::now();
        p.frame(&base, &settings, 0)?;
        if !truth.is_empty() {
            // A frame with truth also computes and encodes it: pace for that too.
            let t = p.truth(&base, &Default::default(), truth)?;
            std::hint::black_box(hilcam_core::frame::truth_block::encode_truth_block(&t));
        }
        Ok(t0.elapsed().mul_f64(1.5).max(Duration::from_millis(20)))
    })
    .await??;

    let (tx, rx) = mpsc::channel(4);
    let (ready_tx, ready_rx) = oneshot::channel();
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let server = tokio::spawn(run(cfg, Embed { inputs: Some(rx), ready: Some(ready_tx), ..Embed::default() }, stop_rx));
    let info = ready_rx.await?;
    let opts = RecvOptions { out_dir: None, count: Some(frames), format: ImageFormat::Png, progress: None };
    let client = tokio::spawn(receive(info.stream, opts));
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut tick = tokio::time::interval(period);
    for seq in 0..frames {
        tick.tick().await;
        let pose = hilcam_core::pose::Pose { seq: seq as u32, t_ns: seq * 1_000_000, ..base };
        tx.send(InputEvent::Pose { pose, arrival: Instant::now() }).await?;
    }
    let summary = tokio::time::timeout(period * (frames as u32 + 4) + Duration::from_secs(30), client).await???;
    let truth_ms = match info.metrics {
        Some(addr) => {
            let text = metrics_text(addr).await?;
            let mean_ms = |name: &str| -> Option<f64> {
                let get = |suffix: &str| {
                    text.lines().find_map(|l| l.strip_prefix(&format!("{name}_{suffix} "))?.parse::<f64>().ok())
                };
                Some(get("sum")? / get("count")?.max(1.0) * 1e3)
            };
            mean_ms("hilcam_truth_seconds").zip(mean_ms("hilcam_render_seconds"))
        }
        None => None,
    };
    let _ = stop_tx.send(());
    let report = server.await??;
    anyhow::ensure!(summary.frames == frames, "client received {} of {frames} frames", summary.frames);
    let bytes_per_frame = summary.bytes / summary.frames.max(1);
    Ok(ServeBenchRow { label: label.to_string(), frames, report, truth_ms, bytes_per_frame })
}

/// GET /metrics as text.
async fn metrics_text(addr: std::net::SocketAddr) -> anyhow::Result<String> {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut s = tokio::net::TcpStream::connect(addr).await?;
    s.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").await?;
    let mut text = String::new();
    s.read_to_string(&mut text).await?;
    Ok(text)
}

pub fn print_table(rows: &[ServeBenchRow]) {
    println!(
        "{:<36} {:>6} {:>12} {:>12} {:>13} {:>13} {:>14}",
        "case", "frames", "render p50", "render p99", "latency p50", "latency p99", "p99 − render"
    );
    for r in rows {
        let s = &r.report.scheduler;
        let (l50, _, l99) = r.report.latency_ms.unwrap_or((f64::NAN, f64::NAN, f64::NAN));
        println!(
            "{:<36} {:>6} {:>9.1} ms {:>9.1} ms {:>10.1} ms {:>10.1} ms {:>11.1} ms",
            r.label,
            s.frames,
            s.render_p50_ms,
            s.render_p99_ms,
            l50,
            l99,
            l99 - s.render_p99_ms
        );
    }
    for r in rows {
        println!("{}: {:.1} MB per frame on the stream", r.label, r.bytes_per_frame as f64 / 1e6);
        if let Some((truth, frame)) = r.truth_ms {
            println!(
                "{}: truth {truth:.1} ms of a {frame:.1} ms frame ({:.1} %), means over the same frames",
                r.label,
                100.0 * truth / frame
            );
        }
    }
}
