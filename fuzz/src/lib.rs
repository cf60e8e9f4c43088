//! The pure codec modules of hilcam, compiled on their own for fuzzing.
#![allow(dead_code)]

#[path = "../../crates/hilcam-core/src/pose/mod.rs"]
pub mod pose;
#[path = "../../crates/hilcam-core/src/sink/gige/gvcp.rs"]
pub mod gvcp;
#[path = "../../crates/hilcam-core/src/sink/gige/gvsp.rs"]
pub mod gvsp;
