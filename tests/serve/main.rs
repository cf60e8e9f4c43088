//! `hilcam serve` and what it feeds, one binary (each binary links the whole crate): the
//! server end to end, its configs and hardening, the frame stream, metrics, sessions,
//! offline replay, GigE Vision, and the golden bytes of every shipped scene.
//! `cargo test --test serve`; one file: `cargo test --test serve golden::`.

#[path = "../common/mod.rs"]
mod common;
mod serve_common;

mod authored_model;
mod cli;
mod end_to_end;
mod exposure_tags;
mod gige;
mod gige_demo;
mod gige_discovery;
mod gige_flood;
mod gige_hostile;
mod gige_link;
mod gige_pending;
mod gige_pending_roi;
mod gige_rate;
mod gige_request;
mod gige_sfnc;
mod gige_truth;
mod golden;
mod hardening;
mod line_formats;
mod live;
mod mask_order;
mod metrics;
mod moving_planet;
mod netns;
mod replay;
mod replay_truth;
mod rig;
mod serve_truth;
mod session;
mod stream;
