//! A run of lit pixels converted a block at a time, for the fused pass.
//!
//! Nearly every lit pixel takes one path through the detector and the ADC: a mean charge
//! of 30 e⁻ or more (shot noise by the normal approximation), both normal variates
//! inside their ziggurat layer's rectangle, an ADC input not within rounding of a code
//! boundary. A block computes that path for all its pixels in loops without branches,
//! which the compiler vectorises (the ziggurat's table look-ups apart, in a scalar loop of
//! their own), then adds each pixel to the row's sums in column order; a pixel off the
//! path takes the caller's scalar path instead, at its place in that order. The same
//! operations on the same values in the same order: the same bits as the scalar path.

use super::adc::Adc;
use super::detector::{Detector, FixedPattern};
use super::noise::{self, POISSON_EXACT_BELOW};
use super::psf_band::Span;
use super::row_stats::RowStats;
use super::stream::PixelStream;
use super::ziggurat::{self, Ziggurat};

/// Pixels per block (each array 512 bytes: the block's working set stays in L1).
const BLOCK: usize = 64;

/// What the block path needs of a frame, resolved once per frame.
pub(super) struct LitPath<'a> {
    d: &'a Detector,
    fixed_pattern: Option<&'a FixedPattern>,
    adc: Adc,
    zig: &'static Ziggurat,
    /// The full well (infinite without one).
    full_well: f64,
    /// The report's bound, with a Monte Carlo variance.
    k: Option<f64>,
    substitute: bool,
}

/// One block's values, kept from row to row (a worker's scratch).
pub(super) struct Block {
    l: [f64; BLOCK],
    v: [f64; BLOCK],
    hs: [u64; BLOCK],
    hr: [u64; BLOCK],
    /// The layer widths `(x_i, x_{i+1})` of the shot and read draws.
    ws: [(f64, f64); BLOCK],
    wr: [(f64, f64); BLOCK],
    lam: [f64; BLOCK],
    e: [f64; BLOCK],
    r2: [f64; BLOCK],
    sr: [f64; BLOCK],
    ve: [f64; BLOCK],
    code: [u16; BLOCK],
    fast: [bool; BLOCK],
}

impl Default for Block {
    fn default() -> Self {
        Block {
            l: [0.0; BLOCK],
            v: [0.0; BLOCK],
            hs: [0; BLOCK],
            hr: [0; BLOCK],
            ws: [(0.0, 0.0); BLOCK],
            wr: [(0.0, 0.0); BLOCK],
            lam: [0.0; BLOCK],
            e: [0.0; BLOCK],
            r2: [0.0; BLOCK],
            sr: [0.0; BLOCK],
            ve: [0.0; BLOCK],
            code: [0; BLOCK],
            fast: [false; BLOCK],
        }
    }
}

/// The sums of a block's pixels on the path that do not depend on their order.
#[derive(Default)]
struct Counts {
    full: u64,
    low: u64,
    high: u64,
    dn: u64,
    lit: u64,
    above: u64,
    above_shot: u64,
}

impl<'a> LitPath<'a> {
    /// The path for detector `d` and `adc`; None when no pixel can take it (shot noise
    /// off, no read noise, or a fixed pattern computed per pixel).
    pub fn new(d: &'a Detector, adc: Adc, k: Option<f64>, substitute: bool) -> Option<LitPath<'a>> {
        let cached = d.fixed_pattern.as_ref().is_none_or(|fp| fp.runs(0, 0).is_some());
        (d.shot_noise && d.read_noise_e > 0.0 && cached).then(|| LitPath {
            d,
            fixed_pattern: d.fixed_pattern.as_ref(),
            adc,
            zig: ziggurat::tables(),
            full_well: d.full_well_e.unwrap_or(f64::INFINITY),
            k,
            substitute,
        })
    }

    /// Convert columns `cols` of a row whose column 0 is pixel `key0`, radiance `rad` and
    /// variance `var` (each zero outside its span), into `out` (the row), adding to `st`;
    /// a pixel off the path is `rare(column, radiance, variance, st)`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn run(
        &self,
        key: u64,
        key0: u64,
        cols: Span,
        rad: (&[f32], Span),
        var: Option<(&[f32], Span)>,
        b: &mut Block,
        out: &mut [u16],
        st: &mut RowStats,
        mut rare: impl FnMut(usize, f64, f64, &mut RowStats) -> u16,
    ) {
        let mut s = *st;
        let mut c0 = cols.0;
        while c0 < cols.1 {
            let n = (cols.1 - c0).min(BLOCK);
            let p0 = key0 + c0 as u64;
            fill(&mut b.l[..n], rad, c0);
            match var {
                Some(v) => fill(&mut b.v[..n], v, c0),
                None => b.v[..n].fill(0.0),
            }
            PixelStream::first_draws(key, p0, 0, &mut b.hs[..n]);
            PixelStream::first_draws(key, p0, 1, &mut b.hr[..n]);
            for j in 0..n {
                b.ws[j] = self.zig.layer(b.hs[j]);
                b.wr[j] = self.zig.layer(b.hr[j]);
            }
            let z = self.fixed_pattern.and_then(|fp| fp.runs(p0, n));
            let t = match self.k {
                Some(k) => self.block::<true>(b, n, z, k),
                None => self.block::<false>(b, n, z, 0.0),
            };
            (s.full, s.low, s.high, s.dn) = (s.full + t.full, s.low + t.low, s.high + t.high, s.dn + t.dn);
            s.mc.lit += t.lit;
            s.mc.above += t.above;
            s.mc.above_shot += t.above_shot;
            // The sums that depend on the order, in column order.
            let out = &mut out[c0..c0 + n];
            for (j, o) in out.iter_mut().enumerate() {
                if b.fast[j] {
                    s.expected += b.lam[j];
                    s.max_expected = s.max_expected.max(b.lam[j]);
                    s.collected += b.e[j];
                    if self.k.is_some() {
                        s.mc.ratio += b.sr[j];
                        s.mc.ratio2 += b.r2[j];
                        s.mc.var_e2 += b.ve[j];
                    }
                    *o = b.code[j];
                } else {
                    *o = rare(c0 + j, b.l[j], b.v[j], &mut s);
                }
            }
            c0 += n;
        }
        *st = s;
    }

    /// The path for the block's first `n` pixels (`z` their fixed pattern): each pixel's
    /// code and sums, and whether it is on the path (`b.fast`). Branch-free; the
    /// arithmetic of [`Detector::expected_parts_z`], [`noise::poisson_normal`],
    /// [`Detector::clip_and_read`], [`Adc::convert`] and the report's `McRow::add`.
    #[inline(always)]
    fn block<const MC: bool>(&self, b: &mut Block, n: usize, z: Option<(&[f32], &[f32])>, k: f64) -> Counts {
        static ZEROS: [f32; BLOCK] = [0.0; BLOCK];
        let (z1, z2) = z.unwrap_or((&ZEROS[..n], &ZEROS[..n]));
        let d = self.d;
        // Without a pattern, PRNU and DSNU are 0: a factor of 1 and the mean dark charge.
        let (prnu, dsnu) = if z.is_some() { (d.prnu, d.dsnu_e) } else { (0.0, 0.0) };
        let (e_per, dark_e, fw, sigma) = (d.e_per_radiance, d.dark_e, self.full_well, d.read_noise_e);
        let (read_e2, kk) = (d.read_noise_e * d.read_noise_e, k * k);
        let max_dn = self.adc.max_dn as f64;
        let mut c = Counts::default();
        let (l, v, ws, wr) = (&b.l[..n], &b.v[..n], &b.ws[..n], &b.wr[..n]);
        let (hs, hr, z1, z2) = (&b.hs[..n], &b.hr[..n], &z1[..n], &z2[..n]);
        let (lam_o, e_o, code_o, fast_o) = (&mut b.lam[..n], &mut b.e[..n], &mut b.code[..n], &mut b.fast[..n]);
        let (r2_o, sr_o, ve_o) = (&mut b.r2[..n], &mut b.sr[..n], &mut b.ve[..n]);
        for j in 0..n {
            let pf = (1.0 + prnu * z1[j] as f64).max(0.0);
            let photo = l[j].max(0.0) * e_per * pf;
            let dark = (dark_e + dsnu * z2[j] as f64).max(0.0);
            let lam = photo + dark;
            let xs = ziggurat::unit(hs[j]) * ws[j].0;
            let xr = ziggurat::unit(hr[j]) * wr[j].0;
            let k_e = noise::poisson_normal(lam, xs);
            let full = k_e >= fw;
            let e = if full { fw } else { k_e };
            let (dn, sure) = self.adc.round_fast(e + sigma * xr);
            let (low, high) = (dn < 0.0, dn >= max_dn);
            let code = (dn + 4_503_599_627_370_496.0).to_bits() as u16;
            let code = if low {
                0
            } else if high {
                self.adc.max_dn as u16
            } else {
                code
            };
            let g = e_per * pf;
            let ve = v[j] * g * g;
            let fast = (l[j] > 0.0)
                & (lam >= POISSON_EXACT_BELOW)
                & (xs.abs() < ws[j].1)
                & (xr.abs() < wr[j].1)
                & sure
                & !(self.substitute & (ve > 0.0));
            lam_o[j] = lam;
            e_o[j] = e;
            code_o[j] = code;
            fast_o[j] = fast;
            c.full += (fast & full) as u64;
            c.low += (fast & low) as u64;
            c.high += (fast & high) as u64;
            c.dn += if fast { code as u64 } else { 0 };
            if MC {
                // `McRow::add`: a pixel is lit from 1 e⁻ of photo-charge (`photo` is not NaN
                // on the path: λ ≥ 30); shot noise is on.
                let lit = fast & (photo >= 1.0);
                let cam = lam + read_e2;
                let r2 = if cam > 0.0 { ve / cam } else { 0.0 };
                c.lit += lit as u64;
                c.above += (lit & (ve > kk * cam)) as u64;
                c.above_shot += (lit & (ve > lam)) as u64;
                // A pixel not lit adds +0 to sums that start at +0 and never go below.
                r2_o[j] = if lit { r2 } else { 0.0 };
                sr_o[j] = if lit { r2.sqrt() } else { 0.0 };
                ve_o[j] = if lit { ve } else { 0.0 };
            }
        }
        c
    }
}

/// `dst` = columns `c0..c0 + dst.len()` of a row that is zero outside its span.
#[inline(always)]
fn fill(dst: &mut [f64], (row, (s0, s1)): (&[f32], Span), c0: usize) {
    dst.fill(0.0);
    let (lo, hi) = (c0.max(s0), (c0 + dst.len()).min(s1));
    for c in lo..hi {
        dst[c - c0] = row[c] as f64;
    }
}
