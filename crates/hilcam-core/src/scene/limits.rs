//! The physical ranges a scene's numbers must lie in, and the pose gate for the scene's
//! `[pose]` and `hilcam render --pose`. Every range is documented in docs/scene.md ("Accepted ranges and
//! refusals"); a value outside one is refused naming the field, the value and the range.

use crate::pose::Pose;
use crate::pose::validate::{PoseLimits, Rejection, check_pose};
use crate::render::camera::view::unit_or_none;
use glam::DVec3;

/// Sun band irradiance, W/m²: 0 (no sun) up to 1e6 (about 700× the solar constant at
/// 1 AU, i.e. closer to the sun than any mission flies); products with it stay finite in f32.
pub const IRRADIANCE_W_M2: (f64, f64) = (0.0, 1.0e6);
/// Background (sky) radiance, W·sr⁻¹·m⁻²: 0 up to 1e6.
pub const BACKGROUND_W_SR_M2: (f64, f64) = (0.0, 1.0e6);
/// Mesh translation, each component, metres.
pub const TRANSLATE_M: f64 = 1.0e5;
/// Mesh rotation, each Euler angle, degrees.
pub const ROTATE_DEG: f64 = 360.0;
/// Mesh scale factor (dimensionless: OBJ units to metres), the smallest and the default
/// largest ([`SceneLimits::max_scale`] raises the largest up to [`MAX_SCALE_CEILING`]).
pub const SCALE: (f64, f64) = (1.0e-6, 1.0e6);
/// The default largest pose range, metres (10 000 km: a rendezvous camera).
pub const MAX_RANGE_M: f64 = 1.0e7;
/// How far `[limits] max_range_m` may go: 100 AU, the planet's own limit. The render frame
/// sits at the target, so f32 geometry does not care about range; tests/render/limits.rs
/// renders a target at this range and finds it where the pinhole puts it.
pub const MAX_RANGE_CEILING_M: f64 = 1.5e13;
/// How far `[limits] max_scale` may go: a unit mesh 10⁹ m across (ten Jupiters; a planet's
/// largest radius), tested at this scale beside the range ceiling.
pub const MAX_SCALE_CEILING: f64 = 1.0e9;

/// A scene's `[limits]`: the largest pose range and mesh scale it accepts (docs/scene.md).
/// A Mars or Earth approach raises them; the defaults keep a rendezvous bench's gate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneLimits {
    /// Largest accepted |position|, m: every pose of this scene, from every input.
    pub max_range_m: f64,
    /// Largest accepted `[[mesh]] scale`.
    pub max_scale: f64,
}

impl Default for SceneLimits {
    fn default() -> Self {
        SceneLimits { max_range_m: MAX_RANGE_M, max_scale: SCALE.1 }
    }
}

impl SceneLimits {
    /// Checked: each within its ceiling (and above the smallest range or scale); a refusal
    /// names the key (`max_range_m`, `max_scale`) and the range.
    pub fn checked(max_range_m: f64, max_scale: f64) -> Result<SceneLimits, (&'static str, String)> {
        in_range(max_range_m, (PoseLimits::default().min_range_m, MAX_RANGE_CEILING_M), " m")
            .map_err(|m| ("max_range_m", m))?;
        in_range(max_scale, (SCALE.0, MAX_SCALE_CEILING), "").map_err(|m| ("max_scale", m))?;
        Ok(SceneLimits { max_range_m, max_scale })
    }

    /// The pose gate for this scene: the default gate with its largest range, and the
    /// radius of its planet (`None`: a pose that moves a planet is refused).
    pub fn pose_limits(&self, planet_radius_m: Option<f64>) -> PoseLimits {
        PoseLimits { max_range_m: self.max_range_m, planet_radius_m, ..PoseLimits::default() }
    }
}
/// OBJ vertex coordinate, each component, OBJ units (before `scale`).
pub const OBJ_COORD: f64 = 1.0e6;
/// Pixel pitch, µm (after `--width` rescaling too).
pub const PITCH_UM: (f64, f64) = (0.01, 1.0e5);
/// Focal length, mm.
pub const FOCAL_MM: (f64, f64) = (0.01, 1.0e5);
/// Path depth (surface interactions per path).
pub const MAX_DEPTH: u32 = 1024;

/// `Ok` when `v` is finite and in `lo..=hi`; else a message with the value, the range and
/// `unit`.
pub fn in_range(v: f64, (lo, hi): (f64, f64), unit: &str) -> Result<(), String> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(format!("must be a finite number in [{lo}, {hi}]{unit}, got {v:?}"))
    }
}

/// A pose refused by [`gate_pose`]: the field (`pose.position`, `pose.attitude`,
/// `pose.sun`) and the message (the gate's reason and the offending value).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRefusal {
    pub field: &'static str,
    pub message: String,
}

/// The live pose gate ([`check_pose`] with the scene's `lim`) for a pose written by
/// hand. The sun is a direction of any non-zero finite length: it is normalised first,
/// robustly (a huge vector is scaled by its largest component before squaring). The
/// attitude is not: a quaternion whose norm is not within the gate's tolerance of 1 is
/// refused, as it is on the wire.
///
/// The accepted pose is normalised as a loaded scene always was (`DQuat::normalize`,
/// `DVec3::normalize`), so frames keep their bytes.
pub fn gate_pose(p: &Pose, lim: &PoseLimits) -> Result<Pose, PoseRefusal> {
    let refuse = |field, message: String| Err(PoseRefusal { field, message });
    let Some(sun) = unit_or_none(p.sun_dir) else {
        let why = if p.sun_dir.is_finite() { "direction is zero" } else { "non-finite value" };
        return refuse("pose.sun", format!("{why} (got {})", fmt3(p.sun_dir)));
    };
    let candidate = Pose { sun_dir: sun, ..*p };
    match check_pose(&candidate, lim) {
        Ok(_) => Ok(Pose { attitude: p.attitude.normalize(), sun_dir: sun, ..*p }),
        Err(r) => {
            let q = p.attitude;
            // Scaled, so that a range beyond ~1e154 m prints as itself rather than inf.
            let big = p.position.abs().max_element();
            let range = if big > 0.0 { big * (p.position / big).length() } else { 0.0 };
            let (field, detail) = match r {
                Rejection::NonFinite if !p.position.is_finite() => ("pose.position", fmt3(p.position)),
                Rejection::NonFinite if !q.is_finite() => ("pose.attitude", fmt_q(p)),
                Rejection::NonFinite if p.planet_centre.is_some_and(|c| !c.is_finite()) => {
                    ("pose.planet_centre", String::new())
                }
                Rejection::NonFinite => ("pose.velocity", String::new()),
                Rejection::QuaternionNorm => (
                    "pose.attitude",
                    format!("norm {}, tolerance {:e}; attitude {}", q.length(), lim.norm_tolerance, fmt_q(p)),
                ),
                Rejection::SunNorm => ("pose.sun", fmt3(p.sun_dir)),
                Rejection::TooClose | Rejection::TooFar => (
                    "pose.position",
                    format!(
                        "range {range:e} m, limits {} … {:e} m; the largest is [limits] max_range_m",
                        lim.min_range_m, lim.max_range_m
                    ),
                ),
                Rejection::Planet => ("pose.planet_centre", crate::pose::validate::describe(p, r, lim)),
                Rejection::RateLimit | Rejection::TimeBackwards => ("pose", String::new()),
            };
            let message = if detail.is_empty() { r.to_string() } else { format!("{r} ({detail})") };
            refuse(field, message)
        }
    }
}

/// A pose given as numbers (`hilcam render --pose`, Python's `Renderer.render`): the
/// position `[px, py, pz]` (m, camera frame), optionally the attitude `[qw, qx, qy, qz]`
/// (body → camera) and the sun direction `[sx, sy, sz]`; what is not given comes from
/// `base` (the scene's `[pose]`). The result has passed [`gate_pose`] with the scene's
/// `lim`; a refusal reads `field: reason (value)`, the same text everywhere.
pub fn pose_from_numbers(
    lim: &PoseLimits,
    base: &Pose,
    position: [f64; 3],
    attitude: Option<[f64; 4]>,
    sun: Option<[f64; 3]>,
) -> Result<Pose, String> {
    let mut p = *base;
    p.position = DVec3::from_array(position);
    if let Some([w, x, y, z]) = attitude {
        p.attitude = glam::DQuat::from_xyzw(x, y, z, w);
    }
    if let Some(s) = sun {
        p.sun_dir = DVec3::from_array(s);
    }
    gate_pose(&p, lim).map_err(|e| format!("{}: {}", e.field, e.message))
}

fn fmt3(v: DVec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

fn fmt_q(p: &Pose) -> String {
    let q = p.attitude;
    format!("[{}, {}, {}, {}]", q.w, q.x, q.y, q.z)
}

/// [`CameraModel::scaled`] for sizes a user typed (`--width`/`--height`): each given side
/// and the size it implies must lie in `1..=MAX_SIDE_PX`, and the scaled camera must pass
/// the scene file's camera checks; the error names the flag and the limit.
pub fn checked_scaled_camera(
    c: &crate::render::camera::CameraModel,
    width: Option<u32>,
    height: Option<u32>,
) -> Result<crate::render::camera::CameraModel, String> {
    for (flag, v) in [("--width", width), ("--height", height)] {
        if let Some(v) = v {
            crate::render::camera::check_side(v).map_err(|m| format!("{flag}: {m}"))?;
        }
    }
    let scaled = c.scaled(width, height);
    let named = |(field, m): (&str, String)| format!("--width/--height: the scaled camera's {field} {m}");
    scaled.check_size().map_err(named)?;
    validate_camera(&scaled).map_err(named)?;
    Ok(scaled)
}

/// Size within [`crate::render::camera::MAX_SIDE_PX`] per side, pitch and focal length finite and
/// in their ranges, the principal point finite and within one image size of the centre.
pub fn validate_camera(c: &crate::render::camera::CameraModel) -> Result<(), (&'static str, String)> {
    c.check_size()?;
    in_range(c.pitch_um, PITCH_UM, " µm").map_err(|m| ("pitch_um", m))?;
    in_range(c.focal_mm, FOCAL_MM, " mm").map_err(|m| ("focal_mm", m))?;
    let bound = f64::from(c.width.max(c.height));
    for v in c.principal_point_px {
        in_range(v, (-bound, bound), " px (one image size)").map_err(|m| ("principal_point_px", m))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn the_gate_names_the_field_and_the_reason() {
        let ok = Pose::ahead(10.0);
        assert!(gate_pose(&ok, &PoseLimits::default()).is_ok());
        let e = gate_pose(&Pose { attitude: DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0), ..ok }, &PoseLimits::default())
            .unwrap_err();
        assert_eq!(e.field, "pose.attitude");
        assert!(e.message.contains("quaternion norm outside tolerance") && e.message.contains("norm 2"), "{e:?}");
        let e = gate_pose(&Pose { attitude: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), ..ok }, &PoseLimits::default())
            .unwrap_err();
        assert_eq!(e.field, "pose.attitude");
        let e = gate_pose(&Pose { sun_dir: DVec3::ZERO, ..ok }, &PoseLimits::default()).unwrap_err();
        assert_eq!(e.field, "pose.sun");
        let e = gate_pose(&Pose { position: DVec3::new(0.0, 0.0, 1e200), ..ok }, &PoseLimits::default()).unwrap_err();
        assert!(e.field == "pose.position" && e.message.contains("range above maximum"), "{e:?}");
        let e =
            gate_pose(&Pose { position: DVec3::new(f64::NAN, 0.0, 1.0), ..ok }, &PoseLimits::default()).unwrap_err();
        assert!(e.field == "pose.position" && e.message.contains("non-finite"), "{e:?}");
    }

    #[test]
    fn a_huge_sun_direction_is_normalised_robustly() {
        let p = Pose { sun_dir: DVec3::new(1e300, 0.0, -1e300), ..Pose::ahead(10.0) };
        let g = gate_pose(&p, &PoseLimits::default()).unwrap();
        assert!((g.sun_dir - DVec3::new(1.0, 0.0, -1.0).normalize()).length() < 1e-15, "{}", g.sun_dir);
        let p = Pose { sun_dir: DVec3::new(1e-320, 0.0, 0.0), ..Pose::ahead(10.0) };
        assert_eq!(gate_pose(&p, &PoseLimits::default()).unwrap().sun_dir, DVec3::X);
    }

    #[test]
    fn numbers_keep_what_is_not_given_and_pass_the_gate() {
        let base = Pose { sun_dir: DVec3::new(0.0, 0.0, -1.0), ..Pose::ahead(10.0) };
        let p = pose_from_numbers(&PoseLimits::default(), &base, [1.0, 2.0, 30.0], None, None).unwrap();
        assert_eq!((p.position, p.attitude, p.sun_dir), (DVec3::new(1.0, 2.0, 30.0), base.attitude, base.sun_dir));
        let p = pose_from_numbers(
            &PoseLimits::default(),
            &base,
            [0.0, 0.0, 5.0],
            Some([0.0, 1.0, 0.0, 0.0]),
            Some([0.0, 2.0, 0.0]),
        )
        .unwrap();
        assert_eq!((p.attitude, p.sun_dir), (DQuat::from_xyzw(1.0, 0.0, 0.0, 0.0), DVec3::Y));
        let e = pose_from_numbers(&PoseLimits::default(), &base, [f64::NAN, 0.0, 5.0], None, None).unwrap_err();
        assert_eq!(e, "pose.position: non-finite value ([NaN, 0, 5])");
        let e = pose_from_numbers(&PoseLimits::default(), &base, [0.0, 0.0, 5.0], None, Some([0.0; 3])).unwrap_err();
        assert_eq!(e, "pose.sun: direction is zero (got [0, 0, 0])");
    }
}
