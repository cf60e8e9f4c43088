//! The GGX (Trowbridge–Reitz) microfacet distribution with separable Smith masking and
//! visible-normal sampling (Heitz 2018, "Sampling the GGX Distribution of Visible
//! Normals", JCGT 7(4)). Local frame, normal = +Z; isotropic, α = roughness².
//!
//! - `D(h) = α² / (π (α² cos²θh + sin²θh)²)`: the usual `1/(π α² cos⁴θh (1 + tan²θh/α²)²)`
//!   written with sin²θh from the half vector's x/y components (no cancellation near the
//!   normal, and no division by cos⁴θh).
//! - `G1(v) = 2 cosθ / (cosθ + √(cos²θ + α² sin²θ))`, the exact Smith term of GGX
//!   (`1/(1 + Λ)`), finite at grazing; `G = G1(wo)·G1(wi)` (separable, as Mitsuba's
//!   `roughconductor` and `roughplastic`).
//! - Sampling draws `h` from the visible normals `D_wo(h) = G1(wo) max(0, wo·h) D(h) / cosθo`
//!   and mirrors `wo`, so `pdf(wi) = G1(wo) D(h) / (4 cosθo)` and a conductor's weight
//!   `f cosθi / pdf` is `G1(wi)·F`, never more than 1.

use super::lobe::{Half, reflect};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Lowest roughness α accepted: below it `D` exceeds f32 near the peak.
pub const MIN_ALPHA: f32 = 1e-4;

/// An isotropic GGX distribution of microfacet normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxDistribution {
    /// α (the glTF / Disney `roughness` squared), in [1e-4, 1].
    pub alpha: f32,
}

impl GgxDistribution {
    /// `D(h)` from the stable half-vector quantities.
    #[inline]
    pub(crate) fn d(&self, hv: &Half) -> f32 {
        let a2 = self.alpha * self.alpha;
        let t = a2 * hv.cos * hv.cos + hv.sin2;
        (a2 / (PI * t * t)).min(f32::MAX)
    }

    /// `G1(v) / cosθv = 2 / (cosθ + √(cos²θ + α² sin²θ))`: finite as cosθ → 0, which lets
    /// `1/cosθo` of the BRDF cancel exactly.
    #[inline]
    pub(crate) fn g1_over_cos(&self, v: Vec3) -> f32 {
        let s2 = v.x * v.x + v.y * v.y;
        2.0 / (v.z + (v.z * v.z + self.alpha * self.alpha * s2).sqrt())
    }

    /// Smith `G1(v)`, in [0, 1] for `v.z ≥ 0`.
    #[inline]
    pub(crate) fn g1(&self, v: Vec3) -> f32 {
        (v.z * self.g1_over_cos(v)).min(1.0)
    }

    /// A microfacet normal drawn from the visible normals seen from `wo` (`wo.z > 0`),
    /// Heitz 2018, listing 1.
    #[inline]
    pub(crate) fn sample_visible_normal(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        // Stretch the view so the distribution becomes the hemisphere of a unit sphere.
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        // A uniform point on the disc, squeezed onto the part of the hemisphere seen from vh.
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Unstretch.
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
    }

    /// `wi` mirrored about a visible normal; `None` when it falls below the horizon.
    #[inline]
    pub(crate) fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let h = self.sample_visible_normal(wo, u);
        let wi = reflect(wo, h);
        (wi.z > 0.0 && wi.is_finite()).then(|| wi.normalize())
    }

    /// Solid-angle density of [`GgxDistribution::sample`]: `G1(wo) D(h) / (4 cosθo)`.
    #[inline]
    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let Some(hv) = Half::new(wo, wi) else {
            return 0.0;
        };
        (self.d(&hv) * self.g1_over_cos(wo) * 0.25).min(f32::MAX)
    }

    /// `D G1(wo) G1(wi) / (4 cosθo cosθi) · cosθi`, without Fresnel, and `wi·h`.
    #[inline]
    pub(crate) fn eval_cos_no_fresnel(&self, wo: Vec3, wi: Vec3) -> Option<(f32, f32)> {
        let hv = Half::new(wo, wi)?;
        let v = self.d(&hv) * self.g1_over_cos(wo) * self.g1(wi) * 0.25;
        Some((v.min(f32::MAX), hv.wo_dot_h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d_is_normalised_over_projected_area() {
        // ∫ D(h) cosθh dω = 1, by midpoint quadrature in θh (f64 reference of the formula).
        for alpha in [0.05f32, 0.3, 1.0] {
            let n = 20_000;
            let mut s = 0.0f64;
            for i in 0..n {
                let th = (i as f64 + 0.5) / n as f64 * std::f64::consts::FRAC_PI_2;
                let hv = Half { cos: th.cos() as f32, sin2: (th.sin() * th.sin()) as f32, wo_dot_h: 1.0 };
                let d = f64::from(GgxDistribution { alpha }.d(&hv));
                s += d * th.cos() * th.sin() * 2.0 * std::f64::consts::PI * std::f64::consts::FRAC_PI_2 / n as f64;
            }
            assert!((s - 1.0).abs() < 2e-3, "α {alpha}: ∫D cos = {s}");
        }
    }

    #[test]
    fn visible_normals_face_the_viewer() {
        let g = GgxDistribution { alpha: 0.7 };
        let wo = Vec3::new(0.99f32.sqrt(), 0.0, 0.1);
        let mut rng = crate::render::sampling::Rng::for_sample(7, 0, 0, 0);
        for _ in 0..10_000 {
            let h = g.sample_visible_normal(wo, rng.next_2d());
            assert!(h.z >= 0.0 && wo.dot(h) >= -1e-6, "{h}");
            assert!((h.length() - 1.0).abs() < 1e-5);
        }
    }
}
