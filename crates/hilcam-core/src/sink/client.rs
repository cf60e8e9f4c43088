//! The reference frame stream client: connect, verify both CRCs of every frame (and of
//! its truth block), save frames (and `truth_<k>.exr`), and measure rate, sequence gaps
//! and latency. `hilcam recv` is a thin CLI
//! over [`receive`]; the demo runs it in-process.

use super::recorder::{ImageFormat, frame_file_name, write_frame_image};
use crate::frame::truth_block::{WireTruth, check_truth_len, decode_frame_truth};
use crate::frame::{
    DecodeError, FrameHeader, HEADER_LEN, Malformed, check_payload, decode_header, pixels_from_le_bytes, unix_ns_now,
};
use crate::metrics::Histogram;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, BufReader};
use tokio::net::TcpStream;

/// What [`receive`] does with the frames.
#[derive(Clone, Debug)]
pub struct RecvOptions {
    /// Save each good frame here as `frame_<seq>.<ext>` (created if missing).
    pub out_dir: Option<PathBuf>,
    /// Stop after this many frames (otherwise at the server's close).
    pub count: Option<u64>,
    pub format: ImageFormat,
    /// Log a progress line at `info` this often (None: never).
    pub progress: Option<Duration>,
}

impl Default for RecvOptions {
    fn default() -> Self {
        RecvOptions { out_dir: None, count: None, format: ImageFormat::Png, progress: Some(Duration::from_secs(1)) }
    }
}

/// Latency percentiles (ns) of the frames received.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LatencyStats {
    pub count: u64,
    pub p50_ns: u64,
    pub p95_ns: u64,
    pub p99_ns: u64,
    pub max_ns: u64,
}

impl LatencyStats {
    fn from(h: &Histogram) -> LatencyStats {
        let s = h.snapshot();
        LatencyStats {
            count: s.count,
            p50_ns: s.quantile(0.5).unwrap_or(0),
            p95_ns: s.quantile(0.95).unwrap_or(0),
            p99_ns: s.quantile(0.99).unwrap_or(0),
            max_ns: s.max.unwrap_or(0),
        }
    }
}

/// What a [`receive`] run saw.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecvSummary {
    /// Frames with valid header and payload CRCs.
    pub frames: u64,
    pub bytes: u64,
    /// `frame_seq` of every good frame, in arrival order.
    pub seqs: Vec<u64>,
    /// Jumps in `frame_seq` (each a run of frames this client lost).
    pub gaps: u64,
    /// Frames missing in those jumps.
    pub missing: u64,
    /// Frames whose payload CRC did not match (not saved, not in `seqs`).
    pub payload_crc_errors: u64,
    /// Good frames that carried a truth block ([`crate::frame::truth_block`]) that decoded.
    pub truth_frames: u64,
    /// Truth blocks that failed their CRC or layout (the frame's image is still kept).
    pub truth_errors: u64,
    /// The server closed in the middle of a frame.
    pub truncated: bool,
    /// From the first header byte to the last frame's last byte.
    pub elapsed: Duration,
    pub fps: f64,
    /// Frame emit (sender's wall clock) → fully received (ours): same host only.
    pub emit_to_recv: LatencyStats,
    /// Pose arrival at the sender → fully received: same host only.
    pub pose_to_recv: LatencyStats,
}

#[derive(Debug, thiserror::Error)]
pub enum RecvError {
    #[error("cannot connect to {addr}: {source}")]
    Connect { addr: SocketAddr, source: std::io::Error },
    #[error("{addr}: {source}")]
    Io { addr: SocketAddr, source: std::io::Error },
    #[error("{addr}: after {frames} frames: {source}")]
    Protocol { addr: SocketAddr, frames: u64, source: Malformed },
    #[error("{path}: {message}")]
    Save { path: PathBuf, message: String },
}

/// Fill `buf` completely. Ok(false) on EOF before the first byte, Ok(true) when full;
/// EOF after some bytes is `UnexpectedEof`.
async fn read_full(rd: &mut (impl AsyncReadExt + Unpin), buf: &mut [u8]) -> std::io::Result<bool> {
    let mut n = 0;
    while n < buf.len() {
        let k = rd.read(&mut buf[n..]).await?;
        if k == 0 {
            if n == 0 {
                return Ok(false);
            }
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        n += k;
    }
    Ok(true)
}

enum RecvFail {
    Protocol(Malformed),
    Truncated,
}

/// Read a frame's truth block (its length first, checked before allocating) into
/// `block` and decode it; a block whose content fails is that frame's truth error only.
async fn read_truth(
    rd: &mut (impl AsyncReadExt + Unpin),
    h: &FrameHeader,
    block: &mut Vec<u8>,
) -> Result<Result<WireTruth, Malformed>, RecvFail> {
    let mut len = [0u8; 8];
    if !matches!(read_full(rd, &mut len).await, Ok(true)) {
        return Err(RecvFail::Truncated);
    }
    let len = u64::from_le_bytes(len);
    check_truth_len(h.meta.width, h.meta.height, len).map_err(RecvFail::Protocol)?;
    block.resize(len as usize, 0);
    if !matches!(read_full(rd, block).await, Ok(true)) && !block.is_empty() {
        return Err(RecvFail::Truncated);
    }
    Ok(decode_frame_truth(&h.meta, block))
}

/// Receive frames from a hilcam stream at `addr` until `opts.count` frames or the
/// server closes; see [`RecvSummary`].
pub async fn receive(addr: SocketAddr, opts: RecvOptions) -> Result<RecvSummary, RecvError> {
    let sock = TcpStream::connect(addr).await.map_err(|source| RecvError::Connect { addr, source })?;
    let _ = sock.set_nodelay(true);
    if let Some(dir) = &opts.out_dir {
        std::fs::create_dir_all(dir).map_err(|e| RecvError::Save { path: dir.clone(), message: e.to_string() })?;
    }
    let mut rd = BufReader::with_capacity(1 << 18, sock);
    let io = |source| RecvError::Io { addr, source };
    let emit_h = Histogram::new();
    let pose_h = Histogram::new();
    let mut s = RecvSummary::default();
    let mut start: Option<Instant> = None;
    let mut last_done = Instant::now();
    let mut last_progress = Instant::now();
    let mut header = [0u8; HEADER_LEN];
    let mut payload = Vec::new();
    let mut block = Vec::new();
    while opts.count.is_none_or(|n| s.frames < n) {
        match read_full(&mut rd, &mut header).await {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                s.truncated = true;
                break;
            }
            Err(e) => return Err(io(e)),
        }
        start.get_or_insert_with(Instant::now);
        let h = match decode_header(&header) {
            Ok(h) => h,
            Err(DecodeError::Malformed(source)) => {
                return Err(RecvError::Protocol { addr, frames: s.frames, source });
            }
            Err(DecodeError::Incomplete { .. }) => unreachable!("a whole header was read"),
        };
        payload.resize(h.payload_len as usize, 0);
        match read_full(&mut rd, &mut payload).await {
            Ok(true) => {}
            Ok(false) if payload.is_empty() => {}
            Ok(false) | Err(_) => {
                s.truncated = true;
                tracing::warn!(seq = h.meta.frame_seq, "stream closed in the middle of a frame");
                break;
            }
        }
        let truth = match h.truth_block {
            false => None,
            true => match read_truth(&mut rd, &h, &mut block).await {
                Ok(t) => Some(t),
                Err(RecvFail::Protocol(source)) => return Err(RecvError::Protocol { addr, frames: s.frames, source }),
                Err(RecvFail::Truncated) => {
                    s.truncated = true;
                    tracing::warn!(seq = h.meta.frame_seq, "stream closed in the middle of a truth block");
                    break;
                }
            },
        };
        let now_ns = unix_ns_now();
        last_done = Instant::now();
        if let Err(e) = check_payload(&h, &payload) {
            s.payload_crc_errors += 1;
            tracing::warn!("{e}");
            continue;
        }
        let seq = h.meta.frame_seq;
        if let Some(&prev) = s.seqs.last() {
            if seq > prev.saturating_add(1) {
                s.gaps += 1;
                s.missing += seq - prev - 1;
            } else if seq <= prev {
                tracing::warn!(prev, seq, "frame_seq went backwards (sender restarted?)");
            }
        }
        s.seqs.push(seq);
        s.frames += 1;
        s.bytes += (HEADER_LEN + payload.len()) as u64 + if h.truth_block { 8 + block.len() as u64 } else { 0 };
        let truth = match truth {
            Some(Ok(t)) => {
                s.truth_frames += 1;
                Some(t)
            }
            Some(Err(e)) => {
                s.truth_errors += 1;
                tracing::warn!(seq, "{e}");
                None
            }
            None => None,
        };
        emit_h.record(now_ns.saturating_sub(h.meta.emit_unix_ns));
        pose_h.record(now_ns.saturating_sub(h.meta.pose_arrival_unix_ns));
        if let Some(dir) = &opts.out_dir {
            let path = dir.join(frame_file_name(seq, opts.format));
            let px = pixels_from_le_bytes(h.meta.format, h.meta.bit_depth, &payload);
            let (w, hh, fmt) = (h.meta.width, h.meta.height, opts.format);
            let p = path.clone();
            tokio::task::spawn_blocking(move || write_frame_image(&p, w, hh, &px, fmt))
                .await
                .map_err(|e| RecvError::Save { path: path.clone(), message: e.to_string() })?
                .map_err(|e| RecvError::Save { path, message: e.to_string() })?;
            if let Some(t) = truth {
                // The mask table comes with the mask channel (the block's `materials` item).
                let path = dir.join(super::truth_exr::truth_file_name(seq));
                let p = path.clone();
                tokio::task::spawn_blocking(move || super::truth_exr::write_truth_exr(&p, &t.image))
                    .await
                    .map_err(|e| RecvError::Save { path: path.clone(), message: e.to_string() })?
                    .map_err(|e| RecvError::Save { path, message: e.to_string() })?;
            }
        }
        if let Some(every) = opts.progress
            && last_progress.elapsed() >= every
        {
            last_progress = Instant::now();
            tracing::info!(frames = s.frames, last_seq = seq, gaps = s.gaps, missing = s.missing, "receiving");
        }
    }
    s.elapsed = start.map_or(Duration::ZERO, |t| last_done.saturating_duration_since(t));
    if s.frames > 1 && !s.elapsed.is_zero() {
        // Frames after the first, over the time from the first's start to the last's end.
        s.fps = (s.frames - 1) as f64 / s.elapsed.as_secs_f64();
    }
    s.emit_to_recv = LatencyStats::from(&emit_h);
    s.pose_to_recv = LatencyStats::from(&pose_h);
    Ok(s)
}
