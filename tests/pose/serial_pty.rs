//! The serial receiver over real pseudo-terminals: line settings, partial
//! writes, garbage between frames, bad poses, unplug and replug, and the
//! pyserial example and `hilcam send --serial` as senders.

use crate::pose_common;

use glam::DVec3;
use hilcam_core::link::serial::{SerialConfig, open_port, run_serial};
use hilcam_core::pose::serial::encode_frame;
use hilcam_core::pose::trajectory::Trajectory;
use hilcam_core::pose::validate::{PoseLimits, Rejection};
use hilcam_core::pose::{Message, Pose};
use pose_common::*;
use serialport::{DataBits, Parity, SerialPort, StopBits, TTYPort};
use std::io::Write;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};

fn pose(seq: u32, t_ns: u64) -> Pose {
    Pose { seq, t_ns, position: DVec3::new(0.1, -0.2, 50.0 - seq as f64 * 0.01), ..Pose::ahead(1.0) }
}

#[test]
fn line_settings_are_applied() {
    let (_master, slave) = TTYPort::pair().unwrap();
    let path = pty_name(&slave);
    // Linux ptys force CS8 and no parity (drivers/tty/pty.c, pty_set_termios),
    // so only the baud rate and stop bits can be checked here; data bits and
    // parity go through the same serialport builder call.
    for (baud, stop) in
        [(9600, StopBits::One), (115_200, StopBits::Two), (921_600, StopBits::One), (4_000_000, StopBits::Two)]
    {
        let p = open_port(&path, baud, DataBits::Eight, Parity::None, stop).unwrap();
        assert_eq!(p.baud_rate().unwrap(), baud);
        assert_eq!(p.stop_bits().unwrap(), stop);
        assert_eq!(p.data_bits().unwrap(), DataBits::Eight);
    }
    let e = open_port("/dev/does-not-exist", 9600, DataBits::Eight, Parity::None, StopBits::One).unwrap_err();
    assert!(e.to_string().contains("/dev/does-not-exist"), "{e}");
}

/// Writes heartbeats until the receiver has seen one, so later writes are not
/// raced against the receiver opening the device.
async fn handshake(w: &mut TTYPort, c: &hilcam_core::link::InputCounters) {
    let hb = encode_frame(&Message::Heartbeat { seq: 0, t_ns: 0, status: 0 });
    let ok = wait_for_with(|| {
        let _ = w.write_all(&hb);
        get(&c.heartbeats) > 0
    })
    .await;
    assert!(ok, "receiver never saw a heartbeat");
}

async fn wait_for_with(mut f: impl FnMut() -> bool) -> bool {
    for _ in 0..3000 {
        if f() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    false
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn partial_writes_garbage_and_bad_poses_at_4_mbaud() {
    let (mut master, slave) = pty_pair();
    let (tx, mut rx) = mpsc::channel(4096);
    let c = counters();
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let task = tokio::spawn(run_serial(SerialConfig::new(pty_name(&slave), 4_000_000), tx, c.clone(), stop_rx));
    handshake(&mut master, &c).await;

    // 200 valid poses; between them garbage without the sync byte (so every
    // garbage byte is counted exactly), a corrupted frame, a NaN pose, and a
    // pose going back in time. Written in odd-sized chunks.
    let mut bytes = Vec::new();
    let mut garbage = 0u64;
    for i in 0..200u32 {
        bytes.extend(encode_frame(&Message::Pose(pose(i, 1_000 + i as u64))));
        if i % 10 == 3 {
            let g: Vec<u8> = (0..(i % 17 + 1)).map(|k| (k * 7 % 0xA0) as u8).collect();
            garbage += g.len() as u64;
            bytes.extend(g);
        }
        if i == 50 {
            let mut bad = encode_frame(&Message::Pose(pose(9999, 1_000 + i as u64)));
            bad[30] ^= 0x40; // CRC failure; resync skips exactly this frame
            garbage += bad.len() as u64;
            bytes.extend(bad);
            let mut nan = pose(9998, 1_000 + i as u64);
            nan.position.x = f64::NAN;
            bytes.extend(encode_frame(&Message::Pose(nan)));
            bytes.extend(encode_frame(&Message::Pose(pose(9997, 10))));
        }
    }
    bytes.extend(encode_frame(&Message::Trigger { seq: 1, t_ns: 5 }));
    let chunks: Vec<Vec<u8>> = bytes.chunks(37).map(|c| c.to_vec()).collect();
    let writer = write_all_slowly(master.try_clone_native().unwrap(), chunks, Duration::from_micros(200));
    let mut ev = Vec::new();
    let done = collect_until(&mut rx, &mut ev, |e| {
        e.iter().any(|x| matches!(x, hilcam_core::link::InputEvent::Trigger { .. }))
    })
    .await;
    writer.join().unwrap();
    assert!(done, "trigger never arrived; counters:\n{}", c.to_prometheus());
    let got = poses(&ev);
    assert_eq!(got.len(), 200, "{}", c.to_prometheus());
    for (i, p) in got.iter().enumerate() {
        assert_eq!(*p, pose(i as u32, 1_000 + i as u64));
    }
    assert_eq!(get(&c.accepted), 200);
    assert_eq!(c.rejected(Rejection::NonFinite), 1);
    assert_eq!(c.rejected(Rejection::TimeBackwards), 1);
    assert_eq!(get(&c.crc_failures), 1);
    // The corrupted frame may contain 0xA5 bytes: each is one resync.
    assert_eq!(get(&c.discarded_bytes), garbage, "{}", c.to_prometheus());
    stop_tx.send(()).unwrap();
    task.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unplug_and_replug_without_restart() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("ttyBENCH");
    let (mut master, slave) = pty_pair();
    std::os::unix::fs::symlink(pty_name(&slave), &link).unwrap();
    let (tx, mut rx) = mpsc::channel(4096);
    let c = counters();
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let cfg = SerialConfig::new(link.to_str().unwrap(), 115_200);
    let task = tokio::spawn(run_serial(cfg, tx, c.clone(), stop_rx));
    handshake(&mut master, &c).await;
    for i in 0..10 {
        master.write_all(&encode_frame(&Message::Pose(pose(i, 100 + i as u64)))).unwrap();
    }
    let mut ev = Vec::new();
    assert!(collect_until(&mut rx, &mut ev, |e| poses(e).len() == 10).await);

    // Unplug: the device node disappears and the other end closes.
    std::fs::remove_file(&link).unwrap();
    drop(master);
    drop(slave);
    assert!(wait_for(|| get(&c.device_errors) >= 2).await, "{}", c.to_prometheus());

    // Replug: a new device appears at the same path.
    let (mut master, slave) = pty_pair();
    std::os::unix::fs::symlink(pty_name(&slave), &link).unwrap();
    assert!(wait_for(|| get(&c.reconnects) == 1).await, "{}", c.to_prometheus());
    let hb_before = get(&c.heartbeats);
    let hb = encode_frame(&Message::Heartbeat { seq: 1, t_ns: 0, status: 0 });
    assert!(
        wait_for_with(|| {
            let _ = master.write_all(&hb);
            get(&c.heartbeats) > hb_before
        })
        .await
    );
    for i in 10..20 {
        master.write_all(&encode_frame(&Message::Pose(pose(i, 100 + i as u64)))).unwrap();
    }
    assert!(collect_until(&mut rx, &mut ev, |e| poses(e).len() == 20).await, "{}", c.to_prometheus());
    assert_eq!(poses(&ev)[19], pose(19, 119));
    stop_tx.send(()).unwrap();
    task.await.unwrap();
    drop(slave);
}

async fn receive_trajectory_from(
    sender: impl FnOnce(&str) -> std::process::Child,
    n: usize,
) -> (Vec<Pose>, std::process::Output) {
    receive_trajectory_with(PoseLimits::default(), sender, n).await
}

/// [`receive_trajectory_from`] through a gate with `limits`.
async fn receive_trajectory_with(
    limits: PoseLimits,
    sender: impl FnOnce(&str) -> std::process::Child,
    n: usize,
) -> (Vec<Pose>, std::process::Output) {
    let cable = NullModem::new();
    let (tx, mut rx) = mpsc::channel(8192);
    let c = counters();
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let cfg = SerialConfig { limits, ..SerialConfig::new(cable.b.clone(), 115_200) };
    let task = tokio::spawn(run_serial(cfg, tx, c.clone(), stop_rx));
    // Let the receiver open its end before the sender starts writing.
    assert!(wait_for(|| std::fs::metadata(&cable.b).is_ok()).await);
    tokio::time::sleep(Duration::from_millis(300)).await;
    let child = sender(&cable.a);
    let mut ev = Vec::new();
    collect_until(&mut rx, &mut ev, |e| poses(e).len() >= n).await;
    let out = child.wait_with_output().unwrap();
    stop_tx.send(()).unwrap();
    task.await.unwrap();
    assert_eq!(c.rejected_total(), 0, "{}", c.to_prometheus());
    (poses(&ev), out)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pyserial_example_sends_the_trajectory() {
    let Some(py) = python() else { return };
    let traj = root().join("scenes/trajectories/approach.csv");
    let want = Trajectory::load(&traj).unwrap();
    let n = 40;
    let (got, out) = receive_trajectory_from(
        |port| {
            std::process::Command::new(&py)
                .arg(root().join("examples/send_serial.py"))
                .args(["--port", port, "--count", &n.to_string(), "--speed", "inf", "--trajectory"])
                .arg(&traj)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        },
        n,
    )
    .await;
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(got.len(), n);
    for (k, p) in got.iter().enumerate() {
        // Bit-exact: the Python encoder (own CRC-32C) and the Rust decoder agree.
        let mut w = want[k].to_pose(k as u32);
        w.attitude = w.attitude.normalize();
        w.sun_dir = w.sun_dir.normalize();
        assert_eq!(p.position, w.position);
        assert_eq!(p.t_ns, w.t_ns);
        assert_eq!(p.seq, k as u32);
        assert!((p.attitude - w.attitude).length() < 1e-15);
    }
    // The example's --hex output equals the Rust encoder's bytes for sample 0.
    let hex = std::process::Command::new(&py)
        .arg(root().join("examples/send_serial.py"))
        .args(["--hex", "--count", "1", "--trajectory"])
        .arg(&traj)
        .output()
        .unwrap();
    let rust: String = encode_frame(&Message::Pose(want[0].to_pose(0))).iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(String::from_utf8_lossy(&hex.stdout).trim(), rust);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hilcam_send_serial_replays_at_fixed_rate() {
    let traj = root().join("scenes/trajectories/flyaround.csv");
    let want = Trajectory::load(&traj).unwrap();
    // --rate equal to twice the sample rate: each sample is held for two sends.
    let dt = want[1].time_s - want[0].time_s;
    let rate = 2.0 / dt;
    let n = 30;
    let (got, out) = receive_trajectory_from(
        |port| {
            std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
                .args(["send", "--serial", port, "--speed", "inf", "--rate", &rate.to_string(), "--trajectory"])
                .arg(&traj)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        },
        2 * want.len() - 1,
    )
    .await;
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(got.len(), 2 * want.len() - 1);
    for (k, p) in got.iter().take(n).enumerate() {
        assert_eq!(p.seq, k as u32);
        assert_eq!(p.position, want[k / 2].position, "send {k} holds sample {}", k / 2);
    }
}

/// SIGINT, SIGTERM and SIGHUP stop `hilcam send` alike (src/cli/signal.rs): after the
/// message in hand, with what was sent printed and exit status 0. (Serve's and replay's
/// signals: tests/serve/hardening.rs.)
#[test]
fn hilcam_send_stops_cleanly_on_sigint_sigterm_and_sighup() {
    use std::io::Read;
    let traj = root().join("scenes/trajectories/flyaround.csv");
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        let (mut master, slave) = TTYPort::pair().unwrap();
        let port = slave.name().unwrap();
        // At its own pace: 600 s of poses, so only the signal ends it.
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
            .args(["send", "--serial", &port, "--trajectory"])
            .arg(&traj)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // A first pose on the wire: the handlers are in place (installed before it).
        master.set_timeout(PATIENCE).unwrap();
        let mut buf = [0u8; 256];
        assert!(master.read(&mut buf).unwrap() > 0, "no pose from hilcam send");
        // SAFETY: kill(2) on our own child's pid.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, sig) }, 0);
        let t0 = std::time::Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed() > PATIENCE {
                let _ = child.kill();
                panic!("signal {sig}: hilcam send did not stop");
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let (mut stdout, mut stderr) = (String::new(), String::new());
        child.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
        child.stderr.take().unwrap().read_to_string(&mut stderr).unwrap();
        assert_eq!(status.code(), Some(0), "signal {sig}: {status}\n{stdout}\n{stderr}");
        assert!(stdout.starts_with("sent ") && stdout.contains(" poses in "), "signal {sig}: {stdout}");
        drop(slave);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hilcam_send_serial_puts_the_planet_on_the_wire_as_the_python_encoder_does() {
    let dir = tempfile::tempdir().unwrap();
    let traj = dir.path().join("moon.csv");
    std::fs::write(
        &traj,
        "time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,ply,plz\n\
         0,0,0,40,1,0,0,0,0,0,-1,-1.25e7,3.5e6,3.844e8\n\
         0.5,0,0,39.5,1,0,0,0,0,0,-1,-1.2500001e7,3.4999e6,3.8440001e8\n",
    )
    .unwrap();
    let want = Trajectory::load(&traj).unwrap();
    let limits = PoseLimits { planet_radius_m: Some(1.7374e6), ..PoseLimits::default() };
    let (got, out) = receive_trajectory_with(
        limits,
        |port| {
            std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
                .args(["send", "--serial", port, "--speed", "inf", "--trajectory"])
                .arg(&traj)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        },
        2,
    )
    .await;
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let centres: Vec<_> = got.iter().map(|p| p.planet_centre).collect();
    assert_eq!(centres, want.iter().map(|s| s.planet_centre).collect::<Vec<_>>());
    assert!(centres.iter().all(Option::is_some));
    // The Python encoder (examples/hilcam_proto.py, its own CRC-32C) writes the same bytes.
    let Some(py) = python() else { return };
    let hex = std::process::Command::new(&py)
        .arg(root().join("examples/send_serial.py"))
        .args(["--hex", "--trajectory"])
        .arg(&traj)
        .output()
        .unwrap();
    let rust: Vec<String> = want
        .iter()
        .enumerate()
        .map(|(k, s)| encode_frame(&Message::Pose(s.to_pose(k as u32))).iter().map(|b| format!("{b:02x}")).collect())
        .collect();
    assert_eq!(String::from_utf8_lossy(&hex.stdout).lines().collect::<Vec<_>>(), rust);
}
