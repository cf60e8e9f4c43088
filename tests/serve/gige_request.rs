//! What a GigE Vision client asks of the frame changes what `hilcam serve` renders: an
//! ROI renders only those pixels (the stream, the TCP sinks and the session all carry
//! the ROI frame), ExposureTime sets the integration time, and `hilcam replay --session`
//! re-renders such frames bit for bit from what the session recorded.

use crate::gige::python_client;
use crate::serve_common;
use hilcam_core::link::InputEvent;
use hilcam_core::render::film::Pixels;
use hilcam_core::serve::config::{InputConfig, RecordSection, TriggerConfig};
use hilcam_core::serve::scheduler::TriggerMode;
use hilcam_core::session::Session;
use hilcam_core::sink::gige::GigeConfig;
use std::net::Ipv4Addr;
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_clients_roi_and_exposure_are_what_serve_renders_and_the_session_replays() {
    let ip = Ipv4Addr::new(127, 0, 0, 41);
    let dir = tempfile::tempdir().unwrap();
    // A 96 × 96 camera (f = 200 px) on a unit sphere; a detector (so ExposureTime
    // matters) and a PSF (so the ROI is rendered with a margin).
    let sensor = serve_common::detector_sensor(12, 0.05, "psf = { kind = \"gaussian\", sigma_px = 0.8 }\n");
    let scene = serve_common::sphere_scene_with(dir.path(), 96, 2, &sensor);
    let trigger = TriggerConfig { mode: TriggerMode::External, ..TriggerConfig::default() };
    let mut cfg = serve_common::config(scene, InputConfig::default(), trigger, Default::default());
    cfg.output.gige = Some(GigeConfig { address: ip, ..GigeConfig::default() });
    let session = dir.path().join("s.jsonl");
    cfg.record = Some(toml::from_str::<RecordSection>(&format!("session = {session:?}")).unwrap());
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let server = serve_common::start(cfg, Some(rx)).await;
    let mut reader = serve_common::Reader::subscribed(&server.info).await;

    let p = glam::DVec3::new(0.8, -0.5, 10.0);
    let pose = serve_common::pose(1, p, -p);
    tx.send(InputEvent::Pose { pose, arrival: std::time::Instant::now() }).await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    // The whole disc (radius 20 px) inside the ROI, so its centroid is the centre.
    let (x, y, w, h) = (36u32, 12u32, 56u32, 52u32);
    let roi = [format!("Width={w}"), format!("Height={h}"), format!("OffsetX={x}"), format!("OffsetY={y}")];
    let mut args: Vec<&str> = roi.iter().map(String::as_str).collect();
    args.extend(["ExposureTime=10", "--trigger"]);
    let v = python_client(ip, 1, &args).await;
    let b = &v["buffers"][0];
    assert_eq!(b["status"], "success", "{v}");
    assert_eq!((b["width"].as_u64(), b["height"].as_u64()), (Some(u64::from(w)), Some(u64::from(h))), "{v}");
    // The sphere's centre through the pinhole, in the ROI's pixel indices.
    let (px, py) = (48.0 + 200.0 * p.x / p.z - 0.5 - f64::from(x), 48.0 + 200.0 * p.y / p.z - 0.5 - f64::from(y));
    let c = b["centroid"].as_array().unwrap();
    let (cx, cy) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
    assert!(
        (cx - px).abs() <= 1.0 && (cy - py).abs() <= 1.0,
        "centroid ({cx:.2}, {cy:.2}) vs pinhole ({px:.2}, {py:.2})"
    );

    // The TCP stream carries the same frame: the ROI's size, the client's exposure.
    let f = reader.next().await;
    assert_eq!((f.meta.width, f.meta.height, f.meta.pose_seq), (w, h, 1));
    assert_eq!(f.meta.integration_s, 10e-6);
    assert!(matches!(&f.pixels, Pixels::Mono16 { data, .. } if data.iter().any(|&v| v > 0)));
    let report = server.finish().await;
    assert_eq!(report.scheduler.triggers, 1);

    // The session recorded the request; replay re-renders the frame bit for bit.
    let s = Session::load(&session).unwrap();
    let line = &s.frames[0];
    let t = line.request.integration_s.expect("the client's exposure is recorded");
    assert!((t - 10e-6).abs() < 1e-12, "{t}");
    assert_eq!(line.request.roi.map(|r| (r.x, r.y, r.width, r.height)), Some((x, y, w, h)));
    let out = dir.path().join("replayed");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["replay", "--session", session.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("1 frames re-rendered, each bit-identical"), "{stdout}");
}
