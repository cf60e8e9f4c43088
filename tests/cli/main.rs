//! What users and senders hand to hilcam, one binary (each binary links the whole crate):
//! the command line (pipes, timing flags), scene files, hostile scene files and flags, and
//! hostile pose and scene values at every entry point, and the docs' examples (`docs.rs`).
//! `cargo test --test cli`; one file: `cargo test --test cli refuse_scene::`.

mod docs;
mod hostile_inputs;
mod pipe;
mod refuse_scene;
mod render;
mod scene_file;
