//! Serial (UART, RS-422, USB CDC) pose receiver.
//!
//! The port is read on a blocking thread (the `serialport` crate is
//! synchronous); decoding, validation and counting happen there too, and events
//! go into the tokio channel with `try_send`. If the device disappears (USB
//! unplug, pty closed) the loop counts a device error and reopens the same path
//! with backoff until it is back, without restarting hilcam.

use super::{Backoff, EventSink, InputCounters, InputEvent, run_blocking_until};
use crate::pose::serial::{DecodeEvent, SerialDecoder};
use crate::pose::validate::PoseLimits;
use crate::shutdown::Shutdown;
use serialport::{DataBits, Parity, SerialPort, StopBits};
use std::io::Read;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// Serial receiver settings (defaults: 115 200 baud, 8N1, default limits).
#[derive(Clone, Debug)]
pub struct SerialConfig {
    /// Device path, e.g. `/dev/ttyUSB0` (a stable symlink survives replugging).
    pub path: String,
    /// Baud rate; any rate the driver accepts, up to 4 000 000.
    pub baud: u32,
    /// Data bits (default 8).
    pub data_bits: DataBits,
    /// Parity (default none).
    pub parity: Parity,
    /// Stop bits (default 1).
    pub stop_bits: StopBits,
    /// Validation limits.
    pub limits: PoseLimits,
    /// Reopen backoff.
    pub backoff: Backoff,
}

impl SerialConfig {
    /// 8N1 at `baud` on `path` with default limits.
    pub fn new(path: impl Into<String>, baud: u32) -> Self {
        SerialConfig {
            path: path.into(),
            baud,
            data_bits: DataBits::Eight,
            parity: Parity::None,
            stop_bits: StopBits::One,
            limits: PoseLimits::default(),
            backoff: Backoff::default(),
        }
    }
}

/// Error opening a serial device, naming it.
#[derive(Debug, thiserror::Error)]
#[error("serial device {path} at {baud} baud: {source}")]
pub struct OpenError {
    /// Device path.
    pub path: String,
    /// Requested baud rate.
    pub baud: u32,
    /// Cause.
    #[source]
    pub source: serialport::Error,
}

/// Opens `path` raw with the given line settings and a 50 ms read timeout.
///
/// # Errors
/// [`OpenError`] naming the device.
pub fn open_port(
    path: &str,
    baud: u32,
    data_bits: DataBits,
    parity: Parity,
    stop_bits: StopBits,
) -> Result<serialport::TTYPort, OpenError> {
    serialport::new(path, baud)
        .data_bits(data_bits)
        .parity(parity)
        .stop_bits(stop_bits)
        .flow_control(serialport::FlowControl::None)
        .timeout(Duration::from_millis(50))
        .open_native()
        .map_err(|source| OpenError { path: path.to_string(), baud, source })
}

/// Receives poses from a serial device until `shutdown` resolves or the
/// channel's receiver is dropped. Never returns early on device errors.
pub async fn run_serial(
    cfg: SerialConfig,
    tx: mpsc::Sender<InputEvent>,
    counters: Arc<InputCounters>,
    shutdown: impl std::future::Future,
) {
    let sink = EventSink::new(tx, counters, cfg.limits, format!("serial:{}", cfg.path));
    run_blocking_until(move |stop| serial_loop(&cfg, sink, stop), shutdown).await;
}

/// Opens the device (with backoff) until it works or `stop` is triggered; `opened`
/// counts successful opens so the second and later ones count as reconnects.
pub(crate) fn open_with_retry(
    cfg: &SerialConfig,
    sink: &mut EventSink,
    stop: &Shutdown,
    opened: &mut u64,
) -> Option<serialport::TTYPort> {
    let mut wait = Duration::ZERO;
    loop {
        if stop.is_triggered() || sink.closed() {
            return None;
        }
        match open_port(&cfg.path, cfg.baud, cfg.data_bits, cfg.parity, cfg.stop_bits) {
            Ok(port) => {
                *opened += 1;
                if *opened > 1 {
                    InputCounters::inc(&sink.counters.reconnects);
                    sink.reconnected();
                    tracing::info!(path = %cfg.path, "serial device reconnected");
                } else {
                    tracing::info!(path = %cfg.path, baud = cfg.baud, "serial device open");
                }
                return Some(port);
            }
            Err(e) => {
                InputCounters::inc(&sink.counters.device_errors);
                sink.warn(format_args!("{e}; retrying"));
                wait = cfg.backoff.next(wait);
                if !stop.sleep(wait) {
                    return None;
                }
            }
        }
    }
}

fn serial_loop(cfg: &SerialConfig, mut sink: EventSink, stop: &Shutdown) {
    let mut opened = 0;
    let mut buf = vec![0u8; 4096];
    while let Some(mut port) = open_with_retry(cfg, &mut sink, stop, &mut opened) {
        // A fresh connection starts mid-stream: drop any partial frame.
        let mut dec = SerialDecoder::new();
        loop {
            if stop.is_triggered() || sink.closed() {
                return;
            }
            match port.read(&mut buf) {
                Ok(0) => {
                    InputCounters::inc(&sink.counters.device_errors);
                    sink.warn(format_args!("serial device {} hung up", cfg.path));
                    break;
                }
                Ok(n) => {
                    let arrival = Instant::now();
                    dec.push(&buf[..n]);
                    while let Some(ev) = dec.next_event() {
                        match ev {
                            DecodeEvent::Message(m) => sink.message(m, arrival),
                            DecodeEvent::Discarded { bytes, reason } => {
                                sink.counters.serial_discard(bytes, reason);
                                sink.warn(format_args!("skipped {bytes} bytes: {reason}"));
                            }
                        }
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    InputCounters::inc(&sink.counters.device_errors);
                    sink.warn(format_args!("serial device {} read error: {e}", cfg.path));
                    break;
                }
            }
        }
        drop(port);
    }
}

/// Current line settings of an open port (for logs and tests).
pub fn describe(port: &dyn SerialPort) -> String {
    format!(
        "{:?} baud {:?} {:?} {:?} {:?}",
        port.name(),
        port.baud_rate().ok(),
        port.data_bits().ok(),
        port.parity().ok(),
        port.stop_bits().ok()
    )
}
