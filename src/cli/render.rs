//! `hilcam render`: one frame of a scene file to an image file.

use super::parse_sensor_k;
use anyhow::{Context, bail};
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Pose;
use hilcam_core::pose::validate::PoseLimits;
use hilcam_core::render::PrimaryVisibility;
use hilcam_core::render::camera::Window;
use hilcam_core::render::film::write_radiance;
use hilcam_core::render::integrator::{QualityMode, SamplerKind, Spp};
use hilcam_core::render::sampling::Sequence;
use hilcam_core::scene::file::parse_name;
use hilcam_core::scene::limits::checked_scaled_camera;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output image: .exr/.pfm hold float radiance (W·sr⁻¹·m⁻²); .png/.tif a scaled preview.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Samples per pixel, ≥ 1 (default: the scene's); a fraction such as 1.25 gives
    /// every pixel one sample and shares the rest out where the pilot saw variance
    #[arg(long)]
    pub spp: Option<Spp>,
    /// Surface interactions per path (1 = direct sunlight only).
    #[arg(long)]
    pub depth: Option<u32>,
    #[arg(long, value_parser = parse_name::<SamplerKind>)]
    pub sampler: Option<SamplerKind>,
    /// Random-number sequence: sobol (stratified, default) or independent.
    #[arg(long, value_parser = parse_name::<Sequence>)]
    pub sequence: Option<Sequence>,
    /// `sensor`: give each pixel samples until its Monte Carlo noise is below `--sensor-k`
    /// × the camera's own temporal noise there, `--spp` being the frame's budget (average
    /// per sampled pixel); `fixed`: `--spp` samples (default: the scene's).
    #[arg(long, value_parser = parse_name::<QualityMode>)]
    pub quality: Option<QualityMode>,
    /// The Monte Carlo noise bound as a fraction of the camera's temporal noise, in (0, 10]
    /// (default: the scene's `render.sensor_k`, 0.5); every frame's noise report uses it.
    #[arg(long, value_parser = parse_sensor_k)]
    pub sensor_k: Option<f32>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// Disable Russian roulette (every path runs to full depth).
    #[arg(long)]
    pub no_roulette: bool,
    /// Give every pixel exactly `--spp` samples instead of sharing them out by the
    /// variance a pilot pass sees around each pixel (`spp` is then the average); a
    /// fraction is spread evenly (⌊spp⌋ or ⌊spp⌋ + 1 samples, at random).
    #[arg(long)]
    pub no_adaptive: bool,
    /// Also write a PNG heat map of the camera samples each pixel got (black: none; the
    /// brightest: the most), to see where adaptive sampling spent the budget.
    #[arg(long, conflicts_with = "sensor")]
    pub samples_map: Option<std::path::PathBuf>,
    /// Frame index (part of every random number's key).
    #[arg(long, default_value_t = 0)]
    pub frame: u64,
    /// Camera: a built-in preset (nav1024, nav2048, paper: the files of config/cameras/) or
    /// a camera TOML file; replaces the scene's camera and sensor.
    #[arg(long)]
    pub camera: Option<String>,
    /// Render a scaled preview this many columns wide (same field of view).
    #[arg(long)]
    pub width: Option<u32>,
    /// Rows of the scaled preview (default: keeps the aspect ratio).
    #[arg(long)]
    pub height: Option<u32>,
    /// Pose override: `px,py,pz` or `px,py,pz,qw,qx,qy,qz` or those plus `,sx,sy,sz`
    /// (camera frame; metres; quaternion body→camera, scalar first; sun direction).
    #[arg(long, allow_hyphen_values = true)]
    pub pose: Option<String>,
    /// Move the scene's `[planet]` to this centre for the frame: `x,y,z` (camera frame,
    /// metres), as a trajectory's `plx,ply,plz` or a serial pose's planet block do.
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub planet: Option<String>,
    /// Write 16-bit PNG previews instead of 8-bit.
    #[arg(long)]
    pub png16: bool,
    /// Apply the camera's sensor model (`[sensor]`): write what the camera would send
    /// (digital numbers, or radiance after the optics) instead of entrance-pupil radiance.
    #[arg(long)]
    pub sensor: bool,
    /// With `--sensor`: render only this region of the sensor, `X,Y,WIDTH,HEIGHT` in
    /// pixels of the (scaled) camera, as a GigE Vision client's ROI does. Its pixels are
    /// the full frame's there (with uniform sampling, byte for byte).
    #[arg(long, requires = "sensor", value_parser = parse_roi)]
    pub roi: Option<Window>,
    /// How primary hits are found: auto (default: traced in packets of eight on the 8-wide
    /// tree with AVX2, else rasterised when that pays, ≥ 2 camera samples per triangle),
    /// raster (whenever exact), trace (every primary ray through the BVH). The same image
    /// with uniform sampling; adaptive frames may differ slightly (each way skips the
    /// pixels that cannot see the target by its own rule, and the budget is spp × sampled
    /// pixels).
    #[arg(long, value_parser = parse_name::<PrimaryVisibility>, default_value = "auto")]
    pub primary: PrimaryVisibility,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Render the frame this many times through the same warm buffers (as a running server
    /// does) and report the median time (and the fastest); the image is the last one,
    /// identical to the others.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Untimed frames rendered first through the same buffers, so that the timed ones run
    /// warm, as every frame of a running server or replay does (`bench-vs-mitsuba.sh`
    /// passes 1: Mitsuba too is timed after a warm-up render). Not with `--samples-map`.
    #[arg(long, default_value_t = 0)]
    pub warm_up: u32,
}

pub fn run(a: RenderArgs) -> anyhow::Result<()> {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let scene = hilcam_core::scene::load(&a.scene)?;
    let mut settings = scene.render.overridden(a.spp, a.depth, a.sampler, a.seed).with_quality(a.quality, a.sensor_k);
    if let Some(v) = a.sequence {
        settings.sequence = v;
    }
    if a.no_roulette {
        settings.roulette = false;
    }
    if a.no_adaptive {
        settings.adaptive = false;
    }
    let (base_camera, sensor_config) = match &a.camera {
        Some(c) => {
            let preset =
                hilcam_core::scene::file::camera_by_name_or_file(c).map_err(|m| anyhow::anyhow!("--camera: {m}"))?;
            (preset.camera, preset.sensor)
        }
        None => (scene.camera.clone(), scene.sensor.clone()),
    };
    let camera = checked_scaled_camera(&base_camera, a.width, a.height).map_err(anyhow::Error::msg)?;
    if let Some(r) = a.roi {
        r.inside(&camera).map_err(|e| anyhow::anyhow!("--roi: {e}"))?;
    }
    let mut pose = match &a.pose {
        Some(s) => parse_pose(s, &scene.pose, &scene.pose_limits()).context("--pose")?,
        None => scene.pose,
    };
    if let Some(s) = &a.planet {
        pose = with_planet(pose, s, &scene.pose_limits()).context("--planet")?;
    }
    let scene = std::sync::Arc::new(scene);
    let mut pipeline =
        FramePipeline::with_sensor(scene.clone(), camera.clone(), &sensor_config)?.with_primary(a.primary);
    // Warm-up through the renderer's buffers only: a sensor frame would also move the
    // auto-exposure state, and the samples map renders apart from the pipeline.
    if a.samples_map.is_none() {
        for _ in 0..a.warm_up {
            pipeline.radiance_warm(&pose, &settings, a.frame);
        }
    }
    let (info, stats) = if a.sensor {
        let request = FrameRequest { roi: a.roi, ..FrameRequest::default() };
        let mut times = Vec::new();
        for _ in 1..a.repeat {
            times.push(pipeline.frame_requested(&pose, &settings, a.frame, &request)?.render.time);
        }
        let mut f = pipeline.frame_requested(&pose, &settings, a.frame, &request)?;
        times.push(f.render.time);
        if a.repeat > 1 {
            f.render.time = print_median(&mut times);
        }
        hilcam_core::render::film::write_pixels(&a.out, f.width, f.height, &f.pixels)?;
        println!(
            "sensor: {:?}, {:.1} ms{}",
            f.pixels.format(),
            f.sensor_time.as_secs_f64() * 1e3,
            f.integration_s.map(|t| format!(", integration {:.3} ms", t * 1e3)).unwrap_or_default()
        );
        if let Some(mc) = &f.mc_noise {
            print_mc_noise(mc, &f.render);
        }
        (hilcam_core::render::film::WriteInfo { preview_scale: None }, f.render)
    } else if let Some(map) = &a.samples_map {
        let view = scene.view(&camera, &pose).with_distortion(sensor_config.optics.distortion);
        let mut buffers = hilcam_core::render::FrameBuffers::<()>::default();
        let options = hilcam_core::render::RenderOptions::new(settings, a.frame);
        let stats = hilcam_core::render::render_into(&mut buffers, &scene, &view, &options);
        let (counts, img) = (buffers.sample_counts(), buffers.take_image());
        let most = write_samples_map(map, camera.width, camera.height, &counts)?;
        println!("{}: samples per pixel, {most} at the brightest", map.display());
        (write_radiance(&a.out, &img, None, a.png16)?, stats)
    } else {
        let mut times = Vec::new();
        for _ in 1..a.repeat {
            times.push(pipeline.radiance_warm(&pose, &settings, a.frame).1.time);
        }
        let (img, mut stats) = pipeline.radiance_warm(&pose, &settings, a.frame);
        times.push(stats.time);
        if a.repeat > 1 {
            stats.time = print_median(&mut times);
        }
        (write_radiance(&a.out, img, None, a.png16)?, stats)
    };
    let (width, height) = a.roi.map_or((camera.width, camera.height), |r| (r.width, r.height));
    let covered = stats.traced_pixels as f64 / (f64::from(width) * f64::from(height)) * 100.0;
    print!(
        "{}: {}x{} spp {}{} depth {} {:?}: {:.3} s, {} rays ({:.2} Mrays/s), traced {:.1} % of pixels, BVH {} triangles built in {:.0} ms",
        a.out.display(),
        width,
        height,
        settings.spp,
        // The renderer's own plan says whether spp is an average, and whether adaptive.
        match hilcam_core::render::adaptive::Adaptive::new(settings.spp, settings.adaptive) {
            _ if settings.quality.is_sensor() => " (sensor-relative budget, average)",
            Some(plan) if !plan.uniform => " (adaptive, average)",
            Some(_) => " (average)",
            None => "",
        },
        settings.depth,
        settings.sampler,
        stats.time.as_secs_f64(),
        stats.rays.total(),
        stats.mrays_per_s(),
        covered,
        scene.mesh.indices.len(),
        scene.accel.build_time.as_secs_f64() * 1e3,
    );
    match info.preview_scale {
        Some(s) => println!(", preview white = {s:.4e} W·sr⁻¹·m⁻²"),
        None => println!(),
    }
    if stats.rays.nonfinite > 0 {
        println!("warning: {} non-finite samples dropped", stats.rays.nonfinite);
    }
    Ok(())
}

/// The frame's Monte Carlo noise against the camera's (`quality = "sensor"` samples to
/// keep it below k × the camera's; every DN frame reports it).
fn print_mc_noise(mc: &hilcam_core::sensor::McNoiseStats, render: &hilcam_core::render::RenderStats) {
    let spent = render.samples as f64 / render.traced_pixels.max(1) as f64;
    println!(
        "Monte Carlo noise: {} of {} lit pixels ({:.2} %) above {} × the camera's temporal noise; \
         σ_mc/σ_cam mean {:.3}, rms {:.3}; {spent:.2} samples per traced pixel",
        mc.above_bound,
        mc.lit_pixels,
        100.0 * mc.above_fraction,
        mc.k,
        mc.mean_ratio,
        mc.rms_ratio,
    );
}

/// Write per-pixel sample counts as an 8-bit heat map (black → red → yellow → white,
/// linear up to the largest count); returns that count.
fn write_samples_map(path: &std::path::Path, width: u32, height: u32, counts: &[u32]) -> anyhow::Result<u32> {
    let most = counts.iter().copied().max().unwrap_or(0).max(1);
    let mut img = image::RgbImage::new(width, height);
    for (px, &n) in img.pixels_mut().zip(counts) {
        let t = n as f32 / most as f32 * 3.0;
        let ramp = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
        *px = image::Rgb([ramp(t), ramp(t - 1.0), ramp(t - 2.0)]);
    }
    img.save(path).with_context(|| format!("writing {}", path.display()))?;
    Ok(most)
}

/// `px,py,pz[,qw,qx,qy,qz[,sx,sy,sz]]`; missing parts come from `base`. The result goes
/// through the pose gate ([`hilcam_core::scene::limits::gate_pose`]) as a scene's `[pose]` does.
/// Print the median, fastest and slowest of the render `times` (sorted here); the median.
fn print_median(times: &mut [std::time::Duration]) -> std::time::Duration {
    times.sort();
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let median = times[times.len() / 2];
    println!(
        "{} renders: median {:.1} ms, fastest {:.1} ms, slowest {:.1} ms",
        times.len(),
        ms(median),
        ms(times[0]),
        ms(times[times.len() - 1])
    );
    median
}

/// `X,Y,WIDTH,HEIGHT`.
fn parse_roi(s: &str) -> Result<Window, String> {
    let v: Vec<u32> =
        s.split(',').map(|x| x.trim().parse::<u32>().map_err(|e| format!("{x:?}: {e}"))).collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, width, height] => Ok(Window { x, y, width, height }),
        _ => Err(format!("expected X,Y,WIDTH,HEIGHT (4 numbers), got {}", v.len())),
    }
}

pub fn parse_pose(s: &str, base: &Pose, limits: &PoseLimits) -> anyhow::Result<Pose> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().with_context(|| format!("`{t}` is not a number")))
        .collect::<Result<_, _>>()?;
    if !matches!(v.len(), 3 | 7 | 10) {
        bail!("expected 3, 7 or 10 comma-separated numbers, got {}", v.len());
    }
    let attitude = (v.len() >= 7).then(|| [v[3], v[4], v[5], v[6]]);
    let sun = (v.len() == 10).then(|| [v[7], v[8], v[9]]);
    hilcam_core::scene::limits::pose_from_numbers(limits, base, [v[0], v[1], v[2]], attitude, sun)
        .map_err(anyhow::Error::msg)
}

/// `pose` with the planet's centre `x,y,z`, through the scene's pose gate (refused: no
/// `[planet]`, the camera inside it, beyond 100 AU).
fn with_planet(pose: Pose, s: &str, limits: &PoseLimits) -> anyhow::Result<Pose> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().with_context(|| format!("`{t}` is not a number")))
        .collect::<Result<_, _>>()?;
    let [x, y, z] = v[..] else { bail!("expected 3 comma-separated numbers, got {}", v.len()) };
    let p = Pose { planet_centre: Some(glam::DVec3::new(x, y, z)), ..pose };
    hilcam_core::scene::limits::gate_pose(&p, limits).map_err(|e| anyhow::anyhow!("{}: {}", e.field, e.message))
}
