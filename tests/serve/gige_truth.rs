//! `[output] truth` on the GigE Vision camera: `hilcam serve` renders the pose sent over
//! a pty on each software trigger, and Aravis (its Python bindings) finds the footprint,
//! one chunk per truth channel in the block and the mask's material table, equal to
//! `FramePipeline::truth` for the same pose — over the whole sensor and over a client's ROI.

use crate::gige::{dn_sphere_scene, python_client};
use glam::DVec3;
use hilcam_core::link::send::{MessageWriter, SerialWriter};
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Message;
use hilcam_core::render::camera::Window;
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::serve::config::ServeConfig;
use serialport::SerialPort;
use std::net::Ipv4Addr;
use std::sync::Arc;
use std::time::Duration;

fn crc32(bytes: impl IntoIterator<Item = [u8; 4]>) -> u64 {
    let v: Vec<u8> = bytes.into_iter().flatten().collect();
    u64::from(hilcam_core::frame::CRC32.checksum(&v))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn aravis_reads_truth_chunks_equal_to_the_pipelines_truth_whole_and_in_an_roi() {
    let ip = Ipv4Addr::new(127, 0, 0, 54);
    let dir = tempfile::tempdir().unwrap();
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let scene_path = dn_sphere_scene(dir.path());
    let text = format!(
        "scene = {:?}\n[input]\nkind = \"serial\"\ndevice = {:?}\nbaud = 921600\n[trigger]\nmode = \"external\"\n\
         [stream]\nlisten = \"127.0.0.1:0\"\n[metrics]\nprint_interval_s = 60.0\n\
         [output]\ntruth = [\"mask\", \"depth\"]\n[output.gige]\naddress = \"{ip}\"\n",
        scene_path,
        slave.name().unwrap()
    );
    let cfg: ServeConfig = toml::from_str(&text).unwrap();
    cfg.validate().unwrap();
    let server = crate::serve_common::start(cfg, None).await;
    tokio::time::sleep(Duration::from_millis(200)).await;

    let scene = Arc::new(hilcam_core::scene::load(&scene_path).unwrap());
    let pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
    let channels = TruthChannels::parse("depth,mask").unwrap();
    let mut writer = SerialWriter::new(master, "test pty");
    let pose = crate::gige::lit_pose;
    let roi = Window { x: 30, y: 20, width: 48, height: 40 };
    let cases = [
        (1u32, DVec3::new(0.8, -0.5, 10.0), None, vec![]),
        (2, DVec3::new(0.4, 0.3, 11.0), Some(roi), vec!["Width=48", "Height=40", "OffsetX=30", "OffsetY=20"]),
    ];
    for (seq, p, roi, features) in cases {
        writer.send(&Message::Pose(pose(seq, p))).unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
        let mut args = features.clone();
        args.push("--trigger");
        let v = python_client(ip, 1, &args).await;
        let b = &v["buffers"][0];
        assert_eq!(b["status"], "success", "{v}");
        assert_eq!(b["meta"]["pose_seq"].as_u64(), Some(u64::from(seq)), "{v}");
        let want = pipeline.truth(&pose(seq, p), &FrameRequest { roi, ..Default::default() }, channels).unwrap();
        let n = u64::from(want.width) * u64::from(want.height);
        assert_eq!(
            (b["width"].as_u64(), b["height"].as_u64()),
            (Some(u64::from(want.width)), Some(u64::from(want.height)))
        );
        let t = &b["truth"];
        let fp = want.footprint().expect("the sphere is in view");
        assert_eq!(t["target_pixels"].as_u64(), Some(fp.pixels), "{v}");
        assert_eq!(t["centroid"][0].as_f64(), Some(fp.centroid_px[0]), "{v}");
        assert_eq!(t["centroid"][1].as_f64(), Some(fp.centroid_px[1]), "{v}");
        let bbox: Vec<u64> = fp.bbox_px.iter().map(|&x| u64::from(x)).collect();
        assert_eq!(t["bbox"], serde_json::json!(bbox), "{v}");
        assert_eq!(t["depth"]["len"].as_u64(), Some(4 * n));
        assert_eq!(
            t["depth"]["crc32"].as_u64(),
            Some(crc32(want.depth.iter().map(|d| d.to_le_bytes()))),
            "depth bit for bit"
        );
        assert_eq!(t["mask"]["crc32"].as_u64(), Some(crc32(want.mask.iter().map(|m| m.to_le_bytes()))), "mask");
        assert!(t.get("normal").is_none(), "normal not configured: {v}");
        // The mask's table: the sphere scene's one material (issue 42).
        assert_eq!(t["materials"].as_str(), Some("1=white_paint"), "{v}");
        let payload = v["features"]["PayloadSize"].as_u64().unwrap();
        // Pixels (Mono16) + trailers, metadata and the SFNC chunks + footprint chunk + the
        // two channels + the table ("1=white_paint", 13 bytes, NUL-padded to 16).
        let chunks = hilcam_core::sink::gige::chunk::CHUNK_OVERHEAD as u64;
        assert_eq!(payload, 2 * n + chunks + (40 + 8) + 2 * (4 * n + 8) + (16 + 8));
    }
    let report = server.finish().await;
    assert_eq!(report.scheduler.triggers, 2);
    drop(slave);
}
