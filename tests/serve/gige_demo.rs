//! `hilcam demo --gige`: the demo loop also serves a GigE Vision camera; Aravis streams
//! from the address it announces.

use crate::gige::run;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

/// The demo process, killed if the test fails before it stops it.
struct Demo(Child);

impl Drop for Demo {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demo_gige_streams_to_arv_camera_test_with_no_missing_packets() {
    let _alone = crate::gige::LOOPBACK_STREAM.lock().await;
    let out = tempfile::tempdir().unwrap();
    let ip = "127.0.0.36";
    let mut child = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["demo", "--gige", "--gige-address", ip, "--frames", "2", "--duration", "180", "--out"])
        .arg(out.path())
        .env("HILCAM_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let demo = Demo(child);
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    // The announcement: the camera's address, then the commands to watch it.
    let mut seen = Vec::new();
    let announced = loop {
        let line = lines.recv_timeout(Duration::from_secs(90)).unwrap_or_else(|_| panic!("no announcement: {seen:?}"));
        if let Some(rest) = line.strip_prefix("demo: GigE Vision camera on ") {
            break rest.split_whitespace().next().unwrap().to_string();
        }
        seen.push(line);
    };
    assert_eq!(announced, format!("{ip}:3956"));
    let watch: Vec<String> = (0..2).map(|_| lines.recv_timeout(Duration::from_secs(5)).unwrap()).collect();
    assert!(watch.iter().any(|l| l.contains(&format!("arv-tool-0.8 -a {ip}"))), "{watch:?}");
    let camera_test = watch.iter().find(|l| l.contains("arv-camera-test-0.8")).expect("arv-camera-test command");
    // Run the command as printed, bounded to 8 s.
    let mut args: Vec<String> = camera_test.split_whitespace().skip(1).map(String::from).collect();
    assert!(args.contains(&ip.to_string()), "{camera_test}");
    args.push("--duration=8".into());
    let (ok, text) = run("arv-camera-test-0.8", args).await;
    assert!(ok, "{text}");
    let stat = |name: &str| -> u64 {
        let line = text.lines().find(|l| l.trim_start().starts_with(name)).unwrap_or_else(|| panic!("{name}?\n{text}"));
        line.split('=').nth(1).unwrap().trim().parse().unwrap()
    };
    // 2 Hz for 8 s, minus start-up: a handful of 1024² Mono16 frames, none incomplete.
    assert!(stat("n_completed_buffers") >= 4, "{text}");
    assert_eq!(stat("n_missing_packets"), 0, "{text}");
    assert_eq!(stat("n_failures"), 0, "{text}");
    assert_eq!(stat("n_size_mismatch_errors"), 0, "{text}");

    // Ctrl-C is the normal end of a --gige demo.
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(demo.0.id() as libc::pid_t, libc::SIGINT) }, 0);
    let mut demo = demo;
    let status = tokio::task::spawn_blocking(move || {
        let t0 = std::time::Instant::now();
        loop {
            if let Some(s) = demo.0.try_wait().unwrap() {
                return s;
            }
            assert!(t0.elapsed() < Duration::from_secs(60), "demo did not stop on SIGINT");
            std::thread::sleep(Duration::from_millis(50));
        }
    })
    .await
    .unwrap();
    let rest: Vec<String> = lines.try_iter().collect();
    assert!(status.success(), "{status:?}: {rest:?}");
    assert!(rest.iter().any(|l| l.contains("SIGINT, stopping")), "{rest:?}");
    assert!(rest.iter().any(|l| l.starts_with("client: 2 frames")), "the TCP client got its frames too: {rest:?}");
}
