//! `[output] truth` in `hilcam serve`: poses over a serial pty, frames on the TCP stream
//! with the truth block after the payload. Checks the block against
//! `FramePipeline::truth` for the same pose (bit for bit) and the sphere's analytic range,
//! a client that skips the block by its length staying in step, `hilcam recv` and the
//! recorder keeping it (truth EXR + the `truth` log object), and truth off sending
//! version 1 frames with the same pixels and nothing after them.

use crate::serve_common::*;
use glam::DVec3;
use hilcam_core::frame::truth_block::WireTruth;
use hilcam_core::frame::{
    DecodeError, Frame, FrameFlags, HEADER_LEN, VERSION, VERSION_TRUTH, decode_frame_with_truth, decode_header,
};
use hilcam_core::link::send::{MessageWriter, SerialWriter};
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Message;
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::serve::config::{GovernorConfig, InputConfig, RecordSection, SerialInput, TriggerConfig};
use hilcam_core::sink::recorder::FrameRecord;
use hilcam_core::sink::{ImageFormat, RecvOptions, receive};
use serialport::SerialPort;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use tokio::io::AsyncReadExt;

const WIDTH: u32 = 96;
const FRAMES: u32 = 3;

/// Target positions of the poses sent (the sphere's centre, camera frame, m).
fn position(k: u32) -> DVec3 {
    DVec3::new(0.8 - 0.3 * f64::from(k), -0.5, 10.0 + f64::from(k))
}

/// The next frame and its decoded truth off a [`Reader`].
async fn next_with_truth(r: &mut Reader) -> (Frame, Option<WireTruth>, Vec<u8>) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        match decode_frame_with_truth(&r.buf) {
            Ok((f, t, used)) => {
                let bytes = r.buf.drain(..used).collect();
                return (f, t, bytes);
            }
            Err(DecodeError::Incomplete { .. }) => {}
            Err(e) => panic!("bad frame: {e:?}"),
        }
        let mut chunk = vec![0u8; 1 << 16];
        let left = deadline.saturating_duration_since(Instant::now());
        let n = tokio::time::timeout(left, r.s.read(&mut chunk)).await.expect("frame in time").unwrap();
        assert!(n > 0, "stream closed");
        r.buf.extend_from_slice(&chunk[..n]);
    }
}

/// A client that knows the header only: it reads the payload, and on a TRUTH frame
/// skips the block by its length without looking inside. Returns each frame's
/// `frame_seq` and payload.
async fn skipping_client(addr: std::net::SocketAddr, frames: u32) -> Vec<(u64, Vec<u8>)> {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    let mut out = Vec::new();
    for _ in 0..frames {
        let mut header = [0u8; HEADER_LEN];
        s.read_exact(&mut header).await.unwrap();
        let h = decode_header(&header).unwrap();
        let mut payload = vec![0u8; h.payload_len as usize];
        s.read_exact(&mut payload).await.unwrap();
        if h.truth_block {
            let mut len = [0u8; 8];
            s.read_exact(&mut len).await.unwrap();
            let mut skip = vec![0u8; u64::from_le_bytes(len) as usize];
            s.read_exact(&mut skip).await.unwrap();
        }
        out.push((h.meta.frame_seq, payload));
    }
    out
}

struct Run {
    /// Each frame, its truth and its bytes on the wire.
    frames: Vec<(Frame, Option<WireTruth>, Vec<u8>)>,
    skipped: Vec<(u64, Vec<u8>)>,
    recv: hilcam_core::sink::RecvSummary,
}

/// Serve the sphere with `truth` (record into `dir/rec`, `hilcam recv` into `dir/recv`),
/// send [`FRAMES`] poses over a pty, read them with three clients.
async fn serve(dir: &Path, truth: &str) -> Run {
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let input = InputConfig::Serial(SerialInput { device: slave.name().unwrap(), baud: 921_600 });
    let scene = sphere_scene(dir, WIDTH, 4);
    let mut cfg = config(scene, input, TriggerConfig::default(), GovernorConfig::default());
    cfg.output.truth = TruthChannels::parse(truth).unwrap();
    cfg.record = Some(RecordSection { dir: Some(dir.join("rec")), session: None, format: ImageFormat::Pfm });
    let server = start(cfg, None).await;
    let mut reader = Reader::connect(server.info.stream).await;
    let skipper = tokio::spawn(skipping_client(server.info.stream, FRAMES));
    let opts = RecvOptions {
        out_dir: Some(dir.join("recv")),
        count: Some(u64::from(FRAMES)),
        format: ImageFormat::Pfm,
        progress: None,
    };
    let recv = tokio::spawn(receive(server.info.stream, opts));
    // The reader, the skipper and `recv`.
    wait_stream_clients(&server.info, 3).await;
    let mut w = SerialWriter::new(master, "test pty");
    let mut frames = Vec::new();
    for k in 0..FRAMES {
        let p = position(k);
        w.send(&Message::Pose(pose(k + 1, p, -p))).unwrap();
        frames.push(next_with_truth(&mut reader).await);
    }
    let skipped = tokio::time::timeout(PATIENCE, skipper).await.unwrap().unwrap();
    let recv = tokio::time::timeout(PATIENCE, recv).await.unwrap().unwrap().unwrap();
    server.finish().await;
    drop(slave);
    Run { frames, skipped, recv }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn truth_rides_after_the_payload_equal_to_the_pipelines_and_clients_that_skip_it_stay_in_step() {
    let dir = tempfile::tempdir().unwrap();
    let on = serve(dir.path(), "depth,mask").await;
    let scene = Arc::new(hilcam_core::scene::load(&dir.path().join("scene.toml")).unwrap());
    let pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
    let channels = TruthChannels::parse("depth,mask").unwrap();
    for (k, (f, truth, bytes)) in on.frames.iter().enumerate() {
        let k = k as u32;
        assert_eq!(u16::from_le_bytes([bytes[4], bytes[5]]), VERSION_TRUTH);
        assert!(f.meta.flags.contains(FrameFlags::TRUTH));
        let truth = truth.as_ref().expect("a truth block");
        let p = position(k);
        let want = pipeline.truth(&pose(k + 1, p, -p), &FrameRequest::default(), channels).unwrap();
        assert_eq!(truth.image.channels, channels);
        assert_eq!(truth.image.mask, want.mask);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&truth.image.depth), bits(&want.depth), "frame {k}: depth bit for bit");
        assert!(truth.image.normal.iter().all(Vec::is_empty), "normal was not asked for");
        assert_eq!(truth.footprint, want.footprint());
        let fp = truth.footprint.unwrap();
        // Pinhole: f = 2 mm / 10 µm = 200 px; the sphere (r = 1 m) projects about its centre.
        let (px, py) = (48.0 + 200.0 * p.x / p.z, 48.0 + 200.0 * p.y / p.z);
        assert!((fp.centroid_px[0] - px).abs() < 0.5 && (fp.centroid_px[1] - py).abs() < 0.5, "{fp:?}");
        // Analytic range at the pixel holding the projected centre: |p| − 1 m. Tolerance
        // 2 mm: the icosphere's faces sit at most ~0.3 mm inside the unit sphere (edge
        // ~0.035 rad), and the pixel centre's ray passes up to half a pixel (25 mm at
        // 10 m) off the centre, where the surface is ~0.3 mm farther.
        let i = py.floor() as usize * WIDTH as usize + px.floor() as usize;
        let d = f64::from(truth.image.depth[i]);
        assert!((d - (p.length() - 1.0)).abs() < 2e-3, "frame {k}: depth {d} vs {}", p.length() - 1.0);
        assert_eq!(truth.image.mask[i], 1, "sphere material 0 → mask 1");
        assert!(truth.image.depth[0].is_infinite() && truth.image.mask[0] == 0, "corner misses");
    }
    // The header-only client read every frame, in order, with the same payloads.
    let seqs: Vec<u64> = on.skipped.iter().map(|(s, _)| *s).collect();
    assert_eq!(seqs, (0..u64::from(FRAMES)).collect::<Vec<_>>());
    for ((_, payload), (_, _, bytes)) in on.skipped.iter().zip(&on.frames) {
        assert_eq!(payload[..], bytes[HEADER_LEN..HEADER_LEN + payload.len()]);
    }
    assert_eq!((on.recv.frames, on.recv.truth_frames, on.recv.truth_errors), (3, 3, 0));
    assert_eq!(on.recv.bytes, on.frames.iter().map(|(_, _, b)| b.len() as u64).sum::<u64>());
    for k in 0..u64::from(FRAMES) {
        assert!(dir.path().join(format!("recv/truth_{k:010}.exr")).is_file());
    }
    // The recorder: truth_<k>.exr beside each frame and the `truth` object in its log line.
    let log = std::fs::read_to_string(dir.path().join("rec/frames.jsonl")).unwrap();
    let records: Vec<FrameRecord> = log.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(records.len(), FRAMES as usize);
    for (r, (_, truth, _)) in records.iter().zip(&on.frames) {
        let t = r.truth.as_ref().expect("truth in the log");
        let fp = truth.as_ref().unwrap().footprint.unwrap();
        assert_eq!((t.channels.as_str(), t.target_pixels), ("depth,mask", fp.pixels));
        assert_eq!((t.target_centroid_px, t.target_bbox_px), (Some(fp.centroid_px), Some(fp.bbox_px)));
        assert!(dir.path().join("rec").join(&t.file).is_file(), "{}", t.file);
    }

    // Truth off: version 1 frames, nothing after the payload, the same pixels.
    let dir_off = tempfile::tempdir().unwrap();
    let off = serve(dir_off.path(), "").await;
    for ((f, truth, bytes), (f_on, _, bytes_on)) in off.frames.iter().zip(&on.frames) {
        assert_eq!(u16::from_le_bytes([bytes[4], bytes[5]]), VERSION);
        assert!(truth.is_none() && !f.meta.flags.contains(FrameFlags::TRUTH));
        assert_eq!(bytes.len() as u64, HEADER_LEN as u64 + f.meta.payload_len());
        assert_eq!(f.pixels, f_on.pixels);
        assert_eq!(bytes[HEADER_LEN..], bytes_on[HEADER_LEN..bytes.len()]);
    }
    assert_eq!((off.recv.frames, off.recv.truth_frames), (3, 0));
    let log = std::fs::read_to_string(dir_off.path().join("rec/frames.jsonl")).unwrap();
    assert!(!log.contains("truth"), "{log}");
    assert!(!dir_off.path().join("rec/truth_0000000000.exr").exists());
}
