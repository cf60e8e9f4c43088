//! `hilcam serve` / `replay` / the recorder as an adversary uses them: clients that never
//! read, SIGTERM and SIGHUP instead of Ctrl-C, and a disk that fills up while recording.
//!
//! The full-disk tests mount a small tmpfs, which needs root (as in CI); if the mount
//! fails they fail, saying why.

use crate::serve_common;
use hilcam_core::link::InputEvent;
use hilcam_core::serve::config::{GovernorConfig, InputConfig, ServeConfig, TriggerConfig};
use hilcam_core::serve::scheduler::TriggerMode;
use hilcam_core::sink::recorder::FrameRecord;
use serve_common::*;
use std::collections::BTreeSet;
use std::io::{BufRead, Read, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::AsyncReadExt;
use tokio::sync::mpsc;

// ---------------------------------------------------------------------------------------
// Helpers

/// GET /metrics from the server's endpoint.
fn metrics_text(addr: SocketAddr) -> String {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).unwrap();
    out
}

/// The value of the series `name_and_labels` (exactly as rendered), 0 if absent.
fn metric(text: &str, name_and_labels: &str) -> u64 {
    text.lines()
        .filter_map(|l| l.strip_prefix(name_and_labels)?.strip_prefix(' '))
        .map(|v| v.trim().parse::<f64>().unwrap() as u64)
        .next()
        .unwrap_or(0)
}

async fn metric_async(addr: SocketAddr, series: &'static str) -> u64 {
    tokio::task::spawn_blocking(move || metric(&metrics_text(addr), series)).await.unwrap()
}

const EVICTED: &str = "hilcam_stream_clients_evicted_total{reason=\"stalled\"}";
const CONNECTED: &str = "hilcam_stream_clients";
const REJECTED: &str = "hilcam_stream_clients_rejected_total";

/// A rate-triggered server of 256² Float32 frames (256 KiB each) at `rate_hz`, fed one
/// pose (rate mode re-renders it every tick), with a metrics endpoint.
async fn big_frame_server(
    dir: &Path,
    rate_hz: f64,
    max_clients: usize,
    evict_after_s: f64,
) -> (Running, mpsc::Sender<InputEvent>) {
    let scene = sphere_scene(dir, 256, 1);
    let trigger = TriggerConfig { mode: TriggerMode::Rate, rate_hz: Some(rate_hz), extrapolate: false };
    let mut cfg = config(scene, InputConfig::default(), trigger, GovernorConfig::default());
    cfg.stream.max_clients = max_clients;
    cfg.stream.evict_after_s = evict_after_s;
    cfg.metrics.listen = Some("127.0.0.1:0".parse().unwrap());
    cfg.validate().unwrap();
    let (tx, rx) = mpsc::channel(16);
    let sun = glam::DVec3::new(0.3, 0.2, -1.0);
    tx.send(InputEvent::Pose { pose: pose(1, glam::DVec3::new(0.0, 0.0, 10.0), sun), arrival: Instant::now() })
        .await
        .unwrap();
    (start(cfg, Some(rx)).await, tx)
}

async fn wait_for_metric(addr: SocketAddr, series: &'static str, want: u64, within: Duration) -> Duration {
    let t0 = Instant::now();
    loop {
        let v = metric_async(addr, series).await;
        if v == want {
            return t0.elapsed();
        }
        assert!(t0.elapsed() < within, "{series} is {v}, expected {want} within {within:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

// ---------------------------------------------------------------------------------------
// Stalled clients

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stalled_clients_are_evicted_and_a_reader_gets_the_slot() {
    const SLOTS: usize = 4;
    let dir = tempfile::tempdir().unwrap();
    let (server, _poses) = big_frame_server(dir.path(), 30.0, SLOTS, 1.0).await;
    let (stream, metrics) = (server.info.stream, server.info.metrics.unwrap());

    // Every slot taken by a client that never reads.
    let t_connect = Instant::now();
    let mut stalled = Vec::new();
    for _ in 0..SLOTS {
        stalled.push(tokio::net::TcpStream::connect(stream).await.unwrap());
    }
    wait_for_metric(metrics, CONNECTED, SLOTS as u64, Duration::from_secs(10)).await;

    // The board's own client is refused while they hold the slots.
    let mut refused = tokio::net::TcpStream::connect(stream).await.unwrap();
    let mut b = [0u8; 1];
    let n = tokio::time::timeout(Duration::from_secs(10), refused.read(&mut b)).await.expect("closed at once");
    assert!(matches!(n, Ok(0) | Err(_)), "a connection beyond max_clients is closed: {n:?}");
    assert_eq!(metric_async(metrics, REJECTED).await, 1);

    // Their socket buffers fill, then their queues; after 1 s full they are evicted.
    let took = wait_for_metric(metrics, EVICTED, SLOTS as u64, Duration::from_secs(30)).await + Duration::ZERO;
    let since_connect = t_connect.elapsed();
    eprintln!("{SLOTS} stalled clients evicted {since_connect:.2?} after connecting (polled {took:.2?})");
    assert!(since_connect >= Duration::from_secs(1), "evicted before evict_after_s: {since_connect:?}");
    wait_for_metric(metrics, CONNECTED, 0, Duration::from_secs(10)).await;

    // A well-behaved client now connects and receives frames.
    let mut reader = Reader::connect(stream).await;
    let mut seqs = Vec::new();
    for _ in 0..5 {
        let f = reader.next().await;
        assert_eq!((f.meta.width, f.meta.height), (256, 256));
        seqs.push(f.meta.frame_seq);
    }
    assert!(seqs.windows(2).all(|w| w[1] > w[0]), "{seqs:?}");

    // The evicted connections are closed: after what the kernel had buffered, EOF or reset.
    for mut s in stalled {
        let mut buf = vec![0u8; 1 << 20];
        let end = tokio::time::timeout(Duration::from_secs(20), async {
            loop {
                match s.read(&mut buf).await {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {}
                }
            }
        })
        .await;
        assert!(end.is_ok(), "an evicted connection stays open");
    }
    assert_eq!(metric_async(metrics, EVICTED).await, SLOTS as u64, "only the stalled clients were evicted");
    let report = server.finish().await;
    assert!(report.scheduler.frames > 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_reader_that_catches_up_now_and_then_is_not_evicted() {
    let dir = tempfile::tempdir().unwrap();
    let (server, _poses) = big_frame_server(dir.path(), 30.0, 4, 3.0).await;
    let (stream, metrics) = (server.info.stream, server.info.metrics.unwrap());
    let mut reader = Reader::connect(stream).await;
    let t0 = Instant::now();
    let (mut frames, mut last_seq, mut missing) = (0u64, None::<u64>, 0u64);
    // Pauses of 2 s (more than the socket buffers hold), each followed by 150 ms of
    // reading: far behind the stream (frames are lost), but the queue empties after
    // every pause, so it is never full for evict_after_s (3 s).
    while t0.elapsed() < Duration::from_secs(8) {
        let burst = Instant::now();
        while burst.elapsed() < Duration::from_millis(150) {
            let seq = reader.next().await.meta.frame_seq;
            missing += last_seq.map_or(0, |l| seq - l - 1);
            last_seq = Some(seq);
            frames += 1;
        }
        tokio::time::sleep(Duration::from_secs(2)).await;
    }
    let text = tokio::task::spawn_blocking(move || metrics_text(metrics)).await.unwrap();
    assert_eq!(metric(&text, EVICTED), 0, "a reading client was evicted");
    assert_eq!(metric(&text, CONNECTED), 1);
    let dropped = metric(&text, "hilcam_stream_frames_dropped_total{client=\"1\",reason=\"queue_full\"}");
    assert!(dropped > 0 && missing > 0, "the slow reader lost frames (drop-oldest, counted): {dropped}, {missing}");
    eprintln!("slow reader: {frames} frames read, {missing} missing, {dropped} dropped at the server, not evicted");
    server.finish().await;
}

#[test]
fn evict_after_s_is_configurable_and_zero_means_never() {
    let parse = |extra: &str| -> Result<ServeConfig, String> {
        let text = format!("scene = \"x\"\n[stream]\nlisten = \"127.0.0.1:0\"\n{extra}");
        let cfg: ServeConfig = toml::from_str(&text).map_err(|e| e.to_string())?;
        cfg.validate().map_err(|(f, m)| format!("{f}: {m}"))?;
        Ok(cfg)
    };
    assert_eq!(parse("").unwrap().stream.evict_after(), Some(Duration::from_secs(5)));
    assert_eq!(parse("evict_after_s = 2.5").unwrap().stream.evict_after(), Some(Duration::from_millis(2500)));
    assert_eq!(parse("evict_after_s = 0").unwrap().stream.evict_after(), None);
    let e = parse("evict_after_s = -1").unwrap_err();
    assert!(e.contains("stream.evict_after_s") && e.contains("-1"), "{e}");
}

// ---------------------------------------------------------------------------------------
// Signals

fn hilcam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hilcam"))
}

/// stderr of a child, collected line by line on a thread (so that it never blocks).
fn collect_stderr(child: &mut Child) -> Arc<Mutex<Vec<String>>> {
    let lines = Arc::new(Mutex::new(Vec::new()));
    let err = child.stderr.take().unwrap();
    let l = lines.clone();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            l.lock().unwrap().push(line);
        }
    });
    lines
}

fn wait_exit(child: &mut Child, within: Duration) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if t0.elapsed() > within {
            let _ = child.kill();
            panic!("process did not exit within {within:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn wait_until(what: &str, within: Duration, mut ok: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ok() {
        assert!(t0.elapsed() < within, "{what}: not within {within:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn send_signal(child: &Child, sig: libc::c_int) {
    // SAFETY: kill(2) on our own child's pid.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, sig) };
    assert_eq!(r, 0, "kill({}, {sig}): {}", child.id(), std::io::Error::last_os_error());
}

/// A serve config: the sphere at `width` px, the fly-around trajectory as input, rate
/// trigger at `rate_hz`, and `extra` TOML appended (e.g. a [record] section).
fn serve_toml(dir: &Path, width: u32, rate_hz: f64, extra: &str) -> PathBuf {
    let scene = sphere_scene(dir, width, 1);
    let traj = std::fs::canonicalize("scenes/trajectories/flyaround.csv").unwrap();
    let text = format!(
        "scene = \"{}\"\n[input]\nkind = \"trajectory\"\nfile = \"{}\"\n[trigger]\nmode = \"rate\"\nrate_hz = \
         {rate_hz}\n[stream]\nlisten = \"127.0.0.1:0\"\n[metrics]\nprint_interval_s = 60.0\n{extra}",
        scene.display(),
        traj.display()
    );
    let p = dir.join("serve.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn session_lines(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path).unwrap_or_default().lines().filter_map(|l| serde_json::from_str(l).ok()).collect()
}

fn serve_stops_cleanly_on(sig: libc::c_int) {
    let dir = tempfile::tempdir().unwrap();
    let cfg = serve_toml(dir.path(), 32, 20.0, "");
    let session = dir.path().join("run.session.jsonl");
    let mut child = hilcam()
        .args(["serve", "--config", cfg.to_str().unwrap(), "--record-session", session.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = collect_stderr(&mut child);
    let frames = |s: &Path| session_lines(s).iter().filter(|v| v["kind"] == "frame").count();
    wait_until("frames in the session file", Duration::from_secs(60), || frames(&session) >= 3);
    send_signal(&child, sig);
    let status = wait_exit(&mut child, Duration::from_secs(30));
    let mut stdout = String::new();
    child.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
    let err = stderr.lock().unwrap().join("\n");
    assert_eq!(status.code(), Some(0), "signal {sig}: {status}\n{stdout}\n{err}");
    let lines = session_lines(&session);
    let last = lines.last().unwrap();
    assert_eq!(last["kind"], "end", "the session file ends with its end line");
    let n = lines.iter().filter(|v| v["kind"] == "frame").count() as u64;
    assert_eq!(last["frames"].as_u64(), Some(n));
    assert!(stdout.contains(&format!("frames {n} (")), "summary printed: {stdout}");
    assert!(stdout.contains("session ") && stdout.contains(" lines, 0 dropped"), "{stdout}");
    let name = if sig == libc::SIGTERM { "SIGTERM" } else { "SIGHUP" };
    assert!(err.contains(&format!("{name}: finishing the current frame")), "{err}");
}

#[test]
fn sigterm_stops_serve_cleanly() {
    serve_stops_cleanly_on(libc::SIGTERM);
}

#[test]
fn sighup_stops_serve_cleanly() {
    serve_stops_cleanly_on(libc::SIGHUP);
}

/// Complete lines in `dir`'s frames.jsonl (safe to call while it is being written).
fn logged_lines(dir: &Path) -> usize {
    std::fs::read(dir.join("frames.jsonl")).map_or(0, |b| b.iter().filter(|c| **c == b'\n').count())
}

fn log_records(dir: &Path) -> Vec<FrameRecord> {
    std::fs::read_to_string(dir.join("frames.jsonl"))
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("frames.jsonl line {l:?}: {e}")))
        .collect()
}

/// The frame images in `dir`, and every other file except the log and the manifest.
fn frame_files(dir: &Path) -> (BTreeSet<String>, Vec<String>) {
    let (mut frames, mut other) = (BTreeSet::new(), Vec::new());
    for e in std::fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().to_string();
        if name.starts_with("frame_") && name.ends_with(".pfm") {
            frames.insert(name);
        } else if !(name.starts_with("frames") && name.ends_with(".jsonl")) && name != "replay.manifest.json" {
            other.push(name);
        }
    }
    (frames, other)
}

/// Every frame file is a complete `size`² PFM, no temporary file is left, and the log
/// lists exactly the files present. Returns the number of frames.
fn assert_complete_and_logged(dir: &Path, size: u32) -> usize {
    let (frames, other) = frame_files(dir);
    assert!(other.is_empty(), "leftover files in {}: {other:?}", dir.display());
    for f in &frames {
        let p = dir.join(f);
        let len = std::fs::metadata(&p).unwrap().len();
        assert!(len > 0, "{f} is empty");
        let img = hilcam_core::render::film::read_pfm(&p)
            .unwrap_or_else(|e| panic!("{f} ({len} bytes) does not decode: {e}"));
        assert_eq!((img.width, img.height), (size, size), "{f}");
    }
    let logged: BTreeSet<String> = log_records(dir).into_iter().map(|r| r.file).collect();
    assert_eq!(logged, frames, "frames.jsonl lists exactly the files present");
    frames.len()
}

fn replay_args(traj: &Path, scene: &Path, out: &Path, every: u32) -> Vec<String> {
    let s = |p: &Path| p.to_str().unwrap().to_string();
    vec![
        "replay".into(),
        "--trajectory".into(),
        s(traj),
        "--scene".into(),
        s(scene),
        "--out".into(),
        s(out),
        "--format".into(),
        "pfm".into(),
        "--every".into(),
        every.to_string(),
    ]
}

#[test]
fn sigterm_stops_replay_after_the_frame_in_hand_and_it_resumes() {
    let dir = tempfile::tempdir().unwrap();
    // A few tens of ms per frame on one thread: long enough to signal mid-run.
    let scene = sphere_scene(dir.path(), 96, 16);
    let traj = std::fs::canonicalize("scenes/trajectories/flyaround.csv").unwrap();
    let out = dir.path().join("out");
    let args = replay_args(&traj, &scene, &out, 10); // 121 frames
    let mut child =
        hilcam().args(&args).args(["--threads", "1"]).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let stderr = collect_stderr(&mut child);
    wait_until("replay frames logged", Duration::from_secs(60), || logged_lines(&out) >= 3);
    send_signal(&child, libc::SIGTERM);
    let status = wait_exit(&mut child, Duration::from_secs(60));
    let err = stderr.lock().unwrap().join("\n");
    assert!(!status.success(), "an interrupted replay exits non-zero: {err}");
    let done = assert_complete_and_logged(&out, 96);
    assert!(done < 121, "stopped before the end ({done} frames)");
    let want = format!("stopped by SIGTERM: {done} of 121 frames are complete in {}", out.display());
    assert!(err.contains(&want), "expected «{want}» in:\n{err}");
    assert!(err.contains("run the same command again to resume"), "{err}");

    // The same command finishes the rest.
    let o = hilcam().args(&args).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains(&format!("{} rendered in", 121 - done)), "{stdout}");
    assert_eq!(assert_complete_and_logged(&out, 96), 121);
}

// ---------------------------------------------------------------------------------------
// Full disk

/// A tmpfs of `size` bytes mounted on a fresh directory; unmounted on drop (also when
/// the test fails).
struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(size: u64) -> Tmpfs {
        let dir = tempfile::tempdir().unwrap();
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs", dir.path().to_str().unwrap()])
            .output()
            .unwrap_or_else(|e| panic!("cannot run mount (this test needs mount and root): {e}"));
        assert!(
            o.status.success(),
            "mounting a {size}-byte tmpfs on {} failed (this test needs root to simulate a full disk): {}",
            dir.path().display(),
            String::from_utf8_lossy(&o.stderr)
        );
        Tmpfs { dir }
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    /// Fill all but `leave` bytes with a ballast file (deleted later to free space).
    fn ballast(&self, leave: u64) -> PathBuf {
        let st = nix_statvfs(self.path());
        let p = self.path().join("ballast");
        std::fs::write(&p, vec![0u8; st.saturating_sub(leave) as usize]).unwrap();
        p
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(self.dir.path()).status();
    }
}

/// Free bytes on the filesystem of `p`.
fn nix_statvfs(p: &Path) -> u64 {
    let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
    // SAFETY: statvfs fills the struct we pass.
    unsafe {
        let mut s: libc::statvfs = std::mem::zeroed();
        assert_eq!(libc::statvfs(c.as_ptr(), &mut s), 0, "statvfs {}", p.display());
        s.f_bavail as u64 * s.f_frsize as u64
    }
}

fn count(lines: &[String], needle: &str) -> usize {
    lines.iter().filter(|l| l.contains(needle)).count()
}

#[test]
fn recording_onto_a_full_disk_leaves_no_partial_files_and_recovers() {
    let fs = Tmpfs::mount(4 << 20);
    let work = tempfile::tempdir().unwrap();
    let frames_dir = fs.path().join("frames");
    std::fs::create_dir(&frames_dir).unwrap();
    // 64² Float32 PFM frames: 16 KiB each, 20 per second; room for about 12.
    let ballast = fs.ballast(200 << 10);
    let record = format!("[record]\ndir = \"{}\"\nformat = \"pfm\"\n", frames_dir.display());
    let cfg = serve_toml(work.path(), 64, 20.0, &record);
    let mut child = hilcam()
        .args(["serve", "--config", cfg.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = collect_stderr(&mut child);
    let lines = || stderr.lock().unwrap().clone();

    // Full within a second or so; then fail for a while (long enough for one "still failing").
    wait_until("the first failure", Duration::from_secs(60), || count(&lines(), "cannot write frames") > 0);
    std::thread::sleep(Duration::from_millis(6000));
    let failing = lines();
    assert_eq!(
        count(&failing, "cannot write frames (disk full)"),
        1,
        "one first-failure line:\n{}",
        failing.join("\n")
    );
    let still = count(&failing, "still failing (disk full)");
    assert!((1..=2).contains(&still), "a periodic reminder, not one per frame ({still}):\n{}", failing.join("\n"));
    // (Only the frame files here: temporary files come and go while the writer tries.)
    let during = frame_files(&frames_dir).0.len();
    assert!(during > 0, "some frames were written before the disk filled");

    // Free space: writing resumes, reported once.
    std::fs::remove_file(&ballast).unwrap();
    wait_until("recovery", Duration::from_secs(30), || count(&lines(), "writing frames again after") > 0);
    wait_until("frames after recovery", Duration::from_secs(30), || frame_files(&frames_dir).0.len() > during + 5);
    send_signal(&child, libc::SIGTERM);
    let status = wait_exit(&mut child, Duration::from_secs(30));
    let mut stdout = String::new();
    child.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
    let all = lines();
    assert_eq!(status.code(), Some(0), "{stdout}\n{}", all.join("\n"));
    assert_eq!(count(&all, "cannot write frames"), 1, "{}", all.join("\n"));
    assert_eq!(count(&all, "writing frames again after"), 1);
    let written = assert_complete_and_logged(&frames_dir, 64);

    // Accounting: every frame rendered was written, dropped (queue) or counted as an error.
    let stats = all.iter().find(|l| l.contains("recorder closed")).expect("recorder stats line");
    let field = |name: &str| -> u64 {
        let at = stats.find(&format!("{name}: ")).unwrap_or_else(|| panic!("{name} in {stats}")) + name.len() + 2;
        stats[at..].split(|c: char| !c.is_ascii_digit()).next().unwrap().parse().unwrap()
    };
    let (w, dropped, errors, disk_full) = (field("written"), field("dropped"), field("errors"), field("disk_full"));
    assert_eq!(w as usize, written, "{stats}");
    assert!(disk_full > 0 && errors == disk_full, "{stats}");
    let rendered: u64 = stdout
        .lines()
        .find_map(|l| l.strip_prefix("frames ")?.split(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("frames line in {stdout}"));
    assert_eq!(w + dropped + errors, rendered, "{stats}\n{stdout}");
    eprintln!("full disk: {rendered} frames, {w} written, {disk_full} not written (disk full), {dropped} dropped");
}

#[test]
fn replay_onto_a_full_disk_stops_naming_the_frame_and_resumes() {
    let fs = Tmpfs::mount(4 << 20);
    let work = tempfile::tempdir().unwrap();
    let scene = sphere_scene(work.path(), 64, 1);
    let traj = std::fs::canonicalize("scenes/trajectories/flyaround.csv").unwrap();
    let out = fs.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let ballast = fs.ballast(200 << 10); // room for about 12 of the 31 frames
    let args = replay_args(&traj, &scene, &out, 40);
    let o = hilcam().args(&args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a replay onto a full disk fails: {err}");
    let done = assert_complete_and_logged(&out, 64);
    assert!((1..31).contains(&done), "{done} frames done");
    let frame = format!("frame {} (frame_{:010}.pfm)", done as u64 * 40, done as u64 * 40);
    assert!(err.contains(&format!("{}: disk full: {frame}", out.display())), "names the directory and frame: {err}");
    assert!(err.contains(&format!("{done} of 31 frames are complete")), "{err}");

    std::fs::remove_file(&ballast).unwrap();
    let o = hilcam().args(&args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(assert_complete_and_logged(&out, 64), 31);
}
