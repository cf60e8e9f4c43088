//! The GigE Vision device: the thin I/O shell around the pure codecs. One tokio task
//! serves the GVCP socket (commands → [`Control`] → acknowledges, heartbeat expiry);
//! one std thread owns the GVSP socket (converts frames to the client's ROI and
//! format, packetises, paces packets by the negotiated delay, keeps a bounded ring of
//! recent blocks and answers resend requests from it).
//!
//! Frames come in through [`GigeDevice::publish`] (the `Sink` interface: never
//! blocks); what a client sets comes out through [`GigeDevice::settings`] (a `watch`
//! of [`CameraSettings`]) and the software-trigger hook, for the renderer to follow.
//! Everything refused or dropped is counted (`hilcam_gige_*`) and logged.

use super::chunk;
use super::control::Control;
use super::discovery;
use super::genicam;
use super::gvcp::{self, GVCP_PORT, Status};
use super::gvsp::{self, Block};
use super::pending::{Awaited, Shown};
use super::pixel;
use super::registers::{
    self as reg, AcquisitionMode, CameraDescription, CameraSettings, DeviceIdentity, Effect, Registers, StreamChannel,
};
use crate::frame::{EncodedFrame, unix_ns_now};
use crate::metrics::{Counter, Histogram, Registry};
use crate::render::camera::Window;
use std::collections::VecDeque;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// `[output.gige]`: where the camera lives and what it calls itself.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GigeConfig {
    /// Address the GVCP and GVSP sockets bind (default 127.0.0.1; a real bench uses the
    /// address of the NIC facing the board). Clients address the camera by it.
    pub address: Ipv4Addr,
    /// GVCP port (3956, the standard; clients such as Aravis only use 3956).
    pub gvcp_port: u16,
    /// GVSP source port (0: any free port).
    pub stream_port: u16,
    /// Initial packet size (IP datagram bytes), until a client writes GevSCPSPacketSize.
    pub packet_size: u32,
    pub manufacturer: String,
    pub model: String,
    pub serial: String,
    pub user_name: String,
    /// Blocks kept for resends.
    pub resend_ring: usize,
    /// Serve the XML zipped (stored) instead of plain.
    pub zip_xml: bool,
    /// The longest a slow write waits for the renderer before its final acknowledge
    /// (ms; the pending timeout register, and the time a PENDING_ACK announces).
    pub pending_timeout_ms: u32,
    /// Answer DISCOVERY_CMD sent to a broadcast address (an extra socket on
    /// `discovery_address`, port `gvcp_port`).
    pub broadcast_discovery: bool,
    /// Where broadcast discovery is heard (default: the subnet broadcast of `address`,
    /// 127.255.255.255 on loopback). Not 0.0.0.0: Linux refuses it while the control
    /// socket holds the port on `address`.
    pub discovery_address: Option<Ipv4Addr>,
}

impl Default for GigeConfig {
    fn default() -> Self {
        GigeConfig {
            address: Ipv4Addr::LOCALHOST,
            gvcp_port: GVCP_PORT,
            stream_port: 0,
            packet_size: 1500,
            manufacturer: "hilcam".into(),
            model: "hilcam simulated camera".into(),
            serial: "HILCAM0001".into(),
            user_name: String::new(),
            resend_ring: 8,
            zip_xml: false,
            pending_timeout_ms: 1000,
            broadcast_discovery: true,
            discovery_address: None,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum GigeError {
    #[error("GigE Vision device: cannot bind {what} socket on {addr}: {source}")]
    Bind { what: &'static str, addr: SocketAddr, source: std::io::Error },
    #[error("GigE Vision device: {0}")]
    Config(String),
}

struct Metrics {
    commands: Counter,
    malformed: Counter,
    refused: Counter,
    heartbeat_expired: Counter,
    frames_sent: Counter,
    packets_sent: Counter,
    bytes_sent: Counter,
    send_errors: Counter,
    resend_requests: Counter,
    packets_resent: Counter,
    resend_unavailable: Counter,
    pending_acks: Counter,
    pending_timeouts: Counter,
    pending_wait: Arc<Histogram>,
    broadcast_discoveries: Counter,
    broadcast_acks: Counter,
    broadcast_refused: Counter,
    dropped_not_acquiring: Counter,
    dropped_no_stream: Counter,
    dropped_untriggered: Counter,
    dropped_rate: Counter,
    dropped_busy: Counter,
    dropped_convert: Counter,
    latency: Arc<Histogram>,
}

impl Metrics {
    fn new(r: &Registry) -> Self {
        let dropped = |reason: &str| {
            r.counter(
                "hilcam_gige_frames_dropped_total",
                "Frames not sent on the GigE Vision stream",
                &[("reason", reason)],
            )
        };
        Metrics {
            commands: r.counter("hilcam_gige_commands_total", "GVCP commands handled", &[]),
            malformed: r.counter(
                "hilcam_gige_commands_rejected_total",
                "GVCP commands answered with an error status",
                &[("reason", "malformed")],
            ),
            refused: r.counter(
                "hilcam_gige_commands_rejected_total",
                "GVCP commands answered with an error status",
                &[("reason", "refused")],
            ),
            heartbeat_expired: r.counter(
                "hilcam_gige_heartbeat_expired_total",
                "Controllers released after their heartbeat timed out",
                &[],
            ),
            frames_sent: r.counter("hilcam_gige_frames_sent_total", "Blocks sent on the GigE Vision stream", &[]),
            packets_sent: r.counter("hilcam_gige_packets_sent_total", "GVSP packets sent (resends included)", &[]),
            bytes_sent: r.counter("hilcam_gige_bytes_sent_total", "GVSP bytes sent (UDP payload)", &[]),
            send_errors: r.counter("hilcam_gige_send_errors_total", "GVSP packets the socket refused", &[]),
            resend_requests: r.counter("hilcam_gige_resend_requests_total", "PACKETRESEND commands received", &[]),
            packets_resent: r.counter("hilcam_gige_packets_resent_total", "GVSP packets sent again on request", &[]),
            resend_unavailable: r.counter(
                "hilcam_gige_resend_unavailable_total",
                "Resend requests for blocks no longer in the ring",
                &[],
            ),
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
            pending_wait: r.histogram(
                "hilcam_gige_pending_wait_seconds",
                "PENDING_ACK to the final acknowledge of the same command",
                &[],
            ),
            broadcast_discoveries: r.counter(
                "hilcam_gige_broadcast_discoveries_total",
                "DISCOVERY_CMDs heard on the discovery (broadcast) address",
                &[],
            ),
            broadcast_acks: r.counter(
                "hilcam_gige_broadcast_acks_total",
                "DISCOVERY_ACK copies broadcast for clients that allow it",
                &[],
            ),
            broadcast_refused: r.counter(
                "hilcam_gige_commands_rejected_total",
                "GVCP commands answered with an error status",
                &[("reason", "broadcast")],
            ),
            dropped_not_acquiring: dropped("not_acquiring"),
            dropped_no_stream: dropped("no_stream_channel"),
            dropped_untriggered: dropped("no_trigger"),
            dropped_rate: dropped("frame_rate"),
            dropped_busy: dropped("stream_busy"),
            dropped_convert: dropped("convert"),
            latency: r.histogram(
                "hilcam_gige_latency_seconds",
                "Pose arrival to the last GVSP packet of its frame sent",
                &[],
            ),
        }
    }
}

enum StreamJob {
    Frame { frame: Arc<EncodedFrame>, settings: CameraSettings, channel: StreamChannel },
    Resend { block_id: u64, first: u32, last: u32 },
}

struct Shared {
    control: Mutex<Control>,
    settings_tx: watch::Sender<CameraSettings>,
    jobs: mpsc::Sender<StreamJob>,
    frames_queued: AtomicUsize,
    pending_triggers: AtomicU32,
    /// When the next frame is due under AcquisitionFrameRate (None: send the next one).
    next_due: Mutex<Option<Instant>>,
    /// (pose time of the newest frame, when it was published): the device clock.
    clock: Mutex<(u64, Instant)>,
    trigger_hook: Mutex<Option<Box<dyn Fn() + Send + Sync>>>,
    /// The settings the device started with (the exposure override and the ROI are
    /// relative to them).
    initial_settings: CameraSettings,
    /// Whether a renderer follows the client's exposure and ROI
    /// (`request::follow_requests`): only then does such a write wait for a frame that
    /// shows it.
    requests_followed: AtomicBool,
    /// What the newest frame published shows (integration time, ROI).
    published: watch::Sender<Option<Shown>>,
    metrics: Metrics,
    stop: AtomicBool,
}

impl Shared {
    /// The device clock, ns: the newest frame's pose time plus the wall time since it
    /// was published (so latched timestamps and leader timestamps share a time base).
    fn clock_ns(&self) -> u64 {
        let (t, at) = *self.clock.lock().expect("clock lock");
        t.saturating_add(at.elapsed().as_nanos() as u64)
    }
}

/// A running GigE Vision device. Drop or [`GigeDevice::shutdown`] stops it.
pub struct GigeDevice {
    shared: Arc<Shared>,
    gvcp_addr: SocketAddr,
    discovery_addr: Option<SocketAddr>,
    stream_addr: SocketAddr,
    control_task: Option<tokio::task::JoinHandle<()>>,
    stream_thread: Option<std::thread::JoinHandle<()>>,
    xml: String,
}

impl GigeDevice {
    /// Bind the sockets and start serving. Must be called inside a tokio runtime.
    pub async fn start(
        cfg: &GigeConfig,
        camera: CameraDescription,
        registry: Arc<Registry>,
    ) -> Result<GigeDevice, GigeError> {
        let pending_range = reg::PENDING_TIMEOUT_MIN_MS..=reg::PENDING_TIMEOUT_MAX_MS;
        if !pending_range.contains(&cfg.pending_timeout_ms) {
            return Err(GigeError::Config(format!(
                "[output.gige] pending_timeout_ms {}: {}..={} ms",
                cfg.pending_timeout_ms,
                pending_range.start(),
                pending_range.end()
            )));
        }
        if cfg.broadcast_discovery && cfg.discovery_address.is_some_and(|a| a.is_unspecified()) {
            return Err(GigeError::Config(format!(
                "[output.gige] discovery_address 0.0.0.0: the port {} is already the control socket's on {}, \
                 so it cannot also be bound on every address; use the subnet's broadcast address (the default, {})",
                cfg.gvcp_port,
                cfg.address,
                discovery::subnet_broadcast(cfg.address)
            )));
        }
        let gvcp_bind = SocketAddr::V4(SocketAddrV4::new(cfg.address, cfg.gvcp_port));
        let gvcp = tokio::net::UdpSocket::bind(gvcp_bind).await.map_err(|source| GigeError::Bind {
            what: "GVCP",
            addr: gvcp_bind,
            source,
        })?;
        let gvcp_addr =
            gvcp.local_addr().map_err(|source| GigeError::Bind { what: "GVCP", addr: gvcp_bind, source })?;
        // Broadcast acknowledges leave from the control socket.
        gvcp.set_broadcast(true).map_err(|source| GigeError::Bind { what: "GVCP", addr: gvcp_bind, source })?;
        let broadcast = discovery::subnet_broadcast(cfg.address);
        let discovery_socket = if cfg.broadcast_discovery {
            let ip = cfg.discovery_address.unwrap_or(broadcast);
            let addr = SocketAddr::V4(SocketAddrV4::new(ip, gvcp_addr.port()));
            Some(discovery::bind(ip, gvcp_addr.port()).map_err(|source| GigeError::Bind {
                what: "GVCP discovery",
                addr,
                source,
            })?)
        } else {
            None
        };
        let discovery_addr = discovery_socket.as_ref().and_then(|s| s.local_addr().ok());
        let stream_bind = SocketAddr::V4(SocketAddrV4::new(cfg.address, cfg.stream_port));
        let stream = UdpSocket::bind(stream_bind).map_err(|source| GigeError::Bind {
            what: "GVSP",
            addr: stream_bind,
            source,
        })?;
        let stream_addr =
            stream.local_addr().map_err(|source| GigeError::Bind { what: "GVSP", addr: stream_bind, source })?;

        let identity = DeviceIdentity {
            manufacturer: cfg.manufacturer.clone(),
            model: cfg.model.clone(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            info: "hilcam hardware-in-the-loop camera simulator".into(),
            serial: cfg.serial.clone(),
            user_name: cfg.user_name.clone(),
            mac: mac_from_serial(&cfg.serial),
            ip: cfg.address,
        };
        let xml = genicam::xml(&identity, &camera);
        let (name, file) = if cfg.zip_xml {
            ("hilcam.zip", super::zip::stored("hilcam.xml", xml.as_bytes()))
        } else {
            ("hilcam.xml", xml.as_bytes().to_vec())
        };
        let mut regs = Registers::new(identity, camera, cfg.packet_size, name, file).map_err(GigeError::Config)?;
        regs.stream.source_port = stream_addr.port();
        regs.pending_timeout_ms = cfg.pending_timeout_ms;
        let settings = regs.settings;
        let (settings_tx, _) = watch::channel(settings);
        let (jobs_tx, jobs_rx) = mpsc::channel();
        let shared = Arc::new(Shared {
            control: Mutex::new(Control::new(regs)),
            settings_tx,
            jobs: jobs_tx,
            frames_queued: AtomicUsize::new(0),
            pending_triggers: AtomicU32::new(0),
            next_due: Mutex::new(None),
            clock: Mutex::new((0, Instant::now())),
            trigger_hook: Mutex::new(None),
            initial_settings: settings,
            requests_followed: AtomicBool::new(false),
            published: watch::channel(None).0,
            metrics: Metrics::new(&registry),
            stop: AtomicBool::new(false),
        });
        let ring = cfg.resend_ring.max(1);
        let thread_shared = shared.clone();
        let stream_thread = std::thread::Builder::new()
            .name("gige-stream".into())
            .spawn(move || stream_loop(stream, jobs_rx, thread_shared, ring))
            .map_err(|e| GigeError::Config(format!("cannot start the GVSP thread: {e}")))?;
        let control_task = tokio::spawn(control_loop(gvcp, discovery_socket, broadcast, shared.clone()));
        tracing::info!(%gvcp_addr, %stream_addr, discovery = ?discovery_addr, "GigE Vision device up (GVCP, GVSP source, broadcast discovery)");
        Ok(GigeDevice {
            shared,
            gvcp_addr,
            discovery_addr,
            stream_addr,
            control_task: Some(control_task),
            stream_thread: Some(stream_thread),
            xml,
        })
    }

    pub fn gvcp_addr(&self) -> SocketAddr {
        self.gvcp_addr
    }

    /// Where broadcast DISCOVERY_CMDs are heard (None: broadcast discovery off).
    pub fn discovery_addr(&self) -> Option<SocketAddr> {
        self.discovery_addr
    }

    pub fn stream_addr(&self) -> SocketAddr {
        self.stream_addr
    }

    /// The GenICam XML the device serves (unzipped).
    pub fn xml(&self) -> &str {
        &self.xml
    }

    /// The camera settings as the client has set them; changes are announced.
    pub fn settings(&self) -> watch::Receiver<CameraSettings> {
        self.shared.settings_tx.subscribe()
    }

    /// Called on every TriggerSoftware execution (the serve loop turns it into a
    /// trigger input: a frame rendered from the latest pose).
    pub fn on_software_trigger(&self, hook: Box<dyn Fn() + Send + Sync>) {
        *self.shared.trigger_hook.lock().expect("trigger hook lock") = Some(hook);
    }

    /// A renderer applies the client's exposure and ROI to the frames it starts from now
    /// on: such writes then wait for a frame that shows them (pending acknowledge).
    pub(super) fn mark_requests_followed(&self) {
        self.shared.requests_followed.store(true, Ordering::Release);
    }

    /// Whether a client has started acquisition.
    pub fn acquiring(&self) -> bool {
        self.shared.control.lock().expect("control lock").regs.acquiring
    }

    /// Hand a frame over without blocking: it is sent if a client acquires, the
    /// trigger / frame-rate / single-frame rules let it through and the stream thread
    /// is not two frames behind; otherwise it is counted as dropped with the reason.
    pub fn publish(&self, frame: &Arc<EncodedFrame>) {
        let s = &self.shared;
        *s.clock.lock().expect("clock lock") = (frame.meta.pose_t_ns, Instant::now());
        let shown = Some(Shown::of(frame));
        s.published.send_if_modified(|v| std::mem::replace(v, shown) != shown);
        let m = &s.metrics;
        let (settings, channel) = {
            let mut c = s.control.lock().expect("control lock");
            if !c.regs.acquiring {
                m.dropped_not_acquiring.inc();
                return;
            }
            let ch = c.regs.stream;
            if ch.host_port == 0 || ch.destination.is_unspecified() {
                m.dropped_no_stream.inc();
                return;
            }
            let st = c.regs.settings;
            if st.trigger_on {
                let taken =
                    s.pending_triggers.fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| n.checked_sub(1)).is_ok();
                if !taken {
                    m.dropped_untriggered.inc();
                    return;
                }
            } else {
                // A schedule at the frame rate that tolerates a quarter period of jitter:
                // a source at exactly the rate loses nothing, one at twice it loses half.
                let mut due = s.next_due.lock().expect("next due lock");
                let period = Duration::from_secs_f64(1.0 / f64::from(st.frame_rate_hz.max(1e-3)));
                let now = Instant::now();
                let d = due.unwrap_or(now);
                if now + period / 4 < d {
                    m.dropped_rate.inc();
                    return;
                }
                *due = Some(d.max(now.checked_sub(period).unwrap_or(now)) + period);
            }
            if st.acquisition_mode == AcquisitionMode::SingleFrame {
                c.regs.acquiring = false;
            }
            (st, ch)
        };
        if s.frames_queued.load(Ordering::Acquire) >= 2 {
            m.dropped_busy.inc();
            tracing::debug!(frame = frame.meta.frame_seq, "GigE stream busy: frame dropped");
            return;
        }
        s.frames_queued.fetch_add(1, Ordering::AcqRel);
        if s.jobs.send(StreamJob::Frame { frame: frame.clone(), settings, channel }).is_err() {
            s.frames_queued.fetch_sub(1, Ordering::AcqRel);
            m.dropped_busy.inc();
        }
    }

    /// Stop both loops and wait for them.
    pub async fn shutdown(mut self) {
        self.stop_now();
        if let Some(t) = self.control_task.take() {
            let _ = t.await;
        }
        if let Some(t) = self.stream_thread.take() {
            let _ = tokio::task::spawn_blocking(move || t.join()).await;
        }
    }

    fn stop_now(&self) {
        self.shared.stop.store(true, Ordering::Release);
        if let Some(t) = &self.control_task {
            t.abort();
        }
    }
}

impl Drop for GigeDevice {
    fn drop(&mut self) {
        self.stop_now();
    }
}

/// A locally administered MAC derived from the serial (stable per device name).
fn mac_from_serial(serial: &str) -> [u8; 6] {
    let h = crate::frame::CRC32.checksum(serial.as_bytes()).to_be_bytes();
    [0x02, 0x48, h[0], h[1], h[2], h[3]]
}

/// What to send back for one datagram.
enum Reply {
    None,
    Now(Vec<u8>),
    /// A write the renderer applies when it starts its next frame: PENDING_ACK now, the
    /// final `ack` once a published frame shows `awaited` (or at the timeout).
    Pending {
        ack_id: u16,
        ack: Vec<u8>,
        awaited: Awaited,
        timeout_ms: u32,
        published: watch::Receiver<Option<Shown>>,
    },
}

async fn control_loop(
    socket: tokio::net::UdpSocket,
    discovery: Option<tokio::net::UdpSocket>,
    broadcast: Ipv4Addr,
    shared: Arc<Shared>,
) {
    let socket = Arc::new(socket);
    let mut buf = vec![0u8; 2048];
    let mut dbuf = vec![0u8; 2048];
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => {
                let (n, peer) = match r {
                    Ok(x) => x,
                    Err(e) => {
                        tracing::warn!("GVCP receive: {e}");
                        continue;
                    }
                };
                match handle_datagram(&shared, &buf[..n], peer) {
                    Reply::None => {}
                    Reply::Now(reply) => {
                        send_ack(&socket, &reply, peer).await;
                        if discovery::broadcast_ack_allowed(&buf[..n]) {
                            broadcast_ack(&socket, &shared, &reply, broadcast, peer).await;
                        }
                    }
                    Reply::Pending { ack_id, ack, awaited, timeout_ms, published } => {
                        let announced = timeout_ms.min(u32::from(u16::MAX)) as u16;
                        send_ack(&socket, &gvcp::pending_ack(ack_id, announced), peer).await;
                        shared.metrics.pending_acks.inc();
                        // The final acknowledge leaves within the announced time.
                        let wait = Duration::from_millis(u64::from(timeout_ms) * 9 / 10);
                        tokio::spawn(finish_pending(socket.clone(), shared.clone(), peer, ack, awaited, wait, published));
                    }
                }
            }
            r = recv_discovery(discovery.as_ref(), &mut dbuf) => {
                let (n, peer) = match r {
                    Ok(x) => x,
                    Err(e) => {
                        tracing::warn!("GVCP discovery receive: {e}");
                        continue;
                    }
                };
                let datagram = &dbuf[..n];
                if !discovery::is_discovery(datagram) {
                    shared.metrics.broadcast_refused.inc();
                    tracing::warn!(%peer, "GVCP command on the broadcast discovery address ignored: only DISCOVERY_CMD is answered there");
                    continue;
                }
                shared.metrics.broadcast_discoveries.inc();
                if let Reply::Now(reply) = handle_datagram(&shared, datagram, peer) {
                    send_ack(&socket, &reply, peer).await;
                    if discovery::broadcast_ack_allowed(datagram) {
                        broadcast_ack(&socket, &shared, &reply, broadcast, peer).await;
                    }
                }
            }
            _ = tick.tick() => {
                let expired = shared.control.lock().expect("control lock").expire(Instant::now());
                if expired {
                    shared.metrics.heartbeat_expired.inc();
                    tracing::warn!("GigE Vision controller's heartbeat timed out: control released, acquisition stopped");
                }
            }
        }
        if shared.stop.load(Ordering::Acquire) {
            break;
        }
    }
}

/// A datagram from the discovery socket; never ready when there is none.
async fn recv_discovery(
    socket: Option<&tokio::net::UdpSocket>,
    buf: &mut [u8],
) -> std::io::Result<(usize, SocketAddr)> {
    match socket {
        Some(s) => s.recv_from(buf).await,
        None => std::future::pending().await,
    }
}

/// The broadcast copy of a DISCOVERY_ACK, for a client that allows one.
async fn broadcast_ack(
    socket: &tokio::net::UdpSocket,
    shared: &Shared,
    ack: &[u8],
    broadcast: Ipv4Addr,
    peer: SocketAddr,
) {
    let to = discovery::broadcast_destination(broadcast, peer);
    shared.metrics.broadcast_acks.inc();
    send_ack(socket, ack, to).await;
}

async fn send_ack(socket: &tokio::net::UdpSocket, ack: &[u8], peer: SocketAddr) {
    if let Err(e) = socket.send_to(ack, peer).await {
        tracing::warn!(%peer, "GVCP acknowledge not sent: {e}");
    }
}

/// Wait until a published frame shows the written exposure / ROI (frames the renderer
/// started before the write still carry the old ones), then send the final acknowledge.
/// At the timeout it is sent anyway (the value is stored and applies from the next
/// frame the renderer starts), counted and logged.
async fn finish_pending(
    socket: Arc<tokio::net::UdpSocket>,
    shared: Arc<Shared>,
    peer: SocketAddr,
    ack: Vec<u8>,
    awaited: Awaited,
    wait: Duration,
    mut published: watch::Receiver<Option<Shown>>,
) {
    let started = Instant::now();
    let shown = published.wait_for(|f| f.as_ref().is_some_and(|f| awaited.shown_by(f)));
    let applied = matches!(tokio::time::timeout(wait, shown).await, Ok(Ok(_)));
    let m = &shared.metrics;
    m.pending_wait.record(started.elapsed().as_nanos() as u64);
    if !applied {
        m.pending_timeouts.inc();
        tracing::warn!(
            %peer,
            integration_s = ?awaited.integration_s,
            roi = ?awaited.roi,
            waited_ms = wait.as_millis() as u64,
            "GigE Vision write acknowledged at the pending timeout: no frame showing it was published yet"
        );
    }
    shared.control.lock().expect("control lock").end_pending(peer, Instant::now());
    send_ack(&socket, &ack, peer).await;
}

fn handle_datagram(shared: &Shared, datagram: &[u8], peer: SocketAddr) -> Reply {
    let m = &shared.metrics;
    m.commands.inc();
    let (outcome, settings, pending) = {
        let mut c = shared.control.lock().expect("control lock");
        let before = c.controller();
        let mut o = c.handle(datagram, peer, Instant::now());
        for e in &o.effects {
            if *e == Effect::TimestampLatch {
                c.regs.latched_timestamp = shared.clock_ns();
            }
        }
        if o.control_changed {
            tracing::info!(from = ?before, to = ?c.controller(), "GigE Vision control privilege changed");
        }
        if o.effects.contains(&Effect::AcquisitionStart) {
            *shared.next_due.lock().expect("next due lock") = None;
            shared.pending_triggers.store(0, Ordering::Release);
        }
        let settings = c.regs.settings;
        // Slow: an exposure or ROI the renderer applies at its next frame, for a client
        // that accepts PENDING_ACK (`pending::Awaited` says which writes).
        let slow = o.reply.is_some()
            && o.error.is_none()
            && c.regs.pending_ack_enabled()
            && shared.requests_followed.load(Ordering::Acquire);
        let awaited = Awaited::of(&shared.initial_settings, &settings, &o.effects).filter(|_| slow);
        if awaited.is_some() {
            c.begin_pending();
        }
        o.effects.dedup();
        (o, settings, awaited.map(|a| (a, c.regs.pending_timeout_ms)))
    };
    if let Some(status) = outcome.error {
        let malformed = matches!(status, Status::InvalidHeader | Status::NotImplemented)
            || (status == Status::InvalidParameter && outcome.reason.as_deref().is_some_and(|r| r.contains("payload")));
        if malformed {
            m.malformed.inc()
        } else {
            m.refused.inc()
        }
        tracing::warn!(%peer, status = status.name(), reason = outcome.reason.as_deref().unwrap_or(""), "GVCP command rejected");
    }
    for e in &outcome.effects {
        match e {
            Effect::Settings | Effect::Exposure | Effect::Roi => {
                shared.settings_tx.send_replace(settings);
            }
            Effect::SoftwareTrigger => {
                shared.pending_triggers.fetch_add(1, Ordering::AcqRel);
                if let Some(hook) = shared.trigger_hook.lock().expect("trigger hook lock").as_ref() {
                    hook();
                }
            }
            Effect::AcquisitionStart => tracing::info!(%peer, "GigE Vision acquisition started"),
            Effect::AcquisitionStop => tracing::info!(%peer, "GigE Vision acquisition stopped"),
            _ => {}
        }
    }
    if let Some((block_id, first, last)) = outcome.resend {
        m.resend_requests.inc();
        let _ = shared.jobs.send(StreamJob::Resend { block_id, first, last });
    }
    match (outcome.reply, pending) {
        (Some(ack), Some((awaited, timeout_ms))) => {
            let ack_id = u16::from_be_bytes([ack[6], ack[7]]);
            let published = shared.published.subscribe();
            Reply::Pending { ack_id, ack, awaited, timeout_ms, published }
        }
        (Some(ack), None) => Reply::Now(ack),
        (None, _) => Reply::None,
    }
}

/// Paces packets by the negotiated inter-packet delay. The schedule is absolute and
/// restarts with each block (packet k leaves at start + k·delay), so the mean rate is
/// exact; the thread sleeps only when it is more than 200 µs ahead, so delays below the
/// OS sleep granularity are kept on average, in short bursts, without spinning. After
/// an oversleep (a loaded machine) it catches up rather than losing the time.
struct Pacer {
    next: Instant,
}

impl Pacer {
    const SLEEP_AHEAD: Duration = Duration::from_micros(200);

    fn start_block(&mut self) {
        self.next = Instant::now();
    }

    fn wait(&mut self, delay: Duration) {
        if delay.is_zero() {
            return;
        }
        let now = Instant::now();
        if self.next > now + Self::SLEEP_AHEAD {
            std::thread::sleep(self.next - now);
        }
        self.next += delay;
    }
}

fn stream_loop(socket: UdpSocket, jobs: mpsc::Receiver<StreamJob>, shared: Arc<Shared>, ring_len: usize) {
    let m = &shared.metrics;
    let mut ring: VecDeque<(Block, SocketAddr, u32)> = VecDeque::with_capacity(ring_len);
    let mut block_id: u16 = 0;
    let mut pacer = Pacer { next: Instant::now() };
    let send = |p: &[u8], dest: SocketAddr| match socket.send_to(p, dest) {
        Ok(n) => {
            m.packets_sent.inc();
            m.bytes_sent.add(n as u64);
        }
        Err(e) => {
            m.send_errors.inc();
            tracing::debug!(%dest, "GVSP packet not sent: {e}");
        }
    };
    loop {
        let job = match jobs.recv_timeout(Duration::from_millis(100)) {
            Ok(j) => j,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if shared.stop.load(Ordering::Acquire) {
                    return;
                }
                continue;
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => return,
        };
        match job {
            StreamJob::Frame { frame, settings, channel } => {
                shared.frames_queued.fetch_sub(1, Ordering::AcqRel);
                let mut data = match pixel::convert(&frame, settings.window(), settings.pixel_format) {
                    Ok(d) => d,
                    Err(e) => {
                        m.dropped_convert.inc();
                        tracing::warn!("GigE stream: {e}");
                        continue;
                    }
                };
                let mut payload_type = gvsp::PAYLOAD_IMAGE;
                if settings.chunk_mode {
                    chunk::append_chunks(&mut data, &frame.meta);
                    if let Some(t) = frame.truth.as_ref().filter(|t| t.channels == settings.truth) {
                        // Whole-array frames are cropped at the offsets, as the pixels.
                        let w = settings.window();
                        let w = if frame.roi.is_some() { Window { x: 0, y: 0, ..w } } else { w };
                        chunk::append_truth_chunks(&mut data, t, w);
                    }
                    payload_type |= gvsp::PAYLOAD_CHUNK_FLAG;
                }
                block_id = gvsp::next_block_id(block_id);
                let block = Block {
                    block_id,
                    timestamp: frame.meta.pose_t_ns,
                    pixel_format: settings.pixel_format.pfnc(),
                    width: settings.width,
                    height: settings.height,
                    offset_x: settings.offset_x,
                    offset_y: settings.offset_y,
                    payload_type,
                    data,
                };
                let dest = SocketAddr::V4(SocketAddrV4::new(channel.destination, channel.host_port));
                let delay = Duration::from_nanos(u64::from(channel.packet_delay_ticks));
                pacer.start_block();
                for pid in 0..block.packet_count(channel.packet_size) {
                    if let Some(p) = block.packet(pid, channel.packet_size, gvsp::STATUS_SUCCESS) {
                        pacer.wait(delay);
                        send(&p, dest);
                    }
                }
                m.frames_sent.inc();
                if frame.meta.pose_arrival_unix_ns > 0 {
                    m.latency.record(unix_ns_now().saturating_sub(frame.meta.pose_arrival_unix_ns));
                }
                if ring.len() == ring_len {
                    ring.pop_front();
                }
                ring.push_back((block, dest, channel.packet_size));
            }
            StreamJob::Resend { block_id: wanted, first, last } => {
                let found = ring.iter().find(|(b, _, _)| u64::from(b.block_id) == wanted);
                match found {
                    Some((b, dest, size)) => {
                        let end = last.min(b.packet_count(*size) - 1);
                        for pid in first..=end {
                            if let Some(p) = b.packet(pid, *size, gvsp::STATUS_RESEND) {
                                send(&p, *dest);
                                m.packets_resent.inc();
                            }
                        }
                    }
                    None => {
                        m.resend_unavailable.inc();
                        tracing::warn!(block = wanted, first, last, "resend requested for a block no longer kept");
                        if let Some((_, dest, _)) = ring.back() {
                            send(&gvsp::unavailable_packet(wanted as u16, first), *dest);
                        }
                    }
                }
            }
        }
    }
}
