//! The server's observability helpers: the `/metrics` endpoint, the periodic summary
//! line and the mirror of the transports' counters into the registry.

use super::config::ServeConfig;
use crate::link::InputCounters;
use crate::metrics::{Registry, Routes, serve_http, spawn_summary_logger};
use crate::shutdown::Shutdown;
use anyhow::Context;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;

pub(super) struct Helpers {
    pub metrics_addr: Option<SocketAddr>,
    tasks: Vec<JoinHandle<()>>,
    mirror: CounterMirror,
}

impl Helpers {
    /// Start them; they run until `shutdown`. `routes` are served beside `/metrics`.
    pub async fn start(
        cfg: &ServeConfig,
        registry: &Arc<Registry>,
        routes: Option<Routes>,
        counters: &Arc<InputCounters>,
        shutdown: &Shutdown,
    ) -> anyhow::Result<Helpers> {
        let mut tasks = Vec::new();
        let mut metrics_addr = None;
        if let Some(addr) = cfg.metrics.listen {
            let listener =
                tokio::net::TcpListener::bind(addr).await.with_context(|| format!("metrics listen {addr}"))?;
            metrics_addr = Some(listener.local_addr()?);
            tasks.push(tokio::spawn(serve_http(listener, registry.clone(), routes, shutdown.clone().wait_owned())));
        }
        let mirror = CounterMirror { registry: registry.clone(), counters: counters.clone(), seen: Default::default() };
        mirror.copy();
        tasks.push(tokio::spawn(mirror.clone().every(Duration::from_millis(250), shutdown.clone())));
        let interval = Duration::from_secs_f64(cfg.metrics.print_interval_s);
        tasks.push(spawn_summary_logger(registry.clone(), interval, shutdown.clone().wait_owned()));
        Ok(Helpers { metrics_addr, tasks, mirror })
    }

    /// Wait for them to stop (after `shutdown`) and copy the counters a last time.
    pub async fn join(self) {
        for t in self.tasks {
            let _ = t.await;
        }
        self.mirror.copy();
    }
}

/// Copies the transports' atomic counters into the registry (as deltas, so they stay
/// counters).
#[derive(Clone)]
struct CounterMirror {
    registry: Arc<Registry>,
    counters: Arc<InputCounters>,
    /// The value last copied, per series.
    seen: Arc<Mutex<HashMap<String, u64>>>,
}

impl CounterMirror {
    /// The first call registers every counter, zeros included, so `/metrics` lists them
    /// all from the start (the Prometheus convention).
    fn copy(&self) {
        let mut seen = self.seen.lock().expect("counter mirror lock");
        self.counters.for_each(|name, labels, v| {
            let key = format!("{name}{{{labels}}}");
            let first = !seen.contains_key(&key);
            let last = seen.entry(key).or_insert(0);
            if v > *last || first {
                let label_pairs: Vec<(&str, String)> = labels
                    .split(',')
                    .filter_map(|kv| kv.split_once('=').map(|(k, v)| (k, v.trim_matches('"').to_string())))
                    .collect();
                let refs: Vec<(&str, &str)> = label_pairs.iter().map(|(k, v)| (*k, v.as_str())).collect();
                self.registry.counter(name, "pose input counter (see docs/protocol.md)", &refs).add(v - *last);
                *last = v;
            }
        });
    }

    async fn every(self, period: Duration, shutdown: Shutdown) {
        let mut t = tokio::time::interval(period);
        loop {
            tokio::select! {
                _ = t.tick() => self.copy(),
                _ = shutdown.wait() => break,
            }
        }
    }
}
