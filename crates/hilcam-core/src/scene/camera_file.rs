//! Camera files (`config/cameras/*.toml`: `[camera]` and `[sensor]`) and the built-in
//! presets, loaded and checked as a scene file's camera is.

use super::limits::validate_camera;
use crate::sensor::CameraPreset;
use std::path::Path;

/// Read a camera file: its `[camera]` table and optional `[sensor]` table.
pub fn load_camera_file(path: &Path) -> Result<CameraPreset, String> {
    let preset = CameraPreset::load(path).map_err(|e| e.to_string())?;
    validate_camera(&preset.camera).map_err(|(f, m)| format!("{}: camera.{f}: {m}", path.display()))?;
    Ok(preset)
}

/// The shipped camera files (`config/cameras/`), by name: what `hilcam render --camera NAME`
/// and Python's `Camera.preset(NAME)` load, built in so that no file is needed.
pub const CAMERA_PRESETS: &[(&str, &str)] = &[
    ("nav1024", include_str!("../../../../config/cameras/nav1024.toml")),
    ("nav2048", include_str!("../../../../config/cameras/nav2048.toml")),
    ("paper", include_str!("../../../../config/cameras/paper.toml")),
];

/// The built-in camera `name` ([`CAMERA_PRESETS`]), checked as a camera file is (camera
/// and sensor); an unknown name is refused with the known ones.
pub fn camera_preset(name: &str) -> Result<CameraPreset, String> {
    let Some((_, text)) = CAMERA_PRESETS.iter().find(|(n, _)| *n == name) else {
        let known: Vec<_> = CAMERA_PRESETS.iter().map(|(n, _)| *n).collect();
        return Err(format!("unknown camera preset `{name}` (known: {})", known.join(", ")));
    };
    let preset: CameraPreset = toml::from_str(text).map_err(|e| format!("camera preset {name}: {e}"))?;
    checked_camera_preset(preset, name)
}

/// A camera preset's name or a camera file's path (anything with a `/` or ending in
/// `.toml`), loaded and checked (camera and sensor).
pub fn camera_by_name_or_file(s: &str) -> Result<CameraPreset, String> {
    if s.contains('/') || s.ends_with(".toml") {
        let preset = load_camera_file(Path::new(s))?;
        checked_camera_preset(preset, s)
    } else {
        camera_preset(s)
    }
}

fn checked_camera_preset(preset: CameraPreset, name: &str) -> Result<CameraPreset, String> {
    validate_camera(&preset.camera).map_err(|(f, m)| format!("{name}: camera.{f}: {m}"))?;
    preset.sensor.validate(&preset.camera).map_err(|e| format!("{name}: sensor: {e}"))?;
    Ok(preset)
}
