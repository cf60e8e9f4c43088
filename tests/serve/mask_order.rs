//! Issue 42, item 3: the mask numbers the scene's materials in name order (alphabetical
//! by `[materials.NAME]`, whatever order the scene file writes them in), and the stream's
//! truth block and the GigE chunks carry the id → name table with the mask. The answers:
//! which plate each pixel sees (geometry) and the documented rule applied by hand.

use hilcam_core::frame::truth_block::{decode_truth_block, encode_truth_block};
use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::render::camera::Window;
use hilcam_core::render::truth::TruthChannels;
use hilcam_core::sink::gige::chunk::{self, ChunkSet, MATERIALS_CHUNK_ID};
use std::path::Path;
use std::sync::Arc;

/// Two 1 m plates side by side at 10 m, `zinc` on the left (x < 0), `alpha` on the right;
/// the scene file names zinc first.
fn two_plates(dir: &Path) -> std::path::PathBuf {
    let obj = "mtllib p.mtl\n\
               v -1.1 -0.5 0\nv -0.1 -0.5 0\nv -0.1 0.5 0\nv -1.1 0.5 0\n\
               v 0.1 -0.5 0\nv 1.1 -0.5 0\nv 1.1 0.5 0\nv 0.1 0.5 0\n\
               usemtl zinc\nf 1 2 3\nf 1 3 4\nusemtl alpha\nf 5 6 7\nf 5 7 8\n";
    std::fs::write(dir.join("p.obj"), obj).unwrap();
    std::fs::write(dir.join("p.mtl"), "newmtl zinc\nKd 1 1 1\nnewmtl alpha\nKd 1 1 1\n").unwrap();
    let scene = "[[mesh]]\nobj = \"p.obj\"\n\
                 [materials.zinc]\nmodel = \"lambert\"\nrho = 0.5\n\
                 [materials.alpha]\nmodel = \"lambert\"\nrho = 0.5\n\
                 [camera]\nwidth = 40\nheight = 20\npitch_um = 10.0\nfocal_mm = 1.0\n\
                 [pose]\nposition = [0.0, 0.0, 10.0]\n";
    let p = dir.join("s.toml");
    std::fs::write(&p, scene).unwrap();
    p
}

#[test]
fn r42_the_mask_numbers_materials_by_name_and_the_truth_carries_their_table() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(hilcam_core::scene::load(&two_plates(dir.path())).unwrap());
    let pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
    let channels = TruthChannels::parse("depth,mask").unwrap();
    let truth = pipeline.truth(&scene.pose, &FrameRequest::default(), channels).unwrap();
    // f = 1 mm / 10 µm = 100 px: at 10 m a metre is 10 px, pixel (col, 10) looks at
    // x = (col + 0.5 − 20) / 10 m, y = 0.05 m. Column 12: x = −0.75 m (zinc); 28: +0.85 m
    // (alpha); 20: +0.05 m, between the plates. (Away from the plates' diagonals: a
    // pixel-centre ray exactly on a shared edge can miss both triangles.)
    let at = |col: usize| truth.mask[10 * 40 + col];
    let want = "1=alpha;2=zinc";
    assert_eq!((at(12), at(28)), (2, 1), "zinc sorts after alpha: mask 2 left, 1 right");
    assert_eq!(at(20), 0, "the gap between the plates is background");
    assert_eq!(truth.materials.as_deref(), Some(want));
    // The stream's block carries the table with the mask, and only with it.
    let wire = decode_truth_block(40, 20, &encode_truth_block(&truth)).unwrap();
    assert_eq!(wire.image.materials.as_deref(), Some(want));
    let depth_only =
        hilcam_core::render::truth::TruthImage { channels: TruthChannels::parse("depth").unwrap(), ..truth.clone() };
    assert_eq!(decode_truth_block(40, 20, &encode_truth_block(&depth_only)).unwrap().image.materials, None);
    // The GigE chunks: the table NUL-terminated and padded to 4, counted by PayloadSize's
    // formula.
    let mut block = Vec::new();
    chunk::append_truth_chunks(&mut block, &truth, Window { x: 0, y: 0, width: 40, height: 20 });
    let table = chunk::find_chunk(&block, MATERIALS_CHUNK_ID).expect("the material table chunk");
    assert_eq!(table, b"1=alpha;2=zinc\0\0");
    let all = chunk::chunks_len(ChunkSet::ALL, channels, want.len() as u32, 40, 20);
    let without_truth = chunk::chunks_len(ChunkSet::ALL, TruthChannels::NONE, 0, 40, 20);
    assert_eq!(all - without_truth, block.len() as u64);
}
