//! Session files: what `hilcam serve` received and rendered, one JSON object per line
//! (`docs/session.md`). Pure codec; the writer lives in `serve::session`, the
//! frame-for-frame re-render in `replay` ([`frame_jobs`]).
//!
//! - Line 1 is a [`SessionHeader`]; then `pose`, `frame`, `frame_failed` lines in the
//!   order the server saw them; an `end` line with the run's counters when it stopped
//!   cleanly. A file without `end` (server killed) still re-renders; a last line cut short
//!   by the kill is skipped and counted.
//! - Floats are written shortest-round-trip and parsed exactly (serde_json
//!   `float_roundtrip`), so the poses read back are the poses rendered, bit for bit.

pub mod writer;

use crate::pipeline::FrameRequest;
use crate::pose::Pose;
use crate::render::integrator::{Method, QualityGoal, RenderSettings, SamplerKind};
use crate::render::sampling::Sequence;
use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Format version written in the header; readers refuse other versions.
pub const SESSION_VERSION: u32 = 1;

/// Errors reading a session file; each names the file and, where it applies, the line.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}: not a session line: {msg}")]
    BadLine { path: PathBuf, line: usize, msg: String },
    #[error("{path}:1: the first line must be the session header (kind \"header\")")]
    NoHeader { path: PathBuf },
    #[error("{path}:{line}: session format version {found}; this hilcam reads version {SESSION_VERSION}")]
    Version { path: PathBuf, line: usize, found: u32 },
}

/// A pose as written: scalar-first quaternion as on the wire, f64 throughout.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseFields {
    pub seq: u32,
    pub t_ns: u64,
    pub position: [f64; 3],
    /// (w, x, y, z).
    pub attitude: [f64; 4],
    pub sun_dir: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angular_rate: Option<[f64; 3]>,
    /// (w, x, y, z), camera → inertial.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_to_inertial: Option<[f64; 4]>,
    /// The planet's centre, camera frame, m (a pose that moves the scene's planet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planet_centre: Option<[f64; 3]>,
}

impl From<&Pose> for PoseFields {
    fn from(p: &Pose) -> Self {
        let q = p.attitude;
        PoseFields {
            seq: p.seq,
            t_ns: p.t_ns,
            position: p.position.to_array(),
            attitude: [q.w, q.x, q.y, q.z],
            sun_dir: p.sun_dir.to_array(),
            velocity: p.velocity.map(|v| v.to_array()),
            angular_rate: p.angular_rate.map(|v| v.to_array()),
            camera_to_inertial: p.camera_to_inertial.map(|q| [q.w, q.x, q.y, q.z]),
            planet_centre: p.planet_centre.map(|c| c.to_array()),
        }
    }
}

impl PoseFields {
    pub fn to_pose(&self) -> Pose {
        let [w, x, y, z] = self.attitude;
        Pose {
            seq: self.seq,
            t_ns: self.t_ns,
            position: DVec3::from_array(self.position),
            attitude: DQuat::from_xyzw(x, y, z, w),
            sun_dir: DVec3::from_array(self.sun_dir),
            velocity: self.velocity.map(DVec3::from_array),
            angular_rate: self.angular_rate.map(DVec3::from_array),
            camera_to_inertial: self.camera_to_inertial.map(|[w, x, y, z]| DQuat::from_xyzw(x, y, z, w)),
            planet_centre: self.planet_centre.map(DVec3::from_array),
        }
    }
}

/// Everything of [`RenderSettings`] that changes pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SettingsFields {
    pub spp: crate::render::integrator::Spp,
    pub depth: u32,
    pub sampler: SamplerKind,
    pub sequence: Sequence,
    pub roulette: bool,
    /// Absent in sessions written before adaptive sampling existed: those were uniform.
    #[serde(default)]
    pub adaptive: bool,
    /// Absent (and not written) for `quality = "fixed"` with the default k: sessions
    /// before sensor-relative quality read as what they were.
    #[serde(default, skip_serializing_if = "is_default_quality")]
    pub quality: QualityGoal,
    /// Absent (and not written) for `method = "path"`: older sessions read as what they were.
    #[serde(default, skip_serializing_if = "is_default_method")]
    pub method: Method,
    pub seed: u64,
}

fn is_default_method(m: &Method) -> bool {
    *m == Method::default()
}

fn is_default_quality(q: &QualityGoal) -> bool {
    *q == QualityGoal::default()
}

impl From<&RenderSettings> for SettingsFields {
    fn from(s: &RenderSettings) -> Self {
        SettingsFields {
            spp: s.spp,
            depth: s.depth,
            sampler: s.sampler,
            sequence: s.sequence,
            roulette: s.roulette,
            adaptive: s.adaptive,
            quality: s.quality,
            method: s.method,
            seed: s.seed,
        }
    }
}

impl SettingsFields {
    pub fn to_settings(&self) -> RenderSettings {
        RenderSettings {
            spp: self.spp,
            depth: self.depth,
            sampler: self.sampler,
            sequence: self.sequence,
            roulette: self.roulette,
            adaptive: self.adaptive,
            quality: self.quality,
            method: self.method,
            seed: self.seed,
        }
    }
}

/// Line 1: how the server was set up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SessionHeader {
    pub version: u32,
    /// hilcam version that wrote the file.
    pub hilcam: String,
    /// Wall clock at session start (the zero of every `mono_ns`), ns since the UNIX epoch.
    pub start_unix_ns: u64,
    /// The scene file the server loaded (absolute when it could be resolved).
    pub scene: String,
    /// The server's `width` setting (None: the camera's own); the re-render uses the same.
    pub width_setting: Option<u32>,
    /// Rendered frame size.
    pub width: u32,
    pub height: u32,
    /// Best quality; a frame's own settings (governor rung) are on its line.
    pub settings: SettingsFields,
    /// pose | rate | external.
    pub trigger: String,
    pub extrapolate: bool,
    /// fixed-quality | fixed-rate.
    pub policy: String,
    /// Where poses came from: serial | slcan | socketcan | trajectory | embedded.
    pub input: String,
}

/// A pose the scheduler received (it passed validation in the transport).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseLine {
    /// Arrival, ns since the session start (monotonic clock).
    pub mono_ns: u64,
    /// Arrival, wall clock, ns since the UNIX epoch (UTC).
    pub unix_ns: u64,
    /// Input kind it came through (as in the header's `input`).
    pub source: String,
    pub pose: PoseFields,
}

/// One rendered frame: exactly what went into it (its inputs), where the frame's header,
/// [`crate::frame::FrameMeta`], says what came out.
///
/// The values both carry, under these names: `index` = `frame_seq`; `pose.seq` =
/// `pose_seq` (= `source_seq`: extrapolation keeps the seq); `pose.t_ns` = `pose_t_ns`;
/// `settings.spp` = `spp`; `settings.depth` = `depth` (the header caps it at 65535);
/// `flags` = `flags` (and `late`, `extrapolated`, `degraded` are its bits spelled out);
/// `integration_s` = `integration_s` (the header's f32, 0 for None); `payload_crc32` =
/// the header's payload CRC. [`crate::frame::FrameMeta::rendered`] builds the metadata a
/// re-render of this line implies. Only here: the session clock times, the poses
/// received, the extrapolation, the full pose and settings. Only in the frame header:
/// the wall-clock times, the pixel format and bit depth, and the size (which the session
/// header gives once).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameLine {
    /// Frame index (`frame_seq` on the wire; also the random-number domain).
    pub index: u64,
    /// When the render started, ns since the session start (monotonic).
    pub mono_ns: u64,
    /// `seq` of the received pose the frame was made from.
    pub source_seq: u32,
    /// That pose's arrival, ns since the session start.
    pub source_mono_ns: u64,
    /// Poses the scheduler had received when the frame started: the source is the last
    /// of them (`pose` line number `poses_received` when no line was dropped).
    pub poses_received: u64,
    /// Seconds the pose was moved forward by extrapolation (0 if not extrapolated).
    pub extrapolated_s: f64,
    /// The pose actually rendered (after extrapolation; `t_ns` is the target time).
    pub pose: PoseFields,
    /// The settings actually rendered (after the governor).
    pub settings: SettingsFields,
    /// FrameFlags bits (LATE = 1, EXTRAPOLATED = 2, DEGRADED = 4).
    pub flags: u32,
    pub late: bool,
    pub extrapolated: bool,
    pub degraded: bool,
    /// Sensor integration time used, s (None without a detector).
    pub integration_s: Option<f64>,
    /// CRC-32/ISO-HDLC of the streamed payload (pixels after the sensor).
    pub payload_crc32: u32,
    /// What a camera client asked of this frame (a GigE Vision client's ExposureTime and
    /// ROI); absent when it asked nothing, so the frame is the configured one.
    #[serde(default, skip_serializing_if = "FrameRequest::is_default")]
    pub request: FrameRequest,
    /// How the frame's Monte Carlo noise compared with the camera's (DN frames with a
    /// detector); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mc_noise: Option<crate::sensor::McNoiseStats>,
}

impl FrameLine {
    /// The flags as the frame carried them.
    pub fn frame_flags(&self) -> crate::frame::FrameFlags {
        crate::frame::FrameFlags(self.flags)
    }
}

/// A frame whose sensor stage failed (nothing was streamed for this index).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameFailedLine {
    pub index: u64,
    pub mono_ns: u64,
    pub source_seq: u32,
    pub error: String,
}

/// Written when the server stops: on a signal, at the end of its inputs, or after a fatal
/// renderer failure (then `fatal` says why).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EndLine {
    pub mono_ns: u64,
    pub unix_ns: u64,
    /// Poses the transports accepted (validation passed).
    pub poses_accepted: u64,
    /// Poses the transports rejected, by reason.
    pub poses_rejected: BTreeMap<String, u64>,
    /// Accepted poses lost because the input channel was full.
    pub input_channel_full: u64,
    /// Poses the scheduler received (= `pose` lines unless records were dropped).
    pub poses_received: u64,
    /// Received poses replaced by a newer one before rendering.
    pub poses_superseded: u64,
    pub frames: u64,
    /// Frames that failed (each has a `frame_failed` line).
    #[serde(default)]
    pub frames_failed: u64,
    /// Why the server stopped on its own, when it did (the renderer kept failing).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fatal: Option<String>,
    /// Session lines the writer could not keep up with (not in this file).
    pub records_dropped: u64,
}

/// One line of a session file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SessionLine {
    Header(SessionHeader),
    Pose(PoseLine),
    Frame(FrameLine),
    FrameFailed(FrameFailedLine),
    End(EndLine),
}

impl SessionLine {
    /// One JSON line, without the newline.
    pub fn encode(&self) -> String {
        serde_json::to_string(self).expect("session lines serialise")
    }

    /// Parse line `line` (1-based) of `path`.
    pub fn decode(text: &str, path: &Path, line: usize) -> Result<SessionLine, SessionError> {
        serde_json::from_str(text).map_err(|e| SessionError::BadLine {
            path: path.to_path_buf(),
            line,
            msg: e.to_string(),
        })
    }
}

/// A session file read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Session {
    pub header: SessionHeader,
    pub poses: Vec<PoseLine>,
    pub frames: Vec<FrameLine>,
    pub failed: Vec<FrameFailedLine>,
    /// None when the server did not stop cleanly.
    pub end: Option<EndLine>,
    /// A cut-short last line was skipped.
    pub truncated: bool,
}

impl Session {
    /// Read and check a session file.
    pub fn load(path: &Path) -> Result<Session, SessionError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| SessionError::Io { path: path.to_path_buf(), source })?;
        Session::parse(&text, path)
    }

    /// Parse a session's text (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Session, SessionError> {
        let complete = text.ends_with('\n');
        let lines: Vec<&str> = text.lines().collect();
        let mut header = None;
        let mut s = Session {
            header: placeholder_header(),
            poses: Vec::new(),
            frames: Vec::new(),
            failed: Vec::new(),
            end: None,
            truncated: false,
        };
        for (i, l) in lines.iter().enumerate() {
            let n = i + 1;
            if l.trim().is_empty() {
                continue;
            }
            let line = match SessionLine::decode(l, path, n) {
                Ok(line) => line,
                Err(_) if n == lines.len() && !complete && header.is_some() => {
                    tracing::warn!(file = %path.display(), line = n, "ignoring a truncated last line");
                    s.truncated = true;
                    continue;
                }
                Err(e) => return Err(e),
            };
            match (line, header.is_some()) {
                (SessionLine::Header(h), false) => {
                    if h.version != SESSION_VERSION {
                        return Err(SessionError::Version { path: path.into(), line: n, found: h.version });
                    }
                    header = Some(h);
                }
                (_, false) => return Err(SessionError::NoHeader { path: path.into() }),
                (SessionLine::Header(_), true) => {
                    return Err(SessionError::BadLine {
                        path: path.into(),
                        line: n,
                        msg: "a second header (two sessions in one file?)".into(),
                    });
                }
                (SessionLine::Pose(p), true) => s.poses.push(p),
                (SessionLine::Frame(f), true) => s.frames.push(f),
                (SessionLine::FrameFailed(f), true) => s.failed.push(f),
                (SessionLine::End(e), true) => s.end = Some(e),
            }
        }
        s.header = header.ok_or_else(|| SessionError::NoHeader { path: path.into() })?;
        Ok(s)
    }

    /// Frame indices missing between 0 and the last frame (failed frames included as
    /// present: nothing was streamed for them). Non-empty means dropped records.
    pub fn frame_gaps(&self) -> Vec<u64> {
        let have: std::collections::HashSet<u64> =
            self.frames.iter().map(|f| f.index).chain(self.failed.iter().map(|f| f.index)).collect();
        let last = have.iter().max().copied();
        last.map_or(Vec::new(), |l| (0..l).filter(|k| !have.contains(k)).collect())
    }
}

fn placeholder_header() -> SessionHeader {
    SessionHeader {
        version: SESSION_VERSION,
        hilcam: String::new(),
        start_unix_ns: 0,
        scene: String::new(),
        width_setting: None,
        width: 0,
        height: 0,
        settings: SettingsFields::from(&RenderSettings::default()),
        trigger: String::new(),
        extrapolate: false,
        policy: String::new(),
        input: String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::FrameFlags;

    fn pose() -> Pose {
        Pose {
            seq: 7,
            t_ns: 123_456_789,
            position: DVec3::new(0.1 + 0.2, -1.0 / 3.0, 1e6 * std::f64::consts::PI),
            attitude: DQuat::from_rotation_y(0.7) * DQuat::from_rotation_x(-2.9),
            sun_dir: DVec3::new(1e-300, -0.6, 0.8),
            velocity: Some(DVec3::new(f64::MIN_POSITIVE, 5e-324, -7.25)),
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        }
    }

    fn frame_line() -> FrameLine {
        let settings = RenderSettings { seed: u64::MAX, ..Default::default() };
        FrameLine {
            index: 3,
            mono_ns: 10,
            source_seq: 7,
            source_mono_ns: 9,
            poses_received: 1,
            extrapolated_s: 0.1 + 0.2,
            pose: PoseFields::from(&pose()),
            settings: SettingsFields::from(&settings),
            flags: FrameFlags::EXTRAPOLATED | FrameFlags::DEGRADED,
            late: false,
            extrapolated: true,
            degraded: true,
            integration_s: Some(1.0 / 3.0),
            payload_crc32: 0xdead_beef,
            request: FrameRequest::default(),
            mc_noise: None,
        }
    }

    #[test]
    fn a_frame_line_carries_a_clients_request_only_when_there_is_one() {
        let plain = SessionLine::Frame(frame_line()).encode();
        assert!(!plain.contains("request"), "{plain}");
        let roi = crate::render::camera::Window { x: 8, y: 4, width: 32, height: 16 };
        let line = FrameLine { request: FrameRequest { integration_s: Some(5e-6), roi: Some(roi) }, ..frame_line() };
        let text = SessionLine::Frame(line.clone()).encode();
        assert!(
            text.ends_with(r#""request":{"integration_s":5e-6,"roi":{"x":8,"y":4,"width":32,"height":16}}}"#),
            "{text}"
        );
        assert_eq!(SessionLine::decode(&text, Path::new("s.jsonl"), 1).unwrap(), SessionLine::Frame(line));
    }

    fn bits(p: &Pose) -> Vec<u64> {
        let mut v: Vec<f64> = p.position.to_array().into();
        v.extend(p.attitude.to_array());
        v.extend(p.sun_dir.to_array());
        v.extend(p.velocity.map_or([0.0; 3], |x| x.to_array()));
        v.extend(p.planet_centre.map_or([0.0; 3], |x| x.to_array()));
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn lines_round_trip_bit_for_bit() {
        let p = pose();
        let lines = [
            SessionLine::Header(SessionHeader { hilcam: "x".into(), width: 4, height: 3, ..placeholder_header() }),
            SessionLine::Pose(PoseLine { mono_ns: 1, unix_ns: 2, source: "embedded".into(), pose: (&p).into() }),
            SessionLine::Frame(frame_line()),
            SessionLine::FrameFailed(FrameFailedLine { index: 4, mono_ns: 11, source_seq: 7, error: "e".into() }),
            SessionLine::End(EndLine { frames: 1, ..Default::default() }),
        ];
        let text: String = lines.iter().map(|l| l.encode() + "\n").collect();
        let path = Path::new("s.jsonl");
        for (l, t) in lines.iter().zip(text.lines()) {
            assert_eq!(&SessionLine::decode(t, path, 1).unwrap(), l);
        }
        let s = Session::parse(&text, path).unwrap();
        assert_eq!((s.poses.len(), s.frames.len(), s.failed.len(), s.end.is_some()), (1, 1, 1, true));
        assert_eq!(bits(&s.poses[0].pose.to_pose()), bits(&p), "every f64 bit survives");
        assert_eq!(s.poses[0].pose.to_pose(), p);
        let f = &s.frames[0];
        assert_eq!((f.index, f.pose.to_pose(), f.payload_crc32), (3, p, 0xdead_beef));
        assert_eq!(f.settings.to_settings().seed, u64::MAX);
        assert_eq!(s.frame_gaps(), vec![0, 1, 2]);
    }

    #[test]
    fn random_f64_bit_patterns_survive_the_codec() {
        let mut rng = crate::render::sampling::Rng::for_sample(42, 0, 0, 0);
        for _ in 0..2000 {
            let mut f = || loop {
                let x = f64::from_bits((u64::from(rng.next_u32()) << 32) | u64::from(rng.next_u32()));
                if x.is_finite() {
                    return x;
                }
            };
            let p = Pose {
                position: DVec3::new(f(), f(), f()),
                attitude: DQuat::from_xyzw(f(), f(), f(), f()),
                sun_dir: DVec3::new(f(), f(), f()),
                velocity: Some(DVec3::new(f(), f(), f())),
                planet_centre: Some(DVec3::new(f(), f(), f())),
                ..pose()
            };
            let t = SessionLine::Pose(PoseLine { mono_ns: 0, unix_ns: 0, source: String::new(), pose: (&p).into() });
            let back = SessionLine::decode(&t.encode(), Path::new("x"), 1).unwrap();
            let SessionLine::Pose(back) = back else { panic!("kind") };
            assert_eq!(bits(&back.pose.to_pose()), bits(&p));
        }
    }

    #[test]
    fn malformed_lines_are_named_by_file_and_line() {
        let header = SessionLine::Header(placeholder_header()).encode();
        let pose =
            SessionLine::Pose(PoseLine { mono_ns: 1, unix_ns: 2, source: "serial".into(), pose: (&pose()).into() })
                .encode();
        let path = Path::new("run1.session.jsonl");
        let bad = format!("{header}\n{pose}\n{{\"kind\":\"pose\",\"mono_ns\":\"x\"}}\n{pose}\n");
        let e = Session::parse(&bad, path).unwrap_err().to_string();
        assert!(e.starts_with("run1.session.jsonl:3: not a session line"), "{e}");
        let e = Session::parse(&format!("{pose}\n"), path).unwrap_err().to_string();
        assert_eq!(e, "run1.session.jsonl:1: the first line must be the session header (kind \"header\")");
        let mut v2 = placeholder_header();
        v2.version = 2;
        let e = Session::parse(&(SessionLine::Header(v2).encode() + "\n"), path).unwrap_err().to_string();
        assert!(e.starts_with("run1.session.jsonl:1: session format version 2"), "{e}");
        // A last line cut short by a kill is skipped; the same line in the middle is not.
        let cut = format!("{header}\n{pose}\n{}", &pose[..pose.len() / 2]);
        let s = Session::parse(&cut, path).unwrap();
        assert!(s.truncated && s.poses.len() == 1);
        let e = Session::parse(&format!("{cut}\n{pose}\n"), path).unwrap_err().to_string();
        assert!(e.starts_with("run1.session.jsonl:3:"), "{e}");
    }
}
