//! The frame of docs/protocol.md's worked example (tests/serve/stream.rs checks its bytes
//! against a literal, tests/pose/docs_protocol.rs against the page).

use hilcam_core::frame::{Frame, FrameFlags, FrameMeta, PixelFormat};
use hilcam_core::render::film::Pixels;
use hilcam_core::render::integrator::Spp;

/// The worked example of docs/protocol.md.
pub fn example_frame() -> Frame {
    let arrival = 1_700_000_000_000_000_000;
    let meta = FrameMeta {
        frame_seq: 42,
        pose_seq: 7,
        pose_t_ns: 1_000_000_000,
        pose_arrival_unix_ns: arrival,
        emit_unix_ns: arrival + 25_000_000,
        width: 2,
        height: 2,
        format: PixelFormat::Mono8, // replaced from the pixels by Frame::new
        bit_depth: 0,
        spp: Spp::whole(4),
        depth: 3,
        integration_s: 0.001,
        line_time_ns: 0,
        flags: FrameFlags(FrameFlags::LATE | FrameFlags::EXTRAPOLATED),
    };
    let px = Pixels::Mono16 { data: vec![0, 1, 4095, 2048], bits: 12 };
    Frame::new(meta, px).unwrap()
}
