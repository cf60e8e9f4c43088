//! The paper's Table 1 and Fig. 7 experiments on top of [`super::sampling`]: run, print
//! in the paper's layout, and write CSV, RMSE plots and image grids.

use super::sampling::{
    Cell, PlaneCase, Reference, image_grid, reduction_pct, reference, rmse_at_time, rmse_indirect_of, rmse_of,
    sampler_name, sequence_name, sweep,
};
use crate::plot::{LineChart, PlotError, Scale, Series};
use hilcam_core::render::bsdf::{Bsdf, ImprovedBlinnPhong};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::SamplerKind;
use hilcam_core::render::sampling::Sequence;
use hilcam_core::scene::fold::{FoldError, FoldLevel, generate_plane};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The paper's average RMSE reduction of cosine over uniform sampling (Table 1).
pub fn paper_average_reduction(level: FoldLevel) -> f64 {
    match level {
        FoldLevel::Slight => 54.68,
        FoldLevel::Medium => 60.07,
        FoldLevel::Severe => 63.42,
    }
}

/// Why an experiment could not finish.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("fold plane: {0}")]
    Fold(#[from] FoldError),
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error("{path}: {source}")]
    Image { path: PathBuf, source: image::ImageError },
}

/// Settings shared by both experiments.
#[derive(Clone, Debug)]
pub struct Table1Config {
    pub levels: Vec<FoldLevel>,
    pub size: u32,
    pub spps: Vec<u32>,
    /// The reference is `2 × ref_half_spp` samples (two halves, Sobol).
    pub ref_half_spp: u32,
    pub depth: u32,
    pub seed: u64,
    /// Fold-plane seed.
    pub fold_seed: u64,
    /// Also run every sampler with the Sobol sequence (what stratification adds).
    pub sobol: bool,
    /// Sun irradiance, W/m² (the paper: 100).
    pub sun: f64,
    /// Radiance of the uniform sky escaping rays collect, W·sr⁻¹·m⁻² (0: black).
    pub sky: f64,
    pub out: Option<PathBuf>,
}

/// Results for one fold level.
pub struct LevelResult {
    pub level: FoldLevel,
    pub disk_pixels: usize,
    pub ref_spp: u32,
    pub ref_noise: f64,
    /// Mean radiance of the reference over the disk pixels.
    pub ref_mean: f64,
    pub cells: Vec<Cell>,
}

impl LevelResult {
    /// Mean over the sample counts of the reduction of `sampler` over uniform sampling.
    /// `indirect` uses the indirect-part RMSE.
    pub fn average_reduction(&self, sampler: SamplerKind, sequence: Sequence, spps: &[u32], indirect: bool) -> f64 {
        let cells: Vec<Cell> = self.cells.iter().filter(|c| c.sequence == sequence).cloned().collect();
        let get = if indirect { rmse_indirect_of } else { rmse_of };
        let v: Vec<f64> = spps
            .iter()
            .filter_map(|&n| Some(reduction_pct(get(&cells, SamplerKind::Uniform, n)?, get(&cells, sampler, n)?)))
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }
}

const SAMPLERS: [SamplerKind; 3] = [SamplerKind::Uniform, SamplerKind::Cosine, SamplerKind::Brdf];

fn write(path: &Path, text: &str) -> Result<(), BenchError> {
    std::fs::write(path, text).map_err(|source| BenchError::Io { path: path.to_path_buf(), source })
}

fn out_dir(out: &Option<PathBuf>) -> Result<Option<&Path>, BenchError> {
    if let Some(d) = out {
        std::fs::create_dir_all(d).map_err(|source| BenchError::Io { path: d.clone(), source })?;
    }
    Ok(out.as_deref())
}

/// Run Table 1 for each level; prints progress and the tables; writes files to `out`.
pub fn run_table1(cfg: &Table1Config) -> Result<Vec<LevelResult>, BenchError> {
    let out = out_dir(&cfg.out)?;
    let mut results = Vec::new();
    let mut csv =
        String::from("level,sequence,sampler,spp,rmse,rmse_indirect,time_s,ref_spp,ref_noise,ref_mean,sun,sky\n");
    for &level in &cfg.levels {
        let plane = generate_plane(level.target(), cfg.fold_seed)?;
        let case = PlaneCase::paper_lambert_lit(plane.mesh, cfg.size, cfg.sun, cfg.sky);
        let r: Reference = reference(&case, SamplerKind::Cosine, cfg.ref_half_spp, cfg.depth);
        println!(
            "{}: E_PLANE {:.4} Var {:.4}; sun {} W/m², sky {} W/sr/m²; {} disk pixels; reference {} spp (cosine, \
             Sobol) in {:.1} s, mean {:.4}, its own RMS noise {:.4}",
            level.name(),
            plane.stats.e_plane,
            plane.stats.var,
            cfg.sun,
            cfg.sky,
            case.disk_pixels(),
            r.spp,
            r.time_s,
            r.mean,
            r.noise
        );
        let mut grid: Vec<Vec<RadianceImage>> = vec![Vec::new(); SAMPLERS.len()];
        let mut cells =
            sweep(&case, &r, &SAMPLERS, &cfg.spps, Sequence::Independent, cfg.depth, cfg.seed, |s, _, img| {
                let row = SAMPLERS.iter().position(|x| *x == s).unwrap_or(0);
                grid[row].push(img.clone());
            });
        if cfg.sobol {
            cells.extend(sweep(&case, &r, &SAMPLERS, &cfg.spps, Sequence::Sobol, cfg.depth, cfg.seed, |_, _, _| {}));
        }
        for c in &cells {
            let _ = writeln!(
                csv,
                "{},{},{},{},{:.6},{:.6},{:.4},{},{:.6},{:.6},{},{}",
                level.name(),
                sequence_name(c.sequence),
                sampler_name(c.sampler),
                c.spp,
                c.rmse,
                c.rmse_indirect,
                c.time_s,
                r.spp,
                r.noise,
                r.mean,
                cfg.sun,
                cfg.sky
            );
        }
        if let Some(dir) = out {
            let scale = r.image.preview_scale();
            let p = dir.join(format!("grid_{}.png", level.name()));
            image_grid(&grid, scale, 2).save(&p).map_err(|source| BenchError::Image { path: p.clone(), source })?;
            let p = dir.join(format!("rmse_{}.png", level.name()));
            rmse_chart(&format!("Table 1, {} fold", level.name()), &cells).save_png(&p)?;
        }
        let res = LevelResult {
            level,
            disk_pixels: case.disk_pixels(),
            ref_spp: r.spp,
            ref_noise: r.noise,
            ref_mean: r.mean,
            cells,
        };
        results.push(res);
    }
    let text = format!(
        "sun {} W/m² at θi = 10°, sky {} W·sr⁻¹·m⁻²\n{}",
        cfg.sun,
        cfg.sky,
        table1_text(&results, &cfg.spps, cfg.sobol)
    );
    print!("{text}");
    if let Some(dir) = out {
        write(&dir.join("table1.csv"), &csv)?;
        write(&dir.join("table1.txt"), &text)?;
    }
    Ok(results)
}

fn rmse_chart(title: &str, cells: &[Cell]) -> LineChart {
    let mut chart =
        LineChart::new(title).x_label("rays per pixel").y_label("RMSE, W·sr⁻¹·m⁻²").scales(Scale::Log, Scale::Log);
    for seq in [Sequence::Independent, Sequence::Sobol] {
        for (k, s) in SAMPLERS.iter().enumerate() {
            let pts: Vec<(f64, f64)> = cells
                .iter()
                .filter(|c| c.sampler == *s && c.sequence == seq)
                .map(|c| (f64::from(c.spp), c.rmse))
                .collect();
            if pts.is_empty() {
                continue;
            }
            let colors = [[31, 119, 180], [255, 127, 14], [44, 160, 44]];
            let mut series = Series::new(format!("{} ({})", sampler_name(*s), sequence_name(seq)), pts)
                .with_markers()
                .color(colors[k]);
            if seq == Sequence::Sobol {
                series = series.dashed();
            }
            chart = chart.series(series);
        }
    }
    chart
}

/// Table 1 in the paper's layout (one block per sequence): the whole pixel's RMSE (the
/// paper's measure) and the RMSE of its indirect part alone.
pub fn table1_text(results: &[LevelResult], spps: &[u32], sobol: bool) -> String {
    let mut t = String::new();
    let seqs: &[Sequence] = if sobol { &[Sequence::Independent, Sequence::Sobol] } else { &[Sequence::Independent] };
    for &seq in seqs {
        let _ = writeln!(
            t,
            "\nTable 1 — RMSE (W·sr⁻¹·m⁻²) against the reference, {} random numbers; reduction vs uniform",
            sequence_name(seq)
        );
        let _ = writeln!(
            t,
            "{:<7} {:>5} | {:>8} {:>8} {:>8} {:>8} {:>8} | indirect part: {:>8} {:>8} {:>8} {:>8} {:>8}",
            "fold",
            "rays",
            "uniform",
            "cosine",
            "brdf",
            "cos %",
            "brdf %",
            "uniform",
            "cosine",
            "brdf",
            "cos %",
            "brdf %"
        );
        for r in results {
            let cells: Vec<Cell> = r.cells.iter().filter(|c| c.sequence == seq).cloned().collect();
            for &n in spps {
                let row = |get: fn(&[Cell], SamplerKind, u32) -> Option<f64>| {
                    let u = get(&cells, SamplerKind::Uniform, n)?;
                    let c = get(&cells, SamplerKind::Cosine, n)?;
                    let b = get(&cells, SamplerKind::Brdf, n)?;
                    Some(format!(
                        "{u:>8.4} {c:>8.4} {b:>8.4} {:>7.2}% {:>7.2}%",
                        reduction_pct(u, c),
                        reduction_pct(u, b)
                    ))
                };
                let (Some(a), Some(i)) = (row(rmse_of), row(rmse_indirect_of)) else {
                    continue;
                };
                let _ = writeln!(t, "{:<7} {:>5} | {a} |                {i}", r.level.name(), n);
            }
            let avg = |s, ind| r.average_reduction(s, seq, spps, ind);
            let _ = writeln!(
                t,
                "{:<7} average reduction vs uniform: cosine {:.2} % (paper {:.2} %), brdf {:.2} %; \
                 indirect part: cosine {:.2} %, brdf {:.2} %; reference mean {:.4}, noise {:.4}",
                r.level.name(),
                avg(SamplerKind::Cosine, false),
                paper_average_reduction(r.level),
                avg(SamplerKind::Brdf, false),
                avg(SamplerKind::Cosine, true),
                avg(SamplerKind::Brdf, true),
                r.ref_mean,
                r.ref_noise
            );
        }
    }
    t
}

/// Settings of the Fig. 7 glint experiment.
#[derive(Clone, Debug)]
pub struct GlintConfig {
    pub size: u32,
    pub spps: Vec<u32>,
    pub ref_half_spp: u32,
    pub depth: u32,
    pub seed: u64,
    pub fold_seed: u64,
    pub theta_i_deg: Vec<f64>,
    pub out: Option<PathBuf>,
}

/// One glint case: the BRDF variant, the sun angle, and its cells.
pub struct GlintResult {
    pub normalized: bool,
    pub theta_i_deg: f64,
    pub ref_noise: f64,
    pub cells: Vec<Cell>,
}

/// Fig. 7: improved Blinn-Phong gold polyimide (paper fit and normalised) on the slight
/// fold plane, θo = 0°, sun at each θi; cosine vs the BRDF's MIS sampling at equal
/// samples and at equal time (cosine's RMSE interpolated log–log at MIS's time).
pub fn run_glints(cfg: &GlintConfig) -> Result<Vec<GlintResult>, BenchError> {
    let out = out_dir(&cfg.out)?;
    let plane = generate_plane(FoldLevel::Slight.target(), cfg.fold_seed)?;
    let samplers = [SamplerKind::Cosine, SamplerKind::Brdf];
    let mut results = Vec::new();
    let mut refs = Vec::new();
    let mut csv = String::from("normalized,theta_i_deg,sampler,spp,rmse,time_s,ref_noise\n");
    for normalized in [false, true] {
        let gold = ImprovedBlinnPhong::gold_polyimide();
        let bsdf = Bsdf::ImprovedBlinnPhong(if normalized { gold.normalized() } else { gold });
        for &ti in &cfg.theta_i_deg {
            let case = PlaneCase::new(plane.mesh.clone(), bsdf, super::sampling::PAPER_IRRADIANCE, ti, cfg.size);
            let r = reference(&case, SamplerKind::Brdf, cfg.ref_half_spp, cfg.depth);
            let cells =
                sweep(&case, &r, &samplers, &cfg.spps, Sequence::Independent, cfg.depth, cfg.seed, |_, _, _| {});
            for c in &cells {
                let _ = writeln!(
                    csv,
                    "{normalized},{ti},{},{},{:.6},{:.4},{:.6}",
                    sampler_name(c.sampler),
                    c.spp,
                    c.rmse,
                    c.time_s,
                    r.noise
                );
            }
            refs.push(r.image);
            results.push(GlintResult { normalized, theta_i_deg: ti, ref_noise: r.noise, cells });
        }
    }
    let text = glint_text(&results, &cfg.spps);
    print!("{text}");
    if let Some(dir) = out {
        write(&dir.join("glints.csv"), &csv)?;
        write(&dir.join("glints.txt"), &text)?;
        // References side by side: row 1 the paper's fit, row 2 normalised; one scale per row.
        let n = cfg.theta_i_deg.len();
        for k in 0..2 {
            let row: Vec<RadianceImage> = refs[k * n..(k + 1) * n].to_vec();
            let scale = row.iter().map(|i| i.preview_scale()).fold(0.0f32, f32::max);
            let p = dir.join(format!("glints_{}.png", if k == 0 { "paper" } else { "normalized" }));
            image_grid(&[row], scale, 2).save(&p).map_err(|source| BenchError::Image { path: p.clone(), source })?;
        }
    }
    Ok(results)
}

/// The Fig. 7 comparison table.
pub fn glint_text(results: &[GlintResult], spps: &[u32]) -> String {
    let mut t = String::from(
        "\nFig. 7 case — gold polyimide (improved Blinn-Phong), slight fold, θo = 0°: RMSE of cosine vs brdf (MIS)\n",
    );
    let _ = writeln!(
        t,
        "{:<10} {:>5} {:>6} {:>10} {:>10} {:>9} {:>9} {:>14} {:>11}",
        "brdf", "θi", "rays", "cosine", "brdf", "cos s", "brdf s", "cut eq. rays", "cut eq. time"
    );
    for r in results {
        for &n in spps {
            let cell = |s| r.cells.iter().find(|c| c.sampler == s && c.spp == n);
            let (Some(c), Some(b)) = (cell(SamplerKind::Cosine), cell(SamplerKind::Brdf)) else {
                continue;
            };
            let at_time = rmse_at_time(&r.cells, SamplerKind::Cosine, b.time_s).unwrap_or(f64::NAN);
            let _ = writeln!(
                t,
                "{:<10} {:>4}° {:>6} {:>10.4} {:>10.4} {:>9.3} {:>9.3} {:>13.1}% {:>10.1}%",
                if r.normalized { "normalized" } else { "paper" },
                r.theta_i_deg,
                n,
                c.rmse,
                b.rmse,
                c.time_s,
                b.time_s,
                reduction_pct(c.rmse, b.rmse),
                reduction_pct(at_time, b.rmse)
            );
        }
        let _ = writeln!(t, "{:<10} {:>4}° reference noise {:.4}", "", r.theta_i_deg, r.ref_noise);
    }
    t
}
