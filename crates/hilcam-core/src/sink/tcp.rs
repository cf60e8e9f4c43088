//! The TCP frame stream: any number of clients, each fed from its own bounded queue.
//!
//! Client policy, from mild to severe:
//! - **Slow client → drop the oldest.** When a client's queue holds `queue_depth` frames
//!   and a new one is published, the oldest queued frame is discarded and counted
//!   (`hilcam_stream_frames_dropped_total{reason="queue_full"}`); a slow client therefore
//!   always gets the newest frame next, and sees the loss as a gap in `frame_seq`.
//! - **Stalled client → evicted.** A client whose queue has stayed full for longer than
//!   `evict_after` (the frame in its socket never finished, so nothing was taken off the
//!   queue) is disconnected, freeing its slot; counted
//!   (`hilcam_stream_clients_evicted_total{reason="stalled"}`) and logged once with its
//!   peer address and how long it was stalled. A client that reads at all, however
//!   slowly, empties its queue now and then and is never evicted.
//! - **Full server → refused.** A connection beyond `max_clients` is accepted and closed
//!   at once (`hilcam_stream_clients_rejected_total`, logged).
//!
//! [`StreamServer::publish`] takes a short std mutex per client and never awaits, so a
//! stalled client can neither delay the renderer nor another client. Frames are shared
//! (`Arc<EncodedFrame>`), never copied per client.

use super::queue::DropOldest;
use crate::frame::EncodedFrame;
use crate::metrics::{Counter, Gauge, Histogram, Registry};
use crate::shutdown::Shutdown;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;

/// Stream server settings.
#[derive(Clone, Debug)]
pub struct StreamConfig {
    /// Listen address; 127.0.0.1 by default (the stream has no authentication).
    pub bind: SocketAddr,
    /// Frames queued per client before the oldest is dropped (≥ 1; default 2). A client
    /// also holds the one frame being written.
    pub queue_depth: usize,
    /// Connections beyond this are accepted and closed at once (counted, logged).
    pub max_clients: usize,
    /// On shutdown, how long a client may take to finish the frame being written.
    pub shutdown_grace: Duration,
    /// Disconnect a client whose queue has been full for this long without a break
    /// (it stopped reading); None: never. Default [`DEFAULT_EVICT_AFTER`].
    pub evict_after: Option<Duration>,
}

/// Long enough for a 1 Hz stream (whose queue of 2 fills in 2 s) to ride out a client's
/// pause of a few seconds; short enough that stalled clients cannot hold every slot for
/// long at 30 Hz.
pub const DEFAULT_EVICT_AFTER: Duration = Duration::from_secs(5);

impl Default for StreamConfig {
    fn default() -> Self {
        StreamConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 5600)),
            queue_depth: 2,
            max_clients: 32,
            shutdown_grace: Duration::from_secs(2),
            evict_after: Some(DEFAULT_EVICT_AFTER),
        }
    }
}

/// Reported after the last byte of a frame went into a client's socket (kernel send
/// buffer): the end point of the "pose arrival → last byte written" latency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameWritten {
    pub client_id: u64,
    pub frame_seq: u64,
    pub last_byte: Instant,
    pub last_byte_unix_ns: u64,
    pub pose_arrival_unix_ns: u64,
}

impl FrameWritten {
    /// Pose arrival to last byte written, ns (wall clock; 0 if the clock stepped back).
    pub fn latency_ns(&self) -> u64 {
        self.last_byte_unix_ns.saturating_sub(self.pose_arrival_unix_ns)
    }
}

/// Called from the client's task after each frame is written; keep it short.
pub type WriteHook = Arc<dyn Fn(&FrameWritten) + Send + Sync>;

/// What one [`StreamServer::publish`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PublishReport {
    /// Clients the frame was queued for.
    pub clients: usize,
    /// Of those, how many had to drop their oldest queued frame to take it.
    pub dropped: usize,
}

/// A client's counters, as seen now.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClientStats {
    pub id: u64,
    pub peer: SocketAddr,
    pub sent: u64,
    /// Frames dropped because the queue was full (the gaps the client sees).
    pub dropped: u64,
    pub queued: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    #[error("frame stream: cannot listen on {addr}: {source}")]
    Bind { addr: SocketAddr, source: std::io::Error },
}

struct Client {
    id: u64,
    peer: SocketAddr,
    queue: DropOldest<Arc<EncodedFrame>>,
    sent: Counter,
    dropped: Counter,
    unsent: Counter,
}

struct Shared {
    cfg: StreamConfig,
    registry: Arc<Registry>,
    hook: Option<WriteHook>,
    clients: Mutex<Vec<Arc<Client>>>,
    next_id: AtomicU64,
    connected: Gauge,
    accepted: Counter,
    rejected: Counter,
    published: Counter,
    bytes: Counter,
    write_errors: Counter,
    evicted: Counter,
    latency: Arc<Histogram>,
}

/// The frame stream server. Create with [`StreamServer::bind`], feed with
/// [`StreamServer::publish`], end with [`StreamServer::shutdown`] (dropping it stops the
/// accept loop and the clients too, without waiting for them).
pub struct StreamServer {
    shared: Arc<Shared>,
    local_addr: SocketAddr,
    /// The server's own stop signal: the accept loop and every client task hold it.
    stop: Shutdown,
    /// Taken by [`StreamServer::shutdown`] to wait for the loop.
    accept_task: Option<tokio::task::JoinHandle<()>>,
}

impl Drop for StreamServer {
    fn drop(&mut self) {
        self.stop.trigger();
    }
}

impl StreamServer {
    /// Listen on `cfg.bind` and start accepting clients (on the current tokio runtime).
    /// Metrics go to `registry` (names `hilcam_stream_*`); `hook` sees every write.
    pub async fn bind(
        cfg: StreamConfig,
        registry: Arc<Registry>,
        hook: Option<WriteHook>,
    ) -> Result<StreamServer, StreamError> {
        let listener =
            TcpListener::bind(cfg.bind).await.map_err(|source| StreamError::Bind { addr: cfg.bind, source })?;
        let local_addr = listener.local_addr().map_err(|source| StreamError::Bind { addr: cfg.bind, source })?;
        let r = &registry;
        let shared = Arc::new(Shared {
            connected: r.gauge("hilcam_stream_clients", "Connected stream clients", &[]),
            accepted: r.counter("hilcam_stream_clients_accepted_total", "Stream clients accepted", &[]),
            rejected: r.counter(
                "hilcam_stream_clients_rejected_total",
                "Stream connections closed at once because max_clients were connected",
                &[],
            ),
            published: r.counter("hilcam_stream_frames_published_total", "Frames handed to the stream server", &[]),
            bytes: r.counter("hilcam_stream_bytes_sent_total", "Bytes written to stream clients (all clients)", &[]),
            write_errors: r.counter(
                "hilcam_stream_write_errors_total",
                "Stream clients dropped on a write error (disconnects)",
                &[],
            ),
            evicted: r.counter(
                "hilcam_stream_clients_evicted_total",
                "Stream clients disconnected because their queue stayed full for evict_after (stalled)",
                &[("reason", "stalled")],
            ),
            latency: r.histogram(
                "hilcam_stream_latency_seconds",
                "Pose arrival to last byte of the frame written to a client",
                &[],
            ),
            cfg: StreamConfig { queue_depth: cfg.queue_depth.max(1), ..cfg },
            registry,
            hook,
            clients: Mutex::new(Vec::new()),
            next_id: AtomicU64::new(1),
        });
        let stop = Shutdown::new();
        let accept_task = tokio::spawn(accept_loop(listener, shared.clone(), stop.clone()));
        tracing::info!(%local_addr, "frame stream listening");
        Ok(StreamServer { shared, local_addr, stop, accept_task: Some(accept_task) })
    }

    /// The bound address (useful with port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Queue `frame` for every connected client; never blocks on a client. A full
    /// queue drops its oldest frame (see the module docs).
    pub fn publish(&self, frame: Arc<EncodedFrame>) -> PublishReport {
        self.shared.published.inc();
        let clients = self.shared.clients.lock().expect("client list poisoned");
        let mut report = PublishReport { clients: clients.len(), dropped: 0 };
        for c in clients.iter() {
            if let Some(old) = c.queue.push(frame.clone()) {
                c.dropped.inc();
                report.dropped += 1;
                tracing::debug!(
                    client = c.id,
                    dropped_seq = old.meta.frame_seq,
                    "slow stream client: dropped oldest queued frame"
                );
            }
        }
        report
    }

    /// Connected clients and their counters.
    pub fn clients(&self) -> Vec<ClientStats> {
        let clients = self.shared.clients.lock().expect("client list poisoned");
        clients
            .iter()
            .map(|c| ClientStats {
                id: c.id,
                peer: c.peer,
                sent: c.sent.get(),
                dropped: c.dropped.get(),
                queued: c.queue.len(),
            })
            .collect()
    }

    pub fn client_count(&self) -> usize {
        self.shared.clients.lock().expect("client list poisoned").len()
    }

    /// Stop accepting, let every client finish the frame it is writing (up to
    /// `shutdown_grace`), close each connection cleanly, and wait for all of it.
    /// Frames still queued are discarded and counted (`reason="shutdown"`).
    pub async fn shutdown(mut self) {
        self.stop.trigger();
        if let Some(task) = self.accept_task.take()
            && let Err(e) = task.await
        {
            tracing::error!("frame stream accept task failed: {e}");
        }
        tracing::info!(addr = %self.local_addr, "frame stream closed");
    }
}

async fn accept_loop(listener: TcpListener, shared: Arc<Shared>, stop: Shutdown) {
    let mut tasks = JoinSet::new();
    loop {
        tokio::select! {
            _ = stop.wait() => break,
            Some(done) = tasks.join_next(), if !tasks.is_empty() => {
                if let Err(e) = done {
                    tracing::error!("stream client task failed: {e}");
                }
            }
            accepted = listener.accept() => match accepted {
                Ok((sock, peer)) => {
                    if let Some(client) = admit(&shared, peer) {
                        tasks.spawn(serve_client(shared.clone(), client, sock, stop.clone()));
                    }
                }
                Err(e) => {
                    // EMFILE and friends: back off rather than spin.
                    tracing::warn!("frame stream accept: {e}");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            },
        }
    }
    drop(listener);
    while let Some(done) = tasks.join_next().await {
        if let Err(e) = done {
            tracing::error!("stream client task failed: {e}");
        }
    }
}

/// Register a new client, or refuse it when `max_clients` are connected.
fn admit(shared: &Shared, peer: SocketAddr) -> Option<Arc<Client>> {
    let mut clients = shared.clients.lock().expect("client list poisoned");
    if clients.len() >= shared.cfg.max_clients {
        shared.rejected.inc();
        tracing::warn!(%peer, max = shared.cfg.max_clients, "stream client refused: too many clients");
        return None;
    }
    let id = shared.next_id.fetch_add(1, Relaxed);
    let ids = id.to_string();
    let dropped = |reason| {
        shared.registry.counter(
            "hilcam_stream_frames_dropped_total",
            "Frames a stream client lost: queue_full (slow client) or shutdown/closed (left in queue)",
            &[("client", &ids), ("reason", reason)],
        )
    };
    let client = Arc::new(Client {
        id,
        peer,
        queue: DropOldest::new(shared.cfg.queue_depth),
        sent: shared.registry.counter(
            "hilcam_stream_frames_sent_total",
            "Frames completely written to a stream client",
            &[("client", &ids)],
        ),
        dropped: dropped("queue_full"),
        unsent: dropped("closed"),
    });
    clients.push(client.clone());
    shared.accepted.inc();
    shared.connected.inc();
    tracing::info!(client = id, %peer, "stream client connected");
    Some(client)
}

/// Why a client's task ended.
#[derive(Debug)]
enum End {
    Shutdown,
    WriteError(std::io::Error),
    GraceExpired,
    /// The queue stayed full this long: the client stopped reading.
    Stalled(Duration),
}

async fn serve_client(shared: Arc<Shared>, client: Arc<Client>, sock: TcpStream, stop: Shutdown) {
    // Frames are written whole; Nagle would only delay the tail of each frame.
    let _ = sock.set_nodelay(true);
    let (mut rd, mut wr) = sock.into_split();
    let mut reading = true;
    let mut scratch = [0u8; 512];
    let end = 'frames: loop {
        // Wait for the next frame; meanwhile discard anything the client sends and
        // notice EOF (after which the client may still read, so keep writing).
        let frame = loop {
            if stop.is_triggered() {
                break 'frames End::Shutdown;
            }
            if let Some(f) = client.queue.take() {
                break f;
            }
            tokio::select! {
                _ = client.queue.pushed() => {}
                _ = stop.wait() => break 'frames End::Shutdown,
                r = rd.read(&mut scratch), if reading => {
                    if !matches!(r, Ok(n) if n > 0) {
                        reading = false;
                    }
                }
            }
        };
        // Write the whole frame; on shutdown, allow `shutdown_grace` to finish it.
        let write = wr.write_all(&frame.bytes);
        let grace = async {
            stop.wait().await;
            tokio::time::sleep(shared.cfg.shutdown_grace).await;
        };
        // A client that stopped reading blocks here, with its queue filling behind it.
        tokio::select! {
            r = write => {
                if let Err(e) = r {
                    break 'frames End::WriteError(e);
                }
            }
            _ = grace => break 'frames End::GraceExpired,
            d = client.queue.stalled(shared.cfg.evict_after) => break 'frames End::Stalled(d),
        }
        let ev = FrameWritten {
            client_id: client.id,
            frame_seq: frame.meta.frame_seq,
            last_byte: Instant::now(),
            last_byte_unix_ns: crate::frame::unix_ns_now(),
            pose_arrival_unix_ns: frame.meta.pose_arrival_unix_ns,
        };
        client.sent.inc();
        shared.bytes.add(frame.bytes.len() as u64);
        if ev.pose_arrival_unix_ns != 0 {
            // 0 means "no pose time" (e.g. a test pattern): nothing to measure from.
            shared.latency.record(ev.latency_ns());
        }
        if let Some(hook) = &shared.hook {
            hook(&ev);
        }
    };
    // Leave the list first so that publish stops queueing for us.
    shared.clients.lock().expect("client list poisoned").retain(|c| c.id != client.id);
    shared.connected.dec();
    let left = client.queue.clear();
    client.unsent.add(left as u64);
    match &end {
        End::Shutdown => {
            // Clean close: FIN after the last complete frame.
            let _ = tokio::time::timeout(shared.cfg.shutdown_grace, wr.shutdown()).await;
        }
        End::WriteError(e) => {
            shared.write_errors.inc();
            tracing::warn!(client = client.id, peer = %client.peer, "stream write failed (client gone?): {e}");
        }
        End::GraceExpired => {}
        End::Stalled(d) => {
            shared.evicted.inc();
            // Reset instead of FIN: the kernel drops the frames still in the socket buffer
            // now rather than holding them for a peer that does not read.
            let _ = wr.as_ref().set_zero_linger();
            tracing::warn!(
                client = client.id,
                peer = %client.peer,
                stalled_s = format!("{:.1}", d.as_secs_f64()),
                "stream client evicted: its queue stayed full (not reading)"
            );
        }
    }
    tracing::info!(
        client = client.id,
        peer = %client.peer,
        sent = client.sent.get(),
        dropped = client.dropped.get(),
        discarded = left,
        reason = ?end,
        "stream client closed"
    );
}
