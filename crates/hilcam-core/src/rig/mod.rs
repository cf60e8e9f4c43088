//! A camera rig: several cameras on the chaser, driven by one pose stream (issue #43,
//! `docs/rig.md`). Pure and synchronous; `serve` does not drive a rig yet.
//!
//! Frames of reference (docs/rig.md draws them):
//!
//! - **Chaser body frame** B: fixed to the chaser spacecraft, right-handed, its origin the
//!   chaser's navigation reference point. Its axes are whatever the bench's dynamics use;
//!   hilcam only needs every mount to be given in the same frame. A rig's pose source sends
//!   a [`BodyPose`]: the target's pose, the sun and the rates in B.
//! - **Camera frame** C: the README's camera frame (+Z boresight, +X toward increasing
//!   column, +Y toward increasing row), origin at the projection centre. Each camera's
//!   [`Mount`] places C in B.
//! - **Target body frame** T: the scene's model frame.
//!
//! [`Mount::camera_pose`] turns a body pose into the camera-frame [`crate::pose::Pose`]
//! the renderer takes; [`time`] moves body poses to each trigger group's exposure instant.

pub mod config;
pub mod mount;
pub mod time;

pub use mount::{BodyPose, Mount};
