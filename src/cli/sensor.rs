//! `hilcam sensor`: apply a camera preset's sensor model to a radiance image (.pfm), or
//! print the preset's photon-transfer table.

use anyhow::{Context, bail};
use hilcam_core::render::film;
use hilcam_core::sensor::{CameraPreset, Sensor, ptc};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SensorArgs {
    /// Camera preset: a TOML file with `[camera]` and `[sensor]` tables.
    #[arg(long)]
    pub camera: PathBuf,
    /// Input radiance image (.pfm, W·sr⁻¹·m⁻², the camera's size).
    pub input: Option<PathBuf>,
    /// Output image; the extension picks the file format (.png, .tif, .exr, .pfm).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the first frame's noise (frame i uses seed + i).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Frames to simulate from the same radiance (auto-exposure settles over frames);
    /// the last one is written.
    #[arg(long, default_value_t = 1)]
    pub frames: u32,
    /// Print the preset's photon-transfer table (flat fields on a 256×256 crop) instead.
    #[arg(long)]
    pub ptc: bool,
}

pub fn run(args: SensorArgs) -> anyhow::Result<()> {
    let preset = CameraPreset::load(&args.camera)?;
    if args.ptc {
        return print_ptc(preset);
    }
    let sensor = Sensor::new(&preset.camera, &preset.sensor).with_context(|| format!("{}", args.camera.display()))?;
    let Some(input) = &args.input else {
        bail!("give an input .pfm radiance image (or --ptc)");
    };
    let img = film::read_pfm(input)?;
    let mut ae = sensor.auto_exposure();
    let mut last = None;
    for i in 0..args.frames.max(1) {
        let seed = args.seed.wrapping_add(i as u64);
        let start = std::time::Instant::now();
        let out = match ae.as_mut() {
            Some(ae) => {
                let (out, upd) = sensor.apply_auto(&img, seed, ae)?;
                println!(
                    "frame {i}: t = {:.6} s, p-ile {:.1} DN (target {:.1}), next t = {:.6} s",
                    upd.previous_s, upd.measured_dn, upd.target_dn, upd.next_s
                );
                out
            }
            None => sensor.apply(&img, seed)?,
        };
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let s = &out.stats;
        println!(
            "frame {i}: {ms:.1} ms, mean {:.1} e⁻ expected, mean DN {:.2}, full well {} px, ADC clipped {} high / {} low",
            s.mean_expected_e, s.mean_dn, s.full_well_pixels, s.adc_high_clipped, s.adc_low_clipped
        );
        last = Some(out);
    }
    if let (Some(path), Some(out)) = (&args.out, last) {
        film::write_pixels(path, img.width, img.height, &out.pixels)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn print_ptc(mut preset: CameraPreset) -> anyhow::Result<()> {
    preset.camera.width = preset.camera.width.min(256);
    preset.camera.height = preset.camera.height.min(256);
    let sensor = Sensor::new(&preset.camera, &preset.sensor)?;
    let (Some(det), Some(k_s)) = (preset.sensor.detector.as_ref(), sensor.electrons_per_radiance_second()) else {
        bail!("--ptc needs a preset with [sensor.detector] and DN output");
    };
    let tau = preset.sensor.optics.transmittance.unwrap_or(1.0);
    // Radiance that fills the well (or 60 000 e⁻ without one).
    let full = det.full_well_e.unwrap_or(60_000.0) / (k_s * det.integration_time_s * tau);
    let fracs = [0.0, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1];
    println!("| radiance W·sr⁻¹·m⁻² | mean DN | temporal variance DN² |");
    println!("|---:|---:|---:|");
    let mut pts = Vec::new();
    for (i, f) in fracs.iter().enumerate() {
        let p = ptc::measure(&sensor, f * full, 1000 + 2 * i as u64)?;
        println!("| {:.4e} | {:.2} | {:.3} |", p.radiance, p.mean_dn, p.var_dn);
        pts.push(p);
    }
    // Fit below 70 % of the well, where the response is linear.
    let fit = ptc::fit(&pts[0], &pts[1..10]);
    println!(
        "\nfit (levels ≤ 70 % full well): gain {:.3} e⁻/DN, dark noise {:.2} e⁻ rms",
        fit.gain_e_per_dn, fit.read_noise_e
    );
    Ok(())
}
