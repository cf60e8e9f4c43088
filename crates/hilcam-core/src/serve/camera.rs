//! The camera transports' control, merged without knowing the transport: each started
//! transport's [`CameraControl`] brings software triggers (merged into the inputs, as a
//! bench's trigger messages), frame requests and frame-rate requests (read by the
//! scheduler). At most one transport may ask for frames and rates: two would disagree.

use crate::link::InputEvent;
use crate::metrics::Registry;
use crate::pipeline::FrameRequest;
use crate::sink::camera_control::{CameraControl, SoftwareTriggers};
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;
use tokio::sync::{mpsc, watch};

/// Events the merged input queue holds before a software trigger is dropped.
const MERGED_DEPTH: usize = 1024;

/// What the scheduler reads of the camera clients (see
/// [`super::scheduler::SchedulerConfig::requests`] and `rate_requests`).
#[derive(Default)]
pub(super) struct CameraRequests {
    pub requests: Option<watch::Receiver<FrameRequest>>,
    pub rate_requests: Option<watch::Receiver<Option<f64>>>,
}

/// Take in a started transport's `control`: its triggers merged into `inputs` (the
/// receiver the scheduler reads is returned), its requests into `into`.
///
/// # Errors
/// A second transport that asks for frames or rates.
pub(super) fn connect(
    control: CameraControl,
    inputs: mpsc::Receiver<InputEvent>,
    registry: &Registry,
    into: &mut CameraRequests,
) -> anyhow::Result<mpsc::Receiver<InputEvent>> {
    let CameraControl { metric, label, requests, rate_requests, triggers } = control;
    if (requests.is_some() && into.requests.is_some()) || (rate_requests.is_some() && into.rate_requests.is_some()) {
        anyhow::bail!("{label}: another camera transport already sets the frames and their rate; serve one");
    }
    into.requests = requests.or(into.requests.take());
    into.rate_requests = rate_requests.or(into.rate_requests.take());
    let Some(triggers) = triggers else { return Ok(inputs) };
    let dropped = registry.counter(
        &format!("hilcam_{metric}_triggers_dropped_total"),
        "Software triggers the input queue refused",
        &[],
    );
    Ok(merge_triggers(inputs, &triggers, dropped, label))
}

/// Merge `triggers` into `inputs`: each becomes an `InputEvent::Trigger`, the same
/// "render now" a bench sends over serial/CAN. Poses and triggers keep their order
/// within each source; a trigger that finds the merged queue full is dropped, counted
/// and logged.
fn merge_triggers(
    mut inputs: mpsc::Receiver<InputEvent>,
    triggers: &SoftwareTriggers,
    dropped: crate::metrics::Counter,
    label: &'static str,
) -> mpsc::Receiver<InputEvent> {
    let (tx, rx) = mpsc::channel::<InputEvent>(MERGED_DEPTH);
    // Weak: the merged channel still closes when the inputs end.
    let trigger_tx = tx.downgrade();
    let seq = Arc::new(AtomicU32::new(0));
    triggers.connect(Box::new(move || {
        let seq = seq.fetch_add(1, Ordering::Relaxed);
        let ev = InputEvent::Trigger { seq, t_ns: 0, arrival: Instant::now() };
        let sent = trigger_tx.upgrade().is_some_and(|t| t.try_send(ev).is_ok());
        if !sent {
            dropped.inc();
            tracing::warn!(seq, "{label} software trigger dropped: input queue full");
        }
    }));
    tokio::spawn(async move {
        while let Some(ev) = inputs.recv().await {
            if tx.send(ev).await.is_err() {
                break;
            }
        }
    });
    rx
}

#[cfg(test)]
mod tests;
