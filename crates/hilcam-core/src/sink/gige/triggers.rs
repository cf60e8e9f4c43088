//! Software triggers from a GigE Vision client into the serve loop's inputs: a
//! TriggerSoftware becomes an `InputEvent::Trigger`, the same "render now" a bench
//! sends over serial/CAN, so the frame is rendered from the latest pose (the serve
//! loop renders on triggers with `trigger.mode = "external"`).

use super::GigeDevice;
use crate::link::InputEvent;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;
use tokio::sync::mpsc;

/// Merge the device's software triggers into `inputs`: returns the receiver the
/// scheduler reads. Poses and triggers keep their order within each source; a trigger
/// that finds the merged queue full is dropped, counted and logged.
pub fn merge_software_triggers(
    mut inputs: mpsc::Receiver<InputEvent>,
    device: &GigeDevice,
    dropped: crate::metrics::Counter,
) -> mpsc::Receiver<InputEvent> {
    let (tx, rx) = mpsc::channel::<InputEvent>(1024);
    // Weak: the merged channel still closes when the inputs end.
    let trigger_tx = tx.downgrade();
    let seq = Arc::new(AtomicU32::new(0));
    device.on_software_trigger(Box::new(move || {
        let seq = seq.fetch_add(1, Ordering::Relaxed);
        let ev = InputEvent::Trigger { seq, t_ns: 0, arrival: Instant::now() };
        let sent = trigger_tx.upgrade().is_some_and(|t| t.try_send(ev).is_ok());
        if !sent {
            dropped.inc();
            tracing::warn!(seq, "GigE Vision software trigger dropped: input queue full");
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
