//! A camera that integrates over its exposure: a target moving at a known image-plane
//! speed is smeared by exactly v·t_int (global shutter) and sheared by v·line_time per
//! row (rolling shutter); no time or no motion gives the instant frame's bytes.

use crate::common::scenes::{camera, lambert, scene, square};
use glam::DVec3;
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::{CameraModel, Motion, View};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::Scene;

/// 320 × 240 pixels of 10 µm behind a 20 mm lens: 2000 px per radian.
const FOCAL_PX: f64 = 2000.0;
const RANGE_M: f64 = 10.0;

fn cam() -> CameraModel {
    camera(320, 240, 10.0, 20.0)
}

/// A 1 m Lambert plate facing the camera at 10 m (200 px wide), lit along its normal,
/// direct light only: every pixel it covers has the same radiance.
fn plate(velocity: DVec3, spp: u32) -> (Scene, Pose, RenderSettings) {
    let settings = RenderSettings {
        spp: Spp::whole(spp),
        depth: 1,
        sampler: SamplerKind::Cosine,
        adaptive: false,
        seed: 3,
        ..Default::default()
    };
    let pose = Pose { velocity: Some(velocity), ..Pose::ahead(RANGE_M) };
    let s = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam(), pose, settings);
    (s, pose, settings)
}

fn moving_view(s: &Scene, pose: &Pose, motion: Motion) -> View {
    s.view(&cam(), pose).with_motion(motion, pose, s.frame_origin_body)
}

fn motion(velocity: DVec3, integration_s: f64, line_time_s: f64) -> Motion {
    Motion { velocity, angular_rate: DVec3::ZERO, integration_s, line_time_s }
}

fn bytes(img: &RadianceImage) -> Vec<u8> {
    img.data.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Row `row`'s radiance sum, centroid column (pixel centres) and the columns lit.
fn row_profile(img: &RadianceImage, row: usize) -> (f64, f64, usize) {
    let w = img.width as usize;
    let r = &img.data[row * w..(row + 1) * w];
    let sum: f64 = r.iter().map(|&v| f64::from(v)).sum();
    let moment: f64 = r.iter().enumerate().map(|(c, &v)| (c as f64 + 0.5) * f64::from(v)).sum();
    (sum, moment / sum, r.iter().filter(|&&v| v > 0.0).count())
}

#[test]
fn a_global_exposure_smears_a_moving_target_by_v_t_over_pitch() {
    // 1.3 m/s across, 20 ms: 0.026 m at 10 m = 5.2 px on the image.
    let v = DVec3::new(1.3, 0.0, 0.0);
    let t_int = 0.02;
    let streak_px = v.x * t_int / RANGE_M * FOCAL_PX;
    let (s, pose, settings) = plate(v, 64);
    let still = render(&s, &s.view(&cam(), &pose), &RenderOptions::new(settings, 0)).0;
    let moving = render(&s, &moving_view(&s, &pose, motion(v, t_int, 0.0)), &RenderOptions::new(settings, 0)).0;
    for row in [60, 120, 180] {
        let (sum0, _, lit0) = row_profile(&still, row);
        let (sum1, _, lit1) = row_profile(&moving, row);
        assert_eq!(lit0, 200, "row {row}: the still plate covers 200 columns");
        // The streak adds its length to the lit extent (within the partly covered pixel).
        let extra = lit1 as f64 - lit0 as f64;
        assert!((extra - streak_px).abs() < 1.0, "row {row}: {extra} more columns lit, streak {streak_px} px");
        // Smearing moves light, it neither adds nor loses any.
        assert!((sum1 / sum0 - 1.0).abs() < 2e-3, "row {row}: {sum1} vs {sum0}");
    }
    // The exposure's mean position is half the streak along the motion. One row's
    // centroid carries the edge pixels' sampling noise (±0.05 px at 64 spp; it
    // converges to 2.600 at 4096 spp), so average the plate's rows.
    let rows = 30..210;
    let n = rows.len() as f64;
    let shift = rows.map(|r| row_profile(&moving, r).1 - row_profile(&still, r).1).sum::<f64>() / n;
    assert!((shift - streak_px / 2.0).abs() < 0.02, "centroid moved {shift} px, predicted {}", streak_px / 2.0);
}

#[test]
fn a_rolling_exposure_shears_by_the_line_time() {
    // 2 m/s across: 400 px/s on the image; 100 µs per row: 0.04 px of shear per row.
    let v = DVec3::new(2.0, 0.0, 0.0);
    let line_time = 1e-4;
    let shear = v.x / RANGE_M * FOCAL_PX * line_time;
    let (s, pose, settings) = plate(v, 16);
    let img = render(&s, &moving_view(&s, &pose, motion(v, 1e-3, line_time)), &RenderOptions::new(settings, 0)).0;
    // Least-squares slope of the row centroids over the plate's rows (20..220).
    let rows: Vec<(f64, f64)> = (30..210).map(|r| (r as f64, row_profile(&img, r).1)).collect();
    let n = rows.len() as f64;
    let (mx, my) = (rows.iter().map(|p| p.0).sum::<f64>() / n, rows.iter().map(|p| p.1).sum::<f64>() / n);
    let slope = rows.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / rows.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    assert!((slope - shear).abs() < 0.002, "shear {slope} px/row, predicted {shear}");
    // Row r starts r·line_time later: its centroid is where the plate is then, plus
    // half the integration's smear.
    let row = 150;
    let want = 160.0 + v.x / RANGE_M * FOCAL_PX * (row as f64 * line_time + 0.5e-3);
    let got = row_profile(&img, row).1;
    assert!((got - want).abs() < 0.05, "row {row}: centroid {got}, predicted {want}");
}

#[test]
fn no_time_or_no_motion_is_the_instant_frame() {
    let (s, pose, settings) = plate(DVec3::new(1.0, 0.5, 0.0), 4);
    let options = RenderOptions::new(settings, 5);
    let instant = bytes(&render(&s, &s.view(&cam(), &pose), &options).0);
    let no_time = motion(DVec3::new(1.0, 0.5, 0.0), 0.0, 0.0);
    let still = Motion { velocity: DVec3::ZERO, ..motion(DVec3::ZERO, 0.02, 1e-4) };
    for m in [no_time, still] {
        let view = moving_view(&s, &pose, m);
        assert!(view.motion().is_none(), "{m:?} is one instant");
        assert_eq!(bytes(&render(&s, &view, &options).0), instant, "{m:?}");
    }
    // And a moving frame is not the instant one.
    let moving = moving_view(&s, &pose, motion(DVec3::new(1.0, 0.5, 0.0), 0.02, 0.0));
    assert_ne!(bytes(&render(&s, &moving, &options).0), instant);
}

#[test]
fn a_moving_frame_has_the_same_bytes_whatever_the_thread_count() {
    let v = DVec3::new(0.7, -0.4, 0.3);
    let (s, pose, settings) = plate(v, 2);
    let m = Motion { angular_rate: DVec3::new(0.05, 0.1, 0.8), ..motion(v, 0.03, 2e-5) };
    let view = moving_view(&s, &pose, m);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| bytes(&render(&s, &view, &RenderOptions::new(settings, 2)).0))
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn a_spinning_target_is_the_average_of_its_instants() {
    // A fast spin (0.8 rad over the exposure) about the boresight: the plate's corners
    // sweep arcs well outside the still plate's rectangle. The moving frame must equal
    // the mean of instant frames across the exposure: same light, same pixels lit (a
    // rectangle that missed part of the sweep would lose some).
    let (s, pose, settings) = plate(DVec3::ZERO, 64);
    let m = Motion { angular_rate: DVec3::new(0.0, 0.0, 40.0), ..motion(DVec3::ZERO, 0.02, 0.0) };
    let view = moving_view(&s, &pose, m);
    let moving = render(&s, &view, &RenderOptions::new(settings, 0)).0;
    let steps = 64;
    let mut mean = vec![0.0f64; moving.data.len()];
    let instant_settings = RenderSettings { spp: Spp::whole(4), ..settings };
    for k in 0..steps {
        let dt = 0.02 * (k as f64 + 0.5) / steps as f64;
        let img = render(&s, &view.instant(dt), &RenderOptions::new(instant_settings, k)).0;
        for (m, &v) in mean.iter_mut().zip(&img.data) {
            *m += f64::from(v) / steps as f64;
        }
    }
    let total = |v: &mut dyn Iterator<Item = f64>| v.sum::<f64>();
    let (a, b) = (total(&mut moving.data.iter().map(|&v| f64::from(v))), total(&mut mean.iter().copied()));
    assert!((a / b - 1.0).abs() < 2e-3, "moving frame {a}, mean of instants {b}");
    let lit_moving = moving.data.iter().filter(|&&v| v > 0.0).count();
    let lit_mean = mean.iter().filter(|&&v| v > 0.0).count();
    assert!(lit_moving > 200 * 200 + 2000, "the corners sweep: {lit_moving} lit pixels");
    let diff = lit_moving.abs_diff(lit_mean) as f64 / lit_mean as f64;
    assert!(diff < 0.01, "{lit_moving} lit pixels moving, {lit_mean} in the mean of instants");
    // Per pixel, inside the sweep, the two agree to the noise of the samples.
    let err: f64 = moving.data.iter().zip(&mean).map(|(&x, &y)| (f64::from(x) - y).abs()).sum::<f64>() / b;
    assert!(err < 0.02, "mean absolute difference {err} of the total");
}

/// Issue 37: a line time the frame's u32 `line_time_ns` cannot hold (≥ 4.295 s, or
/// below 1 ns) was reported saturated (or as a global shutter's 0) in frames.jsonl: it
/// is refused, naming the key; the largest it can hold is reported exactly.
#[test]
fn a_line_time_the_frame_cannot_report_is_refused() {
    use hilcam_core::sensor::config::LINE_TIME_US_MAX;
    for v in ["4294968.0", "1e9", "0.0001"] {
        let s = dn_sensor(&format!("exposure = \"rolling\"\nline_time_us = {v}"));
        let e = s.validate(&cam()).expect_err(v).to_string();
        assert!(e.contains("sensor.detector.line_time_us") && e.contains("u32"), "{e}");
    }
    let s = dn_sensor(&format!("exposure = \"rolling\"\nline_time_us = {LINE_TIME_US_MAX}"));
    s.validate(&cam()).expect("the largest reportable line time");
    let (mut plate_scene, pose, settings) = plate(DVec3::ZERO, 1);
    plate_scene.sensor = s;
    let mut pipeline = hilcam_core::pipeline::FramePipeline::new(std::sync::Arc::new(plate_scene), cam()).unwrap();
    let f = pipeline.frame(&pose, &settings, 1).unwrap();
    let meta = hilcam_core::frame::FrameMeta::rendered(1, &pose, &f, Default::default());
    assert_eq!(meta.line_time_ns, u32::MAX, "4294.967295 s, exactly");
}

/// A 12-bit DN camera over the plate; `exposure` is the detector's TOML tail.
fn dn_sensor(exposure: &str) -> hilcam_core::sensor::SensorConfig {
    toml::from_str(&format!(
        "output = \"dn\"\n[band]\nmin_um = 0.45\nmax_um = 0.75\n[optics]\nf_number = 4.0\n\
         [detector]\nqe = 0.5\nintegration_time_s = 1e-3\n{exposure}\n\
         [adc]\nbits = 12\ngain_e_per_dn = 10.0\noffset_dn = 0.0\n"
    ))
    .expect("sensor TOML")
}

#[test]
fn a_frame_says_when_its_rows_integrated() {
    use hilcam_core::frame::{Frame, FrameFlags, FrameMeta, decode_header};
    use hilcam_core::pipeline::FramePipeline;
    let v = DVec3::new(1.0, 0.0, 0.0);
    let cases = [
        ("", 0, false),
        ("exposure = \"global\"", 0, true),
        ("exposure = \"rolling\"\nline_time_us = 12.5", 12_500, true),
    ];
    for (exposure, line_time_ns, integrates) in cases {
        let (mut s, pose, settings) = plate(v, 1);
        let pose = Pose { t_ns: 5_000_000_000, ..pose };
        s.sensor = dn_sensor(exposure);
        let mut pipeline = FramePipeline::new(std::sync::Arc::new(s), cam()).expect("pipeline");
        let f = pipeline.frame(&pose, &settings, 7).expect("frame");
        let meta = FrameMeta::rendered(7, &pose, &f, FrameFlags::default());
        // Over the wire: the header carries the start, duration and line time.
        let frame = Frame::new(meta, f.pixels.clone()).expect("frame").encode();
        let got = decode_header(&frame.bytes).expect("header").meta;
        assert_eq!(got.flags.contains(FrameFlags::EXPOSURE_START), integrates, "{exposure:?}");
        assert_eq!(got.pose_t_ns, 5_000_000_000, "row 0 starts at the pose's time");
        assert_eq!(got.integration_s, 1e-3);
        assert_eq!(got.line_time_ns, line_time_ns, "{exposure:?}");
    }
}

/// The radiance of `s` (`scenes/satellite_blur.toml`: the satellite tumbling at 2 rad/s
/// and drifting at 1.5 m/s) at 128² with the same field of view, at `depth` (uniform
/// sampling, 2 spp), through an exposure of `mode` lasting `integration_s`: the view is
/// built as the frame pipeline builds it (`ExposureTiming::motion`).
fn satellite_blur_radiance(
    s: &Scene,
    mode: hilcam_core::sensor::ExposureMode,
    integration_s: f64,
    depth: u32,
) -> Vec<u8> {
    let cam = crate::common::scenes::scaled_camera(s, 128, 128, [0.0, 0.0]);
    let settings = RenderSettings { spp: Spp::whole(2), depth, adaptive: false, ..s.render };
    let timing = hilcam_core::sensor::ExposureTiming { mode, integration_s, line_time_s: 0.0 };
    let mut view = s.view(&cam, &s.pose).with_distortion(s.sensor.optics.distortion);
    if let Some(m) = timing.motion(&s.pose) {
        view = view.with_motion(m, &s.pose, s.frame_origin_body);
    }
    bytes(&render(s, &view, &RenderOptions::new(settings, 1)).0)
}

/// Issue 42, item 5: `integration_time_s = 0` is accepted, and a zero-length global
/// exposure is the instant frame byte for byte at any depth; a 1e-12 s one (the target
/// moves 1e-11 m) draws the instant frame's random numbers in every bounce, so it is the
/// instant frame too (it differed in 774 of 65 536 pixels at depth 2 when the exposure's
/// time took a dimension of the path's sample stream).
#[test]
fn r42_a_zero_length_exposure_is_the_instant_frame_at_any_depth() {
    use hilcam_core::sensor::ExposureMode::{Global, Instant};
    let path = std::path::Path::new("scenes/satellite_blur.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let zero = text.replace("integration_time_s = 20e-3", "integration_time_s = 0");
    assert_ne!(zero, text);
    let parts = hilcam_core::scene::file::parse(path, &zero)
        .unwrap_or_else(|e| panic!("integration_time_s = 0 is refused: {e}"));
    let s = hilcam_core::scene::Scene::build(parts);
    let det = s.sensor.detector.as_ref().unwrap();
    assert_eq!((det.integration_time_s, det.exposure), (0.0, Global));
    for depth in [1, 2, 3] {
        let instant = satellite_blur_radiance(&s, Instant, 0.02, depth);
        let zero = satellite_blur_radiance(&s, Global, 0.0, depth);
        assert_eq!(zero, instant, "depth {depth}: a zero-length exposure");
        let tiny = satellite_blur_radiance(&s, Global, 1e-12, depth);
        let differ = tiny.chunks(4).zip(instant.chunks(4)).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "depth {depth}: a 1e-12 s exposure differs from the instant frame in {differ} pixels");
        let moving = satellite_blur_radiance(&s, Global, 0.02, depth);
        assert_ne!(moving, instant, "depth {depth}: the 20 ms exposure smears");
    }
}
