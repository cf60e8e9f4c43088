//! The session file of a run (`[record] session`): its header, the writer and its end line.

use super::config::ServeConfig;
use super::governor::Policy;
use super::scheduler::SchedulerSummary;
use crate::link::InputCounters;
use crate::metrics::Registry;
use crate::render::camera::CameraModel;
use crate::render::integrator::RenderSettings;
use crate::session::writer::{SessionStats, SessionWriter};
use crate::session::{EndLine, SessionHeader};
use anyhow::Context;
use std::sync::Arc;

/// The zero of the session file's clocks (monotonic and wall), taken as the run starts.
#[derive(Clone, Copy)]
pub(super) struct SessionClock {
    mono: std::time::Instant,
    unix_ns: u64,
}

impl SessionClock {
    pub fn now() -> Self {
        SessionClock { mono: std::time::Instant::now(), unix_ns: crate::frame::unix_ns_now() }
    }
}

/// Create the session file if the config asks for one.
pub(super) fn start(
    cfg: &ServeConfig,
    camera: &CameraModel,
    settings: &RenderSettings,
    input: &str,
    clock: SessionClock,
    registry: &Arc<Registry>,
) -> anyhow::Result<Option<SessionWriter>> {
    let Some(path) = cfg.record.as_ref().and_then(|r| r.session.as_ref()) else { return Ok(None) };
    let mut header = header(cfg, camera, settings, input);
    header.start_unix_ns = clock.unix_ns;
    Ok(Some(SessionWriter::start(path, &header, clock.mono, input, registry)?))
}

/// Write the end line and close the file.
pub(super) async fn finish(
    writer: Option<SessionWriter>,
    counters: &InputCounters,
    summary: &SchedulerSummary,
) -> anyhow::Result<Option<SessionStats>> {
    let Some(w) = writer else { return Ok(None) };
    let end = end_line(counters, summary);
    let stats = tokio::task::spawn_blocking(move || w.finish(end)).await.context("session writer")??;
    if stats.dropped > 0 {
        tracing::warn!(file = %stats.path.display(), dropped = stats.dropped, "session lines were dropped");
    }
    Ok(Some(stats))
}

/// The session file's first line: how this server renders.
fn header(cfg: &ServeConfig, camera: &CameraModel, settings: &RenderSettings, input: &str) -> SessionHeader {
    let lower = |v: &dyn std::fmt::Debug| format!("{v:?}").to_lowercase();
    SessionHeader {
        version: crate::session::SESSION_VERSION,
        hilcam: env!("CARGO_PKG_VERSION").to_string(),
        start_unix_ns: 0,
        scene: std::fs::canonicalize(&cfg.scene).unwrap_or(cfg.scene.clone()).display().to_string(),
        width_setting: cfg.width,
        width: camera.width,
        height: camera.height,
        settings: settings.into(),
        trigger: lower(&cfg.trigger.mode),
        extrapolate: cfg.trigger.extrapolate,
        policy: match cfg.governor.policy {
            Policy::FixedQuality => "fixed-quality".into(),
            Policy::FixedRate => "fixed-rate".into(),
        },
        input: input.to_string(),
    }
}

/// The session file's last line: the run's pose and frame counters.
fn end_line(counters: &InputCounters, s: &SchedulerSummary) -> EndLine {
    use crate::pose::validate::Rejection;
    use std::sync::atomic::Ordering::Relaxed;
    EndLine {
        poses_accepted: counters.accepted.load(Relaxed),
        poses_rejected: Rejection::ALL
            .iter()
            .map(|r| (r.as_str().to_string(), counters.rejected(*r)))
            .filter(|(_, n)| *n > 0)
            .collect(),
        input_channel_full: counters.channel_full.load(Relaxed),
        poses_received: s.poses,
        poses_superseded: s.superseded,
        frames: s.frames,
        frames_failed: s.failed,
        fatal: s.fatal.clone(),
        ..EndLine::default()
    }
}
