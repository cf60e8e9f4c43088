//! The GVSP sender: one std thread owns the stream socket, converts each frame to the
//! client's ROI and format, packetises it, paces the packets as a link of the configured
//! speed carries them plus the negotiated delay, keeps a bounded ring of recent blocks
//! and answers resend requests from it — between the packets of the frame in flight —
//! within a budget of one block's packets per frame sent (`stream_jobs.rs`). It stops
//! within [`STOP_POLL`] of the device's [`Shutdown`], even mid-block.

use super::chunk::{self, ChunkKind, SfncValues};
use super::gvsp::{self, Block};
use super::metrics::Metrics;
use super::pixel;
use super::registers::{CameraSettings, StreamChannel};
use super::stream_jobs::{Jobs, Next};
use crate::frame::{EncodedFrame, unix_ns_now};
use crate::render::camera::Window;
use crate::shutdown::Shutdown;
use std::collections::VecDeque;
use std::net::{SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest the thread sleeps between two looks at the stop signal.
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

/// Bytes a GVSP packet occupies on an Ethernet link beyond its UDP payload: IPv4 and UDP
/// headers (28), Ethernet header and FCS (18), preamble and start delimiter (8) and the
/// inter-frame gap (12).
pub const WIRE_OVERHEAD: u64 = 28 + 18 + 8 + 12;

/// How long a packet of `payload` UDP bytes occupies a link of `link_bps` bits/s.
pub fn wire_time(payload: usize, link_bps: u64) -> Duration {
    Duration::from_nanos((payload as u64 + WIRE_OVERHEAD) * 8 * 1_000_000_000 / link_bps.max(1))
}

/// Paces packets as a link of `link_bps` carries them, plus the client's inter-packet
/// delay (GevSCPD): a packet's slot is its wire time and the delay after it, and the next
/// packet starts when the slot ends. The schedule is absolute, so the mean rate is exact;
/// the thread sleeps only when more than [`Pacer::SLACK`] ahead of it, so packets leave in
/// bursts of at most that much link time, and a thread that fell behind (a loaded machine)
/// catches up by at most [`Pacer::SLACK`]: it never sends faster than the link for longer.
struct Pacer {
    next: Instant,
    link_bps: u64,
}

impl Pacer {
    const SLACK: Duration = Duration::from_micros(200);

    fn new(link_bps: u64) -> Self {
        Pacer { next: Instant::now(), link_bps }
    }

    /// Wait for the next packet's slot; false when `stop` was triggered meanwhile.
    fn wait(&mut self, stop: &Shutdown) -> bool {
        loop {
            let now = Instant::now();
            if self.next <= now + Self::SLACK {
                // Behind schedule: forget what was lost beyond the slack (no long burst).
                self.next = self.next.max(now.checked_sub(Self::SLACK).unwrap_or(now));
                return true;
            }
            if stop.is_triggered() {
                return false;
            }
            std::thread::sleep((self.next - now).min(STOP_POLL));
        }
    }

    /// A packet of `payload` bytes went out in the current slot; `delay` (GevSCPD) follows.
    fn sent(&mut self, payload: usize, delay: Duration) {
        self.next += wire_time(payload, self.link_bps) + delay;
    }
}

/// A block kept for resends, with where and how it was sent.
struct Kept {
    block: Block,
    dest: SocketAddr,
    packet_size: u32,
    delay: Duration,
}

pub(super) struct Sender {
    pub socket: UdpSocket,
    pub jobs: Arc<StreamJobs>,
    pub stop: Shutdown,
    pub ring_len: usize,
    /// The simulated link's speed, bits/s (`[output.gige] link_mbps`).
    pub link_bps: u64,
}

impl Sender {
    fn send(&self, p: &[u8], dest: SocketAddr, m: &Metrics) {
        match self.socket.send_to(p, dest) {
            Ok(n) => {
                m.packets_sent.inc();
                m.bytes_sent.add(n as u64);
            }
            Err(e) => {
                m.send_errors.inc();
                tracing::debug!(%dest, "GVSP packet not sent: {e}");
            }
        }
    }

    pub fn run(self, m: &Metrics) {
        let mut ring: VecDeque<Kept> = VecDeque::with_capacity(self.ring_len);
        let mut block_id: u16 = 0;
        let mut pacer = Pacer::new(self.link_bps);
        // Packets resends may still send: one block's worth per frame sent.
        let mut budget: u32 = 0;
        loop {
            if self.stop.is_triggered() {
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
                    let size = channel.packet_size;
                    let packets = block.packet_count(size);
                    // Kept from its first packet on, so a resend of a packet lost early in
                    // this block is served while the rest of it goes out.
                    if ring.len() == self.ring_len {
                        ring.pop_front();
                    }
                    ring.push_back(Kept { block, dest, packet_size: size, delay });
                    budget = packets;
                    for pid in 0..packets {
                        // Resend requests go between this frame's packets: a receiver's
                        // packet timeout does not wait for the frame in flight to finish.
                        while let Some(r) = self.jobs.take_resend() {
                            if !self.resend(&ring, r, &mut budget, &mut pacer, m) {
                                m.dropped_stopped.inc();
                                return;
                            }
                        }
                        if !pacer.wait(&self.stop) {
                            m.dropped_stopped.inc();
                            return;
                        }
                        let kept = ring.back().expect("pushed above");
                        if let Some(p) = kept.block.packet(pid, size, gvsp::STATUS_SUCCESS) {
                            self.send(&p, dest, m);
                            pacer.sent(p.len(), delay);
                        }
                    }
                    m.frames_sent.inc();
                    if frame.meta.pose_arrival_unix_ns > 0 {
                        m.latency.record(unix_ns_now().saturating_sub(frame.meta.pose_arrival_unix_ns));
                    }
                }
                Next::Resend(r) => {
                    if !self.resend(&ring, r, &mut budget, &mut pacer, m) {
                        return;
                    }
                }
            }
        }
    }

    /// Answer one resend request from `ring`, paced like any packet, within `budget`;
    /// false when stopped meanwhile.
    fn resend(&self, ring: &VecDeque<Kept>, r: ResendJob, budget: &mut u32, pacer: &mut Pacer, m: &Metrics) -> bool {
        let ResendJob { block_id: wanted, first, last } = r;
        let Some(k) = ring.iter().find(|k| u64::from(k.block.block_id) == wanted) else {
            m.resend_unavailable.inc();
            tracing::debug!(block = wanted, first, last, "resend requested for a block no longer kept");
            if *budget > 0
                && let Some(k) = ring.back()
            {
                *budget -= 1;
                self.send(&gvsp::unavailable_packet(wanted as u16, first), k.dest, m);
            }
            return true;
        };
        let end = last.min(k.block.packet_count(k.packet_size) - 1);
        let n = end.saturating_sub(first).saturating_add(1);
        if first > end || n > *budget {
            m.resend_budget.inc();
            tracing::debug!(block = wanted, first, last, budget = *budget, "resend over budget: not served");
            return true;
        }
        *budget -= n;
        for pid in first..=end {
            if !pacer.wait(&self.stop) {
                return false;
            }
            if let Some(p) = k.block.packet(pid, k.packet_size, gvsp::STATUS_RESEND) {
                m.packets_resent.inc();
                self.send(&p, k.dest, m);
                pacer.sent(p.len(), k.delay);
            }
        }
        true
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
        let stop = Shutdown::new();
        let mut p = Pacer::new(1_000_000_000);
        assert!(p.wait(&stop), "the first packet leaves at once");
        p.sent(1472, Duration::from_secs(3600));
        stop.trigger();
        let t = Instant::now();
        assert!(!p.wait(&stop));
        assert!(t.elapsed() < STOP_POLL * 2, "{:?}", t.elapsed());
    }

    #[test]
    fn a_full_size_packet_takes_its_wire_time_at_the_link_speed() {
        // 1500-byte IP datagram: 1472 bytes of UDP payload, 1538 bytes on the wire with
        // the Ethernet framing, preamble and gap: 12.304 µs at 1 Gb/s.
        assert_eq!(wire_time(1472, 1_000_000_000), Duration::from_nanos(12_304));
        assert_eq!(wire_time(1472, 10_000_000_000), Duration::from_nanos(1_230));
    }

    #[test]
    fn a_late_pacer_catches_up_by_at_most_its_slack() {
        let stop = Shutdown::new();
        let mut p = Pacer::new(1_000_000_000);
        p.next = Instant::now() - Duration::from_millis(50);
        assert!(p.wait(&stop));
        assert!(Instant::now() - p.next <= Pacer::SLACK + Duration::from_millis(5), "the lost 50 ms are not made up");
    }
}
