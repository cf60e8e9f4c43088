//! The configured pose input, started as a task feeding the scheduler's channel.

use super::config::{InputConfig, SlcanInput, SocketcanInput, TrajectoryInput};
use crate::link::serial::SerialConfig;
use crate::link::slcan::SlcanConfig;
use crate::link::socketcan::SocketCanConfig;
use crate::link::{EventSink, InputCounters, InputEvent};
use crate::pose::Message;
use crate::pose::can::CanIds;
use crate::pose::trajectory::{Trajectory, TrajectorySample};
use crate::pose::validate::PoseLimits;
use crate::shutdown::Shutdown;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// Events that fit in the channel before a transport starts dropping (and counting) them.
const CHANNEL_DEPTH: usize = 1024;

/// Start the input `cfg` describes; its events arrive on the returned channel until
/// `shutdown` (`None` task for `kind = "none"`: the channel is closed at once).
/// Start the configured input. `fill_rates`: the camera integrates over its exposure, so
/// trajectory rows without rates get them from their neighbours
/// ([`crate::pose::rates::fill_missing_rates`]). `limits`: the scene's pose gate
/// (`Scene::pose_limits`: its `[limits]` range and its planet).
pub fn start(
    cfg: &InputConfig,
    counters: Arc<InputCounters>,
    shutdown: &Shutdown,
    fill_rates: bool,
    limits: PoseLimits,
) -> anyhow::Result<(mpsc::Receiver<InputEvent>, Option<JoinHandle<()>>)> {
    let (tx, rx) = mpsc::channel::<InputEvent>(CHANNEL_DEPTH);
    let stop = shutdown.clone().wait_owned();
    let task = match cfg {
        InputConfig::Serial(i) => {
            let sc = SerialConfig { limits, ..SerialConfig::new(i.device.clone(), i.baud) };
            Some(tokio::spawn(crate::link::serial::run_serial(sc, tx, counters, stop)))
        }
        InputConfig::Slcan(i) => {
            let mut sc = slcan_config(i)?;
            sc.serial.limits = limits;
            Some(tokio::spawn(async move {
                if let Err(e) = crate::link::slcan::run_slcan(sc, tx, counters, stop).await {
                    tracing::error!("{e}");
                }
            }))
        }
        InputConfig::Socketcan(i) => {
            let sc = SocketCanConfig { limits, ..socketcan_config(i)? };
            Some(tokio::spawn(crate::link::socketcan::run_socketcan(sc, tx, counters, stop)))
        }
        InputConfig::Trajectory(i) => {
            let TrajectoryInput { file, speed } = i;
            let mut samples = Trajectory::load(file)?;
            if fill_rates {
                crate::pose::rates::fill_missing_rates(&mut samples);
            }
            let gate = EventSink::new(tx, counters, limits, format!("trajectory {}", file.display()));
            Some(tokio::spawn(replay_trajectory(samples, *speed, gate, stop)))
        }
        InputConfig::None {} => None,
    };
    Ok((rx, task))
}

fn can_ids(base: Option<u32>, extended: bool) -> anyhow::Result<CanIds> {
    Ok(CanIds::new(base.unwrap_or(CanIds::DEFAULT_BASE), extended)?)
}

fn slcan_config(i: &SlcanInput) -> anyhow::Result<SlcanConfig> {
    let serial = SerialConfig::new(i.device.clone(), i.baud);
    let ids = can_ids(i.can_base, i.can_extended)?;
    Ok(SlcanConfig { serial, bitrate: i.bitrate, listen_only: false, ids })
}

fn socketcan_config(i: &SocketcanInput) -> anyhow::Result<SocketCanConfig> {
    let mut sc = SocketCanConfig::new(i.iface.clone());
    sc.ids = can_ids(i.can_base, i.can_extended)?;
    Ok(sc)
}

/// Feed a trajectory's poses at their recorded timing (× `speed`) into the input channel
/// through the same pose gate, counters and warnings as a live link: a row the gate
/// refuses is counted under its reason and logged, and the rows after it still render.
async fn replay_trajectory(
    samples: Vec<TrajectorySample>,
    speed: f64,
    mut gate: EventSink,
    stop: impl std::future::Future,
) {
    tokio::pin!(stop);
    let t0 = tokio::time::Instant::now();
    let first = samples.first().map_or(0.0, |s| s.time_s);
    for (k, s) in samples.iter().enumerate() {
        // Capped (at ~30 years) so that absurd times and speeds wait rather than overflow.
        let due = t0 + Duration::from_secs_f64(((s.time_s - first) / speed).clamp(0.0, 1e9));
        tokio::select! {
            _ = tokio::time::sleep_until(due) => {}
            _ = &mut stop => return,
        }
        gate.message(Message::Pose(s.to_pose(k as u32)), std::time::Instant::now());
    }
}
