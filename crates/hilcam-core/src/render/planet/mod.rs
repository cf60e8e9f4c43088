//! A planet behind the target: a sphere lit by the same parallel sun, seen where the
//! target does not hide it, and lighting the target through the indirect bounces
//! (earthshine: the path tracer's escaping rays that meet the sphere pick up its radiance).
//!
//! Radiance leaving a surface point with outward normal `n` toward a viewer at `v`
//! (unit), the sun at `s`, `μ₀ = n·s`, `μ = n·v`, band irradiance `E`:
//! - Lambert, albedo ρ: `L = ρ·E·max(0, μ₀)/π` (the sphere's geometric albedo is 2ρ/3);
//! - Lommel–Seeliger, single-scattering albedo ϖ: BRDF `ϖ/(4π·(μ₀ + μ))`, so
//!   `L = ϖ·E/(4π) · μ₀/(μ₀ + μ)` for `μ₀ > 0` (geometric albedo ϖ/8; a disc of uniform
//!   radiance at full phase).
//!
//! The planet also shadows the sun (an eclipse, [`Eclipse`]): the sun is parallel, so a
//! point is dark when the line from it toward the sun crosses the sphere (no penumbra).
//! No atmosphere, no terrain, no clouds; the planet holds its place in the camera frame
//! over an exposure (a moving view smears the target, not the planet).

pub mod background;
pub mod sphere;

use crate::render::camera::{TargetBounds, View};
use crate::render::geometry::Ray;
use glam::DVec3;
use sphere::{Crossing, first_crossing};

/// How the planet's surface reflects sunlight.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlanetModel {
    /// `L = ρ·E·max(0, μ₀)/π`.
    #[default]
    Lambert,
    /// `L = ϖ·E/(4π) · μ₀/(μ₀ + μ)` (regolith: the Moon's flat-looking full disc).
    LommelSeeliger,
}

/// A sphere placed in the camera frame (what a scene's `[planet]` table says).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Planet {
    /// Centre, camera frame, metres.
    pub centre_cam: DVec3,
    pub radius_m: f64,
    /// ρ (Lambert) or ϖ (Lommel–Seeliger).
    pub albedo: f64,
    pub model: PlanetModel,
}

impl Planet {
    /// The planet in `view`'s render frame, lit by a sun of band irradiance `sun_irradiance`
    /// (W/m²) from `view.sun`.
    pub fn place(&self, view: &View, sun_irradiance: f32) -> PlacedPlanet {
        let centre = view.origin + view.cam_to_render * self.centre_cam;
        let scale = match self.model {
            PlanetModel::Lambert => self.albedo * f64::from(sun_irradiance) / std::f64::consts::PI,
            PlanetModel::LommelSeeliger => self.albedo * f64::from(sun_irradiance) / (4.0 * std::f64::consts::PI),
        };
        let placed = PlacedPlanet {
            centre,
            radius: self.radius_m,
            sun: view.sun.as_dvec3().normalize_or_zero(),
            model: self.model,
            scale,
            eclipse: Eclipse::Lit,
        };
        PlacedPlanet { eclipse: placed.eclipse_of(&view.bounds), ..placed }
    }
}

/// Whether the planet hides the sun from the target (found once per frame from the
/// target's bounding sphere, so that a target wholly in or out of the shadow costs no test
/// per shadow ray).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Eclipse {
    /// Every point of the target sees the sun.
    Lit,
    /// No point of the target sees the sun.
    Dark,
    /// The shadow's edge crosses the target's bounds: each shadow ray is tested.
    Partial,
}

/// A [`Planet`] in one frame's render frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedPlanet {
    /// Centre, render frame, metres.
    pub centre: DVec3,
    pub radius: f64,
    /// Unit vector toward the sun, render frame.
    pub sun: DVec3,
    pub model: PlanetModel,
    /// ρ·E/π (Lambert) or ϖ·E/(4π) (Lommel–Seeliger), W·sr⁻¹·m⁻².
    scale: f64,
    pub eclipse: Eclipse,
}

impl PlacedPlanet {
    /// Radiance (W·sr⁻¹·m⁻²) arriving at `o` along the unit vector `d` from the planet,
    /// or `None` when the line misses it. From inside the sphere (a target buried in the
    /// planet) the planet is an unlit opaque body: 0.
    #[inline]
    pub fn radiance(&self, o: DVec3, d: DVec3) -> Option<f32> {
        match first_crossing(o, d, self.centre, self.radius) {
            Crossing::Miss => None,
            Crossing::Inside => Some(0.0),
            Crossing::Enters(t) => {
                let n = ((o - self.centre) + d * t) / self.radius;
                Some(self.surface_radiance(n, -d) as f32)
            }
        }
    }

    /// [`PlacedPlanet::radiance`] along a traced ray (its f32 origin sits near the target).
    #[inline]
    pub fn radiance_of_ray(&self, ray: &Ray) -> Option<f32> {
        self.radiance(ray.origin.as_dvec3(), ray.dir.as_dvec3().normalize())
    }

    /// Radiance a camera sample at pixel coordinate `(x, y)` of `view` sees on the planet,
    /// or `None` if its line misses it: from the camera centre, in f64 (the disc's edge
    /// is exact at any range).
    #[inline]
    pub fn seen_by_camera(&self, view: &View, x: f64, y: f64) -> Option<f32> {
        let d = (view.cam_to_render * view.camera_dir(x, y)).normalize();
        self.radiance(view.origin, d)
    }

    /// Radiance leaving the surface point of outward unit normal `n` toward `to_viewer`.
    #[inline]
    pub fn surface_radiance(&self, n: DVec3, to_viewer: DVec3) -> f64 {
        let mu0 = n.dot(self.sun);
        if mu0 <= 0.0 {
            return 0.0;
        }
        match self.model {
            PlanetModel::Lambert => self.scale * mu0,
            PlanetModel::LommelSeeliger => self.scale * mu0 / (mu0 + n.dot(to_viewer).max(0.0)),
        }
    }

    /// True when the planet hides the sun from point `p` (render frame).
    #[inline]
    pub fn hides_sun(&self, p: DVec3) -> bool {
        !matches!(first_crossing(p, self.sun, self.centre, self.radius), Crossing::Miss)
    }

    /// Whether the target (its bounding sphere) lies out of, in, or across the planet's
    /// shadow: a cylinder of the planet's radius behind it, away from the sun.
    fn eclipse_of(&self, bounds: &TargetBounds) -> Eclipse {
        let f = bounds.centre - self.centre;
        let along = f.dot(self.sun); // > 0: the target is on the sun's side of the centre
        let across = (f - along * self.sun).length();
        let r = bounds.radius;
        if !(along.is_finite() && across.is_finite()) {
            return Eclipse::Lit;
        }
        // The shadow is the half-cylinder beyond the centre plus the sphere itself; a
        // target whose bounds touch the planet's sunward half is tested ray by ray.
        if along + r < 0.0 && across + r < self.radius {
            Eclipse::Dark
        } else if across - r > self.radius || (along - r > 0.0 && f.length() - r > self.radius) {
            Eclipse::Lit
        } else {
            Eclipse::Partial
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn planet(model: PlanetModel, sun: DVec3) -> PlacedPlanet {
        PlacedPlanet { centre: DVec3::new(0.0, 0.0, 10.0), radius: 2.0, sun, model, scale: 1.0, eclipse: Eclipse::Lit }
    }

    #[test]
    fn lambert_and_lommel_seeliger_at_the_sub_solar_point() {
        // Sun behind the viewer: the disc's centre has μ₀ = μ = 1.
        let l = planet(PlanetModel::Lambert, -DVec3::Z);
        assert_eq!(l.radiance(DVec3::ZERO, DVec3::Z), Some(1.0));
        let ls = planet(PlanetModel::LommelSeeliger, -DVec3::Z);
        assert_eq!(ls.radiance(DVec3::ZERO, DVec3::Z), Some(0.5));
        // Night side: sun beyond the planet.
        assert_eq!(planet(PlanetModel::Lambert, DVec3::Z).radiance(DVec3::ZERO, DVec3::Z), Some(0.0));
        assert_eq!(l.radiance(DVec3::ZERO, DVec3::X), None);
    }

    #[test]
    fn the_shadow_is_a_cylinder_behind_the_planet() {
        let p = planet(PlanetModel::Lambert, -DVec3::Z); // shadow along +z beyond z = 10
        assert!(p.hides_sun(DVec3::new(0.0, 0.0, 20.0)));
        assert!(p.hides_sun(DVec3::new(1.9, 0.0, 20.0)));
        assert!(!p.hides_sun(DVec3::new(2.1, 0.0, 20.0)));
        assert!(!p.hides_sun(DVec3::ZERO));
        let b = |x: f64, z: f64, r: f64| TargetBounds {
            centre: DVec3::new(x, 0.0, z),
            radius: r,
            min: DVec3::ZERO,
            max: DVec3::ZERO,
        };
        assert_eq!(p.eclipse_of(&b(0.0, 20.0, 0.5)), Eclipse::Dark);
        assert_eq!(p.eclipse_of(&b(2.0, 20.0, 0.5)), Eclipse::Partial);
        assert_eq!(p.eclipse_of(&b(3.0, 20.0, 0.5)), Eclipse::Lit);
        assert_eq!(p.eclipse_of(&b(0.0, 0.0, 0.5)), Eclipse::Lit);
    }
}
