//! The events the transports emit, and the shared validate-count-forward step.

use super::InputCounters;
use crate::pose::validate::{PoseLimits, PoseValidator};
use crate::pose::{Message, Pose};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// One validated input, stamped with its wall-clock arrival time (when the
/// transport had the complete message, before validation).
#[derive(Clone, Copy, Debug, PartialEq)]
// A pose (232 bytes with its optional planet centre) moves by value: boxing it would
// allocate per message on the allocation-free input path.
#[allow(clippy::large_enum_variant)]
pub enum InputEvent {
    /// A pose that passed validation (quaternion and sun renormalised).
    Pose {
        /// The pose.
        pose: Pose,
        /// Arrival time.
        arrival: Instant,
    },
    /// "Render now".
    Trigger {
        /// Sender's sequence number (0 over CAN).
        seq: u32,
        /// Simulation time, ns (0 if the link does not carry it).
        t_ns: u64,
        /// Arrival time.
        arrival: Instant,
    },
    /// Sender liveness.
    Heartbeat {
        /// Sender's sequence number.
        seq: u32,
        /// Simulation time, ns (0 over CAN).
        t_ns: u64,
        /// Sender-defined status, 0 = nominal.
        status: u32,
        /// Arrival time.
        arrival: Instant,
    },
}

impl InputEvent {
    /// When the message arrived.
    pub fn arrival(&self) -> Instant {
        match self {
            InputEvent::Pose { arrival, .. }
            | InputEvent::Trigger { arrival, .. }
            | InputEvent::Heartbeat { arrival, .. } => *arrival,
        }
    }
}

/// Validation + counting + forwarding, shared by all receivers.
pub(crate) struct EventSink {
    tx: mpsc::Sender<InputEvent>,
    pub counters: Arc<InputCounters>,
    validator: PoseValidator,
    source: String,
    last_warn: Option<Instant>,
    suppressed: u64,
}

impl EventSink {
    pub fn new(tx: mpsc::Sender<InputEvent>, counters: Arc<InputCounters>, limits: PoseLimits, source: String) -> Self {
        EventSink { tx, counters, validator: PoseValidator::new(limits), source, last_warn: None, suppressed: 0 }
    }

    /// The consumer went away: the transport should stop.
    pub fn closed(&self) -> bool {
        self.tx.is_closed()
    }

    /// A new connection may be a restarted sender: forget its last timestamp.
    pub fn reconnected(&mut self) {
        self.validator.reset_time();
    }

    /// Logs a warning at most once per second per source (counts carry the rest).
    pub fn warn(&mut self, what: std::fmt::Arguments<'_>) {
        let now = Instant::now();
        if self.last_warn.is_none_or(|t| now.duration_since(t) >= Duration::from_secs(1)) {
            tracing::warn!(source = %self.source, suppressed = self.suppressed, "{what}");
            self.last_warn = Some(now);
            self.suppressed = 0;
        } else {
            tracing::debug!(source = %self.source, "{what}");
            self.suppressed += 1;
        }
    }

    /// Validates (poses), counts and forwards one decoded message.
    pub fn message(&mut self, msg: Message, arrival: Instant) {
        let c = &self.counters;
        let ev = match msg {
            Message::Pose(p) => match self.validator.check(&p) {
                Ok(pose) => {
                    InputCounters::inc(&c.accepted);
                    InputEvent::Pose { pose, arrival }
                }
                Err(r) => {
                    c.reject(r);
                    let why = crate::pose::validate::describe(&p, r, self.validator.limits());
                    self.warn(format_args!("pose seq {} t_ns {} rejected: {r} ({why})", p.seq, p.t_ns));
                    return;
                }
            },
            Message::Trigger { seq, t_ns } => {
                InputCounters::inc(&c.triggers);
                InputEvent::Trigger { seq, t_ns, arrival }
            }
            Message::Heartbeat { seq, t_ns, status } => {
                InputCounters::inc(&c.heartbeats);
                InputEvent::Heartbeat { seq, t_ns, status, arrival }
            }
        };
        if let Err(mpsc::error::TrySendError::Full(_)) = self.tx.try_send(ev) {
            InputCounters::inc(&self.counters.channel_full);
            self.warn(format_args!("event channel full: event dropped"));
        }
    }
}
