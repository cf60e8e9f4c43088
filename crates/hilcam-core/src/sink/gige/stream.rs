//! The GVSP sender: one std thread owns the stream socket, converts each frame to the
//! client's ROI and format, packetises it, paces the packets by the negotiated delay,
//! keeps a bounded ring of recent blocks and answers resend requests from it, within a
//! budget of one block's packets per frame sent (frames go first: `stream_jobs.rs`).
//! It stops within [`STOP_POLL`] of the stop flag, even mid-block.

use super::chunk::{self, ChunkKind, SfncValues};
use super::gvsp::{self, Block};
use super::metrics::Metrics;
use super::pixel;
use super::registers::{CameraSettings, StreamChannel};
use super::stream_jobs::{Jobs, Next};
use crate::frame::{EncodedFrame, unix_ns_now};
use crate::render::camera::Window;
use std::collections::VecDeque;
use std::net::{SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The longest the thread sleeps between two looks at the stop flag.
pub const STOP_POLL: Duration = Duration::from_millis(50);

pub(super) struct FrameJob {
    pub frame: Arc<EncodedFrame>,
    pub settings: CameraSettings,
    pub channel: StreamChannel,
}

pub(super) struct ResendJob {
    pub block_id: u64,
    pub first: u32,
    pub last: u32,
}

pub(super) type StreamJobs = Jobs<FrameJob, ResendJob>;

/// Paces packets by the negotiated inter-packet delay. The schedule is absolute and
/// restarts with each block (packet k leaves at start + k·delay), so the mean rate is
/// exact; the thread sleeps only when it is more than 200 µs ahead, so delays below the
/// OS sleep granularity are kept on average, in short bursts, without spinning. After
/// an oversleep (a loaded machine) it catches up rather than losing the time.
struct Pacer {
    next: Instant,
}

impl Pacer {
    const SLEEP_AHEAD: Duration = Duration::from_micros(200);

    fn start_block(&mut self) {
        self.next = Instant::now();
    }

    /// Wait for the next packet's slot; false when `stop` was set meanwhile.
    fn wait(&mut self, delay: Duration, stop: &AtomicBool) -> bool {
        if delay.is_zero() {
            return true;
        }
        loop {
            let now = Instant::now();
            if self.next <= now + Self::SLEEP_AHEAD {
                break;
            }
            if stop.load(Ordering::Acquire) {
                return false;
            }
            std::thread::sleep((self.next - now).min(STOP_POLL));
        }
        self.next += delay;
        true
    }
}

pub(super) struct Sender {
    pub socket: UdpSocket,
    pub jobs: Arc<StreamJobs>,
    pub stop: Arc<AtomicBool>,
    pub ring_len: usize,
}

impl Sender {
    pub fn run(self, m: &Metrics) {
        let mut ring: VecDeque<(Block, SocketAddr, u32)> = VecDeque::with_capacity(self.ring_len);
        let mut block_id: u16 = 0;
        let mut pacer = Pacer { next: Instant::now() };
        // Packets that resends may still send before the next frame.
        let mut budget: u32 = 0;
        let send = |p: &[u8], dest: SocketAddr| match self.socket.send_to(p, dest) {
            Ok(n) => {
                m.packets_sent.inc();
                m.bytes_sent.add(n as u64);
            }
            Err(e) => {
                m.send_errors.inc();
                tracing::debug!(%dest, "GVSP packet not sent: {e}");
            }
        };
        loop {
            if self.stop.load(Ordering::Acquire) {
                return;
            }
            match self.jobs.next(STOP_POLL) {
                Next::Stopped => return,
                Next::Idle => {}
                Next::Frame(FrameJob { frame, settings, channel }) => {
                    let id = gvsp::next_block_id(block_id);
                    let Some(block) = build_block(&frame, &settings, id, m) else { continue };
                    block_id = id;
                    let dest = SocketAddr::V4(SocketAddrV4::new(channel.destination, channel.host_port));
                    let delay = Duration::from_nanos(u64::from(channel.packet_delay_ticks));
                    pacer.start_block();
                    let packets = block.packet_count(channel.packet_size);
                    for pid in 0..packets {
                        if !pacer.wait(delay, &self.stop) {
                            m.dropped_stopped.inc();
                            return;
                        }
                        if let Some(p) = block.packet(pid, channel.packet_size, gvsp::STATUS_SUCCESS) {
                            send(&p, dest);
                        }
                    }
                    m.frames_sent.inc();
                    if frame.meta.pose_arrival_unix_ns > 0 {
                        m.latency.record(unix_ns_now().saturating_sub(frame.meta.pose_arrival_unix_ns));
                    }
                    budget = packets;
                    if ring.len() == self.ring_len {
                        ring.pop_front();
                    }
                    ring.push_back((block, dest, channel.packet_size));
                }
                Next::Resend(ResendJob { block_id: wanted, first, last }) => {
                    let found = ring.iter().find(|(b, _, _)| u64::from(b.block_id) == wanted);
                    match found {
                        Some((b, dest, size)) => {
                            let end = last.min(b.packet_count(*size) - 1);
                            let n = end.saturating_sub(first).saturating_add(1);
                            if first > end || n > budget {
                                m.resend_budget.inc();
                                tracing::debug!(block = wanted, first, last, budget, "resend over budget: not served");
                                continue;
                            }
                            budget -= n;
                            for pid in first..=end {
                                if let Some(p) = b.packet(pid, *size, gvsp::STATUS_RESEND) {
                                    send(&p, *dest);
                                    m.packets_resent.inc();
                                }
                            }
                        }
                        None => {
                            m.resend_unavailable.inc();
                            tracing::debug!(block = wanted, first, last, "resend requested for a block no longer kept");
                            if budget > 0
                                && let Some((_, dest, _)) = ring.back()
                            {
                                budget -= 1;
                                send(&gvsp::unavailable_packet(wanted as u16, first), *dest);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The block for `frame` as `settings` ask: pixels in the client's ROI and format, then
/// the enabled chunks. None (counted) when the frame cannot be converted.
fn build_block(frame: &EncodedFrame, settings: &CameraSettings, block_id: u16, m: &Metrics) -> Option<Block> {
    let mut data = match pixel::convert(frame, settings.window(), settings.pixel_format) {
        Ok(d) => d,
        Err(e) => {
            m.dropped_convert.inc();
            tracing::warn!("GigE stream: {e}");
            return None;
        }
    };
    let timestamp = frame.meta.pose_t_ns;
    let mut payload_type = gvsp::PAYLOAD_IMAGE;
    if settings.chunk_mode {
        let sfnc = SfncValues {
            timestamp,
            exposure_us: chunk::integration_ns(frame.meta.integration_s) as f64 / 1e3,
            frame_id: u64::from(block_id),
        };
        chunk::append_chunks(&mut data, &frame.meta, settings.chunks, &sfnc);
        if settings.chunks.contains(ChunkKind::HilcamTruth)
            && let Some(t) = frame.truth.as_ref().filter(|t| t.channels == settings.truth)
        {
            // Whole-array frames are cropped at the offsets, as the pixels.
            let w = settings.window();
            let w = if frame.roi.is_some() { Window { x: 0, y: 0, ..w } } else { w };
            chunk::append_truth_chunks(&mut data, t, w);
        }
        payload_type |= gvsp::PAYLOAD_CHUNK_FLAG;
    }
    Some(Block {
        block_id,
        timestamp,
        pixel_format: settings.pixel_format.pfnc(),
        width: settings.width,
        height: settings.height,
        offset_x: settings.offset_x,
        offset_y: settings.offset_y,
        payload_type,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pacer_gives_up_a_long_delay_when_stopped() {
        let stop = AtomicBool::new(false);
        let mut p = Pacer { next: Instant::now() };
        p.start_block();
        let delay = Duration::from_secs(3600);
        assert!(p.wait(delay, &stop), "the first packet leaves at once");
        stop.store(true, Ordering::Release);
        let t = Instant::now();
        assert!(!p.wait(delay, &stop));
        assert!(t.elapsed() < STOP_POLL * 2, "{:?}", t.elapsed());
    }
}
