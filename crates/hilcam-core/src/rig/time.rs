//! When each camera exposes, and the pose it exposes from.
//!
//! The pose source sends body poses at its own rate; cameras expose at theirs. A camera
//! gets the newest pose moved to its exposure instant ([`PoseHistory::at`]). Cameras of one
//! trigger group ([`TriggerGroups`]) expose at one instant and get one pose (a stereo pair);
//! the mounts then turn it into each camera's pose ([`group_poses`]). Moving the body pose
//! before the fixed mounts is the same as moving each camera's pose: a mount is affine in
//! position and a constant rotation of the attitude.

use super::mount::{BodyPose, Mount};
use crate::pose::Pose;
use glam::DQuat;

/// The newest two body poses received (time-stamped by the sender).
#[derive(Clone, Copy, Debug, Default)]
pub struct PoseHistory {
    newest: Option<BodyPose>,
    previous: Option<BodyPose>,
}

/// A body pose moved to an instant, and whether anything moved it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moved {
    pub pose: BodyPose,
    /// Some rate moved it by a non-zero time (what an `EXTRAPOLATED` flag would say).
    pub extrapolated: bool,
}

impl PoseHistory {
    /// Keep `pose` as the newest. A pose at the newest one's time replaces it (the newer
    /// sample of one instant wins); an older one is ignored (the pose gate refuses those).
    pub fn push(&mut self, pose: BodyPose) {
        match self.newest {
            Some(n) if pose.0.t_ns < n.0.t_ns => {}
            Some(n) if pose.0.t_ns == n.0.t_ns => self.newest = Some(pose),
            _ => {
                self.previous = self.newest;
                self.newest = Some(pose);
            }
        }
    }

    pub fn newest(&self) -> Option<&BodyPose> {
        self.newest.as_ref()
    }

    /// The body pose at `t_ns`, moved from the newest sample at constant rates: its own
    /// velocity and angular rate where it carries them, else those of the step from the
    /// previous sample (linear in position; in attitude the rotation between the two,
    /// continued at the same rate: slerp past its end). What neither gives is held. The
    /// rates used are written into the pose (motion blur moves it by them). The sun, the
    /// inertial attitude and the planet are held from the newest sample. None before any
    /// pose.
    pub fn at(&self, t_ns: u64) -> Option<Moved> {
        let newest = self.newest?.0;
        let step = self.previous.map(|p| p.0).filter(|p| p.t_ns < newest.t_ns);
        let step_s = step.map(|p| (newest.t_ns - p.t_ns) as f64 * 1e-9);
        let velocity = newest.velocity.or_else(|| Some((newest.position - step?.position) / step_s?));
        let angular_rate = newest.angular_rate.or_else(|| {
            // The shortest rotation from the previous attitude to the newest.
            let mut dq = newest.attitude * step?.attitude.inverse();
            if dq.w < 0.0 {
                dq = -dq;
            }
            Some(dq.normalize().to_scaled_axis() / step_s?)
        });
        // Signed: an instant before the newest sample interpolates back toward the previous.
        let dt_s = (t_ns as i128 - newest.t_ns as i128) as f64 * 1e-9;
        let mut pose = Pose { t_ns, velocity, angular_rate, ..newest };
        let mut extrapolated = false;
        if dt_s != 0.0 {
            if let Some(v) = velocity {
                pose.position = newest.position + v * dt_s;
                extrapolated = true;
            }
            if let Some(w) = angular_rate {
                // exp(ω·dt/2) ⊗ q: the pose convention's constant rate.
                pose.attitude = (DQuat::from_scaled_axis(w * dt_s) * newest.attitude).normalize();
                extrapolated = true;
            }
        }
        Some(Moved { pose: BodyPose(pose), extrapolated })
    }
}

/// How a camera's exposure places its pose in time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exposure {
    /// Integration time, seconds.
    pub integration_s: f64,
    /// The camera integrates motion over its exposure (global or rolling shutter): the
    /// renderer moves the pose from the exposure's start, so that is where the pose belongs.
    pub integrates_motion: bool,
}

impl Exposure {
    /// From the trigger to the instant the camera's pose belongs to: the exposure's start
    /// for a camera that integrates motion, its middle otherwise (as `serve` does today).
    pub fn pose_offset_ns(&self) -> u64 {
        if self.integrates_motion { 0 } else { (self.integration_s * 0.5e9).round() as u64 }
    }
}

/// Which cameras expose together: each camera belongs to exactly one group; a camera named
/// in no group is a group of its own.
#[derive(Clone, Debug, PartialEq)]
pub struct TriggerGroups {
    /// Group index of each camera.
    group_of: Vec<usize>,
    groups: usize,
}

impl TriggerGroups {
    /// Groups from each camera's group name (None: alone). Groups are numbered in the order
    /// their first camera appears.
    pub fn new<'a>(names: impl IntoIterator<Item = Option<&'a str>>) -> TriggerGroups {
        let mut seen: Vec<Option<&str>> = Vec::new();
        let mut group_of = Vec::new();
        for name in names {
            let g = match name.and_then(|n| seen.iter().position(|s| *s == Some(n))) {
                Some(g) => g,
                None => {
                    seen.push(name);
                    seen.len() - 1
                }
            };
            group_of.push(g);
        }
        TriggerGroups { group_of, groups: seen.len() }
    }

    pub fn group_of(&self, camera: usize) -> usize {
        self.group_of[camera]
    }

    pub fn len(&self) -> usize {
        self.groups
    }

    pub fn is_empty(&self) -> bool {
        self.groups == 0
    }

    /// The cameras of `group`, in camera order.
    pub fn members(&self, group: usize) -> impl Iterator<Item = usize> + '_ {
        self.group_of.iter().enumerate().filter(move |(_, g)| **g == group).map(|(c, _)| c)
    }
}

/// One camera's pose for one trigger.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPose {
    pub camera: usize,
    /// In the camera's frame; its `t_ns` is the group's pose instant.
    pub pose: Pose,
    pub extrapolated: bool,
}

/// The poses of `group`'s cameras for a trigger at `trigger_ns`: one body pose, moved to
/// one instant — the trigger plus the smallest of the members' pose offsets (for a lone
/// camera its own; for twins their common one) — through each member's mount. Same-group
/// cameras therefore carry the identical pose timestamp. `exposures` and `mounts` are per
/// camera. None before any pose.
pub fn group_poses(
    history: &PoseHistory,
    groups: &TriggerGroups,
    group: usize,
    trigger_ns: u64,
    exposures: &[Exposure],
    mounts: &[Mount],
) -> Option<Vec<CameraPose>> {
    let offset = groups.members(group).map(|c| exposures[c].pose_offset_ns()).min()?;
    let moved = history.at(trigger_ns.saturating_add(offset))?;
    let poses = groups
        .members(group)
        .map(|c| CameraPose { camera: c, pose: mounts[c].camera_pose(&moved.pose), extrapolated: moved.extrapolated })
        .collect();
    Some(poses)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn at(t_ns: u64, position: DVec3, attitude: DQuat) -> BodyPose {
        BodyPose(Pose { t_ns, position, attitude, ..Pose::ahead(1.0) })
    }

    #[test]
    fn one_pose_without_rates_is_held_and_an_older_one_is_ignored() {
        let mut h = PoseHistory::default();
        assert!(h.at(5).is_none());
        h.push(at(100, DVec3::Z, DQuat::IDENTITY));
        h.push(at(50, DVec3::X, DQuat::IDENTITY));
        let m = h.at(1_000_000).unwrap();
        assert!(!m.extrapolated);
        assert_eq!((m.pose.0.position, m.pose.0.t_ns), (DVec3::Z, 1_000_000));
    }

    #[test]
    fn groups_number_in_order_and_lone_cameras_stand_alone() {
        let g = TriggerGroups::new([Some("stereo"), None, Some("stereo"), None]);
        assert_eq!((0..4).map(|c| g.group_of(c)).collect::<Vec<_>>(), [0, 1, 0, 2]);
        assert_eq!(g.members(0).collect::<Vec<_>>(), [0, 2]);
        assert_eq!(g.len(), 3);
    }

    #[test]
    fn a_group_takes_its_smallest_pose_offset() {
        let e = |s, m| Exposure { integration_s: s, integrates_motion: m };
        assert_eq!(e(0.01, false).pose_offset_ns(), 5_000_000);
        assert_eq!(e(0.01, true).pose_offset_ns(), 0);
        let mut h = PoseHistory::default();
        h.push(BodyPose(Pose { velocity: Some(DVec3::X), ..Pose::ahead(10.0) }));
        let groups = TriggerGroups::new([Some("a"), Some("a"), None]);
        let exposures = [e(0.004, false), e(0.002, false), e(0.01, false)];
        let mounts = [Mount::IDENTITY; 3];
        let a = group_poses(&h, &groups, 0, 1_000, &exposures, &mounts).unwrap();
        assert_eq!(a.iter().map(|p| (p.camera, p.pose.t_ns)).collect::<Vec<_>>(), [(0, 1_001_000), (1, 1_001_000)]);
        let b = group_poses(&h, &groups, 1, 1_000, &exposures, &mounts).unwrap();
        assert_eq!(b[0].pose.t_ns, 5_001_000);
    }
}
