//! Session recording in `hilcam serve` and the frame-for-frame re-render (issue 7 item 3):
//! a closed-loop run with governor-degraded and extrapolated frames is recorded, then
//! `hilcam replay --session` re-renders every streamed frame byte for byte.

use crate::serve_common;
use glam::DVec3;
use hilcam_core::frame::{CRC32, Frame, FrameFlags};
use hilcam_core::link::InputEvent;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::Pose;
use hilcam_core::render::film::Pixels;
use hilcam_core::replay::session_jobs;
use hilcam_core::serve::config::ServeConfig;
use hilcam_core::serve::{Embed, run};
use hilcam_core::session::Session;
use hilcam_core::sink::recorder::FrameRecord;
use serve_common::*;
use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot};

const FRAMES: usize = 16;

/// The shipped sphere behind the nav1024 camera's sensor (auto-exposure, noise), scaled to
/// 40 px; rate trigger with extrapolation; a budget only the lowest rungs can meet.
fn write_config(dir: &Path) -> std::path::PathBuf {
    let scene = std::fs::canonicalize("scenes/sphere.toml").unwrap();
    let text = format!(
        r#"scene = "{}"
width = 40
[trigger]
mode = "rate"
rate_hz = 40.0
extrapolate = true
[governor]
policy = "fixed-rate"
budget_ms = 0.3
[render]
spp = 8
depth = 2
seed = 11
[stream]
listen = "127.0.0.1:0"
queue_depth = 64
[record]
session = "run1.session.jsonl"
[metrics]
print_interval_s = 60.0
listen = "127.0.0.1:0"
"#,
        scene.display()
    );
    let p = dir.join("serve.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// Moving and tumbling, with rates so that frames are extrapolated.
fn moving_pose(seq: u32) -> Pose {
    let t = f64::from(seq) * 5e-3;
    Pose {
        seq,
        t_ns: u64::from(seq) * 5_000_000,
        position: DVec3::new(0.2 + 0.5 * t, -0.1, 10.0 - 2.0 * t),
        attitude: glam::DQuat::from_rotation_y(0.8 * t),
        sun_dir: DVec3::new(0.6, 0.1, -0.8).normalize(),
        velocity: Some(DVec3::new(0.5, 0.0, -2.0)),
        angular_rate: Some(DVec3::new(0.0, 0.8, 0.0)),
        camera_to_inertial: None,
        planet_centre: None,
    }
}

fn u16_payload(f: &Frame) -> &[u16] {
    match &f.pixels {
        Pixels::Mono16 { data, .. } => data,
        other => panic!("expected sensor DN frames, got {:?}", other.format()),
    }
}

fn hilcam(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hilcam")).args(args).output().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_session_re_renders_bit_identical_to_the_stream() {
    let dir = tempfile::tempdir().unwrap();
    let serve_toml = write_config(dir.path());
    let cfg = ServeConfig::load(&serve_toml).unwrap();
    let session_path = dir.path().join("run1.session.jsonl");
    assert_eq!(cfg.record.as_ref().unwrap().session.as_deref(), Some(session_path.as_path()));

    // Serve FRAMES frames from poses sent every 5 ms; capture the stream.
    let (tx, rx) = mpsc::channel(64);
    let (ready_tx, ready_rx) = oneshot::channel();
    let embed = Embed { inputs: Some(rx), ready: Some(ready_tx), max_frames: Some(FRAMES as u64), ..Embed::default() };
    let server = tokio::spawn(run(cfg.clone(), embed, std::future::pending::<()>()));
    let info = tokio::time::timeout(PATIENCE, ready_rx).await.unwrap().unwrap();
    let mut reader = Reader::subscribed(&info).await;
    let sender = tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_millis(5));
        for seq in 1.. {
            tick.tick().await;
            let ev = InputEvent::Pose { pose: moving_pose(seq), arrival: Instant::now() };
            if tx.send(ev).await.is_err() {
                break;
            }
        }
    });
    let mut streamed = Vec::new();
    while streamed.len() < FRAMES {
        streamed.push(reader.next().await);
    }
    let report = tokio::time::timeout(PATIENCE, server).await.unwrap().unwrap().unwrap();
    sender.abort();
    assert_eq!(report.scheduler.frames, FRAMES as u64);
    let stats = report.session.clone().expect("session stats");
    assert_eq!(stats.dropped, 0);

    // The session: every frame, with the flags it was streamed with.
    let s = Session::load(&session_path).unwrap();
    let end = s.end.clone().expect("end line");
    assert_eq!((end.frames, end.records_dropped), (FRAMES as u64, 0));
    assert_eq!(s.poses.len() as u64, end.poses_received);
    assert_eq!(stats.written, 2 + s.poses.len() as u64 + FRAMES as u64, "header + poses + frames + end");
    assert_eq!((s.header.width, s.header.height, s.header.width_setting), (40, 40, Some(40)));
    assert_eq!(s.frames.len(), FRAMES);
    for (f, line) in streamed.iter().zip(&s.frames) {
        assert_eq!(line.index, f.meta.frame_seq);
        assert_eq!(line.source_seq, f.meta.pose_seq);
        assert_eq!((line.flags, line.settings.spp), (f.meta.flags.0, f.meta.spp));
        let payload: Vec<u8> = f.pixels.to_le_bytes();
        assert_eq!(line.payload_crc32, CRC32.checksum(&payload), "frame {}", line.index);
    }
    let flagged = |bit| streamed.iter().filter(|f| f.meta.flags.contains(bit)).count();
    assert!(flagged(FrameFlags::DEGRADED) > 0, "no degraded frame");
    assert!(flagged(FrameFlags::EXTRAPOLATED) > 0, "no extrapolated frame");
    assert!(
        streamed.iter().any(|f| !f.meta.flags.contains(FrameFlags::DEGRADED)),
        "the first frame is at best quality"
    );

    // Independently of replay: a fresh pipeline fed the session's frames in order gives
    // the streamed bytes.
    let scene = Arc::new(hilcam_core::scene::load(&cfg.scene).unwrap());
    let camera = scene.camera.scaled(cfg.width, None);
    let mut pipeline = FramePipeline::new(scene, camera.clone()).unwrap();
    for (job, f) in session_jobs(&s, true).iter().zip(&streamed) {
        let again = pipeline.frame(&job.pose, &job.settings, job.index).unwrap();
        assert_eq!(again.pixels.to_le_bytes(), f.pixels.to_le_bytes(), "frame {}", job.index);
    }
    // Each DN frame's Monte Carlo noise report is in its line, the same as the pipeline's
    // for that frame; the run's summary adds them up.
    let mut pipeline = FramePipeline::new(Arc::new(hilcam_core::scene::load(&cfg.scene).unwrap()), camera).unwrap();
    for (job, line) in session_jobs(&s, true).iter().zip(&s.frames) {
        let mc = line.mc_noise.expect("a DN frame reports its Monte Carlo noise");
        assert!(mc.lit_pixels > 0 && mc.k == 0.5, "{mc:?}");
        assert_eq!(pipeline.frame(&job.pose, &job.settings, job.index).unwrap().mc_noise, Some(mc));
    }
    let lit: u64 = s.frames.iter().map(|l| l.mc_noise.unwrap().lit_pixels).sum();
    let above: u64 = s.frames.iter().map(|l| l.mc_noise.unwrap().above_bound).sum();
    assert_eq!((report.scheduler.mc_lit_pixels, report.scheduler.mc_above_bound), (lit, above));

    // The command: re-render into files; every image holds the streamed DN values.
    let out = dir.path().join("rerender");
    let (sess, conf, outs) = (session_path.to_str().unwrap(), serve_toml.to_str().unwrap(), out.to_str().unwrap());
    let o = hilcam(&["replay", "--session", sess, "--config", conf, "--out", outs, "--format", "pfm"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains(&format!("{FRAMES} frames re-rendered, each bit-identical")), "{stdout}");
    let recs: Vec<FrameRecord> = std::fs::read_to_string(out.join("frames.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(recs.len(), FRAMES);
    assert!(stdout.contains(&format!("Monte Carlo noise: {above} of {lit} lit pixels")), "{stdout}");
    for (r, line) in recs.iter().zip(&s.frames) {
        assert_eq!(r.mc_noise, line.mc_noise, "frame {}: frames.jsonl and the session agree", line.index);
    }
    for (r, f) in recs.iter().zip(&streamed) {
        assert_eq!(
            (r.meta.frame_seq, r.meta.pose_seq, r.meta.pose_t_ns),
            (f.meta.frame_seq, f.meta.pose_seq, f.meta.pose_t_ns)
        );
        assert_eq!((r.meta.spp, r.meta.depth, r.meta.flags), (f.meta.spp, f.meta.depth, f.meta.flags));
        let img = hilcam_core::render::film::read_pfm(&out.join(&r.file)).unwrap();
        let dn: Vec<u16> = img.data.iter().map(|v| *v as u16).collect();
        assert!(img.data.iter().zip(&dn).all(|(v, d)| *v == f32::from(*d)), "integral DN");
        let bytes: Vec<u8> = dn.iter().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(bytes, f.pixels.to_le_bytes(), "frame {} bytes", r.meta.frame_seq);
        assert!(u16_payload(f).iter().any(|v| *v > 0), "frame {} is not black", r.meta.frame_seq);
    }

    // Resume: nothing left to do. Another format into the same directory is refused.
    let o = hilcam(&["replay", "--session", sess, "--out", outs, "--format", "pfm"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("0 rendered in"));
    let o = hilcam(&["replay", "--session", sess, "--out", outs, "--format", "exr"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains(outs) && err.contains("format = pfm"), "{err}");

    // A session file is never overwritten.
    let (_tx, rx) = mpsc::channel(1);
    let e = run(cfg, Embed { inputs: Some(rx), ..Embed::default() }, async {}).await.unwrap_err().to_string();
    assert!(e.contains("run1.session.jsonl") && e.contains("already exists"), "{e}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_malformed_session_is_refused_naming_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.session.jsonl");
    std::fs::write(&p, "{\"kind\":\"pose\"}\n").unwrap();
    let o = hilcam(&["replay", "--session", p.to_str().unwrap(), "--out", dir.path().join("o").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("bad.session.jsonl:1:"), "{err}");
}
