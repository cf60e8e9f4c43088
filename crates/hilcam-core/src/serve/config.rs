//! The `hilcam serve` configuration file (TOML), documented key by key in
//! `docs/serve-config.md`. Errors name the file and field; toml's own errors add the line
//! and column.
//!
//! ```toml
//! scene = "../scenes/satellite.toml"   # relative to this file
//! width = 512                          # optional: scaled camera (same field of view)
//!
//! [input]                              # where poses come from
//! kind = "serial"                      # serial | slcan | socketcan | trajectory | none
//! device = "/dev/ttyUSB0"              # serial, slcan
//! baud = 921600                        # serial, slcan
//! # iface = "can0"                     # socketcan
//! # can_base = 0x300                   # slcan, socketcan: CAN base id
//! # bitrate = 1000000                  # slcan: the adapter's CAN bit rate, bit/s
//! # file = "../scenes/trajectories/flyaround.csv"   # trajectory: real-time replay
//! # speed = 1.0                        # trajectory: time scale
//! # (each kind takes only its own keys: another kind's key is an error)
//!
//! [trigger]
//! mode = "rate"                        # pose | rate | external
//! rate_hz = 10.0
//! extrapolate = true                   # rate mode: move poses to the exposure mid-time
//!
//! [governor]
//! policy = "fixed-rate"                # fixed-quality | fixed-rate
//! budget_ms = 100.0                    # default: 1000 / rate_hz (rate mode) or 100
//!
//! [render]                             # overrides of the scene's [render]
//! spp = 4
//! depth = 2
//!
//! [stream]
//! listen = "127.0.0.1:5600"
//! queue_depth = 2
//! max_clients = 32                     # more connections are refused
//! evict_after_s = 5.0                  # disconnect a client whose queue stayed full this
//!                                      # long (stopped reading); 0 = never; default 5
//!
//! [record]                             # optional
//! dir = "frames"                       # recorder sink: every frame as an image file
//! format = "png"                       # png | tiff | exr | pfm
//! session = "run1.session.jsonl"       # session file: poses received, frames rendered
//!                                      # (docs/session.md; never overwritten)
//!
//! [metrics]
//! listen = "127.0.0.1:9100"            # optional Prometheus endpoint
//! print_interval_s = 5.0
//!
//! [live]                               # optional: the operator's page at /live on the
//! enabled = true                       # metrics listener (needs [metrics] listen)
//! max_width = 512                      # also max_rate_hz, jpeg_quality, queue_depth,
//!                                      # max_viewers, evict_after_s
//!
//! [output]
//! truth = ["depth", "mask"]            # optional ground truth with every frame: depth,
//!                                      # mask, normal, body_xyz (docs/protocol.md)
//!
//! [output.gige]                        # optional: also a GigE Vision camera (docs/gige.md)
//! address = "127.0.0.1"                # GVCP on UDP 3956, GVSP from the same address
//! packet_size = 1500                   # also stream_port, serial, model, resend_ring, zip_xml
//! ```

use super::governor::Policy;
use super::scheduler::TriggerMode;
use crate::render::integrator::SamplerKind;
use crate::render::truth::TruthChannels;
use crate::sink::ImageFormat;
use serde::Deserialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// Bounds of the stream's sizes (docs/serve-config.md): frames queued per client, clients.
/// Every size in this file has one (`[live]`: `live::QUEUE_DEPTH_MAX`, …;
/// `[output.gige]`: `GigeConfig::validate`), refused at start naming the key.
pub const STREAM_QUEUE_DEPTH_MAX: usize = 64;
pub const STREAM_MAX_CLIENTS_MAX: usize = 1024;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: {field}: {message}")]
    Field { path: PathBuf, field: &'static str, message: String },
    /// A `[[camera]]` of a rig, named with its key (docs/rig.md).
    #[error("{path}: {source}")]
    Camera { path: PathBuf, source: crate::rig::config::CameraError },
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServeConfig {
    pub scene: PathBuf,
    pub width: Option<u32>,
    #[serde(default)]
    pub input: InputConfig,
    #[serde(default)]
    pub trigger: TriggerConfig,
    #[serde(default)]
    pub governor: GovernorConfig,
    #[serde(default)]
    pub render: RenderOverrides,
    #[serde(default)]
    pub stream: StreamSection,
    pub record: Option<RecordSection>,
    #[serde(default)]
    pub metrics: MetricsSection,
    #[serde(default)]
    pub output: OutputSection,
    #[serde(default)]
    pub live: super::live::LiveConfig,
    /// `[[camera]]`: a rig of cameras on the chaser (docs/rig.md). Empty: the scene's
    /// camera alone, its pose given in its own frame (an identity mount).
    #[serde(default, rename = "camera")]
    pub cameras: Vec<crate::rig::config::CameraEntry>,
}

/// `[output]`: frame outputs beside the TCP stream.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// `[output.gige]`: also be a GigE Vision camera (docs/gige.md).
    pub gige: Option<crate::sink::gige::GigeConfig>,
    /// Ground-truth channels sent with every frame (`truth = ["depth", "mask"]`): a block
    /// after the payload on the stream, `truth_<k>.exr` from the recorder, chunks on GigE.
    /// Empty (the default): none, and no frame changes.
    #[serde(default, deserialize_with = "truth_channels")]
    pub truth: TruthChannels,
}

/// `truth = [...]`: channel names; an unknown one is refused with the allowed list (the
/// TOML error adds file, line and column).
fn truth_channels<'de, D: serde::Deserializer<'de>>(d: D) -> Result<TruthChannels, D::Error> {
    let names = Vec::<String>::deserialize(d)?;
    TruthChannels::from_names(names.iter().map(String::as_str)).map_err(serde::de::Error::custom)
}

/// `[input]`: where poses come from. `kind` picks the variant and each variant takes
/// exactly its own keys, so a key of another kind (a `device` on a socketcan input) is
/// refused by name rather than ignored.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum InputConfig {
    Serial(SerialInput),
    Slcan(SlcanInput),
    Socketcan(SocketcanInput),
    /// Poses from a trajectory file at its recorded timing (× `speed`), through the same
    /// path as live poses: real-time replay without a dynamics simulator.
    Trajectory(TrajectoryInput),
    /// No input: nothing renders (also what a config without `[input]` gets). A struct
    /// variant so that serde refuses keys here too (a unit variant ignores them).
    None {},
}

impl Default for InputConfig {
    fn default() -> Self {
        InputConfig::None {}
    }
}

/// `kind = "serial"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialInput {
    pub device: String,
    #[serde(default = "default_baud")]
    pub baud: u32,
}

/// `kind = "slcan"`: a serial-line CAN adapter.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlcanInput {
    pub device: String,
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// The adapter's CAN bit rate, set on open (None: as the adapter is).
    pub bitrate: Option<u32>,
    pub can_base: Option<u32>,
    #[serde(default)]
    pub can_extended: bool,
}

/// `kind = "socketcan"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SocketcanInput {
    pub iface: String,
    pub can_base: Option<u32>,
    #[serde(default)]
    pub can_extended: bool,
}

/// `kind = "trajectory"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryInput {
    /// The CSV file (relative to the config file).
    pub file: PathBuf,
    /// Simulation seconds per wall second.
    #[serde(default = "default_speed")]
    pub speed: f64,
}

fn default_baud() -> u32 {
    115_200
}

fn default_speed() -> f64 {
    1.0
}

impl InputConfig {
    /// The config spelling of the kind (`serial`, …).
    pub fn kind(&self) -> &'static str {
        match self {
            InputConfig::Serial(_) => "serial",
            InputConfig::Slcan(_) => "slcan",
            InputConfig::Socketcan(_) => "socketcan",
            InputConfig::Trajectory(_) => "trajectory",
            InputConfig::None {} => "none",
        }
    }

    /// Field-level checks that serde cannot express.
    fn validate(&self) -> Result<(), (&'static str, String)> {
        let baud = match self {
            InputConfig::Serial(i) => Some(i.baud),
            InputConfig::Slcan(i) => Some(i.baud),
            _ => None,
        };
        if let Some(b) = baud
            && !(1..=4_000_000).contains(&b)
        {
            return Err(("input.baud", format!("must be 1..=4000000, got {b}")));
        }
        if let InputConfig::Slcan(SlcanInput { bitrate: Some(b), .. }) = self
            && crate::pose::slcan::bitrate_code(*b).is_none()
        {
            return Err((
                "input.bitrate",
                format!(
                    "{b} bit/s is not an slcan rate (10000, 20000, 50000, 100000, 125000, 250000, 500000, 800000, 1000000)"
                ),
            ));
        }
        if let InputConfig::Trajectory(t) = self
            && !(t.speed.is_finite() && t.speed > 0.0)
        {
            return Err(("input.speed", format!("must be a positive number, got {}", t.speed)));
        }
        Ok(())
    }
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriggerConfig {
    #[serde(default)]
    pub mode: TriggerMode,
    pub rate_hz: Option<f64>,
    #[serde(default)]
    pub extrapolate: bool,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GovernorConfig {
    #[serde(default)]
    pub policy: Policy,
    pub budget_ms: Option<f64>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderOverrides {
    /// Samples per pixel, ≥ 1 (a fraction such as 1.5 is allowed).
    pub spp: Option<crate::render::integrator::Spp>,
    pub depth: Option<u32>,
    pub sampler: Option<SamplerKind>,
    pub seed: Option<u64>,
    /// `"fixed"` or `"sensor"` (samples until the Monte Carlo noise is below `sensor_k` ×
    /// the camera's; `spp` is then the budget, which the fixed-rate governor lowers).
    pub quality: Option<crate::render::integrator::QualityMode>,
    /// The bound, a fraction of the camera's temporal noise in (0, 10].
    #[serde(default, deserialize_with = "sensor_k")]
    pub sensor_k: Option<f32>,
}

fn sensor_k<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    let k = <f64 as serde::Deserialize>::deserialize(d)?;
    crate::render::integrator::QualityGoal::checked_k(k).map(Some).map_err(serde::de::Error::custom)
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamSection {
    #[serde(default = "default_listen")]
    pub listen: SocketAddr,
    #[serde(default = "default_queue")]
    pub queue_depth: usize,
    #[serde(default = "default_max_clients")]
    pub max_clients: usize,
    /// Seconds a client's queue may stay full before it is disconnected; 0 = never.
    #[serde(default = "default_evict_after_s")]
    pub evict_after_s: f64,
}

impl Default for StreamSection {
    fn default() -> Self {
        StreamSection {
            listen: default_listen(),
            queue_depth: default_queue(),
            max_clients: default_max_clients(),
            evict_after_s: default_evict_after_s(),
        }
    }
}

impl StreamSection {
    /// `evict_after_s` for [`crate::sink::StreamConfig::evict_after`] (None: never).
    pub fn evict_after(&self) -> Option<std::time::Duration> {
        (self.evict_after_s > 0.0).then(|| std::time::Duration::from_secs_f64(self.evict_after_s))
    }
}

fn default_evict_after_s() -> f64 {
    crate::sink::tcp::DEFAULT_EVICT_AFTER.as_secs_f64()
}

fn default_listen() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 5600))
}
fn default_queue() -> usize {
    2
}
fn default_max_clients() -> usize {
    32
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordSection {
    /// Recorder sink: frames as image files in this directory.
    pub dir: Option<PathBuf>,
    /// Session file (JSON lines) to create; re-render with `hilcam replay --session`.
    pub session: Option<PathBuf>,
    #[serde(default = "default_format")]
    pub format: ImageFormat,
}

fn default_format() -> ImageFormat {
    ImageFormat::Png
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricsSection {
    pub listen: Option<SocketAddr>,
    #[serde(default = "default_interval")]
    pub print_interval_s: f64,
}

impl Default for MetricsSection {
    fn default() -> Self {
        MetricsSection { listen: None, print_interval_s: default_interval() }
    }
}

fn default_interval() -> f64 {
    5.0
}

impl ServeConfig {
    /// Read, parse and validate; relative paths are resolved against the file's folder.
    pub fn load(path: &Path) -> Result<ServeConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io { path: path.into(), source })?;
        let mut cfg: ServeConfig =
            toml::from_str(&text).map_err(|e| ConfigError::Parse { path: path.into(), message: e.to_string() })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        cfg.scene = dir.join(&cfg.scene);
        if let InputConfig::Trajectory(t) = &mut cfg.input {
            t.file = dir.join(&t.file);
        }
        if let Some(r) = &mut cfg.record {
            r.dir = r.dir.as_ref().map(|d| dir.join(d));
            r.session = r.session.as_ref().map(|s| dir.join(s));
        }
        for c in &mut cfg.cameras {
            c.resolve_paths(dir);
        }
        cfg.validate().map_err(|(field, message)| ConfigError::Field { path: path.into(), field, message })?;
        crate::rig::config::check(&cfg.cameras, cfg.stream.listen)
            .map_err(|source| ConfigError::Camera { path: path.into(), source })?;
        Ok(cfg)
    }

    /// Field-level checks that serde cannot express.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if let Some(w) = self.width {
            crate::render::camera::check_side(w).map_err(|m| ("width", m))?;
        }
        self.input.validate()?;
        match (self.trigger.mode, self.trigger.rate_hz) {
            (TriggerMode::Rate, None) => return Err(("trigger.rate_hz", "rate mode needs rate_hz".into())),
            (_, Some(r)) if !(r.is_finite() && r > 0.0 && r <= 10_000.0) => {
                return Err(("trigger.rate_hz", format!("must be in (0, 10000], got {r}")));
            }
            _ => {}
        }
        if let Some(b) = self.governor.budget_ms
            && !(b.is_finite() && b > 0.0)
        {
            return Err(("governor.budget_ms", format!("must be positive, got {b}")));
        }
        if self.render.depth == Some(0) {
            return Err(("render.depth", "must be at least 1".into()));
        }
        let q = self.stream.queue_depth;
        if !(1..=STREAM_QUEUE_DEPTH_MAX).contains(&q) {
            return Err(("stream.queue_depth", format!("must be 1..={STREAM_QUEUE_DEPTH_MAX}, got {q}")));
        }
        let c = self.stream.max_clients;
        if !(1..=STREAM_MAX_CLIENTS_MAX).contains(&c) {
            return Err(("stream.max_clients", format!("must be 1..={STREAM_MAX_CLIENTS_MAX}, got {c}")));
        }
        if let Some(g) = &self.output.gige {
            g.validate()?;
        }
        let e = self.stream.evict_after_s;
        if !(e.is_finite() && (0.0..=86_400.0).contains(&e)) {
            return Err(("stream.evict_after_s", format!("must be 0 (never) or up to 86400 seconds, got {e}")));
        }
        if let Some(r) = &self.record
            && r.dir.is_none()
            && r.session.is_none()
        {
            return Err(("record", "needs `dir` (frames as images) or `session` (session file), or both".into()));
        }
        if self.width == Some(0) {
            return Err(("width", "must be at least 1".into()));
        }
        if !(self.metrics.print_interval_s.is_finite() && self.metrics.print_interval_s > 0.0) {
            return Err(("metrics.print_interval_s", "must be positive".into()));
        }
        if !self.cameras.is_empty() {
            self.check_rig_top_level()?;
        }
        if self.live.enabled && self.metrics.listen.is_none() {
            return Err((
                "live.enabled",
                "the live page is served on the metrics listener: set [metrics] listen".into(),
            ));
        }
        self.live.validate()
    }

    /// Top-level keys that a rig gives per camera instead: refused beside `[[camera]]`
    /// rather than guessed at.
    fn check_rig_top_level(&self) -> Result<(), (&'static str, String)> {
        let per_camera = |key: &'static str, instead: &str| {
            Err((key, format!("a rig ([[camera]]) gives this per camera: use each camera's `{instead}`")))
        };
        if self.width.is_some() {
            return per_camera("width", "width");
        }
        if self.output.gige.is_some() {
            return per_camera("output.gige", "output.gige");
        }
        if !self.output.truth.is_empty() {
            return per_camera("output.truth", "output.truth");
        }
        if self.record.as_ref().is_some_and(|r| r.dir.is_some()) {
            return per_camera("record.dir", "record.dir");
        }
        Ok(())
    }

    /// Each camera's name and mount: the `[[camera]]` entries, or without any the scene's
    /// camera alone as `"camera"` with an identity mount (today's single camera).
    pub fn camera_mounts(&self) -> Vec<(String, crate::rig::Mount)> {
        if self.cameras.is_empty() {
            return vec![("camera".into(), crate::rig::Mount::IDENTITY)];
        }
        self.cameras.iter().map(|c| (c.name.clone(), c.mount())).collect()
    }

    /// The frame budget: explicit, else one frame period, else 100 ms.
    pub fn budget(&self) -> std::time::Duration {
        let ms = self.governor.budget_ms.or(self.trigger.rate_hz.map(|r| 1000.0 / r)).unwrap_or(100.0);
        std::time::Duration::from_secs_f64(ms / 1e3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(input: &str) -> Result<ServeConfig, String> {
        let text = format!("scene = \"s.toml\"\n[input]\n{input}");
        let cfg: ServeConfig = toml::from_str(&text).map_err(|e| e.to_string())?;
        cfg.validate().map_err(|(field, m)| format!("{field}: {m}"))?;
        Ok(cfg)
    }

    #[test]
    fn the_live_page_needs_the_metrics_listener_and_sane_keys() {
        let e = parse("kind = \"none\"\n[live]\nenabled = true\n").unwrap_err();
        assert!(e.starts_with("live.enabled: "), "{e}");
        let on = "kind = \"none\"\n[metrics]\nlisten = \"127.0.0.1:0\"\n[live]\nenabled = true\n";
        let cfg = parse(on).unwrap();
        assert_eq!((cfg.live.max_width, cfg.live.queue_depth), (512, 2));
        assert!(parse(&format!("{on}max_rate_hz = 0.0\n")).unwrap_err().starts_with("live.max_rate_hz"));
        assert!(parse(&format!("{on}jpeg_quality = 0\n")).unwrap_err().starts_with("live.jpeg_quality"));
        assert!(parse(&format!("{on}colour = 1\n")).unwrap_err().contains("colour"));
        assert!(!parse("kind = \"none\"\n").unwrap().live.enabled, "off by default");
    }

    #[test]
    fn truth_channels_parse_and_an_unknown_name_is_refused_with_its_line_and_the_allowed_list() {
        assert!(parse("kind = \"none\"\n").unwrap().output.truth.is_empty(), "off by default");
        let c = parse("kind = \"none\"\n[output]\ntruth = [\"mask\", \"depth\"]\n").unwrap();
        assert_eq!(c.output.truth.to_string(), "depth,mask");
        let e = parse("kind = \"none\"\n[output]\ntruth = [\"depth\", \"range\"]\n").unwrap_err();
        assert!(e.contains("line 5"), "{e}");
        assert!(e.contains("unknown truth channel `range` (allowed: depth, mask, normal, body_xyz)"), "{e}");
    }

    #[test]
    fn each_kind_takes_its_own_keys_with_defaults() {
        let c = parse("kind = \"slcan\"\ndevice = \"/dev/ttyACM0\"\nbitrate = 500000\ncan_base = 0x300\n").unwrap();
        let InputConfig::Slcan(i) = &c.input else { panic!("{:?}", c.input) };
        assert_eq!(
            (i.device.as_str(), i.baud, i.bitrate, i.can_base),
            ("/dev/ttyACM0", 115_200, Some(500_000), Some(0x300))
        );
        let c = parse("kind = \"trajectory\"\nfile = \"t.csv\"\n").unwrap();
        let InputConfig::Trajectory(t) = &c.input else { panic!("{:?}", c.input) };
        assert_eq!((t.file.as_path(), t.speed), (Path::new("t.csv"), 1.0));
        let c: ServeConfig = toml::from_str("scene = \"s.toml\"\n").unwrap();
        assert_eq!(c.input.kind(), "none");
    }

    #[test]
    fn a_key_of_another_kind_is_refused_by_name() {
        let e = parse("kind = \"serial\"\ndevice = \"/dev/ttyUSB0\"\niface = \"can0\"\n").unwrap_err();
        assert!(e.contains("unknown field `iface`") && e.contains("line 2"), "{e}");
        let e = parse("kind = \"socketcan\"\niface = \"can0\"\nbaud = 9600\n").unwrap_err();
        assert!(e.contains("unknown field `baud`"), "{e}");
        let e = parse("kind = \"trajectory\"\nfile = \"t.csv\"\ncan_base = 0x300\n").unwrap_err();
        assert!(e.contains("unknown field `can_base`"), "{e}");
        let e = parse("kind = \"none\"\ndevice = \"/dev/ttyUSB0\"\n").unwrap_err();
        assert!(e.contains("device"), "{e}");
    }

    #[test]
    fn every_size_has_an_upper_bound_refused_by_its_key() {
        let on = "kind = \"none\"\n[metrics]\nlisten = \"127.0.0.1:0\"\n";
        for (section, key, expect) in [
            ("stream", "queue_depth = 1000000000000", "stream.queue_depth: must be 1..=64, got 1000000000000"),
            ("stream", "max_clients = 100000", "stream.max_clients: must be 1..=1024, got 100000"),
            (
                "live",
                "enabled = true\nqueue_depth = 1000000000000",
                "live.queue_depth: must be 1..=64, got 1000000000000",
            ),
            ("live", "enabled = true\nmax_viewers = 100000", "live.max_viewers: must be 1..=256, got 100000"),
            ("output.gige", "resend_ring = 1000000000", "output.gige.resend_ring: 1000000000: must be 1..=64 blocks"),
            ("output.gige", "packet_size = 65536", "output.gige.packet_size: 65536: must be 576..=9000 in steps of 4"),
        ] {
            assert_eq!(parse(&format!("{on}[{section}]\n{key}\n")).unwrap_err(), expect);
        }
        assert!(parse(&format!("{on}[output.gige]\nresend_ring = 64\n[stream]\nqueue_depth = 64\n")).is_ok());
    }

    #[test]
    fn missing_and_out_of_range_values_name_the_key() {
        let e = parse("kind = \"socketcan\"\n").unwrap_err();
        assert!(e.contains("missing field `iface`"), "{e}");
        let e = parse("kind = \"serial\"\ndevice = \"/dev/x\"\nbaud = 0\n").unwrap_err();
        assert_eq!(e, "input.baud: must be 1..=4000000, got 0");
        let e = parse("kind = \"trajectory\"\nfile = \"t.csv\"\nspeed = -1.0\n").unwrap_err();
        assert_eq!(e, "input.speed: must be a positive number, got -1");
        let e = parse("kind = \"carrier-pigeon\"\n").unwrap_err();
        assert!(e.contains("carrier-pigeon"), "{e}");
    }
}
