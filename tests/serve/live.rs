//! The live page (`[live]`): a real headless Chromium shows the frames of a `serve` run fed
//! over a serial pty, where the pinhole puts the target, with the counters of `/metrics`;
//! and a viewer that never reads neither slows the loop nor goes uncounted.

use crate::serve_common::{self, PATIENCE, pose};
use glam::DVec3;
use hilcam_core::link::send::{MessageWriter, SerialWriter};
use hilcam_core::pose::Message;
use hilcam_core::serve::config::ServeConfig;
use serialport::SerialPort;
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use tokio::io::AsyncWriteExt;

/// Camera side and the preview's widest side: previews are 2×2 box means.
const SIDE: u32 = 128;
const PREVIEW: u32 = 64;
/// Pinhole focal length of `sphere_scene` (2 mm / 10 µm), pixels.
const F_PX: f64 = 200.0;

/// A serve config: the sphere scene, poses from `device` (or none), a frame per pose,
/// the metrics listener on a free port with the live page on it.
fn live_config(dir: &std::path::Path, device: Option<&str>) -> ServeConfig {
    let scene = serve_common::sphere_scene(dir, SIDE, 4);
    let input = match device {
        Some(d) => format!("[input]\nkind = \"serial\"\ndevice = {d:?}\nbaud = 921600\n"),
        None => String::new(),
    };
    let text = format!(
        "scene = {scene:?}\n{input}[stream]\nlisten = \"127.0.0.1:0\"\n\
         [metrics]\nlisten = \"127.0.0.1:0\"\nprint_interval_s = 60.0\n\
         [live]\nenabled = true\nmax_width = {PREVIEW}\nmax_rate_hz = 20.0\n"
    );
    let cfg: ServeConfig = toml::from_str(&text).unwrap();
    cfg.validate().unwrap();
    cfg
}

/// Chromium and a Python with Playwright; missing, the test fails with the fix.
fn browser_tools() -> (PathBuf, PathBuf) {
    let fix = "run scripts/setup-chromium.sh (scripts/test.sh does)";
    let chromium = std::env::var_os("HILCAM_CHROMIUM").map(PathBuf::from).unwrap_or_else(|| "/usr/bin/chromium".into());
    assert!(chromium.exists(), "no chromium at {}: {fix}", chromium.display());
    let python = std::env::var_os("HILCAM_PYTHON")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/hilcam/venv/bin/python")))
        .expect("no HOME and no HILCAM_PYTHON");
    let ok = Command::new(&python).args(["-c", "import playwright.sync_api"]).status().is_ok_and(|s| s.success());
    assert!(ok, "{} cannot import playwright: {fix}", python.display());
    (chromium, python)
}

/// tests/live/browser.py: one command in, one JSON line out.
struct Browser {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Browser {
    fn open(base: &str) -> Browser {
        let (chromium, python) = browser_tools();
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/live/browser.py");
        let mut child = Command::new(python)
            .arg(script)
            .arg("--chromium")
            .arg(chromium)
            .args(["--base", base])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("start tests/live/browser.py");
        let (stdin, stdout) = (child.stdin.take().unwrap(), BufReader::new(child.stdout.take().unwrap()));
        Browser { child, stdin, stdout }
    }

    /// Blocking: call it from `spawn_blocking`.
    fn ask(&mut self, cmd: &str) -> serde_json::Value {
        writeln!(self.stdin, "{cmd}").unwrap();
        let mut line = String::new();
        self.stdout.read_line(&mut line).unwrap();
        assert!(!line.is_empty(), "browser.py ended on {cmd:?} (its error is above)");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("{cmd}: {e}: {line}"))
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

async fn ask(b: Browser, cmd: String) -> (Browser, serde_json::Value) {
    tokio::task::spawn_blocking(move || {
        let mut b = b;
        let v = b.ask(&cmd);
        (b, v)
    })
    .await
    .unwrap()
}

/// Where the pinhole puts the sphere's centre, in preview pixels (2×2 blocks).
fn expected_centroid(p: DVec3) -> [f64; 2] {
    let half = f64::from(SIDE) / 2.0;
    [(half + F_PX * p.x / p.z) / 2.0, (half + F_PX * p.y / p.z) / 2.0]
}

fn centroid(v: &serde_json::Value) -> [f64; 2] {
    let c = v["centroid"].as_array().unwrap_or_else(|| panic!("no centroid: {v}"));
    [c[0].as_f64().unwrap(), c[1].as_f64().unwrap()]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn chromium_shows_each_posed_frame_where_the_pinhole_puts_it_with_the_counters_of_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let server = serve_common::start(live_config(dir.path(), Some(&slave.name().unwrap())), None).await;
    let base = format!("http://{}", server.info.metrics.expect("metrics listener"));
    let mut browser = Browser::open(&base);
    let mut w = SerialWriter::new(master, "test pty");

    // Sun behind the camera along the line of sight: a lit disk centred on the projection.
    let (p1, p2) = (DVec3::new(0.8, -0.5, 10.0), DVec3::new(-1.0, 0.6, 12.0));
    w.send(&Message::Pose(pose(1, p1, -p1))).unwrap();
    let first;
    (browser, first) = ask(browser, "frame 0".into()).await;
    assert_eq!((first["width"].as_u64(), first["height"].as_u64()), (Some(64), Some(64)), "{first}");
    // A pose the gate refuses (0.01 m is inside the 0.1 m minimum range), then a new one.
    w.send(&Message::Pose(pose(2, DVec3::new(0.0, 0.0, 0.01), DVec3::NEG_Z))).unwrap();
    w.send(&Message::Pose(pose(3, p2, -p2))).unwrap();
    let second;
    (browser, second) = ask(browser, "frame 1".into()).await;

    // The displayed image's brightness centroid against the pinhole: the disk is 10 (then
    // ~8) preview pixels in radius and symmetric about the projection; JPEG ringing and
    // the disk's pixelised edge move the centroid by well under one preview pixel.
    for (shown, p) in [(&first, p1), (&second, p2)] {
        let (got, want) = (centroid(shown), expected_centroid(p));
        assert!(
            (got[0] - want[0]).abs() <= 1.0 && (got[1] - want[1]).abs() <= 1.0,
            "displayed centroid {got:?} vs pinhole {want:?} for {p}"
        );
    }

    let counters;
    (browser, counters) = ask(browser, "counters".into()).await;
    let shown = &counters["page"];
    // browser.py waited for every row to equal /metrics; these rows must be among them.
    assert_eq!(shown["hilcam_frames_rendered_total"], "2", "{counters}");
    assert_eq!(shown["hilcam_input_rejected_total{reason=\"too_close\"}"], "1", "{counters}");
    assert_eq!(shown["hilcam_input_accepted_total"], "2", "{counters}");
    assert_eq!(shown["hilcam_live_viewers"], "1", "{counters}");

    let shot = dir.path().join("live.png");
    (browser, _) = ask(browser, format!("screenshot {}", shot.display())).await;
    let png = std::fs::read(&shot).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    if let Some(keep) = std::env::var_os("HILCAM_LIVE_SCREENSHOT") {
        std::fs::write(keep, &png).unwrap();
    }
    drop(browser);
    let report = server.finish().await;
    assert_eq!(report.scheduler.frames, 2);
    drop(slave);
}

/// Read an HTTP response head off `s` (up to the blank line).
async fn read_head(s: &mut tokio::net::TcpStream) -> String {
    use tokio::io::AsyncReadExt;
    let mut head = Vec::new();
    let mut b = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        assert_eq!(s.read(&mut b).await.unwrap(), 1, "connection closed in the head");
        head.push(b[0]);
    }
    String::from_utf8(head).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewers_that_never_read_do_not_slow_the_loop_and_their_drops_are_counted() {
    use hilcam_core::link::InputEvent;
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = live_config(dir.path(), None);
    cfg.live.queue_depth = 1;
    cfg.live.max_rate_hz = 100.0;
    // Never evicted, however long a loaded machine takes: every preview stays accounted.
    cfg.live.evict_after_s = 0.0;
    let (tx, rx) = tokio::sync::mpsc::channel(8);
    let server = serve_common::start(cfg, Some(rx)).await;
    let addr = server.info.metrics.unwrap();
    // Three viewers ask for the stream and never read another byte. Their tiny receive
    // windows keep the server's send buffers small too, so the sockets fill after a few
    // dozen previews and from then on each viewer's queue drops its oldest.
    let mut viewers = Vec::new();
    for _ in 0..3 {
        let sock = tokio::net::TcpSocket::new_v4().unwrap();
        sock.set_recv_buffer_size(2048).unwrap();
        let mut s = sock.connect(addr).await.unwrap();
        s.write_all(b"GET /live/stream.mjpeg HTTP/1.1\r\n\r\n").await.unwrap();
        let head = read_head(&mut s).await;
        assert!(head.contains("multipart/x-mixed-replace"), "{head}");
        viewers.push(s);
    }
    let mut reader = serve_common::Reader::connect(server.info.stream).await;
    let n = 400u32;
    let t0 = std::time::Instant::now();
    for seq in 0..n {
        let p = DVec3::new(0.0, 0.0, 10.0 + f64::from(seq) * 1e-3);
        tx.send(InputEvent::Pose { pose: pose(seq + 1, p, -p), arrival: std::time::Instant::now() }).await.unwrap();
        // One pose per frame: wait for it on the stream, so the loop's pace is the test's.
        let f = tokio::time::timeout(PATIENCE, reader.next()).await.unwrap();
        assert_eq!(f.meta.pose_seq, seq + 1);
    }
    let elapsed = t0.elapsed();
    let m = reqwest_metrics(addr).await;
    let value = |k: &str| m.iter().find(|(key, _)| key == k).map(|(_, v)| *v).unwrap_or_else(|| panic!("{k}"));
    assert_eq!(value("hilcam_frames_rendered_total"), f64::from(n));
    assert_eq!(value("hilcam_live_viewers"), 3.0);
    let (encoded, dropped) = (
        value("hilcam_live_previews_encoded_total"),
        value("hilcam_live_previews_dropped_total{reason=\"queue_full\"}"),
    );
    let sent = value("hilcam_live_previews_sent_total");
    assert!(encoded > 0.0 && dropped > 0.0, "encoded {encoded}, dropped {dropped}");
    // Every preview encoded went to each of the 3 viewers: written, dropped, or still
    // queued (≤ 1) or in the write blocked on the full socket (≤ 1) per viewer.
    let accounted = sent + dropped;
    assert!(
        accounted <= 3.0 * encoded && accounted >= 3.0 * encoded - 6.0,
        "3 × {encoded} encoded vs {sent} sent + {dropped} dropped"
    );
    eprintln!("{n} frames in {elapsed:?} with 3 stalled viewers: {encoded} previews, {sent} sent, {dropped} dropped");
    drop(viewers);
    server.finish().await;
}

/// `/metrics` as (series key, value).
async fn reqwest_metrics(addr: std::net::SocketAddr) -> Vec<(String, f64)> {
    use tokio::io::AsyncReadExt;
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(b"GET /metrics HTTP/1.1\r\n\r\n").await.unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).await.unwrap();
    let body = text.split_once("\r\n\r\n").unwrap().1;
    body.lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .map(|l| {
            let (k, v) = l.rsplit_once(' ').unwrap();
            (k.to_string(), v.parse().unwrap_or(f64::NAN))
        })
        .collect()
}
