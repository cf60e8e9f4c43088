//! SocketCAN pose receiver (Linux `can0`, `vcan0`, …), fully async.
//!
//! Opens a CAN FD raw socket (it receives classic and FD frames) with all
//! error classes enabled. Error frames are counted; bus-off is logged as an
//! error and counted, and recovery is the driver's automatic restart
//! (`ip link set can0 type can restart-ms 100`): the socket stays open and
//! frames flow again once the controller is back. If the socket itself fails
//! (interface down or removed; also polled in sysfs every 200 ms, since a
//! raw socket does not reliably wake its reader for that) it is reopened with
//! backoff once the interface is up again.

use super::{Backoff, EventSink, InputCounters, InputEvent};
use crate::pose::can::{CanAssembler, CanEvent, CanFrame, CanIds};
use crate::pose::validate::PoseLimits;
use socketcan::{CanAnyFrame, EmbeddedFrame, Frame, SocketOptions};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// Receive buffer asked of the kernel: ~4000 frames of slack when the task is
/// briefly descheduled at high frame rates (the default holds ~200).
const RCVBUF_BYTES: i32 = 4 << 20;
/// How often an idle receiver checks that the interface is still up (the
/// socket alone does not reliably report `ip link set … down`).
const LINK_CHECK: Duration = Duration::from_millis(200);

/// Whether `iface` exists and is administratively up (`IFF_UP` in sysfs).
pub fn iface_up(iface: &str) -> bool {
    std::fs::read_to_string(format!("/sys/class/net/{iface}/flags"))
        .ok()
        .and_then(|f| u32::from_str_radix(f.trim().trim_start_matches("0x"), 16).ok())
        .is_some_and(|flags| flags & 1 != 0)
}

/// Opens the FD-capable raw socket with error frames and a large buffer.
fn open_socket(iface: &str) -> std::io::Result<socketcan::tokio::CanFdSocket> {
    if !iface_up(iface) {
        return Err(std::io::Error::new(std::io::ErrorKind::NotConnected, "interface missing or down"));
    }
    let s = socketcan::tokio::CanFdSocket::open(iface)?;
    s.set_error_filter_accept_all()?;
    // SO_RCVBUFFORCE (root) else SO_RCVBUF (capped by net.core.rmem_max).
    if s.set_socket_option_int(libc::SOL_SOCKET, libc::SO_RCVBUFFORCE, RCVBUF_BYTES).is_err() {
        let _ = s.set_socket_option_int(libc::SOL_SOCKET, libc::SO_RCVBUF, RCVBUF_BYTES);
    }
    Ok(s)
}

/// Linux `CAN_ERR_BUSOFF` error class bit.
const CAN_ERR_BUSOFF: u32 = 0x0000_0040;
/// Linux `CAN_ERR_RESTARTED` error class bit.
const CAN_ERR_RESTARTED: u32 = 0x0000_0100;

/// SocketCAN receiver settings.
#[derive(Clone, Debug)]
pub struct SocketCanConfig {
    /// Interface name, e.g. `can0`, `vcan0`.
    pub iface: String,
    /// hilcam's CAN ids.
    pub ids: CanIds,
    /// Validation limits.
    pub limits: PoseLimits,
    /// Reopen backoff.
    pub backoff: Backoff,
}

impl SocketCanConfig {
    /// Default ids and limits on `iface`.
    pub fn new(iface: impl Into<String>) -> Self {
        SocketCanConfig {
            iface: iface.into(),
            ids: CanIds::default(),
            limits: PoseLimits::default(),
            backoff: Backoff::default(),
        }
    }
}

/// Converts a socketcan frame; `None` for remote and error frames.
pub fn from_socketcan(f: &CanAnyFrame) -> Option<CanFrame> {
    match f {
        CanAnyFrame::Normal(d) => CanFrame::new(d.raw_id(), d.is_extended(), d.data()),
        CanAnyFrame::Fd(d) => CanFrame::new_fd(d.raw_id(), d.is_extended(), d.data(), d.is_brs()),
        CanAnyFrame::Remote(_) | CanAnyFrame::Error(_) => None,
    }
}

/// Converts to a socketcan frame for sending.
pub fn to_socketcan(f: &CanFrame) -> CanAnyFrame {
    let id: socketcan::Id = if f.extended {
        socketcan::ExtendedId::new(f.id).expect("checked").into()
    } else {
        socketcan::StandardId::new(f.id as u16).expect("checked").into()
    };
    if f.fd {
        let flags = if f.brs { socketcan::id::FdFlags::BRS } else { socketcan::id::FdFlags::empty() };
        CanAnyFrame::Fd(socketcan::CanFdFrame::with_flags(id, f.data(), flags).expect("≤ 64"))
    } else {
        CanAnyFrame::Normal(socketcan::CanDataFrame::new(id, f.data()).expect("≤ 8"))
    }
}

/// Receives poses from a SocketCAN interface until `shutdown` resolves or the
/// channel's receiver is dropped. Never returns early on device errors.
pub async fn run_socketcan(
    cfg: SocketCanConfig,
    tx: mpsc::Sender<InputEvent>,
    counters: Arc<InputCounters>,
    shutdown: impl std::future::Future,
) {
    let mut sink = EventSink::new(tx, counters, cfg.limits, format!("can:{}", cfg.iface));
    let mut asm = CanAssembler::new(cfg.ids);
    let mut foreign_seen = 0;
    let mut opened = 0u64;
    let mut wait = Duration::ZERO;
    tokio::pin!(shutdown);
    loop {
        let sock = match open_socket(&cfg.iface) {
            Ok(s) => s,
            Err(e) => {
                InputCounters::inc(&sink.counters.device_errors);
                sink.warn(format_args!("CAN interface {}: {e}; retrying", cfg.iface));
                wait = cfg.backoff.next(wait);
                tokio::select! {
                    _ = &mut shutdown => return,
                    _ = tokio::time::sleep(wait) => continue,
                }
            }
        };
        opened += 1;
        wait = Duration::ZERO;
        if opened > 1 {
            InputCounters::inc(&sink.counters.reconnects);
            sink.reconnected();
            tracing::info!(iface = %cfg.iface, "CAN interface reopened");
        } else {
            tracing::info!(iface = %cfg.iface, "CAN interface open");
        }
        let mut link_check = tokio::time::interval(LINK_CHECK);
        loop {
            let r = tokio::select! {
                _ = &mut shutdown => return,
                r = sock.read_frame() => r,
                _ = link_check.tick() => {
                    if iface_up(&cfg.iface) {
                        continue;
                    }
                    Err(std::io::Error::new(std::io::ErrorKind::NotConnected, "interface went down"))
                }
            };
            if sink.closed() {
                return;
            }
            let frame = match r {
                Ok(f) => f,
                Err(e) => {
                    InputCounters::inc(&sink.counters.device_errors);
                    sink.warn(format_args!("CAN interface {} read error: {e}", cfg.iface));
                    if let Some(CanEvent::Dropped(d)) = asm.flush() {
                        sink.counters.can_drop(d);
                    }
                    break;
                }
            };
            let arrival = Instant::now();
            if let CanAnyFrame::Error(e) = &frame {
                InputCounters::inc(&sink.counters.can_error_frames);
                let bits = e.error_bits();
                if bits & CAN_ERR_BUSOFF != 0 {
                    InputCounters::inc(&sink.counters.can_bus_off);
                    tracing::error!(iface = %cfg.iface, "CAN bus-off (waiting for the controller to restart)");
                } else if bits & CAN_ERR_RESTARTED != 0 {
                    tracing::info!(iface = %cfg.iface, "CAN controller restarted");
                } else {
                    sink.warn(format_args!("CAN error frame, class bits {bits:#x}"));
                }
                continue;
            }
            let Some(f) = from_socketcan(&frame) else {
                InputCounters::inc(&sink.counters.can_foreign_frames);
                continue;
            };
            match asm.push(&f) {
                Some(CanEvent::Message(m)) => sink.message(m, arrival),
                Some(CanEvent::Dropped(d)) => {
                    sink.counters.can_drop(d);
                    sink.warn(format_args!("CAN pose dropped: {d}"));
                }
                None => {}
            }
            let foreign = asm.foreign_frames();
            sink.counters.can_foreign_frames.fetch_add(foreign - foreign_seen, std::sync::atomic::Ordering::Relaxed);
            foreign_seen = foreign;
        }
        tokio::select! {
            _ = &mut shutdown => return,
            _ = tokio::time::sleep(cfg.backoff.min) => {}
        }
    }
}
