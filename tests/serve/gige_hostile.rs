//! Issue 37: protocol faults a lab must survive, from raw GVCP datagrams on loopback
//! (only loopback destinations here; register values that could send traffic off the
//! machine are tried in `gige_flood.rs`, inside a private network namespace).

use crate::gige::{RawClient, Rig};
use hilcam_core::sink::gige::gvcp::{self, code};
use hilcam_core::sink::gige::gvsp;
use hilcam_core::sink::gige::registers as reg;
use hilcam_core::sink::gige::{GigeConfig, device::PENDING_MAX};
use std::net::{Ipv4Addr, UdpSocket};
use std::time::{Duration, Instant};

/// A controller on 127.0.0.1 that opened the stream to `rx` and started acquiring.
fn open_stream(c: &mut RawClient, rx: &UdpSocket, delay_ticks: u32) {
    assert_eq!(c.write(reg::CCP, reg::CCP_CONTROL), 0);
    assert_eq!(c.write(reg::SCDA0, u32::from(Ipv4Addr::LOCALHOST)), 0);
    assert_eq!(c.write(reg::SCP0, u32::from(rx.local_addr().unwrap().port())), 0);
    assert_eq!(c.write(reg::SCPS0, 1500), 0);
    assert_eq!(c.write(reg::SCPD0, delay_ticks), 0);
    assert_eq!(c.write(reg::ACQUISITION_START, 1), 0);
}

/// Wait for the next leader on `rx`: its block id.
fn next_leader(rx: &UdpSocket) -> u16 {
    let mut buf = vec![0u8; 2048];
    loop {
        let n = rx.recv(&mut buf).expect("GVSP packet");
        let h = gvsp::parse_header(&buf[..n]).unwrap();
        if h.content == gvsp::CONTENT_LEADER {
            return h.block_id;
        }
    }
}

/// Defect 1: SCPD = 0xFFFFFFFF stopped the stream for good and SIGINT then hung. The
/// delay is bounded (refused beyond 1 ms), and a block paced at the largest delay is
/// given up mid-way when the device stops: shutdown does not wait for the stream.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hostile_packet_delay_is_refused_and_shutdown_does_not_wait_for_the_stream() {
    let ip = Ipv4Addr::new(127, 0, 0, 61);
    // 512×512 Mono16: 352 packets of 1500 bytes, 0.35 s per block at 1 ms between packets.
    let rig = Rig::start(ip, 512, 512).await;
    let addr = rig.device.gvcp_addr();
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
    let rx = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        assert_eq!(c.write(reg::CCP, reg::CCP_CONTROL), 0);
        assert_eq!(c.write(reg::SCPD0, 0xFFFF_FFFF), 0x8002, "4.3 s per packet: refused");
        assert_eq!(c.read(reg::SCPD0), (0, 0), "and not stored");
        open_stream(&mut c, &rx, reg::SCPD_MAX_TICKS);
        // Mid-block: the leader went out, 351 packets are still to pace.
        next_leader(&rx);
        rx
    })
    .await
    .unwrap();
    let took = rig.shutdown().await;
    eprintln!("device shutdown with a block paced at SCPD = 1 ms in flight: {took:?}");
    assert!(took < Duration::from_millis(300), "shutdown took {took:?} with a block being paced");
    drop(rx);
}

/// Defect 2: PACKETRESEND was served for anyone, and queued without bound. A stranger's
/// request is refused and counted; a flood from the destination's own address is served
/// within the queue and the budget (one block of packets per frame sent), the rest
/// counted, and the controller's frames keep their rate.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resend_floods_are_refused_or_bounded_and_frames_keep_their_rate() {
    let ip = Ipv4Addr::new(127, 0, 0, 62);
    let (w, h) = (256, 128);
    let rig = Rig::start(ip, w, h).await;
    let addr = rig.device.gvcp_addr();
    let (frames, sent_in_flood) = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        open_stream(&mut c, &rx, 0);
        let block = next_leader(&rx);
        let resend = |first: u32, last: u32| {
            let mut p = u32::from(block).to_be_bytes().to_vec();
            p.extend_from_slice(&first.to_be_bytes());
            p.extend_from_slice(&last.to_be_bytes());
            gvcp::encode_command(0, code::PACKETRESEND_CMD, 1, &p)
        };
        // A stranger (another address) asks for the whole block 200 times.
        let stranger = UdpSocket::bind("127.0.0.2:0").unwrap();
        for _ in 0..200 {
            stranger.send_to(&resend(0, 1000), addr).unwrap();
        }
        // The destination's address (another port) floods for 1.5 s, 20 000 requests.
        let flooder = UdpSocket::bind("127.0.0.1:0").unwrap();
        let stop = Instant::now() + Duration::from_millis(1500);
        let mut sent = 0u32;
        let mut blocks = 0u32;
        let mut buf = vec![0u8; 2048];
        rx.set_read_timeout(Some(Duration::from_millis(1))).unwrap();
        while Instant::now() < stop {
            for _ in 0..40 {
                flooder.send_to(&resend(0, 1000), addr).unwrap();
                sent += 1;
            }
            while let Ok(n) = rx.recv(&mut buf) {
                let h = gvsp::parse_header(&buf[..n]).unwrap();
                blocks += u32::from(h.content == gvsp::CONTENT_TRAILER && h.status == gvsp::STATUS_SUCCESS);
            }
            std::thread::sleep(Duration::from_millis(3));
        }
        (blocks, sent)
    })
    .await
    .unwrap();
    let rejected = rig.counter("hilcam_gige_commands_rejected_total", &[("reason", "resend_not_destination")]);
    assert_eq!(rejected, 200, "every stranger's request refused and counted");
    let served = rig.counter("hilcam_gige_resend_requests_total", &[]);
    let queue_full = rig.counter("hilcam_gige_resend_dropped_total", &[("reason", "queue_full")]);
    let budget = rig.counter("hilcam_gige_resend_dropped_total", &[("reason", "budget")]);
    let resent = rig.counter("hilcam_gige_packets_resent_total", &[]);
    let sent_frames = rig.counter("hilcam_gige_frames_sent_total", &[]);
    let data = (w * h * 2) as usize + hilcam_core::sink::gige::chunk::CHUNK_OVERHEAD;
    let per_block = data.div_ceil(gvsp::data_per_packet(1500)) as u64 + 2;
    eprintln!(
        "resend flood: {sent_in_flood} requests, {served} accepted, {queue_full} queue-full, {budget} over budget, \
         {resent} packets resent ({per_block} per block), {sent_frames} frames sent, {frames} received in 1.5 s"
    );
    assert_eq!(served, u64::from(sent_in_flood), "the destination's requests are accepted…");
    assert!(queue_full + budget > 0 && resent <= (sent_frames + 1) * per_block, "…within the queue and the budget");
    // 10 Hz for 1.5 s: 15 frames, less scheduling slack.
    assert!(frames >= 12, "the controller got {frames} frames in 1.5 s of resend flood at 10 Hz");
}

/// Defect 3: pending acknowledgements grew without bound. At most PENDING_MAX slow
/// writes wait for a frame; the others are acknowledged at once, counted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pending_acknowledges_are_bounded() {
    let ip = Ipv4Addr::new(127, 0, 0, 63);
    // The source follows the client's exposure 1000 frames late: no write is ever shown.
    let cfg = GigeConfig { address: ip, pending_timeout_ms: 2000, ..GigeConfig::default() };
    let rig = Rig::start_with(cfg, 64, 48, Some(1000)).await;
    let addr = rig.device.gvcp_addr();
    let (pending, immediate) = tokio::task::spawn_blocking(move || {
        let mut c = RawClient::new(addr);
        assert_eq!(c.write(reg::GVCP_CONFIG, reg::GVCP_CONFIG_PENDING_ACK_ENABLE), 0);
        for k in 0..200u32 {
            let us = 20.0 + k as f32;
            let mut p = reg::EXPOSURE_TIME.to_be_bytes().to_vec();
            p.extend_from_slice(&us.to_bits().to_be_bytes());
            c.send_raw(&gvcp::encode_command(gvcp::FLAG_ACK_REQUIRED, code::WRITEREG_CMD, 1000 + k as u16, &p));
        }
        let (mut pending, mut immediate) = (0, 0);
        while let Some(a) = c.recv() {
            match a.answer {
                code::PENDING_ACK => pending += 1,
                code::WRITEREG_ACK if a.status == 0 => immediate += 1,
                _ => {}
            }
            if pending + immediate == 200 {
                break;
            }
        }
        (pending, immediate)
    })
    .await
    .unwrap();
    assert_eq!(pending, PENDING_MAX, "at most {PENDING_MAX} writes wait");
    assert_eq!(immediate, 200 - PENDING_MAX);
    assert_eq!(rig.counter("hilcam_gige_pending_overflow_total", &[]), (200 - PENDING_MAX) as u64);
}
