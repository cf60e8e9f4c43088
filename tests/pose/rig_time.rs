//! A rig's poses in time against analytic motion: a target moving at constant velocity
//! and turning at a constant rate, sampled as a pose source would send it, moved to each
//! camera's exposure instant; cameras of one trigger group share the pose and timestamp.

use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::rig::time::{Exposure, PoseHistory, TriggerGroups, group_poses};
use hilcam_core::rig::{BodyPose, Mount};

const P0: DVec3 = DVec3::new(1.5, -0.4, 30.0);
const V: DVec3 = DVec3::new(0.2, 0.05, -1.5);
const AXIS: DVec3 = DVec3::new(0.0, 0.6, 0.8);
const RATE: f64 = 0.3; // rad/s about AXIS

/// The truth at `t` seconds: position p0 + v·t, attitude turned by RATE·t about AXIS
/// (body frame) from a fixed start.
fn truth(t: f64) -> (DVec3, DQuat) {
    let q0 = DQuat::from_rotation_x(0.5) * DQuat::from_rotation_z(-0.2);
    (P0 + V * t, DQuat::from_axis_angle(AXIS, RATE * t) * q0)
}

fn sample(t: f64, with_rates: bool) -> BodyPose {
    let (position, attitude) = truth(t);
    BodyPose(Pose {
        t_ns: (t * 1e9).round() as u64,
        position,
        attitude,
        velocity: with_rates.then_some(V),
        angular_rate: with_rates.then_some(AXIS * RATE),
        sun_dir: DVec3::NEG_Z,
        ..Pose::ahead(1.0)
    })
}

/// Largest distance a point of a 2 m body moves between the two attitudes, metres.
fn attitude_gap(a: DQuat, b: DQuat) -> f64 {
    [DVec3::X, DVec3::Y, DVec3::Z].iter().map(|v| (a * *v - b * *v).length()).fold(0.0, f64::max)
}

#[test]
fn extrapolation_matches_constant_velocity_and_rate() {
    for with_rates in [false, true] {
        let mut h = PoseHistory::default();
        h.push(sample(0.9, with_rates));
        h.push(sample(1.0, with_rates));
        // Ahead (extrapolated), between the samples (interpolated) and at the newest.
        for t in [1.0, 1.05, 1.35, 2.0, 0.95] {
            let m = h.at((t * 1e9) as u64).unwrap();
            let (p, q) = truth(t);
            assert!((m.pose.0.position - p).length() < 1e-9, "rates {with_rates}, t {t}: {}", m.pose.0.position);
            assert!(attitude_gap(m.pose.0.attitude, q) < 1e-9, "rates {with_rates}, t {t}");
            assert_eq!(m.extrapolated, t != 1.0);
            assert_eq!(m.pose.0.t_ns, (t * 1e9) as u64);
            // The rates it moved by are written into the pose (for motion blur).
            assert!((m.pose.0.velocity.unwrap() - V).length() < 1e-9);
            assert!((m.pose.0.angular_rate.unwrap() - AXIS * RATE).length() < 1e-9);
        }
    }
}

#[test]
fn between_two_samples_the_attitude_is_their_slerp() {
    let mut h = PoseHistory::default();
    let (a, b) = (sample(0.0, false), sample(2.0, false));
    h.push(a);
    h.push(b);
    for s in [0.0, 0.25, 0.5, 0.9] {
        let m = h.at((s * 2e9) as u64).unwrap();
        let slerp = a.0.attitude.slerp(b.0.attitude, s);
        assert!(attitude_gap(m.pose.0.attitude, slerp) < 1e-9, "s {s}");
        assert!((m.pose.0.position - a.0.position.lerp(b.0.position, s)).length() < 1e-9);
    }
}

#[test]
fn one_trigger_group_shares_the_pose_and_timestamp_through_its_mounts() {
    let mut h = PoseHistory::default();
    h.push(sample(0.9, false));
    h.push(sample(1.0, false));
    // A stereo pair (one exposure 2 ms, the other 4 ms) and a lone camera with 10 ms.
    let groups = TriggerGroups::new([Some("stereo"), Some("stereo"), None]);
    let exposures = [
        Exposure { integration_s: 0.002, integrates_motion: false },
        Exposure { integration_s: 0.004, integrates_motion: false },
        Exposure { integration_s: 0.010, integrates_motion: false },
    ];
    let mounts = [
        Mount { position: DVec3::new(-0.15, 0.0, 0.0), attitude: DQuat::IDENTITY },
        Mount { position: DVec3::new(0.15, 0.0, 0.0), attitude: DQuat::IDENTITY },
        Mount::from_euler_deg(DVec3::new(0.0, 0.3, 0.0), [0.0, 30.0, 0.0]),
    ];
    let trigger_ns = 1_200_000_000;
    let pair = group_poses(&h, &groups, groups.group_of(0), trigger_ns, &exposures, &mounts).unwrap();
    // The pair's instant: the trigger plus the smaller mid-exposure offset (1 ms).
    let t = 1.201;
    assert_eq!(
        pair.iter().map(|c| (c.camera, c.pose.t_ns)).collect::<Vec<_>>(),
        [(0, 1_201_000_000), (1, 1_201_000_000)]
    );
    let (p, q) = truth(t);
    for c in &pair {
        // Independently: the body-frame truth, shifted by the mount's offset (no rotation).
        let want = p - mounts[c.camera].position;
        assert!((c.pose.position - want).length() < 1e-9, "camera {}: {}", c.camera, c.pose.position);
        assert!(attitude_gap(c.pose.attitude, q) < 1e-9);
        assert!(c.extrapolated);
    }
    let lone = group_poses(&h, &groups, groups.group_of(2), trigger_ns, &exposures, &mounts).unwrap();
    assert_eq!((lone.len(), lone[0].pose.t_ns), (1, 1_205_000_000));
    // A 30° turn about body y, by hand: camera x = cos·x − sin·z, z = sin·x + cos·z.
    let (p, _) = truth(1.205);
    let d = p - DVec3::new(0.0, 0.3, 0.0);
    let (s, c) = 30f64.to_radians().sin_cos();
    let want = DVec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z);
    assert!((lone[0].pose.position - want).length() < 1e-9, "{} vs {want}", lone[0].pose.position);
}
