//! hilcam as a GigE Vision camera, checked through a real third-party client (Aravis:
//! `arv-tool-0.8`, `arv-camera-test-0.8` and its Python bindings) and through raw GVCP
//! datagrams for what a client library hides (privilege, heartbeat, malformed
//! commands, resends, packet pacing).
//!
//! Aravis only speaks GVCP on port 3956, so each test binds its own loopback address
//! (127.0.0.21 …) on that port. Aravis must be installed (`scripts/setup-aravis.sh`);
//! the tests that need it fail, loudly, when it is not.

use crate::serve_common;
use hilcam_core::frame::{EncodedFrame, Frame, FrameFlags, FrameMeta, PixelFormat};
use hilcam_core::metrics::Registry;
use hilcam_core::render::film::Pixels;
use hilcam_core::render::integrator::Spp;
use hilcam_core::sink::gige::gvcp::{self, FLAG_ACK_REQUIRED, code};
use hilcam_core::sink::gige::registers as reg;
use hilcam_core::sink::gige::{CameraDescription, GevPixelFormat, GigeConfig, GigeDevice, gvsp};
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::{Duration, Instant};

const RATE_HZ: f64 = 10.0;

/// Held by the tests that stream 1024² frames over loopback and require zero missing
/// packets: run together (one of them renders on every core) they starve each other's
/// receivers, and the kernel drops packets.
pub(crate) static LOOPBACK_STREAM: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

pub(crate) fn camera(w: u32, h: u32) -> CameraDescription {
    CameraDescription {
        sensor_width: w,
        sensor_height: h,
        adc_bits: 12,
        exposure_us: 1000.0,
        exposure_min_us: 10.0,
        exposure_max_us: 100_000.0,
        auto_exposure: true,
        frame_rate_hz: RATE_HZ as f32,
        frame_rate_max_hz: reg::FRAME_RATE_MAX,
        truth: Default::default(),
        truth_materials_len: 0,
        rate_sets_schedule: false,
    }
}

/// Pose time of pose `seq` in the synthetic source: 50 ms steps from an odd start.
fn pose_t_ns(pose_seq: u32) -> u64 {
    1_000_000_007 + u64::from(pose_seq) * 50_000_000
}

/// Where the synthetic source draws its 8×8 square for pose `seq` (sensor pixels).
fn square_centre(pose_seq: u32, w: u32, h: u32) -> (f64, f64) {
    let x = 48 + (pose_seq * 7) % (w - 96);
    let y = 56 + (pose_seq * 3) % (h - 112);
    (f64::from(x) + 3.5, f64::from(y) + 3.5)
}

/// Image `k` of the synthetic source: a 12-bit frame with a bright square at
/// [`square_centre`] of pose 1000 + k; odd images are flagged EXTRAPOLATED.
pub(crate) fn synthetic_frame(k: u64, w: u32, h: u32) -> EncodedFrame {
    let pose_seq = 1000 + k as u32;
    let (cx, cy) = square_centre(pose_seq, w, h);
    let (x0, y0) = ((cx - 3.5) as u32, (cy - 3.5) as u32);
    let mut data = vec![40u16; (w * h) as usize];
    for y in y0..y0 + 8 {
        for x in x0..x0 + 8 {
            data[(y * w + x) as usize] = 4000;
        }
    }
    let meta = FrameMeta {
        frame_seq: k,
        pose_seq,
        pose_t_ns: pose_t_ns(pose_seq),
        pose_arrival_unix_ns: 0,
        emit_unix_ns: 0,
        width: w,
        height: h,
        format: PixelFormat::Mono16,
        bit_depth: 12,
        spp: Spp::from_milli(2000),
        depth: 2,
        integration_s: 0.001,
        line_time_ns: 0,
        flags: FrameFlags(if k % 2 == 1 { FrameFlags::EXTRAPOLATED } else { 0 }),
    };
    Frame::new(meta, Pixels::Mono16 { data, bits: 12 }).unwrap().encode()
}

/// A device fed by a frame source at RATE_HZ cycling through 8 synthetic images.
pub(crate) struct Rig {
    pub(crate) device: Arc<GigeDevice>,
    registry: Arc<Registry>,
    stop: Arc<AtomicBool>,
    producer: Option<std::thread::JoinHandle<()>>,
}

impl Rig {
    pub(crate) async fn start(ip: Ipv4Addr, w: u32, h: u32) -> Rig {
        Rig::start_with(GigeConfig { address: ip, ..GigeConfig::default() }, w, h, None).await
    }

    /// With `exposure_lag: Some(n)` the source follows the client's exposure like the
    /// serve loop's renderer, `n` frames late (the frames already in the pipeline):
    /// frame k integrates the exposure set when frame k − n started.
    pub(crate) async fn start_with(cfg: GigeConfig, w: u32, h: u32, exposure_lag: Option<usize>) -> Rig {
        let registry = Registry::new();
        let device = Arc::new(GigeDevice::start(&cfg, camera(w, h), registry.clone()).await.expect("device starts"));
        let exposure = exposure_lag.map(|n| (n, hilcam_core::sink::gige::request::follow_requests(&device)));
        let stop = Arc::new(AtomicBool::new(false));
        let (d, s) = (device.clone(), stop.clone());
        let producer = std::thread::spawn(move || {
            let images: Vec<EncodedFrame> = (0..8).map(|k| synthetic_frame(k, w, h)).collect();
            let mut in_flight = std::collections::VecDeque::new();
            let mut seq = 0u64;
            while !s.load(Ordering::Acquire) {
                let mut f = images[(seq % 8) as usize].clone();
                f.meta.frame_seq = seq;
                f.meta.pose_arrival_unix_ns = hilcam_core::frame::unix_ns_now();
                if let Some((lag, rx)) = &exposure {
                    in_flight.push_back(rx.borrow().integration_s);
                    if in_flight.len() > *lag
                        && let Some(Some(t)) = in_flight.pop_front()
                    {
                        f.meta.integration_s = t as f32;
                    }
                }
                d.publish(&Arc::new(f));
                seq += 1;
                std::thread::sleep(Duration::from_secs_f64(1.0 / RATE_HZ));
            }
        });
        Rig { device, registry, stop, producer: Some(producer) }
    }

    pub(crate) fn counter(&self, name: &str, labels: &[(&str, &str)]) -> u64 {
        self.registry.counter(name, "", labels).get()
    }

    /// Stop the frame source, then the device: how long the device's shutdown took.
    pub(crate) async fn shutdown(self) -> Duration {
        let device = self.device.clone();
        drop(self);
        let device = Arc::try_unwrap(device).ok().expect("only the test holds the device");
        let t = Instant::now();
        device.shutdown().await;
        t.elapsed()
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(p) = self.producer.take() {
            let _ = p.join();
        }
    }
}

pub(crate) fn require_tool(tool: &str) {
    let ok = Command::new("sh").arg("-c").arg(format!("command -v {tool}")).output().is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "{tool} not found: install Aravis with scripts/setup-aravis.sh (Debian: aravis-tools-cli, aravis-tools)"
    );
}

pub(crate) async fn run(cmd: &'static str, args: Vec<String>) -> (bool, String) {
    require_tool(cmd);
    tokio::task::spawn_blocking(move || {
        let out = Command::new(cmd).args(&args).output().unwrap_or_else(|e| panic!("{cmd}: {e}"));
        let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        (out.status.success(), text)
    })
    .await
    .unwrap()
}

pub(crate) async fn python_client(ip: Ipv4Addr, frames: u32, extra: &[&str]) -> serde_json::Value {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/gige_client/aravis_client.py");
    let mut args = vec![script.to_string(), ip.to_string(), frames.to_string()];
    args.extend(extra.iter().map(|s| s.to_string()));
    let (ok, out) = run("/usr/bin/python3", args).await;
    assert!(ok, "Aravis Python client failed (scripts/setup-aravis.sh installs gir1.2-aravis-0.8):\n{out}");
    let line = out.lines().rev().find(|l| l.starts_with('{')).unwrap_or_else(|| panic!("no JSON in:\n{out}"));
    serde_json::from_str(line).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn arv_tool_lists_the_device_and_reads_and_writes_features() {
    let ip = Ipv4Addr::new(127, 0, 0, 21);
    let rig = Rig::start(ip, 320, 240).await;
    let (ok, features) = run("arv-tool-0.8", vec!["-a".into(), ip.to_string(), "features".into()]).await;
    assert!(ok, "{features}");
    for f in ["Width", "SensorWidth", "PixelFormat", "TriggerSoftware", "ExposureTime", "GevTimestampTickFrequency"] {
        assert!(features.contains(f), "{f} not listed:\n{features}");
    }
    let (ok, xml) = run("arv-tool-0.8", vec!["-a".into(), ip.to_string(), "genicam".into()]).await;
    assert!(ok && xml.contains("<Port Name=\"HilcamChunkPort\">"), "XML not served:\n{xml}");

    let args = |kv: &[&str]| {
        let mut v = vec!["-a".to_string(), ip.to_string(), "control".to_string()];
        v.extend(kv.iter().map(|s| s.to_string()));
        v
    };
    let (ok, out) =
        run("arv-tool-0.8", args(&["Width=160", "Height=100", "PixelFormat=Mono8", "ExposureTime=250"])).await;
    assert!(ok, "{out}");
    assert!(out.contains("Width = 160") && out.contains("Height = 100"), "{out}");
    let s = *rig.device.settings().borrow();
    assert_eq!((s.width, s.height, s.pixel_format), (160, 100, GevPixelFormat::Mono8));
    assert_eq!(s.exposure_us, 250.0);
    assert!(!s.exposure_auto, "writing ExposureTime turns auto-exposure off");

    // Out of range: the device answers INVALID_PARAMETER and keeps its value.
    let refused = rig.counter("hilcam_gige_commands_rejected_total", &[("reason", "refused")]);
    let (_, out) = run("arv-tool-0.8", args(&["Width=100000"])).await;
    assert_eq!(rig.device.settings().borrow().width, 160, "{out}");
    assert!(rig.counter("hilcam_gige_commands_rejected_total", &[("reason", "refused")]) > refused, "{out}");
    let (_, out) = run("arv-tool-0.8", args(&["Width"])).await;
    assert!(out.contains("Width = 160"), "{out}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn arv_camera_test_streams_1024_mono16_with_no_missing_packets() {
    let _alone = LOOPBACK_STREAM.lock().await;
    let ip = Ipv4Addr::new(127, 0, 0, 22);
    let rig = Rig::start(ip, 1024, 1024).await;
    // 20 µs between 1500-byte packets (75 MB/s, below a GigE link's 125 MB/s): a
    // loopback burst of 1433 packets would overflow the receiver's socket buffer.
    let args = ["-n", &ip.to_string(), "--no-packet-socket", "-a", "--duration=4", "--gv-packet-delay=20000"]
        .map(String::from)
        .to_vec();
    let (ok, out) = run("arv-camera-test-0.8", args).await;
    assert!(ok, "{out}");
    let stat = |name: &str| -> u64 {
        let line = out.lines().find(|l| l.trim_start().starts_with(name)).unwrap_or_else(|| panic!("{name}?\n{out}"));
        line.split('=').nth(1).unwrap().trim().parse().unwrap()
    };
    let completed = stat("n_completed_buffers");
    assert!(completed >= 25, "{completed} frames in 4 s at {RATE_HZ} Hz:\n{out}");
    assert_eq!(stat("n_missing_packets"), 0, "{out}");
    assert_eq!(stat("n_failures"), 0, "{out}");
    assert_eq!(stat("n_size_mismatch_errors"), 0, "{out}");
    assert!(rig.counter("hilcam_gige_frames_sent_total", &[]) >= completed);
    assert!(out.contains("gv packet delay        = 20000 ns"), "{out}");
    let s = *rig.device.settings().borrow();
    assert_eq!((s.width, s.height, s.pixel_format), (1024, 1024, GevPixelFormat::Mono16));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn aravis_client_gets_roi_mono8_and_the_pose_of_each_frame() {
    let ip = Ipv4Addr::new(127, 0, 0, 23);
    let (w, h) = (320, 240);
    let _rig = Rig::start(ip, w, h).await;
    let v = python_client(ip, 6, &["Width=256", "Height=200", "OffsetX=32", "OffsetY=20", "PixelFormat=Mono8"]).await;
    let f = &v["features"];
    assert_eq!((f["Width"].as_u64(), f["Height"].as_u64()), (Some(256), Some(200)));
    assert_eq!(f["PayloadSize"].as_u64(), Some(256 * 200 + hilcam_core::sink::gige::chunk::CHUNK_OVERHEAD as u64));
    assert_eq!(f["TickFrequency"].as_u64(), Some(1_000_000_000));
    for b in v["buffers"].as_array().unwrap() {
        assert_eq!(b["status"], "success", "{v}");
        assert_eq!((b["width"].as_u64(), b["height"].as_u64()), (Some(256), Some(200)));
        assert_eq!(b["pixel_format"].as_u64(), Some(u64::from(GevPixelFormat::Mono8.pfnc())));
        let m = &b["meta"];
        let pose_seq = m["pose_seq"].as_u64().expect("metadata chunk") as u32;
        assert_eq!(m["pose_t_ns"].as_u64(), Some(pose_t_ns(pose_seq)), "chunk pose time belongs to its pose");
        assert_eq!(b["timestamp"].as_u64(), Some(pose_t_ns(pose_seq)), "leader timestamp is the pose time");
        assert_eq!(m["bit_depth"].as_u64(), Some(12));
        let extrapolated = m["flags"].as_u64().unwrap() & u64::from(FrameFlags::EXTRAPOLATED) != 0;
        assert_eq!(extrapolated, pose_seq % 2 == 1, "flags travel with the frame");
        // Mono8 from the 12-bit DN: 4000 >> 4.
        assert_eq!(b["max"].as_u64(), Some(4000 >> 4));
        let (cx, cy) = square_centre(pose_seq, w, h);
        let c = b["centroid"].as_array().unwrap();
        let (gx, gy) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
        assert!((gx - (cx - 32.0)).abs() < 0.01 && (gy - (cy - 20.0)).abs() < 0.01, "centroid {gx},{gy} vs {cx},{cy}");
    }
    assert_eq!(v["n_missing_packets"].as_u64(), Some(0));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn software_trigger_sends_one_frame_per_trigger() {
    let ip = Ipv4Addr::new(127, 0, 0, 24);
    let rig = Rig::start(ip, 320, 240).await;
    let fired = Arc::new(AtomicU32::new(0));
    let f = fired.clone();
    rig.device.on_software_trigger(Box::new(move || {
        f.fetch_add(1, Ordering::AcqRel);
    }));
    let v = python_client(ip, 3, &["--trigger"]).await;
    assert_eq!(v["untriggered_buffer"], false, "no frame without a trigger: {v}");
    let bufs = v["buffers"].as_array().unwrap();
    assert_eq!(bufs.len(), 3);
    assert!(bufs.iter().all(|b| b["status"] == "success"), "{v}");
    assert_eq!(fired.load(Ordering::Acquire), 3, "each TriggerSoftware reaches the renderer's hook");
    assert!(rig.counter("hilcam_gige_frames_dropped_total", &[("reason", "no_trigger")]) > 0);
}

/// A raw GVCP client (what Aravis does under the hood, without its retries).
pub(crate) struct RawClient {
    pub(crate) sock: UdpSocket,
    device: SocketAddr,
    id: u16,
}

impl RawClient {
    pub(crate) fn new(device: SocketAddr) -> Self {
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        sock.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        RawClient { sock, device, id: 0 }
    }

    pub(crate) fn send_raw(&self, bytes: &[u8]) {
        self.sock.send_to(bytes, self.device).unwrap();
    }

    pub(crate) fn recv(&self) -> Option<gvcp::Ack> {
        let mut buf = [0u8; 1024];
        let n = self.sock.recv(&mut buf).ok()?;
        gvcp::decode_ack(&buf[..n])
    }

    pub(crate) fn cmd(&mut self, code: u16, payload: &[u8]) -> gvcp::Ack {
        self.id = self.id.wrapping_add(1).max(1);
        self.send_raw(&gvcp::encode_command(FLAG_ACK_REQUIRED, code, self.id, payload));
        let ack = self.recv().expect("acknowledge");
        assert_eq!(ack.ack_id, self.id);
        ack
    }

    pub(crate) fn write(&mut self, addr: u32, v: u32) -> u16 {
        let mut p = addr.to_be_bytes().to_vec();
        p.extend_from_slice(&v.to_be_bytes());
        self.cmd(code::WRITEREG_CMD, &p).status
    }

    pub(crate) fn read(&mut self, addr: u32) -> (u16, u32) {
        let a = self.cmd(code::READREG_CMD, &addr.to_be_bytes());
        (a.status, a.payload.get(..4).map(|b| u32::from_be_bytes(b.try_into().unwrap())).unwrap_or(0))
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn control_privilege_is_exclusive_and_lost_without_heartbeat() {
    let ip = Ipv4Addr::new(127, 0, 0, 25);
    let rig = Rig::start(ip, 128, 128).await;
    let addr = rig.device.gvcp_addr();
    tokio::task::spawn_blocking(move || {
        let (mut a, mut b) = (RawClient::new(addr), RawClient::new(addr));
        assert_eq!(a.write(reg::CCP, reg::CCP_CONTROL), 0);
        assert_eq!(a.write(reg::HEARTBEAT_TIMEOUT, 500), 0);
        assert_eq!(b.write(reg::CCP, reg::CCP_CONTROL), 0x8006, "a second client cannot take control");
        assert_eq!(b.write(reg::WIDTH, 32), 0x8006, "nor write while another holds control");
        assert_eq!(b.read(reg::WIDTH), (0, 128), "but it may read");
        assert_eq!(a.write(reg::ACQUISITION_START, 1), 0);
        // A keeps control while it talks …
        for _ in 0..4 {
            std::thread::sleep(Duration::from_millis(200));
            assert_eq!(a.read(reg::CCP), (0, reg::CCP_CONTROL));
        }
        // … and loses it after 500 ms of silence.
        std::thread::sleep(Duration::from_millis(900));
        assert_eq!(b.read(reg::ACQUISITION_STATUS), (0, 0), "acquisition stopped with the controller");
        assert_eq!(b.write(reg::CCP, reg::CCP_CONTROL), 0, "control is free again");
        assert_eq!(a.write(reg::WIDTH, 32), 0x8006);
    })
    .await
    .unwrap();
    assert_eq!(rig.counter("hilcam_gige_heartbeat_expired_total", &[]), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_gvcp_is_counted_and_answered_with_an_error_status() {
    let ip = Ipv4Addr::new(127, 0, 0, 26);
    let rig = Rig::start(ip, 128, 128).await;
    let addr = rig.device.gvcp_addr();
    tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        c.send_raw(b"\x42\x01\x00");
        c.send_raw(b"not a gvcp packet at all");
        // Unknown command, odd READREG payload, payload shorter than the header says.
        c.send_raw(&gvcp::encode_command(FLAG_ACK_REQUIRED, 0x00c0, 77, &[]));
        assert_eq!(c.recv().map(|a| (a.status, a.ack_id)), Some((0x8001, 77)));
        c.send_raw(&gvcp::encode_command(FLAG_ACK_REQUIRED, code::READREG_CMD, 78, &[0, 0, 1]));
        assert_eq!(c.recv().map(|a| (a.status, a.ack_id)), Some((0x8002, 78)));
        c.send_raw(&[0x42, 1, 0, 0x80, 0, 8, 0, 79, 0, 0, 0, 4]);
        assert_eq!(c.recv().map(|a| (a.status, a.ack_id)), Some((0x800E, 79)));
        // Well formed, but the address does not exist / is misaligned.
        assert_eq!(c.read(0x0005_0000).0, 0x8003);
        assert_eq!(c.read(0x0002_0001).0, 0x8005);
        // The device still answers normally.
        assert_eq!(c.read(reg::SENSOR_WIDTH), (0, 128));
    })
    .await
    .unwrap();
    assert_eq!(rig.counter("hilcam_gige_commands_rejected_total", &[("reason", "malformed")]), 5);
    assert_eq!(rig.counter("hilcam_gige_commands_rejected_total", &[("reason", "refused")]), 2);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resend_requests_are_answered_and_packet_delay_is_honoured() {
    let ip = Ipv4Addr::new(127, 0, 0, 27);
    let (w, h) = (256, 128);
    let rig = Rig::start(ip, w, h).await;
    let addr = rig.device.gvcp_addr();
    tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        assert_eq!(c.write(reg::CCP, reg::CCP_CONTROL), 0);
        assert_eq!(c.write(reg::SCDA0, u32::from(Ipv4Addr::LOCALHOST)), 0);
        assert_eq!(c.write(reg::SCP0, u32::from(rx.local_addr().unwrap().port())), 0);
        assert_eq!(c.write(reg::SCPS0, 576), 0);
        assert_eq!(c.write(reg::SCPD0, 300_000), 0); // 0.3 ms between packets
        assert_eq!(c.write(reg::ACQUISITION_START, 1), 0);
        // One whole block, leader to trailer, with arrival times.
        let mut buf = vec![0u8; 2048];
        let mut block: Vec<(u32, Vec<u8>, Instant)> = Vec::new();
        loop {
            let n = rx.recv(&mut buf).expect("GVSP packet");
            let hd = gvsp::parse_header(&buf[..n]).unwrap();
            if hd.content == gvsp::CONTENT_LEADER {
                block.clear();
            }
            block.push((hd.packet_id, buf[..n].to_vec(), Instant::now()));
            if hd.content == gvsp::CONTENT_TRAILER && block[0].0 == 0 {
                break;
            }
        }
        assert_eq!(c.write(reg::ACQUISITION_STOP, 1), 0);
        let n_packets = block.len() as u32;
        let bytes = (w * h * 2) as usize + hilcam_core::sink::gige::chunk::CHUNK_OVERHEAD;
        assert_eq!(n_packets, bytes.div_ceil(540) as u32 + 2);
        let span = block.last().unwrap().2 - block[0].2;
        let floor = Duration::from_micros(300) * (n_packets - 1);
        assert!(span >= floor.mul_f64(0.9), "{n_packets} packets in {span:?}, the delay asks for ≥ {floor:?}");
        // Drain what is in flight, then ask for packets 2..=4 again.
        rx.set_read_timeout(Some(Duration::from_millis(300))).unwrap();
        while rx.recv(&mut buf).is_ok() {}
        let block_id = gvsp::parse_header(&block[0].1).unwrap().block_id;
        let resend = |first: u32, last: u32, id: u16| {
            let mut p = u32::from(id).to_be_bytes().to_vec();
            p.extend_from_slice(&first.to_be_bytes());
            p.extend_from_slice(&last.to_be_bytes());
            gvcp::encode_command(0, code::PACKETRESEND_CMD, 99, &p)
        };
        c.send_raw(&resend(2, 4, block_id));
        for pid in 2..=4u32 {
            let n = rx.recv(&mut buf).expect("resent packet");
            let hd = gvsp::parse_header(&buf[..n]).unwrap();
            assert_eq!((hd.status, hd.block_id, hd.packet_id), (gvsp::STATUS_RESEND, block_id, pid));
            assert_eq!(&buf[8..n], &block[pid as usize].1[8..], "resent bytes are the original bytes");
        }
        // A block that is not in the ring is answered with PACKET_UNAVAILABLE.
        c.send_raw(&resend(1, 1, block_id.wrapping_add(500)));
        let n = rx.recv(&mut buf).expect("unavailable answer");
        assert_eq!(gvsp::parse_header(&buf[..n]).unwrap().status, gvsp::STATUS_PACKET_UNAVAILABLE);
    })
    .await
    .unwrap();
    assert_eq!(rig.counter("hilcam_gige_packets_resent_total", &[]), 3);
    assert_eq!(rig.counter("hilcam_gige_resend_unavailable_total", &[]), 1);
}

/// A 96×96 camera (f = 200 px) looking at a unit sphere, with a 12-bit ADC: the
/// sensor's DN is what the GigE stream carries.
pub(crate) fn dn_sphere_scene(dir: &std::path::Path) -> std::path::PathBuf {
    serve_common::sphere_scene_with(
        dir,
        96,
        16,
        "[sensor]\noutput = \"dn\"\nradiance_scale = 5.0\n[sensor.adc]\nbits = 12\n",
    )
}

/// A pose `seq` (1 ms apart from t = 5 s) with the target at `p`, lit from the camera's side.
pub(crate) fn lit_pose(seq: u32, p: glam::DVec3) -> hilcam_core::pose::Pose {
    hilcam_core::pose::Pose {
        seq,
        t_ns: 5_000_000_000 + u64::from(seq) * 1_000_000,
        position: p,
        sun_dir: (-p).normalize(),
        ..hilcam_core::pose::Pose::ahead(10.0)
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serve_renders_the_pose_sent_over_a_pty_and_aravis_sees_it_where_the_pinhole_puts_it() {
    use glam::DVec3;
    use hilcam_core::link::send::{MessageWriter, SerialWriter};
    use hilcam_core::pose::Message;
    use hilcam_core::serve::config::ServeConfig;
    use serialport::SerialPort;

    let ip = Ipv4Addr::new(127, 0, 0, 28);
    let dir = tempfile::tempdir().unwrap();
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let text = format!(
        "scene = {:?}\n[input]\nkind = \"serial\"\ndevice = {:?}\nbaud = 921600\n[trigger]\nmode = \"external\"\n\
         [stream]\nlisten = \"127.0.0.1:0\"\n[metrics]\nprint_interval_s = 60.0\n[output.gige]\naddress = \"{ip}\"\n",
        dn_sphere_scene(dir.path()),
        slave.name().unwrap()
    );
    let cfg: ServeConfig = toml::from_str(&text).unwrap();
    cfg.validate().unwrap();
    let server = crate::serve_common::start(cfg, None).await;
    tokio::time::sleep(Duration::from_millis(200)).await;

    let mut writer = SerialWriter::new(master, "test pty");
    let pose = lit_pose;
    for (seq, p) in [(1u32, DVec3::new(0.8, -0.5, 10.0)), (2, DVec3::new(-1.0, 0.6, 12.0))] {
        writer.send(&Message::Pose(pose(seq, p))).unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
        // Trigger mode: TriggerSoftware → the serve loop renders from the latest pose.
        let v = python_client(ip, 1, &["--trigger"]).await;
        assert_eq!(v["untriggered_buffer"], false, "{v}");
        let b = &v["buffers"][0];
        assert_eq!(b["status"], "success", "{v}");
        assert_eq!(b["pixel_format"].as_u64(), Some(u64::from(GevPixelFormat::Mono16.pfnc())));
        let m = &b["meta"];
        assert_eq!(m["pose_seq"].as_u64(), Some(u64::from(seq)), "the frame of the pose just sent: {v}");
        assert_eq!(m["pose_t_ns"].as_u64(), Some(pose(seq, p).t_ns));
        assert_eq!(b["timestamp"].as_u64(), Some(pose(seq, p).t_ns), "leader timestamp = pose time");
        assert_eq!(m["bit_depth"].as_u64(), Some(12));
        // Pinhole: f = 2 mm / 10 µm = 200 px; centre (48 + f·x/z, 48 + f·y/z) in pixel-edge
        // coordinates; the client's centroid counts pixel indices (centres at +0.5).
        let (px, py) = (48.0 + 200.0 * p.x / p.z - 0.5, 48.0 + 200.0 * p.y / p.z - 0.5);
        let c = b["centroid"].as_array().unwrap();
        let (cx, cy) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
        assert!(
            (cx - px).abs() <= 1.0 && (cy - py).abs() <= 1.0,
            "centroid ({cx:.2}, {cy:.2}) vs pinhole ({px:.2}, {py:.2})"
        );
    }
    let report = server.finish().await;
    assert_eq!(report.scheduler.triggers, 2, "one render per software trigger");
    drop(slave);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn aravis_reads_the_xml_from_a_zip_in_device_memory() {
    let ip = Ipv4Addr::new(127, 0, 0, 29);
    let cfg = GigeConfig { address: ip, zip_xml: true, ..GigeConfig::default() };
    let device = GigeDevice::start(&cfg, camera(320, 240), Registry::new()).await.expect("device starts");
    let (ok, out) =
        run("arv-tool-0.8", vec!["-a".into(), ip.to_string(), "control".into(), "SensorWidth".into()]).await;
    assert!(ok && out.contains("SensorWidth = 320"), "{out}");
    let (ok, xml) = run("arv-tool-0.8", vec!["-a".into(), ip.to_string(), "genicam".into()]).await;
    assert!(ok && xml.contains("<Port Name=\"HilcamChunkPort\">"), "{xml}");
    device.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_clients_exposure_time_is_the_integration_time_of_the_next_frames() {
    use hilcam_core::link::InputEvent;
    use hilcam_core::serve::config::{InputConfig, TriggerConfig};
    let ip = Ipv4Addr::new(127, 0, 0, 30);
    let dir = tempfile::tempdir().unwrap();
    let sensor = serve_common::detector_sensor(16, 1.0, "");
    let scene = serve_common::sphere_scene_with(dir.path(), 48, 1, &sensor);
    let mut cfg = serve_common::config(scene, InputConfig::default(), TriggerConfig::default(), Default::default());
    cfg.output.gige = Some(GigeConfig { address: ip, ..GigeConfig::default() });
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let server = serve_common::start(cfg, Some(rx)).await;
    let mut reader = serve_common::Reader::subscribed(&server.info).await;
    let frame_at = |seq: u32| {
        let tx = tx.clone();
        async move {
            let pose = serve_common::pose(seq, glam::DVec3::new(0.0, 0.0, 10.0), glam::DVec3::NEG_Z);
            tx.send(InputEvent::Pose { pose, arrival: std::time::Instant::now() }).await.unwrap();
        }
    };
    let dn_sum = |f: &Frame| match &f.pixels {
        Pixels::Mono16 { data, .. } => data.iter().map(|&v| f64::from(v)).sum::<f64>(),
        other => panic!("expected DN, got {:?}", other.format()),
    };
    frame_at(1).await;
    let f1 = reader.next().await;
    assert_eq!(f1.meta.integration_s, 2e-5, "before any write: the configured time");
    // A client writes ExposureTime (µs); the next frame integrates that long.
    let (ok, out) =
        run("arv-tool-0.8", vec!["-a".into(), ip.to_string(), "control".into(), "ExposureTime=5".into()]).await;
    assert!(ok, "{out}");
    tokio::time::sleep(Duration::from_millis(100)).await;
    frame_at(2).await;
    let f2 = reader.next().await;
    assert_eq!(f2.meta.pose_seq, 2);
    assert_eq!(f2.meta.integration_s, 5e-6, "the client's exposure");
    let ratio = dn_sum(&f2) / dn_sum(&f1);
    assert!((ratio - 0.25).abs() < 0.01, "signal scales with the exposure: ratio {ratio}");
    server.finish().await;
}
