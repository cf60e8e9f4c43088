//! When the sensor's rows integrate: one instant, a global shutter or a rolling one.

use crate::pose::Pose;
use crate::render::camera::Motion;
use serde::Deserialize;

/// How the detector's rows integrate over time (`[sensor.detector] exposure`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExposureMode {
    /// The frame shows the scene at the pose's instant (integration time sets only the
    /// signal). Nothing moves during the exposure.
    #[default]
    Instant,
    /// Every row integrates over `[t, t + integration]` while the target moves with
    /// the pose's velocity and angular rate: a moving target is smeared.
    Global,
    /// Row `r` integrates over `[t + r·line_time, … + integration]`: a moving target is
    /// also sheared.
    Rolling,
}

/// When one frame's rows integrated, as the frame's metadata reports it: row `r` of the
/// sensor over `[start + r·line_time_s, start + r·line_time_s + integration_s]`, where
/// start is the frame's pose time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExposureTiming {
    pub mode: ExposureMode,
    /// Each row's integration time, s (0 without a detector).
    pub integration_s: f64,
    /// Delay between consecutive rows' starts, s (0 unless rolling).
    pub line_time_s: f64,
}

impl ExposureTiming {
    /// True when the frame integrates the target's motion (not one instant).
    pub fn integrates_motion(&self) -> bool {
        self.mode != ExposureMode::Instant
    }

    /// The motion a view integrates for a frame at `pose`: its rates over this timing.
    /// None for an instant frame, or a pose without rates (it cannot move).
    pub fn motion(&self, pose: &Pose) -> Option<Motion> {
        if !self.integrates_motion() || (pose.velocity.is_none() && pose.angular_rate.is_none()) {
            return None;
        }
        let m = Motion {
            velocity: pose.velocity.unwrap_or_default(),
            angular_rate: pose.angular_rate.unwrap_or_default(),
            integration_s: self.integration_s,
            line_time_s: self.line_time_s,
        };
        (!m.is_still()).then_some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn only_a_moving_pose_over_a_timed_exposure_moves() {
        let moving = Pose { velocity: Some(DVec3::X), ..Pose::ahead(10.0) };
        let global = ExposureTiming { mode: ExposureMode::Global, integration_s: 0.01, line_time_s: 0.0 };
        let m = global.motion(&moving).expect("moves");
        assert_eq!((m.velocity, m.angular_rate, m.integration_s), (DVec3::X, DVec3::ZERO, 0.01));
        assert_eq!(global.motion(&Pose::ahead(10.0)), None, "no rates");
        let instant = ExposureTiming { mode: ExposureMode::Instant, ..global };
        assert_eq!(instant.motion(&moving), None);
        let zero = ExposureTiming { integration_s: 0.0, ..global };
        assert_eq!(zero.motion(&moving), None, "no time passes");
    }
}
