//! Offline replay (issue 7 items 1–2): files and log lines, resume, truncated logs,
//! sharding (frames and environment), auto-exposure handling, and bit-identity with
//! frames rendered live through `FramePipeline::frame`.

use crate::common;
use crate::serve_common::hilcam;
use common::scenes::*;
use glam::{DQuat, DVec3};
use hilcam_core::frame::{CRC32, PixelFormat};
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::Pose;
use hilcam_core::pose::trajectory::TrajectorySample;
use hilcam_core::render::integrator::RenderSettings;
use hilcam_core::render::integrator::Spp;
use hilcam_core::replay::{
    ReplayConfig, ReplayError, ReplayStats, Shard, merge, pin_integration_time, replay, select_frames,
};
use hilcam_core::scene::Scene;
use hilcam_core::sink::recorder::{FrameRecord, ImageFormat};
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;

const SETTINGS: RenderSettings = RenderSettings {
    spp: Spp::whole(2),
    depth: 2,
    sampler: hilcam_core::render::integrator::SamplerKind::Cosine,
    sequence: hilcam_core::render::sampling::Sequence::Sobol,
    roulette: true,
    adaptive: true,
    quality: hilcam_core::render::integrator::QualityGoal::FIXED,
    method: hilcam_core::render::integrator::Method::Path,
    seed: 7,
};

/// A 1 m Lambert plate seen from 5 m by a 12×12 camera (≈ 2 m field).
fn plate_scene() -> Scene {
    let cam = camera(12, 12, 333.0, 10.0);
    let pose = Pose { sun_dir: sun_at_incidence(30.0), ..Pose::ahead(5.0) };
    scene(square(0.0, 0.0, 0.0, 1.0, 0), vec![lambert("paint", 0.5)], cam, pose, SETTINGS)
}

/// `n` poses: the plate drifts sideways and turns, so every frame differs.
fn samples(n: usize) -> Vec<TrajectorySample> {
    (0..n)
        .map(|i| TrajectorySample {
            time_s: i as f64 * 0.1,
            position: DVec3::new(0.05 * i as f64, 0.0, 5.0),
            attitude: DQuat::from_rotation_y(0.1 * i as f64),
            sun_dir: sun_at_incidence(30.0),
            velocity: None,
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        })
        .collect()
}

fn cfg(dir: &Path, shard: Shard) -> ReplayConfig {
    ReplayConfig {
        out_dir: dir.to_path_buf(),
        format: ImageFormat::Pfm,
        settings: SETTINGS,
        every: 1,
        shard,
        source: "samples".into(),
        scene: "plate".into(),
        truth: hilcam_core::render::truth::TruthChannels::NONE,
    }
}

fn pipeline(scene: Scene) -> FramePipeline {
    let cam = scene.camera.clone();
    FramePipeline::new(Arc::new(scene), cam).unwrap()
}

fn records(path: &Path) -> Vec<FrameRecord> {
    std::fs::read_to_string(path).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

fn run(dir: &Path, shard: Shard, n: usize) -> Result<ReplayStats, ReplayError> {
    let mut p = pipeline(plate_scene());
    replay(&mut p, &samples(n), &cfg(dir, shard), |_| {})
}

#[test]
fn writes_every_frame_and_matches_live_frames_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let n = 5;
    let mut progress_calls = 0;
    let mut p = pipeline(plate_scene());
    let stats = replay(&mut p, &samples(n), &cfg(dir.path(), Shard::ALL), |_| progress_calls += 1).unwrap();
    assert_eq!((stats.selected, stats.rendered, stats.skipped), (5, 5, 0));
    assert_eq!(progress_calls, 6, "once at the start, once per frame");
    let recs = records(&dir.path().join("frames.jsonl"));
    assert_eq!(recs.len(), n);
    // The live path, computed independently: a fresh pipeline fed the same poses in order.
    let mut live = pipeline(plate_scene());
    for (k, (rec, s)) in recs.iter().zip(samples(n)).enumerate() {
        let f = live.frame(&s.to_pose(k as u32), &SETTINGS, k as u64).unwrap();
        let payload = f.pixels.to_le_bytes();
        assert!(payload.iter().any(|b| *b != 0), "frame {k} is not black");
        assert_eq!(
            (rec.meta.frame_seq, rec.meta.pose_seq, rec.meta.pose_t_ns),
            (k as u64, k as u32, (k as u64) * 100_000_000)
        );
        assert_eq!(rec.payload_crc32, CRC32.checksum(&payload), "frame {k} CRC");
        assert_eq!((rec.meta.width, rec.meta.height, rec.meta.spp, rec.meta.depth), (12, 12, Spp::whole(2), 2));
        // The file holds the same f32 values (PFM is lossless for Float32).
        let img = hilcam_core::render::film::read_pfm(&dir.path().join(&rec.file)).unwrap();
        let bytes: Vec<u8> = img.data.iter().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(bytes, payload, "frame {k} file bytes");
    }
    // No temporary files are left behind: the frames, the log and the manifest.
    let names: Vec<String> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    assert_eq!(names.len(), n + 2, "{names:?}");
    assert!(names.iter().any(|n| n == "replay.manifest.json"), "{names:?}");
}

#[test]
fn resume_renders_only_the_missing_frame() {
    let dir = tempfile::tempdir().unwrap();
    run(dir.path(), Shard::ALL, 4).unwrap();
    let again = run(dir.path(), Shard::ALL, 4).unwrap();
    assert_eq!((again.rendered, again.skipped), (0, 4));
    let before = records(&dir.path().join("frames.jsonl"));
    std::fs::remove_file(dir.path().join(&before[2].file)).unwrap();
    let resumed = run(dir.path(), Shard::ALL, 4).unwrap();
    assert_eq!((resumed.rendered, resumed.skipped), (1, 3));
    let after = records(&dir.path().join("frames.jsonl"));
    assert_eq!(after.len(), 5);
    assert_eq!(after[4].meta.frame_seq, 2);
    assert_eq!(after[4].payload_crc32, before[2].payload_crc32, "the re-render is the same frame");
    assert!(dir.path().join(&before[2].file).exists());
}

#[test]
fn truncated_last_log_line_is_tolerated_and_cut() {
    let dir = tempfile::tempdir().unwrap();
    run(dir.path(), Shard::ALL, 3).unwrap();
    let log = dir.path().join("frames.jsonl");
    let text = std::fs::read_to_string(&log).unwrap();
    // Kill in the middle of writing frame 2's line.
    let cut = text.len() - 1 - text.lines().last().unwrap().len() / 2;
    std::fs::write(&log, &text[..cut]).unwrap();
    let s = run(dir.path(), Shard::ALL, 3).unwrap();
    assert_eq!((s.rendered, s.skipped, s.truncated_lines), (1, 2, 0), "own log is cut before reading");
    let recs = records(&log);
    assert_eq!(recs.iter().map(|r| r.meta.frame_seq).collect::<Vec<_>>(), vec![0, 1, 2]);
    // A bad line that is not the last is an error naming the file and line.
    std::fs::write(&log, format!("garbage\n{text}")).unwrap();
    let e = run(dir.path(), Shard::ALL, 3).unwrap_err().to_string();
    assert!(e.contains("frames.jsonl:1: not a frame record"), "{e}");
}

#[test]
fn shards_partition_the_frames() {
    for n_rows in [0u64, 1, 7, 20] {
        for every in 1..4 {
            let all = select_frames(n_rows, every, Shard::ALL);
            assert_eq!(all, (0..n_rows).step_by(every as usize).collect::<Vec<_>>());
            for count in 1..6 {
                let mut union = BTreeSet::new();
                let mut total = 0;
                for index in 0..count {
                    let part = select_frames(n_rows, every, Shard { index, count });
                    total += part.len();
                    union.extend(part);
                }
                assert_eq!(total, all.len(), "no overlap: rows {n_rows} every {every} N {count}");
                assert_eq!(union.into_iter().collect::<Vec<_>>(), all);
            }
        }
    }
}

#[test]
fn shards_share_a_directory_and_merge() {
    let dir = tempfile::tempdir().unwrap();
    let whole = tempfile::tempdir().unwrap();
    run(whole.path(), Shard::ALL, 5).unwrap();
    let a = run(dir.path(), Shard { index: 0, count: 2 }, 5).unwrap();
    let b = run(dir.path(), Shard { index: 1, count: 2 }, 5).unwrap();
    assert_eq!((a.rendered, b.rendered), (3, 2));
    assert_eq!(records(&dir.path().join("frames.shard-0-of-2.jsonl")).len(), 3);
    let m = merge(dir.path()).unwrap();
    assert_eq!((m.logs, m.frames, m.gaps.len()), (2, 5, 0));
    // Losing shard 0's log leaves gaps 0 and 2, which merge reports (shard 1's frames
    // 1 and 3 fix the stride at 1; a stride of 2 alone would read as `--every 2`).
    std::fs::remove_file(dir.path().join("frames.shard-0-of-2.jsonl")).unwrap();
    std::fs::remove_file(dir.path().join("frames.jsonl")).unwrap();
    let m = merge(dir.path()).unwrap();
    assert_eq!((m.frames, m.gaps.clone()), (2, vec![0, 2]));
    run(dir.path(), Shard { index: 0, count: 2 }, 5).unwrap();
    assert_eq!(merge(dir.path()).unwrap().frames, 5);
    let merged = records(&dir.path().join("frames.jsonl"));
    let reference = records(&whole.path().join("frames.jsonl"));
    for (x, y) in merged.iter().zip(&reference) {
        assert_eq!(
            (x.meta.frame_seq, x.payload_crc32),
            (y.meta.frame_seq, y.payload_crc32),
            "shards render the live bytes"
        );
    }
}

/// The plate behind the nav1024 camera's sensor, which has auto-exposure.
fn auto_exposure_scene() -> Scene {
    let preset = hilcam_core::scene::file::load_camera_file(Path::new("config/cameras/nav1024.toml")).unwrap();
    assert!(preset.sensor.auto_exposure.is_some());
    let mut s = plate_scene();
    s.sensor = preset.sensor;
    s
}

#[test]
fn auto_exposure_refuses_shards_and_resume_unless_pinned() {
    let dir = tempfile::tempdir().unwrap();
    let shard = Shard { index: 0, count: 2 };
    let mut p = pipeline(auto_exposure_scene());
    let e = replay(&mut p, &samples(3), &cfg(dir.path(), shard), |_| {}).unwrap_err();
    assert!(matches!(e, ReplayError::AutoExposure { .. }));
    assert!(e.to_string().contains("shard 0/2") && e.to_string().contains("--integration-s"), "{e}");
    // A whole run in order is the live sequence; resuming it is refused.
    let whole = tempfile::tempdir().unwrap();
    let mut p = pipeline(auto_exposure_scene());
    replay(&mut p, &samples(3), &cfg(whole.path(), Shard::ALL), |_| {}).unwrap();
    std::fs::remove_file(whole.path().join("frame_0000000001.pfm")).unwrap();
    let mut p = pipeline(auto_exposure_scene());
    let e = replay(&mut p, &samples(3), &cfg(whole.path(), Shard::ALL), |_| {}).unwrap_err().to_string();
    assert!(e.contains("resuming (2 of 3 frames"), "{e}");
    // Pinned: every frame uses the given time, in any shard.
    let mut s = auto_exposure_scene();
    pin_integration_time(&mut s, 2e-3).unwrap();
    let mut p = pipeline(s);
    let st = replay(&mut p, &samples(3), &cfg(dir.path(), shard), |_| {}).unwrap();
    assert_eq!(st.rendered, 2);
    for r in records(&dir.path().join("frames.shard-0-of-2.jsonl")) {
        assert_eq!(r.meta.integration_s, 2e-3_f32);
        assert_eq!((r.meta.format, r.meta.bit_depth), (PixelFormat::Mono16, 10));
    }
    let mut plain = plate_scene();
    assert!(matches!(pin_integration_time(&mut plain, 1e-3), Err(ReplayError::NoDetector)));
    assert!(matches!(pin_integration_time(&mut plain, -1.0), Err(ReplayError::BadIntegration(_))));
}

#[test]
fn resuming_with_other_settings_is_refused_naming_the_directory_and_field() {
    let dir = tempfile::tempdir().unwrap();
    run(dir.path(), Shard::ALL, 3).unwrap();
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("replay.manifest.json")).unwrap()).unwrap();
    assert_eq!((manifest["seed"].as_u64(), manifest["spp"].as_u64()), (Some(7), Some(2)));
    assert_eq!((manifest["scene"].as_str(), manifest["format"].as_str()), (Some("plate"), Some("pfm")));
    type Change = fn(&mut ReplayConfig);
    let variants: [(&str, &str, &str, Change); 6] = [
        ("seed", "7", "8", |c| c.settings.seed = 8),
        ("sampler", "cosine", "uniform", |c| {
            c.settings.sampler = hilcam_core::render::integrator::SamplerKind::Uniform
        }),
        ("spp", "2", "4", |c| c.settings.spp = Spp::whole(4)),
        ("depth", "2", "3", |c| c.settings.depth = 3),
        ("scene", "plate", "other", |c| c.scene = "other".into()),
        ("format", "pfm", "exr", |c| c.format = ImageFormat::Exr),
    ];
    for (field, found, expected, change) in variants {
        let mut c = cfg(dir.path(), Shard::ALL);
        change(&mut c);
        let e = replay(&mut pipeline(plate_scene()), &samples(3), &c, |_| {}).unwrap_err();
        assert!(matches!(e, ReplayError::ManifestMismatch { field: f, .. } if f == field), "{field}: {e}");
        let text = e.to_string();
        let want =
            format!("{}: was rendered with {field} = {found}, this run has {field} = {expected}", dir.path().display());
        assert!(text.starts_with(&want), "{text}");
    }
    // A sharded resume with the same settings shares the directory.
    let s = run(dir.path(), Shard { index: 1, count: 2 }, 3).unwrap();
    assert_eq!((s.rendered, s.skipped), (0, 1));
}

#[test]
fn jobs_carry_their_own_settings_flags_and_expected_crc() {
    use hilcam_core::frame::FrameFlags;
    use hilcam_core::replay::{replay_jobs, trajectory_jobs};
    let dir = tempfile::tempdir().unwrap();
    let mut jobs = trajectory_jobs(&samples(3), &SETTINGS);
    // Frame 1 as a governor-degraded, extrapolated frame; its CRC computed independently.
    jobs[1].settings.spp = Spp::ONE;
    jobs[1].flags = FrameFlags(FrameFlags::DEGRADED | FrameFlags::EXTRAPOLATED);
    let mut live = pipeline(plate_scene());
    for j in &mut jobs {
        let f = live.frame(&j.pose, &j.settings, j.index).unwrap();
        j.expect_crc32 = Some(CRC32.checksum(&f.pixels.to_le_bytes()));
    }
    replay_jobs(&mut pipeline(plate_scene()), &jobs, &cfg(dir.path(), Shard::ALL), |_| {}).unwrap();
    let recs = records(&dir.path().join("frames.jsonl"));
    assert_eq!(recs.iter().map(|r| r.meta.spp).collect::<Vec<_>>(), vec![Spp::whole(2), Spp::ONE, Spp::whole(2)]);
    assert!(recs[1].extrapolated && recs[1].meta.flags.0 == FrameFlags::DEGRADED | FrameFlags::EXTRAPOLATED);
    for (r, j) in recs.iter().zip(&jobs) {
        assert_eq!(Some(r.payload_crc32), j.expect_crc32);
    }
    // A frame that does not reproduce its CRC stops the run before its file is written.
    let other = tempfile::tempdir().unwrap();
    jobs[2].expect_crc32 = jobs[2].expect_crc32.map(|c| c ^ 1);
    let e = replay_jobs(&mut pipeline(plate_scene()), &jobs, &cfg(other.path(), Shard::ALL), |_| {}).unwrap_err();
    assert!(matches!(e, ReplayError::NotIdentical { frame: 2, .. }), "{e}");
    assert!(!other.path().join("frame_0000000002.pfm").exists());
    assert_eq!(records(&other.path().join("frames.jsonl")).len(), 2);
}

#[test]
fn replay_refuses_a_trajectory_row_the_pose_gate_refuses_naming_file_line_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    let out = dir.path().join("out");
    for (row, reason) in [
        ("1,0,0,5,2,0,0,0,0,0,-1", "quaternion norm outside tolerance (attitude norm 2e0, must be within 1e-3 of 1)"),
        ("1,0,0,5,0,0,0,0,0,0,-1", "quaternion norm outside tolerance (attitude norm 0e0"),
        ("1,0,0,5,1,0,0,0,0,0,0", "sun direction not a unit vector (sun norm 0e0"),
        (
            "1,0,0,1e200,1,0,0,0,0,0,-1",
            "range above maximum (range 1e200 m, above the 1e7 m limit (the scene's [limits] max_range_m))",
        ),
        ("1,0,0,1e-310,1,0,0,0,0,0,-1", "range below minimum"),
    ] {
        std::fs::write(&csv, format!("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz\n0,0,0,5,1,0,0,0,0,0,-1\n{row}\n")).unwrap();
        let (ok, err) = hilcam(&[
            "replay".as_ref(),
            "--trajectory".as_ref(),
            csv.as_os_str(),
            "--scene".as_ref(),
            "scenes/plate.toml".as_ref(),
            "--width".as_ref(),
            "8".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        assert!(!ok && !err.contains("panicked"), "{row}: {err}");
        let want = format!("{}:3:0: pose refused: {reason}", csv.display());
        assert!(err.contains(&want), "{row}: want `{want}` in:\n{err}");
        assert!(!out.exists(), "nothing is rendered before the trajectory passes the gate");
    }
}

#[test]
fn session_replay_refuses_an_edited_pose_the_gate_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.jsonl");
    let header = r#"{"kind":"header","version":1,"hilcam":"0.1.0","start_unix_ns":0,"scene":"scenes/plate.toml","width_setting":8,"width":8,"height":8,"settings":{"spp":1,"depth":1,"sampler":"cosine","sequence":"sobol","roulette":true,"seed":0},"trigger":"pose","extrapolate":false,"policy":"fixed-quality","input":"embedded"}"#;
    let frame = r#"{"kind":"frame","index":0,"mono_ns":0,"source_seq":4,"source_mono_ns":0,"poses_received":1,"extrapolated_s":0.0,"pose":{"seq":4,"t_ns":0,"position":[0.0,0.0,5.0],"attitude":[0.0,0.0,0.0,0.0],"sun_dir":[0.0,0.0,-1.0]},"settings":{"spp":1,"depth":1,"sampler":"cosine","sequence":"sobol","roulette":true,"seed":0},"flags":0,"late":false,"extrapolated":false,"degraded":false,"integration_s":null,"payload_crc32":0}"#;
    std::fs::write(&session, format!("{header}\n{frame}\n")).unwrap();
    let out = dir.path().join("out");
    let (ok, err) =
        hilcam(&["replay".as_ref(), "--session".as_ref(), session.as_os_str(), "--out".as_ref(), out.as_os_str()]);
    assert!(!ok && !err.contains("panicked"), "{err}");
    assert!(err.contains("frame 0 (pose seq 4): pose refused: quaternion norm outside tolerance"), "{err}");
}

#[test]
fn a_replayed_frame_is_hilcam_render_at_its_pose_and_frame_index() {
    // What the README's determinism row promises: frame k of a replay is `hilcam render
    // --pose <row k> --frame k` with the same seed and settings, byte for byte.
    let dir = tempfile::tempdir().unwrap();
    let plate = std::fs::canonicalize("scenes/meshes/plate.obj").unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        format!(
            "[camera]\nwidth = 48\nheight = 32\npitch_um = 20.0\nfocal_mm = 4.0\n\
             [[mesh]]\nobj = {plate:?}\nmaterial = \"paint\"\n\
             [materials.paint]\nmodel = \"lambert\"\nrho = 0.5\n[render]\nspp = 2\ndepth = 2\n"
        ),
    )
    .unwrap();
    let rows = ["0,0,0,6,1,0,0,0,0.5,0,-0.8660254037844386", "1,0.1,0,6,1,0,0,0,0.5,0,-0.8660254037844386"];
    let csv = dir.path().join("t.csv");
    std::fs::write(&csv, format!("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz\n{}\n{}\n", rows[0], rows[1])).unwrap();
    let out = dir.path().join("out");
    let os = |s: &str| std::ffi::OsString::from(s);
    let (ok, err) = hilcam(&[
        &os("replay"),
        &os("--trajectory"),
        csv.as_os_str(),
        &os("--scene"),
        scene.as_os_str(),
        &os("--format"),
        &os("pfm"),
        &os("--seed"),
        &os("7"),
        &os("--out"),
        out.as_os_str(),
    ]);
    assert!(ok, "{err}");
    for (k, row) in rows.iter().enumerate() {
        let pose = row.split_once(',').unwrap().1;
        let single = dir.path().join(format!("render_{k}.pfm"));
        let (ok, err) = hilcam(&[
            &os("render"),
            scene.as_os_str(),
            &os("--pose"),
            &os(pose),
            &os("--frame"),
            &os(&k.to_string()),
            &os("--seed"),
            &os("7"),
            &os("--out"),
            single.as_os_str(),
        ]);
        assert!(ok, "{err}");
        let replayed = std::fs::read(out.join(format!("frame_{k:010}.pfm"))).unwrap();
        let rendered = std::fs::read(&single).unwrap();
        assert!(replayed == rendered, "frame {k}: the replay's PFM differs from `hilcam render --frame {k}`");
    }
    // And the index matters: frame 1's pose rendered as frame 0 is another image.
    let other = dir.path().join("other.pfm");
    let pose1 = rows[1].split_once(',').unwrap().1;
    let (ok, err) = hilcam(&[
        &os("render"),
        scene.as_os_str(),
        &os("--pose"),
        &os(pose1),
        &os("--frame"),
        &os("0"),
        &os("--seed"),
        &os("7"),
        &os("--out"),
        other.as_os_str(),
    ]);
    assert!(ok, "{err}");
    assert!(std::fs::read(&other).unwrap() != std::fs::read(out.join("frame_0000000001.pfm")).unwrap());
}
