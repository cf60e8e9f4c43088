//! A separable PSF run row by row, for the sensor's fused pass: the horizontal pass of
//! one row, then the vertical pass of one output row from the horizontal rows around it.
//!
//! Every output value is computed with the same products, summed in the same order, as
//! [`psf::convolve`] and [`psf::convolve_variance`] compute it over the whole image (the
//! weights and reflecting borders of their gathers, taken from the same lists), so the
//! results are theirs bit for bit (tested). What is skipped is only work on zeros: each
//! row carries the half-open column span outside which it is exactly zero, a pass
//! computes only inside its input's span grown by the kernel's reach, and leaving out
//! a product with a zero never changes a sum that starts at +0 (round to nearest).

use super::psf::{Gather, Kernel};

/// A half-open column span `[0, 0)` is empty.
pub type Span = (usize, usize);

/// Lists of items, one list per index, stored flat.
#[derive(Clone, Debug)]
struct Lists<T> {
    start: Vec<usize>,
    items: Vec<T>,
}

impl<T> Lists<T> {
    fn build(n: usize, mut list: impl FnMut(usize, &mut Vec<T>)) -> Lists<T> {
        let (mut start, mut items) = (vec![0], Vec::new());
        for i in 0..n {
            list(i, &mut items);
            start.push(items.len());
        }
        Lists { start, items }
    }

    #[inline]
    fn of(&self, i: usize) -> &[T] {
        &self.items[self.start[i]..self.start[i + 1]]
    }
}

/// A separable kernel's two passes planned for one image size.
#[derive(Clone, Debug)]
pub struct SeparablePsf {
    width: usize,
    height: usize,
    /// Horizontal radius; the vertical one is `ry`.
    rx: usize,
    ry: usize,
    /// Horizontal weights for offsets −rx..=rx, and their squares in f64.
    taps: Vec<f32>,
    taps2: Vec<f64>,
    /// Columns whose every tap reads an unreflected input (empty when the image is no
    /// wider than the kernel).
    lo: usize,
    hi: usize,
    /// Per column outside `lo..hi`: (input column, weight) in the gather's order, and
    /// (input column, summed weight squared) per distinct input column.
    border: Lists<(usize, f32)>,
    border2: Lists<(usize, f64)>,
    /// Per output row: (input row, weight) in the gather's order, and (input row, summed
    /// weight squared) per distinct input row.
    rows: Lists<(usize, f32)>,
    rows2: Lists<(usize, f64)>,
}

impl SeparablePsf {
    /// The passes of `(h, v)` (a horizontal kernel, `ry = 0`, and a vertical one,
    /// `rx = 0`: [`Kernel::gaussian`]'s pair) over a `width × height` image.
    pub fn new(h: &Kernel, v: &Kernel, width: usize, height: usize) -> SeparablePsf {
        assert!(h.ry == 0 && v.rx == 0, "a separable pair: horizontal, then vertical");
        let (rx, ry) = (h.rx, v.ry);
        let (lo, hi) = if width > 2 * rx { (rx, width - rx) } else { (0, 0) };
        let taps: Vec<f32> = (-(rx as i64)..=rx as i64).map(|m| h.at(m, 0)).collect();
        // As `convolve_variance` forms them: each weight summed (here a single term) in f64.
        let taps2 = (-(rx as i64)..=rx as i64)
            .map(|m| {
                let w: f64 = [h.at(m, 0) as f64].iter().sum();
                w * w
            })
            .collect();
        let gx = Gather::new(width, rx);
        let gy = Gather::new(height, ry);
        let is_border = |c: usize| c < lo || c >= hi.max(lo);
        let border = Lists::build(width, |c, out| {
            if is_border(c) {
                out.extend(gx.of(c).iter().map(|&(i, m)| (i, h.at(m, 0))));
            }
        });
        let border2 = Lists::build(width, |c, out| {
            if is_border(c) {
                for cols in gx.of(c).chunk_by(|a, b| a.0 == b.0) {
                    let w: f64 = cols.iter().map(|&(_, m)| [h.at(m, 0) as f64].iter().sum::<f64>()).sum();
                    out.push((cols[0].0, w * w));
                }
            }
        });
        let rows = Lists::build(height, |r, out| out.extend(gy.of(r).iter().map(|&(i, m)| (i, v.at(0, m)))));
        let rows2 = Lists::build(height, |r, out| {
            for rs in gy.of(r).chunk_by(|a, b| a.0 == b.0) {
                let w: f64 = rs.iter().map(|&(_, m)| v.at(0, m) as f64).sum();
                out.push((rs[0].0, w * w));
            }
        });
        SeparablePsf { width, height, rx, ry, taps, taps2, lo, hi, border, border2, rows, rows2 }
    }

    /// True for a column some tap of which reads a reflected input.
    #[inline]
    fn is_border(&self, c: usize) -> bool {
        c < self.lo || c >= self.hi.max(self.lo)
    }

    /// The input rows the vertical pass reads for output rows `r0..r1`.
    pub fn input_rows(&self, r0: usize, r1: usize) -> (usize, usize) {
        (r0.saturating_sub(self.ry), (r1 + self.ry).min(self.height))
    }

    /// The columns a horizontal pass reads for an input nonzero on `span`: those it
    /// writes ([`SeparablePsf::out_span`]) and their taps' reach.
    pub fn read_span(&self, span: Span) -> Span {
        self.out_span(self.out_span(span))
    }

    /// The columns a horizontal pass may make nonzero from an input nonzero on `span`.
    pub fn out_span(&self, (a, b): Span) -> Span {
        if a >= b { (0, 0) } else { (a.saturating_sub(self.rx), (b + self.rx).min(self.width)) }
    }

    /// The horizontal pass of one row: `out` on [`SeparablePsf::out_span`]`(span)`, from
    /// `src`, which must hold the input on `read_span(span)` (zero outside `span`).
    pub fn horizontal(&self, src: &[f32], span: Span, out: &mut [f32]) -> Span {
        let (a, b) = self.out_span(span);
        let (i0, i1) = (a.max(self.lo), b.min(self.hi));
        if i0 < i1 {
            let o = &mut out[i0..i1];
            o.fill(0.0);
            for (k, w) in self.taps.iter().enumerate() {
                // out[c] += w · src[c − m], m = k − rx.
                let s0 = i0 + self.rx - k;
                for (o, s) in o.iter_mut().zip(&src[s0..s0 + (i1 - i0)]) {
                    *o += w * s;
                }
            }
        }
        for c in (a..b).filter(|&c| self.is_border(c)) {
            let mut acc = 0.0f32;
            for &(i, w) in self.border.of(c) {
                acc += w * src[i];
            }
            out[c] = 0.0 + acc;
        }
        (a, b)
    }

    /// [`SeparablePsf::horizontal`] of a variance row (squared weights, f64 sums);
    /// `acc` is scratch of the row's width.
    pub fn horizontal_var(&self, src: &[f32], span: Span, acc: &mut [f64], out: &mut [f32]) -> Span {
        let (a, b) = self.out_span(span);
        acc[a..b].fill(0.0);
        let (i0, i1) = (a.max(self.lo), b.min(self.hi));
        if i0 < i1 {
            for (k, w2) in self.taps2.iter().enumerate() {
                let s0 = i0 + self.rx - k;
                for (o, s) in acc[i0..i1].iter_mut().zip(&src[s0..s0 + (i1 - i0)]) {
                    *o += w2 * *s as f64;
                }
            }
        }
        for c in (a..b).filter(|&c| self.is_border(c)) {
            for &(i, w2) in self.border2.of(c) {
                acc[c] += w2 * src[i] as f64;
            }
        }
        for (o, v) in out[a..b].iter_mut().zip(&acc[a..b]) {
            *o = *v as f32;
        }
        (a, b)
    }

    /// The vertical pass of output row `oy`: `input(iy)` gives horizontal row `iy` and
    /// its span. Writes `out` on the returned span (the union of its inputs' spans).
    pub fn vertical<'a>(&self, oy: usize, input: impl Fn(usize) -> (&'a [f32], Span), out: &mut [f32]) -> Span {
        let span = self.rows.of(oy).iter().fold((usize::MAX, 0), |s, &(iy, _)| union(s, input(iy).1));
        let span = if span.0 >= span.1 { (0, 0) } else { span };
        out[span.0..span.1].fill(0.0);
        for &(iy, w) in self.rows.of(oy) {
            let (row, (a, b)) = input(iy);
            for (o, s) in out[a..b].iter_mut().zip(&row[a..b]) {
                *o += w * s;
            }
        }
        span
    }

    /// [`SeparablePsf::vertical`] of variance rows; `acc` is scratch of the row's width.
    pub fn vertical_var<'a>(
        &self,
        oy: usize,
        input: impl Fn(usize) -> (&'a [f32], Span),
        acc: &mut [f64],
        out: &mut [f32],
    ) -> Span {
        let span = self.rows2.of(oy).iter().fold((usize::MAX, 0), |s, &(iy, _)| union(s, input(iy).1));
        let span = if span.0 >= span.1 { (0, 0) } else { span };
        acc[span.0..span.1].fill(0.0);
        for &(iy, w2) in self.rows2.of(oy) {
            let (row, (a, b)) = input(iy);
            for (o, s) in acc[a..b].iter_mut().zip(&row[a..b]) {
                *o += w2 * *s as f64;
            }
        }
        for (o, v) in out[span.0..span.1].iter_mut().zip(&acc[span.0..span.1]) {
            *o = *v as f32;
        }
        span
    }
}

/// The smallest span holding both (an empty span adds nothing).
#[inline]
pub fn union(s: Span, t: Span) -> Span {
    if t.0 >= t.1 {
        s
    } else if s.0 >= s.1 {
        t
    } else {
        (s.0.min(t.0), s.1.max(t.1))
    }
}

/// The span of `row` outside which it is zero (±0). Scans 16 values at a time (their
/// bits OR-ed, sign masked: a loop the compiler vectorises), then the edge chunks singly.
pub fn nonzero_span(row: &[f32]) -> Span {
    const C: usize = 16;
    let any = |c: &[f32]| c.iter().fold(0u32, |a, v| a | (v.to_bits() & 0x7fff_ffff)) != 0;
    let nonzero = |v: &f32| *v != 0.0;
    let chunks = row.len() / C;
    let Some(first) = (0..chunks).find(|&k| any(&row[k * C..(k + 1) * C])) else {
        // No nonzero chunk: only the tail may hold one.
        let tail = &row[chunks * C..];
        return match tail.iter().position(nonzero) {
            None => (0, 0),
            Some(a) => (chunks * C + a, chunks * C + tail.iter().rposition(nonzero).expect("one is") + 1),
        };
    };
    let a = first * C + row[first * C..].iter().position(nonzero).expect("a nonzero chunk");
    let last = (first..chunks).rev().find(|&k| any(&row[k * C..(k + 1) * C])).expect("the first one");
    let tail_end = row[chunks * C..].iter().rposition(nonzero).map(|b| chunks * C + b + 1);
    let b = tail_end
        .unwrap_or_else(|| last * C + row[last * C..(last + 1) * C].iter().rposition(nonzero).expect("nonzero") + 1);
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::super::psf::{convolve, convolve_variance};
    use super::*;

    /// Both passes over a whole image, row by row, as the fused pass runs them.
    fn by_rows(p: &SeparablePsf, img: &[f32], var: bool) -> Vec<f32> {
        let (w, h) = (p.width, p.height);
        let mut hor = vec![f32::NAN; w * h];
        let mut spans = vec![(0, 0); h];
        let mut acc = vec![0.0f64; w];
        for r in 0..h {
            let src = &img[r * w..(r + 1) * w];
            let span = nonzero_span(src);
            let out = &mut hor[r * w..(r + 1) * w];
            spans[r] = if var { p.horizontal_var(src, span, &mut acc, out) } else { p.horizontal(src, span, out) };
        }
        let mut out = vec![0.0f32; w * h];
        for r in 0..h {
            let input = |iy: usize| (&hor[iy * w..(iy + 1) * w], spans[iy]);
            let mut row = vec![f32::NAN; w];
            let (a, b) =
                if var { p.vertical_var(r, input, &mut acc, &mut row) } else { p.vertical(r, input, &mut row) };
            out[r * w + a..r * w + b].copy_from_slice(&row[a..b]);
        }
        out
    }

    #[test]
    fn spans_are_the_first_and_last_nonzero_values() {
        for n in [0, 1, 15, 16, 17, 40, 64] {
            for a in 0..n {
                for b in a..n {
                    let mut row = vec![0.0f32; n];
                    row[a] = 1.0;
                    row[b] = f32::NAN;
                    if a + 1 < b {
                        row[a + 1] = -0.0;
                    }
                    assert_eq!(nonzero_span(&row), (a, b + 1), "{n}: {a}..={b}");
                }
            }
            assert_eq!(nonzero_span(&vec![-0.0; n]), (0, 0));
        }
    }

    #[test]
    fn rows_with_spans_give_the_whole_image_passes_bit_for_bit() {
        for (sigma, w, h) in [(0.7, 37, 23), (1.3, 9, 40), (2.0, 5, 3), (0.7, 1, 12)] {
            let (kh, kv) = Kernel::gaussian(sigma);
            let p = SeparablePsf::new(&kh, &kv, w, h);
            // Signal on a few blobs (some at the borders), zeros elsewhere, a −0 among them.
            let mut img = vec![0.0f32; w * h];
            for (i, v) in img.iter_mut().enumerate() {
                let (c, r) = (i % w, i / w);
                if (r % 7 < 2 && c % 5 != 3) || c == w - 1 {
                    *v = (i as f32 * 0.37).sin().abs() * 100.0 + 1e-3;
                }
            }
            img[w / 2] = -0.0;
            let want = convolve(&convolve(&img, w, h, &kh), w, h, &kv);
            let got = by_rows(&p, &img, false);
            assert!(want.iter().zip(&got).all(|(a, b)| a.to_bits() == b.to_bits()), "σ {sigma}, {w}×{h}");
            let want = convolve_variance(&convolve_variance(&img, w, h, &kh), w, h, &kv);
            let got = by_rows(&p, &img, true);
            assert!(want.iter().zip(&got).all(|(a, b)| a.to_bits() == b.to_bits()), "var σ {sigma}, {w}×{h}");
        }
    }
}
