//! `hilcam serve` end to end: poses over a real pty or an in-process channel, frames over
//! loopback TCP, checked against independent answers.

use glam::DVec3;
use hilcam::film::Pixels;
use hilcam::frame::{DecodeError, Frame, FrameFlags, decode_frame};
use hilcam::pose::{Message, Pose};
use hilcam::serve::config::{GovernorConfig, InputConfig, InputKind, ServeConfig, TriggerConfig};
use hilcam::serve::governor::Policy;
use hilcam::serve::scheduler::TriggerMode;
use hilcam::serve::{Embed, ServeInfo, ServeReport, run};
use hilcam::transport::InputEvent;
use hilcam::transport::send::{MessageWriter, SerialWriter};
use serialport::SerialPort;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tokio::io::AsyncReadExt;
use tokio::net::TcpStream;
use tokio::sync::{mpsc, oneshot};

const PATIENCE: Duration = Duration::from_secs(60);

/// A sphere scene with a small float-output camera (no sensor): pixels are radiance.
fn sphere_scene(dir: &Path, width: u32, spp: u32) -> PathBuf {
    let mesh = std::fs::canonicalize("scenes/meshes/sphere.obj").unwrap();
    let text = format!(
        r#"
[[mesh]]
obj = "{}"
[materials.white_paint]
model = "lambert"
rho = 0.5
[camera]
width = {width}
height = {width}
pitch_um = 10.0
focal_mm = 2.0
[render]
spp = {spp}
depth = 1
"#,
        mesh.display()
    );
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn config(scene: PathBuf, input: InputConfig, trigger: TriggerConfig, governor: GovernorConfig) -> ServeConfig {
    let text = "scene = \"x\"\n[stream]\nlisten = \"127.0.0.1:0\"\n";
    let mut cfg: ServeConfig = toml::from_str(text).unwrap();
    cfg.scene = scene;
    cfg.input = input;
    cfg.trigger = trigger;
    cfg.governor = governor;
    cfg.metrics.print_interval_s = 60.0;
    cfg.validate().unwrap();
    cfg
}

struct Running {
    info: ServeInfo,
    stop: oneshot::Sender<()>,
    task: tokio::task::JoinHandle<anyhow::Result<ServeReport>>,
}

async fn start(cfg: ServeConfig, inputs: Option<mpsc::Receiver<InputEvent>>) -> Running {
    let (ready_tx, ready_rx) = oneshot::channel();
    let (stop, stop_rx) = oneshot::channel::<()>();
    let task = tokio::spawn(run(cfg, Embed { inputs, ready: Some(ready_tx), max_frames: None }, stop_rx));
    let info = tokio::time::timeout(PATIENCE, ready_rx).await.expect("server start").expect("server ready");
    Running { info, stop, task }
}

impl Running {
    async fn finish(self) -> ServeReport {
        let _ = self.stop.send(());
        tokio::time::timeout(PATIENCE, self.task).await.expect("server stops").unwrap().unwrap()
    }
}

/// Read frames off a stream connection.
struct Reader {
    s: TcpStream,
    buf: Vec<u8>,
}

impl Reader {
    async fn connect(addr: std::net::SocketAddr) -> Reader {
        Reader { s: TcpStream::connect(addr).await.unwrap(), buf: Vec::new() }
    }

    async fn next(&mut self) -> Frame {
        let deadline = Instant::now() + PATIENCE;
        loop {
            match decode_frame(&self.buf) {
                Ok((f, used)) => {
                    self.buf.drain(..used);
                    return f;
                }
                Err(DecodeError::Incomplete { .. }) => {}
                Err(e) => panic!("bad frame: {e:?}"),
            }
            let mut chunk = vec![0u8; 1 << 16];
            let left = deadline.saturating_duration_since(Instant::now());
            let n = tokio::time::timeout(left, self.s.read(&mut chunk)).await.expect("frame in time").unwrap();
            assert!(n > 0, "stream closed");
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }
}

fn radiance(f: &Frame) -> &[f32] {
    match &f.pixels {
        Pixels::Float32(v) => v,
        other => panic!("expected float frames, got {:?}", other.format()),
    }
}

fn pose(seq: u32, position: DVec3, sun: DVec3) -> Pose {
    Pose { seq, t_ns: u64::from(seq) * 1_000_000, position, sun_dir: sun.normalize(), ..Pose::ahead(10.0) }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pose_sent_over_a_pty_arrives_as_a_frame_where_the_pinhole_model_puts_it() {
    let dir = tempfile::tempdir().unwrap();
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let device = slave.name().unwrap();
    let input =
        InputConfig { kind: InputKind::Serial, device: Some(device), baud: Some(921_600), ..Default::default() };
    let cfg = config(sphere_scene(dir.path(), 96, 16), input, TriggerConfig::default(), GovernorConfig::default());
    let server = start(cfg, None).await;
    let mut reader = Reader::connect(server.info.stream).await;
    tokio::time::sleep(Duration::from_millis(200)).await;

    // Target off-axis; the sun straight behind the camera along the line of sight, so the
    // lit disk is symmetric about the projected centre.
    let p = DVec3::new(0.8, -0.5, 10.0);
    let mut w = SerialWriter::new(master, "test pty");
    w.send(&Message::Pose(pose(1, p, -p))).unwrap();
    let f = reader.next().await;
    assert_eq!(f.meta.pose_seq, 1);
    let img = radiance(&f);
    let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
    for (i, &v) in img.iter().enumerate() {
        let (col, row) = ((i % 96) as f64 + 0.5, (i / 96) as f64 + 0.5);
        sx += col * v as f64;
        sy += row * v as f64;
        s += v as f64;
    }
    // Pinhole: f = 2 mm / 10 µm = 200 px; the centre projects to (48 + f·x/z, 48 + f·y/z).
    let (px, py) = (48.0 + 200.0 * p.x / p.z, 48.0 + 200.0 * p.y / p.z);
    assert!(s > 0.0);
    let (cx, cy) = (sx / s, sy / s);
    assert!(
        (cx - px).abs() <= 1.0 && (cy - py).abs() <= 1.0,
        "centroid ({cx:.2}, {cy:.2}) vs pinhole ({px:.2}, {py:.2})"
    );
    let lit = s;

    // Sun behind the target: the side the camera sees goes dark.
    w.send(&Message::Pose(pose(2, p, p))).unwrap();
    let f = reader.next().await;
    assert_eq!(f.meta.pose_seq, 2);
    let dark: f64 = radiance(&f).iter().map(|&v| v as f64).sum();
    assert!(dark < 0.01 * lit, "lit {lit}, sun behind {dark}");
    let report = server.finish().await;
    assert_eq!(report.poses_accepted, 2);
    assert_eq!(report.scheduler.frames, 2);
    drop(slave);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pose_flood_never_builds_a_backlog_and_frames_use_the_newest_pose() {
    let dir = tempfile::tempdir().unwrap();
    let trigger = TriggerConfig { mode: TriggerMode::Rate, rate_hz: Some(10.0), extrapolate: false };
    let cfg = config(sphere_scene(dir.path(), 32, 1), InputConfig::default(), trigger, GovernorConfig::default());
    let (tx, rx) = mpsc::channel(1024);
    let server = start(cfg, Some(rx)).await;
    let mut reader = Reader::connect(server.info.stream).await;
    // 1 kHz poses for about a second; remember when each was sent.
    let t0 = Instant::now();
    let sender = tokio::spawn(async move {
        let mut sent = Vec::new();
        let mut tick = tokio::time::interval(Duration::from_millis(1));
        for seq in 1..=1000u32 {
            tick.tick().await;
            let arrival = Instant::now();
            tx.send(InputEvent::Pose { pose: pose(seq, DVec3::new(0.0, 0.0, 10.0), DVec3::NEG_Z), arrival })
                .await
                .unwrap();
            sent.push(arrival);
        }
        sent
    });
    let mut frames = Vec::new();
    while frames.len() < 6 {
        let f = reader.next().await;
        frames.push((f.meta.pose_seq, Instant::now()));
    }
    let sent = sender.await.unwrap();
    let report = server.finish().await;
    // Frames are rendered from ever newer poses; a frame received at time t used a pose
    // sent no more than one frame period plus its render time before t.
    for w in frames.windows(2) {
        assert!(w[1].0 >= w[0].0, "pose sequence went backwards: {frames:?}");
    }
    for &(seq, received) in &frames {
        let newest_before = sent.iter().filter(|&&t| t <= received).count() as u32;
        assert!(seq <= newest_before && seq > 0);
    }
    let s = &report.scheduler;
    assert!(s.poses >= 1000 - 5, "poses {}", s.poses);
    assert!(
        s.superseded >= s.poses - s.frames - 1,
        "superseded {} of {} poses, {} frames",
        s.superseded,
        s.poses,
        s.frames
    );
    assert!(t0.elapsed() < PATIENCE);
}

async fn run_with_policy(policy: Policy, budget_ms: f64, spp: u32) -> (Vec<Frame>, ServeReport) {
    let dir = tempfile::tempdir().unwrap();
    let gov = GovernorConfig { policy, budget_ms: Some(budget_ms) };
    let cfg = config(sphere_scene(dir.path(), 128, spp), InputConfig::default(), TriggerConfig::default(), gov);
    let (tx, rx) = mpsc::channel(16);
    let server = start(cfg, Some(rx)).await;
    let mut reader = Reader::connect(server.info.stream).await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    let mut frames = Vec::new();
    for seq in 1..=10u32 {
        let p = pose(seq, DVec3::new(0.0, 0.0, 10.0), DVec3::NEG_Z);
        tx.send(InputEvent::Pose { pose: p, arrival: Instant::now() }).await.unwrap();
        frames.push(reader.next().await);
    }
    (frames, server.finish().await)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fixed_quality_reports_late_frames_and_fixed_rate_lowers_quality_to_meet_the_budget() {
    // An impossible budget with fixed quality: every frame keeps its quality and is late.
    let (frames, report) = run_with_policy(Policy::FixedQuality, 0.001, 64).await;
    assert!(frames.iter().all(|f| f.meta.spp == 64 && f.meta.flags.contains(FrameFlags::LATE)));
    assert_eq!(report.scheduler.late, 10);

    // Fixed rate: measure what the best quality costs here, then give a budget that only
    // a lower rung can meet; the governor must step down and flag it.
    let (best, _) = run_with_policy(Policy::FixedQuality, 10_000.0, 64).await;
    assert!(best.iter().all(|f| !f.meta.flags.contains(FrameFlags::LATE)));
    let (frames, report) = run_with_policy(Policy::FixedRate, 1e-3, 64).await;
    let last = frames.last().unwrap();
    assert!(last.meta.spp < 64 && last.meta.flags.contains(FrameFlags::DEGRADED), "last frame spp {}", last.meta.spp);
    assert!(report.scheduler.degraded > 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_trajectory_file_is_replayed_in_real_time_through_the_pose_path() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    let mut text = String::from("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz\n");
    for k in 0..5 {
        text.push_str(&format!("{},0,0,{},1,0,0,0,0,0,-1\n", f64::from(k) * 0.1, 10.0 + f64::from(k)));
    }
    std::fs::write(&csv, text).unwrap();
    let input = InputConfig { kind: InputKind::Trajectory, file: Some(csv), speed: Some(2.0), ..Default::default() };
    let cfg = config(sphere_scene(dir.path(), 32, 1), input, TriggerConfig::default(), GovernorConfig::default());
    let t0 = Instant::now();
    let server = start(cfg, None).await;
    let mut reader = Reader::connect(server.info.stream).await;
    // Frames come in pose order and the last pose (seq 4) is always rendered.
    let mut last = 0;
    while last != 4 {
        let f = reader.next().await;
        assert!(f.meta.pose_seq >= last);
        last = f.meta.pose_seq;
    }
    // 0.4 s of trajectory at 2× speed takes at least 0.2 s of wall time.
    assert!(t0.elapsed() >= Duration::from_millis(200));
    let report = server.finish().await;
    assert_eq!(report.poses_accepted, 5);
}
