//! A camera client's ROI renders only its pixels, and they are the full frame's pixels:
//! the same primary rays, random numbers, cos⁴ factor, PSF, fixed pattern and noise per
//! sensor pixel (`render::camera::window`, `FramePipeline::frame_requested`). Adaptive
//! sampling spreads its budget over the pixels it renders, so there an ROI is the same
//! picture, not the same bytes.

use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::render::camera::Window;
use hilcam_core::render::film::Pixels;
use hilcam_core::render::integrator::RenderSettings;
use std::path::Path;
use std::sync::Arc;

/// The satellite through the shipped nav1024 camera (Brown–Conrady lens, Gaussian PSF,
/// cos⁴, PRNU/DSNU, shot and read noise, 10-bit ADC), at 160 × 160 pixels.
fn pipeline(principal_point_px: [f64; 2]) -> FramePipeline {
    let mut scene = hilcam_core::scene::load(Path::new("scenes/satellite.toml")).unwrap();
    scene.camera = scene.camera.scaled(Some(160), None);
    scene.camera.principal_point_px = principal_point_px;
    assert!(scene.sensor.optics.psf.is_some() && scene.sensor.optics.cos4 && scene.sensor.detector.is_some());
    let scene = Arc::new(scene);
    FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap()
}

fn u16s(p: &Pixels) -> &[u16] {
    match p {
        Pixels::Mono16 { data, .. } => data,
        other => panic!("expected Mono16 DN, got {:?}", other.format()),
    }
}

#[test]
fn with_uniform_sampling_an_roi_is_the_full_frame_there_byte_for_byte_and_renders_fewer_pixels() {
    for pp in [[0.0, 0.0], [3.25, -7.5]] {
        let mut full_pipe = pipeline(pp);
        let scene = full_pipe.scene().clone();
        let settings = RenderSettings { adaptive: false, ..scene.render };
        let exposure = FrameRequest { integration_s: Some(40e-6), roi: None };
        let full = full_pipe.frame_requested(&scene.pose, &settings, 3, &exposure).unwrap();
        assert!(u16s(&full.pixels).iter().any(|&v| v > 200), "the target is in view");
        // Inside, on the sensor's edges (where the PSF reflects), one pixel, the whole array.
        for roi in [
            Window { x: 40, y: 52, width: 64, height: 48 },
            Window { x: 0, y: 0, width: 33, height: 17 },
            Window { x: 101, y: 130, width: 59, height: 30 },
            Window { x: 80, y: 80, width: 1, height: 1 },
            Window { x: 0, y: 0, width: 160, height: 160 },
        ] {
            // A fresh pipeline per ROI: nothing carried over from the full frame.
            let mut p = pipeline(pp);
            let request = FrameRequest { roi: Some(roi), ..exposure };
            let f = p.frame_requested(&scene.pose, &settings, 3, &request).unwrap();
            assert_eq!((f.width, f.height), (roi.width, roi.height));
            let (got, want) = (u16s(&f.pixels), full.pixels.crop(160, &roi));
            let differ = got.iter().zip(u16s(&want)).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "ROI {roi:?}, principal point {pp:?}: pixels unlike the full frame's");
            assert_eq!(f.integration_s, full.integration_s);
            // Only the ROI and the PSF's reach (a few pixels) are rendered.
            let reach = u64::from(roi.width + 8) * u64::from(roi.height + 8);
            assert!(f.render.traced_pixels <= reach, "ROI {roi:?}: {} pixels traced", f.render.traced_pixels);
            assert_eq!(f.render.samples, 4 * f.render.traced_pixels, "uniform: spp × traced pixels");
        }
    }
}

#[test]
fn with_adaptive_sampling_an_roi_is_the_same_picture() {
    let mut full_pipe = pipeline([0.0, 0.0]);
    let scene = full_pipe.scene().clone();
    assert!(scene.render.adaptive);
    let exposure = FrameRequest { integration_s: Some(40e-6), roi: None };
    let full = full_pipe.frame_requested(&scene.pose, &scene.render, 3, &exposure).unwrap();
    let roi = Window { x: 40, y: 52, width: 64, height: 48 };
    let request = FrameRequest { roi: Some(roi), ..exposure };
    let f = pipeline([0.0, 0.0]).frame_requested(&scene.pose, &scene.render, 3, &request).unwrap();
    let mean = |v: &[u16]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
    let (got, want) = (mean(u16s(&f.pixels)), mean(u16s(&full.pixels.crop(160, &roi))));
    assert!((got / want - 1.0).abs() < 0.01, "mean DN {got} in the ROI frame, {want} in the full frame there");
    assert!(f.render.traced_pixels <= 72 * 56, "{} pixels traced", f.render.traced_pixels);
    assert!(full.render.traced_pixels > 72 * 56, "{} pixels traced in the full frame", full.render.traced_pixels);
}

#[test]
fn an_roi_outside_the_sensor_is_a_named_refusal() {
    let mut p = pipeline([0.0, 0.0]);
    let scene = p.scene().clone();
    let request = FrameRequest { roi: Some(Window { x: 150, y: 0, width: 20, height: 10 }), integration_s: None };
    let e = p.frame_requested(&scene.pose, &scene.render, 0, &request).unwrap_err();
    assert_eq!(e.to_string(), "roi: window 20x10 at (150, 0) is not inside the 160x160 sensor (or is empty)");
}
