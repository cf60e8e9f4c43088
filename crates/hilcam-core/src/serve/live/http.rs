//! The live view's routes on the metrics listener: the page, its state and the image
//! stream (MJPEG: `multipart/x-mixed-replace`, which an `<img>` shows as it arrives).

use super::{Shared, Viewer};
use crate::metrics::{Route, Routes};
use crate::sink::queue::DropOldest;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;

/// The page: HTML, CSS and JS in one file, no external assets.
const PAGE: &str = include_str!("page.html");

/// Series shown in the page's counters table: every counter and gauge whose name starts
/// with one of these (the same keys and values as `/metrics`).
const COUNTER_PREFIXES: [&str; 5] =
    ["hilcam_frames_", "hilcam_poses_", "hilcam_input_", "hilcam_live_", "hilcam_triggers_"];

const BOUNDARY: &str = "hilcamframe";

/// A viewer socket's send buffer, bytes (the kernel doubles it): about one 512-pixel preview.
const SEND_BUFFER: usize = 16 * 1024;

pub(super) fn routes(shared: Arc<Shared>) -> Routes {
    Arc::new(move |path: &str| match path {
        "/live" | "/live/" => Some(Route::Body { content_type: "text/html; charset=utf-8", body: PAGE.into() }),
        "/live/state.json" => Some(Route::Body { content_type: "application/json", body: state_json(&shared) }),
        "/live/stream.mjpeg" => {
            let shared = shared.clone();
            Some(Route::Stream(Box::new(move |sock| Box::pin(stream(shared, sock)))))
        }
        _ => None,
    })
}

fn state_json(s: &Shared) -> Vec<u8> {
    let mut v = s.state.lock().expect("live state poisoned").to_json();
    let snap = s.registry.snapshot();
    let counters: Vec<(String, i64)> =
        snap.values.into_iter().filter(|(k, _)| COUNTER_PREFIXES.iter().any(|p| k.starts_with(p))).collect();
    v["counters"] = serde_json::json!(counters);
    let preview = s.preview.lock().expect("live preview poisoned").as_ref().map(|p| p.frame_seq);
    v["preview_seq"] = serde_json::json!(preview);
    let e = s.m.encode.snapshot();
    v["encode_ms_p50"] = serde_json::json!(e.quantile(0.5).map(|ns| ns as f64 / 1e6));
    serde_json::to_vec(&v).unwrap_or_default()
}

/// One viewer's image stream: the newest preview now, then each new one through the
/// viewer's drop-oldest queue, until it leaves, stalls or the server stops.
async fn stream(s: Arc<Shared>, mut sock: TcpStream) {
    let Some(viewer) = admit(&s) else {
        s.m.refused.inc();
        let _ =
            sock.write_all(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n").await;
        return;
    };
    s.m.viewers.inc();
    if let Some(p) = s.preview.lock().expect("live preview poisoned").clone() {
        viewer.queue.push(p);
    }
    // A frame that arrived while nobody watched is encoded now.
    s.watching.fetch_add(1, Relaxed);
    s.wake.notify_one();
    let _ = sock.set_nodelay(true);
    // A small kernel buffer: a slow browser's backlog waits in its drop-oldest queue,
    // where newer previews replace it, not in the socket, where it would show seconds late.
    let _ = socket2::SockRef::from(&sock).set_send_buffer_size(SEND_BUFFER);
    let evicted = serve_previews(&s, &viewer, &mut sock).await;
    if evicted {
        s.m.evicted.inc();
        tracing::warn!("live viewer closed: it stopped reading");
    }
    s.watching.fetch_sub(1, Relaxed);
    s.viewers.lock().expect("live viewers poisoned").retain(|v| !Arc::ptr_eq(v, &viewer));
    s.m.viewers.dec();
}

/// A new viewer, or None when `max_viewers` are watching.
fn admit(s: &Shared) -> Option<Arc<Viewer>> {
    let mut viewers = s.viewers.lock().expect("live viewers poisoned");
    if viewers.len() >= s.cfg.max_viewers {
        return None;
    }
    let v = Arc::new(Viewer { queue: DropOldest::new(s.cfg.queue_depth) });
    viewers.push(v.clone());
    Some(v)
}

/// Write previews until the viewer leaves or the server stops (false), or the viewer
/// stalled for `evict_after_s` (true).
///
/// Each part is followed by the next boundary at once: a browser shows a part only once
/// it sees the boundary after it (the Content-Length is not enough for Chromium), and
/// the newest frame must not wait for the next one.
async fn serve_previews(s: &Shared, viewer: &Viewer, sock: &mut TcpStream) -> bool {
    let head = format!(
        "HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary={BOUNDARY}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n\r\n--{BOUNDARY}\r\n"
    );
    if sock.write_all(head.as_bytes()).await.is_err() {
        return false;
    }
    loop {
        let p = loop {
            if let Some(p) = viewer.queue.take() {
                break p;
            }
            tokio::select! {
                _ = viewer.queue.pushed() => {}
                _ = s.stop.wait() => return false,
            }
        };
        let part = format!(
            "Content-Type: image/jpeg\r\nContent-Length: {}\r\nX-Frame-Seq: {}\r\n\r\n",
            p.jpeg.len(),
            p.frame_seq
        );
        let write = async {
            sock.write_all(part.as_bytes()).await?;
            sock.write_all(&p.jpeg).await?;
            sock.write_all(format!("\r\n--{BOUNDARY}\r\n").as_bytes()).await
        };
        tokio::select! {
            r = write => {
                if r.is_err() {
                    return false;
                }
                s.m.sent.inc();
            }
            _ = viewer.queue.stalled(s.cfg.evict_after()) => return true,
            _ = s.stop.wait() => return false,
        }
    }
}
