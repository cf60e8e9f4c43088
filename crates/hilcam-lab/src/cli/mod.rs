//! The lab's subcommands of `hilcam` (arguments and `run`), one file each.

pub mod bench;
pub mod bench_quality;
pub mod bench_trade;
pub mod bench_trade_sensor;
pub mod brdf;
pub mod fold;
pub mod model;
