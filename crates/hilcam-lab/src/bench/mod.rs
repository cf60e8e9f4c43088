//! Benchmarks that print ratios measured side by side in one run (never timed tests).

pub mod effects;
pub mod fixed_costs;
pub mod quality;
pub mod render;
pub mod sampling;
pub mod serve;
pub mod table1;
pub mod trade;
pub mod trade_sensor;

/// Median of a few timings (robust against a neighbour's burst on a shared machine).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { f64::NAN } else { v[v.len() / 2] }
}
