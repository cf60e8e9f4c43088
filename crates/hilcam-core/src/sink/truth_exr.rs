//! A frame's truth channels (`render::truth`) as one multi-channel float32 EXR,
//! `truth_<frame>.exr`, written whole or not at all (temporary file + rename).
//!
//! Channels (only those asked for; EXR stores them sorted by name): `depth`, `mask`,
//! `normal.X`/`.Y`/`.Z`, `body_xyz.X`/`.Y`/`.Z`. The header attribute `hilcam_materials`
//! (text) maps mask values to material names: `1=gold_mli;2=white_paint` (0 is the
//! background; `render::truth::materials_table`).

use crate::render::film::write_file_atomically;
use crate::render::truth::{TruthChannel, TruthImage};
use std::path::Path;

/// File name of frame `frame_seq`'s truth, beside `frame_<frame_seq>.<ext>`.
pub fn truth_file_name(frame_seq: u64) -> String {
    format!("truth_{frame_seq:010}.exr")
}

/// Header attribute holding the mask → material-name table.
pub const MATERIALS_ATTRIBUTE: &str = "hilcam_materials";

/// Why a truth file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum TruthWriteError {
    #[error("{path}: {source}")]
    Io { path: std::path::PathBuf, source: std::io::Error },
    #[error("{path}: EXR encoding failed: {message}")]
    Exr { path: std::path::PathBuf, message: String },
}

impl TruthWriteError {
    pub fn is_disk_full(&self) -> bool {
        matches!(self, TruthWriteError::Io { source, .. } if crate::render::film::is_disk_full(source))
    }
}

/// Write `truth`'s channels to `path` (float32, lossless), with its mask table
/// (`TruthImage::materials`; empty when it has none) in the header.
pub fn write_truth_exr(path: &Path, truth: &TruthImage) -> Result<(), TruthWriteError> {
    use exr::prelude::*;
    let f32s = |v: &Vec<f32>| FlatSamples::F32(v.clone());
    let mut list = Vec::new();
    for c in truth.channels.iter() {
        match c {
            TruthChannel::Depth => list.push(AnyChannel::new("depth", f32s(&truth.depth))),
            TruthChannel::Mask => {
                list.push(AnyChannel::new("mask", FlatSamples::F32(truth.mask.iter().map(|&m| m as f32).collect())))
            }
            TruthChannel::Normal | TruthChannel::BodyXyz => {
                let (name, planes) = match c {
                    TruthChannel::Normal => ("normal", &truth.normal),
                    _ => ("body_xyz", &truth.body_xyz),
                };
                for (axis, plane) in ["X", "Y", "Z"].into_iter().zip(planes) {
                    list.push(AnyChannel::new(format!("{name}.{axis}").as_str(), f32s(plane)));
                }
            }
        }
    }
    let mut attributes = LayerAttributes::named("truth");
    attributes.other.insert(
        Text::from(MATERIALS_ATTRIBUTE),
        AttributeValue::Text(Text::from(truth.materials.as_deref().unwrap_or(""))),
    );
    let layer = Layer::new(
        (truth.width as usize, truth.height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut out)
        .map_err(|e| TruthWriteError::Exr { path: path.to_path_buf(), message: e.to_string() })?;
    write_file_atomically(path, out.get_ref())
        .map_err(|source| TruthWriteError::Io { path: path.to_path_buf(), source })
}
