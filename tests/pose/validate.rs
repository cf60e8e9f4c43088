//! Validation: every rejection reason, renormalisation of small drift.

use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::pose::validate::{PoseLimits, PoseValidator, Rejection, check_pose};

fn lim() -> PoseLimits {
    PoseLimits::default()
}

#[test]
fn each_rejection_reason() {
    let ok = Pose::ahead(100.0);
    let cases = [
        (Pose { position: DVec3::new(f64::NAN, 0.0, 1.0), ..ok }, Rejection::NonFinite),
        (Pose { velocity: Some(DVec3::new(0.0, f64::INFINITY, 0.0)), ..ok }, Rejection::NonFinite),
        (Pose { attitude: DQuat::from_xyzw(0.0, 0.0, 0.0, 1.01), ..ok }, Rejection::QuaternionNorm),
        (Pose { attitude: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), ..ok }, Rejection::QuaternionNorm),
        (Pose { sun_dir: DVec3::new(0.0, 0.0, 0.5), ..ok }, Rejection::SunNorm),
        (Pose::ahead(0.01), Rejection::TooClose),
        (Pose::ahead(2.0e7), Rejection::TooFar),
        (Pose { angular_rate: Some(DVec3::new(0.0, 0.0, 11.0)), ..ok }, Rejection::RateLimit),
        (Pose { velocity: Some(DVec3::new(2.0e4, 0.0, 0.0)), ..ok }, Rejection::RateLimit),
    ];
    for (p, want) in cases {
        assert_eq!(check_pose(&p, &lim()), Err(want), "{p:?}");
    }
    assert!(check_pose(&ok, &lim()).is_ok());
}

#[test]
fn small_drift_is_renormalised() {
    // |q| = 1.0005 is within the 1e-3 tolerance: accepted and made unit.
    let q = DQuat::from_axis_angle(DVec3::Y, 0.3) * 1.0005;
    let p = Pose { attitude: q, sun_dir: DVec3::new(0.6, 0.0, 0.8) * 0.9995, ..Pose::ahead(5.0) };
    let out = check_pose(&p, &lim()).unwrap();
    assert!((out.attitude.length() - 1.0).abs() < 1e-15);
    assert!((out.sun_dir.length() - 1.0).abs() < 1e-15);
    // Direction is unchanged by renormalisation.
    assert!((out.attitude - DQuat::from_axis_angle(DVec3::Y, 0.3)).length() < 1e-15);
    assert!((out.sun_dir - DVec3::new(0.6, 0.0, 0.8)).length() < 1e-15);
}

#[test]
fn backwards_time_dropped_equal_time_kept() {
    let mut v = PoseValidator::new(lim());
    let at = |t| Pose { t_ns: t, ..Pose::ahead(10.0) };
    assert!(v.check(&at(100)).is_ok());
    assert!(v.check(&at(100)).is_ok());
    assert_eq!(v.check(&at(99)), Err(Rejection::TimeBackwards));
    assert!(v.check(&at(101)).is_ok());
    // A rejected pose does not advance the clock.
    assert_eq!(v.check(&Pose { t_ns: 500, ..Pose::ahead(0.0) }), Err(Rejection::TooClose));
    assert!(v.check(&at(102)).is_ok());
    v.reset_time();
    assert!(v.check(&at(1)).is_ok());
}
