//! A traced frame's bands: rayon over bands of rows, each band pass by pass through the
//! tiles of `integrator::waves` — every pixel's first stage (its samples, or an adaptive
//! frame's pilot), the pilot's statistics, the second stage where the noise is, each
//! pixel's mean into the image and, when asked, its Monte Carlo variance.

use super::adaptive::{self, Adaptive};
use super::buffers::{Band, WorkerScratch, Workers};
use super::camera::PixelRect;
use super::film::RadianceImage;
use super::integrator::waves::{CameraSample, TILE_PATHS, TileJob};
use super::integrator::{RayCounts, RayLog};
use super::sampling::{PerSample, mix64};
use super::sensor_plan::SensorPlan;
use rayon::prelude::*;

/// Rows per band: a band is one rayon task; its pixels are cut into tiles of a few
/// columns × all its rows, so a tile is compact on the image.
pub(super) const BAND_ROWS: usize = 8;

/// Camera samples traced in one call in the adaptive stage (bounds its buffers).
const PASS_SAMPLES: usize = 16 * 1024;

/// The parts of [`FrameBuffers`] the bands write.
pub(super) struct FrameParts<'a, L> {
    pub img: &'a mut RadianceImage,
    pub bands: &'a mut [Band<L>],
    pub stat: &'a mut Vec<[f32; 2]>,
    /// Each pixel's Monte Carlo variance, when asked for (frame-sized, zeroed).
    pub variance: Option<&'a mut [f32]>,
}

/// How a frame's samples are shared out.
#[derive(Clone, Copy)]
pub(super) struct Plan<'a> {
    /// Samples in every pixel without a second stage.
    pub spp: u32,
    /// The two-stage plan (also the pilot of a sensor-quality frame).
    pub adaptive: Option<Adaptive>,
    /// The second stage follows the camera's noise, not the pilot's weights.
    pub sensor: Option<&'a SensorPlan>,
}

/// Render the rectangle's rows band by band (rayon over bands), each band pass by pass:
/// `spp` samples in every pixel, or (`adaptive`) a pilot in every pixel and the rest of
/// the budget where the pilot saw variance (or, `uniform`, evenly; or, `sensor`, where the
/// camera's noise asks for it). Then, when asked, each pixel's Monte Carlo variance.
pub(super) fn render_bands<S: PerSample + Send, L: RayLog + Default + Send + Sync>(
    job: &TileJob,
    parts: FrameParts<L>,
    workers: &mut Workers<S>,
    rect: PixelRect,
    span: &(dyn Fn(u32) -> (u32, u32) + Sync),
    plan: Plan,
) {
    let FrameParts { img, bands, stat, variance } = parts;
    let w = job.width;
    let (row0, row1) = (rect.row0 as usize, rect.row1 as usize);
    let first_stage = plan.adaptive.map_or(plan.spp, |a| a.pilot);
    let weighted = plan.adaptive.is_some_and(|a| !a.uniform);
    // Sums of squares: the pilot's for the second stage's weights, every sample's for the
    // variance.
    let squares = weighted || variance.is_some();
    workers.ensure();
    let shared = &*workers;
    bands.par_iter_mut().enumerate().for_each(|(b, band)| {
        shared.with(|WorkerScratch { tile, pass, .. }| {
            let first_row = row0 + b * BAND_ROWS;
            let rows = first_row as u32..(first_row + BAND_ROWS).min(row1) as u32;
            band.first_row = first_row;
            band_pixels(job, rows, span, &mut band.pixels);
            let n = band.pixels.len();
            band.sums.clear();
            band.sums.resize(n, 0.0);
            band.sum_sq.clear();
            if squares {
                band.sum_sq.resize(n, 0.0);
            }
            band.counts.clear();
            band.counts.resize(n, first_stage);
            band.rays = RayCounts::default();
            band.log = L::default();
            for s in 0..first_stage {
                pass.clear();
                pass.extend(band.pixels.iter().map(|&(row, col)| CameraSample { row, col, index: s }));
                let values = job.trace_pass(pass, tile, &mut band.rays, &mut band.log);
                for (i, &v) in values.iter().enumerate() {
                    band.add_sample(i, v, squares);
                }
            }
        })
    });
    // The pilot statistics: what the second stage's weights read, and the variance of a
    // pixel left with one sample.
    let statistics = (weighted || (variance.is_some() && first_stage == 1)).then(|| {
        // With a planet the pixels left unsampled are not one constant: their statistic is
        // their value in the image (which holds no traced pixel yet).
        let backdrop = job.ctx.planet.is_some().then_some(&img.data[..]);
        pilot_statistics(job, bands, (stat, backdrop), first_stage, img.height as usize)
    });
    if let Some(adaptive) = plan.adaptive {
        let pilot = statistics.map(|(base, rows)| PilotView { stat: &stat[..], base, rows });
        add_second_stage::<S, L>(job, bands, shared, pilot, adaptive, plan.sensor, variance.is_some());
    }
    workers.equalise();
    img.data[row0 * w..row1 * w].par_chunks_mut(w * BAND_ROWS).zip(bands.par_iter()).for_each(|(out, band)| {
        for ((&(row, col), &sum), &n) in band.pixels.iter().zip(&band.sums).zip(&band.counts) {
            out[(row as usize - band.first_row) * w + col as usize] = sum * (1.0 / n as f32);
        }
    });
    if let Some(var) = variance {
        let pilot = statistics.map(|(base, rows)| PilotView { stat: &stat[..], base, rows });
        mean_variances(w, bands, pilot, &mut var[row0 * w..row1 * w]);
    }
}

/// The pilot statistics of a frame: `stat` holds rows `base..base + rows` of the image.
#[derive(Clone, Copy)]
struct PilotView<'a> {
    stat: &'a [[f32; 2]],
    base: usize,
    rows: usize,
}

/// Each sampled pixel's Monte Carlo variance of its mean into `out` (the bands' rows):
/// s²/N from its own N ≥ 2 samples (unbiased whatever N is, since N never depends on the
/// pixel's own samples), or, with one sample, its neighbours' estimate
/// ([`adaptive::neighbour_estimate`]; unbiased where the radiance is flat across them,
/// larger where it varies).
fn mean_variances<L: Send + Sync>(w: usize, bands: &[Band<L>], pilot: Option<PilotView>, out: &mut [f32]) {
    out.par_chunks_mut(w * BAND_ROWS).zip(bands.par_iter()).for_each(|(out, band)| {
        for (i, &(row, col)) in band.pixels.iter().enumerate() {
            let n = band.counts[i];
            let v = if n >= 2 {
                adaptive::sample_variance(band.sums[i], band.sum_sq[i], n) / n as f32
            } else {
                pilot.map_or(0.0, |p| {
                    adaptive::neighbour_estimate(p.stat, w, p.rows, row as usize - p.base, col as usize).variance
                })
            };
            out[(row as usize - band.first_row) * w + col as usize] = v;
        }
    });
}

/// The second stage of a two-stage frame: share out the rest of the budget — by what the
/// pilot saw around each pixel (`adaptive`), evenly (`uniform`), or by what the camera's
/// noise asks for (`sensor`) — and trace those samples.
fn add_second_stage<S: PerSample + Send, L: RayLog + Send + Sync>(
    job: &TileJob,
    bands: &mut [Band<L>],
    workers: &Workers<S>,
    pilot: Option<PilotView>,
    plan: Adaptive,
    sensor: Option<&SensorPlan>,
    squares: bool,
) {
    let w = job.width;
    match (sensor, pilot) {
        (Some(sensor), Some(p)) => {
            bands.par_iter_mut().for_each(|b| {
                b.counts.clear();
                b.counts.extend(b.pixels.iter().map(|&(r, c)| sensor.need(p.stat, w, p.rows, p.base, r, c)));
            });
            let cap = sensor.cap(bands.par_iter().map(|b| &b.counts[..]));
            let key = mix64(job.seed ^ mix64(job.frame ^ 0x7365_6e73_6f72_6361)); // "sensorca"
            bands.par_iter_mut().for_each(|b| {
                for (n, &(r, c)) in b.counts.iter_mut().zip(&b.pixels) {
                    let u = (mix64(key ^ (u64::from(r) * w as u64 + u64::from(c))) >> 11) as f64 / (1u64 << 53) as f64;
                    *n = cap.apply(*n, u);
                }
            });
        }
        _ => {
            match pilot {
                Some(p) if !plan.uniform => bands.par_iter_mut().for_each(|b| {
                    b.weight.clear();
                    b.weight.extend(
                        b.pixels.iter().map(|&(r, c)| plan.weight(p.stat, w, p.rows, r as usize - p.base, c as usize)),
                    );
                }),
                // An even share of a fraction: no pilot statistics to read.
                _ => bands.par_iter_mut().for_each(|b| {
                    b.weight.clear();
                    b.weight.resize(b.pixels.len(), 0.0);
                }),
            }
            let shares = plan.shares(bands.iter().map(|b| &b.weight[..]));
            bands.par_iter_mut().for_each(|band| {
                band.index.clear();
                band.index.extend(band.pixels.iter().map(|&(r, c)| u64::from(r) * w as u64 + u64::from(c)));
                plan.counts_into(&shares, &band.weight, &band.index, job.seed, job.frame, &mut band.counts);
            });
        }
    }
    bands.par_iter_mut().for_each(|band| {
        workers.with(|WorkerScratch { tile, pass, owner }| {
            // Pixel by pixel (in the band's tile order), each pixel's extra samples one after
            // the other: a packet of neighbouring paths is then mostly one pixel's, whose
            // rays start together, and each pixel's samples are summed in index order.
            pass.clear();
            owner.clear();
            for (i, (&(row, col), &n)) in band.pixels.iter().zip(&band.counts).enumerate() {
                for s in plan.pilot..n {
                    pass.push(CameraSample { row, col, index: s });
                    owner.push(i as u32);
                }
            }
            for (chunk, owners) in pass.chunks(PASS_SAMPLES).zip(owner.chunks(PASS_SAMPLES)) {
                let values = job.trace_pass(chunk, tile, &mut band.rays, &mut band.log);
                for (&i, &v) in owners.iter().zip(values) {
                    band.add_sample(i as usize, v, squares);
                }
            }
        })
    });
}

/// Every sampled pixel's pilot statistic (`[mean, variance]` of its first `pilot`
/// samples) into `stat`, for the sampled rows and the row on either side (what the
/// neighbour estimates read; unsampled pixels hold the background or `backdrop`'s value).
/// Returns the image row of `stat`'s first row and how many rows it holds.
fn pilot_statistics<L: Send + Sync>(
    job: &TileJob,
    bands: &[Band<L>],
    (stat, backdrop): (&mut Vec<[f32; 2]>, Option<&[f32]>),
    pilot: u32,
    height: usize,
) -> (usize, usize) {
    let w = job.width;
    let statistic = |sum: f32, sq: f32| [sum / pilot as f32, adaptive::sample_variance(sum, sq, pilot)];
    let background = |v: f32| [v, 0.0];
    let first = bands.first().map_or(0, |b| b.first_row);
    let (base, end) = (first.saturating_sub(1), (first + bands.len() * BAND_ROWS + 1).min(height));
    // Every entry is written below; resizing keeps last frame's values only to overwrite
    // them. The row on either side of the bands is background.
    stat.resize((end - base) * w, background(job.ctx.scene.background));
    let inside = (first - base) * w..((first + bands.len() * BAND_ROWS).min(end) - base) * w;
    // What an unsampled pixel's statistic is: the background, or its value in `backdrop`
    // (entry `i` of `stat` is the image's pixel `base·w + i`).
    let unsampled = |dst: &mut [[f32; 2]], at: usize| match backdrop {
        None => dst.fill(background(job.ctx.scene.background)),
        Some(img) => {
            for (d, &v) in dst.iter_mut().zip(&img[base * w + at..]) {
                *d = background(v);
            }
        }
    };
    let (before, after) = (inside.start, inside.end);
    unsampled(&mut stat[..before], 0);
    unsampled(&mut stat[after..], after);
    // Bands own disjoint rows: each clears and writes its own while they are in cache
    // (one pass over the statistics instead of a frame-wide fill and then a scatter).
    stat[inside].par_chunks_mut(BAND_ROWS * w).zip(bands.par_iter()).enumerate().for_each(|(b, (mine, band))| {
        unsampled(mine, before + b * BAND_ROWS * w);
        for ((&(row, col), &sum), &sq) in band.pixels.iter().zip(&band.sums).zip(&band.sum_sq) {
            mine[(row as usize - band.first_row) * w + col as usize] = statistic(sum, sq);
        }
    });
    (base, end - base)
}

/// A band's pixels that may see the target, in tile order: blocks of about
/// `TILE_PATHS / BAND_ROWS` columns × all the band's rows, so a tile is compact.
fn band_pixels(
    job: &TileJob,
    rows: std::ops::Range<u32>,
    span: &(dyn Fn(u32) -> (u32, u32) + Sync),
    pixels: &mut Vec<(u32, u32)>,
) {
    let tile_cols = (TILE_PATHS / BAND_ROWS).max(1) as u32;
    let mut spans = [(0u32, 0u32); BAND_ROWS];
    for (s, row) in spans.iter_mut().zip(rows.clone()) {
        *s = span(row);
    }
    let spans = &spans[..rows.len()];
    pixels.clear();
    let c_min = spans.iter().filter(|s| s.0 < s.1).map(|s| s.0).min().unwrap_or(0);
    let c_max = spans.iter().filter(|s| s.0 < s.1).map(|s| s.1).max().unwrap_or(0);
    for c0 in (c_min..c_max).step_by(tile_cols as usize) {
        let c1 = (c0 + tile_cols).min(c_max);
        for (row, &(a, b)) in rows.clone().zip(spans) {
            let cols = a.max(c0)..b.min(c1);
            match job.coverage {
                Some(c) => pixels.extend(cols.filter(|&col| c.may_hit(row, col)).map(|col| (row, col))),
                None => pixels.extend(cols.map(|col| (row, col))),
            }
        }
    }
}
