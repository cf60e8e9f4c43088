//! The scene file's `[planet]` table: a sphere behind the target, in the camera frame.
//!
//! ```toml
//! [planet]
//! body = "earth"                 # preset radius and albedo: "earth" | "moon"
//! radius_m = 6.371e6             # overrides the preset's
//! albedo = 0.3                   # ρ (lambert) or ϖ (lommel-seeliger), 0..=1
//! model = "lambert"              # or "lommel-seeliger"
//! center_m = [0.0, 6.771e6, 0.0] # camera frame, metres
//! ```

use crate::render::planet::{Planet, PlanetModel};
use glam::DVec3;
use serde::Deserialize;
use toml::Spanned;

/// Earth's mean radius, metres, and a Bond albedo of 0.3.
pub const EARTH: (f64, f64) = (6.371e6, 0.3);
/// The Moon's mean radius, metres, and its Bond albedo, 0.11.
pub const MOON: (f64, f64) = (1.7374e6, 0.11);
/// Radius, metres: a 1 m boulder up to ten times Jupiter.
pub const RADIUS_M: (f64, f64) = (1.0, 1.0e9);
/// Distance of the centre from the camera, metres: up to 100 AU.
pub const MAX_DISTANCE_M: f64 = crate::pose::validate::MAX_PLANET_DISTANCE_M;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlanetSection {
    body: Option<Spanned<String>>,
    radius_m: Option<Spanned<f64>>,
    albedo: Option<Spanned<f64>>,
    #[serde(default)]
    model: PlanetModel,
    center_m: Spanned<[f64; 3]>,
}

/// A refused `[planet]`: the byte span, the key (`planet.radius_m`, …) and why.
pub(super) type Refusal = (std::ops::Range<usize>, String, String);

impl PlanetSection {
    /// The planet, or the first key whose value is refused. `table` is the span of the
    /// whole table (named when a key is missing).
    pub(super) fn build(&self, table: std::ops::Range<usize>) -> Result<Planet, Refusal> {
        let refuse = |span: std::ops::Range<usize>, key: &str, m: String| (span, format!("planet.{key}"), m);
        let preset = match &self.body {
            None => None,
            Some(b) => Some(body_preset(b.get_ref()).map_err(|m| refuse(b.span(), "body", m))?),
        };
        let radius = match (&self.radius_m, preset) {
            (Some(r), _) => {
                let v = *r.get_ref();
                super::limits::in_range(v, RADIUS_M, " m").map_err(|m| refuse(r.span(), "radius_m", m))?;
                v
            }
            (None, Some((r, _))) => r,
            (None, None) => return Err(refuse(table, "radius_m", "give radius_m or body".into())),
        };
        let albedo = match (&self.albedo, preset) {
            (Some(a), _) => {
                let v = *a.get_ref();
                super::limits::in_range(v, (0.0, 1.0), "").map_err(|m| refuse(a.span(), "albedo", m))?;
                v
            }
            (None, Some((_, a))) => a,
            (None, None) => return Err(refuse(table, "albedo", "give albedo or body".into())),
        };
        let span = self.center_m.span();
        checked_planet(DVec3::from_array(*self.center_m.get_ref()), radius, albedo, self.model)
            .map_err(|(key, m)| refuse(span, key, m))
    }
}

/// The planet a `[planet]` table or Python's `Renderer.render(planet=…)` describes, its
/// centre `centre` in the camera frame (m), checked: the radius within [`RADIUS_M`], the
/// albedo in 0..=1, the centre finite and within [`MAX_DISTANCE_M`] of the camera, the
/// camera outside the sphere. A refusal: the key (`radius_m`, `albedo`, `center_m`) and why.
pub fn checked_planet(
    centre: DVec3,
    radius: f64,
    albedo: f64,
    model: PlanetModel,
) -> Result<Planet, (&'static str, String)> {
    super::limits::in_range(radius, RADIUS_M, " m").map_err(|m| ("radius_m", m))?;
    super::limits::in_range(albedo, (0.0, 1.0), "").map_err(|m| ("albedo", m))?;
    let dist = centre.length();
    if !(centre.is_finite() && dist <= MAX_DISTANCE_M) {
        let m = format!("must be finite and within {MAX_DISTANCE_M:e} m of the camera, got {centre:?}");
        return Err(("center_m", m));
    }
    if dist <= radius {
        let m = format!("the camera is inside the planet: |center_m| = {dist} m ≤ radius {radius} m");
        return Err(("center_m", m));
    }
    Ok(Planet { centre_cam: centre, radius_m: radius, albedo, model })
}

/// A body's preset radius (m) and albedo by name (`earth`, `moon`).
pub fn body_preset(name: &str) -> Result<(f64, f64), String> {
    match name {
        "earth" => Ok(EARTH),
        "moon" => Ok(MOON),
        other => Err(format!("unknown body `{other}` (known: earth, moon)")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_planet_from_code_is_checked_as_the_table_is() {
        let au = 1.495978707e11;
        let p = checked_planet(DVec3::new(0.0, 0.0, au), EARTH.0, EARTH.1, PlanetModel::Lambert).unwrap();
        assert_eq!((p.centre_cam.z, p.radius_m, p.albedo), (au, 6.371e6, 0.3));
        let inside = checked_planet(DVec3::new(0.0, 0.0, 1e6), EARTH.0, 0.3, PlanetModel::Lambert).unwrap_err();
        assert_eq!(inside.0, "center_m");
        assert!(inside.1.starts_with("the camera is inside the planet"), "{}", inside.1);
        let far = checked_planet(DVec3::new(0.0, 0.0, 1e14), MOON.0, 0.1, PlanetModel::Lambert).unwrap_err();
        assert_eq!(far.0, "center_m");
        let nan = checked_planet(DVec3::new(f64::NAN, 0.0, au), EARTH.0, 0.3, PlanetModel::Lambert).unwrap_err();
        assert_eq!(nan.0, "center_m");
        assert_eq!(checked_planet(DVec3::Z * au, 0.5, 0.3, PlanetModel::Lambert).unwrap_err().0, "radius_m");
        assert_eq!(checked_planet(DVec3::Z * au, EARTH.0, 1.5, PlanetModel::Lambert).unwrap_err().0, "albedo");
        assert_eq!(body_preset("moon"), Ok(MOON));
        assert_eq!(body_preset("mars"), Err("unknown body `mars` (known: earth, moon)".into()));
    }
}
