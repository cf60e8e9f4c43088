//! hilcam — a hardware-in-the-loop camera simulator for spacecraft navigation.
//!
//! A dynamics simulator sends the target's relative pose (and the sun direction) over
//! serial or CAN; hilcam renders the frame a real camera would see with a low-sample
//! Monte Carlo path tracer and streams it to the navigation computer under test.
//!
//! Layout (synchronous, pure core first; the tokio shell last):
//!
//! - [`pose`]: the `Pose` type (f64), validation, and the wire codecs (pure, over bytes).
//! - [`camera`]: pinhole camera at the real pixel geometry; pose → render frame.
//! - [`scene`]: TOML scene files, OBJ/MTL loading, material mapping.
//! - [`geometry`]: triangles, the obvhs BVH and the sun-aligned shadow grid (the only modules that import obvhs).
//! - [`fold`]: fold (wrinkled MLI) planes: generate, measure E_PLANE/Var, wrap onto meshes.
//! - [`model`]: procedural models (the Jason-like satellite), written as OBJ + MTL.
//! - [`bsdf`]: BRDF models (Lambert, Blinn-Phong, improved Blinn-Phong, Cook-Torrance).
//! - [`sampling`]: deterministic random numbers keyed by (seed, frame, pixel, sample).
//! - [`integrator`]: the path-tracing estimator for one camera sample, no threading.
//! - [`render`]: the rayon pixel loop: (scene, camera, pose, settings, seed) → image.
//! - [`pipeline`]: one frame from pose to pixels (render → sensor), shared by serve and replay.
//! - [`film`]: radiance images and writing them to files.
//! - [`sensor`]: entrance-pupil radiance → electrons → digital numbers.
//! - [`frame`]: a rendered frame with its metadata, as streamed and recorded.
//! - [`sink`]: frame sinks (TCP stream, recorder, null).
//! - [`gige`]: hilcam as a GigE Vision camera (GVCP device, GenICam XML, GVSP stream).
//! - [`metrics`]: counters, latency histograms, Prometheus text and `/metrics` HTTP.
//! - [`transport`]: async serial / SocketCAN / slcan I/O feeding the pose codecs.
//! - [`trajectory`]: trajectory CSV files (timed poses) for replay and `hilcam send`.
//! - [`replay`]: offline replay of a trajectory to files: resumable, sharded for clusters.
//! - [`bench`]: benchmarks that print side-by-side ratios (`hilcam bench …`).
//! - [`session`]: session files (poses received, frames rendered by `serve`) for re-rendering.
//! - [`serve`]: the real-time scheduler, quality governor and `hilcam serve`.
//! - [`plot`]: small PNG line charts (RMSE vs spp, Pareto fronts, BRDF curves).
//! - [`cli`]: the `hilcam` command line (thin; `main.rs` only calls it).

pub mod bench;
pub mod bsdf;
pub mod camera;
pub mod cli;
pub mod film;
pub mod fold;
pub mod frame;
pub mod geometry;
pub mod gige;
pub mod integrator;
pub mod metrics;
pub mod model;
pub mod pipeline;
pub mod plot;
pub mod pose;
pub mod render;
pub mod replay;
pub mod sampling;
pub mod scene;
pub mod sensor;
pub mod serve;
pub mod session;
pub mod sink;
pub mod trajectory;
pub mod transport;
