//! The device's counters (`hilcam_gige_*`, listed in `docs/gige.md`): every command
//! refused, every frame or resend not sent, with its reason.

use super::control::Rejection;
use crate::metrics::{Counter, Histogram, Registry};
use std::sync::Arc;

pub(super) struct Metrics {
    pub commands: Counter,
    /// `hilcam_gige_commands_rejected_total{reason}`, one per [`Rejection`] (in its order).
    rejected: Vec<Counter>,
    pub broadcast_refused: Counter,
    pub heartbeat_expired: Counter,
    pub frames_sent: Counter,
    pub packets_sent: Counter,
    pub bytes_sent: Counter,
    pub send_errors: Counter,
    pub resend_requests: Counter,
    pub packets_resent: Counter,
    pub resend_unavailable: Counter,
    pub resend_queue_full: Counter,
    pub resend_budget: Counter,
    pub pending_acks: Counter,
    pub pending_timeouts: Counter,
    pub pending_overflow: Counter,
    pub pending_wait: Arc<Histogram>,
    pub broadcast_discoveries: Counter,
    pub broadcast_acks: Counter,
    pub receive_errors: Counter,
    pub dropped_not_acquiring: Counter,
    pub dropped_no_stream: Counter,
    pub dropped_untriggered: Counter,
    pub dropped_rate: Counter,
    pub dropped_busy: Counter,
    pub dropped_convert: Counter,
    pub dropped_stopped: Counter,
    pub latency: Arc<Histogram>,
}

impl Metrics {
    pub fn new(r: &Registry) -> Self {
        let dropped = |reason: &str| {
            r.counter(
                "hilcam_gige_frames_dropped_total",
                "Frames not sent on the GigE Vision stream",
                &[("reason", reason)],
            )
        };
        let rejected = |reason: &str| {
            r.counter(
                "hilcam_gige_commands_rejected_total",
                "GVCP commands refused (answered with an error status, or ignored)",
                &[("reason", reason)],
            )
        };
        let resend_dropped = |reason: &str| {
            r.counter(
                "hilcam_gige_resend_dropped_total",
                "PACKETRESEND requests not served (queue full, or over the per-frame budget)",
                &[("reason", reason)],
            )
        };
        Metrics {
            commands: r.counter("hilcam_gige_commands_total", "GVCP commands handled", &[]),
            rejected: Rejection::ALL.iter().map(|c| rejected(c.label())).collect(),
            broadcast_refused: rejected("broadcast"),
            heartbeat_expired: r.counter(
                "hilcam_gige_heartbeat_expired_total",
                "Controllers released after their heartbeat timed out",
                &[],
            ),
            frames_sent: r.counter("hilcam_gige_frames_sent_total", "Blocks sent on the GigE Vision stream", &[]),
            packets_sent: r.counter("hilcam_gige_packets_sent_total", "GVSP packets sent (resends included)", &[]),
            bytes_sent: r.counter("hilcam_gige_bytes_sent_total", "GVSP bytes sent (UDP payload)", &[]),
            send_errors: r.counter("hilcam_gige_send_errors_total", "GVSP packets the socket refused", &[]),
            resend_requests: r.counter("hilcam_gige_resend_requests_total", "PACKETRESEND commands accepted", &[]),
            packets_resent: r.counter("hilcam_gige_packets_resent_total", "GVSP packets sent again on request", &[]),
            resend_unavailable: r.counter(
                "hilcam_gige_resend_unavailable_total",
                "Resend requests for blocks no longer in the ring",
                &[],
            ),
            resend_queue_full: resend_dropped("queue_full"),
            resend_budget: resend_dropped("budget"),
            pending_acks: r.counter(
                "hilcam_gige_pending_acks_total",
                "PENDING_ACKs sent for writes the renderer applies at its next frame",
                &[],
            ),
            pending_timeouts: r.counter(
                "hilcam_gige_pending_timeouts_total",
                "Pending writes acknowledged at the pending timeout, before a frame showed them",
                &[],
            ),
            pending_overflow: r.counter(
                "hilcam_gige_pending_overflow_total",
                "Slow writes acknowledged at once because the pending acknowledges were at their bound",
                &[],
            ),
            pending_wait: r.histogram(
                "hilcam_gige_pending_wait_seconds",
                "PENDING_ACK to the final acknowledge of the same command",
                &[],
            ),
            broadcast_discoveries: r.counter(
                "hilcam_gige_broadcast_discoveries_total",
                "DISCOVERY_CMDs heard on the discovery (broadcast) addresses",
                &[],
            ),
            broadcast_acks: r.counter(
                "hilcam_gige_broadcast_acks_total",
                "DISCOVERY_ACK copies broadcast for clients that allow it",
                &[],
            ),
            receive_errors: r.counter("hilcam_gige_receive_errors_total", "GVCP socket receive errors", &[]),
            dropped_not_acquiring: dropped("not_acquiring"),
            dropped_no_stream: dropped("no_stream_channel"),
            dropped_untriggered: dropped("no_trigger"),
            dropped_rate: dropped("frame_rate"),
            dropped_busy: dropped("stream_busy"),
            dropped_convert: dropped("convert"),
            dropped_stopped: dropped("stopped"),
            latency: r.histogram(
                "hilcam_gige_latency_seconds",
                "Pose arrival to the last GVSP packet of its frame sent",
                &[],
            ),
        }
    }

    pub fn rejected(&self, class: Rejection) -> &Counter {
        let i = Rejection::ALL.iter().position(|c| *c == class).expect("every class has a counter");
        &self.rejected[i]
    }
}
