//! The rig's `[[camera]]` config and its single-camera promise: the shipped rig loads,
//! refusals name the file, the camera and the key, a config without `[[camera]]` is one
//! camera on an identity mount that renders the golden bytes, and serve refuses a rig it
//! does not drive yet.

use crate::serve_common::pixel_bytes;
use glam::DVec3;
use hilcam_core::frame::CRC32;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::rig::{BodyPose, Mount};
use hilcam_core::serve::config::ServeConfig;
use std::path::Path;
use std::sync::Arc;

fn load_text(text: &str) -> Result<ServeConfig, String> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rig.toml");
    std::fs::write(&p, format!("scene = \"s.toml\"\n{text}")).unwrap();
    ServeConfig::load(&p).map_err(|e| e.to_string())
}

const NARROW: &str = "[[camera]]\nname = \"narrow\"\nmodel = \"nav1024\"\nstream.listen = \"127.0.0.1:5601\"\n";

#[test]
fn the_shipped_rig_loads_with_its_three_cameras_and_mounts() {
    let cfg = ServeConfig::load(Path::new("config/serve-rig.toml")).unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<_> = cfg.cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["narrow", "wide", "star"]);
    let sizes: Vec<_> = cfg.cameras.iter().map(|c| c.model().unwrap().camera.width).collect();
    assert_eq!(sizes, [1024, 512, 1024]);
    let mounts = cfg.camera_mounts();
    assert_eq!((mounts[0].1.attitude, mounts[1].1.attitude), (glam::DQuat::IDENTITY, glam::DQuat::IDENTITY));
    // The star tracker looks 20° behind body −Y: +110° about body X.
    let boresight = mounts[2].1.attitude * DVec3::Z;
    let want = DVec3::new(0.0, -110f64.to_radians().sin(), 110f64.to_radians().cos());
    assert!((boresight - want).length() < 1e-12, "{boresight}");
    let rates: Vec<_> = cfg.cameras.iter().map(|c| c.trigger.rate_hz.unwrap()).collect();
    assert_eq!(rates, [5.0, 10.0, 4.0]);
}

#[test]
fn rig_config_errors_name_the_file_the_camera_and_the_key() {
    // A narrow and a wide camera, each with extra keys.
    let two = |narrow: &str, wide: &str| {
        format!(
            "{NARROW}{narrow}[[camera]]\nname = \"wide\"\nmodel = \"nav1024\"\nstream.listen = \"127.0.0.1:5602\"\n{wide}"
        )
    };
    let wide = |extra: &str| two("", extra);
    let in_wide = |e: &str| format!("camera[1] \"wide\": {e}");
    for (text, want) in [
        (
            wide("mount.attitude = [1.0, 0.0, 0.2, 0.0]\n"),
            in_wide("mount.attitude: [1.0, 0.0, 0.2, 0.0] has norm 1.0198"),
        ),
        (
            wide("mount.attitude = [1.0, 0.0, 0.0, 0.0]\nmount.euler_deg = [0.0, 0.0, 0.0]\n"),
            in_wide("mount: give either attitude or euler_deg, not both"),
        ),
        (wide("mount.position = [0.0, 5000.0, 0.0]\n"), in_wide("mount.position: [0.0, 5000.0, 0.0]: must be finite")),
        (wide("trigger.rate_hz = 0.0\n"), in_wide("trigger.rate_hz: must be in (0, 10000], got 0")),
        (wide("render.depth = 0\n"), in_wide("render.depth: must be at least 1")),
        (wide("output.truth = [\"range\"]\n"), in_wide("output.truth: unknown truth channel `range`")),
        (
            format!("{NARROW}[[camera]]\nname = \"wide\"\nmodel = \"nav4096\"\nstream.listen = \"127.0.0.1:5602\"\n"),
            in_wide("model: unknown camera preset `nav4096` (known: nav1024, nav2048, paper)"),
        ),
        (
            format!("{NARROW}[[camera]]\nname = \"wide\"\nmodel = \"nav1024\"\nstream.listen = \"127.0.0.1:5601\"\n"),
            in_wide("stream.listen: 127.0.0.1:5601 is also camera[0] \"narrow\"'s"),
        ),
        (
            format!("{NARROW}[[camera]]\nname = \"narrow\"\nmodel = \"nav1024\"\n"),
            "camera[1] \"narrow\": name: the name is also camera[0] \"narrow\"'s".into(),
        ),
        (
            two("output.gige.serial = \"A1\"\n", "output.gige = { address = \"127.0.0.2\", serial = \"A1\" }\n"),
            in_wide("output.gige.serial: serial \"A1\" is also camera[0] \"narrow\"'s"),
        ),
        (
            two("output.gige.serial = \"A1\"\n", "output.gige.serial = \"A2\"\n"),
            in_wide("output.gige.gvcp_port: 127.0.0.1:3956 is also camera[0] \"narrow\"'s"),
        ),
        (
            two(
                "output.gige = { serial = \"A1\", user_name = \"nav\" }\n",
                "output.gige = { address = \"127.0.0.2\", serial = \"A2\", user_name = \"nav\" }\n",
            ),
            in_wide("output.gige.user_name: user ID \"nav\" is also camera[0] \"narrow\"'s"),
        ),
        (
            two("trigger = { group = \"pair\", rate_hz = 5.0 }\n", "trigger = { group = \"pair\", rate_hz = 4.0 }\n"),
            in_wide("trigger.rate_hz: 4 Hz, but trigger group \"pair\" runs at camera[0] \"narrow\"'s 5 Hz"),
        ),
        (format!("{NARROW}name2 = \"x\"\n"), "unknown field `name2`".into()),
        (format!("width = 512\n{NARROW}"), "width: a rig ([[camera]]) gives this per camera".into()),
    ] {
        let e = load_text(&text).unwrap_err();
        assert!(e.contains("rig.toml: ") && e.contains(want.as_str()), "{text}\n→ {e}\nwanted {want}");
    }
    // The unknown key is found at its line.
    let e = load_text(&format!("{NARROW}name2 = \"x\"\n")).unwrap_err();
    assert!(e.contains("line 6"), "{e}");
}

#[test]
fn no_camera_table_is_one_camera_on_an_identity_mount_with_todays_bytes() {
    let cfg = load_text("").unwrap();
    let mounts = cfg.camera_mounts();
    assert_eq!(mounts.len(), 1);
    assert!(mounts[0].1.is_identity() && mounts[0].1 == Mount::IDENTITY);
    // The golden frames (tests/golden/frames.txt, golden::) through the mount.
    let golden = std::fs::read_to_string("tests/golden/frames.txt").unwrap();
    let want = |key: &str| {
        let line = golden.lines().find(|l| l.split(' ').next() == Some(key)).unwrap();
        u32::from_str_radix(line.split(' ').nth(1).unwrap(), 16).unwrap()
    };
    for name in ["plate", "satellite"] {
        let mut scene = hilcam_core::scene::load(Path::new(&format!("scenes/{name}.toml"))).unwrap();
        scene.camera = scene.camera.scaled(Some(96), None);
        let scene = Arc::new(scene);
        let mut pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
        let pose = mounts[0].1.camera_pose(&BodyPose(scene.pose));
        let (img, _) = pipeline.radiance(&pose, &scene.render, 0);
        let radiance = CRC32.checksum(&img.data.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>());
        assert_eq!(radiance, want(&format!("render/{name}")), "{name}: radiance");
        let f = pipeline.frame(&pose, &scene.render, 0).unwrap();
        assert_eq!(CRC32.checksum(&pixel_bytes(&f.pixels)), want(&format!("sensor/{name}")), "{name}: frame");
    }
}

#[test]
fn serve_refuses_a_rig_it_does_not_drive_yet() {
    let cfg = ServeConfig::load(Path::new("config/serve-rig.toml")).unwrap();
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    let e = rt.block_on(hilcam_core::serve::run(cfg, Default::default(), std::future::pending::<()>())).unwrap_err();
    assert!(e.to_string().contains("a rig of 3 cameras ([[camera]]); `hilcam serve` does not drive a rig yet"), "{e}");
}
