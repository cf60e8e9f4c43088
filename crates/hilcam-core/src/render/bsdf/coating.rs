//! The directional albedo `E(μ)` of a rough dielectric coating (GGX, separable Smith,
//! dielectric Fresnel), tabulated once per material: the rough plastic's diffuse base sees
//! only the light the coating does not reflect, `1 − E(μ)` on the way in and on the way
//! out (Kelemen & Szirmay-Kalos 2001's coupling; docs/brdf.md).

use super::fresnel::dielectric;
use super::ggx::GgxDistribution;
use super::lobe::stratified_albedo;

/// Nodes of the table, at μ = j/(N − 1) (node 0 is evaluated at μ = 1e-3).
const N: usize = 32;
/// Side of the stratified grid per node (64² VNDF samples: the weight `G1(wi)·F` is smooth,
/// so the error is ~1e-4).
const GRID: u32 = 64;

/// `E(μ)` on a linear grid, with its cosine-weighted hemispherical mean
/// `Ē = 2∫ E(μ) μ dμ` taken exactly over the same piecewise-linear interpolant, so that
/// the coupled diffuse term integrates to `1 − E(μo)` exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoatingAlbedo {
    e: [f32; N],
    /// `Ē`, the coating's albedo under uniform illumination.
    pub mean: f32,
}

impl CoatingAlbedo {
    /// A coating that reflects nothing (`η = 1`, or no diffuse base to couple).
    pub const NONE: CoatingAlbedo = CoatingAlbedo { e: [0.0; N], mean: 0.0 };

    /// Tabulate the coating of roughness `dist` and index `eta`.
    pub fn new(dist: GgxDistribution, eta: f32) -> Self {
        let mut e = [0.0f32; N];
        for (j, ej) in e.iter_mut().enumerate() {
            let mu = (j as f32 / (N - 1) as f32).max(1e-3);
            *ej = stratified_albedo(
                mu,
                GRID,
                |o, u| dist.sample(o, u),
                |o, i| dist.eval_cos_no_fresnel(o, i).map_or(0.0, |(v, c)| v * dielectric(c, eta)),
                |o, i| dist.pdf(o, i),
            )
            .clamp(0.0, 1.0);
        }
        // ∫ over [a, b] of a linear E times μ: (b − a)/6 · (E_a (2a + b) + E_b (a + 2b)).
        let mut mean = 0.0f64;
        for j in 0..N - 1 {
            let (a, b) = (j as f64 / (N - 1) as f64, (j + 1) as f64 / (N - 1) as f64);
            mean += (b - a) / 6.0 * (f64::from(e[j]) * (2.0 * a + b) + f64::from(e[j + 1]) * (a + 2.0 * b));
        }
        CoatingAlbedo { e, mean: (2.0 * mean) as f32 }
    }

    /// `E(μ)` by linear interpolation, μ clamped to [0, 1].
    #[inline]
    pub fn at(&self, mu: f32) -> f32 {
        let t = mu.clamp(0.0, 1.0) * (N - 1) as f32;
        let i = (t as usize).min(N - 2);
        let f = t - i as f32;
        self.e[i] + f * (self.e[i + 1] - self.e[i])
    }
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
}
