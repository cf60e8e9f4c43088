//! The periodic one-line metrics summary (tracing `info`).

use super::{HistogramSnapshot, Registry, RegistrySnapshot};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

/// One line: every non-zero counter/gauge as `name{labels}=total(+delta)`, and every
/// histogram's interval count and p50/p95/p99 in ms (values recorded since `prev`).
pub fn summary_line(now: &RegistrySnapshot, prev: &RegistrySnapshot) -> String {
    let before: HashMap<&str, i64> = prev.values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let hist_before: HashMap<&str, &HistogramSnapshot> = prev.histograms.iter().map(|(k, h)| (k.as_str(), h)).collect();
    let mut parts = Vec::new();
    for (k, v) in &now.values {
        if *v == 0 {
            continue;
        }
        let d = v - before.get(k.as_str()).copied().unwrap_or(0);
        parts.push(format!("{k}={v}({d:+})"));
    }
    for (k, h) in &now.histograms {
        let h = match hist_before.get(k.as_str()) {
            Some(p) => h.since(p),
            None => h.clone(),
        };
        if h.count == 0 {
            continue;
        }
        let ms = |q| h.quantile(q).map_or(f64::NAN, |ns| ns as f64 / 1e6);
        parts.push(format!("{k} n={} p50={:.3}ms p95={:.3}ms p99={:.3}ms", h.count, ms(0.5), ms(0.95), ms(0.99)));
    }
    if parts.is_empty() { "no activity".into() } else { parts.join(" ") }
}

/// Log [`summary_line`] at `info` every `period` until the returned task is aborted
/// or `shutdown` completes.
pub fn spawn_summary_logger(
    registry: Arc<Registry>,
    period: Duration,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        tokio::pin!(shutdown);
        let mut tick = tokio::time::interval(period);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        tick.tick().await; // the first tick is immediate
        let mut prev = registry.snapshot();
        loop {
            tokio::select! {
                _ = &mut shutdown => break,
                _ = tick.tick() => {
                    let now = registry.snapshot();
                    tracing::info!(target: "crate::metrics", "{}", summary_line(&now, &prev));
                    prev = now;
                }
            }
        }
    })
}
