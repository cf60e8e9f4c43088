//! `hilcam send`: replay a trajectory file as live pose messages.

use anyhow::Context;
use hilcam_core::link::send::{SendOptions, SendTarget, open_target, send_trajectory};
use hilcam_core::pose::can::{self, CanIds};
use hilcam_core::pose::trajectory::Trajectory;
use std::path::PathBuf;

/// Arguments of `hilcam send`.
#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("target").required(true).args(["serial", "can", "slcan"])))]
pub struct SendArgs {
    /// Trajectory CSV (see docs/trajectory.md).
    #[arg(long)]
    pub trajectory: PathBuf,
    /// Send serial frames on this tty.
    #[arg(long, value_name = "DEV")]
    pub serial: Option<String>,
    /// Send CAN frames on this SocketCAN interface.
    #[arg(long, value_name = "IFACE")]
    pub can: Option<String>,
    /// Send CAN frames through an slcan adapter on this tty.
    #[arg(long, value_name = "DEV")]
    pub slcan: Option<String>,
    /// Fixed send rate in Hz (latest sample held); default: each sample at its time.
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// Replay speed (simulation s per wall s); `inf` = as fast as the link takes.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Serial baud rate (also the slcan adapter's line).
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// CAN bit rate configured on the slcan adapter.
    #[arg(long, default_value_t = 500_000)]
    pub bitrate: u32,
    /// CAN base id (hex with 0x, or decimal).
    #[arg(long, default_value = "0x300", value_parser = parse_id)]
    pub can_base: u32,
    /// Use 29-bit CAN ids.
    #[arg(long)]
    pub can_extended: bool,
    /// Send each pose as one CAN FD frame instead of a classic group.
    #[arg(long)]
    pub can_fd: bool,
}

fn parse_id(s: &str) -> Result<u32, String> {
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u32::from_str_radix(h, 16),
        None => s.parse(),
    }
    .map_err(|e| format!("bad CAN id `{s}`: {e}"))
}

/// Runs `hilcam send`.
///
/// # Errors
/// Bad trajectory, options or device.
pub fn run(args: SendArgs) -> anyhow::Result<()> {
    let samples = Trajectory::load(&args.trajectory)?;
    let ids = CanIds::new(args.can_base, args.can_extended)?;
    let target = match (&args.serial, &args.can, &args.slcan) {
        (Some(p), _, _) => SendTarget::Serial { path: p.clone(), baud: args.baud },
        (_, Some(i), _) => SendTarget::Can { iface: i.clone() },
        (_, _, Some(p)) => SendTarget::Slcan { path: p.clone(), baud: args.baud, bitrate: Some(args.bitrate) },
        _ => unreachable!("clap requires one target"),
    };
    // A CAN FD frame holds a pose with the planet's centre and at most one rate (a pose
    // with both rates and a planet is 76 of its 64 bytes): refuse rather than switch such
    // poses to classic groups behind the user's back.
    if args.can_fd
        && !matches!(target, SendTarget::Serial { .. })
        && let Some(s) = samples.iter().find(|s| !can::fits_fd(&s.to_pose(0)))
    {
        anyhow::bail!(
            "{}: the sample at {} s has the planet's centre and both rates, 76 bytes that one \
                 CAN FD frame (64) cannot carry; send it as classic CAN groups (without --can-fd) \
                 or on the serial link (docs/protocol.md)",
            args.trajectory.display(),
            s.time_s
        );
    }
    let writer = open_target(&target, ids, args.can_fd)?;
    let opts = SendOptions { rate_hz: args.rate, speed: args.speed };
    // SIGINT, SIGTERM or SIGHUP: stop after the message in hand, report what was sent.
    let shutdown = super::signal::stop_on_signals(super::signal::Again::Ignore)?;
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("tokio runtime")?;
    let stats = rt.block_on(send_trajectory(samples.into(), opts, writer, shutdown.wait_owned()))?;
    tracing::info!(poses = stats.poses, elapsed_s = stats.elapsed.as_secs_f64(), "send finished");
    println!("sent {} poses in {:.3} s", stats.poses, stats.elapsed.as_secs_f64());
    Ok(())
}
