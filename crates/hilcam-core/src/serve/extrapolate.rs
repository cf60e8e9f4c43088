//! Moving a pose forward in time with its relative velocity and angular rate (constant
//! rates over the short interval between a pose's arrival and the exposure mid-time).

use crate::pose::Pose;
use glam::{DQuat, DVec3};

/// The pose `dt_s` seconds later. Without rates it is returned unchanged (flagged by the
/// `bool`: true when something was extrapolated).
pub fn extrapolate(p: &Pose, dt_s: f64) -> (Pose, bool) {
    if dt_s == 0.0 || (p.velocity.is_none() && p.angular_rate.is_none()) {
        return (*p, false);
    }
    let mut out = *p;
    if let Some(v) = p.velocity {
        out.position = p.position + v * dt_s;
    }
    if let Some(w) = p.angular_rate {
        // ω is the body's angular rate relative to the camera, in the camera frame:
        // q(t+dt) = exp(ω·dt/2) ⊗ q(t).
        let angle = w.length() * dt_s;
        if angle != 0.0 {
            let dq = DQuat::from_axis_angle(w.normalize(), angle);
            out.attitude = (dq * p.attitude).normalize();
        }
    }
    let dt_ns = (dt_s * 1e9).round();
    out.t_ns = if dt_ns >= 0.0 { p.t_ns.saturating_add(dt_ns as u64) } else { p.t_ns.saturating_sub((-dt_ns) as u64) };
    (out, true)
}

/// Camera-frame velocity of a body point under the pose's rates (for tests and docs).
pub fn point_velocity(p: &Pose, body_point: DVec3) -> DVec3 {
    let r = p.attitude * body_point;
    p.velocity.unwrap_or(DVec3::ZERO) + p.angular_rate.unwrap_or(DVec3::ZERO).cross(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_rates_match_a_finely_integrated_motion() {
        let p = Pose {
            velocity: Some(DVec3::new(0.3, -0.1, -2.0)),
            angular_rate: Some(DVec3::new(0.05, 0.2, -0.1)),
            attitude: DQuat::from_rotation_x(0.4),
            ..Pose::ahead(50.0)
        };
        // Integrate a body point's motion with 10 000 small Euler steps.
        let point = DVec3::new(1.0, 2.0, -0.5);
        let (mut q, mut pos) = (p.attitude, p.position);
        let n = 10_000;
        let dt = 0.25 / n as f64;
        for _ in 0..n {
            let w = p.angular_rate.unwrap();
            q = (DQuat::from_axis_angle(w.normalize(), w.length() * dt) * q).normalize();
            pos += p.velocity.unwrap() * dt;
        }
        let (e, moved) = extrapolate(&p, 0.25);
        assert!(moved);
        let want = q * point + pos;
        let got = e.attitude * point + e.position;
        assert!((want - got).length() < 1e-9, "{want} vs {got}");
        assert_eq!(e.t_ns, p.t_ns + 250_000_000);
        assert!(point_velocity(&p, point).length() > 0.0);
    }

    #[test]
    fn no_rates_no_change() {
        let p = Pose::ahead(10.0);
        assert_eq!(extrapolate(&p, 1.0), (p, false));
    }
}
