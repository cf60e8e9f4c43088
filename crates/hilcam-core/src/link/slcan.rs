//! slcan (Lawicel ASCII over a serial line) pose receiver, so that a cheap
//! USB-CAN adapter works without `slcand` or kernel CAN support.
//!
//! On every (re)open it sends `C` (close, in case the adapter was left open),
//! `Sn` (bit rate) and `O` (open) or `L` (listen only), then decodes frames and
//! feeds them to the [`CanAssembler`]. Device loss is handled like the serial
//! receiver: count, log, reopen.

use super::serial::{SerialConfig, open_with_retry};
use super::{EventSink, InputCounters, InputEvent, run_blocking_until};
use crate::pose::can::{CanAssembler, CanEvent, CanIds};
use crate::pose::slcan::{SlcanDecoder, SlcanItem, bitrate_code};
use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;
use tokio::sync::mpsc;

/// slcan receiver settings.
#[derive(Clone, Debug)]
pub struct SlcanConfig {
    /// The serial line to the adapter (baud is irrelevant for USB CDC adapters).
    pub serial: SerialConfig,
    /// CAN bit rate to configure (`Sn`); `None` leaves the adapter's setting.
    pub bitrate: Option<u32>,
    /// Open in listen-only mode (`L`) instead of normal (`O`).
    pub listen_only: bool,
    /// hilcam's CAN ids.
    pub ids: CanIds,
}

/// A bit rate slcan has no `Sn` code for.
#[derive(Debug, thiserror::Error)]
#[error("slcan: no Sn code for bit rate {0} bit/s (use 10k,20k,50k,100k,125k,250k,500k,800k,1M)")]
pub struct BitrateError(pub u32);

/// The command lines sent on open: `C`, optional `Sn`, then `O` or `L`.
///
/// # Errors
/// [`BitrateError`] for a bit rate without an `Sn` code.
pub fn open_commands(bitrate: Option<u32>, listen_only: bool) -> Result<String, BitrateError> {
    let mut s = String::from("C\r");
    if let Some(b) = bitrate {
        let code = bitrate_code(b).ok_or(BitrateError(b))?;
        s.push_str(&format!("S{code}\r"));
    }
    s.push_str(if listen_only { "L\r" } else { "O\r" });
    Ok(s)
}

/// Receives poses via an slcan adapter until `shutdown` resolves or the
/// channel's receiver is dropped.
///
/// # Errors
/// Only configuration errors (bad bit rate), before anything is opened.
pub async fn run_slcan(
    cfg: SlcanConfig,
    tx: mpsc::Sender<InputEvent>,
    counters: Arc<InputCounters>,
    shutdown: impl std::future::Future,
) -> Result<(), BitrateError> {
    let init = open_commands(cfg.bitrate, cfg.listen_only)?;
    let sink = EventSink::new(tx, counters, cfg.serial.limits, format!("slcan:{}", cfg.serial.path));
    run_blocking_until(move |stop| slcan_loop(&cfg, &init, sink, stop), shutdown).await;
    Ok(())
}

fn slcan_loop(cfg: &SlcanConfig, init: &str, mut sink: EventSink, stop: &crate::shutdown::Shutdown) {
    let mut opened = 0;
    let mut buf = vec![0u8; 4096];
    let mut asm = CanAssembler::new(cfg.ids);
    let mut foreign_seen = 0;
    while let Some(mut port) = open_with_retry(&cfg.serial, &mut sink, stop, &mut opened) {
        if let Err(e) = port.write_all(init.as_bytes()) {
            InputCounters::inc(&sink.counters.device_errors);
            sink.warn(format_args!("slcan init write failed: {e}"));
            continue;
        }
        let mut dec = SlcanDecoder::new();
        if let Some(CanEvent::Dropped(d)) = asm.flush() {
            sink.counters.can_drop(d);
        }
        loop {
            if stop.is_triggered() || sink.closed() {
                return;
            }
            match port.read(&mut buf) {
                Ok(0) => {
                    InputCounters::inc(&sink.counters.device_errors);
                    sink.warn(format_args!("slcan device {} hung up", cfg.serial.path));
                    break;
                }
                Ok(n) => {
                    let arrival = Instant::now();
                    dec.push(&buf[..n]);
                    while let Some(item) = dec.next_item() {
                        match item {
                            Ok(SlcanItem::Frame(f)) => match asm.push(&f) {
                                Some(CanEvent::Message(m)) => sink.message(m, arrival),
                                Some(CanEvent::Dropped(d)) => {
                                    sink.counters.can_drop(d);
                                    sink.warn(format_args!("CAN pose dropped: {d}"));
                                }
                                None => {}
                            },
                            Ok(SlcanItem::Nack) => {
                                InputCounters::inc(&sink.counters.slcan_nacks);
                                sink.warn(format_args!("slcan adapter rejected a command"));
                            }
                            Ok(SlcanItem::Remote { .. }) => InputCounters::inc(&sink.counters.can_foreign_frames),
                            Ok(SlcanItem::Ack | SlcanItem::Reply) => {}
                            Err(e) => {
                                sink.counters.slcan_error(e);
                                sink.warn(format_args!("bad slcan line: {e}"));
                            }
                        }
                    }
                    let foreign = asm.foreign_frames();
                    sink.counters.can_foreign_frames.fetch_add(foreign - foreign_seen, Ordering::Relaxed);
                    foreign_seen = foreign;
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    InputCounters::inc(&sink.counters.device_errors);
                    sink.warn(format_args!("slcan device {} read error: {e}", cfg.serial.path));
                    break;
                }
            }
        }
    }
}
