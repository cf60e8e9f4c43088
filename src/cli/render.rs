//! `hilcam render`: one frame of a scene file to an image file.

use crate::camera::CameraModel;
use crate::film::write_radiance;
use crate::integrator::{SamplerKind, Spp};
use crate::pipeline::FramePipeline;
use crate::pose::Pose;
use anyhow::{Context, bail};
use glam::{DQuat, DVec3};
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
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerKind>,
    /// Random-number sequence: sobol (stratified, default) or independent.
    #[arg(long, value_enum)]
    pub sequence: Option<crate::sampling::Sequence>,
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
    /// Write 16-bit PNG previews instead of 8-bit.
    #[arg(long)]
    pub png16: bool,
    /// Apply the camera's sensor model (`[sensor]`): write what the camera would send
    /// (digital numbers, or radiance after the optics) instead of entrance-pupil radiance.
    #[arg(long)]
    pub sensor: bool,
    /// How primary hits are found: auto (default: traced in packets of eight on the 8-wide
    /// tree with AVX2, else rasterised when that pays, ≥ 2 camera samples per triangle),
    /// raster (whenever exact), trace (every primary ray through the BVH). The same image
    /// with uniform sampling; adaptive frames may differ slightly (each way skips the
    /// pixels that cannot see the target by its own rule, and the budget is spp × sampled
    /// pixels).
    #[arg(long, value_enum, default_value = "auto")]
    pub primary: crate::render::PrimaryVisibility,
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
    let scene = crate::scene::load(&a.scene)?;
    let mut settings = scene.render.overridden(a.spp, a.depth, a.sampler, a.seed);
    if let Some(v) = a.sequence {
        settings.sequence = v;
    }
    if a.no_roulette {
        settings.roulette = false;
    }
    if a.no_adaptive {
        settings.adaptive = false;
    }
    let camera = checked_scaled_camera(&scene.camera, a.width, a.height)?;
    let pose = match &a.pose {
        Some(s) => parse_pose(s, &scene.pose).context("--pose")?,
        None => scene.pose,
    };
    let scene = std::sync::Arc::new(scene);
    let mut pipeline = FramePipeline::new(scene.clone(), camera.clone())?.with_primary(a.primary);
    // Warm-up through the renderer's buffers only: a sensor frame would also move the
    // auto-exposure state, and the samples map renders apart from the pipeline.
    if a.samples_map.is_none() {
        for _ in 0..a.warm_up {
            pipeline.radiance_warm(&pose, &settings, a.frame);
        }
    }
    let (info, stats) = if a.sensor {
        let f = pipeline.frame(&pose, &settings, a.frame)?;
        crate::film::write_pixels(&a.out, f.width, f.height, &f.pixels)?;
        println!(
            "sensor: {:?}, {:.1} ms{}",
            f.pixels.format(),
            f.sensor_time.as_secs_f64() * 1e3,
            f.integration_s.map(|t| format!(", integration {:.3} ms", t * 1e3)).unwrap_or_default()
        );
        (crate::film::WriteInfo { preview_scale: None }, f.render)
    } else if let Some(map) = &a.samples_map {
        let view = crate::camera::View::new(&camera, &pose, scene.frame_origin_body, scene.bounds)
            .with_distortion(scene.sensor.optics.distortion);
        let (img, stats, counts) = crate::render::render_view_counted(&scene, &camera, &view, &settings, a.frame);
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
            times.sort();
            stats.time = times[times.len() / 2];
            println!(
                "{} renders: median {:.1} ms, fastest {:.1} ms, slowest {:.1} ms",
                a.repeat,
                stats.time.as_secs_f64() * 1e3,
                times[0].as_secs_f64() * 1e3,
                times[times.len() - 1].as_secs_f64() * 1e3
            );
        }
        (write_radiance(&a.out, img, None, a.png16)?, stats)
    };
    let covered = stats.traced_pixels as f64 / (f64::from(camera.width) * f64::from(camera.height)) * 100.0;
    print!(
        "{}: {}x{} spp {}{} depth {} {:?}: {:.3} s, {} rays ({:.2} Mrays/s), traced {:.1} % of pixels, BVH {} triangles built in {:.0} ms",
        a.out.display(),
        camera.width,
        camera.height,
        settings.spp,
        // The renderer's own plan says whether spp is an average, and whether adaptive.
        match crate::render::adaptive::Adaptive::new(settings.spp, settings.adaptive) {
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

/// [`scaled_camera`] for sizes given on the command line: `--width`/`--height` and the
/// size they imply must lie in `1..=MAX_SIDE_PX`; the error names the flag and the limit.
pub fn checked_scaled_camera(c: &CameraModel, width: Option<u32>, height: Option<u32>) -> anyhow::Result<CameraModel> {
    for (flag, v) in [("--width", width), ("--height", height)] {
        if let Some(v) = v {
            crate::camera::check_side(v).map_err(|m| anyhow::anyhow!("{flag}: {m}"))?;
        }
    }
    let scaled = scaled_camera(c, width, height);
    scaled.check_size().map_err(|(field, m)| anyhow::anyhow!("--width/--height: the scaled camera's {field} {m}"))?;
    crate::scene::file::validate_camera(&scaled)
        .map_err(|(field, m)| anyhow::anyhow!("--width/--height: the scaled camera's {field} {m}"))?;
    Ok(scaled)
}

/// The same camera at another resolution, with the same field of view.
pub fn scaled_camera(c: &CameraModel, width: Option<u32>, height: Option<u32>) -> CameraModel {
    let Some(w) = width.or(height.map(|h| (f64::from(h) * f64::from(c.width) / f64::from(c.height)).round() as u32))
    else {
        return c.clone();
    };
    let k = f64::from(c.width) / f64::from(w);
    let h = height.unwrap_or_else(|| ((f64::from(c.height) / k).round() as u32).max(1));
    CameraModel {
        width: w.max(1),
        height: h,
        pitch_um: c.pitch_um * k,
        focal_mm: c.focal_mm,
        principal_point_px: c.principal_point_px.map(|v| v / k),
    }
}

/// `px,py,pz[,qw,qx,qy,qz[,sx,sy,sz]]`; missing parts come from `base`. The result goes
/// through the pose gate ([`crate::scene::limits::gate_pose`]) as a scene's `[pose]` does.
pub fn parse_pose(s: &str, base: &Pose) -> anyhow::Result<Pose> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().with_context(|| format!("`{t}` is not a number")))
        .collect::<Result<_, _>>()?;
    if !matches!(v.len(), 3 | 7 | 10) {
        bail!("expected 3, 7 or 10 comma-separated numbers, got {}", v.len());
    }
    let mut p = *base;
    p.position = DVec3::new(v[0], v[1], v[2]);
    if v.len() >= 7 {
        p.attitude = DQuat::from_xyzw(v[4], v[5], v[6], v[3]);
    }
    if v.len() == 10 {
        p.sun_dir = DVec3::new(v[7], v[8], v[9]);
    }
    crate::scene::limits::gate_pose(&p).map_err(|e| anyhow::anyhow!("{}: {}", e.field, e.message))
}
