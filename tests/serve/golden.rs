//! Golden bytes: the shipped scenes rendered (radiance), through their sensors (the
//! frame's pixels), over the serve stream and by offline replay, each reduced to a CRC-32
//! and compared with `tests/golden/frames.txt`. A refactor that should not change what
//! hilcam outputs proves it here; a change that does is visible in the diff of that file.
//!
//! After an intended output change: `HILCAM_BLESS=1 cargo test --test serve golden::`
//! rewrites the file (commit it with the reason). Frames are pure functions of their
//! inputs, so the checksums hold for any thread count on one kind of machine.

use crate::serve_common;
use hilcam_core::frame::CRC32;
use hilcam_core::link::InputEvent;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::trajectory::Trajectory;
use hilcam_core::pose::validate::PoseLimits;
use hilcam_core::sink::recorder::FrameRecord;
use serve_common::*;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

const GOLDEN: &str = "tests/golden/frames.txt";
const SCENES: [&str; 8] = [
    "corner",
    "gltf_satellite",
    "gltf_satellite_obj",
    "jason_paper",
    "plate",
    "satellite",
    "satellite_lambert",
    "sphere",
];
/// Small enough to run in seconds, large enough that every scene's target covers pixels.
const WIDTH: u32 = 96;

fn crc_f32(v: &[f32]) -> u32 {
    CRC32.checksum(&v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>())
}

/// The first three rows of the shipped fly-around, gated as replay gates them.
fn flyaround() -> Vec<hilcam_core::pose::trajectory::TrajectorySample> {
    let mut s = Trajectory::load_gated("scenes/trajectories/flyaround.csv", &PoseLimits::default()).unwrap();
    s.truncate(3);
    s
}

/// name → CRC-32 for everything hilcam outputs.
fn outputs() -> BTreeMap<String, u32> {
    let mut out = BTreeMap::new();
    // Render and sensor, each shipped scene at its own pose and settings.
    for name in SCENES {
        let mut scene = hilcam_core::scene::load(Path::new(&format!("scenes/{name}.toml"))).unwrap();
        scene.camera = scene.camera.scaled(Some(WIDTH), None);
        let scene = Arc::new(scene);
        let mut pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
        let (img, _) = pipeline.radiance(&scene.pose, &scene.render, 0);
        assert!(img.data.iter().any(|v| *v > 0.0), "{name}: the target is in view");
        out.insert(format!("render/{name}"), crc_f32(&img.data));
        let f = pipeline.frame(&scene.pose, &scene.render, 0).unwrap();
        out.insert(format!("sensor/{name}"), CRC32.checksum(&pixel_bytes(&f.pixels)));
    }
    // The serve stream: three fly-around poses, one frame each (payload bytes).
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    rt.block_on(async {
        let mut cfg = config(
            std::fs::canonicalize("scenes/satellite.toml").unwrap(),
            Default::default(),
            Default::default(),
            Default::default(),
        );
        cfg.width = Some(WIDTH);
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        let server = start(cfg, Some(rx)).await;
        let mut reader = Reader::subscribed(&server.info).await;
        for (k, s) in flyaround().iter().enumerate() {
            tx.send(InputEvent::Pose { pose: s.to_pose(k as u32), arrival: Instant::now() }).await.unwrap();
            let f = reader.next().await;
            assert_eq!(f.meta.frame_seq, k as u64);
            out.insert(format!("serve/satellite/frame{k}"), CRC32.checksum(&pixel_bytes(&f.pixels)));
        }
        server.finish().await;
    });
    // Offline replay of the same poses, from the command line (payload CRCs it logs).
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    Trajectory::save(&csv, &flyaround()).unwrap();
    let dest = dir.path().join("out");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["replay", "--scene", "scenes/satellite.toml", "--width", &WIDTH.to_string(), "--format", "png"])
        .arg("--trajectory")
        .arg(&csv)
        .arg("--out")
        .arg(&dest)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let log = std::fs::read_to_string(dest.join("frames.jsonl")).unwrap();
    for line in log.lines() {
        let r: FrameRecord = serde_json::from_str(line).unwrap();
        out.insert(format!("replay/satellite/frame{}", r.meta.frame_seq), r.payload_crc32);
    }
    out
}

#[test]
fn every_output_matches_its_golden_checksum() {
    let got = outputs();
    let text: String = got.iter().map(|(k, v)| format!("{k} {v:08x}\n")).collect();
    if std::env::var_os("HILCAM_BLESS").is_some() {
        std::fs::create_dir_all("tests/golden").unwrap();
        std::fs::write(GOLDEN, &text).unwrap();
        return;
    }
    let want = std::fs::read_to_string(GOLDEN).unwrap_or_else(|e| panic!("{GOLDEN}: {e} (HILCAM_BLESS=1 writes it)"));
    let diff: Vec<String> =
        want.lines().zip(text.lines()).filter(|(w, g)| w != g).map(|(w, g)| format!("golden {w}, now {g}")).collect();
    assert!(diff.is_empty() && want.lines().count() == text.lines().count(), "outputs changed:\n{}", diff.join("\n"));
    // The live stream and offline replay are the same frames, byte for byte.
    for k in 0..3 {
        assert_eq!(got[&format!("serve/satellite/frame{k}")], got[&format!("replay/satellite/frame{k}")], "frame {k}");
    }
}
