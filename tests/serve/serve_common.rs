//! Helpers shared by the `serve` end-to-end tests: a small sphere scene, a config, the
//! embedded server, and a frame reader on the TCP stream.
#![allow(dead_code)]

use glam::DVec3;
use hilcam_core::frame::{DecodeError, Frame, decode_frame};
use hilcam_core::link::InputEvent;
use hilcam_core::pose::Pose;
use hilcam_core::render::film::Pixels;
use hilcam_core::serve::config::{GovernorConfig, InputConfig, ServeConfig, TriggerConfig};
use hilcam_core::serve::{Embed, ServeInfo, ServeReport, run};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tokio::io::AsyncReadExt;
use tokio::net::TcpStream;
use tokio::sync::{mpsc, oneshot};

pub const PATIENCE: Duration = Duration::from_secs(60);

/// A sphere scene with a small float-output camera (no sensor): pixels are radiance.
pub fn sphere_scene(dir: &Path, width: u32, spp: impl std::fmt::Display) -> PathBuf {
    sphere_scene_with(dir, width, spp, "")
}

/// [`sphere_scene`] with more TOML appended (e.g. a `[sensor]` section).
pub fn sphere_scene_with(dir: &Path, width: u32, spp: impl std::fmt::Display, extra: &str) -> PathBuf {
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
{extra}"#,
        mesh.display()
    );
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// A `[sensor]` with a detector (integration 20 µs, QE 0.5), an ADC of `bits` at
/// `gain_e_per_dn`, and `optics` (TOML lines) after `f_number = 2.8`: frames carry DN, and
/// a client's ExposureTime changes them.
pub fn detector_sensor(bits: u8, gain_e_per_dn: f64, optics: &str) -> String {
    format!(
        "[sensor]\noutput = \"dn\"\n[sensor.detector]\nqe = 0.5\nintegration_time_s = 2e-5\n\
         [sensor.adc]\nbits = {bits}\ngain_e_per_dn = {gain_e_per_dn:?}\n[sensor.band]\nmin_um = 0.45\nmax_um = 0.75\n\
         [sensor.optics]\nf_number = 2.8\n{optics}"
    )
}

pub fn config(scene: PathBuf, input: InputConfig, trigger: TriggerConfig, governor: GovernorConfig) -> ServeConfig {
    let text = "scene = \"x\"\n[stream]\nlisten = \"127.0.0.1:0\"\n";
    let mut cfg: ServeConfig = toml::from_str(text).unwrap();
    cfg.scene = scene;
    cfg.input = input;
    cfg.trigger = trigger;
    cfg.governor = governor;
    cfg.metrics.print_interval_s = 60.0;
    // Scraped by `Reader::subscribed` to know when the server lists a new client.
    cfg.metrics.listen = Some("127.0.0.1:0".parse().unwrap());
    cfg.validate().unwrap();
    cfg
}

pub struct Running {
    pub info: ServeInfo,
    pub stop: oneshot::Sender<()>,
    pub task: tokio::task::JoinHandle<anyhow::Result<ServeReport>>,
}

pub async fn start(cfg: ServeConfig, inputs: Option<mpsc::Receiver<InputEvent>>) -> Running {
    let (ready_tx, ready_rx) = oneshot::channel();
    let (stop, stop_rx) = oneshot::channel::<()>();
    let task = tokio::spawn(run(cfg, Embed { inputs, ready: Some(ready_tx), ..Embed::default() }, stop_rx));
    let info = tokio::time::timeout(PATIENCE, ready_rx).await.expect("server start").expect("server ready");
    Running { info, stop, task }
}

impl Running {
    pub async fn finish(self) -> ServeReport {
        let _ = self.stop.send(());
        tokio::time::timeout(PATIENCE, self.task).await.expect("server stops").unwrap().unwrap()
    }
}

/// Read frames off a stream connection.
pub struct Reader {
    pub s: TcpStream,
    pub buf: Vec<u8>,
}

impl Reader {
    pub async fn connect(addr: std::net::SocketAddr) -> Reader {
        Reader { s: TcpStream::connect(addr).await.unwrap(), buf: Vec::new() }
    }

    /// Connect and wait until the server lists this client (its `hilcam_stream_clients`
    /// gauge grows; a bounded poll, not a guess at how long that takes), so that every
    /// frame published after this returns reaches it. Needs the metrics listener
    /// ([`config`] turns it on).
    pub async fn subscribed(info: &ServeInfo) -> Reader {
        let metrics = info.metrics.expect("Reader::subscribed needs the server's metrics listener");
        let before = stream_clients(metrics).await;
        let reader = Reader::connect(info.stream).await;
        wait_stream_clients(info, before + 1).await;
        reader
    }

    pub async fn next(&mut self) -> Frame {
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

pub fn radiance(f: &Frame) -> &[f32] {
    match &f.pixels {
        Pixels::Float32(v) => v,
        other => panic!("expected float frames, got {:?}", other.format()),
    }
}

pub fn pose(seq: u32, position: DVec3, sun: DVec3) -> Pose {
    Pose { seq, t_ns: u64::from(seq) * 1_000_000, position, sun_dir: sun.normalize(), ..Pose::ahead(10.0) }
}

/// `hilcam …` as a user runs it: (exit success, stderr).
pub fn hilcam(args: &[&std::ffi::OsStr]) -> (bool, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam")).args(args).output().unwrap();
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// A frame's pixels as the bytes the stream carries (little-endian).
pub fn pixel_bytes(p: &hilcam_core::render::film::Pixels) -> Vec<u8> {
    use hilcam_core::render::film::Pixels;
    match p {
        Pixels::Mono8(d) => d.clone(),
        Pixels::Mono16 { data, .. } => data.iter().flat_map(|v| v.to_le_bytes()).collect(),
        Pixels::Float32(d) => d.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

/// GET /metrics from `addr` as text.
pub async fn metrics_text(addr: std::net::SocketAddr) -> String {
    use tokio::io::AsyncWriteExt;
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).await.unwrap();
    text
}

/// The value of the un-labelled series `series` in a metrics text.
pub fn metric(text: &str, series: &str) -> Option<u64> {
    text.lines().find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

/// Wait (a bounded poll) until the server lists at least `n` stream clients.
pub async fn wait_stream_clients(info: &ServeInfo, n: u64) {
    let metrics = info.metrics.expect("waiting for stream clients needs the server's metrics listener");
    let deadline = Instant::now() + PATIENCE;
    while stream_clients(metrics).await < n {
        assert!(Instant::now() < deadline, "the server never listed {n} stream clients");
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
}

/// Stream clients the server lists now.
async fn stream_clients(metrics: std::net::SocketAddr) -> u64 {
    metric(&metrics_text(metrics).await, "hilcam_stream_clients").unwrap_or(0)
}
