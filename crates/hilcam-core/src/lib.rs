//! hilcam-core — the product: what a hardware-in-the-loop bench runs.
//!
//! A dynamics simulator sends the target's relative pose (and the sun direction) over
//! serial or CAN; hilcam renders the frame a real camera would see with a low-sample
//! Monte Carlo path tracer and streams it to the navigation computer under test.
//!
//! Modules in data-flow order (each imports only modules above it; `tests/architecture.rs`
//! checks that):
//!
//! - [`shutdown`]: [`Shutdown`], the one stop signal every long-running part holds.
//! - [`heap`]: the C heap's tuning for frame after frame (keeps big buffers' pages).
//! - [`metrics`]: counters, latency histograms, Prometheus text and `/metrics` HTTP.
//! - [`pose`]: the `Pose` type (f64), the pose gate ([`pose::validate`]), wire codecs and
//!   trajectory CSV files (pure, over bytes).
//! - [`link`]: async serial / SocketCAN / slcan I/O feeding the pose codecs.
//! - [`render`]: the path tracer: camera, BVH, BSDFs, sampling, the estimator, pixel
//!   culling, the wave loop and radiance images ([`render::film`]).
//! - [`sensor`]: entrance-pupil radiance → electrons → digital numbers.
//! - [`scene`]: scene files (TOML), OBJ/MTL loading, limits, fold planes.
//! - [`pipeline`]: one frame from pose to pixels (render → sensor), shared by serve and replay.
//! - [`frame`]: a rendered frame's metadata and the TCP frame wire codec.
//! - [`session`]: session files: what `serve` received and rendered.
//! - [`sink`]: frame sinks: TCP stream, recorder, null, GigE Vision ([`sink::gige`]).
//! - [`rig`]: a camera rig: the chaser body frame, camera mounts, trigger groups and the
//!   `[[camera]]` config (pure; serve does not drive a rig yet).
//! - [`replay`]: offline replay of trajectories and sessions to files: resumable, sharded.
//! - [`serve`]: the real-time scheduler, quality governor and the serving loop.

pub mod frame;
pub mod heap;
pub mod link;
pub mod metrics;
pub mod pipeline;
pub mod pose;
pub mod render;
pub mod replay;
pub mod rig;
pub mod scene;
pub mod sensor;
pub mod serve;
pub mod session;
pub mod shutdown;
pub mod sink;

pub use shutdown::Shutdown;
