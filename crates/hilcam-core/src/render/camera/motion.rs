//! A camera that integrates over its exposure while the target moves.
//!
//! The pose of a frame is the one at the start of its exposure. Over the exposure the
//! target moves with the pose's constant relative velocity and angular rate (the model
//! `hilcam serve` extrapolates with): at `δ` seconds after the start,
//! `p(δ) = p + v·δ` and `q(δ) = exp(ω·δ/2) ⊗ q` (ω in the camera frame). Row `r` of the
//! sensor integrates over `[r·line_time, r·line_time + integration]` (a global shutter
//! has line time 0); every camera sample draws its own time in its row's window, so a
//! moving target is smeared (and, with a rolling shutter, sheared) by exactly the
//! motion the board's camera would record.

use glam::{DMat3, DQuat, DVec3};

/// How the camera's rows integrate over one exposure, and how the target moves meanwhile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Relative velocity of the target origin, camera frame, m/s.
    pub velocity: DVec3,
    /// Angular rate of the target body relative to the camera, camera frame, rad/s.
    pub angular_rate: DVec3,
    /// Each row's integration time, s.
    pub integration_s: f64,
    /// Delay between the starts of consecutive sensor rows, s (0: global shutter).
    pub line_time_s: f64,
}

impl Motion {
    /// True when the frame would be the instant one: no time, or nothing moves.
    pub fn is_still(&self) -> bool {
        let moves = self.velocity != DVec3::ZERO || self.angular_rate != DVec3::ZERO;
        !moves || (self.integration_s <= 0.0 && self.line_time_s <= 0.0)
    }
}

/// A [`Motion`] bound to a view's pose: the camera's place and orientation in the render
/// frame at any time of the exposure.
#[derive(Clone, Copy, Debug)]
pub(in crate::render) struct MovingPose {
    motion: Motion,
    /// Target origin in the camera frame and body → camera rotation at the start.
    position: DVec3,
    attitude: DQuat,
    frame_origin_body: DVec3,
    /// Sensor row of the image's row 0 (a window's offset).
    pub(in crate::render) first_row: u32,
}

impl MovingPose {
    pub(in crate::render) fn new(motion: Motion, position: DVec3, attitude: DQuat, frame_origin_body: DVec3) -> Self {
        MovingPose { motion, position, attitude, frame_origin_body, first_row: 0 }
    }

    pub(in crate::render) fn motion(&self) -> &Motion {
        &self.motion
    }

    /// Seconds after the exposure start at which the sample with time coordinate
    /// `u ∈ [0, 1)` of image row `row` integrates.
    #[inline]
    pub(in crate::render) fn time_of(&self, row: u32, u: f32) -> f64 {
        f64::from(self.first_row + row) * self.motion.line_time_s + f64::from(u) * self.motion.integration_s
    }

    /// The last instant any of `rows` image rows integrates (the exposure's span).
    pub(in crate::render) fn span_s(&self, rows: u32) -> f64 {
        f64::from(self.first_row + rows.saturating_sub(1)) * self.motion.line_time_s + self.motion.integration_s
    }

    /// Camera centre and camera → render rotation `dt` seconds after the start: the
    /// formulas of [`super::View::new`] at the moved pose (the same numbers at `dt = 0`).
    #[inline]
    pub(in crate::render) fn at(&self, dt: f64) -> (DVec3, DMat3) {
        let Motion { velocity, angular_rate, .. } = self.motion;
        let attitude = if angular_rate == DVec3::ZERO {
            self.attitude
        } else {
            DQuat::from_scaled_axis(angular_rate * dt) * self.attitude
        };
        let cam_to_body = DMat3::from_quat(attitude.normalize()).transpose();
        let origin = -(cam_to_body * (self.position + velocity * dt)) - self.frame_origin_body;
        (origin, cam_to_body)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motion(v: DVec3, w: DVec3) -> Motion {
        Motion { velocity: v, angular_rate: w, integration_s: 0.01, line_time_s: 1e-5 }
    }

    #[test]
    fn still_when_nothing_moves_or_no_time_passes() {
        assert!(motion(DVec3::ZERO, DVec3::ZERO).is_still());
        assert!(!motion(DVec3::X, DVec3::ZERO).is_still());
        assert!(!motion(DVec3::ZERO, DVec3::Y).is_still());
        let m = Motion { integration_s: 0.0, line_time_s: 0.0, ..motion(DVec3::X, DVec3::Y) };
        assert!(m.is_still());
    }

    #[test]
    fn body_points_move_with_the_rates() {
        let (v, w) = (DVec3::new(0.5, -0.2, 1.0), DVec3::new(0.0, 0.3, 0.1));
        let q = DQuat::from_rotation_x(0.3);
        let p = DVec3::new(0.1, 0.2, 30.0);
        let m = MovingPose::new(motion(v, w), p, q, DVec3::ZERO);
        // A body point's camera-frame position, from the moved camera: x_c = R(x_b − o).
        let xb = DVec3::new(1.0, -2.0, 0.5);
        for dt in [0.0, 0.004, 0.01] {
            let (o, c2r) = m.at(dt);
            let seen = c2r.transpose() * (xb - o);
            let want = DQuat::from_scaled_axis(w * dt) * q * xb + p + v * dt;
            assert!((seen - want).length() < 1e-12, "{dt}: {seen} vs {want}");
        }
    }

    #[test]
    fn rows_start_one_line_time_apart() {
        let mut m = MovingPose::new(motion(DVec3::X, DVec3::ZERO), DVec3::Z, DQuat::IDENTITY, DVec3::ZERO);
        assert_eq!(m.time_of(0, 0.0), 0.0);
        assert!((m.time_of(10, 0.5) - (10.0 * 1e-5 + 0.005)).abs() < 1e-15);
        m.first_row = 100;
        assert!((m.time_of(0, 0.0) - 1e-3).abs() < 1e-15);
        assert!((m.span_s(10) - (109.0 * 1e-5 + 0.01)).abs() < 1e-15);
    }
}
