//! `hilcam recv`: the reference frame stream client.

use anyhow::Context;
use hilcam_core::scene::file::parse_name;
use hilcam_core::sink::client::{LatencyStats, RecvOptions, receive};
use hilcam_core::sink::recorder::ImageFormat;
use std::net::SocketAddr;
use std::path::PathBuf;

/// Receive frames from a `hilcam serve` stream, verify them, optionally save them.
#[derive(clap::Args, Debug)]
pub struct RecvArgs {
    /// Stream address (host:port).
    #[arg(long, default_value = "127.0.0.1:5600")]
    pub connect: SocketAddr,
    /// Save frames to this directory as frame_<seq>.<ext>.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Exit after this many frames (default: when the server closes).
    #[arg(long)]
    pub count: Option<u64>,
    /// Image format for --out.
    #[arg(long, value_parser = parse_name::<ImageFormat>, default_value = "png")]
    pub format: ImageFormat,
}

pub fn run(args: RecvArgs) -> anyhow::Result<()> {
    let rt =
        tokio::runtime::Builder::new_current_thread().enable_all().build().context("starting the tokio runtime")?;
    let opts = RecvOptions { out_dir: args.out, count: args.count, format: args.format, ..RecvOptions::default() };
    let s = rt.block_on(receive(args.connect, opts))?;
    println!(
        "frames {} ({} MB) in {:.3} s: {:.2} frames/s",
        s.frames,
        s.bytes as f64 / 1e6,
        s.elapsed.as_secs_f64(),
        s.fps
    );
    println!(
        "frame_seq {}..{}: {} gaps, {} frames missing, {} payload CRC errors{}",
        s.seqs.first().map_or("-".into(), |v| v.to_string()),
        s.seqs.last().map_or("-".into(), |v| v.to_string()),
        s.gaps,
        s.missing,
        s.payload_crc_errors,
        if s.truncated { ", last frame truncated" } else { "" }
    );
    print_latency("emit -> receive", &s.emit_to_recv);
    print_latency("pose arrival -> receive", &s.pose_to_recv);
    Ok(())
}

fn print_latency(what: &str, l: &LatencyStats) {
    if l.count == 0 {
        return;
    }
    let ms = |ns: u64| ns as f64 / 1e6;
    println!(
        "latency {what} (same-host clock): p50 {:.3} ms, p95 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        ms(l.p50_ns),
        ms(l.p95_ns),
        ms(l.p99_ns),
        ms(l.max_ns)
    );
}
