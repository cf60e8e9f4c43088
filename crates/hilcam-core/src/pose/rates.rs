//! Relative velocity and angular rate of trajectory rows that give none, from their
//! neighbouring rows (what a camera that integrates over its exposure moves the pose by).

use crate::pose::trajectory::TrajectorySample;
use glam::DQuat;

/// Fill each sample's missing velocity and angular rate with central differences of its
/// neighbours (one-sided at the ends; nothing for a single row). Rates a row gives are
/// kept. The angular rate is the body's relative to the camera, in the camera frame,
/// as the pose convention has it: `q(t + dt) = exp(ω·dt/2) ⊗ q(t)`.
pub fn fill_missing_rates(samples: &mut [TrajectorySample]) {
    let n = samples.len();
    if n < 2 {
        return;
    }
    let rates: Vec<_> = (0..n)
        .map(|k| {
            let (a, b) = (&samples[k.saturating_sub(1)], &samples[(k + 1).min(n - 1)]);
            let dt = b.time_s - a.time_s;
            let velocity = (b.position - a.position) / dt;
            // Shortest rotation from a's attitude to b's.
            let mut dq = (b.attitude * a.attitude.inverse()).normalize();
            if dq.w < 0.0 {
                dq = -dq;
            }
            (velocity, DQuat::to_scaled_axis(dq) / dt)
        })
        .collect();
    for (s, (v, w)) in samples.iter_mut().zip(rates) {
        s.velocity.get_or_insert(v);
        s.angular_rate.get_or_insert(w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn row(t: f64, w: DVec3, v: DVec3) -> TrajectorySample {
        TrajectorySample {
            time_s: t,
            position: DVec3::new(0.0, 0.0, 20.0) + v * t,
            attitude: DQuat::from_scaled_axis(w * t) * DQuat::from_rotation_x(0.2),
            sun_dir: DVec3::NEG_Z,
            velocity: None,
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        }
    }

    #[test]
    fn constant_motion_is_recovered_at_every_row() {
        let (w, v) = (DVec3::new(0.01, -0.02, 0.05), DVec3::new(0.3, 0.0, -1.0));
        let mut rows: Vec<_> = (0..5).map(|k| row(k as f64 * 0.1, w, v)).collect();
        fill_missing_rates(&mut rows);
        for r in &rows {
            assert!((r.velocity.unwrap() - v).length() < 1e-12, "{:?}", r.velocity);
            assert!((r.angular_rate.unwrap() - w).length() < 1e-12, "{:?}", r.angular_rate);
        }
    }

    #[test]
    fn given_rates_are_kept_and_one_row_gets_none() {
        let mut rows = vec![row(0.0, DVec3::ZERO, DVec3::X), row(1.0, DVec3::ZERO, DVec3::X)];
        rows[0].velocity = Some(DVec3::Y);
        fill_missing_rates(&mut rows);
        assert_eq!(rows[0].velocity, Some(DVec3::Y));
        assert_eq!(rows[1].velocity, Some(DVec3::X));
        let mut one = vec![row(0.0, DVec3::ZERO, DVec3::X)];
        fill_missing_rates(&mut one);
        assert_eq!(one[0].velocity, None);
    }
}
