//! Standard normal variates by the ziggurat method (Marsaglia & Tsang 2000, 256 layers,
//! with the independent layer bits of Doornik 2005): exact, one 64-bit draw and no
//! transcendental function for 98.8 % of the variates.
//!
//! The density `f(x) = exp(−x²/2)` (unnormalised) on x ≥ 0 is covered by 256 layers of
//! equal area `V`: layer 0 is the strip `[0, R] × [0, f(R)]` plus the tail beyond `R`
//! (area `R f(R) + ∫_R^∞ f`), layer `i ≥ 1` the rectangle `[0, x_i] × [f(x_i), f(x_{i+1})]`.
//! A draw picks a layer and a point in it: inside the part of the rectangle under the
//! curve it is returned at once; in the wedge above the curve it is tested against `f`;
//! in layer 0 beyond `R` it is drawn from the tail (Marsaglia 1964). Every draw comes
//! from the pixel's own stream, so rejections keep the result deterministic.

use super::stream::PixelStream;
use std::sync::LazyLock;

/// Start of the tail (256 layers; Marsaglia & Tsang).
const R: f64 = 3.654_152_885_361_009;
/// Area of each layer: `R·f(R) + √(π/2)·erfc(R/√2)`, computed in double precision.
const V: f64 = 0.004_928_673_233_974_658;

/// The layer tables.
#[derive(Debug, PartialEq)]
pub struct Ziggurat {
    /// Layer widths: `x[0] = V / f(R)` (layer 0's equivalent width), `x[1] = R`, …,
    /// `x[256] = 0`.
    x: [f64; 257],
    /// `f(x[i])`, with `f[256] = 1`.
    f: [f64; 257],
}

static TABLES: LazyLock<Ziggurat> = LazyLock::new(|| {
    let f = |x: f64| (-0.5 * x * x).exp();
    let mut t = Ziggurat { x: [0.0; 257], f: [0.0; 257] };
    t.x[0] = V / f(R);
    t.x[1] = R;
    for i in 1..256 {
        // The next layer's top: f(x_{i+1}) = f(x_i) + V / x_i.
        let y = f(t.x[i]) + V / t.x[i];
        t.x[i + 1] = if i == 255 || y >= 1.0 { 0.0 } else { (-2.0 * y.ln()).sqrt() };
    }
    for i in 0..257 {
        t.f[i] = f(t.x[i]);
    }
    t.f[256] = 1.0;
    t
});

/// The tables, built on first use (a loop over many variates keeps the reference).
pub fn tables() -> &'static Ziggurat {
    &TABLES
}

/// One standard normal variate from `s`.
pub fn normal(s: &mut PixelStream) -> f64 {
    tables().normal(s)
}

impl Ziggurat {
    /// One standard normal variate from `s`: the rectangle's inner part inline, the rest
    /// (1.2 % of the draws) out of line.
    #[inline(always)]
    pub fn normal(&self, s: &mut PixelStream) -> f64 {
        let bits = s.next_u64();
        let (i, x) = self.point(bits);
        if x.abs() < self.x[i + 1] { x } else { self.edge(s, i, x) }
    }

    /// Layer `i` from the low 8 bits; x = u·x_i with u from [`unit`].
    #[inline(always)]
    fn point(&self, bits: u64) -> (usize, f64) {
        let i = (bits & 0xff) as usize;
        (i, unit(bits) * self.x[i])
    }

    /// The width of the layer `bits` picks and the next one's, `(x_i, x_{i+1})`: a draw
    /// `x = unit(bits)·x_i` with `|x| < x_{i+1}` is returned as it is by
    /// [`Ziggurat::normal`] (for a caller that does the rest of that test itself).
    #[inline(always)]
    pub fn layer(&self, bits: u64) -> (f64, f64) {
        let i = (bits & 0xff) as usize;
        (self.x[i], self.x[i + 1])
    }

    /// A point outside layer `i`'s inner rectangle: the tail (layer 0) or the wedge test,
    /// and on a rejection a fresh draw.
    #[inline(never)]
    fn edge(&self, s: &mut PixelStream, mut i: usize, mut x: f64) -> f64 {
        loop {
            if i == 0 {
                return tail(s, x < 0.0);
            }
            // The wedge between the rectangle's lower edge and the curve.
            let y = self.f[i] + (self.f[i + 1] - self.f[i]) * s.uniform_open();
            if y < (-0.5 * x * x).exp() {
                return x;
            }
            (i, x) = self.point(s.next_u64());
            if x.abs() < self.x[i + 1] {
                return x;
            }
        }
    }
}

/// u uniform on [−1, 1) from the top 52 bits of `bits`: `2·(bits >> 12)·2⁻⁵² − 1`, the
/// integer converted by placing it in a double's mantissa (exact below 2⁵², and a few
/// vector instructions, where `as f64` of a 64-bit integer is not one before AVX-512).
#[inline(always)]
pub fn unit(bits: u64) -> f64 {
    const TWO52: f64 = 4_503_599_627_370_496.0;
    let m = f64::from_bits((bits >> 12) | TWO52.to_bits()) - TWO52;
    2.0 * (m * (1.0 / TWO52)) - 1.0
}

/// A variate beyond `R` (or below −`R`), by Marsaglia's exponential rejection.
fn tail(s: &mut PixelStream, negative: bool) -> f64 {
    loop {
        let x = -s.uniform_open().ln() / R;
        let y = -s.uniform_open().ln();
        if 2.0 * y >= x * x {
            return if negative { -(R + x) } else { R + x };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layers_close_at_the_mode() {
        // The recurrence must reach f = 1 at the 256th layer: V and R agree.
        let t = tables();
        let y = t.f[255] + V / t.x[255];
        assert!((y - 1.0).abs() < 1e-12, "{y}");
        assert!(t.x.windows(2).all(|w| w[0] > w[1]));
    }

    #[test]
    fn unit_is_the_top_52_bits_converted() {
        let mut s = PixelStream::new(5, 1, 0);
        for bits in [0, u64::MAX, 1 << 63, 0xfff, 0x1000].into_iter().chain((0..10_000).map(|_| s.next_u64())) {
            let want = 2.0 * ((bits >> 12) as i64 as f64 * (1.0 / 4_503_599_627_370_496.0)) - 1.0;
            assert_eq!(unit(bits).to_bits(), want.to_bits(), "{bits:#x}");
        }
        assert_eq!((unit(0), unit(u64::MAX)), (-1.0, 1.0 - 2.0f64.powi(-51)));
    }
}
