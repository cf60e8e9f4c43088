//! Pose validation: every decoded pose passes here before anything renders it.
//!
//! Checks, in order: all values finite; attitude quaternion norm within
//! [`PoseLimits::norm_tolerance`] of 1 (then renormalised) else rejected; the
//! same for the sun direction; range within `[min_range_m, max_range_m]`;
//! optional speed / angular-rate limits; a planet centre, when the pose carries one,
//! finite, outside the scene's planet and within 100 AU; simulation time not before the
//! last accepted pose. Every rejection is a [`Rejection`] the caller logs and counts.

use super::Pose;

/// Farthest accepted planet centre from the camera, metres: 100 AU (a scene's `[planet]`
/// table and a pose's planet centre alike).
pub const MAX_PLANET_DISTANCE_M: f64 = 1.5e13;

/// Configured limits (defaults suit a rendezvous camera: 0.1 m … 10 000 km).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseLimits {
    /// Smallest accepted range (|position|), m.
    pub min_range_m: f64,
    /// Largest accepted range, m.
    pub max_range_m: f64,
    /// Largest accepted |‖q‖ − 1| and |‖sun‖ − 1|; smaller drift is renormalised.
    pub norm_tolerance: f64,
    /// Largest accepted |velocity|, m/s.
    pub max_speed_mps: f64,
    /// Largest accepted |angular rate|, rad/s.
    pub max_angular_rate_rps: f64,
    /// The radius (m) of the scene's planet that a pose's `planet_centre` moves; `None`:
    /// the scene has no planet, and a pose that carries a centre is refused.
    pub planet_radius_m: Option<f64>,
}

impl Default for PoseLimits {
    fn default() -> Self {
        PoseLimits {
            min_range_m: 0.1,
            max_range_m: 1.0e7,
            // CAN's Q23 quaternion and Q15 sun quantisation stay far inside this.
            norm_tolerance: 1.0e-3,
            max_speed_mps: 1.0e4,
            max_angular_rate_rps: 10.0,
            planet_radius_m: None,
        }
    }
}

/// Why a pose was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum Rejection {
    /// A NaN or infinite value.
    #[error("non-finite value")]
    NonFinite,
    /// Attitude quaternion norm too far from 1.
    #[error("quaternion norm outside tolerance")]
    QuaternionNorm,
    /// Sun direction norm too far from 1.
    #[error("sun direction not a unit vector")]
    SunNorm,
    /// Range below the minimum.
    #[error("range below minimum")]
    TooClose,
    /// Range above the maximum.
    #[error("range above maximum")]
    TooFar,
    /// Velocity or angular rate above its limit.
    #[error("velocity or angular rate above limit")]
    RateLimit,
    /// Simulation time earlier than the last accepted pose.
    #[error("timestamp went backwards")]
    TimeBackwards,
    /// A planet centre the scene cannot render: no `[planet]` to move, the camera inside
    /// the sphere, or farther than [`MAX_PLANET_DISTANCE_M`].
    #[error("planet centre refused")]
    Planet,
}

impl Rejection {
    /// Every reason, for exporting zero-valued counters.
    pub const ALL: [Rejection; 8] = [
        Rejection::NonFinite,
        Rejection::QuaternionNorm,
        Rejection::SunNorm,
        Rejection::TooClose,
        Rejection::TooFar,
        Rejection::RateLimit,
        Rejection::TimeBackwards,
        Rejection::Planet,
    ];

    /// Stable snake_case name for logs and metric labels.
    pub fn as_str(&self) -> &'static str {
        match self {
            Rejection::NonFinite => "non_finite",
            Rejection::QuaternionNorm => "quaternion_norm",
            Rejection::SunNorm => "sun_norm",
            Rejection::TooClose => "too_close",
            Rejection::TooFar => "too_far",
            Rejection::RateLimit => "rate_limit",
            Rejection::TimeBackwards => "time_backwards",
            Rejection::Planet => "planet",
        }
    }
}

/// Euclidean norm without overflow or underflow: 1e200 and 1e-200 components give their
/// true norm, not infinity or zero (finite inputs; the checks test finiteness first).
/// Ordinary values take the plain formula, so renormalised poses keep their bits.
fn norm<const N: usize>(v: [f64; N]) -> f64 {
    let plain = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if plain.is_finite() && plain > 1e-150 {
        return plain;
    }
    let m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    m * v.iter().map(|x| (x / m) * (x / m)).sum::<f64>().sqrt()
}

/// Stateless checks of one pose; returns it with unit quaternion and sun.
///
/// # Errors
/// The first failed check.
pub fn check_pose(p: &Pose, lim: &PoseLimits) -> Result<Pose, Rejection> {
    let q = p.attitude;
    let finite = p.position.is_finite()
        && q.is_finite()
        && p.sun_dir.is_finite()
        && p.velocity.is_none_or(|v| v.is_finite())
        && p.angular_rate.is_none_or(|v| v.is_finite())
        && p.planet_centre.is_none_or(|v| v.is_finite());
    if !finite {
        return Err(Rejection::NonFinite);
    }
    let qn = norm(glam::DVec4::from(q).to_array());
    if (qn - 1.0).abs() > lim.norm_tolerance {
        return Err(Rejection::QuaternionNorm);
    }
    let sn = norm(p.sun_dir.to_array());
    if (sn - 1.0).abs() > lim.norm_tolerance {
        return Err(Rejection::SunNorm);
    }
    let range = norm(p.position.to_array());
    if range < lim.min_range_m {
        return Err(Rejection::TooClose);
    }
    if range > lim.max_range_m {
        return Err(Rejection::TooFar);
    }
    if p.velocity.is_some_and(|v| norm(v.to_array()) > lim.max_speed_mps)
        || p.angular_rate.is_some_and(|w| norm(w.to_array()) > lim.max_angular_rate_rps)
    {
        return Err(Rejection::RateLimit);
    }
    if let Some(c) = p.planet_centre {
        let d = norm(c.to_array());
        if lim.planet_radius_m.is_none_or(|r| d <= r) || d > MAX_PLANET_DISTANCE_M {
            return Err(Rejection::Planet);
        }
    }
    Ok(Pose { attitude: q / qn, sun_dir: p.sun_dir / sn, ..*p })
}

/// The offending value behind `r`, for an error message: "range 2e8 m, above the 1e7 m limit".
pub fn describe(p: &Pose, r: Rejection, lim: &PoseLimits) -> String {
    match r {
        Rejection::NonFinite => {
            let fields = [
                ("position", p.position.is_finite()),
                ("attitude", p.attitude.is_finite()),
                ("sun", p.sun_dir.is_finite()),
                ("velocity", p.velocity.is_none_or(|v| v.is_finite())),
                ("angular rate", p.angular_rate.is_none_or(|v| v.is_finite())),
                ("planet centre", p.planet_centre.is_none_or(|v| v.is_finite())),
            ];
            let bad: Vec<&str> = fields.iter().filter(|(_, ok)| !ok).map(|(n, _)| *n).collect();
            format!("NaN or infinity in {}", bad.join(", "))
        }
        Rejection::QuaternionNorm => {
            format!(
                "attitude norm {:e}, must be within {:e} of 1",
                norm(glam::DVec4::from(p.attitude).to_array()),
                lim.norm_tolerance
            )
        }
        Rejection::SunNorm => {
            format!("sun norm {:e}, must be within {:e} of 1", norm(p.sun_dir.to_array()), lim.norm_tolerance)
        }
        Rejection::TooClose => {
            format!("range {:e} m, below the {:e} m limit", norm(p.position.to_array()), lim.min_range_m)
        }
        Rejection::TooFar => {
            let r = norm(p.position.to_array());
            format!("range {r:e} m, above the {:e} m limit (the scene's [limits] max_range_m)", lim.max_range_m)
        }
        Rejection::RateLimit => format!(
            "speed {:e} m/s (limit {:e}), angular rate {:e} rad/s (limit {:e})",
            p.velocity.map_or(0.0, |v| norm(v.to_array())),
            lim.max_speed_mps,
            p.angular_rate.map_or(0.0, |w| norm(w.to_array())),
            lim.max_angular_rate_rps
        ),
        Rejection::TimeBackwards => format!("t_ns {} is earlier than the last accepted pose", p.t_ns),
        Rejection::Planet => {
            let d = p.planet_centre.map_or(0.0, |c| norm(c.to_array()));
            match lim.planet_radius_m {
                None => "the pose moves a planet but the scene has no [planet]".into(),
                Some(r) if d <= r => {
                    format!("|planet centre| {d:e} m ≤ the planet's radius {r:e} m: the camera is inside it")
                }
                Some(_) => format!("|planet centre| {d:e} m, above the {:e} m limit", MAX_PLANET_DISTANCE_M),
            }
        }
    }
}

/// Stateful validator for one pose stream: [`check_pose`] plus monotonic time.
#[derive(Clone, Debug)]
pub struct PoseValidator {
    limits: PoseLimits,
    last_t_ns: Option<u64>,
}

impl PoseValidator {
    /// A validator with no pose seen yet.
    pub fn new(limits: PoseLimits) -> Self {
        PoseValidator { limits, last_t_ns: None }
    }

    /// The limits in force.
    pub fn limits(&self) -> &PoseLimits {
        &self.limits
    }

    /// Forgets the last timestamp (e.g. after the sender restarted its
    /// simulation; the transports call it on reconnect).
    pub fn reset_time(&mut self) {
        self.last_t_ns = None;
    }

    /// Checks `p`; on success remembers its time. Equal timestamps pass
    /// (a sender may repeat a pose), earlier ones do not.
    ///
    /// # Errors
    /// The [`Rejection`] reason.
    pub fn check(&mut self, p: &Pose) -> Result<Pose, Rejection> {
        let ok = check_pose(p, &self.limits)?;
        if self.last_t_ns.is_some_and(|last| p.t_ns < last) {
            return Err(Rejection::TimeBackwards);
        }
        self.last_t_ns = Some(p.t_ns);
        Ok(ok)
    }
}
