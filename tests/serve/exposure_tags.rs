//! Issue 42, item 1: a float32 (radiance) frame from a camera whose exposure integrates
//! over time is tagged with that integration time — in `frames.jsonl` (replay) and in
//! the stream's header (serve) — not with 0. The answers are the scene file's own
//! `integration_time_s` and `line_time_us`, not hilcam's output.

use crate::common;
use crate::serve_common;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::frame::{FrameFlags, FrameMeta};
use hilcam_core::link::InputEvent;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::Pose;
use hilcam_core::pose::trajectory::TrajectorySample;
use hilcam_core::render::integrator::{RenderSettings, Spp};
use hilcam_core::replay::{ReplayConfig, Shard, replay};
use hilcam_core::sensor::SensorConfig;
use hilcam_core::serve::config::{InputConfig, TriggerConfig};
use hilcam_core::sink::recorder::{FrameRecord, ImageFormat};
use std::sync::Arc;
use std::time::Instant;

/// A radiance-output sensor whose detector integrates `exposure` over 20 ms.
fn float_sensor(exposure: &str) -> String {
    format!(
        "output = \"float32\"\n[band]\nmin_um = 0.45\nmax_um = 0.75\n[optics]\nf_number = 2.8\n\
         [detector]\nqe = 0.5\nintegration_time_s = 0.02\n{exposure}"
    )
}

const GLOBAL: &str = "exposure = \"global\"\n";
const ROLLING: &str = "exposure = \"rolling\"\nline_time_us = 20.0\n";

fn settings() -> RenderSettings {
    RenderSettings { spp: Spp::whole(2), depth: 1, adaptive: false, ..Default::default() }
}

/// Replay three poses of a plate drifting at 1 m/s through a camera with `sensor`.
fn replayed(sensor: &str) -> Vec<FrameRecord> {
    let cam = camera(16, 16, 333.0, 10.0);
    let pose = Pose { sun_dir: sun_at_incidence(30.0), ..Pose::ahead(5.0) };
    let mut scene = scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam.clone(), pose, settings());
    scene.sensor = toml::from_str::<SensorConfig>(sensor).unwrap();
    let mut p = FramePipeline::new(Arc::new(scene), cam).unwrap();
    let samples: Vec<TrajectorySample> = (0..3)
        .map(|i| TrajectorySample {
            time_s: f64::from(i) * 0.1,
            position: DVec3::new(0.1 * f64::from(i), 0.0, 5.0),
            attitude: DQuat::IDENTITY,
            sun_dir: sun_at_incidence(30.0),
            velocity: Some(DVec3::new(1.0, 0.0, 0.0)),
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let cfg = ReplayConfig {
        out_dir: dir.path().to_path_buf(),
        format: ImageFormat::Pfm,
        settings: settings(),
        every: 1,
        shard: Shard::ALL,
        source: "samples".into(),
        scene: "plate".into(),
        truth: hilcam_core::render::truth::TruthChannels::NONE,
    };
    replay(&mut p, &samples, &cfg, |_| {}).unwrap();
    let log = std::fs::read_to_string(dir.path().join("frames.jsonl")).unwrap();
    log.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

fn tagged(meta: &FrameMeta, line_time_ns: u32) {
    assert_eq!(meta.format, hilcam_core::frame::PixelFormat::Float32);
    assert_eq!(meta.integration_s, 0.02f32, "the scene's integration_time_s");
    assert_eq!(meta.line_time_ns, line_time_ns, "the scene's line_time_us");
    assert!(meta.flags.contains(FrameFlags::EXPOSURE_START), "flags {:?}", meta.flags);
}

#[test]
fn r42_a_replayed_exposure_integrated_float_frame_carries_its_integration_time() {
    for rec in replayed(&float_sensor(GLOBAL)) {
        tagged(&rec.meta, 0);
    }
    for rec in replayed(&float_sensor(ROLLING)) {
        tagged(&rec.meta, 20_000);
    }
    // An instant float32 frame integrated nothing: 0 stays the truth there.
    for rec in replayed(&float_sensor("")) {
        assert_eq!((rec.meta.integration_s, rec.meta.line_time_ns), (0.0, 0));
        assert!(!rec.meta.flags.contains(FrameFlags::EXPOSURE_START));
    }
}

#[test]
fn r42_the_start_up_warning_says_which_detector_stages_a_float_frame_gets() {
    let note = |s: &str| toml::from_str::<SensorConfig>(s).unwrap().float_output_note().expect("a note");
    let global = note(&float_sensor(GLOBAL));
    assert!(global.contains("global exposure is applied") && global.contains("0.02 s"), "{global}");
    assert!(!global.contains("are not applied"), "{global}");
    assert!(note(&float_sensor("")).contains("[sensor.detector] and [sensor.adc] are not applied"));
    let dn = "output = \"dn\"\n[adc]\nbits = 12\ngain_e_per_dn = 1.0\n";
    assert_eq!(toml::from_str::<SensorConfig>(dn).unwrap().float_output_note(), None);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r42_a_served_exposure_integrated_float_frame_carries_its_integration_time_in_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let extra = float_sensor(ROLLING)
        .replace("output =", "[sensor]\noutput =")
        .replace("[band]", "[sensor.band]")
        .replace("[optics]", "[sensor.optics]")
        .replace("[detector]", "[sensor.detector]");
    let scene = serve_common::sphere_scene_with(dir.path(), 24, 1, &extra);
    let cfg = serve_common::config(scene, InputConfig::default(), TriggerConfig::default(), Default::default());
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let server = serve_common::start(cfg, Some(rx)).await;
    let mut reader = serve_common::Reader::connect(server.info.stream).await;
    let pose = Pose {
        velocity: Some(DVec3::new(2.0, 0.0, 0.0)),
        ..serve_common::pose(1, DVec3::new(0.0, 0.0, 10.0), DVec3::NEG_Z)
    };
    tx.send(InputEvent::Pose { pose, arrival: Instant::now() }).await.unwrap();
    let f = reader.next().await;
    tagged(&f.meta, 20_000);
    server.finish().await;
}
