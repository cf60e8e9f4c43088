//! The GigE Vision device: the thin I/O shell around the pure codecs. One tokio task
//! serves the GVCP sockets (the control socket and the two broadcast-discovery ones:
//! commands → [`Control`] → acknowledges, heartbeat expiry); one std thread owns the
//! GVSP socket (`stream.rs`: ROI and format, packets paced at the link speed plus the
//! negotiated delay, a bounded ring of recent blocks for resends).
//!
//! Frames come in through [`GigeDevice::publish`] (the `Sink` interface: never
//! blocks); what a client sets comes out through [`GigeDevice::settings`] (a `watch`
//! of [`CameraSettings`]) and the software-trigger hook, for the renderer to follow.
//! Everything refused or dropped is counted (`hilcam_gige_*`) and logged at a bounded
//! rate (`log_limit.rs`).

pub use super::config::GigeConfig;
use super::control::{Control, Rejection};
use super::discovery;
use super::genicam;
use super::gvcp;
use super::log_limit::LogLimit;
use super::metrics::Metrics;
use super::pending::{Awaited, Shown};
use super::rate_gate::RateGate;
use super::registers::{AcquisitionMode, CameraDescription, CameraSettings, DeviceIdentity, Effect, Registers};
use super::stream::{FrameJob, ResendJob, Sender, StreamJobs};
use crate::frame::EncodedFrame;
use crate::metrics::Registry;
use crate::shutdown::Shutdown;
use crate::sink::camera_control::SoftwareTriggers;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// Slow writes waiting for their final acknowledge at most: beyond it a slow write is
/// acknowledged as soon as it is stored (`hilcam_gige_pending_overflow_total`).
pub const PENDING_MAX: usize = 16;
/// How long [`GigeDevice::shutdown`] waits for the stream thread (it looks at the stop
/// signal every 50 ms, so only a wedged socket makes it wait this long).
const STREAM_JOIN_TIMEOUT: Duration = Duration::from_millis(500);

#[derive(Debug, thiserror::Error)]
pub enum GigeError {
    #[error("GigE Vision device: cannot bind {what} socket on {addr}: {source}")]
    Bind { what: &'static str, addr: SocketAddr, source: std::io::Error },
    #[error("GigE Vision device: {0}")]
    Config(String),
}

struct Shared {
    control: Mutex<Control>,
    settings_tx: watch::Sender<CameraSettings>,
    jobs: Arc<StreamJobs>,
    pending_triggers: AtomicU32,
    /// Slow writes waiting for their final acknowledge (at most [`PENDING_MAX`]).
    pending: AtomicUsize,
    /// AcquisitionFrameRate: which published frames go out.
    gate: Mutex<RateGate>,
    /// One warning per reason per interval (floods are counted, not logged line by line).
    log: Mutex<LogLimit>,
    /// (pose time of the newest frame, when it was published): the device clock.
    clock: Mutex<(u64, Instant)>,
    triggers: SoftwareTriggers,
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
    /// The device's own stop: it closes after the last frame is published, not at the
    /// server's signal.
    stop: Shutdown,
}

impl Shared {
    /// The device clock, ns: the newest frame's pose time plus the wall time since it
    /// was published (so latched timestamps and leader timestamps share a time base).
    fn clock_ns(&self) -> u64 {
        let (t, at) = *self.clock.lock().expect("clock lock");
        t.saturating_add(at.elapsed().as_nanos() as u64)
    }

    /// Whether to log an occurrence of `reason` now: `Some(suppressed since the last line)`.
    fn log_admit(&self, reason: &'static str) -> Option<u64> {
        self.log.lock().expect("log lock").admit(reason, Instant::now())
    }
}

/// A running GigE Vision device. Drop or [`GigeDevice::shutdown`] stops it.
pub struct GigeDevice {
    shared: Arc<Shared>,
    gvcp_addr: SocketAddr,
    discovery_addr: Option<SocketAddr>,
    limited_discovery_addr: Option<SocketAddr>,
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
        cfg.validate().map_err(|(key, why)| GigeError::Config(format!("{key}: {why}")))?;
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
        // Limited broadcasts (255.255.255.255, what Aravis 0.8 sends on each interface)
        // reach only sockets bound to that address or to 0.0.0.0.
        let limited_socket = if cfg.broadcast_discovery {
            let addr = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::BROADCAST, gvcp_addr.port()));
            Some(discovery::bind(Ipv4Addr::BROADCAST, gvcp_addr.port()).map_err(|source| GigeError::Bind {
                what: "GVCP limited-broadcast discovery",
                addr,
                source,
            })?)
        } else {
            None
        };
        let discovery_addr = discovery_socket.as_ref().and_then(|s| s.local_addr().ok());
        let limited_discovery_addr = limited_socket.as_ref().and_then(|s| s.local_addr().ok());
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
        regs.allow_broadcast_stream = cfg.allow_broadcast_stream;
        let settings = regs.settings;
        let (settings_tx, _) = watch::channel(settings);
        let jobs = Arc::new(StreamJobs::default());
        let stop = Shutdown::new();
        let shared = Arc::new(Shared {
            control: Mutex::new(Control::new(regs)),
            settings_tx,
            jobs: jobs.clone(),
            pending_triggers: AtomicU32::new(0),
            pending: AtomicUsize::new(0),
            gate: Mutex::new(RateGate::default()),
            log: Mutex::new(LogLimit::default()),
            clock: Mutex::new((0, Instant::now())),
            triggers: SoftwareTriggers::default(),
            initial_settings: settings,
            requests_followed: AtomicBool::new(false),
            published: watch::channel(None).0,
            metrics: Metrics::new(&registry),
            stop: stop.clone(),
        });
        let sender = Sender {
            socket: stream,
            jobs,
            stop,
            ring_len: cfg.resend_ring,
            link_bps: u64::from(cfg.link_mbps) * 1_000_000,
        };
        let thread_shared = shared.clone();
        let stream_thread = std::thread::Builder::new()
            .name("gige-stream".into())
            .spawn(move || sender.run(&thread_shared.metrics))
            .map_err(|e| GigeError::Config(format!("cannot start the GVSP thread: {e}")))?;
        let discovery = [discovery_socket, limited_socket];
        let control_task = tokio::spawn(control_loop(gvcp, discovery, broadcast, shared.clone()));
        tracing::info!(%gvcp_addr, %stream_addr, discovery = ?discovery_addr, limited = ?limited_discovery_addr, "GigE Vision device up (GVCP, GVSP source, broadcast discovery)");
        Ok(GigeDevice {
            shared,
            gvcp_addr,
            discovery_addr,
            limited_discovery_addr,
            stream_addr,
            control_task: Some(control_task),
            stream_thread: Some(stream_thread),
            xml,
        })
    }

    pub fn gvcp_addr(&self) -> SocketAddr {
        self.gvcp_addr
    }

    /// Where directed-broadcast DISCOVERY_CMDs are heard (None: broadcast discovery off).
    pub fn discovery_addr(&self) -> Option<SocketAddr> {
        self.discovery_addr
    }

    /// Where limited-broadcast (255.255.255.255) DISCOVERY_CMDs are heard.
    pub fn limited_discovery_addr(&self) -> Option<SocketAddr> {
        self.limited_discovery_addr
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
        self.shared.triggers.connect(hook);
    }

    /// The device's TriggerSoftware executions, for its [`crate::sink::camera_control::CameraControl`].
    pub fn software_triggers(&self) -> SoftwareTriggers {
        self.shared.triggers.clone()
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
            // ExposureTime under auto-exposure reads what the sensor integrates.
            c.regs.integrated_us = Some((super::chunk::integration_ns(frame.meta.integration_s) as f64 / 1e3) as f32);
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
            } else if !c.regs.camera.rate_sets_schedule
                && !s.gate.lock().expect("rate gate lock").admit(Instant::now(), st.frame_rate_hz)
            {
                m.dropped_rate.inc();
                return;
            }
            if st.acquisition_mode == AcquisitionMode::SingleFrame {
                c.regs.acquiring = false;
            }
            (st, ch)
        };
        if s.jobs.push_frame(FrameJob { frame: frame.clone(), settings, channel }).is_err() {
            m.dropped_busy.inc();
            tracing::debug!(frame = frame.meta.frame_seq, "GigE stream busy: frame dropped");
        }
    }

    /// Stop both loops and wait for them: the control task at once, the stream thread
    /// for at most [`STREAM_JOIN_TIMEOUT`] (it gives up a block mid-way when stopped;
    /// were it wedged, it is left behind with a warning rather than holding shutdown).
    pub async fn shutdown(mut self) {
        self.stop_now();
        if let Some(t) = self.control_task.take() {
            let _ = t.await;
        }
        if let Some(t) = self.stream_thread.take() {
            let (done_tx, done_rx) = tokio::sync::oneshot::channel();
            std::thread::spawn(move || {
                let _ = t.join();
                let _ = done_tx.send(());
            });
            if tokio::time::timeout(STREAM_JOIN_TIMEOUT, done_rx).await.is_err() {
                tracing::warn!("GigE Vision stream thread did not stop within {STREAM_JOIN_TIMEOUT:?}: left behind");
            }
        }
    }

    fn stop_now(&self) {
        self.shared.stop.trigger();
        self.shared.jobs.stop();
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
    discovery: [Option<tokio::net::UdpSocket>; 2],
    broadcast: Ipv4Addr,
    shared: Arc<Shared>,
) {
    let socket = Arc::new(socket);
    let [directed, limited] = discovery;
    let mut buf = vec![0u8; 2048];
    let (mut dbuf, mut lbuf) = (vec![0u8; 2048], vec![0u8; 2048]);
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => {
                let Some((n, peer)) = received(&shared, r) else { continue };
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
            r = recv_discovery(directed.as_ref(), &mut dbuf) => {
                let Some((n, peer)) = received(&shared, r) else { continue };
                discovery_datagram(&socket, &shared, &dbuf[..n], peer, broadcast).await;
            }
            r = recv_discovery(limited.as_ref(), &mut lbuf) => {
                let Some((n, peer)) = received(&shared, r) else { continue };
                discovery_datagram(&socket, &shared, &lbuf[..n], peer, broadcast).await;
            }
            _ = tick.tick() => {
                let expired = shared.control.lock().expect("control lock").expire(Instant::now());
                if expired {
                    shared.metrics.heartbeat_expired.inc();
                    tracing::warn!("GigE Vision controller's heartbeat timed out: control released, acquisition stopped");
                }
            }
        }
        if shared.stop.is_triggered() {
            break;
        }
    }
}

/// A received datagram, or None after a receive error (counted, logged at a bounded rate).
fn received(shared: &Shared, r: std::io::Result<(usize, SocketAddr)>) -> Option<(usize, SocketAddr)> {
    match r {
        Ok(x) => Some(x),
        Err(e) => {
            shared.metrics.receive_errors.inc();
            if let Some(suppressed) = shared.log_admit("receive") {
                tracing::warn!(suppressed, "GVCP receive: {e}");
            }
            None
        }
    }
}

/// A datagram on a broadcast address: only DISCOVERY_CMD is answered there.
async fn discovery_datagram(
    socket: &tokio::net::UdpSocket,
    shared: &Shared,
    datagram: &[u8],
    peer: SocketAddr,
    broadcast: Ipv4Addr,
) {
    if !discovery::is_discovery(datagram) {
        shared.metrics.broadcast_refused.inc();
        if let Some(suppressed) = shared.log_admit("broadcast") {
            tracing::warn!(%peer, suppressed, "GVCP command on a broadcast address ignored: only DISCOVERY_CMD is answered there");
        }
        return;
    }
    shared.metrics.broadcast_discoveries.inc();
    if let Reply::Now(reply) = handle_datagram(shared, datagram, peer) {
        send_ack(socket, &reply, peer).await;
        if discovery::broadcast_ack_allowed(datagram) {
            broadcast_ack(socket, shared, &reply, broadcast, peer).await;
        }
    }
}

/// A datagram from a discovery socket; never ready when there is none.
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
        tracing::debug!(%peer, "GVCP acknowledge not sent: {e}");
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
    shared.pending.fetch_sub(1, Ordering::AcqRel);
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
            shared.gate.lock().expect("rate gate lock").reset();
            shared.pending_triggers.store(0, Ordering::Release);
        }
        let settings = c.regs.settings;
        // Slow: an exposure or ROI the renderer applies at its next frame, for a client
        // that accepts PENDING_ACK (`pending::Awaited` says which writes).
        let slow = o.reply.is_some()
            && o.error.is_none()
            && c.regs.pending_ack_enabled()
            && shared.requests_followed.load(Ordering::Acquire);
        let mut awaited = Awaited::of(&shared.initial_settings, &settings, &o.effects).filter(|_| slow);
        if awaited.is_some() {
            let room = shared
                .pending
                .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| (n < PENDING_MAX).then_some(n + 1));
            if room.is_ok() {
                c.begin_pending();
            } else {
                // The value is stored; only the wait for a frame showing it is skipped.
                awaited = None;
                m.pending_overflow.inc();
                if let Some(suppressed) = shared.log_admit("pending_overflow") {
                    tracing::warn!(%peer, suppressed, "{PENDING_MAX} GigE Vision writes already wait for a frame: this one is acknowledged at once");
                }
            }
        }
        o.effects.dedup();
        (o, settings, awaited.map(|a| (a, c.regs.pending_timeout_ms)))
    };
    if let Some(status) = outcome.error {
        let class = outcome.class.unwrap_or(Rejection::Refused);
        m.rejected(class).inc();
        if let Some(suppressed) = shared.log_admit(class.label()) {
            let reason = outcome.reason.as_deref().unwrap_or("");
            tracing::warn!(%peer, status = status.name(), reason, suppressed, "GVCP command rejected (one line per reason per 10 s; all counted in hilcam_gige_commands_rejected_total)");
        }
    }
    for e in &outcome.effects {
        match e {
            Effect::Settings | Effect::Exposure | Effect::Roi | Effect::FrameRate => {
                shared.settings_tx.send_replace(settings);
            }
            Effect::SoftwareTrigger => {
                shared.pending_triggers.fetch_add(1, Ordering::AcqRel);
                shared.triggers.fire();
            }
            Effect::AcquisitionStart => tracing::info!(%peer, "GigE Vision acquisition started"),
            Effect::AcquisitionStop => tracing::info!(%peer, "GigE Vision acquisition stopped"),
            _ => {}
        }
    }
    if let Some((block_id, first, last)) = outcome.resend {
        m.resend_requests.inc();
        if shared.jobs.push_resend(ResendJob { block_id, first, last }).is_err() {
            m.resend_queue_full.inc();
            if let Some(suppressed) = shared.log_admit("resend_queue_full") {
                tracing::warn!(%peer, suppressed, "GVSP resend request dropped: the resend queue is full");
            }
        }
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
