//! Fresnel reflectance (unpolarised, one band) for the GGX models: a conductor's from its
//! complex index of refraction `n + ik`, Schlick's form from `F0` (glTF's metallic), and
//! a dielectric's from its real index `η` (outside medium: vacuum).

/// How a conductor's Fresnel reflectance is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConductorFresnel {
    /// Exact unpolarised reflectance of a complex index `n + ik` (pbrt-v3's `FrConductor`).
    Complex { n: f32, k: f32 },
    /// Schlick's `F0 + (1 − F0)(1 − cosθ)⁵` (glTF 2.0's metallic: F0 = base colour).
    Schlick { f0: f32 },
}

/// Named conductors: `[n, k]` for one band over 450–750 nm (docs/brdf.md: the pair whose
/// Fresnel curve is the least-squares fit, θ = 0…88°, to the band mean of the reflectance
/// computed from pbrt-v4's tabulated `metal-*-eta`/`metal-*-k` spectra, Palik's data).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
pub enum Metal {
    /// Gold: n 0.3804, k 2.4792 (F0 0.811).
    Au,
    /// Aluminium: n 1.2337, k 7.2602 (F0 0.915).
    Al,
    /// Silver: n 0.1283, k 3.4801 (F0 0.962).
    Ag,
    /// Copper: n 0.5479, k 2.8396 (F0 0.791).
    Cu,
}

impl Metal {
    /// `[n, k]` for hilcam's band.
    pub fn nk(self) -> [f32; 2] {
        match self {
            Metal::Au => [0.3804, 2.4792],
            Metal::Al => [1.2337, 7.2602],
            Metal::Ag => [0.1283, 3.4801],
            Metal::Cu => [0.5479, 2.8396],
        }
    }
}

impl ConductorFresnel {
    /// Reflectance at `cos` = cosine between the direction and the microfacet normal.
    #[inline]
    pub fn eval(&self, cos: f32) -> f32 {
        match *self {
            ConductorFresnel::Complex { n, k } => conductor(cos, n, k),
            ConductorFresnel::Schlick { f0 } => schlick(cos, f0),
        }
    }
}

/// Schlick's approximation.
#[inline]
pub fn schlick(cos: f32, f0: f32) -> f32 {
    let c = (1.0 - cos).clamp(0.0, 1.0);
    let c2 = c * c;
    f0 + (1.0 - f0) * c2 * c2 * c
}

/// Unpolarised reflectance of a conductor `n + ik` seen from vacuum, exact (the mean of
/// the s and p reflectances; pbrt-v3 `FrConductor`).
#[inline]
pub fn conductor(cos: f32, n: f32, k: f32) -> f32 {
    let c = cos.clamp(0.0, 1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let (n2, k2) = (n * n, k * k);
    let t0 = n2 - k2 - s2;
    let a2b2 = (t0 * t0 + 4.0 * n2 * k2).sqrt();
    let t1 = a2b2 + c2;
    let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + s2 * s2;
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    (0.5 * (rs + rp)).clamp(0.0, 1.0)
}

/// Unpolarised reflectance of a dielectric of index `eta` seen from vacuum (no total
/// internal reflection from this side).
#[inline]
pub fn dielectric(cos: f32, eta: f32) -> f32 {
    let c = cos.clamp(0.0, 1.0);
    let sin2_t = (1.0 - c * c) / (eta * eta);
    let ct = (1.0 - sin2_t).max(0.0).sqrt();
    let rs = (c - eta * ct) / (c + eta * ct);
    let rp = (eta * c - ct) / (eta * c + ct);
    (0.5 * (rs * rs + rp * rp)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_matches_the_closed_forms() {
        // Conductor: ((n−1)² + k²)/((n+1)² + k²); dielectric: ((η−1)/(η+1))².
        for m in [Metal::Au, Metal::Al, Metal::Ag, Metal::Cu] {
            let [n, k] = m.nk();
            let want = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
            assert!((conductor(1.0, n, k) - want).abs() < 1e-6, "{m:?}");
        }
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // A conductor with k = 0 is a dielectric.
        for c in [0.1f32, 0.5, 0.9] {
            assert!((conductor(c, 1.5, 0.0) - dielectric(c, 1.5)).abs() < 1e-5, "{c}");
        }
    }

    #[test]
    fn grazing_incidence_reflects_everything() {
        assert!((conductor(0.0, 0.38, 2.48) - 1.0).abs() < 1e-6);
        assert!((dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(schlick(0.0, 0.3), 1.0);
    }

    #[test]
    fn dielectric_brewster_angle_has_no_p_reflection() {
        // At tanθ = η, rp = 0, so F = rs²/2 with rs = (cosθ − η cosθt)/(cosθ + η cosθt).
        let eta = 1.5f64;
        let th = eta.atan();
        let ct = (1.0 - th.sin().powi(2) / (eta * eta)).sqrt();
        let rs = (th.cos() - eta * ct) / (th.cos() + eta * ct);
        assert!((f64::from(dielectric(th.cos() as f32, 1.5)) - rs * rs / 2.0).abs() < 1e-6);
    }
}
