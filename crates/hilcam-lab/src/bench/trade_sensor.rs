//! The sensor axis of the quality/time trade (issue 27): fixed spp against
//! `quality = "sensor"`, judged by the share of lit pixels whose Monte Carlo noise is above
//! k × the camera's own temporal noise.
//!
//! Every frame goes through [`FramePipeline`] (render + sensor) at one integration time:
//! the auto-exposure's once it has settled on the scene's own settings ([`settle`]), then
//! held ([`FrameRequest::integration_s`]) so that every row meets the same camera noise.
//! Each frame is judged at its own bound (the frame's report) and at a common one,
//! [`COMMON_K`], recounted from the frame's radiance and variance
//! (`Sensor::mc_noise_stats`). Rows are measured in rounds, each round rendering every row
//! once (frame index = round), so a neighbour's burst on a shared machine hits all rows
//! alike; times are medians over the rounds, the quality figures their means.

use super::median;
use super::trade::relative_rmse;
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Pose;
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{QualityGoal, QualityMode, RenderSettings, Spp};
use hilcam_core::render::sensor_plan::SensorPlan;
use hilcam_core::sensor::{McNoiseStats, SensorError};
use std::fmt::Write as _;

/// The bound every row is judged against besides its own.
pub const COMMON_K: f64 = 0.5;

/// How a row's frames spend their samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RowKind {
    /// `spp` per traced pixel on average, shared out as the scene's settings say
    /// (adaptive or not).
    Fixed { spp: Spp },
    /// `quality = "sensor"` at bound `k` within `budget` (mean spp per traced pixel).
    Sensor { k: f32, budget: Spp },
}

impl RowKind {
    /// The scene's settings `base` with this row's sampling.
    pub fn settings(&self, base: &RenderSettings) -> RenderSettings {
        match *self {
            // The report's own k is then the common one.
            RowKind::Fixed { spp } => {
                RenderSettings { spp, quality: QualityGoal { mode: QualityMode::Fixed, k: COMMON_K as f32 }, ..*base }
            }
            RowKind::Sensor { k, budget } => {
                RenderSettings { spp: budget, quality: QualityGoal { mode: QualityMode::Sensor, k }, ..*base }
            }
        }
    }

    /// The bound the frame's own report uses.
    pub fn k(&self) -> f64 {
        match *self {
            RowKind::Fixed { .. } => COMMON_K,
            RowKind::Sensor { k, .. } => f64::from(k),
        }
    }

    /// `fixed 4`, `sensor 0.5 ≤ 64`.
    pub fn label(&self) -> String {
        match self {
            RowKind::Fixed { spp } => format!("fixed {spp}"),
            RowKind::Sensor { k, budget } => format!("sensor {k} ≤ {budget}"),
        }
    }
}

/// The auto-exposure's integration time once it stopped moving.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settled {
    pub integration_s: f64,
    /// Frames rendered to get there.
    pub frames: u32,
    /// False when `max_frames` ran out before the time changed by less than the tolerance.
    pub converged: bool,
}

/// Render frames with `settings` until the integration time the auto-exposure picks
/// changes by less than `tolerance` (relative) from one frame to the next, at most
/// `max_frames`. Without auto-exposure the configured time is settled at once.
pub fn settle(
    pipeline: &mut FramePipeline,
    pose: &Pose,
    settings: &RenderSettings,
    max_frames: u32,
    tolerance: f64,
) -> Result<Settled, SensorError> {
    let mut t = pipeline.exposure_timing(None).integration_s;
    for i in 0..max_frames {
        pipeline.frame(pose, settings, u64::from(i))?;
        let next = pipeline.exposure_timing(None).integration_s;
        let change = (next - t).abs() / t.abs().max(f64::MIN_POSITIVE);
        t = next;
        if change < tolerance {
            return Ok(Settled { integration_s: t, frames: i + 1, converged: true });
        }
    }
    Ok(Settled { integration_s: t, frames: max_frames, converged: false })
}

/// The converged radiance the rows' relative RMSE is measured against: `spp` samples in
/// every pixel at the scene's depth and sampler, with another seed (independent noise).
pub fn reference(pipeline: &FramePipeline, pose: &Pose, base: &RenderSettings, spp: u32) -> (RadianceImage, f64) {
    let s = RenderSettings {
        spp: Spp::whole(spp.max(1)),
        adaptive: false,
        quality: QualityGoal::FIXED,
        seed: base.seed.wrapping_add(1),
        ..*base
    };
    let (img, stats) = pipeline.radiance(pose, &s, 0);
    (img, stats.time.as_secs_f64())
}

/// One frame of one row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowFrame {
    /// Camera samples per traced pixel.
    pub spp: f64,
    pub render_s: f64,
    pub sensor_s: f64,
    /// The frame's own report (at the row's k).
    pub own: McNoiseStats,
    /// The same frame counted at [`COMMON_K`].
    pub common: McNoiseStats,
    /// Relative RMSE of the radiance against the reference.
    pub rel_rmse: f64,
}

/// Share of lit pixels above the report's bound (0 without lit pixels).
pub fn fraction_above(s: &McNoiseStats) -> f64 {
    if s.lit_pixels == 0 { 0.0 } else { s.above_bound as f64 / s.lit_pixels as f64 }
}

/// Render and convert frame `index` of row `kind` at integration time `t_s`, and judge it.
///
/// # Errors
/// The pipeline's; [`SensorError::Invalid`] when the sensor gives no Monte Carlo report
/// (no detector with DN output).
pub fn measure_frame(
    pipeline: &mut FramePipeline,
    pose: &Pose,
    base: &RenderSettings,
    kind: RowKind,
    t_s: f64,
    index: u64,
    reference: &RadianceImage,
) -> Result<RowFrame, SensorError> {
    let request = FrameRequest { integration_s: Some(t_s), roi: None };
    let f = pipeline.frame_requested(pose, &kind.settings(base), index, &request)?;
    let no_report = || SensorError::Invalid {
        field: "sensor".into(),
        message: "the sensor axis needs a detector with DN output (its Monte Carlo noise report)".into(),
    };
    let own = f.mc_noise.ok_or_else(no_report)?;
    let (img, var) = pipeline.last_render();
    let common =
        pipeline.sensor().mc_noise_stats(img, var.ok_or_else(no_report)?, t_s, COMMON_K)?.ok_or_else(no_report)?;
    Ok(RowFrame {
        spp: f.render.samples as f64 / f.render.traced_pixels.max(1) as f64,
        render_s: f.render.time.as_secs_f64(),
        sensor_s: f.sensor_time.as_secs_f64(),
        own,
        common,
        rel_rmse: relative_rmse(img, reference),
    })
}

/// One row of the table: its frames summarised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorRow {
    pub kind: RowKind,
    /// Mean camera samples per traced pixel.
    pub spp: f64,
    /// Medians over the rounds, s: render, sensor, and the two together.
    pub render_s: f64,
    pub sensor_s: f64,
    pub frame_s: f64,
    /// Mean lit pixels.
    pub lit_pixels: f64,
    /// Mean share of lit pixels above the [`COMMON_K`] bound.
    pub above_common: f64,
    /// Mean share of lit pixels above the row's own bound.
    pub above_own: f64,
    /// Mean of the frames' `rms_ratio` (σ_mc / σ_cam, root mean square over lit pixels).
    pub rms_ratio: f64,
    /// Mean relative RMSE of the radiance against the reference.
    pub rel_rmse: f64,
}

impl SensorRow {
    /// Summarise `frames` of row `kind` (at least one).
    pub fn from_frames(kind: RowKind, frames: &[RowFrame]) -> SensorRow {
        let n = frames.len().max(1) as f64;
        let mean = |f: fn(&RowFrame) -> f64| frames.iter().map(f).sum::<f64>() / n;
        let med = |f: fn(&RowFrame) -> f64| median(frames.iter().map(f).collect());
        SensorRow {
            kind,
            spp: mean(|f| f.spp),
            render_s: med(|f| f.render_s),
            sensor_s: med(|f| f.sensor_s),
            frame_s: med(|f| f.render_s + f.sensor_s),
            lit_pixels: mean(|f| f.common.lit_pixels as f64),
            above_common: mean(|f| fraction_above(&f.common)),
            above_own: mean(|f| fraction_above(&f.own)),
            rms_ratio: mean(|f| f.own.rms_ratio),
            rel_rmse: mean(|f| f.rel_rmse),
        }
    }
}

/// Measure `kinds` in `rounds` rounds (each round every row once, frame index = round);
/// `progress` gets each round's number as it ends.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    pipeline: &mut FramePipeline,
    pose: &Pose,
    base: &RenderSettings,
    kinds: &[RowKind],
    t_s: f64,
    rounds: usize,
    reference: &RadianceImage,
    mut progress: impl FnMut(usize),
) -> Result<Vec<SensorRow>, SensorError> {
    let mut frames: Vec<Vec<RowFrame>> = vec![Vec::new(); kinds.len()];
    for round in 0..rounds.max(1) {
        for (kind, out) in kinds.iter().zip(&mut frames) {
            out.push(measure_frame(pipeline, pose, base, *kind, t_s, round as u64, reference)?);
        }
        progress(round);
    }
    Ok(kinds.iter().zip(&frames).map(|(k, f)| SensorRow::from_frames(*k, f)).collect())
}

/// The budgets of the frame-rate sweep: the pilot's 2 spp (a smaller budget still spends
/// the pilot), then doubling up to `max`.
pub fn sweep_budgets(max: u32) -> Vec<Spp> {
    std::iter::successors(Some(SensorPlan::PILOT), |b| b.checked_mul(2))
        .take_while(|b| *b <= max.max(SensorPlan::PILOT))
        .map(Spp::whole)
        .collect()
}

/// The first row (in sweep order) with at most `limit` of its lit pixels above the
/// common bound.
pub fn first_meeting(rows: &[SensorRow], limit: f64) -> Option<&SensorRow> {
    rows.iter().find(|r| r.above_common <= limit)
}

/// One CSV line per row, `table` rows then `sweep` rows.
pub fn to_csv(table: &[SensorRow], sweep: &[SensorRow]) -> String {
    let mut s = String::from(
        "part,mode,spp,k,mean_spp,render_ms,sensor_ms,frame_ms,lit_pixels,above_k05,above_own_k,rms_ratio,rel_rmse\n",
    );
    for (part, rows) in [("table", table), ("sweep", sweep)] {
        for r in rows {
            let (mode, spp) = match r.kind {
                RowKind::Fixed { spp } => ("fixed", spp),
                RowKind::Sensor { budget, .. } => ("sensor", budget),
            };
            let _ = writeln!(
                s,
                "{part},{mode},{spp},{},{:.3},{:.3},{:.3},{:.3},{:.0},{:.6},{:.6},{:.4},{:.6}",
                r.kind.k(),
                r.spp,
                r.render_s * 1e3,
                r.sensor_s * 1e3,
                r.frame_s * 1e3,
                r.lit_pixels,
                r.above_common,
                r.above_own,
                r.rms_ratio,
                r.rel_rmse
            );
        }
    }
    s
}

/// Share of lit pixels above the k = 0.5 bound against frame time: the fixed rows, the
/// sensor rows, and the k = 0.5 budget sweep.
pub fn chart(table: &[SensorRow], sweep: &[SensorRow], title: &str) -> crate::plot::LineChart {
    use crate::plot::{LineChart, Scale, Series};
    let pts = |rows: &[SensorRow], fixed: bool| -> Vec<(f64, f64)> {
        rows.iter()
            .filter(|r| matches!(r.kind, RowKind::Fixed { .. }) == fixed)
            .map(|r| (r.frame_s, r.above_common * 100.0))
            .collect()
    };
    LineChart::new(title)
        .x_label("frame time, render + sensor (s)")
        .y_label("% of lit pixels above 0.5 × camera noise")
        .scales(Scale::Log, Scale::Linear)
        .size(900, 650)
        .series(Series::new("fixed spp", pts(table, true)).with_markers())
        .series(Series::new("sensor, k = 1 / 0.5 / 0.25", pts(table, false)).with_markers())
        .series(Series::new("sensor k = 0.5, budget sweep", pts(sweep, false)).with_markers().dashed())
}
