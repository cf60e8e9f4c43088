//! The fused sensor pass (optics, PSF, detector, ADC and report over bands of rows, dark
//! pixels on a short path) against the chain applied stage by stage over whole images:
//! the same DN and the same report, bit for bit, for any thread count.

use super::sensor::preset;
use hilcam_core::render::camera::Window;
use hilcam_core::render::film::{Pixels, RadianceImage};
use hilcam_core::sensor::adc::Adc;
use hilcam_core::sensor::config::NoiseMode;
use hilcam_core::sensor::detector::{Detector, FixedPattern};
use hilcam_core::sensor::empty_well::EmptyWell;
use hilcam_core::sensor::stream::{PixelNoise, PixelStream, frame_key};
use hilcam_core::sensor::{CameraPreset, McNoiseStats, Sensor, noise, ziggurat};

const T: f64 = 50e-6;
const K: f64 = 0.5;

/// A preset at `w × h` with its field of view kept.
fn scaled(name: &str, w: u32, h: u32) -> CameraPreset {
    let mut p: CameraPreset = toml::from_str(&std::fs::read_to_string(preset(name)).unwrap()).unwrap();
    p.camera.focal_mm *= f64::from(w) / f64::from(p.camera.width);
    (p.camera.width, p.camera.height) = (w, h);
    p
}

/// Blobs of light (one on the left border, one in the bottom-right corner, one in the
/// middle with exact zeros and a −0 inside) on black; the variance follows the light,
/// plus a few pixels with variance and no light.
fn frame(w: u32, h: u32) -> (RadianceImage, Vec<f32>) {
    let mut img = RadianceImage::new(w, h, 0.0);
    let mut var = vec![0.0f32; img.data.len()];
    let (wf, hf) = (f64::from(w), f64::from(h));
    for (i, (l, v)) in img.data.iter_mut().zip(&mut var).enumerate() {
        let (c, r) = ((i % w as usize) as f64, (i / w as usize) as f64);
        let d = |x: f64, y: f64| ((c - x).powi(2) + (r - y).powi(2)).sqrt();
        let lit = d(wf * 0.5, hf * 0.45) < hf * 0.3 || d(0.0, hf * 0.3) < 6.0 || d(wf, hf) < 9.0;
        if lit && i % 37 != 0 {
            *l = (0.05 + 0.75 * ((i as f64 * 0.61).sin() * 0.5 + 0.5)) as f32;
            *v = *l * *l * 0.02;
        }
        if i % 53 == 0 && !lit {
            *v = 1e-4;
        }
    }
    img.data[(h / 2 * w + w / 2) as usize] = -0.0;
    (img, var)
}

/// The chain stage by stage: whole-image optics, then every pixel on its own — a pixel
/// without light (and nothing to substitute) by the dark path's definition: the count
/// from the low 32 bits of its shot stream's first draw, an empty well read from the
/// table with the high 32 bits.
fn stage_by_stage(sensor: &Sensor, img: &RadianceImage, var: Option<&[f32]>, seed: u64) -> Vec<u16> {
    let cfg = sensor.config();
    let dc = cfg.detector.as_ref().unwrap();
    let full = sensor.camera();
    let fp = (dc.prnu.unwrap_or(0.0) > 0.0 || dc.dsnu_e_per_s.unwrap_or(0.0) > 0.0)
        .then(|| FixedPattern::new(dc.fpn_seed, (full.width * full.height) as usize));
    let d = Detector::new(dc, sensor.electrons_per_radiance_second().unwrap(), T, fp);
    let adc = Adc::new(cfg.adc.as_ref().unwrap());
    let well = EmptyWell::new(dc.read_noise_e.unwrap_or(0.0), &adc).unwrap();
    let rad = sensor.optics(img).unwrap().data;
    let v = var.map(|v| sensor.optics_variance(v).unwrap());
    let win = sensor.window();
    (0..rad.len())
        .map(|i| {
            let (c, r) = (i as u32 % win.width, i as u32 / win.width);
            let p = u64::from(r + win.y) * u64::from(full.width) + u64::from(c + win.x);
            let mut noise = PixelNoise::new(frame_key(seed), p);
            let (photo, dark) = d.expected_parts(rad[i] as f64, p);
            let v_e = v.as_ref().map_or(0.0, |v| v[i] as f64 * d.photo_gain(p).powi(2));
            let substitute = dc.noise == NoiseMode::Substitute && v.as_ref().is_some_and(|v| v[i] > 0.0);
            if rad[i] <= 0.0 && !substitute && dc.shot_noise {
                let mut shot = PixelStream::new(frame_key(seed), p, 0);
                let h = shot.next_u64();
                let k = match dark {
                    l if l <= 0.0 => 0.0,
                    l if l < noise::POISSON_EXACT_BELOW => {
                        noise::poisson_inversion(l, (h as u32 as f64 + 0.5) / 4_294_967_296.0)
                    }
                    l => noise::poisson_normal(l, ziggurat::normal(&mut shot)),
                };
                let code = if k == 0.0 {
                    well.draw((h >> 32) as u32)
                } else {
                    adc.convert(d.clip_and_read(dark, k, &mut noise).read_e)
                };
                return code.dn() as u16;
            }
            let charge = if dc.noise == NoiseMode::Substitute && v_e > 0.0 {
                d.sample_substituted(photo + dark, v_e, &mut noise)
            } else {
                d.sample(photo + dark, &mut noise)
            };
            adc.convert(charge.read_e).dn() as u16
        })
        .collect()
}

fn dn(px: &Pixels) -> &[u16] {
    match px {
        Pixels::Mono16 { data, .. } => data,
        other => panic!("16-bit DN expected, got {:?}", other.format()),
    }
}

/// The fused frame on `threads` threads: pixels and report.
fn fused(
    sensor: &Sensor,
    img: &RadianceImage,
    var: Option<&[f32]>,
    seed: u64,
    threads: usize,
) -> (Vec<u16>, Option<McNoiseStats>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| sensor.apply_with_variance(img, var, seed, T, K).unwrap());
    (dn(&out.pixels).to_vec(), out.stats.mc)
}

fn check(what: &str, sensor: &Sensor, img: &RadianceImage, var: Option<&[f32]>) {
    let want = stage_by_stage(sensor, img, var, 9);
    let (got, mc) = fused(sensor, img, var, 9, 1);
    let differ = want.iter().zip(&got).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{what}: {differ} of {} pixels differ", want.len());
    let want_mc = var.map(|v| sensor.mc_noise_stats(img, v, T, K).unwrap().unwrap());
    assert_eq!(mc, want_mc, "{what}: report");
    assert!(want_mc.is_none_or(|m| m.lit_pixels > 100), "{what}: a lit frame");
    assert_eq!(fused(sensor, img, var, 9, 3), (got, mc), "{what}: 3 threads");
}

#[test]
fn the_fused_pass_is_the_chain_stage_by_stage() {
    let (w, h) = (150, 100);
    let (img, var) = frame(w, h);
    let mut p = scaled("nav1024.toml", w, h);
    let nav = Sensor::new(&p.camera, &p.sensor).unwrap();
    check("Gaussian PSF, add", &nav, &img, Some(&var));
    check("Gaussian PSF, no variance", &nav, &img, None);
    let win = Window { x: 20, y: 10, width: 100, height: 70 };
    let crop = |v: &[f32]| -> Vec<f32> {
        (0..win.height)
            .flat_map(|r| (0..win.width).map(move |c| ((r + win.y) * w + c + win.x) as usize))
            .map(|i| v[i])
            .collect()
    };
    let img_w = RadianceImage { width: win.width, height: win.height, data: crop(&img.data) };
    check("Gaussian PSF, a window", &nav.windowed(win), &img_w, Some(&crop(&var)));

    p.sensor.detector.as_mut().unwrap().noise = NoiseMode::Substitute;
    let sub = Sensor::new(&p.camera, &p.sensor).unwrap();
    check("Gaussian PSF, substitute", &sub, &img, Some(&var));
    check("Gaussian PSF, substitute, a window", &sub.windowed(win), &img_w, Some(&crop(&var)));
    let o = &mut p.sensor.optics;
    (o.psf, o.cos4, o.transmittance) = (None, false, None);
    check("no optics, substitute", &Sensor::new(&p.camera, &p.sensor).unwrap(), &img, Some(&var));
    p.sensor.optics.cos4 = true;
    check("cos⁴ only, substitute", &Sensor::new(&p.camera, &p.sensor).unwrap(), &img, Some(&var));

    let airy = scaled("nav2048.toml", w, h);
    check("Airy PSF", &Sensor::new(&airy.camera, &airy.sensor).unwrap(), &img, Some(&var));
}

/// Lit pixels from a few electrons to twice the full well, through an ADC that clips at
/// both ends: every branch of the lit pixels' block path and of the pixels it hands back.
#[test]
fn the_lit_pixels_block_path_is_the_chain_at_every_level() {
    let (w, h) = (150, 100);
    let (mut img, mut var) = frame(w, h);
    for (i, (l, v)) in img.data.iter_mut().zip(&mut var).enumerate() {
        // From about 1 e⁻ to 2 full wells (at 50 µs, 11 000 e⁻ ≈ 47 W·sr⁻¹·m⁻²).
        let f = 10f32.powf(((i * 7919) % 1000) as f32 / 1000.0 * 5.0 - 2.0);
        (*l, *v) = (*l * f, *v * f * f);
    }
    let mut p = scaled("nav1024.toml", w, h);
    let adc = p.sensor.adc.as_mut().unwrap();
    (adc.gain_e_per_dn, adc.offset_dn) = (8.0, 0.5);
    let nav = Sensor::new(&p.camera, &p.sensor).unwrap();
    let (got, _) = fused(&nav, &img, Some(&var), 9, 1);
    let (zero, max) = (got.iter().filter(|&&d| d == 0).count(), got.iter().filter(|&&d| d == 1023).count());
    assert!(zero > 100 && max > 100, "{zero} pixels at 0, {max} at 1023");
    check("bright, clipping", &nav, &img, Some(&var));
    check("bright, clipping, no variance", &nav, &img, None);
    p.sensor.detector.as_mut().unwrap().noise = NoiseMode::Substitute;
    check("bright, clipping, substitute", &Sensor::new(&p.camera, &p.sensor).unwrap(), &img, Some(&var));
    p.sensor.detector.as_mut().unwrap().full_well_e = None;
    check("bright, no full well", &Sensor::new(&p.camera, &p.sensor).unwrap(), &img, Some(&var));
}
