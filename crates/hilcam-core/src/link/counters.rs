//! Shared input counters: plain atomics behind an `Arc`, written by the
//! transport tasks, read by whoever prints or exports them.

use crate::pose::can::GroupDrop;
use crate::pose::serial::Malformed;
use crate::pose::slcan::SlcanError;
use crate::pose::validate::Rejection;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

macro_rules! counters {
    ($( $(#[$doc:meta])* $field:ident ),* $(,)?) => {
        /// Counters of one or more input transports (all monotonic).
        ///
        /// Export with [`InputCounters::for_each`] or
        /// [`InputCounters::to_prometheus`]; names are `hilcam_input_<field>_total`.
        #[derive(Debug, Default)]
        pub struct InputCounters {
            $( $(#[$doc])* pub $field: AtomicU64, )*
            /// Poses rejected by validation, indexed like [`Rejection::ALL`].
            pub rejected: [AtomicU64; Rejection::ALL.len()],
        }

        impl InputCounters {
            fn scalars(&self) -> [(&'static str, &AtomicU64); [$(stringify!($field)),*].len()] {
                [ $( (stringify!($field), &self.$field), )* ]
            }
        }
    };
}

counters! {
    /// Poses that passed validation and were sent on.
    accepted,
    /// Trigger messages received.
    triggers,
    /// Heartbeat messages received.
    heartbeats,
    /// Serial: bytes skipped while resynchronising.
    discarded_bytes,
    /// Serial: resynchronisations (each skips ≥ 1 byte).
    resyncs,
    /// Serial: frames with a CRC-32C mismatch.
    crc_failures,
    /// Serial: frames with a bad version, type, length or flags.
    malformed_frames,
    /// CAN: pose groups dropped for a missing frame.
    groups_missing_frame,
    /// CAN: pose groups dropped for frames of different groups mixed.
    groups_mixed,
    /// CAN: pose groups dropped for a duplicated frame.
    groups_duplicate,
    /// CAN: pose groups dropped for a group CRC-16 mismatch.
    groups_crc,
    /// CAN: hilcam frames with a bad length or flags.
    can_malformed,
    /// CAN: frames on other ids (normal on a shared bus).
    can_foreign_frames,
    /// CAN: error frames received.
    can_error_frames,
    /// CAN: bus-off reports.
    can_bus_off,
    /// slcan: lines that are not valid slcan.
    slcan_bad_lines,
    /// slcan: commands the adapter rejected (BEL).
    slcan_nacks,
    /// Device open/read/write failures.
    device_errors,
    /// Successful reopenings after a device failure.
    reconnects,
    /// Events dropped because the consumer's channel was full.
    channel_full,
}

impl InputCounters {
    /// A fresh set of zeroed counters.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds 1 to `c`.
    pub fn inc(c: &AtomicU64) {
        c.fetch_add(1, Relaxed);
    }

    /// Counts a validation rejection.
    pub fn reject(&self, r: Rejection) {
        let i = Rejection::ALL.iter().position(|x| *x == r).expect("listed");
        Self::inc(&self.rejected[i]);
    }

    /// Rejections so far for `r`.
    pub fn rejected(&self, r: Rejection) -> u64 {
        let i = Rejection::ALL.iter().position(|x| *x == r).expect("listed");
        self.rejected[i].load(Relaxed)
    }

    /// All rejections so far.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.iter().map(|c| c.load(Relaxed)).sum()
    }

    /// Counts a serial resync of `bytes` bytes.
    pub fn serial_discard(&self, bytes: usize, reason: Malformed) {
        self.discarded_bytes.fetch_add(bytes as u64, Relaxed);
        Self::inc(&self.resyncs);
        match reason {
            Malformed::NoSync => {}
            Malformed::Crc { .. } => Self::inc(&self.crc_failures),
            _ => Self::inc(&self.malformed_frames),
        }
    }

    /// Counts a dropped CAN group or malformed hilcam CAN frame.
    pub fn can_drop(&self, d: GroupDrop) {
        Self::inc(match d {
            GroupDrop::MissingFrame => &self.groups_missing_frame,
            GroupDrop::MixedSequence => &self.groups_mixed,
            GroupDrop::DuplicateFrame => &self.groups_duplicate,
            GroupDrop::Crc => &self.groups_crc,
            GroupDrop::BadLength(_) | GroupDrop::BadFlags(_) => &self.can_malformed,
        });
    }

    /// Counts a bad slcan line.
    pub fn slcan_error(&self, _e: SlcanError) {
        Self::inc(&self.slcan_bad_lines);
    }

    /// Calls `f(name, labels, value)` for every counter, in a stable order.
    /// `labels` is Prometheus label text without braces (`reason="too_far"`)
    /// or empty.
    pub fn for_each(&self, mut f: impl FnMut(&str, &str, u64)) {
        for (name, c) in self.scalars() {
            f(&format!("hilcam_input_{name}_total"), "", c.load(Relaxed));
        }
        for (r, c) in Rejection::ALL.iter().zip(&self.rejected) {
            let label = format!("reason=\"{}\"", r.as_str());
            f("hilcam_input_rejected_total", &label, c.load(Relaxed));
        }
    }

    /// Prometheus text exposition (counter type lines included).
    pub fn to_prometheus(&self) -> String {
        let mut out = String::new();
        let mut last = String::new();
        self.for_each(|name, labels, v| {
            if name != last {
                out.push_str(&format!("# TYPE {name} counter\n"));
                last = name.to_string();
            }
            if labels.is_empty() {
                out.push_str(&format!("{name} {v}\n"));
            } else {
                out.push_str(&format!("{name}{{{labels}}} {v}\n"));
            }
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prometheus_lists_every_counter_once_with_values() {
        let c = InputCounters::new();
        InputCounters::inc(&c.accepted);
        c.reject(Rejection::TooFar);
        c.reject(Rejection::TooFar);
        c.serial_discard(5, Malformed::Crc { got: 0, computed: 1 });
        let text = c.to_prometheus();
        assert!(text.contains("hilcam_input_accepted_total 1\n"));
        assert!(text.contains("hilcam_input_rejected_total{reason=\"too_far\"} 2\n"));
        assert!(text.contains("hilcam_input_rejected_total{reason=\"non_finite\"} 0\n"));
        assert!(text.contains("hilcam_input_discarded_bytes_total 5\n"));
        assert!(text.contains("hilcam_input_crc_failures_total 1\n"));
        assert_eq!(text.matches("# TYPE hilcam_input_rejected_total").count(), 1);
        let mut n = 0;
        c.for_each(|_, _, _| n += 1);
        assert_eq!(n, 20 + Rejection::ALL.len());
    }
}
