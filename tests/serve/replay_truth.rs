//! `hilcam replay --truth`: the truth EXR beside each frame (channels, mask table, values
//! equal to `FramePipeline::truth`), its log fields, independence from spp, resume and the
//! manifest, and the command line's refusal of unknown channel names.

use crate::common;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Pose;
use hilcam_core::pose::trajectory::TrajectorySample;
use hilcam_core::render::integrator::{RenderSettings, Spp};
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::replay::{ReplayConfig, ReplayError, ReplayStats, Shard, replay};
use hilcam_core::scene::Scene;
use hilcam_core::sink::recorder::{FrameRecord, ImageFormat};
use std::path::Path;
use std::sync::Arc;

fn settings(spp: u32) -> RenderSettings {
    RenderSettings { spp: Spp::whole(spp), depth: 2, seed: 3, ..Default::default() }
}

/// A 1 m plate from 5 m, 16×12 pixels (~2.4 m field): edges and background in view.
fn plate_scene(spp: u32) -> Scene {
    let cam = camera(16, 12, 300.0, 10.0);
    let pose = Pose { sun_dir: sun_at_incidence(30.0), ..Pose::ahead(5.0) };
    scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam, pose, settings(spp))
}

fn samples() -> Vec<TrajectorySample> {
    (0..3)
        .map(|i| TrajectorySample {
            time_s: i as f64 * 0.1,
            position: DVec3::new(0.1 * i as f64, 0.0, 5.0),
            attitude: DQuat::from_rotation_y(0.2 * i as f64),
            sun_dir: sun_at_incidence(30.0),
            velocity: None,
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        })
        .collect()
}

fn run(dir: &Path, spp: u32, truth: &str) -> Result<ReplayStats, ReplayError> {
    let scene = plate_scene(spp);
    let cfg = ReplayConfig {
        out_dir: dir.to_path_buf(),
        format: ImageFormat::Pfm,
        settings: settings(spp),
        every: 1,
        shard: Shard::ALL,
        source: "samples".into(),
        scene: "plate".into(),
        truth: TruthChannels::parse(truth).unwrap(),
    };
    let cam = scene.camera.clone();
    let mut p = FramePipeline::new(Arc::new(scene), cam).unwrap();
    replay(&mut p, &samples(), &cfg, |_| {})
}

/// Every channel of an EXR by name (read with the exr crate), and its mask-table attribute.
fn read_exr(path: &Path) -> (Vec<(String, Vec<f32>)>, String) {
    use exr::prelude::*;
    let image = read().no_deep_data().largest_resolution_level().all_channels().first_valid_layer().all_attributes();
    let image = image.from_file(path).unwrap();
    let layer = &image.layer_data;
    let table = match layer.attributes.other.get(&Text::from("hilcam_materials")) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        other => panic!("no mask table: {other:?}"),
    };
    let channels =
        layer.channel_data.list.iter().map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect())).collect();
    (channels, table)
}

#[test]
fn truth_exr_beside_each_frame_holds_the_pipelines_truth_and_the_log_its_footprint() {
    let dir = tempfile::tempdir().unwrap();
    let stats = run(dir.path(), 1, "depth,mask,normal,body_xyz").unwrap();
    assert_eq!(stats.rendered, 3);
    let recs: Vec<FrameRecord> = std::fs::read_to_string(dir.path().join("frames.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let scene = Arc::new(plate_scene(1));
    let p = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
    for (k, rec) in recs.iter().enumerate() {
        let t = rec.truth.as_ref().expect("truth fields on the log line");
        assert_eq!(
            (t.file.as_str(), t.channels.as_str()),
            (format!("truth_{k:010}.exr").as_str(), "depth,mask,normal,body_xyz")
        );
        let (channels, table) = read_exr(&dir.path().join(&t.file));
        assert_eq!(table, "1=paint");
        let names: Vec<_> = channels.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            ["body_xyz.X", "body_xyz.Y", "body_xyz.Z", "depth", "mask", "normal.X", "normal.Y", "normal.Z"]
        );
        // The file holds exactly what the pipeline computes for that pose (bit for bit).
        let want = p
            .truth(
                &samples()[k].to_pose(k as u32),
                &FrameRequest::default(),
                TruthChannels::parse("depth,mask").unwrap(),
            )
            .unwrap();
        let get = |n: &str| &channels.iter().find(|(c, _)| c == n).unwrap().1;
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(get("depth")), bits(&want.depth));
        assert_eq!(get("mask").iter().map(|&m| m as u32).collect::<Vec<_>>(), want.mask);
        // The log's footprint is the mask's.
        let f = want.footprint().unwrap();
        assert_eq!(
            (t.target_pixels, t.target_centroid_px, t.target_bbox_px),
            (f.pixels, Some(f.centroid_px), Some(f.bbox_px))
        );
        assert!(f.pixels > 20 && f.pixels < 16 * 12, "the plate and its edges are in view: {}", f.pixels);
    }
    let manifest = std::fs::read_to_string(dir.path().join("replay.manifest.json")).unwrap();
    assert!(manifest.contains("\"truth\": \"depth,mask,normal,body_xyz\""), "{manifest}");
}

#[test]
fn truth_files_are_the_same_bytes_at_any_spp() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    run(a.path(), 1, "depth,mask,normal,body_xyz").unwrap();
    run(b.path(), 4, "depth,mask,normal,body_xyz").unwrap();
    for k in 0..3 {
        let name = format!("truth_{k:010}.exr");
        let (x, y) = (std::fs::read(a.path().join(&name)).unwrap(), std::fs::read(b.path().join(&name)).unwrap());
        assert!(x == y && !x.is_empty(), "{name} differs between spp 1 and 4");
        // …while the frames themselves differ (the test would be empty otherwise).
        let name = format!("frame_{k:010}.pfm");
        assert_ne!(std::fs::read(a.path().join(&name)).unwrap(), std::fs::read(b.path().join(&name)).unwrap());
    }
}

#[test]
fn frames_and_their_crcs_are_the_same_with_truth_on_and_off() {
    let (on, off) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    run(on.path(), 2, "depth,mask,normal,body_xyz").unwrap();
    run(off.path(), 2, "").unwrap();
    let crcs = |d: &Path| {
        let text = std::fs::read_to_string(d.join("frames.jsonl")).unwrap();
        text.lines().map(|l| serde_json::from_str::<FrameRecord>(l).unwrap().payload_crc32).collect::<Vec<_>>()
    };
    assert_eq!(crcs(on.path()), crcs(off.path()));
    for k in 0..3 {
        let name = format!("frame_{k:010}.pfm");
        assert_eq!(std::fs::read(on.path().join(&name)).unwrap(), std::fs::read(off.path().join(&name)).unwrap());
        assert!(!off.path().join(format!("truth_{k:010}.exr")).exists());
    }
    // Without truth the log lines carry no `truth` object.
    assert!(!std::fs::read_to_string(off.path().join("frames.jsonl")).unwrap().contains("truth"));
}

#[test]
fn a_lost_truth_file_is_rendered_again_and_other_channels_are_refused_by_the_manifest() {
    let dir = tempfile::tempdir().unwrap();
    run(dir.path(), 1, "depth").unwrap();
    std::fs::remove_file(dir.path().join("truth_0000000001.exr")).unwrap();
    let stats = run(dir.path(), 1, "depth").unwrap();
    assert_eq!((stats.rendered, stats.skipped), (1, 2));
    assert!(dir.path().join("truth_0000000001.exr").exists());
    match run(dir.path(), 1, "depth,mask") {
        Err(ReplayError::ManifestMismatch { field: "truth", found, expected, .. }) => {
            assert_eq!((found.as_str(), expected.as_str()), ("depth", "depth,mask"))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_command_line_refuses_an_unknown_channel_naming_the_allowed_ones() {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["replay", "--trajectory", "t.csv", "--scene", "scenes/plate.toml", "--truth", "depth,range", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("unknown truth channel `range` (allowed: depth, mask, normal, body_xyz)"), "{err}");
}
