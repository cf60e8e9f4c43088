//! The quality/time trade: frame time and relative error over spp × depth × sampler.
//!
//! Error of a setting = relative RMSE against a converged reference: the RMSE over the
//! pixels where the reference is > 0, divided by the reference mean over those pixels.
//! The reference is the deepest setting (depth 4, many spp, BRDF sampling) rendered with
//! another seed, so its noise is independent of the estimates'. Depth also changes the
//! converged answer: the error of depth 1 and 2 includes their bias (missing bounces).
//!
//! Sub-pixel glints (a sharp lobe mirroring the sun from a facet that covers part of a
//! pixel) are estimated by pixel-area sampling with a heavy tail: on the shipped
//! satellite ten pixels out of ~10 000 hold > 99 % of the squared error at 1 spp. So a
//! second error is reported beside it, the *body* error: the same relative RMSE over the
//! lit pixels at or below the reference's 99.9th percentile (the glints, which a real
//! detector clips, left out).

use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::Pose;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use std::fmt::Write as _;

/// One measured grid point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TradePoint {
    pub spp: Spp,
    pub depth: u32,
    pub sampler: SamplerKind,
    /// Median render time of one frame, s.
    pub time_s: f64,
    /// Relative RMSE against the reference.
    pub rel_rmse: f64,
    /// Relative RMSE over the reference's lit pixels at or below its 99.9th percentile.
    pub rel_rmse_body: f64,
}

impl TradePoint {
    /// This point ranked by its body error instead (for a front of the body error).
    pub fn by_body_error(&self) -> TradePoint {
        TradePoint { rel_rmse: self.rel_rmse_body, ..*self }
    }
}

/// The grid to measure.
#[derive(Clone, Debug)]
pub struct TradeGrid {
    pub spp: Vec<Spp>,
    pub depths: Vec<u32>,
    pub samplers: Vec<SamplerKind>,
    /// Timed renders per point (the median is kept).
    pub rounds: usize,
    /// Reference: depth, spp (BRDF sampling, seed `seed + 1`).
    pub reference_depth: u32,
    pub reference_spp: u32,
    /// Base settings (sequence, roulette, seed) of every point.
    pub base: RenderSettings,
}

impl TradeGrid {
    /// spp 1, 1.25, 1.5, then 2, 4 … up to `max_spp` (the fractions where the error
    /// falls fastest, when `max_spp` ≥ 2); depth 1/2/4; the three samplers; reference at
    /// depth 4 and 4 × `max_spp`.
    pub fn standard(max_spp: u32, base: RenderSettings) -> TradeGrid {
        let max = max_spp.max(1);
        let fractions = if max >= 2 { vec![Spp::from_milli(1250), Spp::from_milli(1500)] } else { vec![] };
        let spp = std::iter::once(Spp::ONE)
            .chain(fractions)
            .chain(std::iter::successors(Some(2u32), |s| s.checked_mul(2)).take_while(|s| *s <= max).map(Spp::whole))
            .collect();
        TradeGrid {
            spp,
            depths: vec![1, 2, 4],
            samplers: vec![SamplerKind::Uniform, SamplerKind::Cosine, SamplerKind::Brdf],
            rounds: 3,
            reference_depth: 4,
            reference_spp: max_spp.max(1).saturating_mul(4),
            base,
        }
    }
}

/// Relative RMSE of `img` against `reference` over the pixels where the reference is
/// > 0, divided by the reference mean there (NaN when no reference pixel is lit).
pub fn relative_rmse(img: &RadianceImage, reference: &RadianceImage) -> f64 {
    relative_rmse_up_to(img, reference, f32::INFINITY)
}

/// [`relative_rmse`] over the reference pixels in `(0, max]`.
pub fn relative_rmse_up_to(img: &RadianceImage, reference: &RadianceImage, max: f32) -> f64 {
    let (mut se, mut sum, mut n) = (0.0f64, 0.0f64, 0u64);
    for (&x, &r) in img.data.iter().zip(&reference.data) {
        if r > 0.0 && r <= max {
            let d = f64::from(x) - f64::from(r);
            se += d * d;
            sum += f64::from(r);
            n += 1;
        }
    }
    if n == 0 { f64::NAN } else { (se / n as f64).sqrt() / (sum / n as f64) }
}

/// The `q`-quantile (0…1) of the reference's lit (> 0) pixels; ∞ if none is lit.
pub fn lit_quantile(reference: &RadianceImage, q: f64) -> f32 {
    let mut lit: Vec<f32> = reference.data.iter().copied().filter(|&r| r > 0.0).collect();
    if lit.is_empty() {
        return f32::INFINITY;
    }
    lit.sort_by(f32::total_cmp);
    lit[((lit.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize]
}

/// Render the reference, then every grid point; `progress` gets each point as measured.
pub fn measure(
    pipeline: &FramePipeline,
    pose: &Pose,
    grid: &TradeGrid,
    mut progress: impl FnMut(&TradePoint),
) -> (Vec<TradePoint>, f64) {
    let ref_settings = RenderSettings {
        spp: Spp::whole(grid.reference_spp),
        depth: grid.reference_depth,
        sampler: SamplerKind::Brdf,
        // Every pixel alike: the reference must not depend on the sampling under test.
        adaptive: false,
        seed: grid.base.seed.wrapping_add(1),
        ..grid.base
    };
    let (reference, ref_stats) = pipeline.radiance(pose, &ref_settings, 0);
    let body_max = lit_quantile(&reference, 0.999);
    let mut out = Vec::new();
    for &depth in &grid.depths {
        for &sampler in &grid.samplers {
            for &spp in &grid.spp {
                let s = RenderSettings { spp, depth, sampler, ..grid.base };
                let mut times = Vec::new();
                let (mut err, mut body) = (f64::NAN, f64::NAN);
                for _ in 0..grid.rounds.max(1) {
                    let (img, st) = pipeline.radiance(pose, &s, 0);
                    times.push(st.time.as_secs_f64());
                    err = relative_rmse(&img, &reference);
                    body = relative_rmse_up_to(&img, &reference, body_max);
                }
                let time_s = super::median(times);
                let p = TradePoint { spp, depth, sampler, time_s, rel_rmse: err, rel_rmse_body: body };
                progress(&p);
                out.push(p);
            }
        }
    }
    (out, ref_stats.time.as_secs_f64())
}

/// The Pareto front: points no other point beats in both time and error, by increasing
/// time (so error strictly decreases along it).
pub fn pareto_front(points: &[TradePoint]) -> Vec<TradePoint> {
    let mut v: Vec<TradePoint> = points.iter().copied().filter(|p| p.rel_rmse.is_finite()).collect();
    v.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.rel_rmse.total_cmp(&b.rel_rmse)));
    let mut front: Vec<TradePoint> = Vec::new();
    for p in v {
        if front.last().is_none_or(|l| p.rel_rmse < l.rel_rmse) {
            front.push(p);
        }
    }
    front
}

/// The lowest-error front point that renders at `fps` (time ≤ 1/fps).
pub fn best_for_fps(front: &[TradePoint], fps: f64) -> Option<TradePoint> {
    front.iter().rev().find(|p| p.time_s <= 1.0 / fps).copied()
}

/// The fastest front point with error ≤ `error`.
pub fn best_for_error(front: &[TradePoint], error: f64) -> Option<TradePoint> {
    front.iter().find(|p| p.rel_rmse <= error).copied()
}

/// `spp,depth,sampler,time_s,rel_rmse,rel_rmse_body,pareto` with one row per point
/// (`pareto`: on the front of `rel_rmse`).
pub fn to_csv(points: &[TradePoint], front: &[TradePoint]) -> String {
    let mut s = String::from("spp,depth,sampler,time_s,rel_rmse,rel_rmse_body,pareto\n");
    for p in points {
        let on = front.iter().any(|f| f == p);
        let _ = writeln!(
            s,
            "{},{},{},{:.6},{:.6},{:.6},{}",
            p.spp,
            p.depth,
            sampler_name(p.sampler),
            p.time_s,
            p.rel_rmse,
            p.rel_rmse_body,
            on as u8
        );
    }
    s
}

pub fn sampler_name(s: SamplerKind) -> &'static str {
    match s {
        SamplerKind::Uniform => "uniform",
        SamplerKind::Cosine => "cosine",
        SamplerKind::Brdf => "brdf",
    }
}

/// Error against time on log axes: one line per (depth, sampler) through its spp values,
/// and the Pareto front dashed in black.
pub fn chart(points: &[TradePoint], front: &[TradePoint], title: &str) -> crate::plot::LineChart {
    use crate::plot::{LineChart, Scale, Series};
    let mut c = LineChart::new(title)
        .x_label("frame time (s)")
        .y_label("relative RMSE vs reference")
        .scales(Scale::Log, Scale::Log)
        .size(900, 650);
    let mut keys: Vec<(u32, SamplerKind)> = Vec::new();
    for p in points {
        if !keys.contains(&(p.depth, p.sampler)) {
            keys.push((p.depth, p.sampler));
        }
    }
    for (d, s) in keys {
        let pts = points.iter().filter(|p| p.depth == d && p.sampler == s).map(|p| (p.time_s, p.rel_rmse)).collect();
        c = c.series(Series::new(format!("depth {d} {}", sampler_name(s)), pts).with_markers());
    }
    c.series(
        Series::new("Pareto front", front.iter().map(|p| (p.time_s, p.rel_rmse)).collect()).dashed().color([0, 0, 0]),
    )
}
