//! Metrics: histogram percentiles against exact ones, Prometheus text, HTTP endpoint.

use hilcam_core::metrics::*;
use proptest::prelude::*;
use std::collections::BTreeMap;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Exact nearest-rank quantile: the ⌈q·n⌉-th smallest value.
fn exact(sorted: &[u64], q: f64) -> u64 {
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// The histogram's answer must lie within half a bucket of the exact value:
/// ≤ 1/128 relative above 128 ns, exact below.
fn assert_close(got: u64, want: u64, what: &str) {
    let tol = want / 128;
    assert!(got.abs_diff(want) <= tol, "{what}: histogram {got}, exact {want}, tolerance {tol}");
    assert!((got as f64 - want as f64).abs() <= 0.01 * want as f64, "{what}: beyond 1 %");
}

/// Deterministic pseudo-random latencies spanning 10 ns .. ~10 s (xorshift, log-uniform).
fn latencies(n: usize, mut x: u64) -> Vec<u64> {
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = (x >> 11) as f64 / (1u64 << 53) as f64;
            (10f64 * 1e9f64.powf(u)) as u64
        })
        .collect()
}

#[test]
fn percentiles_match_exact_percentiles_within_bucket_resolution() {
    let data = latencies(100_000, 0x9E37_79B9_7F4A_7C15);
    let h = Histogram::new();
    for &v in &data {
        h.record(v);
    }
    let mut sorted = data.clone();
    sorted.sort_unstable();
    let s = h.snapshot();
    assert_eq!(s.count, data.len() as u64);
    assert_eq!(s.sum, data.iter().sum::<u64>());
    assert_eq!((s.min, s.max), (Some(sorted[0]), Some(*sorted.last().unwrap())));
    for q in [0.001, 0.01, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 0.999, 1.0] {
        assert_close(s.quantile(q).unwrap(), exact(&sorted, q), &format!("q={q}"));
    }
}

proptest! {
    #[test]
    fn any_data_percentiles_are_within_resolution(
        data in prop::collection::vec(0u64..u64::MAX / 2, 1..400),
        q in 0.001f64..=1.0,
    ) {
        let h = Histogram::new();
        for &v in &data { h.record(v); }
        let mut sorted = data.clone();
        sorted.sort_unstable();
        let got = h.snapshot().quantile(q).unwrap();
        let want = exact(&sorted, q);
        prop_assert!(got.abs_diff(want) <= want / 128, "got {got} want {want}");
    }
}

#[test]
fn interval_snapshots_see_only_the_new_values() {
    let h = Histogram::new();
    for v in latencies(5000, 7) {
        h.record(v);
    }
    let before = h.snapshot();
    let second: Vec<u64> = (1..=1000).map(|i| i * 1_000_000).collect(); // 1..1000 ms
    for &v in &second {
        h.record(v);
    }
    let d = h.snapshot().since(&before);
    assert_eq!(d.count, 1000);
    assert_eq!(d.sum, second.iter().sum::<u64>());
    for q in [0.5, 0.95, 0.99] {
        assert_close(d.quantile(q).unwrap(), exact(&second, q), &format!("q={q}"));
    }
    assert_eq!(Histogram::new().snapshot().quantile(0.5), None);
}

/// One sample line: name, labels in order, value.
type Sample = (String, Vec<(String, String)>, f64);

/// A strict reader for the subset of the text format we emit.
#[derive(Debug, Default)]
struct Parsed {
    types: BTreeMap<String, String>,
    helps: BTreeMap<String, String>,
    samples: Vec<Sample>,
}

fn parse_prometheus(text: &str) -> Parsed {
    let mut p = Parsed::default();
    let name_ok = |n: &str| {
        !n.is_empty()
            && !n.starts_with(|c: char| c.is_ascii_digit())
            && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':')
    };
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("# HELP ") {
            let (n, h) = rest.split_once(' ').unwrap();
            p.helps.insert(n.into(), h.into());
        } else if let Some(rest) = line.strip_prefix("# TYPE ") {
            let (n, t) = rest.split_once(' ').unwrap();
            assert!(["counter", "gauge", "summary"].contains(&t), "{line}");
            assert!(p.types.insert(n.into(), t.into()).is_none(), "TYPE twice: {line}");
        } else {
            let (name, rest) = match line.find('{') {
                Some(i) => (&line[..i], &line[i..]),
                None => line.split_at(line.find(' ').unwrap()),
            };
            assert!(name_ok(name), "{line}");
            let mut labels = Vec::new();
            let mut chars = rest.chars().peekable();
            if chars.peek() == Some(&'{') {
                chars.next();
                loop {
                    let k: String = chars.by_ref().take_while(|c| *c != '=').collect();
                    assert_eq!(chars.next(), Some('"'), "{line}");
                    let mut v = String::new();
                    loop {
                        match chars.next().unwrap() {
                            '\\' => match chars.next().unwrap() {
                                'n' => v.push('\n'),
                                c => v.push(c),
                            },
                            '"' => break,
                            c => v.push(c),
                        }
                    }
                    assert!(name_ok(&k), "{line}");
                    labels.push((k, v));
                    match chars.next() {
                        Some(',') => continue,
                        Some('}') => break,
                        c => panic!("{line}: unexpected {c:?}"),
                    }
                }
            }
            let value: String = chars.collect();
            let value = value.strip_prefix(' ').expect("space before value");
            let v: f64 = match value {
                "NaN" => f64::NAN,
                "+Inf" => f64::INFINITY,
                "-Inf" => f64::NEG_INFINITY,
                s => s.parse().unwrap_or_else(|_| panic!("{line}: value {s:?}")),
            };
            let family = ["_sum", "_count"]
                .iter()
                .find_map(|s| name.strip_suffix(s).filter(|f| p.types.get(*f).is_some_and(|t| t == "summary")))
                .unwrap_or(name);
            assert!(p.types.contains_key(family), "sample before its TYPE: {line}");
            p.samples.push((name.into(), labels, v));
        }
    }
    p
}

fn sample(p: &Parsed, name: &str, labels: &[(&str, &str)]) -> f64 {
    p.samples
        .iter()
        .find(|(n, l, _)| {
            n == name && l.len() == labels.len() && l.iter().zip(labels).all(|(a, b)| a.0 == b.0 && a.1 == b.1)
        })
        .unwrap_or_else(|| panic!("no sample {name}{labels:?}"))
        .2
}

#[test]
fn prometheus_text_parses_with_names_labels_and_values() {
    let r = Registry::new();
    r.counter("hilcam_poses_total", "Poses by result", &[("result", "accepted")]).add(41);
    r.counter("hilcam_poses_total", "Poses by result", &[("result", "rejected"), ("reason", "crc")]).inc();
    let odd = "say \"hi\"\\\nbye";
    r.counter("hilcam_odd_total", "Help with \\ and\nnewline", &[("v", odd)]).add(3);
    r.gauge("hilcam_clients", "Connected", &[]).set(-2);
    let h = r.histogram("hilcam_latency_seconds", "Latency", &[("sink", "tcp")]);
    for ms in 1..=100u64 {
        h.record(ms * 1_000_000);
    }
    let text = r.render_prometheus();
    let p = parse_prometheus(&text);
    assert_eq!(p.types["hilcam_poses_total"], "counter");
    assert_eq!(p.types["hilcam_clients"], "gauge");
    assert_eq!(p.types["hilcam_latency_seconds"], "summary");
    assert_eq!(p.helps["hilcam_odd_total"], "Help with \\\\ and\\nnewline");
    assert_eq!(sample(&p, "hilcam_poses_total", &[("result", "accepted")]), 41.0);
    assert_eq!(sample(&p, "hilcam_poses_total", &[("result", "rejected"), ("reason", "crc")]), 1.0);
    assert_eq!(sample(&p, "hilcam_odd_total", &[("v", odd)]), 3.0);
    assert_eq!(sample(&p, "hilcam_clients", &[]), -2.0);
    for (q, want_ms) in [("0.5", 50.0), ("0.95", 95.0), ("0.99", 99.0)] {
        let v = sample(&p, "hilcam_latency_seconds", &[("sink", "tcp"), ("quantile", q)]);
        assert!((v * 1e3 - want_ms).abs() <= want_ms / 128.0, "q{q}: {v}");
    }
    assert_eq!(sample(&p, "hilcam_latency_seconds_count", &[("sink", "tcp")]), 100.0);
    let sum = sample(&p, "hilcam_latency_seconds_sum", &[("sink", "tcp")]);
    assert!((sum - 5.05).abs() < 1e-9, "{sum}");
    assert_eq!(p.samples.len(), 4 + 5);
}

#[test]
fn summary_line_shows_totals_deltas_and_interval_percentiles() {
    let r = Registry::new();
    let c = r.counter("frames_total", "f", &[("sink", "tcp")]);
    let h = r.histogram("lat_seconds", "l", &[]);
    c.add(10);
    h.record(999_000_000); // before the interval
    let prev = r.snapshot();
    c.add(5);
    for _ in 0..10 {
        h.record(2_000_000);
    }
    let line = summary_line(&r.snapshot(), &prev);
    assert!(line.contains("frames_total{sink=\"tcp\"}=15(+5)"), "{line}");
    // An interval has no exact min/max: the quantile is the middle of 2 ms's bucket.
    let (lo, hi) = bucket_bounds(bucket_of(2_000_000));
    let mid = (lo + (hi - lo) / 2) as f64 / 1e6;
    assert!((mid - 2.0).abs() <= 2.0 / 128.0);
    let want = format!("lat_seconds n=10 p50={mid:.3}ms p95={mid:.3}ms p99={mid:.3}ms");
    assert!(line.contains(&want), "{line} vs {want}");
}

async fn http_get(addr: std::net::SocketAddr, req: &str) -> String {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(req.as_bytes()).await.unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).await.unwrap();
    out
}

#[tokio::test]
async fn http_endpoint_serves_metrics_and_nothing_else() {
    let r = Registry::new();
    r.counter("hilcam_x_total", "x", &[]).add(7);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(serve_http(listener, r.clone(), None, async {
        let _ = rx.await;
    }));
    let resp = http_get(addr, "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await;
    let (head, body) = resp.split_once("\r\n\r\n").unwrap();
    assert!(head.starts_with("HTTP/1.1 200 OK\r\n"), "{head}");
    assert!(head.contains("Content-Type: text/plain; version=0.0.4"), "{head}");
    assert!(head.contains(&format!("Content-Length: {}", body.len())), "{head}");
    assert_eq!(body, r.render_prometheus());
    assert_eq!(sample(&parse_prometheus(body), "hilcam_x_total", &[]), 7.0);
    let resp = http_get(addr, "GET /other HTTP/1.1\r\n\r\n").await;
    assert!(resp.starts_with("HTTP/1.1 404"), "{resp}");
    let resp = http_get(addr, "POST /metrics HTTP/1.1\r\n\r\n").await;
    assert!(resp.starts_with("HTTP/1.1 405"), "{resp}");
    tx.send(()).unwrap();
    server.await.unwrap();
    assert!(tokio::net::TcpStream::connect(addr).await.is_err(), "listener closed");
}
