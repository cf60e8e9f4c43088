//! The pure codec modules of hilcam, compiled on their own for fuzzing.
#![allow(dead_code)]

#[path = "../../src/pose/mod.rs"]
pub mod pose;
#[path = "../../src/trajectory.rs"]
pub mod trajectory;
#[path = "../../src/gige/gvcp.rs"]
pub mod gvcp;
