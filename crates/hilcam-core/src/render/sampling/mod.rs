//! Deterministic random numbers and the warps that turn them into directions.
//!
//! Every random number is a pure function of (seed, frame, pixel, sample, dimension),
//! so an image does not depend on how rayon schedules pixels onto threads.

pub mod sobol;

use glam::{Vec2, Vec3};
pub use sobol::SobolStream;
use std::f32::consts::{FRAC_1_PI, PI};

/// A small, fast generator (PCG32, O'Neill 2014) seeded from a hash of the sample's key.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

const PCG_MULT: u64 = 6364136223846793005;
const PCG_INC: u64 = 1442695040888963407;

/// SplitMix64 finaliser: a strong 64-bit mixer for building keys.
#[inline]
pub const fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

impl Rng {
    /// The stream for one camera sample: keyed by (seed, frame, pixel index, sample index).
    #[inline]
    pub fn for_sample(seed: u64, frame: u64, pixel: u64, sample: u32) -> Self {
        let k = mix64(seed ^ mix64(frame.wrapping_add(0x9e3779b97f4a7c15)));
        let k = mix64(k ^ mix64(pixel.wrapping_mul(0xd1b54a32d192ed03)));
        let k = mix64(k ^ u64::from(sample).wrapping_mul(0xa0761d6478bd642f));
        Self::from_state(k)
    }

    #[inline]
    pub fn from_state(state: u64) -> Self {
        let mut r = Rng { state: 0 };
        r.state = r.state.wrapping_mul(PCG_MULT).wrapping_add(PCG_INC);
        r.state = r.state.wrapping_add(state);
        r.state = r.state.wrapping_mul(PCG_MULT).wrapping_add(PCG_INC);
        r
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULT).wrapping_add(PCG_INC);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1): 24 random bits, so the result never rounds up to 1.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

/// Where an estimator takes its random numbers from.
pub trait SampleSource {
    fn next_1d(&mut self) -> f32;
    fn next_2d(&mut self) -> Vec2;
}

/// A [`SampleSource`] keyed by (seed, frame, pixel, sample index): one per camera sample.
pub trait PerSample: SampleSource + Sized {
    fn for_sample(seed: u64, frame: u64, pixel: u64, index: u32) -> Self;
}

impl PerSample for Rng {
    #[inline]
    fn for_sample(seed: u64, frame: u64, pixel: u64, index: u32) -> Self {
        Rng::for_sample(seed, frame, pixel, index)
    }
}

impl PerSample for SobolStream {
    #[inline]
    fn for_sample(seed: u64, frame: u64, pixel: u64, index: u32) -> Self {
        SobolStream::new(seed, frame, pixel, index)
    }
}

impl SampleSource for Rng {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        self.next_f32()
    }
    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        Rng::next_2d(self)
    }
}

impl SampleSource for SobolStream {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        SobolStream::next_1d(self)
    }
    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        SobolStream::next_2d(self)
    }
}

/// Which sequence feeds the estimator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sequence {
    /// Independent random numbers (PCG32) per sample.
    Independent,
    /// Shuffled Owen-scrambled Sobol points per dimension pair (stratified).
    #[default]
    Sobol,
}

/// Uniform direction on the upper (+Z) hemisphere; pdf 1/(2π).
#[inline]
pub fn uniform_hemisphere(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

pub const UNIFORM_HEMISPHERE_PDF: f32 = 0.5 * FRAC_1_PI;

/// Cosine-weighted direction on the upper (+Z) hemisphere (Malley's method with
/// Shirley's concentric disk); pdf cosθ/π.
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Shirley–Chiu concentric map from the unit square to the unit disk (area-preserving).
///
/// Its angle always reduces to `φ ∈ [−π/4, π/4]` (the second case uses cos(π/2 − φ) =
/// sin φ), where short Taylor polynomials are within 3·10⁻⁸ of sin and cos (before f32 rounding): no call to
/// `sincosf` (~3 % of a 1-spp frame, every bounce draws one).
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    if o.x.abs() > o.y.abs() {
        let (s, c) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (o.y / o.x));
        o.x * Vec2::new(c, s)
    } else {
        let (s, c) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (o.x / o.y));
        o.y * Vec2::new(s, c)
    }
}

/// sin and cos of `x ∈ [−π/4, π/4]`: Taylor terms to x⁹ and x⁸ (truncation below 2·10⁻⁹
/// and 3·10⁻⁸ there), evaluated by Horner's rule in x².
#[inline]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let s = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0)))));
    let c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0))));
    (s, c)
}

/// The local shading basis: orthonormal, with `n` as +Z (Duff et al. 2017, branchless
/// and exact for unit n). BSDFs work in it.
#[derive(Clone, Copy, Debug)]
pub struct ShadingBasis {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl ShadingBasis {
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bb = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        ShadingBasis { t, b: bb, n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_a_pure_function_of_its_key() {
        let a: Vec<u32> = (0..8).map(|_| 0).scan(Rng::for_sample(1, 2, 3, 4), |r, _| Some(r.next_u32())).collect();
        let b: Vec<u32> = (0..8).map(|_| 0).scan(Rng::for_sample(1, 2, 3, 4), |r, _| Some(r.next_u32())).collect();
        let c: Vec<u32> = (0..8).map(|_| 0).scan(Rng::for_sample(1, 2, 3, 5), |r, _| Some(r.next_u32())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn rng_uniform_mean_and_range() {
        let mut r = Rng::for_sample(7, 0, 0, 0);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.003);
    }

    #[test]
    fn quarter_sin_cos_match_f64_to_f32_rounding() {
        let mut worst = 0.0f64;
        for k in 0..=100_000 {
            let x = (f64::from(k) / 50_000.0 - 1.0) * std::f64::consts::FRAC_PI_4;
            let (s, c) = sin_cos_quarter(x as f32);
            let x = f64::from(x as f32);
            worst = worst.max((f64::from(s) - x.sin()).abs()).max((f64::from(c) - x.cos()).abs());
        }
        assert!(worst < 2e-7, "{worst}");
    }

    #[test]
    fn concentric_disk_matches_the_angle_form() {
        // The map as Shirley and Chiu write it, in f64.
        let reference = |u: Vec2| {
            let (x, y) = (2.0 * f64::from(u.x) - 1.0, 2.0 * f64::from(u.y) - 1.0);
            let (r, t) = if x.abs() > y.abs() {
                (x, std::f64::consts::FRAC_PI_4 * (y / x))
            } else {
                (y, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (x / y))
            };
            (r * t.cos(), r * t.sin())
        };
        let mut r = Rng::from_state(11);
        for _ in 0..200_000 {
            let u = Vec2::new(r.next_f32(), r.next_f32());
            let d = concentric_disk(u);
            let (x, y) = reference(u);
            assert!((f64::from(d.x) - x).abs() < 4e-7 && (f64::from(d.y) - y).abs() < 4e-7, "{u}: {d} vs ({x}, {y})");
        }
        assert_eq!(concentric_disk(Vec2::splat(0.5)), Vec2::ZERO);
    }

    #[test]
    fn frame_is_orthonormal_for_any_normal() {
        let mut r = Rng::from_state(3);
        for _ in 0..10_000 {
            let n = (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 2.0 - 1.0).normalize_or(Vec3::Z);
            let f = ShadingBasis::from_normal(n);
            assert!(f.t.dot(f.b).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5 && f.b.dot(n).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5 && (f.b.length() - 1.0).abs() < 1e-5);
            let v = Vec3::new(0.3, -0.2, 0.9);
            assert!((f.to_local(f.to_world(v)) - v).length() < 1e-5);
        }
        // The branch cut at n = -Z.
        let f = ShadingBasis::from_normal(-Vec3::Z);
        assert!(f.t.dot(f.b).abs() < 1e-6);
    }

    #[test]
    fn cosine_hemisphere_matches_its_pdf_in_mean_cos() {
        // E[cosθ] under pdf cosθ/π is 2/3; under uniform it is 1/2.
        let mut r = Rng::from_state(11);
        let n = 200_000;
        let (mut c, mut u) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let w = cosine_hemisphere(r.next_2d());
            assert!((w.length() - 1.0).abs() < 1e-4 && w.z >= 0.0);
            c += w.z as f64;
            u += uniform_hemisphere(r.next_2d()).z as f64;
        }
        assert!((c / n as f64 - 2.0 / 3.0).abs() < 0.003);
        assert!((u / n as f64 - 0.5).abs() < 0.003);
    }

    #[allow(clippy::needless_range_loop)]
    /// Bin sampled directions by (cosθ, φ) and compare each bin's count with the pdf
    /// integrated over the bin by quadrature (chi-square, as pbrt's bsdfs_test does).
    fn chi_square(sample: impl Fn(Vec2) -> Vec3, pdf: impl Fn(Vec3) -> f32) -> (f64, usize, f64) {
        const NT: usize = 16;
        const NP: usize = 32;
        let n = 400_000usize;
        let mut counts = [[0u32; NP]; NT];
        let mut r = Rng::from_state(99);
        for _ in 0..n {
            let w = sample(r.next_2d());
            let it = ((w.z.clamp(0.0, 0.999_999)) * NT as f32) as usize;
            let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
            let ip = ((phi / (2.0 * PI)) * NP as f32).min(NP as f32 - 1.0) as usize;
            counts[it][ip] += 1;
        }
        // Expected counts: ∫ pdf dω over each bin, dω = d(cosθ) dφ; 8×8 midpoint quadrature.
        let (mut chi2, mut dof, mut total_p) = (0.0f64, 0usize, 0.0f64);
        for it in 0..NT {
            for ip in 0..NP {
                let mut p = 0.0f64;
                for a in 0..8 {
                    for b in 0..8 {
                        let z = (it as f32 + (a as f32 + 0.5) / 8.0) / NT as f32;
                        let phi = (ip as f32 + (b as f32 + 0.5) / 8.0) / NP as f32 * 2.0 * PI;
                        let s = (1.0 - z * z).max(0.0).sqrt();
                        p += pdf(Vec3::new(s * phi.cos(), s * phi.sin(), z)) as f64;
                    }
                }
                let p = p / 64.0 * (1.0 / NT as f64) * (2.0 * std::f64::consts::PI / NP as f64);
                total_p += p;
                let e = p * n as f64;
                let o = counts[it][ip] as f64;
                chi2 += (o - e) * (o - e) / e;
                dof += 1;
            }
        }
        (chi2, dof - 1, total_p)
    }

    #[test]
    fn hemisphere_samplers_match_their_pdfs() {
        for (name, (chi2, dof, total)) in [
            ("uniform", chi_square(uniform_hemisphere, |_| UNIFORM_HEMISPHERE_PDF)),
            ("cosine", chi_square(cosine_hemisphere, |w| cosine_hemisphere_pdf(w.z))),
        ] {
            // The pdf integrates to 1 over the hemisphere.
            assert!((total - 1.0).abs() < 1e-3, "{name}: ∫pdf = {total}");
            // For 511 degrees of freedom, χ² above dof + 5·sqrt(2·dof) ≈ 671 has p < 1e-6.
            let limit = dof as f64 + 5.0 * (2.0 * dof as f64).sqrt();
            assert!(chi2 < limit, "{name}: chi2 {chi2:.1} for {dof} dof (limit {limit:.0})");
        }
    }
}
