//! hilcam as a GigE Vision camera: discovery and register access over GVCP, a GenICam
//! XML describing the camera, frames over GVSP — so an unmodified GigE Vision client
//! (Aravis, a vendor SDK, a GenTL producer) can control and receive hilcam.
//!
//! Pure codecs first, the I/O shell last:
//! - [`gvcp`]: GVCP command / acknowledge codec (fuzzed).
//! - [`discovery`]: broadcast discovery (the discovery socket, broadcast acknowledges).
//! - [`registers`]: bootstrap + feature register map, validation → effects.
//! - [`control`]: control privilege, heartbeat, command dispatch.
//! - [`genicam`]: the GenICam XML, from the camera description.
//! - [`pixel`]: PFNC formats; a frame's DN → the client's ROI and format.
//! - [`chunk`]: the metadata chunk (pose sequence, pose time, flags …).
//! - [`gvsp`]: leader / payload / trailer packets.
//! - [`zip`]: the XML as a stored zip.
//! - [`describe`]: the camera description from hilcam's camera and sensor config.
//! - [`config`]: `[output.gige]` and the bounds of its sizes.
//! - [`device`]: the sockets, the control loop, the device's public face.
//! - [`stream`]: the stream thread, its pacing and the resend ring; [`stream_jobs`]
//!   its bounded work queue.
//! - [`rate_gate`]: which frames AcquisitionFrameRate lets through.
//! - [`metrics`]: the `hilcam_gige_*` counters; [`log_limit`]: one warning per reason
//!   per interval.
//! - [`request`]: the client's ExposureTime and ROI as what each frame renders, its
//!   AcquisitionFrameRate as the rate frames are rendered at; with TriggerSoftware, the
//!   device's [`crate::sink::camera_control::CameraControl`].
//! - [`pending`]: what a slow write waits for a published frame to show.
//!
//! Reference: `docs/gige.md`.

pub mod chunk;
pub mod config;
pub mod control;
pub mod describe;
pub mod device;
pub mod discovery;
pub mod genicam;
pub mod gvcp;
pub mod gvsp;
pub mod log_limit;
mod metrics;
pub mod pending;
pub mod pixel;
pub mod rate_gate;
pub mod registers;
pub mod request;
pub mod stream;
pub mod stream_jobs;
pub mod zip;

pub use device::{GigeConfig, GigeDevice, GigeError};
pub use pixel::GevPixelFormat;
pub use registers::{CameraDescription, CameraSettings};
