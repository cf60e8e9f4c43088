//! The relative pose the bench sends, and (in submodules) its validation and wire codecs.
//!
//! Conventions (README "Conventions"): positions in metres in the camera frame
//! (+Z boresight, +X toward increasing column, +Y toward increasing row); attitude is a
//! unit quaternion (Hamilton, scalar first on the wire) rotating target-body vectors into
//! the camera frame; the sun direction is a unit vector toward the sun in the camera frame.
//! All pose maths is f64.

use glam::{DQuat, DVec3};

/// One relative pose of the target with respect to the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Sender's sequence number (wraps).
    pub seq: u32,
    /// Simulation time of the pose, nanoseconds.
    pub t_ns: u64,
    /// Target body origin in the camera frame, metres.
    pub position: DVec3,
    /// Rotation taking target-body vectors into the camera frame.
    pub attitude: DQuat,
    /// Unit vector toward the sun, camera frame.
    pub sun_dir: DVec3,
    /// Optional relative velocity of the target origin, camera frame, m/s.
    pub velocity: Option<DVec3>,
    /// Optional angular rate of the target body relative to the camera, camera frame, rad/s.
    pub angular_rate: Option<DVec3>,
}

impl Pose {
    /// A pose with the target `range` metres straight ahead, body axes aligned with the
    /// camera's, and the sun behind the camera (full phase).
    pub fn ahead(range: f64) -> Self {
        Pose {
            seq: 0,
            t_ns: 0,
            position: DVec3::new(0.0, 0.0, range),
            attitude: DQuat::IDENTITY,
            sun_dir: DVec3::new(0.0, 0.0, -1.0),
            velocity: None,
            angular_rate: None,
        }
    }
}
