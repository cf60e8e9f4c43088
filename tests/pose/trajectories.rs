//! The shipped trajectories meet their briefs (5 m target, 1024² camera with a
//! 20° field of view), and their velocity / angular-rate columns are consistent
//! with the poses (checked by extrapolating one step and comparing with the
//! next sample, an independent check of the rate convention).

use glam::{DQuat, DVec3};
use hilcam_core::pose::trajectory::{Trajectory, TrajectorySample};

const HALF_FOV: f64 = 10.0 * std::f64::consts::PI / 180.0;

fn load(name: &str) -> Vec<TrajectorySample> {
    Trajectory::load(format!("{}/scenes/trajectories/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

fn off_boresight(p: DVec3) -> f64 {
    p.angle_between(DVec3::Z)
}

#[test]
fn approach_goes_from_1_km_to_10_m_with_target_in_view() {
    let s = load("approach.csv");
    let r: Vec<f64> = s.iter().map(|x| x.position.length()).collect();
    assert!((r[0] - 1000.0).abs() < 1e-6, "{}", r[0]);
    assert!((r[r.len() - 1] - 10.0).abs() < 1e-6);
    assert!(r.windows(2).all(|w| w[1] < w[0]), "range decreases monotonically");
    for x in &s {
        assert!((x.attitude.length() - 1.0).abs() < 1e-12);
        assert!((x.sun_dir.length() - 1.0).abs() < 1e-12);
        // Target centre in the field of view with margin for its 2.5 m radius
        // while it still fits (beyond ~15 m), and always near the boresight.
        assert!(off_boresight(x.position) < 0.01);
        let radius = (2.5 / x.position.length()).asin();
        if x.position.length() > 15.0 {
            assert!(off_boresight(x.position) + radius < HALF_FOV);
        }
    }
    // The 5 m target spans ~15 px at 1 km and overfills the frame at 10 m.
    let px = |range: f64| (5.0 / range) / (2.0 * HALF_FOV) * 1024.0;
    assert!(px(r[0]) > 10.0 && px(r[0]) < 20.0 && px(r[r.len() - 1]) > 1024.0);
}

#[test]
fn flyaround_keeps_target_on_boresight_while_sun_moves() {
    let s = load("flyaround.csv");
    let mut max_sun_cam = 0.0f64;
    let mut max_sun_body = 0.0f64;
    let body_sun = |x: &TrajectorySample| x.attitude.inverse() * x.sun_dir;
    for x in &s {
        let r = x.position.length();
        assert!((30.0..=50.0).contains(&r), "range {r}");
        assert!(off_boresight(x.position) < 1e-9);
        // 5 m target at ≥ 32 m: fits in the 20° field of view.
        assert!((2.5 / r).asin() < HALF_FOV);
        max_sun_cam = max_sun_cam.max(x.sun_dir.angle_between(s[0].sun_dir));
        max_sun_body = max_sun_body.max(body_sun(x).angle_between(body_sun(&s[0])));
    }
    assert!(max_sun_cam > 90f64.to_radians(), "sun sweeps in the camera frame: {max_sun_cam}");
    assert!(max_sun_body > 45f64.to_radians(), "sun moves over the target body: {max_sun_body}");
}

#[test]
fn flyaround_rates_predict_the_next_sample() {
    let s = load("flyaround.csv");
    let (mut worst_p, mut worst_q, mut hold_q) = (0.0f64, 0.0f64, 0.0f64);
    for w in s.windows(2) {
        let dt = w[1].time_s - w[0].time_s;
        let v = w[0].velocity.unwrap();
        let om = w[0].angular_rate.unwrap();
        worst_p = worst_p.max((w[0].position + v * dt - w[1].position).length());
        // dq/dt = ½ ω ⊗ q, ω in the camera frame: q(t+dt) ≈ exp(ω dt) ⊗ q(t).
        let step =
            if om.length() > 0.0 { DQuat::from_axis_angle(om.normalize(), om.length() * dt) } else { DQuat::IDENTITY };
        worst_q = worst_q.max((step * w[0].attitude).angle_between(w[1].attitude));
        hold_q = hold_q.max(w[0].attitude.angle_between(w[1].attitude));
    }
    // Second-order residuals only, far below the first-order change itself.
    assert!(worst_p < 1e-3, "position extrapolation error {worst_p} m");
    assert!(worst_q < 1e-5, "attitude extrapolation error {worst_q} rad");
    assert!(hold_q > 100.0 * worst_q, "rates carry information: {hold_q} vs {worst_q}");
}

#[test]
fn save_then_load_is_exact() {
    let s = load("flyaround.csv");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.csv");
    Trajectory::save(&p, &s).unwrap();
    assert_eq!(Trajectory::load(&p).unwrap(), s);
    let e = Trajectory::load(dir.path().join("missing.csv")).unwrap_err();
    assert!(e.to_string().contains("missing.csv"));
}
