//! How much light a rough dielectric coating (GGX, separable Smith, dielectric Fresnel)
//! lets through to the diffuse base of a rough plastic, and back out, tabulated once per
//! material in one of two couplings (docs/brdf.md, "Plastic"):
//!
//! - [`Coupling::Energy`] (the default): the base receives `t = 1 − E(μ)` — all that the
//!   coating's single scattering does not reflect, `E` its directional albedo — and the
//!   term is normalised by `1 − Ē` (Kelemen & Szirmay-Kalos 2001), so a white base under a
//!   white furnace returns exactly 1.
//! - [`Coupling::Mitsuba`]: Mitsuba 3's `roughplastic` (`nonlinear = false`): `t = T(μ)`,
//!   the rough interface's single-scattering transmittance, and the normalisation
//!   `η² (1 − F_int)` with `F_int` the interface's reflectance from inside averaged as
//!   Mitsuba averages it. Single scattering loses energy on both ways, so a white base
//!   returns less than 1 (≈ 0.73 at α 0.25, η 1.5). For comparing with Mitsuba.

use super::fresnel::dielectric;
use super::ggx::GgxDistribution;
use super::lobe::stratified_albedo;
use glam::{Vec2, Vec3};

/// Nodes of the table, at μ = j/(N − 1) (node 0 is evaluated at μ = 1e-3 for `E`, 1e-6
/// for `T`). Mitsuba's own tables have 64 nodes; 32 keep a material small (`Ggx` is
/// `Copy`) and interpolate T within ~1e-4 of them (the pointwise test against Mitsuba).
const N: usize = 32;
/// Nodes of Mitsuba's average of the internal reflectance (`MI_ROUGH_TRANSMITTANCE_RES`),
/// at μ = max(1e-6, j/63).
const N_MITSUBA: usize = 64;
/// Side of the stratified grid per node (64² VNDF samples: the weight `G1(wi)·F` is smooth,
/// so the error is ~1e-4).
const GRID: u32 = 64;
/// The same for the reflectance from inside, whose total internal reflection makes the
/// weight kink (Mitsuba uses 128² Gauss–Legendre nodes there too).
const GRID_INSIDE: u32 = 128;

/// How the base under the coating is coupled to it (scene key `coupling` of `ggx_plastic`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Coupling {
    /// `t = 1 − E`, normalised by `1 − Ē`: a white base returns all the light.
    #[default]
    Energy,
    /// Mitsuba 3's `roughplastic`: `t = T`, normalised by `η² (1 − F_int)`.
    Mitsuba,
}

/// The coating's table: what reaches the base, `t(μ)`, by linear interpolation, and the
/// diffuse term's normalisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoatingAlbedo {
    /// Node values: `E(μ)` for the energy coupling (`t = 1 − E`), `T(μ)` for Mitsuba's.
    v: [f32; N],
    coupling: Coupling,
    /// `Ē = 2∫ E(μ) μ dμ` (energy coupling), the coating's albedo under uniform light.
    pub mean: f32,
    /// The diffuse term's denominator: `1 − Ē`, or `η² (1 − F_int)`.
    pub norm: f32,
    /// `2∫ t(μ) μ dμ` over the interpolant: a base's share of uniform light.
    pub t_mean: f32,
}

impl CoatingAlbedo {
    /// A coating that reflects nothing (`η = 1`, or no diffuse base to couple).
    pub const NONE: CoatingAlbedo =
        CoatingAlbedo { v: [0.0; N], coupling: Coupling::Energy, mean: 0.0, norm: 1.0, t_mean: 1.0 };

    /// Tabulate the coating of roughness `dist` and index `eta` in the energy coupling.
    #[cfg(test)]
    pub fn new(dist: GgxDistribution, eta: f32) -> Self {
        CoatingAlbedo::coupled(dist, eta, Coupling::Energy)
    }

    /// Tabulate the coating of roughness `dist` and index `eta` in `coupling`.
    pub fn coupled(dist: GgxDistribution, eta: f32, coupling: Coupling) -> Self {
        let mut v = [0.0f32; N];
        match coupling {
            Coupling::Energy => {
                for (j, ej) in v.iter_mut().enumerate() {
                    *ej = reflectance(dist, (j as f32 / (N - 1) as f32).max(1e-3), eta, GRID);
                }
                let mean = (2.0 * linear_mu_integral(&v)) as f32;
                CoatingAlbedo { v, coupling, mean, norm: 1.0 - mean, t_mean: 1.0 - mean }
            }
            Coupling::Mitsuba => {
                for (j, tj) in v.iter_mut().enumerate() {
                    *tj = transmittance(dist, (j as f32 / (N - 1) as f32).max(1e-6), eta, GRID);
                }
                let mu = |j: usize| (j as f32 / (N_MITSUBA - 1) as f32).max(1e-6);
                // Mitsuba's average: 2 × the plain mean over its nodes of R(μ; 1/η)·μ.
                let f_int = 2.0
                    * (0..N_MITSUBA)
                        .map(|j| f64::from(reflectance(dist, mu(j), 1.0 / eta, GRID_INSIDE) * mu(j)))
                        .sum::<f64>()
                    / N_MITSUBA as f64;
                let norm = (f64::from(eta * eta) * (1.0 - f_int)) as f32;
                let t_mean = (2.0 * linear_mu_integral(&v)) as f32;
                CoatingAlbedo { v, coupling, mean: 0.0, norm, t_mean }
            }
        }
    }

    /// `(1 − w) a + w b`, node by node (its integrals are linear in the nodes too): the
    /// coating between two tabulated roughnesses (`coating_family`).
    pub fn blend(a: &CoatingAlbedo, b: &CoatingAlbedo, w: f32) -> CoatingAlbedo {
        debug_assert_eq!(a.coupling, b.coupling);
        let l = |x: f32, y: f32| x + w * (y - x);
        CoatingAlbedo {
            v: std::array::from_fn(|j| l(a.v[j], b.v[j])),
            coupling: a.coupling,
            mean: l(a.mean, b.mean),
            norm: l(a.norm, b.norm),
            t_mean: l(a.t_mean, b.t_mean),
        }
    }

    /// The table's value at μ by linear interpolation, μ clamped to [0, 1].
    #[inline]
    fn lerp(&self, mu: f32) -> f32 {
        let t = mu.clamp(0.0, 1.0) * (N - 1) as f32;
        let i = (t as usize).min(N - 2);
        let f = t - i as f32;
        self.v[i] + f * (self.v[i + 1] - self.v[i])
    }

    /// `E(μ)`, the coating's directional albedo (energy coupling's table).
    #[cfg(test)]
    pub fn at(&self, mu: f32) -> f32 {
        self.lerp(mu)
    }

    /// `t(μ)`: the share of light at cosine μ that reaches the base (and, reciprocally,
    /// leaves it toward μ).
    #[inline]
    pub fn transmitted(&self, mu: f32) -> f32 {
        match self.coupling {
            Coupling::Energy => 1.0 - self.lerp(mu),
            Coupling::Mitsuba => self.lerp(mu),
        }
    }
}

/// `∫₀¹ v(μ) μ dμ` of the piecewise-linear interpolant of `v` on nodes `j/(len − 1)`:
/// over [a, b], `(b − a)/6 · (v_a (2a + b) + v_b (a + 2b))`.
fn linear_mu_integral(v: &[f32]) -> f64 {
    let n = v.len();
    (0..n - 1)
        .map(|j| {
            let (a, b) = (j as f64 / (n - 1) as f64, (j + 1) as f64 / (n - 1) as f64);
            (b - a) / 6.0 * (f64::from(v[j]) * (2.0 * a + b) + f64::from(v[j + 1]) * (a + 2.0 * b))
        })
        .sum()
}

/// `R(μ; η)`: the interface's single-scattering reflectance from the side whose relative
/// index is `eta` (below 1: from inside, with total internal reflection), by a stratified
/// `grid²` visible-normal quadrature.
fn reflectance(dist: GgxDistribution, mu: f32, eta: f32, grid: u32) -> f32 {
    stratified_albedo(
        mu,
        grid,
        |o, u| dist.sample(o, u),
        |o, i| dist.eval_cos_no_fresnel(o, i).map_or(0.0, |(v, c)| v * dielectric(c, eta)),
        |o, i| dist.pdf(o, i),
    )
    .clamp(0.0, 1.0)
}

/// `T(μ; η)`: the interface's single-scattering transmittance into a medium of relative
/// index `eta`: over visible normals m seen from wi, `(1 − F(wi·m)) G1(wt)` with wt the
/// refracted direction (0 where it would not cross the surface).
fn transmittance(dist: GgxDistribution, mu: f32, eta: f32, grid: u32) -> f32 {
    let c = mu.clamp(1e-6, 1.0);
    let wi = Vec3::new((1.0 - c * c).max(0.0).sqrt(), 0.0, c);
    let mut sum = 0.0f64;
    for i in 0..grid {
        for j in 0..grid {
            let u = Vec2::new((i as f32 + 0.5) / grid as f32, (j as f32 + 0.5) / grid as f32);
            let m = dist.sample_visible_normal(wi, u);
            let cos_i = wi.dot(m);
            let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
            if cos_i <= 0.0 || sin2_t >= 1.0 {
                continue;
            }
            let cos_t = (1.0 - sin2_t).sqrt();
            let wt = -wi / eta + (cos_i / eta - cos_t) * m;
            if wt.z >= 0.0 {
                continue;
            }
            // G1 of the refracted direction, seen from below (its mirror image above).
            let g = dist.g1(Vec3::new(wt.x, wt.y, -wt.z).normalize());
            sum += f64::from((1.0 - dielectric(cos_i, eta)) * g);
        }
    }
    (sum / f64::from(grid * grid)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_smooth_coating_reflects_the_fresnel_reflectance() {
        // α → 0: the coating is a mirror, E(μ) = F(μ; η).
        let c = CoatingAlbedo::new(GgxDistribution { alpha: 1e-3 }, 1.5);
        for mu in [0.2f32, 0.5, 1.0] {
            assert!((c.at(mu) - dielectric(mu, 1.5)).abs() < 2e-3, "μ {mu}: {} vs {}", c.at(mu), dielectric(mu, 1.5));
        }
        // The smooth interface's hemispherical reflectance at η = 1.5 is 0.0918 (d'Eon's
        // Fdr tables; Egan & Hilgeman's fit gives 0.092).
        assert!((c.mean - 0.0918).abs() < 2e-3, "{}", c.mean);
    }

    #[test]
    fn a_smooth_coating_in_mitsubas_coupling_transmits_one_minus_fresnel() {
        // α → 0: T(μ) = 1 − F(μ; η), and from inside the interface reflects the smooth
        // internal reflectance, 2∫R μ dμ = 1 − (1 − Ē)/η² = 0.5963 at η 1.5, averaged as
        // Mitsuba does: 2 × the plain mean of R μ over 64 nodes j/63, which is the
        // trapezoid rule's 63/64 plus the end node's (R(1) = 0.04)/64: 0.5876.
        let c = CoatingAlbedo::coupled(GgxDistribution { alpha: 1e-3 }, 1.5, Coupling::Mitsuba);
        for mu in [0.2f32, 0.5, 1.0] {
            let want = 1.0 - dielectric(mu, 1.5);
            assert!((c.transmitted(mu) - want).abs() < 2e-3, "μ {mu}: {} vs {want}", c.transmitted(mu));
        }
        let f_int = 1.0 - c.norm / 2.25;
        let want = 63.0 / 64.0 * 0.5963 + 0.04 / 64.0;
        assert!((f_int - want).abs() < 2e-3, "F_int {f_int} vs {want}");
        // Energy: the same coating's t is 1 − E and its norm 1 − Ē.
        let e = CoatingAlbedo::new(GgxDistribution { alpha: 1e-3 }, 1.5);
        assert_eq!(e.norm, 1.0 - e.mean);
        assert_eq!(e.transmitted(0.5), 1.0 - e.at(0.5));
    }
}
