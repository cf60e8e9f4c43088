//! A minimal HTTP/1.1 server for `GET /metrics` (one request per connection), with
//! room for extra routes that later layers add (the live view's page and streams).

use super::Registry;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// Longest request head we read; anything longer is answered 431 and closed.
const MAX_HEAD: usize = 8 * 1024;
/// A client that sends no complete request head within this time is dropped.
const READ_TIMEOUT: Duration = Duration::from_secs(5);

/// Routes beside `/metrics`: the request path (no query) → the answer, None for 404.
pub type Routes = Arc<dyn Fn(&str) -> Option<Route> + Send + Sync>;

/// A long-lived answer: it gets the socket once the request head is read, and writes
/// the status line, headers and body itself (a `multipart/x-mixed-replace` stream).
pub type StreamHandler = Box<dyn FnOnce(TcpStream) -> Pin<Box<dyn Future<Output = ()> + Send>> + Send>;

/// What an extra route answers.
pub enum Route {
    /// `200 OK` with this body, then close.
    Body {
        content_type: &'static str,
        body: Vec<u8>,
    },
    Stream(StreamHandler),
}

/// Serve `registry` as Prometheus text on `GET /metrics`, and `routes`, until `shutdown`
/// completes.
///
/// Bind the listener yourself (127.0.0.1 unless exposing metrics is intended); each
/// connection gets its own task, answers one request and closes. Other paths are 404,
/// other methods 405.
pub async fn serve_http(
    listener: TcpListener,
    registry: Arc<Registry>,
    routes: Option<Routes>,
    shutdown: impl Future<Output = ()>,
) {
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            _ = &mut shutdown => break,
            accepted = listener.accept() => match accepted {
                Ok((sock, peer)) => {
                    let (registry, routes) = (registry.clone(), routes.clone());
                    tokio::spawn(async move {
                        if let Err(e) = handle(sock, &registry, routes.as_ref()).await {
                            tracing::debug!(%peer, "metrics http: {e}");
                        }
                    });
                }
                Err(e) => {
                    // Typically EMFILE: back off instead of spinning.
                    tracing::warn!("metrics http accept: {e}");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            },
        }
    }
}

async fn handle(mut sock: TcpStream, registry: &Registry, routes: Option<&Routes>) -> std::io::Result<()> {
    let mut head = Vec::with_capacity(512);
    let mut buf = [0u8; 1024];
    let complete = tokio::time::timeout(READ_TIMEOUT, async {
        while !head.windows(4).any(|w| w == b"\r\n\r\n") && head.len() <= MAX_HEAD {
            let n = sock.read(&mut buf).await?;
            if n == 0 {
                return Ok::<bool, std::io::Error>(false);
            }
            head.extend_from_slice(&buf[..n]);
        }
        Ok(true)
    })
    .await;
    let complete = match complete {
        Ok(r) => r?,
        Err(_) => return Ok(()), // timed out: just close
    };
    if !complete {
        return Ok(());
    }
    let (status, ctype, body) = if head.len() > MAX_HEAD {
        ("431 Request Header Fields Too Large", "text/plain", Vec::new())
    } else {
        let line = head.split(|b| *b == b'\r').next().unwrap_or(&[]);
        let line = String::from_utf8_lossy(line);
        let mut parts = line.split(' ');
        let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
        let path = target.split('?').next().unwrap_or("");
        match (method, path) {
            ("GET" | "HEAD", "/metrics") => {
                ("200 OK", "text/plain; version=0.0.4; charset=utf-8", registry.render_prometheus().into_bytes())
            }
            ("GET" | "HEAD", _) => match routes.and_then(|r| r(path)) {
                Some(Route::Body { content_type, body }) => ("200 OK", content_type, body),
                Some(Route::Stream(handler)) => {
                    handler(sock).await;
                    return Ok(());
                }
                None => ("404 Not Found", "text/plain", b"not found\n".to_vec()),
            },
            _ => ("405 Method Not Allowed", "text/plain", "only GET\n".into()),
        }
    };
    let is_head = head.starts_with(b"HEAD ");
    let mut resp = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )
    .into_bytes();
    if !is_head {
        resp.extend_from_slice(&body);
    }
    sock.write_all(&resp).await?;
    sock.shutdown().await
}
