//! The replay directory's manifest (`replay.manifest.json`): what every frame in it was
//! rendered from. Written by the first run; a later run into the same directory (resume,
//! another shard) with a different scene, source, size, format, exposure or settings is
//! refused, naming the field, instead of mixing frames of two setups.

use super::{ReplayConfig, ReplayError};
use crate::pipeline::FramePipeline;
use crate::render::integrator::SamplerKind;
use crate::render::sampling::Sequence;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// File name of the manifest inside the output directory.
pub const MANIFEST_NAME: &str = "replay.manifest.json";

/// What a replay directory's frames were rendered from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayManifest {
    pub source: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    /// Image file extension.
    pub format: String,
    /// `auto`, `fixed <seconds>` or `none` (no detector).
    pub exposure: String,
    pub seed: u64,
    pub sampler: SamplerKind,
    pub sequence: Sequence,
    pub roulette: bool,
    /// Best quality (a session's degraded frames carry their own on their log lines).
    pub spp: crate::render::integrator::Spp,
    pub depth: u32,
    /// Ground-truth channels written beside each frame (empty: none; absent in the
    /// manifests of earlier versions, which wrote none).
    #[serde(default)]
    pub truth: String,
}

impl ReplayManifest {
    /// The manifest of a run of `cfg` through `pipeline`.
    pub fn new(cfg: &ReplayConfig, pipeline: &FramePipeline) -> Self {
        let exposure = match (&pipeline.scene().sensor.detector, pipeline.sensor().auto_exposure()) {
            (_, Some(_)) => "auto".to_string(),
            (Some(d), None) => format!("fixed {}", d.integration_time_s),
            (None, None) => "none".to_string(),
        };
        let s = &cfg.settings;
        ReplayManifest {
            source: cfg.source.clone(),
            scene: cfg.scene.clone(),
            width: pipeline.camera().width,
            height: pipeline.camera().height,
            format: cfg.format.extension().to_string(),
            exposure,
            seed: s.seed,
            sampler: s.sampler,
            sequence: s.sequence,
            roulette: s.roulette,
            spp: s.spp,
            depth: s.depth,
            truth: cfg.truth.to_string(),
        }
    }

    /// (field, value) pairs in file order, for naming the first difference.
    fn fields(&self) -> Vec<(&'static str, String)> {
        vec![
            ("source", self.source.clone()),
            ("scene", self.scene.clone()),
            ("width", self.width.to_string()),
            ("height", self.height.to_string()),
            ("format", self.format.clone()),
            ("exposure", self.exposure.clone()),
            ("seed", self.seed.to_string()),
            ("sampler", format!("{:?}", self.sampler).to_lowercase()),
            ("sequence", format!("{:?}", self.sequence).to_lowercase()),
            ("roulette", self.roulette.to_string()),
            ("spp", self.spp.to_string()),
            ("depth", self.depth.to_string()),
            ("truth", self.truth.clone()),
        ]
    }
}

/// Require `dir`'s manifest, if it has one, to equal `m`; Ok(false) when it has none.
pub fn check(dir: &Path, m: &ReplayManifest) -> Result<bool, ReplayError> {
    let path = dir.join(MANIFEST_NAME);
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(source) => return Err(ReplayError::Io { path, source }),
    };
    let old: ReplayManifest =
        serde_json::from_str(&text).map_err(|e| ReplayError::BadManifest { path: path.clone(), msg: e.to_string() })?;
    for ((field, found), (_, expected)) in old.fields().into_iter().zip(m.fields()) {
        if found != expected {
            return Err(ReplayError::ManifestMismatch { dir: dir.to_path_buf(), field, found, expected });
        }
    }
    Ok(true)
}

/// Write `m` as `dir`'s manifest (temporary file + rename: readers never see half of it;
/// two shards starting together write the same text, either wins).
pub fn write(dir: &Path, m: &ReplayManifest) -> Result<(), ReplayError> {
    let path = dir.join(MANIFEST_NAME);
    let tmp = dir.join(format!(".{MANIFEST_NAME}.{}", std::process::id()));
    let text = serde_json::to_string_pretty(m).expect("manifest serialises") + "\n";
    let written = std::fs::write(&tmp, text).and_then(|_| std::fs::rename(&tmp, &path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written.map_err(|source| ReplayError::Io { path, source })
}
