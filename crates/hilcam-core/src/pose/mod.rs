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
    /// Optional inertial attitude of the camera: the rotation taking camera-frame vectors
    /// into the inertial (J2000 equatorial) frame. Places a scene's star field.
    pub camera_to_inertial: Option<DQuat>,
    /// Optional centre of the scene's planet, camera frame, metres: moves the scene's
    /// `[planet]` for this pose (a featureless sphere, so its attitude does not show).
    pub planet_centre: Option<DVec3>,
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
            camera_to_inertial: None,
            planet_centre: None,
        }
    }
}

pub mod can;
pub mod crc;
pub mod rates;
pub mod serial;
pub mod slcan;
pub mod trajectory;
pub mod validate;
mod wire;

/// One decoded protocol message, whatever link it came over.
///
/// Fields a link does not carry are documented per link in `docs/protocol.md`
/// (e.g. a CAN trigger has no sequence number, so `seq` is 0 there).
#[derive(Clone, Copy, Debug, PartialEq)]
// A pose (232 bytes with its optional planet centre) moves by value: boxing it would
// allocate per message on the allocation-free input path.
#[allow(clippy::large_enum_variant)]
pub enum Message {
    /// A relative pose (not yet validated: see [`validate::PoseValidator`]).
    Pose(Pose),
    /// "Render now" from the bench, stamped with its simulation time.
    Trigger {
        /// Sender's sequence number (wraps; 0 where the link does not carry it).
        seq: u32,
        /// Simulation time, ns (0 where the link does not carry it).
        t_ns: u64,
    },
    /// Liveness message; `status` is sender-defined (0 = nominal).
    Heartbeat {
        /// Sender's sequence number (wraps).
        seq: u32,
        /// Simulation time, ns (0 where the link does not carry it).
        t_ns: u64,
        /// Sender-defined status word, 0 = nominal.
        status: u32,
    },
}
