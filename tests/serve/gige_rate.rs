//! A GigE Vision client's AcquisitionFrameRate sets the rate `hilcam serve` renders at
//! in `rate` trigger mode (the configured rate is its maximum), checked on the TCP
//! stream's frame intervals after `arv-tool-0.8 control AcquisitionFrameRate=…`.

use crate::gige::run;
use crate::serve_common;
use hilcam_core::link::InputEvent;
use hilcam_core::serve::config::{InputConfig, TriggerConfig};
use hilcam_core::serve::scheduler::TriggerMode;
use hilcam_core::sink::gige::GigeConfig;
use std::net::{Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Emit times (ms since the UNIX epoch) of the frames on the stream in `window`.
async fn emit_times_ms(reader: &mut serve_common::Reader, window: Duration) -> Vec<f64> {
    let end = Instant::now() + window;
    let mut t = Vec::new();
    while Instant::now() < end {
        t.push(reader.next().await.meta.emit_unix_ns as f64 / 1e6);
    }
    t
}

fn median_interval_ms(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(d.len() >= 3, "too few frames to measure a rate: {t:?}");
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

pub(crate) async fn metric(addr: SocketAddr, name: &str) -> i64 {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).await.unwrap();
    let line = text
        .lines()
        .find(|l| l.strip_prefix(name).is_some_and(|r| r.starts_with(" ")))
        .unwrap_or_else(|| panic!("no {name} in:\n{text}"));
    line.rsplit(' ').next().unwrap().parse().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn acquisition_frame_rate_sets_the_rate_serve_renders_at() {
    let ip = Ipv4Addr::new(127, 0, 0, 51);
    let dir = tempfile::tempdir().unwrap();
    let scene = serve_common::sphere_scene_with(dir.path(), 48, 1, &serve_common::detector_sensor(12, 1.0, ""));
    let trigger = TriggerConfig { mode: TriggerMode::Rate, rate_hz: Some(20.0), extrapolate: false };
    let mut cfg = serve_common::config(scene, InputConfig::default(), trigger, Default::default());
    cfg.output.gige = Some(GigeConfig { address: ip, ..GigeConfig::default() });
    cfg.metrics.listen = Some("127.0.0.1:0".parse().unwrap());
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let server = serve_common::start(cfg, Some(rx)).await;
    let metrics = server.info.metrics.expect("metrics endpoint");
    let mut reader = serve_common::Reader::connect(server.info.stream).await;
    let pose = serve_common::pose(1, glam::DVec3::new(0.0, 0.0, 10.0), glam::DVec3::NEG_Z);
    tx.send(InputEvent::Pose { pose, arrival: Instant::now() }).await.unwrap();
    reader.next().await;

    let configured = median_interval_ms(&emit_times_ms(&mut reader, Duration::from_millis(600)).await);
    assert!((40.0..=60.0).contains(&configured), "20 Hz configured: median interval {configured:.1} ms");
    assert_eq!(metric(metrics, "hilcam_frame_rate_setting_millihz").await, 20_000);

    let control = |kv: &str| vec!["-a".into(), ip.to_string(), "control".into(), kv.to_string()];
    // Above the configured rate: refused by the device (the XML's Max is 20), rate kept.
    let (_, out) = run("arv-tool-0.8", control("AcquisitionFrameRate=40")).await;
    let (ok, read) = run("arv-tool-0.8", control("AcquisitionFrameRate")).await;
    assert!(ok && read.contains("AcquisitionFrameRate = 20"), "the write of 40 Hz was not refused: {out}\n{read}");

    let (ok, out) = run("arv-tool-0.8", control("AcquisitionFrameRate=5")).await;
    assert!(ok && out.contains("AcquisitionFrameRate = 5"), "{out}");
    // Frames queued on the stream before the write: drain them (one period of the old rate at most).
    emit_times_ms(&mut reader, Duration::from_millis(250)).await;
    let slowed = emit_times_ms(&mut reader, Duration::from_millis(1800)).await;
    let interval = median_interval_ms(&slowed);
    assert!((180.0..=220.0).contains(&interval), "5 Hz written: median interval {interval:.1} ms ({slowed:?})");
    assert_eq!(metric(metrics, "hilcam_frame_rate_setting_millihz").await, 5_000);

    // Back to the configured rate.
    let (ok, out) = run("arv-tool-0.8", control("AcquisitionFrameRate=20")).await;
    assert!(ok, "{out}");
    emit_times_ms(&mut reader, Duration::from_millis(300)).await;
    let back = median_interval_ms(&emit_times_ms(&mut reader, Duration::from_millis(600)).await);
    assert!((40.0..=60.0).contains(&back), "20 Hz again: median interval {back:.1} ms");
    eprintln!(
        "median frame interval: {configured:.1} ms at 20 Hz configured, {interval:.1} ms after 5 Hz written, {back:.1} ms back at 20 Hz"
    );
    drop(tx);
    server.finish().await;
}
