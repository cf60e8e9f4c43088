//! A spacecraft described only by a GLB (GGX metal, a solar-cell texture) is served like
//! any scene: the stream's frame is the offline pipeline's frame at the same pose and
//! frame index, and the same model's OBJ + MTL + PNG export streams the same bytes.

use crate::serve_common;
use hilcam_core::link::InputEvent;
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::render::film::Pixels;
use serve_common::*;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

const WIDTH: u32 = 128;

/// One frame of `scene` at its own pose, through a running server.
async fn served(scene: &str) -> Vec<u8> {
    let mut cfg =
        config(std::fs::canonicalize(scene).unwrap(), Default::default(), Default::default(), Default::default());
    cfg.width = Some(WIDTH);
    let pose = hilcam_core::scene::load(Path::new(scene)).unwrap().pose;
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let server = start(cfg, Some(rx)).await;
    let mut reader = Reader::subscribed(&server.info).await;
    tx.send(InputEvent::Pose { pose, arrival: Instant::now() }).await.unwrap();
    let f = reader.next().await;
    assert_eq!(f.meta.frame_seq, 0);
    server.finish().await;
    pixel_bytes(&f.pixels)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_textured_glb_spacecraft_streams_what_renders_offline_and_what_its_obj_export_streams() {
    let glb = served("scenes/textured_satellite.toml").await;
    let obj = served("scenes/textured_satellite_obj.toml").await;
    assert!(glb == obj, "the GLB and its OBJ + MTL + PNG export stream different frames");
    // Offline, the same scene through the same pipeline: the same bytes.
    let mut scene = hilcam_core::scene::load(Path::new("scenes/textured_satellite.toml")).unwrap();
    assert!(scene.texturing.is_some(), "the scene is textured");
    scene.camera = scene.camera.scaled(Some(WIDTH), None);
    let scene = Arc::new(scene);
    let mut pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
    let offline = pipeline.frame(&scene.pose, &scene.render, 0).unwrap();
    assert!(pixel_bytes(&offline.pixels) == glb, "the served frame differs from the offline one");
    // Not a black frame: the target is in view and lit.
    let lit = match &offline.pixels {
        Pixels::Mono16 { data, .. } => data.iter().filter(|&&v| v > 200).count(),
        Pixels::Mono8(d) => d.iter().filter(|&&v| v > 20).count(),
        Pixels::Float32(d) => d.iter().filter(|&&v| v > 0.0).count(),
    };
    assert!(lit > 200, "only {lit} lit pixels");
}
