//! Issue 37: a GVCP/GVSP fuzz and flood against `hilcam serve` (the binary, as a lab
//! runs it), in a private network namespace (`netns.rs`): random and adversarial
//! datagrams, hostile register values (a stream destination off the machine, broadcast,
//! a 4.3 s packet delay, control taken, the heartbeat disabled …) and a resend flood,
//! from three addresses, while a controller streams at 10 Hz. It checks that the
//! controller keeps its frame rate, the server's memory stays bounded, every rejection
//! is counted in /metrics (exactly, in a slow batch), the log stays short, and SIGINT
//! and SIGTERM end `serve` within a second.

use crate::gige::RawClient;
use crate::netns;
use crate::serve_common;
use hilcam_core::sink::gige::gvcp::{self, FLAG_ACK_REQUIRED, code};
use hilcam_core::sink::gige::gvsp;
use hilcam_core::sink::gige::registers as reg;
use std::io::{Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpStream, UdpSocket};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Fixed ports: the namespace is the test's own.
const METRICS: &str = "127.0.0.1:9100";
const GVCP: SocketAddr = SocketAddr::V4(std::net::SocketAddrV4::new(Ipv4Addr::LOCALHOST, 3956));
const RATE_HZ: f64 = 10.0;
const FLOOD: Duration = Duration::from_secs(3);

/// `hilcam serve` on a 64² sphere with a 12-bit DN sensor, poses from the fly-around
/// trajectory, rendered at 10 Hz, GigE Vision on 127.0.0.1.
fn start_serve(dir: &std::path::Path) -> (Child, std::path::PathBuf) {
    let scene = serve_common::sphere_scene_with(dir, 64, 1, &serve_common::detector_sensor(12, 1.0, ""));
    let trajectory = std::fs::canonicalize("scenes/trajectories/flyaround.csv").unwrap();
    let cfg = dir.join("serve.toml");
    std::fs::write(
        &cfg,
        format!(
            "scene = {scene:?}\n[input]\nkind = \"trajectory\"\nfile = {trajectory:?}\n\
             [trigger]\nmode = \"rate\"\nrate_hz = {RATE_HZ}\n[stream]\nlisten = \"127.0.0.1:5600\"\n\
             [metrics]\nlisten = \"{METRICS}\"\nprint_interval_s = 60.0\n[output.gige]\naddress = \"127.0.0.1\"\n"
        ),
    )
    .unwrap();
    let log = dir.join("serve.log");
    let child = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .arg("serve")
        .arg("--config")
        .arg(&cfg)
        .env("HILCAM_LOG", "info")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .expect("hilcam serve starts");
    // Ready when /metrics answers (a bounded poll: the scene loads first).
    let until = Instant::now() + serve_common::PATIENCE;
    while metrics_text().is_none() {
        assert!(Instant::now() < until, "serve did not come up:\n{}", std::fs::read_to_string(&log).unwrap());
        std::thread::sleep(Duration::from_millis(50));
    }
    (child, log)
}

fn metrics_text() -> Option<String> {
    let mut s = TcpStream::connect(METRICS).ok()?;
    s.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").ok()?;
    let mut text = String::new();
    s.read_to_string(&mut text).ok()?;
    Some(text)
}

/// A counter's value in /metrics (`name{labels}` exactly as exported; 0 when absent).
fn metric(text: &str, series: &str) -> u64 {
    text.lines()
        .find_map(|l| l.strip_prefix(series).and_then(|r| r.strip_prefix(' ')))
        .map_or(0, |v| v.trim().parse::<f64>().unwrap() as u64)
}

/// Peak resident memory of `pid` (VmHWM), KiB.
fn peak_rss_kib(pid: u32) -> u64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = s.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// Send `sig` and wait for the process to exit: how long it took (None: not within 5 s).
fn stop_with(child: &mut Child, sig: i32) -> Option<Duration> {
    let t = Instant::now();
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0);
    while t.elapsed() < Duration::from_secs(5) {
        if child.try_wait().unwrap().is_some() {
            return Some(t.elapsed());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

fn writereg(a: u32, v: u32, id: u16) -> Vec<u8> {
    let mut p = a.to_be_bytes().to_vec();
    p.extend_from_slice(&v.to_be_bytes());
    gvcp::encode_command(FLAG_ACK_REQUIRED, code::WRITEREG_CMD, id, &p)
}

fn resend(block: u16, first: u32, last: u32) -> Vec<u8> {
    let mut p = u32::from(block).to_be_bytes().to_vec();
    p.extend_from_slice(&first.to_be_bytes());
    p.extend_from_slice(&last.to_be_bytes());
    gvcp::encode_command(0, code::PACKETRESEND_CMD, 1, &p)
}

/// Hostile commands from a client that is not the controller: each is refused.
fn adversarial(k: u32) -> Vec<u8> {
    let id = (k % 0xFFFE + 1) as u16;
    match k % 12 {
        0 => writereg(reg::SCPD0, 0xFFFF_FFFF, id),
        1 => writereg(reg::SCDA0, u32::from(Ipv4Addr::new(192, 0, 2, 99)), id), // off the machine
        2 => writereg(reg::SCDA0, u32::from(Ipv4Addr::BROADCAST), id),
        3 => writereg(reg::SCP0, 9, id),
        4 => writereg(reg::CCP, reg::CCP_EXCLUSIVE, id),
        5 => writereg(reg::GVCP_CONFIG, reg::GVCP_CONFIG_HEARTBEAT_DISABLE, id),
        6 => writereg(reg::ACQUISITION_STOP, 1, id),
        7 => writereg(reg::WIDTH, 0, id),
        8 => resend(1, 0, 0x00FF_FFFF),
        9 => gvcp::encode_command(FLAG_ACK_REQUIRED, 0x4242, id, &[]),
        10 => writereg(reg::TRIGGER_SOFTWARE, 1, id),
        _ => gvcp::encode_command(FLAG_ACK_REQUIRED, code::READMEM_CMD, id, &[0, 1, 0, 0, 0, 0, 0, 6]), // count 6
    }
}

/// xorshift64*: random bytes without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn datagram(&mut self) -> Vec<u8> {
        let n = (self.next() % 600) as usize;
        let mut d: Vec<u8> = (0..n).map(|_| self.next() as u8).collect();
        // Half of them look like commands: the key byte and a plausible code.
        if n >= 8 && self.next().is_multiple_of(2) {
            d[0] = gvcp::KEY;
            let codes =
                [code::READREG_CMD, code::WRITEREG_CMD, code::READMEM_CMD, code::WRITEMEM_CMD, code::PACKETRESEND_CMD];
            d[2..4].copy_from_slice(&codes[(self.next() % 5) as usize].to_be_bytes());
        }
        d
    }
}

/// Counts complete blocks (trailers) arriving on `rx` and when.
fn receive_blocks(
    rx: UdpSocket,
    stop: Arc<AtomicBool>,
    arrivals: Arc<Mutex<Vec<Instant>>>,
    last_block: Arc<AtomicU64>,
) {
    rx.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    let mut buf = vec![0u8; 9000];
    while !stop.load(Ordering::Acquire) {
        if let Ok(n) = rx.recv(&mut buf)
            && let Some(h) = gvsp::parse_header(&buf[..n])
            && h.content == gvsp::CONTENT_TRAILER
            && h.status == gvsp::STATUS_SUCCESS
        {
            arrivals.lock().unwrap().push(Instant::now());
            last_block.store(u64::from(h.block_id), Ordering::Release);
        }
    }
}

fn frames_between(arrivals: &Mutex<Vec<Instant>>, from: Instant, to: Instant) -> usize {
    arrivals.lock().unwrap().iter().filter(|t| **t >= from && **t < to).count()
}

#[test]
fn gvcp_gvsp_fuzz_and_flood_leave_the_controllers_frames_memory_and_shutdown_intact() {
    if !netns::enter("gige_flood::gvcp_gvsp_fuzz_and_flood_leave_the_controllers_frames_memory_and_shutdown_intact") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mut serve, log) = start_serve(dir.path());
    let pid = serve.id();

    // The controller: control, the stream to rx, acquisition; a heartbeat every 300 ms.
    let mut c = RawClient::new(GVCP);
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    assert_eq!(c.write(reg::CCP, reg::CCP_CONTROL), 0);
    assert_eq!(c.write(reg::SCDA0, u32::from(Ipv4Addr::LOCALHOST)), 0);
    assert_eq!(c.write(reg::SCP0, u32::from(rx.local_addr().unwrap().port())), 0);
    assert_eq!(c.write(reg::ACQUISITION_START, 1), 0);
    let (stop_rx, arrivals, last_block) =
        (Arc::new(AtomicBool::new(false)), Arc::new(Mutex::new(Vec::new())), Arc::new(AtomicU64::new(1)));
    let receiver = {
        let (s, a, b) = (stop_rx.clone(), arrivals.clone(), last_block.clone());
        std::thread::spawn(move || receive_blocks(rx, s, a, b))
    };
    let heartbeat = |c: &mut RawClient, for_: Duration| {
        let end = Instant::now() + for_;
        while Instant::now() < end {
            assert_eq!(c.read(reg::CCP), (0, reg::CCP_CONTROL), "the controller keeps control");
            std::thread::sleep(Duration::from_millis(300));
        }
    };
    let t0 = Instant::now();
    heartbeat(&mut c, Duration::from_millis(1500));
    let baseline = frames_between(&arrivals, t0 + Duration::from_millis(500), Instant::now());
    let rss_before = peak_rss_kib(pid);

    // The flood: three senders on three addresses, ~10 000 datagrams/s each.
    let stop_flood = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(AtomicU64::new(0));
    let flooders: Vec<_> = (0..3u32)
        .map(|who| {
            let (stop, sent, last_block) = (stop_flood.clone(), sent.clone(), last_block.clone());
            std::thread::spawn(move || {
                let from = Ipv4Addr::new(127, 0, 0, if who == 2 { 1 } else { 2 + who as u8 });
                let s = UdpSocket::bind((from, 0)).unwrap();
                let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ u64::from(who + 1));
                let mut k = 0u32;
                while !stop.load(Ordering::Acquire) {
                    for _ in 0..20 {
                        let d = match who {
                            0 => rng.datagram(),
                            1 => adversarial(k),
                            // The destination's own address: whole-block resends of the newest block.
                            _ => resend(last_block.load(Ordering::Acquire) as u16, 0, 0x00FF_FFFF),
                        };
                        let _ = s.send_to(&d, GVCP);
                        k += 1;
                    }
                    sent.fetch_add(20, Ordering::Relaxed);
                    std::thread::sleep(Duration::from_millis(2));
                }
            })
        })
        .collect();
    let flood_start = Instant::now();
    heartbeat(&mut c, FLOOD);
    let flood_end = Instant::now();
    let during = frames_between(&arrivals, flood_start, flood_end);
    let rss_flood = peak_rss_kib(pid);
    let flood_sent = sent.load(Ordering::Relaxed);

    // SIGINT while the flood goes on: serve ends within a second.
    let sigint = stop_with(&mut serve, libc::SIGINT);
    stop_flood.store(true, Ordering::Release);
    for f in flooders {
        f.join().unwrap();
    }
    stop_rx.store(true, Ordering::Release);
    receiver.join().unwrap();
    let text = std::fs::read_to_string(&log).unwrap();
    let warn_lines = text.lines().filter(|l| l.contains("WARN") && l.contains("GVCP")).count();
    let expected = (FLOOD.as_secs_f64() * RATE_HZ) as usize;
    println!(
        "flood: {flood_sent} datagrams in {:?}; frames {during} during the flood ({expected} due at {RATE_HZ} Hz), \
         {baseline} in the 1 s before; peak RSS {rss_before} KiB before, {rss_flood} KiB after; SIGINT → exit in \
         {sigint:?}; {warn_lines} GVCP warning lines",
        flood_end - flood_start
    );
    assert!(sigint.is_some_and(|d| d < Duration::from_secs(1)), "SIGINT under flood: {sigint:?}\n{text}");
    assert!(during * 10 >= expected * 9, "{during} frames of {expected} during the flood");
    assert!(rss_flood <= rss_before + 32 * 1024, "peak RSS grew from {rss_before} to {rss_flood} KiB");
    assert!(warn_lines <= 20, "{warn_lines} warning lines for {flood_sent} datagrams:\n{text}");
}

/// Every rejection is counted, exactly: a slow batch of known hostile commands (no
/// socket drops) against a fresh `serve`, then SIGTERM ends it within a second.
#[test]
fn every_rejection_is_counted_and_sigterm_ends_serve_within_a_second() {
    if !netns::enter("gige_flood::every_rejection_is_counted_and_sigterm_ends_serve_within_a_second") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mut serve, log) = start_serve(dir.path());
    let mut controller = RawClient::new(GVCP);
    assert_eq!(controller.write(reg::CCP, reg::CCP_CONTROL), 0);
    let before = metrics_text().unwrap();
    let stranger_sock = UdpSocket::bind("127.0.0.2:0").unwrap();
    stranger_sock.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
    let n = 120u32;
    let mut buf = [0u8; 2048];
    for k in 0..n {
        let d = adversarial(k);
        stranger_sock.send_to(&d, GVCP).unwrap();
        // Wait for the answer of those that get one (PACKETRESEND gets none).
        if k % 12 != 8 {
            let got = stranger_sock.recv(&mut buf).expect("an error acknowledge");
            assert_ne!(gvcp::decode_ack(&buf[..got]).unwrap().status, 0, "{k}: accepted");
        } else {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    std::thread::sleep(Duration::from_millis(100));
    let after = metrics_text().unwrap();
    let delta = |series: &str| metric(&after, series) - metric(&before, series);
    let reasons = ["malformed", "refused", "access_denied", "resend_not_destination"];
    let counted: u64 =
        reasons.iter().map(|r| delta(&format!("hilcam_gige_commands_rejected_total{{reason=\"{r}\"}}"))).sum();
    println!(
        "rejections counted: {counted} of {n}: {:?}",
        reasons.map(|r| delta(&format!("hilcam_gige_commands_rejected_total{{reason=\"{r}\"}}")))
    );
    assert_eq!(counted, u64::from(n), "every hostile command counted once");
    assert_eq!(delta("hilcam_gige_commands_rejected_total{reason=\"resend_not_destination\"}"), u64::from(n / 12));
    assert_eq!(controller.read(reg::SCPD0), (0, 0), "no hostile value stored");
    assert_eq!(controller.read(reg::SCDA0), (0, 0));
    let sigterm = stop_with(&mut serve, libc::SIGTERM);
    println!("SIGTERM → exit in {sigterm:?}");
    assert!(
        sigterm.is_some_and(|d| d < Duration::from_secs(1)),
        "{sigterm:?}\n{}",
        std::fs::read_to_string(&log).unwrap()
    );
}
