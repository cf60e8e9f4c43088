//! `hilcam bench trade --sensor`: the trade's sensor axis (`bench::trade_sensor`).

use crate::bench::trade_sensor::{
    COMMON_K, RowKind, SensorRow, chart, first_meeting, measure, reference, settle, sweep_budgets, to_csv,
};
use crate::cli::bench_trade::TradeArgs;
use anyhow::Context;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::render::integrator::Spp;
use hilcam_core::scene::limits::checked_scaled_camera;
use std::sync::Arc;

/// The frame-rate question: the share of lit pixels allowed above the k = 0.5 bound.
const MEET_LIMIT: f64 = 0.01;
/// Auto-exposure warm-up: at most this many frames, until the time moves < 1 %.
const SETTLE_FRAMES: u32 = 40;
const SETTLE_TOLERANCE: f64 = 0.01;
/// Default reference spp (every pixel, the scene's depth and sampler).
const REFERENCE_SPP: u32 = 1024;

pub fn run(a: &TradeArgs) -> anyhow::Result<()> {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let scene = hilcam_core::scene::load(&a.scene)?;
    let camera = checked_scaled_camera(&scene.camera, a.width, None).map_err(anyhow::Error::msg)?;
    let (pose, base) = (scene.pose, scene.render);
    let mut pipeline = FramePipeline::new(Arc::new(scene), camera.clone())?;
    let rounds = a.rounds.max(1);
    println!(
        "{}: {}x{}, depth {} {:?}, adaptive {}; {} threads; {rounds} rounds per row (times: medians; \
         quality: means)",
        a.scene.display(),
        camera.width,
        camera.height,
        base.depth,
        base.sampler,
        base.adaptive,
        rayon::current_num_threads()
    );

    let settled = settle(&mut pipeline, &pose, &base, SETTLE_FRAMES, SETTLE_TOLERANCE)?;
    println!(
        "auto-exposure {} after {} frames at spp {}: integration time {:.4} ms, held for every row",
        if settled.converged { "settled (< 1 % change)" } else { "NOT settled" },
        settled.frames,
        base.spp,
        settled.integration_s * 1e3
    );
    let t = settled.integration_s;
    let ref_spp = a.reference_spp.unwrap_or(REFERENCE_SPP);
    let (reference, ref_s) = reference(&pipeline, &pose, &base, ref_spp);
    println!("reference: {ref_spp} spp in every pixel, seed + 1, rendered in {ref_s:.1} s");

    let budget = Spp::whole(a.sensor_budget.max(1));
    let kinds: Vec<RowKind> = a
        .fixed_spp
        .iter()
        .map(|&spp| RowKind::Fixed { spp })
        .chain(a.sensor_k.iter().map(|&k| RowKind::Sensor { k, budget }))
        .collect();
    let table = measure(&mut pipeline, &pose, &base, &kinds, t, rounds, &reference, |r| {
        eprintln!("  round {} of {rounds} done", r + 1)
    })?;
    print_header();
    for r in &table {
        print_row(r);
    }

    println!("frame rate: quality = \"sensor\", k = {COMMON_K}, budgets 2 … {} until ≤ 1 % above", a.max_budget);
    print_header();
    let mut sweep = Vec::new();
    for b in sweep_budgets(a.max_budget) {
        let kind = RowKind::Sensor { k: COMMON_K as f32, budget: b };
        let row = measure(&mut pipeline, &pose, &base, &[kind], t, rounds, &reference, |_| {})?[0];
        print_row(&row);
        sweep.push(row);
        if row.above_common <= MEET_LIMIT {
            break;
        }
        // Frames that spent < 95 % of the budget were limited by the bound: a larger
        // budget renders the same frames.
        if row.spp < 0.95 * b.get() {
            println!("(the bound, not the budget, limits from here on: larger budgets give these frames)");
            break;
        }
    }
    match first_meeting(&sweep, MEET_LIMIT) {
        Some(r) => println!(
            "99 % of lit pixels within {COMMON_K} × camera noise: budget {} ({:.1} mean spp), {:.1} ms \
             (render {:.1} + sensor {:.1}) → {:.2} fps on {} threads",
            match r.kind {
                RowKind::Sensor { budget, .. } => budget,
                RowKind::Fixed { spp } => spp,
            },
            r.spp,
            r.frame_s * 1e3,
            r.render_s * 1e3,
            r.sensor_s * 1e3,
            1.0 / r.frame_s,
            rayon::current_num_threads()
        ),
        None => println!(
            "99 % of lit pixels within {COMMON_K} × camera noise: not reached (the sweep stopped at budget {})",
            sweep.last().map_or(Spp::ONE, |r| match r.kind {
                RowKind::Sensor { budget, .. } => budget,
                RowKind::Fixed { spp } => spp,
            })
        ),
    }

    let csv = a.out.with_extension("csv");
    std::fs::write(&csv, to_csv(&table, &sweep)).with_context(|| csv.display().to_string())?;
    let png = a.out.with_extension("png");
    let title =
        format!("{} at {}x{}: noise above the bound vs frame time", a.scene.display(), camera.width, camera.height);
    chart(&table, &sweep, &title).save_png(&png)?;
    println!("wrote {} and {}", csv.display(), png.display());
    Ok(())
}

fn print_header() {
    println!(
        "{:<18} {:>8} {:>10} {:>10} {:>10} {:>7} {:>8} {:>8} {:>8} {:>9}",
        "row", "mean spp", "render ms", "sensor ms", "frame ms", "fps", ">0.5 %", ">own k %", "rms σ/σ", "rel RMSE"
    );
}

fn print_row(r: &SensorRow) {
    println!(
        "{:<18} {:>8.2} {:>10.1} {:>10.1} {:>10.1} {:>7.2} {:>8.2} {:>8.2} {:>8.3} {:>9.4}",
        r.kind.label(),
        r.spp,
        r.render_s * 1e3,
        r.sensor_s * 1e3,
        r.frame_s * 1e3,
        1.0 / r.frame_s,
        r.above_common * 100.0,
        r.above_own * 100.0,
        r.rms_ratio,
        r.rel_rmse
    );
}
