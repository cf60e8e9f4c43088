//! slcan over pseudo-terminals: the receiver talking to a scripted "adapter",
//! hilcam's own slcan sender, and the python-can slcan interface.

use crate::pose_common;

use hilcam_core::Shutdown;
use hilcam_core::link::send::{SendOptions, SlcanWriter, send_trajectory_blocking};
use hilcam_core::link::serial::SerialConfig;
use hilcam_core::link::slcan::{SlcanConfig, run_slcan};
use hilcam_core::pose::Message;
use hilcam_core::pose::can::{CanIds, encode_message};
use hilcam_core::pose::slcan::{SlcanDecoder, SlcanItem, encode_frame};
use hilcam_core::pose::trajectory::Trajectory;
use pose_common::*;
use serialport::{SerialPort, TTYPort};
use std::io::{Read, Write};
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};

fn cfg(path: String) -> SlcanConfig {
    SlcanConfig {
        serial: SerialConfig::new(path, 115_200),
        bitrate: Some(500_000),
        listen_only: false,
        ids: CanIds::default(),
    }
}

/// Reads from `port` until `want` appears (the adapter's view of commands).
fn read_until(port: &mut TTYPort, want: &[u8]) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 256];
    let t0 = std::time::Instant::now();
    port.set_timeout(Duration::from_millis(50)).unwrap();
    while !got.windows(want.len()).any(|w| w == want) {
        assert!(t0.elapsed() < PATIENCE, "never saw {want:?}, got {got:?}");
        match port.read(&mut buf) {
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => panic!("{e}"),
        }
    }
    got
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn receiver_configures_adapter_and_decodes_groups() {
    let (mut adapter, slave) = pty_pair();
    let (tx, mut rx) = mpsc::channel(4096);
    let c = counters();
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let task = tokio::spawn(run_slcan(cfg(pty_name(&slave)), tx, c.clone(), stop_rx));
    // The adapter sees: close, 500 kbit/s, open — and acknowledges each.
    let cmds = read_until(&mut adapter, b"O\r");
    assert_eq!(cmds, b"C\rS6\rO\r");
    adapter.set_timeout(PATIENCE).unwrap();
    adapter.write_all(b"\r\r\r").unwrap();

    let ids = CanIds::default();
    let traj = Trajectory::load(root().join("scenes/trajectories/flyaround.csv")).unwrap();
    let mut text = String::new();
    for (k, s) in traj.iter().take(50).enumerate() {
        // Alternate classic groups and FD frames; drop frame 2 of pose 8.
        let frames = encode_message(ids, &Message::Pose(s.to_pose(k as u32)), k % 2 == 1);
        for (j, f) in frames.iter().enumerate() {
            if !(k == 8 && j == 2) {
                text.push_str(&encode_frame(f));
            }
        }
        if k == 20 {
            text.push_str("t1232AABB\r"); // other bus traffic
            text.push_str("tZZZ\r"); // garbage line
            text.push('\x07'); // a NACK
        }
    }
    text.push_str(&encode_frame(&encode_message(ids, &Message::Trigger { seq: 0, t_ns: 1 }, false)[0]));
    adapter.write_all(text.as_bytes()).unwrap();
    let mut ev = Vec::new();
    assert!(
        collect_until(&mut rx, &mut ev, |e| e
            .iter()
            .any(|x| matches!(x, hilcam_core::link::InputEvent::Trigger { .. })))
        .await
    );
    let got = poses(&ev);
    assert_eq!(got.len(), 49, "{}", c.to_prometheus());
    assert!(got.iter().all(|p| p.seq != 8));
    for p in &got {
        let s = &traj[p.seq as usize];
        assert!((p.position - s.position).length() <= s.position.length() * 1e-7);
    }
    assert_eq!(get(&c.groups_missing_frame), 1, "{}", c.to_prometheus());
    assert_eq!(get(&c.can_foreign_frames), 1);
    assert_eq!(get(&c.slcan_bad_lines), 1);
    assert_eq!(get(&c.slcan_nacks), 1);
    stop_tx.send(()).unwrap();
    task.await.unwrap().unwrap();
}

#[test]
fn slcan_sender_writes_what_an_adapter_expects() {
    let (mut adapter, slave) = pty_pair();
    let traj = Trajectory::load(root().join("scenes/trajectories/approach.csv")).unwrap();
    let sample = traj[..20].to_vec();
    let port = hilcam_core::link::serial::open_port(
        &pty_name(&slave),
        115_200,
        serialport::DataBits::Eight,
        serialport::Parity::None,
        serialport::StopBits::One,
    )
    .unwrap();
    let mut w = SlcanWriter::open(port, "pty", Some(1_000_000), CanIds::default(), false).unwrap();
    let opts = SendOptions { rate_hz: None, speed: f64::INFINITY };
    let stats = send_trajectory_blocking(&sample, &opts, &mut w, &Shutdown::new()).unwrap();
    assert_eq!(stats.poses, 20);
    // 20 poses × 6 frames (approach has no velocity/rate columns) after "C S8 O".
    let mut dec = SlcanDecoder::new();
    let mut asm = hilcam_core::pose::can::CanAssembler::new(CanIds::default());
    let mut got = vec![];
    let mut raw = Vec::new();
    let mut buf = [0u8; 4096];
    while got.len() < 20 {
        adapter.set_timeout(Duration::from_millis(50)).unwrap();
        let n = match adapter.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) => panic!("{e}"),
        };
        raw.extend_from_slice(&buf[..n]);
        dec.push(&buf[..n]);
        while let Some(item) = dec.next_item() {
            if let Ok(SlcanItem::Frame(f)) = item
                && let Some(hilcam_core::pose::can::CanEvent::Message(Message::Pose(p))) = asm.push(&f)
            {
                got.push(p);
            }
        }
    }
    assert!(raw.starts_with(b"C\rS8\rO\r"));
    assert_eq!(raw.iter().filter(|&&b| b == b'\r').count(), 3 + 20 * 6);
    for (k, p) in got.iter().enumerate() {
        assert_eq!(p.t_ns, sample[k].to_pose(0).t_ns);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_can_slcan_example_sends_the_group() {
    let Some(py) = python() else { return };
    let cable = NullModem::new();
    let (tx, mut rx) = mpsc::channel(4096);
    let c = counters();
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let task = tokio::spawn(run_slcan(cfg(cable.b.clone()), tx, c.clone(), stop_rx));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let traj = root().join("scenes/trajectories/flyaround.csv");
    let want = Trajectory::load(&traj).unwrap();
    let n = 25;
    let child = std::process::Command::new(&py)
        .arg(root().join("examples/send_can.py"))
        .args([
            "--interface",
            "slcan",
            "--channel",
            &cable.a,
            "--count",
            &n.to_string(),
            "--speed",
            "inf",
            "--trajectory",
        ])
        .arg(&traj)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut ev = Vec::new();
    collect_until(&mut rx, &mut ev, |e| poses(e).len() >= n).await;
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let got = poses(&ev);
    assert_eq!(got.len(), n, "{}", c.to_prometheus());
    for (k, p) in got.iter().enumerate() {
        let w = want[k].to_pose(k as u32);
        assert_eq!(p.t_ns, w.t_ns);
        assert!((p.position - w.position).abs().max_element() <= w.position.abs().max_element() * 6e-8);
        assert!((p.attitude.normalize() - w.attitude.normalize()).length() < 1e-6);
        assert_eq!(p.velocity.is_some(), w.velocity.is_some());
    }
    assert_eq!(get(&c.groups_crc) + get(&c.groups_missing_frame) + get(&c.groups_mixed), 0);
    stop_tx.send(()).unwrap();
    task.await.unwrap().unwrap();
}

#[test]
fn hilcam_send_slcan_carries_the_planet_and_refuses_what_one_fd_frame_cannot() {
    let dir = tempfile::tempdir().unwrap();
    let traj = dir.path().join("moon.csv");
    // Both rates and the planet: 75 block bytes, an 11-frame classic group per pose.
    std::fs::write(
        &traj,
        "time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,vx,vy,vz,wx,wy,wz,plx,ply,plz\n\
         0,0,0,40,1,0,0,0,0,0,-1,0,0,-1,0,0,0.01,-1.25e7,3.5e6,3.844e8\n\
         0.5,0,0,39.5,1,0,0,0,0,0,-1,0,0,-1,0,0,0.01,-1.2500001e7,3.4999e6,3.8440001e8\n",
    )
    .unwrap();
    let want = Trajectory::load(&traj).unwrap();
    let bin = env!("CARGO_BIN_EXE_hilcam");
    // One CAN FD frame cannot hold it (76 of 64 bytes): refused before the port opens.
    let o = std::process::Command::new(bin)
        .args(["send", "--slcan", "/nonexistent/adapter", "--can-fd", "--trajectory"])
        .arg(&traj)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("moon.csv") && err.contains("without --can-fd"), "{err}");
    // As classic groups through an adapter (a pty): the planet arrives in f32.
    let (mut adapter, slave) = pty_pair();
    let mut child = std::process::Command::new(bin)
        .args(["send", "--slcan", &pty_name(&slave), "--speed", "inf", "--trajectory"])
        .arg(&traj)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut dec = SlcanDecoder::new();
    let mut asm = hilcam_core::pose::can::CanAssembler::new(CanIds::default());
    let (mut got, mut frames) = (vec![], 0);
    let mut buf = [0u8; 4096];
    let deadline = std::time::Instant::now() + PATIENCE;
    while got.len() < want.len() && std::time::Instant::now() < deadline {
        adapter.set_timeout(Duration::from_millis(50)).unwrap();
        let n = match adapter.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) => panic!("{e}"),
        };
        dec.push(&buf[..n]);
        while let Some(item) = dec.next_item() {
            if let Ok(SlcanItem::Frame(f)) = item {
                frames += 1;
                if let Some(hilcam_core::pose::can::CanEvent::Message(Message::Pose(p))) = asm.push(&f) {
                    got.push(p);
                }
            }
        }
    }
    assert!(child.wait().unwrap().success());
    assert_eq!(frames, 11 * want.len());
    let f32ed = |c: glam::DVec3| glam::DVec3::new(c.x as f32 as f64, c.y as f32 as f64, c.z as f32 as f64);
    let centres: Vec<_> = got.iter().map(|p| p.planet_centre).collect();
    assert_eq!(centres, want.iter().map(|s| s.planet_centre.map(f32ed)).collect::<Vec<_>>());
    // The Python encoder (examples/hilcam_proto.py, its own struct packing and CRC-16)
    // writes the same 11 frames per pose.
    let Some(py) = python() else { return };
    let script = "import sys; sys.path.insert(0, sys.argv[1]); import hilcam_proto as hp\n\
                  for k, r in enumerate(hp.load_trajectory(sys.argv[2])):\n\
                  \x20   print(' '.join(f'{i}:{d.hex()}' for i, d in hp.can_group(hp.pose_of(r, k))))";
    let o =
        std::process::Command::new(&py).args(["-c", script]).arg(root().join("examples")).arg(&traj).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rust: Vec<String> = want
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let g = hilcam_core::pose::can::encode_group(CanIds::default(), &s.to_pose(k as u32));
            let hex = |d: &[u8]| d.iter().map(|b| format!("{b:02x}")).collect::<String>();
            g.iter().map(|f| format!("{}:{}", f.id - 0x300, hex(f.data()))).collect::<Vec<_>>().join(" ")
        })
        .collect();
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().collect::<Vec<_>>(), rust);
}
