//! Side-by-side check that a stalled client costs the publisher and the other clients
//! nothing: the same paced frame stream is run with one reading client, then with that
//! client plus one that never reads, and the ratios are printed.
//!
//!     cargo run --release --example stream_bench -- [frames] [fps] [width]

use hilcam_core::frame::{Frame, FrameFlags, FrameMeta, PixelFormat, unix_ns_now};
use hilcam_core::metrics::{Histogram, Registry};
use hilcam_core::render::film::Pixels;
use hilcam_core::sink::client::{RecvOptions, receive};
use hilcam_core::sink::tcp::{FrameWritten, StreamConfig, StreamServer, WriteHook};
use std::sync::Arc;
use std::time::{Duration, Instant};

struct Run {
    publish_p50: u64,
    publish_p99: u64,
    latency_p50: u64,
    latency_p99: u64,
    received: u64,
    missing: u64,
    stalled_dropped: u64,
}

async fn run(frames: u64, fps: f64, width: u32, stalled: bool) -> Run {
    let reg = Registry::new();
    let latency = Arc::new(Histogram::new());
    let fast_id = 1; // the first client to connect
    let lat = latency.clone();
    let hook: WriteHook = Arc::new(move |e: &FrameWritten| {
        if e.client_id == fast_id {
            lat.record(e.latency_ns());
        }
    });
    let cfg = StreamConfig { bind: "127.0.0.1:0".parse().unwrap(), ..StreamConfig::default() };
    let server = StreamServer::bind(cfg, reg, Some(hook)).await.unwrap();
    let addr = server.local_addr();
    let opts = RecvOptions { progress: None, ..RecvOptions::default() };
    let fast = tokio::spawn(receive(addr, opts));
    while server.client_count() < 1 {
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    let _stall = if stalled {
        let s = tokio::net::TcpStream::connect(addr).await.unwrap();
        while server.client_count() < 2 {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        Some(s)
    } else {
        None
    };
    let n = (width * width) as usize;
    let data: Vec<u16> = (0..n).map(|i| (i % 4096) as u16).collect();
    let publish = Histogram::new();
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / fps));
    for seq in 0..frames {
        tick.tick().await;
        let now = unix_ns_now();
        let meta = FrameMeta {
            frame_seq: seq,
            pose_seq: seq as u32,
            pose_t_ns: seq * 10_000_000,
            pose_arrival_unix_ns: now,
            emit_unix_ns: now,
            width,
            height: width,
            format: PixelFormat::Mono16,
            bit_depth: 12,
            spp: hilcam_core::render::integrator::Spp::ONE,
            depth: 1,
            integration_s: 0.0,
            line_time_ns: 0,
            flags: FrameFlags::default(),
        };
        let px = Pixels::Mono16 { data: data.clone(), bits: 12 };
        let f = Arc::new(Frame::new(meta, px).unwrap().encode());
        let t = Instant::now();
        server.publish(f);
        publish.record_duration(t.elapsed());
    }
    // Let the reading client drain its queue, then close: it finishes at the clean EOF
    // (frames it lost show as `missing`, they never hang the run).
    let queued = |s: &StreamServer| s.clients().iter().find(|c| c.id == fast_id).map_or(0, |c| c.queued);
    while queued(&server) > 0 {
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    let stalled_dropped = server.clients().iter().filter(|c| c.id != fast_id).map(|c| c.dropped).sum();
    server.shutdown().await;
    let summary = fast.await.unwrap().unwrap();
    let (p, l) = (publish.snapshot(), latency.snapshot());
    Run {
        publish_p50: p.quantile(0.5).unwrap(),
        publish_p99: p.quantile(0.99).unwrap(),
        latency_p50: l.quantile(0.5).unwrap_or(0),
        latency_p99: l.quantile(0.99).unwrap_or(0),
        received: summary.frames,
        missing: summary.missing,
        stalled_dropped,
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let args: Vec<String> = std::env::args().collect();
    let frames: u64 = args.get(1).map_or(300, |s| s.parse().unwrap());
    let fps: f64 = args.get(2).map_or(60.0, |s| s.parse().unwrap());
    let width: u32 = args.get(3).map_or(1024, |s| s.parse().unwrap());
    println!(
        "{frames} frames of {width}x{width} Mono16 ({:.1} MB) at {fps} fps, queue depth 2",
        (width * width * 2) as f64 / 1e6
    );
    let a = run(frames, fps, width, false).await;
    let b = run(frames, fps, width, true).await;
    let us = |ns: u64| ns as f64 / 1e3;
    println!("                          1 client   +1 stalled   ratio");
    for (name, x, y) in [
        ("publish() p50 (us)", a.publish_p50, b.publish_p50),
        ("publish() p99 (us)", a.publish_p99, b.publish_p99),
        ("pose->last byte p50 (us)", a.latency_p50, b.latency_p50),
        ("pose->last byte p99 (us)", a.latency_p99, b.latency_p99),
    ] {
        println!("{name:<25} {:>9.1} {:>12.1} {:>7.2}", us(x), us(y), us(y) / us(x));
    }
    println!(
        "reading client: {} / {} frames ({} missing) | {} / {} ({} missing), stalled client dropped {}",
        a.received, frames, a.missing, b.received, frames, b.missing, b.stalled_dropped
    );
}
