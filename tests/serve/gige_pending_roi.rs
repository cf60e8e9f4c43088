//! Pending acknowledges for ROI writes: Width / Height / OffsetX / OffsetY are rendered
//! from the next frame the renderer starts, so a client that accepts PENDING_ACK gets
//! one at once and the final acknowledge (same id) once a published frame was rendered
//! for the region the write left — each write of a sequence waits for its own region.

use crate::gige::{RawClient, Rig};
use crate::gige_pending::{rig_config, writereg};
use crate::gige_rate::metric;
use crate::serve_common;
use hilcam_core::frame::unix_ns_now;
use hilcam_core::link::InputEvent;
use hilcam_core::render::film::Pixels;
use hilcam_core::serve::config::{InputConfig, TriggerConfig};
use hilcam_core::sink::gige::gvcp::{self, code};
use hilcam_core::sink::gige::registers as reg;
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

/// A frame off the TCP stream: width, emit time (ns since the epoch), DN.
type Seen = (u32, u64, Vec<u16>);

/// Which of the two 32-wide regions (OffsetX 0 or 16) a 32-wide frame shows: the one
/// whose pixels of the whole-sensor frame `full` (48 wide) it is closer to.
fn offset_of(roi: &[u16], full: &[u16]) -> u32 {
    let distance = |x0: usize| -> u64 {
        (0..48)
            .flat_map(|y| (0..32).map(move |x| (y, x)))
            .map(|(y, x)| u64::from(roi[y * 32 + x].abs_diff(full[y * 48 + x0 + x])))
            .sum()
    };
    if distance(0) <= distance(16) { 0 } else { 16 }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn through_serve_each_roi_write_is_acknowledged_after_a_frame_rendered_for_its_region() {
    let ip = Ipv4Addr::new(127, 0, 0, 52);
    let dir = tempfile::tempdir().unwrap();
    let sensor = serve_common::detector_sensor(16, 1.0, "");
    let scene = serve_common::sphere_scene_with(dir.path(), 48, 1, &sensor);
    let mut cfg = serve_common::config(scene, InputConfig::default(), TriggerConfig::default(), Default::default());
    cfg.output.gige = Some(rig_config(ip, 5000));
    cfg.metrics.listen = Some("127.0.0.1:0".parse().unwrap());
    let (tx, rx) = tokio::sync::mpsc::channel(64);
    let server = serve_common::start(cfg, Some(rx)).await;
    let metrics = server.info.metrics.expect("metrics endpoint");
    let mut reader = serve_common::Reader::connect(server.info.stream).await;
    // The same pose every 40 ms: one frame per pose, identical but for the region.
    let poses = tokio::spawn(async move {
        for seq in 1u32..400 {
            let pose = serve_common::pose(seq, glam::DVec3::new(0.3, 0.0, 10.0), glam::DVec3::NEG_Z);
            if tx.send(InputEvent::Pose { pose, arrival: Instant::now() }).await.is_err() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(40)).await;
        }
    });
    let (frames_tx, mut frames_rx) = tokio::sync::mpsc::unbounded_channel::<Seen>();
    let collect = tokio::spawn(async move {
        loop {
            let f = reader.next().await;
            let Pixels::Mono16 { data, .. } = f.pixels else { panic!("expected DN frames") };
            if frames_tx.send((f.meta.width, f.meta.emit_unix_ns, data)).is_err() {
                break;
            }
        }
    });
    tokio::time::sleep(Duration::from_millis(300)).await;
    let addr = std::net::SocketAddr::from((ip, gvcp::GVCP_PORT));
    // Width 32, then OffsetX 16, back to 0, Width 48 (the whole sensor): (register, value,
    // the region after the write as (OffsetX, Width)).
    let writes = [
        (reg::WIDTH, 32, (0, 32)),
        (reg::OFFSET_X, 16, (16, 32)),
        (reg::OFFSET_X, 0, (0, 32)),
        (reg::WIDTH, 48, (0, 48)),
    ];
    let acks = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        c.sock.set_read_timeout(Some(Duration::from_secs(8))).unwrap();
        assert_eq!(c.write(reg::GVCP_CONFIG, reg::GVCP_CONFIG_PENDING_ACK_ENABLE), 0);
        let mut acks = Vec::new();
        for (k, &(register, value, region)) in writes.iter().enumerate() {
            let id = 0x0500 + k as u16;
            let sent = Instant::now();
            let sent_ns = unix_ns_now();
            c.send_raw(&writereg(register, value, id));
            let pending = c.recv().expect("PENDING_ACK");
            assert_eq!((pending.answer, pending.ack_id), (code::PENDING_ACK, id), "write {k}");
            let fin = c.recv().expect("final acknowledge");
            let acked_ns = unix_ns_now();
            assert_eq!((fin.answer, fin.status, fin.ack_id), (code::WRITEREG_ACK, 0, id), "write {k}");
            assert!(sent.elapsed() < Duration::from_millis(4500), "write {k} acknowledged at the timeout");
            acks.push((region, sent_ns, acked_ns));
        }
        acks
    })
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    // Scraped while poses still come (the server stops when its inputs close).
    let pending_acks = metric(metrics, "hilcam_gige_pending_acks_total").await;
    let timeouts = metric(metrics, "hilcam_gige_pending_timeouts_total").await;
    poses.abort();
    collect.abort();
    let mut frames = Vec::new();
    while let Ok(f) = frames_rx.try_recv() {
        frames.push(f);
    }
    let full = frames.iter().find(|f| f.0 == 48).expect("a whole-sensor frame first").2.clone();
    // Each frame's region as (OffsetX, Width).
    let region = |f: &Seen| if f.0 == 48 { (0, 48) } else { (offset_of(&f.2, &full), f.0) };
    let regions: Vec<(u32, u32)> = frames.iter().map(region).collect();
    for (k, &(wanted, sent_ns, acked_ns)) in acks.iter().enumerate() {
        let shown = frames
            .iter()
            .position(|f| f.1 > sent_ns && region(f) == wanted)
            .unwrap_or_else(|| panic!("write {k}: no frame shows {wanted:?} after it: {regions:?}"));
        assert!(
            frames[shown].1 <= acked_ns,
            "write {k}: final acknowledge before the first frame for {wanted:?} was emitted ({regions:?})"
        );
    }
    assert_eq!(regions.last(), Some(&(0, 48)), "the whole sensor again: {regions:?}");
    assert!(regions.contains(&(16, 32)), "{regions:?}");
    assert_eq!(pending_acks, 4);
    assert_eq!(timeouts, 0, "every region was shown");
    server.finish().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_roi_write_no_frame_shows_is_acknowledged_at_the_pending_timeout() {
    let ip = Ipv4Addr::new(127, 0, 0, 53);
    // The rig's frames follow the exposure, never the region: no frame shows the ROI.
    let rig = Rig::start_with(rig_config(ip, 300), 128, 128, Some(1)).await;
    let addr = rig.device.gvcp_addr();
    let waited = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        // Without pending acknowledges: acknowledged as soon as stored.
        assert_eq!(c.write(reg::WIDTH, 96), 0);
        assert_eq!(c.write(reg::GVCP_CONFIG, reg::GVCP_CONFIG_PENDING_ACK_ENABLE), 0);
        c.send_raw(&writereg(reg::WIDTH, 64, 7));
        let sent = Instant::now();
        let pending = c.recv().expect("PENDING_ACK");
        assert_eq!((pending.answer, pending.ack_id), (code::PENDING_ACK, 7));
        let fin = c.recv().expect("final acknowledge");
        assert_eq!((fin.answer, fin.status, fin.ack_id), (code::WRITEREG_ACK, 0, 7));
        sent.elapsed()
    })
    .await
    .unwrap();
    assert!(waited >= Duration::from_millis(250) && waited < Duration::from_millis(300), "{waited:?}");
    assert_eq!(rig.counter("hilcam_gige_pending_acks_total", &[]), 1, "only the write with pending acknowledges on");
    assert_eq!(rig.counter("hilcam_gige_pending_timeouts_total", &[]), 1);
    assert_eq!(rig.device.settings().borrow().width, 64, "the value is stored all the same");
}
