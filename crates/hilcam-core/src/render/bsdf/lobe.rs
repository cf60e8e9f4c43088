//! Half-vector geometry and the Blinn lobe shared by the Blinn-Phong models.
//!
//! Everything is in the local shading frame (normal = +Z). The formulas avoid the
//! cancellation in `1 − n·h` that destroys `(n·h)^α` for α in the thousands: the
//! half-vector's sin²θh comes straight from its x/y components, and
//! `(n·h)^α = exp(α · ½ · ln1p(−sin²θh))`.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The half vector of `wo` and `wi` with the quantities the lobes need, computed stably.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Half {
    /// cosθh = n·h (> 0 when both directions are above the surface).
    pub cos: f32,
    /// sin²θh, from the x/y components (no cancellation near the normal).
    pub sin2: f32,
    /// wo·h = wi·h = |wo + wi| / 2 (≥ 0 for unit vectors).
    pub wo_dot_h: f32,
}

impl Half {
    /// `None` if either direction is at or below the horizon (the BRDF is zero there).
    #[inline]
    pub fn new(wo: Vec3, wi: Vec3) -> Option<Half> {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return None;
        }
        // Rescale before squaring: at grazing angles |wo + wi|² underflows f32.
        let sum = wo + wi;
        let scale = sum.abs().max_element();
        let v = sum * (1.0 / scale);
        let len2 = v.length_squared();
        let len = len2.sqrt();
        let sin2 = ((v.x * v.x + v.y * v.y) / len2).min(1.0);
        Some(Half { cos: v.z / len, sin2, wo_dot_h: 0.5 * len * scale })
    }

    /// `ln cosθh`, accurate when θh is tiny.
    #[inline]
    pub fn ln_cos(&self) -> f32 {
        0.5 * (-self.sin2).ln_1p()
    }

    /// `1 − cosθh = sin²θh / (1 + cosθh)`, accurate when θh is tiny.
    #[inline]
    pub fn one_minus_cos(&self) -> f32 {
        self.sin2 / (1.0 + self.cos)
    }
}

/// `x^p` for `x > 0` as `exp(p · ln x)`; 0 for `x ≤ 0` unless `p == 0`.
#[inline]
pub(crate) fn pow_pos(x: f32, p: f32) -> f32 {
    if p == 0.0 {
        1.0
    } else if x <= 0.0 {
        0.0
    } else {
        (p * x.ln()).exp()
    }
}

/// Mirror `wo` about the unit half vector `h`.
#[inline]
pub(crate) fn reflect(wo: Vec3, h: Vec3) -> Vec3 {
    2.0 * wo.dot(h) * h - wo
}

/// The Blinn-Phong specular lobe of Eq. (4)/(5):
/// `f_s = ρs · (n·h)^α / (n·l)^a · exp(−b · (1 − n·h)^(1/π))`, with `l = wi`.
/// Eq. (4) is `a = 1, b = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlinnLobe {
    /// Specular coefficient ρs (sr⁻¹ scale; not an albedo).
    pub rho_s: f32,
    /// Blinn exponent α on n·h.
    pub alpha: f32,
    /// Exponent a on the incidence cosine in the denominator, 0 ≤ a ≤ 1.
    pub a: f32,
    /// Fall-off coefficient b ≥ 0 of the exp term.
    pub b: f32,
}

impl BlinnLobe {
    /// `f_s · cosθi` as one finite product: the `(n·l)^-a` of Eq. (5) and the `cosθi` of
    /// the rendering equation combine into `cosθi^(1−a)`, bounded by 1 for `a ≤ 1`.
    #[inline]
    pub fn eval_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.beyond_lobe(wo, wi) {
            return 0.0;
        }
        let Some(hv) = Half::new(wo, wi) else {
            return 0.0;
        };
        self.rho_s * self.shape(&hv) * pow_pos(wi.z, 1.0 - self.a)
    }

    /// True where `(n·h)^α` underflows f32 to exactly 0, so the lobe (and its sampling
    /// density) is exactly 0 without a square root, a division, a logarithm and two
    /// exponentials. Most directions of a sharp lobe (α = 3865.7: θh > 14.5°) land here.
    /// Bound: `α·ln cosθh = α·½·ln(1 − sin²θh) ≤ −α·sin²θh/2 < −120` when
    /// `α·sin²θh > 240`, and f32 `exp(x)` is 0 below x ≈ −103.9. With `s = wo + wi`,
    /// `sin²θh = (s_x² + s_y²)/|s|²`, compared without dividing; when `|s|²` is tiny
    /// (both directions grazing, opposite) the test declines and the full path runs.
    #[inline]
    fn beyond_lobe(&self, wo: Vec3, wi: Vec3) -> bool {
        let s = wo + wi;
        let t = s.x * s.x + s.y * s.y;
        let l2 = t + s.z * s.z;
        l2 > 1e-30 && self.alpha * t > 240.0 * l2
    }

    /// `(n·h)^α · exp(−b (1 − n·h)^(1/π))`, in [0, 1].
    #[inline]
    fn shape(&self, hv: &Half) -> f32 {
        let blinn = (self.alpha * hv.ln_cos()).exp();
        let fall = if self.b == 0.0 { 1.0 } else { (-self.b * pow_pos(hv.one_minus_cos(), 1.0 / PI)).exp() };
        blinn * fall
    }

    /// Sample `h` with density `(α+1)/(2π) · cos^α θh` (`cosθh = u^(1/(α+1))`, computed
    /// in logs so α = 10⁵ is exact), then mirror `wo`. `None` below the horizon.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        // 1 − u ∈ (0, 1]: ln is finite.
        let ln_cos = (1.0 - u.x).ln() / (self.alpha + 1.0);
        let cos = ln_cos.exp();
        let sin = (-(2.0 * ln_cos).exp_m1()).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let h = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos);
        let wi = reflect(wo, h);
        (wi.z > 0.0 && wo.z > 0.0).then(|| wi.normalize())
    }

    /// Solid-angle density of [`BlinnLobe::sample`]: `pdf_h / (4 wo·h)`.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.beyond_lobe(wo, wi) {
            return 0.0;
        }
        let Some(hv) = Half::new(wo, wi) else {
            return 0.0;
        };
        let pdf_h = (self.alpha + 1.0) / (2.0 * PI) * (self.alpha * hv.ln_cos()).exp();
        (pdf_h / (4.0 * hv.wo_dot_h)).min(f32::MAX)
    }

    /// A cheap estimate of the lobe's directional albedo, used only to choose between
    /// lobes: near the normal `∫ cos^α θh dω = 2π/(α+1)`, the Jacobian is `4 wo·h ≈
    /// 4 cosθo`, `cosθi ≈ cosθo`, and the exp term is taken at the lobe's mean
    /// `1 − cosθh ≈ 1/(α+2)`.
    pub fn albedo_hint(&self, cos_o: f32) -> f32 {
        let fall = (-self.b * pow_pos(1.0 / (self.alpha + 2.0), 1.0 / PI)).exp();
        let c = cos_o.clamp(0.0, 1.0);
        self.rho_s * 8.0 * PI / (self.alpha + 1.0) * fall * pow_pos(c, 2.0 - self.a)
    }
}

/// Deterministic estimate of a lobe's directional albedo `∫ f_s cosθi dωi` by sampling
/// it with its own sampler on an `n × n` stratified grid (midpoints). The ratio
/// `f cos / pdf` is smooth inside the lobe, so this converges fast.
pub(crate) fn stratified_albedo(
    cos_o: f32,
    n: u32,
    sample: impl Fn(Vec3, Vec2) -> Option<Vec3>,
    eval_cos: impl Fn(Vec3, Vec3) -> f32,
    pdf: impl Fn(Vec3, Vec3) -> f32,
) -> f32 {
    let c = cos_o.clamp(0.0, 1.0);
    let wo = Vec3::new((1.0 - c * c).max(0.0).sqrt(), 0.0, c);
    if c <= 0.0 {
        return 0.0;
    }
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            if let Some(wi) = sample(wo, u) {
                let p = pdf(wo, wi);
                if p > 0.0 {
                    sum += f64::from(eval_cos(wo, wi)) / f64::from(p);
                }
            }
        }
    }
    (sum / f64::from(n * n)) as f32
}

/// Largest directional albedo of a lobe over a grid of view angles (0°…89.5°), used to
/// normalise a lobe so that `ρd + albedo ≤ 1` everywhere.
pub(crate) fn max_albedo(albedo_at: impl Fn(f32) -> f32) -> f32 {
    let mut m = 0.0f32;
    for k in 0..=90 {
        let theta = (k as f32).min(89.5).to_radians();
        m = m.max(albedo_at(theta.cos()));
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_cos_is_exact_near_the_normal() {
        // θh = 1e-4 rad: f32 cos rounds to 1, but the x/y route keeps sin² = 1e-8.
        let t = 1e-4f32;
        let wo = Vec3::new(t.sin(), 0.0, t.cos());
        let wi = Vec3::new(t.sin(), 0.0, t.cos()); // h = wo, θh = t
        let hv = Half::new(wo, wi).unwrap();
        let want = (f64::from(t)).cos().ln();
        assert!((f64::from(hv.ln_cos()) - want).abs() < 1e-12, "{}", hv.ln_cos());
        // (n·h)^1e5 = exp(-1e5 · 5e-9) ≈ 0.9995.
        let l = BlinnLobe { rho_s: 1.0, alpha: 1e5, a: 1.0, b: 0.0 };
        let v = l.eval_cos(wo, wi);
        assert!((f64::from(v) - (1e5 * want).exp()).abs() < 1e-5, "{v}");
    }

    #[test]
    fn the_lobe_shortcut_only_skips_exact_zeros() {
        // Wherever `beyond_lobe` answers, the full formula underflows to exactly 0 too.
        let mut rng = crate::render::sampling::Rng::for_sample(3, 0, 0, 0);
        let mut skipped = 0;
        for alpha in [20.0f32, 300.0, 3865.7, 1e5] {
            let lobe = BlinnLobe { rho_s: 283.9, alpha, a: 0.9665, b: 1.3965 };
            for _ in 0..20_000 {
                let wo = crate::render::sampling::cosine_hemisphere(rng.next_2d());
                // Directions concentrated near the mirror direction, where the bound is tight.
                let jitter = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.0) * 0.3;
                let wi = (Vec3::new(-wo.x, -wo.y, wo.z) + jitter).normalize();
                let Some(hv) = Half::new(wo, wi) else { continue };
                if lobe.beyond_lobe(wo, wi) {
                    skipped += 1;
                    assert_eq!(lobe.shape(&hv), 0.0, "α {alpha}, sin² {}", hv.sin2);
                    assert_eq!((alpha * hv.ln_cos()).exp(), 0.0);
                }
            }
        }
        assert!(skipped > 10_000, "only {skipped} evaluations skipped");
    }

    #[test]
    fn sampled_cos_theta_h_follows_u_to_the_one_over_alpha_plus_one() {
        let l = BlinnLobe { rho_s: 1.0, alpha: 3865.7, a: 1.0, b: 0.0 };
        let wo = Vec3::Z;
        for &ux in &[0.0f32, 0.1, 0.5, 0.9, 0.999] {
            let wi = l.sample(wo, Vec2::new(ux, 0.3)).unwrap();
            let h = (wo + wi).normalize();
            let want = (1.0 - f64::from(ux)).powf(1.0 / 3866.7);
            assert!((f64::from(h.z) - want).abs() < 1e-6);
        }
    }

    #[test]
    fn albedo_hint_is_close_to_the_stratified_albedo_at_normal_incidence() {
        let l = BlinnLobe { rho_s: 283.9, alpha: 3865.7, a: 0.9665, b: 1.3965 };
        let est = stratified_albedo(1.0, 64, |o, u| l.sample(o, u), |o, i| l.eval_cos(o, i), |o, i| l.pdf(o, i));
        let hint = l.albedo_hint(1.0);
        assert!((hint / est - 1.0).abs() < 0.1, "hint {hint} est {est}");
    }
}
