//! Frame header codec, TCP stream server, reference client, Python client, recorder.
//! Network tests bind 127.0.0.1:0; nothing asserts on elapsed time.

use crate::common;
use common::frames::example_frame;
use hilcam_core::frame::*;
use hilcam_core::metrics::Registry;
use hilcam_core::render::film::Pixels;
use hilcam_core::render::integrator::Spp;
use hilcam_core::sink::client::{RecvOptions, receive};
use hilcam_core::sink::recorder::{FrameRecord, ImageFormat, LOG_NAME, Recorder, RecorderConfig};
use hilcam_core::sink::tcp::{FrameWritten, StreamConfig, StreamServer, WriteHook};
use proptest::prelude::*;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpSocket, TcpStream};

// ---------------------------------------------------------------- codec

/// Header and payload CRCs computed independently with Python's zlib.crc32.
const EXAMPLE_BYTES: [u8; 96] = [
    0x48, 0x4c, 0x43, 0x46, 0x01, 0x00, 0x58, 0x00, 0x2a, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, //
    0x07, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x00, 0xca, 0x9a, 0x3b, 0x00, 0x00, 0x00, 0x00, //
    0x00, 0x00, 0x2a, 0x36, 0xfe, 0x9c, 0x97, 0x17, 0x40, 0x78, 0xa7, 0x37, 0xfe, 0x9c, 0x97, 0x17, //
    0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x0c, 0x04, 0x00, 0x03, 0x00, 0x00, 0x00, //
    0x6f, 0x12, 0x83, 0x3a, 0x32, 0xc5, 0xfc, 0x75, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, //
    0x00, 0x00, 0x00, 0x00, 0x1c, 0xdc, 0x79, 0xff, // header ends (88 bytes)
    0x00, 0x00, 0x01, 0x00, 0xff, 0x0f, 0x00, 0x08, // payload: 0, 1, 4095, 2048 (u16 LE)
];

#[test]
fn crc_is_iso_hdlc() {
    // The catalogue check value of CRC-32/ISO-HDLC.
    assert_eq!(CRC32.checksum(b"123456789"), 0xCBF4_3926);
}

#[test]
fn worked_example_encodes_to_documented_bytes() {
    let enc = example_frame().encode();
    assert_eq!(enc.bytes, EXAMPLE_BYTES);
    let (frame, used) = decode_frame(&EXAMPLE_BYTES).unwrap();
    assert_eq!(used, 96);
    assert_eq!(frame, example_frame());
    let h = decode_header(&EXAMPLE_BYTES).unwrap();
    assert_eq!(h.payload_len, 8);
    assert_eq!(h.payload_crc, 0x75FC_C532);
}

/// Re-seal a header after editing it, so that a later check is the one that fails.
fn reseal(b: &mut [u8]) {
    let crc = CRC32.checksum(&b[..84]);
    b[84..88].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn decoder_names_each_violation() {
    let good = EXAMPLE_BYTES;
    let mal = |b: &[u8]| match decode_frame(b) {
        Err(DecodeError::Malformed(m)) => m,
        other => panic!("expected Malformed, got {other:?}"),
    };
    let mut b = good;
    b[0] = b'X';
    assert!(matches!(mal(&b), Malformed::Magic(_)));
    let mut b = good;
    b[4] = 3;
    reseal(&mut b);
    assert_eq!(mal(&b), Malformed::Version(3));
    let mut b = good;
    b[6] = 96;
    reseal(&mut b);
    assert_eq!(mal(&b), Malformed::HeaderLen(96));
    let mut b = good;
    b[10] ^= 1; // frame_seq bit flip, not resealed
    assert!(matches!(mal(&b), Malformed::HeaderCrc { .. }));
    let mut b = good;
    b[56] = 9;
    reseal(&mut b);
    assert_eq!(mal(&b), Malformed::PixelFormat(9));
    let mut b = good;
    b[57] = 17; // Mono16 cannot have 17 significant bits
    reseal(&mut b);
    assert!(matches!(mal(&b), Malformed::BitDepth { bits: 17, .. }));
    let mut b = good;
    b[72] = 9;
    reseal(&mut b);
    assert!(matches!(mal(&b), Malformed::PayloadLen { found: 9, expected: 8, .. }));
    let mut b = good;
    b[62..64].copy_from_slice(&1000u16.to_le_bytes()); // a thousandth part of 1000
    reseal(&mut b);
    assert_eq!(mal(&b), Malformed::Spp { whole: 4, milli: 1000 });
    let mut b = good;
    b[58] = 0; // 0 samples per pixel
    reseal(&mut b);
    assert_eq!(mal(&b), Malformed::Spp { whole: 0, milli: 0 });
    let mut b = good;
    b[90] ^= 0x40; // payload bit flip
    assert!(matches!(mal(&b), Malformed::PayloadCrc { seq: 42, .. }));
}

#[test]
fn a_fractional_budget_travels_in_the_header() {
    let mut f = example_frame();
    f.meta.spp = "1.25".parse().unwrap();
    let enc = f.encode();
    assert_eq!(&enc.bytes[58..60], &1u16.to_le_bytes());
    assert_eq!(&enc.bytes[62..64], &250u16.to_le_bytes());
    let (back, _) = decode_frame(&enc.bytes).unwrap();
    assert_eq!(back.meta.spp.to_string(), "1.25");
}

#[test]
fn short_input_is_incomplete_with_the_missing_count() {
    for n in 0..EXAMPLE_BYTES.len() {
        let needed = EXAMPLE_BYTES.len() - n;
        let expect_header = n < HEADER_LEN;
        match decode_frame(&EXAMPLE_BYTES[..n]) {
            Err(DecodeError::Incomplete { needed: k }) if expect_header => {
                assert_eq!(k, HEADER_LEN - n)
            }
            Err(DecodeError::Incomplete { needed: k }) => assert_eq!(k, needed),
            other => panic!("{n} bytes: {other:?}"),
        }
    }
}

#[test]
fn frame_new_checks_size_and_depth() {
    let mut meta = example_frame().meta;
    meta.width = 3;
    assert!(matches!(
        Frame::new(meta, Pixels::Mono8(vec![0; 4])),
        Err(FrameError::SizeMismatch { expected: 6, actual: 4, .. })
    ));
    meta.width = 2;
    let px = Pixels::Mono16 { data: vec![0; 4], bits: 0 };
    assert!(matches!(Frame::new(meta, px), Err(FrameError::BitDepth { .. })));
}

fn any_frame() -> impl Strategy<Value = Frame> {
    let dims = (0u32..6, 0u32..6);
    let meta = (
        any::<u64>(),
        any::<u32>(),
        any::<u64>(),
        any::<u64>(),
        any::<u64>(),
        any::<u16>(),
        any::<u16>(),
        any::<u32>(), // integration time bits: any f32, NaN included
        any::<u32>(),
    );
    (dims, meta, 0u8..3, 1u8..=16).prop_flat_map(|((w, h), m, kind, bits)| {
        let n = (w * h) as usize;
        let px = match kind {
            0 => prop::collection::vec(any::<u8>(), n).prop_map(Pixels::Mono8).boxed(),
            1 => prop::collection::vec(any::<u16>(), n).prop_map(move |data| Pixels::Mono16 { data, bits }).boxed(),
            _ => prop::collection::vec(any::<u32>(), n)
                .prop_map(|v| Pixels::Float32(v.into_iter().map(f32::from_bits).collect()))
                .boxed(),
        };
        px.prop_map(move |px| {
            let meta = FrameMeta {
                frame_seq: m.0,
                pose_seq: m.1,
                pose_t_ns: m.2,
                pose_arrival_unix_ns: m.3,
                emit_unix_ns: m.4,
                width: w,
                height: h,
                format: PixelFormat::Mono8,
                bit_depth: 8,
                spp: Spp::from_milli(u32::from(m.5.max(1)) * 1000 + u32::from(m.5) % 1000),
                depth: m.6,
                integration_s: f32::from_bits(m.7),
                line_time_ns: 0,
                flags: FrameFlags(m.8),
            };
            Frame::new(meta, px).unwrap()
        })
    })
}

proptest! {
    /// decode(encode(f)) reproduces f bit for bit (compared via re-encoding, so NaNs
    /// in the payload or integration time count as equal when their bits are).
    #[test]
    fn codec_round_trips(f in any_frame(), tail in prop::collection::vec(any::<u8>(), 0..8)) {
        let enc = f.encode();
        let mut buf = enc.bytes.clone();
        buf.extend_from_slice(&tail);
        let (back, used) = decode_frame(&buf).unwrap();
        prop_assert_eq!(used, enc.bytes.len());
        prop_assert_eq!(back.encode().bytes, enc.bytes.clone());
        prop_assert_eq!(back.meta.frame_seq, f.meta.frame_seq);
        prop_assert_eq!(back.meta.integration_s.to_bits(), f.meta.integration_s.to_bits());
        prop_assert_eq!(back.pixels.format(), f.pixels.format());
        prop_assert_eq!(enc.pixels().to_le_bytes(), f.pixels.to_le_bytes());
    }

    /// Any single corrupted header byte is detected (CRC-32 catches all bursts ≤ 32 bits).
    #[test]
    fn any_header_byte_error_is_malformed(f in any_frame(), i in 0usize..HEADER_LEN, x in 1u8..=255) {
        let mut b = f.encode().bytes;
        b[i] ^= x;
        prop_assert!(matches!(decode_frame(&b), Err(DecodeError::Malformed(_))));
    }
}

// ---------------------------------------------------------------- helpers

fn float_frame(seq: u64, w: u32, h: u32) -> Arc<EncodedFrame> {
    let meta = FrameMeta {
        frame_seq: seq,
        pose_seq: seq as u32,
        pose_t_ns: seq * 1_000_000,
        pose_arrival_unix_ns: unix_ns_now(),
        emit_unix_ns: unix_ns_now(),
        width: w,
        height: h,
        format: PixelFormat::Float32,
        bit_depth: 32,
        spp: Spp::whole(1),
        depth: 2,
        integration_s: 0.0,
        line_time_ns: 0,
        flags: FrameFlags::default(),
    };
    let data = (0..w * h).map(|i| (i as f32) * 0.5 + seq as f32).collect();
    Arc::new(Frame::new(meta, Pixels::Float32(data)).unwrap().encode())
}

fn cfg(depth: usize) -> StreamConfig {
    StreamConfig { bind: SocketAddr::from(([127, 0, 0, 1], 0)), queue_depth: depth, ..StreamConfig::default() }
}

/// Read one whole frame's bytes from a raw socket (header + payload), None on EOF.
async fn read_frame(s: &mut TcpStream) -> Option<Vec<u8>> {
    let mut buf = vec![0u8; HEADER_LEN];
    match s.read_exact(&mut buf).await {
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return None,
        Err(e) => panic!("{e}"),
    }
    let h = decode_header(&buf).unwrap();
    buf.resize(HEADER_LEN + h.payload_len as usize, 0);
    s.read_exact(&mut buf[HEADER_LEN..]).await.unwrap();
    check_payload(&h, &buf[HEADER_LEN..]).unwrap();
    Some(buf)
}

fn seq_of(bytes: &[u8]) -> u64 {
    decode_header(bytes).unwrap().meta.frame_seq
}

/// Wait (without a deadline of our own: the test harness bounds it) until `pred`.
async fn until(mut pred: impl FnMut() -> bool) {
    while !pred() {
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
}

fn counter(reg: &Registry, key: &str) -> i64 {
    reg.snapshot().values.iter().find(|(k, _)| k == key).map_or(0, |(_, v)| *v)
}

// ---------------------------------------------------------------- server

#[tokio::test]
async fn every_client_receives_identical_frames() {
    let reg = Registry::new();
    let server = StreamServer::bind(cfg(8), reg.clone(), None).await.unwrap();
    let addr = server.local_addr();
    assert!(addr.ip().is_loopback());
    let mut clients = Vec::new();
    for _ in 0..3 {
        clients.push(TcpStream::connect(addr).await.unwrap());
    }
    until(|| server.client_count() == 3).await;
    let frames: Vec<_> = (0..5).map(|s| float_frame(s, 16, 8)).collect();
    for f in &frames {
        let r = server.publish(f.clone());
        assert_eq!((r.clients, r.dropped), (3, 0));
    }
    for c in &mut clients {
        for f in &frames {
            assert_eq!(read_frame(c).await.unwrap(), f.bytes);
        }
    }
    // One encoded copy shared by all: 5 frames × 3 clients in the byte counter.
    let per_frame = frames[0].bytes.len() as i64;
    until(|| counter(&reg, "hilcam_stream_bytes_sent_total") == 15 * per_frame).await;
    server.shutdown().await;
    for c in &mut clients {
        assert!(read_frame(c).await.is_none(), "clean close at a frame boundary");
    }
}

/// Dropping the server without `shutdown()` stops it too: the listener closes and each
/// client gets a clean close after its last whole frame.
#[tokio::test]
async fn dropping_the_server_closes_its_clients() {
    let reg = Registry::new();
    let server = StreamServer::bind(cfg(8), reg.clone(), None).await.unwrap();
    let addr = server.local_addr();
    let mut client = TcpStream::connect(addr).await.unwrap();
    until(|| server.client_count() == 1).await;
    let frame = float_frame(0, 16, 8);
    server.publish(frame.clone());
    assert_eq!(read_frame(&mut client).await.unwrap(), frame.bytes);
    drop(server);
    let closed = tokio::time::timeout(Duration::from_secs(10), read_frame(&mut client)).await;
    assert!(closed.expect("the client was closed").is_none(), "clean close at a frame boundary");
    until(|| counter(&reg, "hilcam_stream_clients") == 0).await;
}

/// A client that stops reading loses frames (oldest first) and never slows another.
#[tokio::test]
async fn stalled_client_drops_oldest_and_fast_client_gets_everything() {
    const N: u64 = 40;
    let reg = Registry::new();
    let server = StreamServer::bind(cfg(2), reg.clone(), None).await.unwrap();
    let addr = server.local_addr();
    let mut fast = TcpStream::connect(addr).await.unwrap();
    until(|| server.client_count() == 1).await;
    // The stalled client advertises a tiny receive window so the server's socket fills.
    let sock = TcpSocket::new_v4().unwrap();
    sock.set_recv_buffer_size(4096).unwrap();
    let mut stalled = sock.connect(addr).await.unwrap();
    until(|| server.client_count() == 2).await;
    let ids: Vec<u64> = server.clients().iter().map(|c| c.id).collect();
    let (fast_id, stalled_id) = (ids[0], ids[1]);

    let mut reported_drops = 0;
    for seq in 0..N {
        // 1 MiB frames: 40 MiB in all, far beyond the socket buffers (≤ 4 MiB here).
        let r = server.publish(float_frame(seq, 512, 512));
        assert_eq!(r.clients, 2);
        reported_drops += r.dropped as u64;
        // The fast client reads each frame before the next is published, so its queue
        // never overflows — whatever the stalled one does.
        let got = read_frame(&mut fast).await.unwrap();
        assert_eq!(seq_of(&got), seq);
    }
    let stats = server.clients();
    let f = stats.iter().find(|c| c.id == fast_id).unwrap();
    let s = stats.iter().find(|c| c.id == stalled_id).unwrap();
    assert_eq!((f.sent, f.dropped), (N, 0));
    assert!(s.dropped > 0, "stalled client must have lost frames: {s:?}");
    assert_eq!(s.dropped, reported_drops);
    let key = format!("hilcam_stream_frames_dropped_total{{client=\"{stalled_id}\",reason=\"queue_full\"}}");
    assert_eq!(counter(&reg, &key), s.dropped as i64);

    // Now drain the stalled client: it gets exactly the frames that were not dropped,
    // in order, ending with the newest (drop-oldest policy).
    let expect = N - s.dropped;
    let mut seqs = Vec::new();
    while (seqs.len() as u64) < expect {
        seqs.push(seq_of(&read_frame(&mut stalled).await.unwrap()));
    }
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    assert_eq!(*seqs.last().unwrap(), N - 1);
    assert!(seqs.windows(2).any(|w| w[1] > w[0] + 1), "the loss shows as a gap");
    server.shutdown().await;
}

#[tokio::test]
async fn disconnect_mid_frame_leaves_server_healthy() {
    let reg = Registry::new();
    let server = StreamServer::bind(cfg(2), reg.clone(), None).await.unwrap();
    let addr = server.local_addr();
    let mut good = TcpStream::connect(addr).await.unwrap();
    until(|| server.client_count() == 1).await;
    let mut quitter = TcpStream::connect(addr).await.unwrap();
    until(|| server.client_count() == 2).await;

    server.publish(float_frame(0, 1024, 1024)); // 4 MiB
    let mut part = vec![0u8; 1000];
    quitter.read_exact(&mut part).await.unwrap();
    drop(quitter); // unread data pending: the kernel sends RST
    assert_eq!(seq_of(&read_frame(&mut good).await.unwrap()), 0);

    // The server notices on a later write; keep streaming until it has.
    let mut seq = 1;
    while server.client_count() != 1 {
        assert!(seq < 1000, "server never noticed the disconnect");
        server.publish(float_frame(seq, 1024, 1024));
        assert_eq!(seq_of(&read_frame(&mut good).await.unwrap()), seq);
        seq += 1;
    }
    assert_eq!(counter(&reg, "hilcam_stream_write_errors_total"), 1);
    assert_eq!(counter(&reg, "hilcam_stream_clients"), 1);

    // Still accepting and streaming to old and new clients alike.
    let mut late = TcpStream::connect(addr).await.unwrap();
    until(|| server.client_count() == 2).await;
    let f = float_frame(seq, 64, 64);
    server.publish(f.clone());
    assert_eq!(read_frame(&mut good).await.unwrap(), f.bytes);
    assert_eq!(read_frame(&mut late).await.unwrap(), f.bytes);
    server.shutdown().await;
}

#[tokio::test]
async fn shutdown_finishes_frames_and_reports_every_write() {
    let reg = Registry::new();
    let events: Arc<Mutex<Vec<FrameWritten>>> = Arc::default();
    let ev = events.clone();
    let hook: WriteHook = Arc::new(move |e| ev.lock().unwrap().push(*e));
    let server = StreamServer::bind(cfg(8), reg.clone(), Some(hook)).await.unwrap();
    let addr = server.local_addr();
    let opts = RecvOptions { progress: None, ..RecvOptions::default() };
    let client = tokio::spawn(receive(addr, opts));
    until(|| server.client_count() == 1).await;
    let id = server.clients()[0].id;
    for seq in 0..3 {
        server.publish(float_frame(seq, 256, 256));
    }
    until(|| events.lock().unwrap().len() == 3).await;
    server.shutdown().await;
    let s = client.await.unwrap().unwrap();
    assert_eq!(s.seqs, vec![0, 1, 2]);
    assert!(!s.truncated);
    assert_eq!((s.gaps, s.missing, s.payload_crc_errors), (0, 0, 0));
    assert_eq!(s.emit_to_recv.count, 3);
    let ev = events.lock().unwrap();
    assert_eq!(ev.iter().map(|e| e.frame_seq).collect::<Vec<_>>(), vec![0, 1, 2]);
    assert!(ev.iter().all(|e| e.client_id == id));
    assert!(ev.iter().all(|e| e.last_byte_unix_ns >= e.pose_arrival_unix_ns));
    let snap = reg.snapshot();
    let (_, lat) = snap.histograms.iter().find(|(k, _)| k == "hilcam_stream_latency_seconds").unwrap();
    assert_eq!(lat.count, 3);
}

/// A client that never reads cannot hold shutdown hostage: after the grace period the
/// frame in flight is abandoned. Paused time makes the 1-hour grace elapse at once.
#[tokio::test(start_paused = true)]
async fn shutdown_abandons_a_stalled_write_after_the_grace_period() {
    let reg = Registry::new();
    let mut c = cfg(2);
    c.shutdown_grace = Duration::from_secs(3600);
    let server = StreamServer::bind(c, reg.clone(), None).await.unwrap();
    let sock = TcpSocket::new_v4().unwrap();
    sock.set_recv_buffer_size(4096).unwrap();
    let _stalled = sock.connect(server.local_addr()).await.unwrap();
    until(|| server.client_count() == 1).await;
    // 16 MiB: more than the socket buffers can take, so the write cannot finish.
    server.publish(float_frame(0, 2048, 2048));
    // Once the queue is empty the writer has taken the frame and is blocked in it.
    until(|| server.clients()[0].queued == 0).await;
    let before = tokio::time::Instant::now();
    server.shutdown().await;
    assert!(tokio::time::Instant::now() - before >= Duration::from_secs(3600));
    assert_eq!(counter(&reg, "hilcam_stream_frames_sent_total{client=\"1\"}"), 0);
}

#[tokio::test]
async fn max_clients_refuses_extra_connections() {
    let reg = Registry::new();
    let mut c = cfg(2);
    c.max_clients = 1;
    let server = StreamServer::bind(c, reg.clone(), None).await.unwrap();
    let _a = TcpStream::connect(server.local_addr()).await.unwrap();
    until(|| server.client_count() == 1).await;
    let mut b = TcpStream::connect(server.local_addr()).await.unwrap();
    let mut buf = [0u8; 1];
    assert_eq!(b.read(&mut buf).await.unwrap_or(0), 0, "refused client is closed");
    assert_eq!(counter(&reg, "hilcam_stream_clients_rejected_total"), 1);
    assert_eq!(server.client_count(), 1);
    server.shutdown().await;
}

// ---------------------------------------------------------------- clients

/// The reference client counts a corrupted payload, skips it, and goes on.
#[tokio::test]
async fn receive_counts_payload_crc_errors_and_gaps() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = RecvOptions {
        out_dir: Some(dir.path().to_path_buf()),
        format: ImageFormat::Pfm,
        progress: None,
        ..RecvOptions::default()
    };
    let client = tokio::spawn(receive(addr, opts));
    let (mut sock, _) = listener.accept().await.unwrap();
    let mut bad = float_frame(1, 4, 4).bytes.clone();
    *bad.last_mut().unwrap() ^= 1;
    for bytes in [float_frame(0, 4, 4).bytes.clone(), bad, float_frame(5, 4, 4).bytes.clone()] {
        sock.write_all(&bytes).await.unwrap();
    }
    drop(sock);
    let s = client.await.unwrap().unwrap();
    assert_eq!(s.seqs, vec![0, 5]);
    assert_eq!((s.payload_crc_errors, s.gaps, s.missing), (1, 1, 4));
    let img = hilcam_core::render::film::read_pfm(&dir.path().join("frame_0000000005.pfm")).unwrap();
    let Pixels::Float32(want) = float_frame(5, 4, 4).pixels() else { unreachable!() };
    assert_eq!(img.data, want);
    assert!(!dir.path().join("frame_0000000001.pfm").exists());
}

/// examples/recv_frames.py parses the same stream and agrees on CRCs, gaps and flags.
#[tokio::test]
async fn python_example_client_verifies_the_stream() {
    let server = StreamServer::bind(cfg(8), Registry::new(), None).await.unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/recv_frames.py");
    let child = std::process::Command::new("python3")
        .args([script, "--connect", &server.local_addr().to_string(), "--count", "5"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("python3 is required for this test");
    until(|| server.client_count() == 1).await;
    for seq in [0u64, 1, 2, 5, 6] {
        let mut f = (*float_frame(seq, 8, 4)).clone();
        if seq == 2 {
            // Re-encode with the LATE flag set to see it reported.
            let mut frame = decode_frame(&f.bytes).unwrap().0;
            frame.meta.flags = frame.meta.flags.with(FrameFlags::LATE);
            f = frame.encode();
        }
        server.publish(Arc::new(f));
    }
    let out = tokio::task::spawn_blocking(move || child.wait_with_output()).await.unwrap().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 6, "{stdout}");
    for (line, seq) in lines.iter().zip([0, 1, 2, 5, 6]) {
        assert!(line.starts_with(&format!("frame seq={seq} pose_seq={seq} 8x4 Float32 bits=32")), "{line}");
        assert!(line.contains("crc=ok"), "{line}");
    }
    assert!(lines[2].contains("flags=late"), "{}", lines[2]);
    assert!(lines[1].contains("flags=-"), "{}", lines[1]);
    assert!(lines[5].starts_with("summary frames=5 gaps=1 missing=2 crc_errors=0"), "{}", lines[5]);
    server.shutdown().await;
}

// ---------------------------------------------------------------- recorder

fn mono16_frame(seq: u64) -> Arc<EncodedFrame> {
    let (w, h) = (5, 3);
    let mut f = (*float_frame(seq, w, h)).clone().meta;
    f.flags = FrameFlags(FrameFlags::EXTRAPOLATED);
    f.integration_s = 0.0125;
    let data = (0..w * h).map(|i| (i * 271 + seq as u32) as u16 & 0x0fff).collect();
    Arc::new(Frame::new(f, Pixels::Mono16 { data, bits: 12 }).unwrap().encode())
}

#[test]
fn recorder_writes_images_and_json_lines_that_parse_back() {
    let dir = tempfile::tempdir().unwrap();
    let reg = Registry::new();
    let rec = Recorder::start(RecorderConfig::new(dir.path(), ImageFormat::Png), &reg).unwrap();
    let frames: Vec<_> = (10..13).map(mono16_frame).collect();
    for f in &frames {
        assert!(rec.publish(f.clone()), "queue of 8 takes 3 frames");
    }
    let stats = rec.finish().unwrap();
    assert_eq!((stats.written, stats.dropped), (3, 0));
    assert_eq!(stats.errors, 0);
    let log = std::fs::read_to_string(dir.path().join(LOG_NAME)).unwrap();
    let records: Vec<FrameRecord> = log.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(records.len() as u64, stats.written);
    for r in &records {
        let f = frames.iter().find(|f| f.meta.frame_seq == r.meta.frame_seq).unwrap();
        assert_eq!(r.meta, f.meta);
        assert!(r.extrapolated && !r.late);
        assert_eq!(r.payload_crc32, decode_header(&f.bytes).unwrap().payload_crc);
        // The 16-bit PNG holds the DN values as they were.
        let img = image::open(dir.path().join(&r.file)).unwrap().into_luma16();
        let Pixels::Mono16 { data, .. } = f.pixels() else { unreachable!() };
        assert_eq!(img.into_raw(), data);
    }
}

/// With a one-frame queue, whatever the disk speed: written + dropped = offered, and the
/// log lists exactly the written frames.
#[test]
fn recorder_counts_what_it_cannot_keep_up_with() {
    let dir = tempfile::tempdir().unwrap();
    let reg = Registry::new();
    let mut cfg = RecorderConfig::new(dir.path(), ImageFormat::Pfm);
    cfg.queue_depth = 1;
    let rec = Recorder::start(cfg, &reg).unwrap();
    let mut accepted = 0;
    for seq in 0..50 {
        accepted += rec.publish(float_frame(seq, 128, 128)) as u64;
    }
    let stats = rec.finish().unwrap();
    assert_eq!(stats.written, accepted);
    assert_eq!(stats.written + stats.dropped, 50);
    assert_eq!(counter(&reg, "hilcam_recorder_frames_dropped_total"), stats.dropped as i64);
    let lines = std::fs::read_to_string(dir.path().join(LOG_NAME)).unwrap();
    assert_eq!(lines.lines().count() as u64, stats.written);
    for l in lines.lines() {
        let r: FrameRecord = serde_json::from_str(l).unwrap();
        let img = hilcam_core::render::film::read_pfm(&dir.path().join(&r.file)).unwrap();
        let Pixels::Float32(want) = float_frame(r.meta.frame_seq, 128, 128).pixels() else { unreachable!() };
        assert_eq!(img.data, want);
    }
}

/// `hilcam recv` end to end: saves the frames in the chosen format and prints the stats.
#[tokio::test]
async fn recv_command_saves_frames_and_reports_gaps() {
    let server = StreamServer::bind(cfg(8), Registry::new(), None).await.unwrap();
    let dir = tempfile::tempdir().unwrap();
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["recv", "--connect", &server.local_addr().to_string(), "--count", "3"])
        .args(["--format", "tiff", "--out"])
        .arg(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    until(|| server.client_count() == 1).await;
    let frames: Vec<_> = [3u64, 4, 7].into_iter().map(mono16_frame).collect();
    for f in &frames {
        server.publish(f.clone());
    }
    let out = tokio::task::spawn_blocking(move || child.wait_with_output()).await.unwrap().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("frames 3 "), "{stdout}");
    assert!(stdout.contains("frame_seq 3..7: 1 gaps, 2 frames missing, 0 payload CRC errors"), "{stdout}");
    assert!(stdout.contains("latency emit -> receive"), "{stdout}");
    for f in &frames {
        let name = format!("frame_{:010}.tif", f.meta.frame_seq);
        let img = image::open(dir.path().join(name)).unwrap().into_luma16();
        let Pixels::Mono16 { data, .. } = f.pixels() else { unreachable!() };
        assert_eq!(img.into_raw(), data);
    }
    server.shutdown().await;
}

/// The truth of the worked example in docs/protocol.md ("Ground truth block"): the
/// frame's pixels (1, 0) and (0, 1) see material 0 at 5 m and 5.25 m.
fn example_truth() -> hilcam_core::render::truth::TruthImage {
    hilcam_core::render::truth::TruthImage {
        width: 2,
        height: 2,
        channels: hilcam_core::render::truth::TruthChannels::parse("depth,mask").unwrap(),
        mask: vec![0, 1, 1, 0],
        materials: Some("1=paint".into()),
        depth: vec![f32::INFINITY, 5.0, 5.25, f32::INFINITY],
        normal: Default::default(),
        body_xyz: Default::default(),
    }
}

/// The hex dump of the truth worked example in docs/protocol.md, as bytes.
fn documented_truth_example() -> Vec<u8> {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/protocol.md")).unwrap();
    let start = doc.find("### Worked example with truth").expect("section in docs/protocol.md");
    let block = doc[start..].split("```").nth(1).expect("a code block");
    block
        .lines()
        .filter_map(|l| l.split_once(": "))
        .flat_map(|(_, rest)| {
            rest.split("   ").next().unwrap().split_whitespace().map(|h| u8::from_str_radix(h, 16).unwrap())
        })
        .collect()
}

#[test]
fn truth_worked_example_encodes_to_the_documented_bytes_and_decodes_back() {
    let enc = example_frame().encode_with_truth(Arc::new(example_truth()));
    let doc = documented_truth_example();
    assert_eq!(enc.bytes, doc, "docs/protocol.md \"Worked example with truth\"");
    let (frame, truth, used) = decode_frame_with_truth(&doc).unwrap();
    assert_eq!(used, doc.len());
    assert_eq!(frame.pixels, example_frame().pixels);
    assert_eq!(frame.meta.flags.0, FrameFlags::LATE | FrameFlags::EXTRAPOLATED | FrameFlags::TRUTH);
    let t = truth.unwrap();
    assert_eq!((t.image.mask.clone(), t.image.depth.clone()), (example_truth().mask, example_truth().depth));
    assert_eq!(t.image.materials.as_deref(), Some("1=paint"), "the mask's table");
    // Issue 42: the sentence's byte counts are the dump's (it said 132 for 124 bytes).
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/protocol.md")).unwrap();
    let section = &page[page.find("### Worked example with truth").unwrap()..];
    let number_before = |marker: &str| -> usize {
        let head = section[..section.find(marker).unwrap_or_else(|| panic!("no `{marker}`"))].trim_end();
        head.rsplit(|c: char| !c.is_ascii_digit()).next().unwrap().parse().unwrap()
    };
    let after_payload = doc.len() - HEADER_LEN - 8;
    assert_eq!(number_before("bytes follow it"), after_payload, "docs/protocol.md: bytes after the payload");
    assert_eq!(number_before("-byte block"), after_payload - 8, "docs/protocol.md: the block's length");
    let fp = t.footprint.unwrap();
    assert_eq!((fp.pixels, fp.centroid_px, fp.bbox_px), (2, [1.0, 1.0], [0, 0, 2, 2]));
    // The payload accessor stops before the block.
    assert_eq!(enc.payload(), &doc[HEADER_LEN..HEADER_LEN + 8]);
}

#[test]
fn a_truncated_or_oversized_truth_block_waits_or_is_refused_before_allocating() {
    let doc = example_frame().encode_with_truth(Arc::new(example_truth())).bytes;
    for cut in [HEADER_LEN + 8, HEADER_LEN + 12, doc.len() - 1] {
        assert!(matches!(decode_frame_with_truth(&doc[..cut]), Err(DecodeError::Incomplete { .. })), "cut {cut}");
    }
    let mut big = doc.clone();
    big[HEADER_LEN + 8..HEADER_LEN + 16].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(matches!(decode_frame_with_truth(&big), Err(DecodeError::Malformed(Malformed::TruthLen { .. }))));
    let mut flipped = doc.clone();
    *flipped.last_mut().unwrap() ^= 1;
    assert!(matches!(decode_frame_with_truth(&flipped), Err(DecodeError::Malformed(Malformed::TruthBlock { .. }))));
    // A version 1 header with bit 4 set has no block: the frame ends at its payload.
    let mut v1 = EXAMPLE_BYTES;
    v1[20] |= FrameFlags::TRUTH as u8;
    reseal(&mut v1);
    assert_eq!(decode_frame_with_truth(&v1).unwrap().2, HEADER_LEN + 8);
    // And a frame encoded without truth never claims a block, whatever its meta says.
    let mut f = example_frame();
    f.meta.flags = f.meta.flags.with(FrameFlags::TRUTH);
    assert_eq!(f.encode().bytes, EXAMPLE_BYTES);
}
