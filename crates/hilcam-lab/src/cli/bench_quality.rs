//! `hilcam bench quality`: the independent judge of sensor-equivalent frames
//! (`bench::quality`), row by row, with the frame rate of each.

use crate::bench::quality::{Conversion, K, Reference, Row, RowResult, measure_row, photo_charge, reference, to_csv};
use crate::bench::trade_sensor::settle;
use anyhow::Context;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::render::film::{read_pfm, write_radiance};
use hilcam_core::render::integrator::{Method, QualityGoal, QualityMode, RenderSettings, Spp};
use hilcam_core::scene::limits::checked_scaled_camera;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(clap::Args, Debug)]
pub struct QualityArgs {
    /// Scene file (default: the shipped satellite at its 1024² navigation camera).
    #[arg(long, default_value = "scenes/satellite.toml")]
    pub scene: PathBuf,
    /// Render at this many columns (same field of view; default: the camera's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Frames (seeds) per row, same pose and frame index (≥ 16 for the count).
    #[arg(long, default_value_t = 16)]
    pub seeds: u32,
    /// Rows: `fixed:SPP` (the scene's sampling at SPP, path-traced), `sensor:K:BUDGET`
    /// (`quality = "sensor"`), `hybrid` (the scene's settings, `method = "hybrid"`),
    /// `scene` (the scene's own settings).
    #[arg(long, value_delimiter = ',', default_value = "fixed:1,fixed:4,sensor:0.5:256,scene")]
    pub rows: Vec<String>,
    /// Samples per pixel of each reference chunk (not adaptive).
    #[arg(long, default_value_t = 256)]
    pub reference_spp: u32,
    /// Independent reference chunks (the reference has chunks × spp samples per pixel;
    /// its own variance comes from the chunks' spread).
    #[arg(long, default_value_t = 16)]
    pub reference_chunks: u32,
    /// Where references are kept between runs (keyed by scene, camera, pose and settings).
    #[arg(long, default_value = "target/bench-quality")]
    pub cache: PathBuf,
    /// Output prefix: writes PREFIX.csv, and PREFIX_<row>.png: each lit pixel's RMS error
    /// over the bound (grey 128 at the bound, white at twice it or more).
    #[arg(long, default_value = "quality")]
    pub out: PathBuf,
    /// Also write what was judged, for an outside judge to recount: each row's seed frames'
    /// radiance (`DIR/<row>/seed<NN>.pfm`) and the reference (`DIR/reference.bin`: width
    /// and height u32, spp u64, then each pixel's mean and mean's variance, e⁻ and e⁻², f64;
    /// all little-endian, top row first).
    #[arg(long)]
    pub dump: Option<PathBuf>,
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `hilcam bench charge`: radiance frames through a scene camera's sensor chain to
/// photo-charge, as `bench quality` converts its own.
#[derive(clap::Args, Debug)]
pub struct ChargeArgs {
    /// Scene file: its camera and sensor (and its pose and settings for the exposure).
    #[arg(long, default_value = "scenes/satellite.toml")]
    pub scene: PathBuf,
    /// The camera at this many columns (same field of view), as `bench quality --width`.
    #[arg(long)]
    pub width: Option<u32>,
    /// Integration time, s (default: the auto-exposure settled on the scene's frames, as
    /// `bench quality` settles it).
    #[arg(long)]
    pub integration_s: Option<f64>,
    /// Radiance frames (.pfm) of the camera's size; each is written beside itself as
    /// `<stem>.e64`: photo-charge, e⁻, f64 little-endian, top row first.
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    #[arg(long)]
    pub threads: Option<usize>,
}

/// A row from its `--rows` spelling.
fn parse_row(spec: &str, base: &RenderSettings) -> anyhow::Result<Row> {
    let parts: Vec<&str> = spec.split(':').collect();
    let settings = match parts.as_slice() {
        ["scene"] => *base,
        ["hybrid"] => RenderSettings { method: Method::Hybrid, ..*base },
        ["fixed", spp] => RenderSettings {
            spp: spp.parse::<Spp>().map_err(|e| anyhow::anyhow!("row {spec:?}: {e}"))?,
            quality: QualityGoal { mode: QualityMode::Fixed, ..base.quality },
            method: Method::Path,
            ..*base
        },
        ["sensor", k, budget] => RenderSettings {
            spp: budget.parse::<Spp>().map_err(|e| anyhow::anyhow!("row {spec:?}: {e}"))?,
            quality: QualityGoal {
                mode: QualityMode::Sensor,
                k: QualityGoal::parse_k(k).map_err(|e| anyhow::anyhow!("row {spec:?}: {e}"))?,
            },
            method: Method::Path,
            ..*base
        },
        _ => anyhow::bail!("row {spec:?}: expected fixed:SPP, sensor:K:BUDGET, hybrid or scene"),
    };
    Ok(Row { label: spec.to_string(), settings })
}

pub fn run(a: QualityArgs) -> anyhow::Result<()> {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let scene = hilcam_core::scene::load(&a.scene)?;
    let camera = checked_scaled_camera(&scene.camera, a.width, None).map_err(anyhow::Error::msg)?;
    let (pose, base) = (scene.pose, scene.render);
    let rows = a.rows.iter().map(|r| parse_row(r, &base)).collect::<anyhow::Result<Vec<_>>>()?;
    let key = reference_key(&scene, &camera, &a);
    if let Some(d) = &a.dump {
        std::fs::create_dir_all(d).with_context(|| d.display().to_string())?;
    }
    println!(
        "{}: {}x{}, depth {}; {} seeds per row; {} threads",
        a.scene.display(),
        camera.width,
        camera.height,
        base.depth,
        a.seeds,
        rayon::current_num_threads()
    );
    let (mut pipeline, t) = settled_pipeline(scene, camera.clone())?;
    let conv = Conversion::of(&pipeline, t)
        .context("the judge needs a camera with a detector and DN output (its noise is the yardstick)")?;
    let reference = cached_reference(&a, key, || {
        let total = a.reference_chunks.max(2);
        eprintln!("reference: {total} chunks of {} spp …", a.reference_spp);
        reference(&pipeline, &pose, &base, a.reference_spp, total, &conv, |c| eprintln!("  chunk {} of {total}", c + 1))
            .map_err(anyhow::Error::from)
    })?;
    println!("reference: {} spp per pixel (not adaptive), its own variance from its chunks", reference.spp);
    if let Some(d) = &a.dump {
        let p = d.join("reference.bin");
        write_reference(&p, &reference).with_context(|| p.display().to_string())?;
    }
    println!(
        "bound: σ ≤ {K} × √(signal + dark + read² + gain²/12); floor {:.1} e⁻², quantisation {:.1} e⁻²",
        conv.floor_e2, conv.quant_e2
    );
    print_header();
    let mut results = Vec::new();
    for row in rows {
        let name: String =
            row.label.chars().map(|c| if c.is_ascii_alphanumeric() || c == '.' { c } else { '_' }).collect();
        let dir = a.dump.as_ref().map(|d| d.join(&name));
        if let Some(d) = &dir {
            std::fs::create_dir_all(d).with_context(|| d.display().to_string())?;
        }
        let mut written = Ok(());
        let m = measure_row(&mut pipeline, &pose, &row.settings, a.seeds, 0, t, &reference, &conv, |s, img| {
            if let (Some(d), Ok(())) = (&dir, &written) {
                let p = d.join(format!("seed{s:02}.pfm"));
                written = write_radiance(&p, img, None, false).map(|_| ()).with_context(|| p.display().to_string());
            }
        })?;
        written?;
        print_row(&row, &m.result);
        let png = PathBuf::from(format!("{}_{name}.png", a.out.display()));
        image::GrayImage::from_raw(camera.width, camera.height, m.map)
            .context("error map size")?
            .save(&png)
            .with_context(|| png.display().to_string())?;
        results.push((row, m.result));
    }
    let csv = a.out.with_extension("csv");
    std::fs::write(&csv, to_csv(&results)).with_context(|| csv.display().to_string())?;
    println!("wrote {}", csv.display());
    Ok(())
}

/// The pipeline of `scene` at `width` columns and the integration time `bench quality`
/// holds: the auto-exposure settled on the scene's own frames (printed).
fn settled_pipeline(
    scene: hilcam_core::scene::Scene,
    camera: hilcam_core::render::camera::CameraModel,
) -> anyhow::Result<(FramePipeline, f64)> {
    let (pose, base) = (scene.pose, scene.render);
    let mut pipeline = FramePipeline::new(Arc::new(scene), camera)?;
    let settled = settle(&mut pipeline, &pose, &base, 40, 0.01)?;
    println!(
        "auto-exposure {} after {} frames: integration {:.4} ms, held for every frame",
        if settled.converged { "settled" } else { "NOT settled" },
        settled.frames,
        settled.integration_s * 1e3
    );
    Ok((pipeline, settled.integration_s))
}

/// `hilcam bench charge`: each frame's photo-charge (`bench::quality::photo_charge`, the
/// conversion `bench quality` judges with), and the conversion's constants, printed as
/// `name value` lines with every digit (`integration_s`, `e_per_radiance`, `full_well_e`,
/// `floor_e2`, `quant_e2`, `k`).
pub fn run_charge(a: ChargeArgs) -> anyhow::Result<()> {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let scene = hilcam_core::scene::load(&a.scene)?;
    let camera = checked_scaled_camera(&scene.camera, a.width, None).map_err(anyhow::Error::msg)?;
    let (pipeline, t) = match a.integration_s {
        Some(t) => (FramePipeline::new(Arc::new(scene), camera)?, t),
        None => settled_pipeline(scene, camera)?,
    };
    let conv = Conversion::of(&pipeline, t)
        .context("the conversion needs a camera with a detector and DN output (its noise is the yardstick)")?;
    println!("integration_s {t:?}");
    println!("e_per_radiance {:?}", conv.e_per_radiance);
    println!("full_well_e {:?}", conv.full_well_e);
    println!("floor_e2 {:?}", conv.floor_e2);
    println!("quant_e2 {:?}", conv.quant_e2);
    println!("k {K:?}");
    for f in &a.frames {
        let img = read_pfm(f).with_context(|| f.display().to_string())?;
        let e = photo_charge(&pipeline, &img, &conv).with_context(|| f.display().to_string())?;
        let out = f.with_extension("e64");
        let bytes: Vec<u8> = e.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(&out, bytes).with_context(|| out.display().to_string())?;
    }
    println!("wrote {} photo-charge images (.e64)", a.frames.len());
    Ok(())
}

/// A key of everything the reference depends on: geometry, materials, camera, pose,
/// settings and the reference's size.
fn reference_key(
    scene: &hilcam_core::scene::Scene,
    camera: &hilcam_core::render::camera::CameraModel,
    a: &QualityArgs,
) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for p in &scene.target.mesh.positions {
        p.to_array().map(f32::to_bits).hash(&mut h);
    }
    scene.target.mesh.indices.hash(&mut h);
    scene.target.mesh.material.hash(&mut h);
    format!(
        "{:?}|{:?}|{:?}|{:?}|{:?}",
        scene.target.materials.iter().map(|m| (&m.name, m.bsdf)).collect::<Vec<_>>(),
        camera,
        scene.sensor,
        scene.pose,
        scene.render
    )
    .hash(&mut h);
    (a.reference_spp, a.reference_chunks, scene.target.sun_irradiance.to_bits(), scene.target.background.to_bits())
        .hash(&mut h);
    h.finish()
}

/// The reference from the cache directory, or made by `make` and stored there.
fn cached_reference(
    a: &QualityArgs,
    key: u64,
    make: impl FnOnce() -> anyhow::Result<Reference>,
) -> anyhow::Result<Reference> {
    let path = a.cache.join(format!("reference-clipped-{key:016x}.bin"));
    if let Some(r) = read_reference(&path) {
        println!("reference: reused {}", path.display());
        return Ok(r);
    }
    let r = make()?;
    std::fs::create_dir_all(&a.cache).with_context(|| a.cache.display().to_string())?;
    write_reference(&path, &r).with_context(|| path.display().to_string())?;
    Ok(r)
}

fn write_reference(path: &Path, r: &Reference) -> std::io::Result<()> {
    let mut b = Vec::with_capacity(24 + r.mean_e.len() * 16);
    b.extend_from_slice(&r.width.to_le_bytes());
    b.extend_from_slice(&r.height.to_le_bytes());
    b.extend_from_slice(&r.spp.to_le_bytes());
    for v in r.mean_e.iter().chain(&r.mean_var_e2) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, b)
}

fn read_reference(path: &Path) -> Option<Reference> {
    let b = std::fs::read(path).ok()?;
    let u32_at = |o: usize| Some(u32::from_le_bytes(b.get(o..o + 4)?.try_into().ok()?));
    let (width, height) = (u32_at(0)?, u32_at(4)?);
    let spp = u64::from_le_bytes(b.get(8..16)?.try_into().ok()?);
    let n = width as usize * height as usize;
    if b.len() != 16 + n * 16 {
        return None;
    }
    let f = |i: usize| f64::from_le_bytes(b[16 + i * 8..24 + i * 8].try_into().expect("8 bytes"));
    Some(Reference { width, height, spp, mean_e: (0..n).map(f).collect(), mean_var_e2: (n..2 * n).map(f).collect() })
}

fn print_header() {
    println!(
        "{:<18} {:>7} {:>9} {:>9} {:>9} {:>9} {:>6} {:>8} {:>8} {:>8} {:>8} {:>9} {:>15}",
        "row",
        "spp",
        "render ms",
        "first ms",
        "sensor ms",
        "frame ms",
        "fps",
        "noise %",
        "error %",
        "own %",
        "rms σ/σc",
        "bias %",
        "centroid px"
    );
}

fn print_row(row: &Row, r: &RowResult) {
    let j = &r.judgement;
    println!(
        "{:<18} {:>7.2} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>6.2} {:>8.2} {:>8.2} {:>8} {:>8.2} {:>9.3} {:>15}",
        row.label,
        r.spp,
        r.render_s * 1e3,
        r.first_render_s * 1e3,
        r.sensor_s * 1e3,
        r.frame_s() * 1e3,
        1.0 / r.frame_s(),
        j.noise_share() * 100.0,
        j.error_share() * 100.0,
        r.own_share.map_or("-".into(), |v| format!("{:.2}", v * 100.0)),
        j.rms_error_ratio,
        j.mean_bias * 100.0,
        format!("{:.4} ± {:.4}", j.centroid_shift(), j.centroid_se_px)
    );
}
