//! The sending side: trajectory replay as live pose messages over serial,
//! slcan or SocketCAN. Used by `hilcam send`, the tests and the demo (which
//! can hand any `std::io::Write`, e.g. one end of a pty pair, to
//! [`SerialWriter`] or [`SlcanWriter`]).

use super::serial::{OpenError, open_port};
use super::slcan::{BitrateError, open_commands};
use super::socketcan::to_socketcan;
use crate::pose::Message;
use crate::pose::can::{CanIds, encode_message};
use crate::pose::serial::encode_frame_into;
use crate::pose::slcan::encode_frame;
use crate::pose::trajectory::{Trajectory, TrajectorySample};
use crate::shutdown::Shutdown;
use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Sending failed.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// Could not open a serial device.
    #[error(transparent)]
    Open(#[from] OpenError),
    /// Bad slcan bit rate.
    #[error(transparent)]
    Bitrate(#[from] BitrateError),
    /// I/O on a device.
    #[error("{device}: {source}")]
    Io {
        /// Device or interface.
        device: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// Bad options.
    #[error("{0}")]
    Options(String),
}

/// Something that transmits protocol messages.
pub trait MessageWriter: Send {
    /// Encodes and transmits one message.
    ///
    /// # Errors
    /// [`SendError::Io`] naming the device.
    fn send(&mut self, msg: &Message) -> Result<(), SendError>;
}

/// Serial frames over any byte sink (tty, pty, TCP, `Vec<u8>`).
pub struct SerialWriter<W> {
    w: W,
    name: String,
    buf: Vec<u8>,
}

impl<W: Write + Send> SerialWriter<W> {
    /// Wraps `w`; `name` appears in errors.
    pub fn new(w: W, name: impl Into<String>) -> Self {
        SerialWriter { w, name: name.into(), buf: Vec::new() }
    }
    /// The wrapped sink.
    pub fn into_inner(self) -> W {
        self.w
    }
}

impl<W: Write + Send> MessageWriter for SerialWriter<W> {
    fn send(&mut self, msg: &Message) -> Result<(), SendError> {
        self.buf.clear();
        encode_frame_into(msg, &mut self.buf);
        self.w
            .write_all(&self.buf)
            .and_then(|_| self.w.flush())
            .map_err(|source| SendError::Io { device: self.name.clone(), source })
    }
}

/// CAN frames as slcan lines over any byte sink.
pub struct SlcanWriter<W> {
    w: W,
    name: String,
    ids: CanIds,
    fd: bool,
}

impl<W: Write + Send> SlcanWriter<W> {
    /// Wraps `w` and sends the open sequence (`C`, `Sn`, `O`).
    ///
    /// # Errors
    /// Bad bit rate or a write error.
    pub fn open(
        mut w: W,
        name: impl Into<String>,
        bitrate: Option<u32>,
        ids: CanIds,
        fd: bool,
    ) -> Result<Self, SendError> {
        let name = name.into();
        w.write_all(open_commands(bitrate, false)?.as_bytes())
            .map_err(|source| SendError::Io { device: name.clone(), source })?;
        Ok(SlcanWriter { w, name, ids, fd })
    }
    /// The wrapped sink.
    pub fn into_inner(self) -> W {
        self.w
    }
}

impl<W: Write + Send> MessageWriter for SlcanWriter<W> {
    fn send(&mut self, msg: &Message) -> Result<(), SendError> {
        let mut s = String::new();
        for f in encode_message(self.ids, msg, self.fd) {
            s.push_str(&encode_frame(&f));
        }
        self.w
            .write_all(s.as_bytes())
            .and_then(|_| self.w.flush())
            .map_err(|source| SendError::Io { device: self.name.clone(), source })
    }
}

/// CAN frames on a SocketCAN interface (blocking socket).
pub struct SocketCanWriter {
    sock: socketcan::CanFdSocket,
    iface: String,
    ids: CanIds,
    fd: bool,
}

impl SocketCanWriter {
    /// Opens `iface`.
    ///
    /// # Errors
    /// [`SendError::Io`] naming the interface.
    pub fn open(iface: &str, ids: CanIds, fd: bool) -> Result<Self, SendError> {
        use socketcan::Socket;
        let sock = socketcan::CanFdSocket::open(iface)
            .map_err(|source| SendError::Io { device: iface.to_string(), source })?;
        Ok(SocketCanWriter { sock, iface: iface.to_string(), ids, fd })
    }
}

impl MessageWriter for SocketCanWriter {
    fn send(&mut self, msg: &Message) -> Result<(), SendError> {
        use socketcan::Socket;
        for f in encode_message(self.ids, msg, self.fd) {
            self.sock
                .write_frame(&to_socketcan(&f))
                .map_err(|source| SendError::Io { device: self.iface.clone(), source })?;
        }
        Ok(())
    }
}

/// Where `hilcam send` sends.
#[derive(Clone, Debug)]
pub enum SendTarget {
    /// Serial frames on a tty at a baud rate (8N1).
    Serial {
        /// Device path.
        path: String,
        /// Baud rate.
        baud: u32,
    },
    /// CAN frames via an slcan adapter.
    Slcan {
        /// Device path.
        path: String,
        /// Serial baud rate.
        baud: u32,
        /// CAN bit rate (`Sn`), or keep the adapter's.
        bitrate: Option<u32>,
    },
    /// CAN frames on a SocketCAN interface.
    Can {
        /// Interface name.
        iface: String,
    },
}

/// 8N1, with a write timeout long enough to ride out a busy receiver but
/// short enough to report a stalled link.
fn open_for_sending(path: &str, baud: u32) -> Result<serialport::TTYPort, SendError> {
    use serialport::{DataBits, Parity, SerialPort, StopBits};
    let mut p = open_port(path, baud, DataBits::Eight, Parity::None, StopBits::One)?;
    p.set_timeout(Duration::from_secs(5)).map_err(|e| SendError::Io { device: path.to_string(), source: e.into() })?;
    Ok(p)
}

/// Opens a target. `ids` and `fd` (pose as one CAN FD frame instead of a
/// classic group) apply to the CAN targets.
///
/// # Errors
/// Open failures naming the device.
pub fn open_target(t: &SendTarget, ids: CanIds, fd: bool) -> Result<Box<dyn MessageWriter>, SendError> {
    Ok(match t {
        SendTarget::Serial { path, baud } => {
            let p = open_for_sending(path, *baud)?;
            Box::new(SerialWriter::new(p, path.clone()))
        }
        SendTarget::Slcan { path, baud, bitrate } => {
            let p = open_for_sending(path, *baud)?;
            Box::new(SlcanWriter::open(p, path.clone(), *bitrate, ids, fd)?)
        }
        SendTarget::Can { iface } => Box::new(SocketCanWriter::open(iface, ids, fd)?),
    })
}

/// Replay pacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SendOptions {
    /// Send at this fixed rate, holding the latest sample (no interpolation);
    /// `None` sends every sample at its own time.
    pub rate_hz: Option<f64>,
    /// Simulation seconds per wall second; `f64::INFINITY` sends as fast as
    /// the link takes.
    pub speed: f64,
}

impl Default for SendOptions {
    fn default() -> Self {
        SendOptions { rate_hz: None, speed: 1.0 }
    }
}

/// What a replay did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SendStats {
    /// Pose messages sent.
    pub poses: u64,
    /// Wall time taken.
    pub elapsed: Duration,
}

/// Replays `samples` through `w`, blocking, until done or `stop` is triggered.
/// Pose `k` gets sequence number `k` and the sample's time (ns).
///
/// # Errors
/// Bad options, or the first write error.
pub fn send_trajectory_blocking(
    samples: &[TrajectorySample],
    opts: &SendOptions,
    w: &mut dyn MessageWriter,
    stop: &Shutdown,
) -> Result<SendStats, SendError> {
    if opts.speed.is_nan() || opts.speed <= 0.0 {
        return Err(SendError::Options(format!("speed must be > 0, got {}", opts.speed)));
    }
    if opts.rate_hz.is_some_and(|r| r.is_nan() || r <= 0.0 || r.is_infinite()) {
        return Err(SendError::Options("rate must be a positive number".into()));
    }
    let (Some(first), Some(last)) = (samples.first(), samples.last()) else {
        return Ok(SendStats::default());
    };
    let t0 = Instant::now();
    let due = |sim_dt: f64| t0 + Duration::from_secs_f64(sim_dt / opts.speed);
    let paced = opts.speed.is_finite();
    let mut seq = 0u32;
    let mut send = |s: &TrajectorySample, seq: &mut u32| -> Result<(), SendError> {
        w.send(&Message::Pose(s.to_pose(*seq)))?;
        *seq = seq.wrapping_add(1);
        Ok(())
    };
    match opts.rate_hz {
        None => {
            for s in samples {
                if paced && !stop.sleep_until(due(s.time_s - first.time_s)) {
                    break;
                }
                if stop.is_triggered() {
                    break;
                }
                send(s, &mut seq)?;
            }
        }
        Some(rate) => {
            for k in 0u64.. {
                let sim_dt = k as f64 / rate;
                let t = first.time_s + sim_dt;
                if t > last.time_s {
                    break;
                }
                if paced && !stop.sleep_until(due(sim_dt)) {
                    break;
                }
                if stop.is_triggered() {
                    break;
                }
                let i = Trajectory::index_at(samples, t).expect("t ≥ first sample");
                send(&samples[i], &mut seq)?;
            }
        }
    }
    Ok(SendStats { poses: seq as u64, elapsed: t0.elapsed() })
}

/// Async wrapper: replays on a blocking thread until done or `shutdown`.
///
/// # Errors
/// As [`send_trajectory_blocking`].
pub async fn send_trajectory(
    samples: Arc<[TrajectorySample]>,
    opts: SendOptions,
    mut w: Box<dyn MessageWriter>,
    shutdown: impl std::future::Future,
) -> Result<SendStats, SendError> {
    let stop = Shutdown::new();
    let for_thread = stop.clone();
    let mut task =
        tokio::task::spawn_blocking(move || send_trajectory_blocking(&samples, &opts, w.as_mut(), &for_thread));
    let joined = tokio::select! {
        r = &mut task => r,
        _ = shutdown => {
            stop.trigger();
            task.await
        }
    };
    joined.map_err(|e| SendError::Options(format!("sender task failed: {e}")))?
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3};

    struct Record(Arc<std::sync::Mutex<Vec<Message>>>);
    impl MessageWriter for Record {
        fn send(&mut self, msg: &Message) -> Result<(), SendError> {
            self.0.lock().unwrap().push(*msg);
            Ok(())
        }
    }

    fn samples(n: usize, dt: f64) -> Vec<TrajectorySample> {
        (0..n)
            .map(|k| TrajectorySample {
                time_s: 1.0 + k as f64 * dt,
                position: DVec3::new(0.0, 0.0, 100.0 - k as f64),
                attitude: DQuat::IDENTITY,
                sun_dir: DVec3::Z,
                velocity: None,
                angular_rate: None,
                camera_to_inertial: None,
                planet_centre: None,
            })
            .collect()
    }

    #[test]
    fn fixed_rate_holds_latest_sample() {
        let log = Arc::new(std::sync::Mutex::new(Vec::new()));
        let s = samples(5, 0.5);
        let opts = SendOptions { rate_hz: Some(3.0), speed: f64::INFINITY };
        let st = send_trajectory_blocking(&s, &opts, &mut Record(log.clone()), &Shutdown::new()).unwrap();
        // Ticks at 0, 1/3, 2/3, … ≤ 2 s after the first sample: 7 sends.
        assert_eq!(st.poses, 7);
        let z: Vec<f64> = log
            .lock()
            .unwrap()
            .iter()
            .map(|m| match m {
                Message::Pose(p) => p.position.z,
                _ => panic!(),
            })
            .collect();
        // Sample k covers [0.5k, 0.5k + 0.5): ticks 0,.33 → 0; .67 → 1; 1.0,1.33 → 2; 1.67 → 3; 2.0 → 4.
        assert_eq!(z, vec![100.0, 100.0, 99.0, 98.0, 98.0, 97.0, 96.0]);
        let bad = SendOptions { rate_hz: None, speed: 0.0 };
        assert!(send_trajectory_blocking(&s, &bad, &mut Record(log), &Shutdown::new()).is_err());
    }

    #[tokio::test]
    async fn shutdown_stops_a_paced_replay() {
        let log = Arc::new(std::sync::Mutex::new(Vec::new()));
        let s: Arc<[TrajectorySample]> = samples(1000, 1.0).into();
        let opts = SendOptions { rate_hz: None, speed: 1.0 };
        let st = send_trajectory(s, opts, Box::new(Record(log.clone())), async {}).await.unwrap();
        // Shutdown was already resolved: at most the first (due at once) pose went out.
        assert!(st.poses <= 1, "{st:?}");
        assert_eq!(log.lock().unwrap().len() as u64, st.poses);
    }
}
