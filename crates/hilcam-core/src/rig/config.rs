//! The serve config's `[[camera]]` array: a rig's cameras, each with its model, mount,
//! trigger, quality and outputs (docs/rig.md). Parsed by serde inside the serve config;
//! [`check`] refuses what serde cannot (values, and clashes between cameras), naming the
//! camera and the field.
//!
//! ```toml
//! [[camera]]
//! name = "narrow"                      # unique: names its frames, files and errors
//! model = "nav1024"                    # a camera preset, or a camera file (relative path)
//! mount.position = [0.0, 0.1, 0.0]     # projection centre in the chaser body frame, m
//! mount.attitude = [1.0, 0.0, 0.0, 0.0]   # w, x, y, z: camera → body (or mount.euler_deg)
//! trigger.rate_hz = 5.0                # or trigger.group = "stereo"
//! render.spp = 4
//! stream.listen = "127.0.0.1:5601"
//! ```

use super::mount::Mount;
use crate::render::integrator::{QualityGoal, QualityMode, Spp};
use crate::render::truth::TruthChannels;
use crate::sensor::CameraPreset;
use crate::sink::gige::GigeConfig;
use glam::{DQuat, DVec3};
use serde::Deserialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// How far from 1 a mount quaternion's norm may be (renormalised within), as the pose gate.
pub const MOUNT_NORM_TOLERANCE: f64 = 1e-3;
/// The farthest a camera may sit from the body origin, metres (a typing error beyond).
pub const MOUNT_MAX_OFFSET_M: f64 = 1000.0;
/// Longest camera name, bytes: it names files and metric labels.
pub const NAME_MAX_LEN: usize = 31;

/// One `[[camera]]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub name: String,
    /// A camera preset's name (`nav1024`) or a camera file's path (with a `/` or ending in
    /// `.toml`, relative to the serve config; made absolute by [`CameraEntry::resolve_paths`]).
    pub model: String,
    /// Render a scaled camera: this many columns, the same field of view.
    pub width: Option<u32>,
    #[serde(default)]
    pub mount: MountEntry,
    #[serde(default)]
    pub trigger: CameraTrigger,
    #[serde(default)]
    pub render: CameraRender,
    #[serde(default)]
    pub stream: CameraStream,
    #[serde(default)]
    pub output: CameraOutput,
    pub record: Option<CameraRecord>,
}

/// `mount`: the camera frame in the chaser body frame. Neither attitude key: aligned.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountEntry {
    /// Projection centre in the body frame, metres.
    #[serde(default)]
    pub position: [f64; 3],
    /// `[w, x, y, z]`: rotates camera-frame vectors into the body frame.
    pub attitude: Option<[f64; 4]>,
    /// `[x, y, z]` degrees about body X, then Y, then Z (fixed axes).
    pub euler_deg: Option<[f64; 3]>,
}

/// `trigger`: when the camera exposes.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraTrigger {
    /// Frames per second; absent: the top-level `[trigger]` (a frame per pose, its rate,
    /// or the external trigger).
    pub rate_hz: Option<f64>,
    /// Cameras naming one group expose at one instant from one pose (a stereo pair).
    pub group: Option<String>,
}

/// `render`: this camera's overrides of the top-level `[render]` and the scene's.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraRender {
    pub spp: Option<Spp>,
    pub depth: Option<u32>,
    pub quality: Option<QualityMode>,
    pub sensor_k: Option<f64>,
}

/// `stream`: this camera's TCP frame stream (the top-level `[stream]`'s other keys apply).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraStream {
    /// Absent: the top-level `[stream] listen`.
    pub listen: Option<SocketAddr>,
}

/// `output`: this camera's GigE Vision device and ground truth.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraOutput {
    pub gige: Option<GigeConfig>,
    /// Ground-truth channel names (`depth`, `mask`, `normal`, `body_xyz`).
    #[serde(default)]
    pub truth: Vec<String>,
}

/// `record`: this camera's recorder.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraRecord {
    pub dir: PathBuf,
}

/// A refused `[[camera]]`: which one, which key, why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("camera[{index}] {name:?}: {field}: {message}")]
pub struct CameraError {
    pub index: usize,
    pub name: String,
    pub field: String,
    pub message: String,
}

impl CameraEntry {
    /// Make a camera file's path and the recorder's directory relative to `dir` (the
    /// serve config's folder); a preset name stays as it is.
    pub fn resolve_paths(&mut self, dir: &Path) {
        if self.model_is_file() {
            self.model = dir.join(&self.model).to_string_lossy().into_owned();
        }
        if let Some(r) = &mut self.record {
            r.dir = dir.join(&r.dir);
        }
    }

    fn model_is_file(&self) -> bool {
        self.model.contains('/') || self.model.ends_with(".toml")
    }

    /// The camera model and sensor, loaded and checked.
    pub fn model(&self) -> Result<CameraPreset, String> {
        let mut preset = crate::scene::file::camera_by_name_or_file(&self.model)?;
        preset.camera = preset.camera.scaled(self.width, None);
        Ok(preset)
    }

    /// The mount (valid once [`check`] passed).
    pub fn mount(&self) -> Mount {
        let m = &self.mount;
        let position = DVec3::from_array(m.position);
        match (m.attitude, m.euler_deg) {
            (Some([w, x, y, z]), _) => Mount { position, attitude: DQuat::from_xyzw(x, y, z, w).normalize() },
            (None, Some(e)) => Mount::from_euler_deg(position, e),
            (None, None) => Mount { position, attitude: DQuat::IDENTITY },
        }
    }

    /// The ground-truth channels (valid once [`check`] passed).
    pub fn truth(&self) -> TruthChannels {
        TruthChannels::from_names(self.output.truth.iter().map(String::as_str)).unwrap_or_default()
    }

    /// The stream address: its own, else the top-level one.
    pub fn listen(&self, top_level: SocketAddr) -> SocketAddr {
        self.stream.listen.unwrap_or(top_level)
    }

    /// This camera's own keys, alone.
    fn check_own(&self) -> Result<(), (&'static str, String)> {
        let ok_name = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
        if self.name.is_empty() || self.name.len() > NAME_MAX_LEN || !self.name.chars().all(ok_name) {
            return Err((
                "name",
                format!("{:?}: 1 to {NAME_MAX_LEN} letters, digits, `_` or `-` (it names files)", self.name),
            ));
        }
        if let Some(w) = self.width {
            crate::render::camera::check_side(w).map_err(|m| ("width", m))?;
        }
        self.model().map_err(|m| ("model", m))?;
        self.check_mount()?;
        if let Some(r) = self.trigger.rate_hz
            && !(r.is_finite() && r > 0.0 && r <= 10_000.0)
        {
            return Err(("trigger.rate_hz", format!("must be in (0, 10000], got {r}")));
        }
        if self.trigger.group.as_ref().is_some_and(|g| g.is_empty()) {
            return Err(("trigger.group", "must not be empty".into()));
        }
        if self.render.depth == Some(0) {
            return Err(("render.depth", "must be at least 1".into()));
        }
        if let Some(k) = self.render.sensor_k {
            QualityGoal::checked_k(k).map_err(|m| ("render.sensor_k", m))?;
        }
        TruthChannels::from_names(self.output.truth.iter().map(String::as_str)).map_err(|m| ("output.truth", m))?;
        if let Some(g) = &self.output.gige {
            g.validate()?;
        }
        Ok(())
    }

    fn check_mount(&self) -> Result<(), (&'static str, String)> {
        let m = &self.mount;
        let p = DVec3::from_array(m.position);
        if !(p.is_finite() && p.length() <= MOUNT_MAX_OFFSET_M) {
            return Err((
                "mount.position",
                format!("{:?}: must be finite and within {MOUNT_MAX_OFFSET_M} m of the body origin", m.position),
            ));
        }
        match (m.attitude, m.euler_deg) {
            (Some(_), Some(_)) => Err(("mount", "give either attitude or euler_deg, not both".into())),
            (Some(q), None) => {
                let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                if norm.is_finite() && (norm - 1.0).abs() <= MOUNT_NORM_TOLERANCE {
                    Ok(())
                } else {
                    Err((
                        "mount.attitude",
                        format!(
                            "{q:?} has norm {norm}: a unit quaternion [w, x, y, z] (within {MOUNT_NORM_TOLERANCE})"
                        ),
                    ))
                }
            }
            (None, Some(e)) if !e.iter().all(|v| v.is_finite()) => {
                Err(("mount.euler_deg", format!("{e:?}: must be finite degrees")))
            }
            _ => Ok(()),
        }
    }
}

/// Every camera's keys, then what cameras must not share: names, stream addresses, GigE
/// Vision addresses, serial numbers and user IDs, recorder folders; cameras of one trigger
/// group must agree on their rate. `listen` is the top-level `[stream] listen`.
pub fn check(cameras: &[CameraEntry], listen: SocketAddr) -> Result<(), CameraError> {
    let refuse = |k: usize, field: &str, message: String| CameraError {
        index: k,
        name: cameras[k].name.clone(),
        field: field.into(),
        message,
    };
    for (k, c) in cameras.iter().enumerate() {
        c.check_own().map_err(|(f, m)| refuse(k, f, m))?;
    }
    for (k, c) in cameras.iter().enumerate() {
        for (j, other) in cameras[..k].iter().enumerate() {
            let clash = |what: &str| format!("{what} is also camera[{j}] {:?}'s", other.name);
            if c.name == other.name {
                return Err(refuse(k, "name", clash("the name")));
            }
            let (a, b) = (c.listen(listen), other.listen(listen));
            if a == b && a.port() != 0 {
                return Err(refuse(k, "stream.listen", clash(&format!("{a}"))));
            }
            if let (Some(g), Some(h)) = (&c.output.gige, &other.output.gige) {
                gige_clash(g, h).map_err(|(f, what)| refuse(k, f, clash(&what)))?;
            }
            if let (Some(r), Some(s)) = (&c.record, &other.record)
                && r.dir == s.dir
            {
                return Err(refuse(k, "record.dir", clash(&format!("{}", r.dir.display()))));
            }
            if c.trigger.group.is_some()
                && c.trigger.group == other.trigger.group
                && let (Some(r), Some(s)) = (c.trigger.rate_hz, other.trigger.rate_hz)
                && r != s
            {
                let g = c.trigger.group.as_deref().unwrap_or_default();
                return Err(refuse(
                    k,
                    "trigger.rate_hz",
                    format!("{r} Hz, but trigger group {g:?} runs at camera[{j}] {:?}'s {s} Hz", other.name),
                ));
            }
        }
    }
    Ok(())
}

/// What two cameras' GigE Vision devices must not share: (field, the shared value).
fn gige_clash(g: &GigeConfig, h: &GigeConfig) -> Result<(), (&'static str, String)> {
    if g.address == h.address && g.gvcp_port == h.gvcp_port {
        return Err(("output.gige.gvcp_port", format!("{}:{}", g.address, g.gvcp_port)));
    }
    if g.address == h.address && g.stream_port != 0 && g.stream_port == h.stream_port {
        return Err(("output.gige.stream_port", format!("{}:{}", g.address, g.stream_port)));
    }
    if g.serial == h.serial {
        return Err(("output.gige.serial", format!("serial {:?}", g.serial)));
    }
    if !g.user_name.is_empty() && g.user_name == h.user_name {
        return Err(("output.gige.user_name", format!("user ID {:?}", g.user_name)));
    }
    Ok(())
}
