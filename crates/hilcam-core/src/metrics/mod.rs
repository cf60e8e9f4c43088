//! Run-time metrics: a generic registry of labelled counters, gauges and latency
//! histograms, rendered as Prometheus text (format 0.0.4), served on an optional HTTP
//! port, and summarised periodically in one `tracing` info line.
//!
//! Any module registers its own series by name (`registry.counter("hilcam_poses_total",
//! help, &[("result", "rejected"), ("reason", "crc")])`) and keeps the returned handle;
//! updating it is one relaxed atomic add, no lock.

mod histogram;
mod http;
mod prometheus;
mod summary;

pub use histogram::{BUCKETS, Histogram, HistogramSnapshot, bucket_bounds, bucket_of};
pub use http::{Route, Routes, StreamHandler, serve_http};
pub use summary::{spawn_summary_logger, summary_line};

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};

/// A monotonically increasing count (Prometheus `counter`). Cloning shares the value.
#[derive(Clone, Debug, Default)]
pub struct Counter(Arc<AtomicU64>);

impl Counter {
    pub fn inc(&self) {
        self.0.fetch_add(1, Relaxed);
    }
    pub fn add(&self, n: u64) {
        self.0.fetch_add(n, Relaxed);
    }
    pub fn get(&self) -> u64 {
        self.0.load(Relaxed)
    }
}

/// A value that goes up and down (Prometheus `gauge`). Cloning shares the value.
#[derive(Clone, Debug, Default)]
pub struct Gauge(Arc<AtomicI64>);

impl Gauge {
    pub fn set(&self, v: i64) {
        self.0.store(v, Relaxed);
    }
    pub fn inc(&self) {
        self.0.fetch_add(1, Relaxed);
    }
    pub fn dec(&self) {
        self.0.fetch_sub(1, Relaxed);
    }
    pub fn get(&self) -> i64 {
        self.0.load(Relaxed)
    }
}

/// The kind of a metric family, as in the `# TYPE` line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Counter,
    Gauge,
    /// A latency histogram exposed as a Prometheus `summary` (p50/p95/p99, sum, count).
    Summary,
}

/// Label pairs in the order they were registered.
pub type Labels = Vec<(String, String)>;

#[derive(Clone, Debug)]
pub(crate) enum Series {
    Counter(Counter),
    Gauge(Gauge),
    Summary(Arc<Histogram>),
}

#[derive(Debug)]
pub(crate) struct Family {
    pub help: String,
    pub kind: Kind,
    pub series: BTreeMap<Labels, Series>,
}

/// Named metric families, each a set of labelled series. Share it as `Arc<Registry>`.
///
/// Histograms record nanoseconds and are exposed in seconds: name them `*_seconds`.
#[derive(Debug, Default)]
pub struct Registry {
    families: Mutex<BTreeMap<String, Family>>,
}

impl Registry {
    pub fn new() -> Arc<Registry> {
        Arc::new(Registry::default())
    }

    /// The counter `name{labels}`, created at 0 on first use.
    ///
    /// # Panics
    /// If `name` or a label name is not a valid Prometheus name, or `name` was already
    /// registered as another kind (both are programming errors, not run-time input).
    pub fn counter(&self, name: &str, help: &str, labels: &[(&str, &str)]) -> Counter {
        match self.series(name, help, Kind::Counter, labels) {
            Series::Counter(c) => c,
            _ => unreachable!("kind checked"),
        }
    }

    /// The gauge `name{labels}`, created at 0 on first use. Panics as [`Registry::counter`].
    pub fn gauge(&self, name: &str, help: &str, labels: &[(&str, &str)]) -> Gauge {
        match self.series(name, help, Kind::Gauge, labels) {
            Series::Gauge(g) => g,
            _ => unreachable!("kind checked"),
        }
    }

    /// The latency histogram `name{labels}` (values in ns, exposed in seconds as a
    /// summary with quantiles 0.5, 0.95, 0.99). Panics as [`Registry::counter`].
    pub fn histogram(&self, name: &str, help: &str, labels: &[(&str, &str)]) -> Arc<Histogram> {
        match self.series(name, help, Kind::Summary, labels) {
            Series::Summary(h) => h,
            _ => unreachable!("kind checked"),
        }
    }

    fn series(&self, name: &str, help: &str, kind: Kind, labels: &[(&str, &str)]) -> Series {
        assert!(valid_name(name), "invalid metric name {name:?}");
        for (k, _) in labels {
            assert!(valid_name(k) && !k.contains(':') && *k != "quantile", "metric {name}: invalid label name {k:?}");
        }
        let mut families = self.families.lock().expect("metrics registry poisoned");
        let family = families.entry(name.to_string()).or_insert_with(|| Family {
            help: help.to_string(),
            kind,
            series: BTreeMap::new(),
        });
        assert_eq!(family.kind, kind, "metric {name} registered as {:?}, requested as {kind:?}", family.kind);
        let key: Labels = labels.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        family
            .series
            .entry(key)
            .or_insert_with(|| match kind {
                Kind::Counter => Series::Counter(Counter::default()),
                Kind::Gauge => Series::Gauge(Gauge::default()),
                Kind::Summary => Series::Summary(Arc::new(Histogram::new())),
            })
            .clone()
    }

    /// Prometheus text exposition format 0.0.4 of every series.
    pub fn render_prometheus(&self) -> String {
        let families = self.families.lock().expect("metrics registry poisoned");
        prometheus::render(&families)
    }

    /// Every counter and gauge as (`name{labels}`, value), and every histogram's
    /// snapshot, in name order (for the summary line and for tests).
    pub fn snapshot(&self) -> RegistrySnapshot {
        let families = self.families.lock().expect("metrics registry poisoned");
        let mut snap = RegistrySnapshot::default();
        for (name, fam) in families.iter() {
            for (labels, s) in &fam.series {
                let key = series_key(name, labels);
                match s {
                    Series::Counter(c) => snap.values.push((key, c.get() as i64)),
                    Series::Gauge(g) => snap.values.push((key, g.get())),
                    Series::Summary(h) => snap.histograms.push((key, h.snapshot())),
                }
            }
        }
        snap
    }
}

/// See [`Registry::snapshot`].
#[derive(Clone, Debug, Default)]
pub struct RegistrySnapshot {
    pub values: Vec<(String, i64)>,
    pub histograms: Vec<(String, HistogramSnapshot)>,
}

/// `name{k="v",…}` (or just `name`), values escaped as in the exposition format.
pub fn series_key(name: &str, labels: &Labels) -> String {
    if labels.is_empty() {
        return name.to_string();
    }
    let inner: Vec<String> = labels.iter().map(|(k, v)| format!("{k}=\"{}\"", prometheus::escape_label(v))).collect();
    format!("{name}{{{}}}", inner.join(","))
}

/// `[a-zA-Z_:][a-zA-Z0-9_:]*`
fn valid_name(s: &str) -> bool {
    let mut chars = s.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_' || c == ':')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_name_and_labels_share_one_series() {
        let r = Registry::new();
        r.counter("x_total", "x", &[("a", "1")]).add(2);
        r.counter("x_total", "x", &[("a", "1")]).inc();
        r.counter("x_total", "x", &[("a", "2")]).inc();
        assert_eq!(r.counter("x_total", "x", &[("a", "1")]).get(), 3);
        assert_eq!(r.snapshot().values.len(), 2);
    }

    #[test]
    #[should_panic(expected = "registered as Counter")]
    fn kind_clash_is_a_programming_error() {
        let r = Registry::new();
        r.counter("y", "y", &[]);
        r.gauge("y", "y", &[]);
    }

    #[test]
    fn names_are_validated() {
        assert!(valid_name("hilcam_frames_total"));
        assert!(valid_name("a:b_c1"));
        assert!(!valid_name("1abc"));
        assert!(!valid_name("a-b"));
        assert!(!valid_name(""));
    }
}
