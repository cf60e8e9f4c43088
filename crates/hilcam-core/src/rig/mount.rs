//! Where a camera sits on the chaser, and the pose that camera sees.

use crate::pose::Pose;
use glam::{DQuat, DVec3, EulerRot};

/// A pose whose vectors are in the chaser body frame (not a camera's): the rig's input.
///
/// The fields of the wrapped [`Pose`] read with "camera" replaced by "chaser body":
/// `position` is the target body origin in the body frame (m); `attitude` rotates
/// target-body vectors into the body frame; `sun_dir` points to the sun in the body frame;
/// `velocity` is d/dt of `position` (m/s) and `angular_rate` the target's rate relative to
/// the chaser, in the body frame (rad/s, `dq/dt = ½ ω ⊗ q`); `camera_to_inertial` is the
/// rotation taking body vectors into the inertial frame; `planet_centre` is in the body
/// frame. Time and sequence are the sender's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyPose(pub Pose);

/// A camera's mount: the camera frame's origin and attitude in the chaser body frame.
/// Fixed on the chaser, so it moves nothing over time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mount {
    /// The camera's projection centre in the body frame, metres.
    pub position: DVec3,
    /// Unit quaternion rotating camera-frame vectors into the body frame (Hamilton, the
    /// pose attitude's convention: it rotates the mounted frame's vectors into the frame it
    /// is given in). Column 3 of its matrix is the boresight in body coordinates.
    pub attitude: DQuat,
}

impl Mount {
    /// The camera frame is the body frame: a camera-frame pose passes through unchanged.
    pub const IDENTITY: Mount = Mount { position: DVec3::ZERO, attitude: DQuat::IDENTITY };

    /// A mount whose attitude is the body frame rotated about body X, then Y, then Z (fixed
    /// axes, degrees): the scene file's `rotate_deg` convention.
    pub fn from_euler_deg(position: DVec3, euler_deg: [f64; 3]) -> Mount {
        let [rx, ry, rz] = euler_deg.map(f64::to_radians);
        Mount { position, attitude: DQuat::from_euler(EulerRot::ZYX, rz, ry, rx) }
    }

    pub fn is_identity(&self) -> bool {
        self.position == DVec3::ZERO && self.attitude == DQuat::IDENTITY
    }

    /// A body-frame point in this camera's frame.
    pub fn point_to_camera(&self, body_point: DVec3) -> DVec3 {
        self.attitude.conjugate() * (body_point - self.position)
    }

    /// The pose this camera sees: every vector of `body` in the camera frame. An identity
    /// mount returns the pose as it came, bit for bit (a single camera with no mount renders
    /// today's bytes).
    pub fn camera_pose(&self, body: &BodyPose) -> Pose {
        let p = &body.0;
        if self.is_identity() {
            return *p;
        }
        let to_camera = self.attitude.conjugate();
        Pose {
            position: self.point_to_camera(p.position),
            attitude: to_camera * p.attitude,
            sun_dir: to_camera * p.sun_dir,
            // The mount is fixed on the chaser: relative rates only change frames.
            velocity: p.velocity.map(|v| to_camera * v),
            angular_rate: p.angular_rate.map(|w| to_camera * w),
            camera_to_inertial: p.camera_to_inertial.map(|body_to_inertial| body_to_inertial * self.attitude),
            planet_centre: p.planet_centre.map(|c| self.point_to_camera(c)),
            ..*p
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(p: &Pose) -> Vec<u64> {
        let v = |v: DVec3| v.to_array().map(f64::to_bits);
        let mut out = vec![p.seq as u64, p.t_ns];
        out.extend(v(p.position));
        out.extend(p.attitude.to_array().map(f64::to_bits));
        out.extend(v(p.sun_dir));
        for o in [p.velocity, p.angular_rate, p.planet_centre] {
            out.extend(o.map_or([u64::MAX; 3], v));
        }
        out.extend(p.camera_to_inertial.map_or([u64::MAX; 4], |q| q.to_array().map(f64::to_bits)));
        out
    }

    #[test]
    fn identity_mounts_return_the_same_bits() {
        // Negative zeros would lose their sign through a rotation by the identity.
        let p = Pose {
            position: DVec3::new(-0.0, 1e-300, 22.5),
            attitude: DQuat::from_xyzw(-0.0, 0.3, 0.0, 0.9).normalize(),
            velocity: Some(DVec3::new(-0.0, 0.1, -1.0)),
            angular_rate: Some(DVec3::new(0.01, -0.0, 0.0)),
            camera_to_inertial: Some(DQuat::from_rotation_z(1.0)),
            planet_centre: Some(DVec3::new(0.0, 7e6, -0.0)),
            ..Pose::ahead(1.0)
        };
        for m in [Mount::IDENTITY, Mount::from_euler_deg(DVec3::ZERO, [0.0; 3])] {
            assert!(m.is_identity(), "{m:?}");
            assert_eq!(bits(&m.camera_pose(&BodyPose(p))), bits(&p));
        }
    }

    #[test]
    fn a_mount_moves_every_vector_into_the_camera_frame() {
        // Camera 1 m along body +x, boresight along body +x (rotated +90° about body y).
        let m = Mount::from_euler_deg(DVec3::X, [0.0, 90.0, 0.0]);
        let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-12;
        assert!(close(m.attitude * DVec3::Z, DVec3::X), "boresight along body x");
        let body = BodyPose(Pose {
            position: DVec3::new(11.0, 0.0, 0.0),
            sun_dir: DVec3::NEG_X,
            velocity: Some(DVec3::new(-1.0, 0.0, 0.0)),
            angular_rate: Some(DVec3::Z),
            camera_to_inertial: Some(DQuat::IDENTITY),
            ..Pose::ahead(1.0)
        });
        let c = m.camera_pose(&body);
        assert!(close(c.position, DVec3::new(0.0, 0.0, 10.0)), "{}", c.position);
        assert!(close(c.sun_dir, DVec3::NEG_Z) && close(c.velocity.unwrap(), DVec3::NEG_Z));
        // Body z is the camera's −x when the camera is turned +90° about body y.
        assert!(close(c.angular_rate.unwrap(), DVec3::NEG_X), "{:?}", c.angular_rate);
        // A target body vector ends where going through the body frame puts it.
        let v = DVec3::new(0.3, -0.2, 0.5);
        assert!(close(c.attitude * v, m.attitude.conjugate() * (body.0.attitude * v)));
        // Camera vectors reach the inertial frame through the body.
        assert!(close(c.camera_to_inertial.unwrap() * DVec3::Z, DVec3::X));
    }
}
