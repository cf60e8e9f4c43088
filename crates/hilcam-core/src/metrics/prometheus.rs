//! Prometheus text exposition format 0.0.4 (`text/plain; version=0.0.4`).

use super::{Family, Kind, Series, series_key};
use std::collections::BTreeMap;
use std::fmt::Write;

/// Quantiles every summary exposes.
pub const QUANTILES: [f64; 3] = [0.5, 0.95, 0.99];

pub(crate) fn render(families: &BTreeMap<String, Family>) -> String {
    let mut out = String::new();
    for (name, fam) in families {
        let kind = match fam.kind {
            Kind::Counter => "counter",
            Kind::Gauge => "gauge",
            Kind::Summary => "summary",
        };
        let _ = writeln!(out, "# HELP {name} {}", escape_help(&fam.help));
        let _ = writeln!(out, "# TYPE {name} {kind}");
        for (labels, series) in &fam.series {
            match series {
                Series::Counter(c) => {
                    let _ = writeln!(out, "{} {}", series_key(name, labels), c.get());
                }
                Series::Gauge(g) => {
                    let _ = writeln!(out, "{} {}", series_key(name, labels), g.get());
                }
                Series::Summary(h) => {
                    let s = h.snapshot();
                    for q in QUANTILES {
                        let mut l = labels.clone();
                        l.push(("quantile".into(), q.to_string()));
                        let v = s.quantile(q).map_or(f64::NAN, |ns| ns as f64 * 1e-9);
                        let _ = writeln!(out, "{} {}", series_key(name, &l), fmt_f64(v));
                    }
                    let sum = s.sum as f64 * 1e-9;
                    let _ = writeln!(out, "{} {}", series_key(&format!("{name}_sum"), labels), fmt_f64(sum));
                    let _ = writeln!(out, "{} {}", series_key(&format!("{name}_count"), labels), s.count);
                }
            }
        }
    }
    out
}

/// Go-style float text as Prometheus parsers accept it (`NaN`, `+Inf`).
fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        "NaN".into()
    } else if v.is_infinite() {
        if v > 0.0 { "+Inf".into() } else { "-Inf".into() }
    } else {
        format!("{v}")
    }
}

/// Label values escape `\`, `"` and newline.
pub(crate) fn escape_label(v: &str) -> String {
    v.replace('\\', "\\\\").replace('"', "\\\"").replace('\n', "\\n")
}

/// HELP text escapes `\` and newline.
fn escape_help(v: &str) -> String {
    v.replace('\\', "\\\\").replace('\n', "\\n")
}
