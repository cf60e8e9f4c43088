//! Pending acknowledges: an exposure write is applied by the renderer when it starts
//! its next frame, so a client that accepts PENDING_ACK (GVCP configuration bit 1) gets
//! one at once and the final acknowledge, with the same id, when a frame integrating the
//! new exposure reaches the device. Checked with raw GVCP datagrams and through Aravis,
//! which extends its acknowledge timeout on a PENDING_ACK instead of resending.

use crate::gige::{RawClient, Rig, run};
use hilcam_core::sink::gige::GigeConfig;
use hilcam_core::sink::gige::gvcp::{self, FLAG_ACK_REQUIRED, code};
use hilcam_core::sink::gige::registers as reg;
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

pub(crate) fn writereg(addr: u32, v: u32, id: u16) -> Vec<u8> {
    let mut p = addr.to_be_bytes().to_vec();
    p.extend_from_slice(&v.to_be_bytes());
    gvcp::encode_command(FLAG_ACK_REQUIRED, code::WRITEREG_CMD, id, &p)
}

pub(crate) fn rig_config(ip: Ipv4Addr, pending_timeout_ms: u32) -> GigeConfig {
    GigeConfig { address: ip, pending_timeout_ms, ..GigeConfig::default() }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn exposure_write_gets_a_pending_ack_then_the_final_ack_with_the_same_id() {
    let ip = Ipv4Addr::new(127, 0, 0, 31);
    // 4 frames in the pipeline at 10 Hz: the new exposure shows ~0.3–0.4 s after the write.
    let rig = Rig::start_with(rig_config(ip, 3000), 128, 128, Some(4)).await;
    let addr = rig.device.gvcp_addr();
    let waited = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        c.sock.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        assert_ne!(c.read(reg::GVCP_CAPABILITY).1 & reg::capability::PENDING_ACK, 0, "capability offered");
        assert_eq!(c.read(reg::PENDING_TIMEOUT), (0, 3000));
        // Pending acknowledges not enabled: the write is acknowledged as soon as it is stored.
        let ack = c.cmd(
            code::WRITEREG_CMD,
            &[&reg::EXPOSURE_TIME.to_be_bytes()[..], &300f32.to_bits().to_be_bytes()].concat(),
        );
        assert_eq!((ack.answer, ack.status), (code::WRITEREG_ACK, 0));

        assert_eq!(c.write(reg::GVCP_CONFIG, reg::GVCP_CONFIG_PENDING_ACK_ENABLE), 0);
        assert_eq!(c.read(reg::GVCP_CONFIG), (0, reg::GVCP_CONFIG_PENDING_ACK_ENABLE));
        c.send_raw(&writereg(reg::EXPOSURE_TIME, 250f32.to_bits(), 0x0404));
        let sent = Instant::now();
        let pending = c.recv().expect("PENDING_ACK");
        assert_eq!((pending.answer, pending.status, pending.ack_id), (code::PENDING_ACK, 0, 0x0404));
        assert_eq!(pending.payload, 3000u32.to_be_bytes(), "time to completion, ms");
        let fin = c.recv().expect("final acknowledge");
        let waited = sent.elapsed();
        assert_eq!((fin.answer, fin.status, fin.ack_id), (code::WRITEREG_ACK, 0, 0x0404));
        assert_eq!(fin.payload, [0, 0, 0, 1], "one register written");

        // Not slow (applied to the next frame the device sends): a plain acknowledge.
        let mono8 = hilcam_core::sink::gige::GevPixelFormat::Mono8.pfnc();
        let ack = c.cmd(code::WRITEREG_CMD, &[&reg::PIXEL_FORMAT.to_be_bytes()[..], &mono8.to_be_bytes()].concat());
        assert_eq!((ack.answer, ack.status), (code::WRITEREG_ACK, 0));
        waited
    })
    .await
    .unwrap();
    assert!(
        waited >= Duration::from_millis(200) && waited < Duration::from_millis(2700),
        "final acknowledge {waited:?} after the write: the frames in flight first, within the pending timeout"
    );
    assert_eq!(rig.counter("hilcam_gige_pending_acks_total", &[]), 1);
    assert_eq!(rig.counter("hilcam_gige_pending_timeouts_total", &[]), 0, "a frame showed the exposure");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pending_write_no_frame_shows_is_acknowledged_at_the_pending_timeout() {
    let ip = Ipv4Addr::new(127, 0, 0, 32);
    // A pipeline far deeper than the 300 ms pending timeout.
    let rig = Rig::start_with(rig_config(ip, 300), 128, 128, Some(1000)).await;
    let addr = rig.device.gvcp_addr();
    let waited = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        assert_eq!(c.write(reg::GVCP_CONFIG, reg::GVCP_CONFIG_PENDING_ACK_ENABLE), 0);
        c.send_raw(&writereg(reg::EXPOSURE_TIME, 250f32.to_bits(), 9));
        let sent = Instant::now();
        let pending = c.recv().expect("PENDING_ACK");
        assert_eq!((pending.answer, pending.ack_id), (code::PENDING_ACK, 9));
        assert_eq!(pending.payload, 300u32.to_be_bytes());
        let fin = c.recv().expect("final acknowledge");
        assert_eq!((fin.answer, fin.status, fin.ack_id), (code::WRITEREG_ACK, 0, 9));
        sent.elapsed()
    })
    .await
    .unwrap();
    assert!(waited < Duration::from_millis(300), "within the announced time: {waited:?}");
    assert!(waited >= Duration::from_millis(250), "waited for a frame until the timeout: {waited:?}");
    assert_eq!(rig.counter("hilcam_gige_pending_timeouts_total", &[]), 1);
    assert_eq!(rig.device.settings().borrow().exposure_us, 250.0, "the value is stored all the same");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn aravis_waits_through_a_pending_ack_longer_than_its_ack_timeout() {
    let ip = Ipv4Addr::new(127, 0, 0, 33);
    // 8 frames in flight at 10 Hz: ~0.8 s, longer than Aravis' 500 ms acknowledge timeout.
    let rig = Rig::start_with(rig_config(ip, 3000), 320, 240, Some(8)).await;
    let started = Instant::now();
    let args = ["-a", &ip.to_string(), "control", "GevGVCPPendingAck=1", "ExposureTime=250"].map(String::from);
    let (ok, out) = run("arv-tool-0.8", args.to_vec()).await;
    let took = started.elapsed();
    assert!(ok, "{out}");
    assert!(out.contains("ExposureTime = 250"), "{out}");
    assert!(took >= Duration::from_millis(600), "the write waited for its frame: {took:?}\n{out}");
    assert_eq!(
        rig.counter("hilcam_gige_pending_acks_total", &[]),
        1,
        "Aravis waited for the final acknowledge instead of resending the write"
    );
    assert_eq!(rig.counter("hilcam_gige_pending_timeouts_total", &[]), 0);
    assert_eq!(rig.device.settings().borrow().exposure_us, 250.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn through_serve_the_final_ack_follows_the_first_frame_rendered_with_the_new_exposure() {
    use crate::serve_common;
    use hilcam_core::link::InputEvent;
    use hilcam_core::serve::config::{InputConfig, TriggerConfig};
    let ip = Ipv4Addr::new(127, 0, 0, 38);
    let dir = tempfile::tempdir().unwrap();
    let sensor = serve_common::detector_sensor(16, 1.0, "");
    let scene = serve_common::sphere_scene_with(dir.path(), 48, 1, &sensor);
    let mut cfg = serve_common::config(scene, InputConfig::default(), TriggerConfig::default(), Default::default());
    cfg.output.gige = Some(rig_config(ip, 5000));
    let (tx, rx) = tokio::sync::mpsc::channel(64);
    let server = serve_common::start(cfg, Some(rx)).await;
    let mut reader = serve_common::Reader::connect(server.info.stream).await;
    // Poses every 40 ms: the serve loop renders one frame per pose.
    let poses = tokio::spawn(async move {
        for seq in 1u32.. {
            let pose = serve_common::pose(seq, glam::DVec3::new(0.0, 0.0, 10.0), glam::DVec3::NEG_Z);
            if tx.send(InputEvent::Pose { pose, arrival: Instant::now() }).await.is_err() || seq > 150 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(40)).await;
        }
    });
    let (frames_tx, mut frames_rx) = tokio::sync::mpsc::unbounded_channel();
    let collect = tokio::spawn(async move {
        loop {
            let f = reader.next().await;
            if frames_tx.send((f.meta.integration_s, f.meta.emit_unix_ns)).is_err() {
                break;
            }
        }
    });
    tokio::time::sleep(Duration::from_millis(300)).await;
    let addr = std::net::SocketAddr::from((ip, gvcp::GVCP_PORT));
    let (waited, acked_unix_ns) = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        c.sock.set_read_timeout(Some(Duration::from_secs(8))).unwrap();
        assert_eq!(c.write(reg::GVCP_CONFIG, reg::GVCP_CONFIG_PENDING_ACK_ENABLE), 0);
        c.send_raw(&writereg(reg::EXPOSURE_TIME, 5f32.to_bits(), 0x0777));
        let sent = Instant::now();
        let pending = c.recv().expect("PENDING_ACK");
        assert_eq!((pending.answer, pending.ack_id), (code::PENDING_ACK, 0x0777));
        let fin = c.recv().expect("final acknowledge");
        let acked = hilcam_core::frame::unix_ns_now();
        assert_eq!((fin.answer, fin.status, fin.ack_id), (code::WRITEREG_ACK, 0, 0x0777));
        (sent.elapsed(), acked)
    })
    .await
    .unwrap();
    assert!(waited < Duration::from_millis(4500), "acknowledged by a frame, not at the timeout: {waited:?}");
    tokio::time::sleep(Duration::from_millis(300)).await;
    poses.abort();
    collect.abort();
    let mut frames = Vec::new();
    while let Ok(f) = frames_rx.try_recv() {
        frames.push(f);
    }
    let first_new =
        frames.iter().position(|&(t, _)| t == 5e-6).unwrap_or_else(|| panic!("no frame at 5 µs: {frames:?}"));
    assert!(first_new > 0 && frames[..first_new].iter().all(|&(t, _)| t == 2e-5), "{frames:?}");
    assert!(
        frames[first_new].1 <= acked_unix_ns,
        "the first frame with the new exposure was emitted before the final acknowledge arrived"
    );
    server.finish().await;
}
