//! hilcam-lab — the lab around the product: benchmarks that print side-by-side ratios,
//! PNG plots, BRDF tables and fits, fold-plane measurement and procedural models. Not
//! needed to serve frames; the `hilcam` binary includes it with its default `lab` feature.

pub mod bench;
pub mod cli;
pub mod model;
pub mod obj;
pub mod plot;
pub mod preview;
pub mod sun_shadow;
