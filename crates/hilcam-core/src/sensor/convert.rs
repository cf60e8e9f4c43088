//! The fused DN pass: optics, PSF, detector, ADC and the frame's report in one sweep over
//! bands of rows, each band's working rows in cache.
//!
//! A band of output rows first runs the scale (τ cos⁴) and the horizontal PSF pass over
//! the input rows its vertical pass reads (the band plus the kernel's reach above and
//! below), then, row by row, the vertical pass and the conversion of every pixel. Rows
//! carry the span outside which they are zero, so the optics run only where there is
//! light; a pixel without light or Monte Carlo variance takes the dark path (no photo
//! charge, no PRNU, no report), with the same draws and result as the general one.
//!
//! Bands run in parallel; each pixel's noise is its own streams' and each row's sums are
//! kept apart and reduced in row order, so the bytes do not depend on the thread count.

use super::adc::{Adc, Conversion};
use super::dark_run;
use super::dark_sums::DarkSums;
use super::detector::{Detector, FixedPattern, PixelCharge};
use super::empty_well::EmptyWell;
use super::lit_run::{Block, LitPath};
use super::noise;
use super::optics_plan::PsfPlan;
use super::psf_band::{Span, nonzero_span, union};
use super::row_stats::RowStats;
use super::stream::{PixelNoise, PixelStream, frame_key};
use super::{Sensor, SensorError};
use crate::render::camera::PixelKeys;
use crate::render::film::RadianceImage;
use rayon::prelude::*;

/// Output rows per band: 32 keeps a band's working rows (40 rows of radiance and of
/// variance at 1024 columns, 330 KB) in L2 and gives two threads 32 bands to share.
const BAND_ROWS: usize = 32;

/// What converting one pixel needs, resolved once per frame.
struct Frame<'a> {
    det: Option<&'a Detector>,
    fixed_pattern: Option<&'a FixedPattern>,
    adc: Adc,
    /// Electrons per unit radiance without a detector (`radiance_scale`).
    scale: f64,
    key: u64,
    keys: PixelKeys,
    /// The report's bound, when the frame has a Monte Carlo variance (and a detector).
    k: Option<f64>,
    substitute: bool,
    /// How a pixel without charge reads (with a detector whose shot noise is on).
    well: Option<&'a EmptyWell>,
    /// The lit pixels' block path, where the detector allows it.
    lit: Option<LitPath<'a>>,
    /// The dark charge's sums per chunk of the array (with a cached fixed pattern).
    dark_sums: Option<&'a DarkSums>,
}

/// What every band of a frame reads.
#[derive(Clone, Copy)]
struct Band<'a> {
    f: &'a Frame<'a>,
    /// The optics over the whole image (radiance, variance), when they ran first.
    whole: Option<&'a (Vec<f32>, Option<Vec<f32>>)>,
    img: &'a RadianceImage,
    variance: Option<&'a [f32]>,
}

thread_local! {
    /// Each worker's rows, kept from band to band and frame to frame (not grown and
    /// zeroed again for every piece of work rayon splits off).
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::default();
}

/// True when the CPU has AVX2 (checked once; cached by the standard library).
fn avx2() -> bool {
    #[cfg(test)]
    if tests::BASELINE.with(|b| b.get()) {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One worker's rows, reused from band to band.
#[derive(Default)]
struct Scratch {
    /// Horizontally filtered input rows of the band (radiance, variance) and their spans.
    hrad: Vec<f32>,
    hvar: Vec<f32>,
    rspan: Vec<Span>,
    vspan: Vec<Span>,
    /// One scaled input row, one f64 accumulator row, one output row of each.
    scaled: Vec<f32>,
    acc: Vec<f64>,
    rad: Vec<f32>,
    var: Vec<f32>,
    /// The lit pixels' block.
    block: Box<Block>,
}

impl Sensor {
    /// Convert a frame to DN with the fused pass: the pixels and each row's sums.
    pub(super) fn convert_dn(
        &self,
        img: &RadianceImage,
        variance: Option<&[f32]>,
        det: Option<&Detector>,
        adc: Adc,
        frame_seed: u64,
        k: f64,
    ) -> Result<(Vec<u16>, Vec<RowStats>), SensorError> {
        let (w, h) = (img.width as usize, img.height as usize);
        // The Monte Carlo variance is carried only with a detector (the comparison and the
        // substitution are in electrons).
        let variance = variance.filter(|_| det.is_some());
        // A 2D kernel runs over the whole image first; the rows then only convert.
        let whole = match self.psf_plan {
            PsfPlan::Whole => Some((self.optics(img)?.data, variance.map(|v| self.optics_variance(v)).transpose()?)),
            _ => None,
        };
        let f = Frame {
            det,
            fixed_pattern: det.and_then(|d| d.fixed_pattern.as_ref()),
            adc,
            scale: self.radiance_scale,
            key: frame_key(frame_seed),
            keys: self.keys(),
            k: variance.map(|_| k),
            substitute: self.cfg.detector.as_ref().is_some_and(|d| d.noise == super::NoiseMode::Substitute),
            well: self.empty_well.as_deref().filter(|_| det.is_some_and(|d| d.shot_noise)),
            lit: None,
            dark_sums: self.dark_sums.as_deref(),
        };
        let f = Frame { lit: det.and_then(|d| LitPath::new(d, adc, f.k, f.substitute)), ..f };
        let mut dn = vec![0u16; w * h];
        let mut rows = vec![RowStats::default(); h];
        let band = Band { f: &f, whole: whole.as_ref(), img, variance };
        let avx2 = avx2();
        dn.par_chunks_mut(BAND_ROWS * w).zip(rows.par_chunks_mut(BAND_ROWS)).enumerate().for_each(
            |(b, (out, stats))| {
                SCRATCH.with_borrow_mut(|s| {
                    #[cfg(target_arch = "x86_64")]
                    if avx2 {
                        // SAFETY: `avx2()` found the CPU to have AVX2.
                        return unsafe { self.band_avx2(&band, b * BAND_ROWS, s, out, stats) };
                    }
                    self.band(&band, b * BAND_ROWS, s, out, stats)
                })
            },
        );
        Ok((dn, rows))
    }

    /// [`Sensor::band`] compiled for AVX2 (the noise hashes four pixels at a time); the
    /// same arithmetic, so the same bits (Rust never fuses a multiply and an add).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn band_avx2(&self, band: &Band, r0: usize, s: &mut Scratch, out: &mut [u16], stats: &mut [RowStats]) {
        self.band(band, r0, s, out, stats)
    }

    /// Convert the band of rows from `r0` (as many as `stats` has) into `out`.
    #[inline(always)]
    fn band(&self, band: &Band, r0: usize, s: &mut Scratch, out: &mut [u16], stats: &mut [RowStats]) {
        let Band { f, whole, img, variance } = *band;
        let w = img.width as usize;
        let r1 = r0 + stats.len();
        s.ensure(w);
        match (whole, &self.psf_plan) {
            (Some((rad, var)), _) => {
                for r in r0..r1 {
                    let rad = &rad[r * w..(r + 1) * w];
                    let var = var.as_ref().map(|v| &v[r * w..(r + 1) * w]);
                    let vrow = var.map(|v| (v, nonzero_span(v)));
                    let (o, st) = (&mut out[(r - r0) * w..], &mut stats[r - r0]);
                    f.row(r, (rad, nonzero_span(rad)), vrow, &mut s.block, o, st);
                }
            }
            (None, PsfPlan::Separable(psf)) => self.band_separable(f, psf, img, variance, r0, r1, s, out, stats),
            (None, _) => {
                for r in r0..r1 {
                    let rad = self.optics_row(&img.data[r * w..(r + 1) * w], r, false, &mut s.rad);
                    let var = variance.map(|v| self.optics_row(&v[r * w..(r + 1) * w], r, true, &mut s.var));
                    f.row(r, rad, var, &mut s.block, &mut out[(r - r0) * w..], &mut stats[r - r0]);
                }
            }
        }
    }

    /// Input row `r` after the scale (τ cos⁴; `squared` for a variance), in `dst` or, with
    /// nothing to scale, `src` itself; with its span.
    fn optics_row<'a>(&self, src: &'a [f32], r: usize, squared: bool, dst: &'a mut [f32]) -> (&'a [f32], Span) {
        let span = nonzero_span(src);
        match &self.scale {
            Some(sc) => {
                sc.row(r, src, span, squared, dst);
                (dst, span)
            }
            None => (src, span),
        }
    }

    /// Output rows `r0..r1` through a separable PSF.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn band_separable(
        &self,
        f: &Frame,
        psf: &super::psf_band::SeparablePsf,
        img: &RadianceImage,
        variance: Option<&[f32]>,
        r0: usize,
        r1: usize,
        s: &mut Scratch,
        out: &mut [u16],
        stats: &mut [RowStats],
    ) {
        let w = img.width as usize;
        let (i0, i1) = psf.input_rows(r0, r1);
        s.hrad.resize((i1 - i0) * w, 0.0);
        s.rspan.clear();
        s.vspan.clear();
        if variance.is_some() {
            s.hvar.resize((i1 - i0) * w, 0.0);
        }
        for iy in i0..i1 {
            let hrow = &mut s.hrad[(iy - i0) * w..(iy - i0 + 1) * w];
            s.rspan.push(self.horizontal(
                psf,
                &img.data[iy * w..(iy + 1) * w],
                iy,
                false,
                &mut s.scaled,
                &mut s.acc,
                hrow,
            ));
            if let Some(v) = variance {
                let hrow = &mut s.hvar[(iy - i0) * w..(iy - i0 + 1) * w];
                s.vspan.push(self.horizontal(psf, &v[iy * w..(iy + 1) * w], iy, true, &mut s.scaled, &mut s.acc, hrow));
            }
        }
        for r in r0..r1 {
            let (hrad, rspan) = (&s.hrad, &s.rspan);
            let rs = psf.vertical(r, |iy| (&hrad[(iy - i0) * w..(iy - i0 + 1) * w], rspan[iy - i0]), &mut s.rad);
            let vs = variance.map(|_| {
                let (hvar, vspan) = (&s.hvar, &s.vspan);
                let input = |iy: usize| (&hvar[(iy - i0) * w..(iy - i0 + 1) * w], vspan[iy - i0]);
                psf.vertical_var(r, input, &mut s.acc, &mut s.var)
            });
            let (o, st) = (&mut out[(r - r0) * w..], &mut stats[r - r0]);
            f.row(r, (&s.rad, rs), vs.map(|vs| (&s.var[..], vs)), &mut s.block, o, st);
        }
    }

    /// Scale input row `iy` (`squared` for a variance) and run the horizontal pass into
    /// `out`; returns the output's span.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn horizontal(
        &self,
        psf: &super::psf_band::SeparablePsf,
        src: &[f32],
        iy: usize,
        squared: bool,
        scaled: &mut [f32],
        acc: &mut [f64],
        out: &mut [f32],
    ) -> Span {
        let span = nonzero_span(src);
        if span.0 >= span.1 {
            return span;
        }
        let input = match &self.scale {
            Some(sc) => {
                sc.row(iy, src, psf.read_span(span), squared, scaled);
                &scaled[..]
            }
            None => src,
        };
        if squared { psf.horizontal_var(input, span, acc, out) } else { psf.horizontal(input, span, out) }
    }
}

impl Scratch {
    fn ensure(&mut self, w: usize) {
        for v in [&mut self.scaled, &mut self.rad, &mut self.var] {
            v.resize(w, 0.0);
        }
        self.acc.resize(w, 0.0);
    }
}

impl Frame<'_> {
    /// Convert row `r`: radiance `rad` (zero outside its span), Monte Carlo variance `var`
    /// (likewise; None without a report), into `out`.
    #[inline(always)]
    fn row(
        &self,
        r: usize,
        rad: (&[f32], Span),
        var: Option<(&[f32], Span)>,
        block: &mut Block,
        out: &mut [u16],
        st: &mut RowStats,
    ) {
        let w = rad.0.len();
        let lit = union(rad.1, var.map_or((0, 0), |v| v.1));
        let (a, b) = if lit.0 >= lit.1 { (w, w) } else { lit };
        let key0 = self.keys.key(r as u32, 0);
        self.dark(key0, &mut out[..a], st);
        self.dark(key0 + b as u64, &mut out[b..w], st);
        if let Some(path) = &self.lit {
            let rare = |c: usize, l, v, st: &mut RowStats| self.pixel(l, v, key0 + c as u64, st);
            return path.run(self.key, key0, (a, b), rad, var, block, out, st, rare);
        }
        let at = |(v, (s0, s1)): (&[f32], Span), c: usize| if c >= s0 && c < s1 { v[c] as f64 } else { 0.0 };
        for (c, o) in out.iter_mut().enumerate().take(b).skip(a) {
            let v = var.map_or(0.0, |v| at(v, c));
            *o = self.pixel(at(rad, c), v, key0 + c as u64, st);
        }
    }

    /// Pixels with neither light nor Monte Carlo variance, the first one's key `first`:
    /// [`Frame::pixel`]'s dark path with the fixed pattern's row at hand.
    #[inline(always)]
    fn dark(&self, first: u64, out: &mut [u16], st: &mut RowStats) {
        let Some(d) = self.det else {
            for (i, o) in out.iter_mut().enumerate() {
                *o = self.pixel(0.0, 0.0, first + i as u64, st);
            }
            return;
        };
        let z = self.fixed_pattern.map(|fp| (fp, fp.dsnu_run(first, out.len())));
        match (self.well, z, d.dark_max()) {
            (Some(well), None, Some(max)) => self.dark_table_run(d, well, first, out, |_| d.dark_e, None, max, st),
            (Some(well), Some((_, Some(z))), Some(max)) => {
                self.dark_table_run(d, well, first, out, |i| d.dark_z(z[i]), Some(z), max, st)
            }
            _ => {
                let dark = |i: usize| match z {
                    None => d.dark_e,
                    Some((fp, _)) => d.dark_z(fp.z_dsnu(first + i as u64)),
                };
                for (i, o) in out.iter_mut().enumerate() {
                    *o = self.dark_pixel(d, dark(i), first + i as u64, st);
                }
            }
        }
    }

    /// A run of dark pixels read from the empty-well table: [`Frame::dark_pixel`] for each
    /// (the same draws and codes), with what most of them share taken out of the loop.
    /// Every mean dark charge is at most `dark_max`, so a first draw at or below
    /// `1 − dark_max` is an empty well without computing the pixel's own mean
    /// ([`dark_run::run`]); the run's expected charge is summed apart: from the DSNU
    /// values `z` through the chunks' sums where the sensor has them, else in four lanes
    /// (column mod 4).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn dark_table_run(
        &self,
        d: &Detector,
        well: &EmptyWell,
        first: u64,
        out: &mut [u16],
        dark: impl Fn(usize) -> f64,
        z: Option<&[f32]>,
        dark_max: f64,
        st: &mut RowStats,
    ) {
        let empty = if dark_max < noise::POISSON_EXACT_BELOW { 1.0 - dark_max } else { -1.0 };
        let mut s = *st;
        let tally = dark_run::run(self.key, first, out, well, dark_run::empty_threshold(empty), |i, o| {
            // Rare (a probability of about `dark_max`): the pixel's own path, its sums
            // but the expected charge (counted below with the others').
            let e = s.expected;
            *o = self.dark_pixel(d, dark(i), first + i as u64, &mut s);
            s.expected = e;
        });
        s.dn += tally.dn;
        s.low += tally.low;
        s.high += tally.high;
        if let (Some(z), Some(sums)) = (z, self.dark_sums) {
            let (sum, max) = sums.sum(first, z, |z| d.dark_z(z), d.dark_e, d.dsnu_e);
            s.expected += sum;
            s.max_expected = s.max_expected.max(max);
            *st = s;
            return;
        }
        let (mut lanes, mut max) = ([0.0f64; 4], [s.max_expected; 4]);
        let n4 = out.len() / 4 * 4;
        for c in (0..n4).step_by(4) {
            for l in 0..4 {
                let e = dark(c + l);
                lanes[l] += e;
                max[l] = max[l].max(e);
            }
        }
        for i in n4..out.len() {
            let e = dark(i);
            lanes[i % 4] += e;
            max[i % 4] = max[i % 4].max(e);
        }
        s.expected += (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
        s.max_expected = max.iter().fold(s.max_expected, |m, v| m.max(*v));
        *st = s;
    }

    /// A pixel without photo charge, whose mean dark charge is `dark`: its count is drawn
    /// from the first draw of its shot stream (low 32 bits; a normal variate after it at
    /// a mean of 30 or more), and an empty well reads from the [`EmptyWell`] table with
    /// the high 32 bits. Without the table (shot noise off), [`Detector::sample`].
    #[inline(always)]
    fn dark_pixel(&self, d: &Detector, dark: f64, p: u64, st: &mut RowStats) -> u16 {
        let Some(well) = self.well else {
            return self.count(d.sample(dark, &mut PixelNoise::new(self.key, p)), st);
        };
        let mut shot = PixelStream::new(self.key, p, 0);
        let h = shot.next_u64();
        let k = if dark <= 0.0 {
            0.0
        } else if dark < noise::POISSON_EXACT_BELOW {
            noise::poisson_inversion(dark, (h as u32 as f64 + 0.5) * (1.0 / 4_294_967_296.0))
        } else {
            noise::poisson_normal(dark, super::ziggurat::tables().normal(&mut shot))
        };
        if k == 0.0 {
            let c = PixelCharge { expected_e: dark, collected_e: 0.0, full: false, read_e: 0.0 };
            return self.count_code(well.draw((h >> 32) as u32), c, st);
        }
        // A dark electron or more (a probability of about the mean): read like any charge.
        self.count(d.clip_and_read(dark, k, &mut PixelNoise::new(self.key, p)), st)
    }

    /// Convert one pixel of radiance `l` and Monte Carlo variance `v` (both after the
    /// optics), counting it in `st`.
    #[inline(always)]
    fn pixel(&self, l: f64, v: f64, p: u64, st: &mut RowStats) -> u16 {
        let Some(d) = self.det else {
            let e = l * self.scale;
            return self.count(PixelCharge { expected_e: e, collected_e: e, full: false, read_e: e }, st);
        };
        // The dark path: no photo charge, so neither PRNU nor the report (a pixel is lit
        // from 1 e⁻); nothing to substitute without Monte Carlo variance.
        if l <= 0.0 && (v <= 0.0 || !self.substitute) {
            let dark = match self.fixed_pattern {
                Some(fp) => d.dark_z(fp.z_dsnu(p)),
                None => d.dark_e,
            };
            return self.dark_pixel(d, dark, p, st);
        }
        let c = self.charge(d, l, v, p, st);
        self.count(c, st)
    }

    /// The DN of charge `c`, counted in `st`.
    #[inline(always)]
    fn count(&self, c: PixelCharge, st: &mut RowStats) -> u16 {
        self.count_code(self.adc.convert(c.read_e), c, st)
    }

    /// Code `conv` of charge `c` (whose `read_e` is not looked at), counted in `st`.
    #[inline(always)]
    fn count_code(&self, conv: Conversion, c: PixelCharge, st: &mut RowStats) -> u16 {
        match conv {
            Conversion::InRange(_) => {}
            Conversion::ClippedLow => st.low += 1,
            Conversion::ClippedHigh(_) => st.high += 1,
        }
        let dn = conv.dn();
        st.expected += c.expected_e;
        st.max_expected = st.max_expected.max(c.expected_e);
        st.collected += c.collected_e;
        st.full += c.full as u64;
        st.dn += u64::from(dn);
        dn as u16
    }

    /// The charge of a pixel with light (or Monte Carlo variance to substitute for).
    #[inline(always)]
    fn charge(&self, d: &Detector, l: f64, v: f64, p: u64, st: &mut RowStats) -> PixelCharge {
        let mut noise = PixelNoise::new(self.key, p);
        let z = self.fixed_pattern.map_or([0.0; 2], |fp| fp.z(p));
        let (photo, dark) = d.expected_parts_z(l, z);
        match self.k {
            None => d.sample(photo + dark, &mut noise),
            Some(k) => {
                let g = d.photo_gain_z(z[0]);
                let v_e = v * g * g;
                st.mc.add(k, d.shot_noise, photo, dark, v_e, d.read_noise_e * d.read_noise_e);
                if self.substitute && v_e > 0.0 {
                    d.sample_substituted(photo + dark, v_e, &mut noise)
                } else {
                    d.sample(photo + dark, &mut noise)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::render::film::{Pixels, RadianceImage};
    use crate::sensor::{CameraPreset, Sensor};
    use std::cell::Cell;

    thread_local! {
        /// Set: this thread's frames take the baseline code whatever the CPU has.
        pub(super) static BASELINE: Cell<bool> = const { Cell::new(false) };
    }

    #[test]
    fn the_baseline_and_the_avx2_code_give_the_same_bytes() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/cameras/nav1024.toml");
        let mut p = CameraPreset::load(std::path::Path::new(path)).unwrap();
        (p.camera.width, p.camera.height) = (200, 90);
        let sensor = Sensor::new(&p.camera, &p.sensor).unwrap();
        // A lit disc on black, a variance that follows it.
        let mut img = RadianceImage::new(200, 90, 0.0);
        for (i, v) in img.data.iter_mut().enumerate() {
            let (c, r) = ((i % 200) as f64 - 100.0, (i / 200) as f64 - 45.0);
            if c * c + r * r < 900.0 && i % 29 != 0 {
                *v = (0.05 + 0.8 * (i as f64 * 0.37).sin().abs()) as f32;
            }
        }
        let var: Vec<f32> = img.data.iter().map(|l| l * l * 0.02).collect();
        // One thread, so that the flag (per thread) covers every band.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let run = |baseline: bool| {
            pool.install(|| {
                BASELINE.with(|b| b.set(baseline));
                sensor.apply_with_variance(&img, Some(&var), 3, 5e-3, 0.5).unwrap()
            })
        };
        let (fast, base) = (run(false), run(true));
        assert!(matches!(&base.pixels, Pixels::Mono16 { data, .. } if data.iter().any(|&d| d > 40 && d < 1023)));
        assert_eq!(fast, base);
    }
}
