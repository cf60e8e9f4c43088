//! The TOML scene file. Every error names the file, and where it can the line and field.
//!
//! ```toml
//! [[mesh]]
//! obj = "plate.obj"            # relative to this file
//! translate = [0.0, 0.0, 0.0]  # body frame, metres
//! rotate_deg = [0.0, 0.0, 0.0] # about body X, then Y, then Z (fixed axes)
//! scale = 1.0
//!
//! [materials.white_paint]      # MTL material name → BRDF
//! model = "lambert"
//! rho = 0.522
//!
//! [sun]
//! irradiance = 593.1           # W/m² in the band
//! [background]
//! radiance = 0.0               # W·sr⁻¹·m⁻²
//!
//! camera_file = "../config/cameras/nav1024.toml"   # or an inline [camera] table
//!
//! [pose]                       # default pose (camera frame)
//! position = [0.0, 0.0, 10.0]
//! attitude = [1.0, 0.0, 0.0, 0.0]   # w, x, y, z: body → camera
//! sun = [0.0, 0.0, -1.0]            # toward the sun
//!
//! [stars]                      # optional: a star field behind the target (docs/stars.md)
//! catalogue = "stars/bsc5.csv" # relative to this file; needs pose.camera_to_inertial
//! max_vmag = 6.5
//! [planet]                     # optional: a sphere behind the target (`scene::planet`)
//! body = "earth"
//! center_m = [0.0, 6.771e6, 0.0]
//!
//! [limits]                     # optional: raise the pose range and mesh scale gates
//! max_range_m = 1.0e7          # default 1e7 m, at most 1.5e13 (100 AU)
//! max_scale = 1.0e6            # default 1e6, at most 1e9
//!
//! [[wrap]]                     # optional: wrinkle a material's faces (MLI folds)
//! material = "mli_gold"
//! level = "medium"             # or e_plane = 0.968, var = 0.0077
//! edge_m = 0.02
//!
//! [render]
//! spp = 4
//! depth = 2
//! sampler = "cosine"
//! seed = 0
//! bvh = "bvh8"                 # the default; the lab build also has "bvh4", "bvh2", "cwbvh"
//! texture_filter = "mip"       # the default; "bilinear": full resolution (docs/brdf.md)
//! ```

use super::limits::{self, validate_camera};
use super::material_entry::MaterialEntry;
use super::mesh_entries::{MeshEntry, WrapEntry, apply_wraps, load_meshes};
use super::scene_error::At;
use super::{Material, Scene, SceneParts};
use crate::pose::Pose;
use crate::render::camera::CameraModel;
use crate::render::geometry::BvhLayout;
use crate::render::integrator::{Method, QualityGoal, QualityMode, RenderSettings, SamplerKind, Spp};
use crate::render::sampling::Sequence;
use crate::render::stars::catalogue::Selection;
use crate::render::stars::{StarField, band_zero_point_w_m2};
use crate::render::texture::TextureFilter;
use crate::sensor::SensorConfig;
use glam::{DQuat, DVec3};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use super::camera_file::{CAMERA_PRESETS, camera_by_name_or_file, camera_preset, load_camera_file};
pub use super::scene_error::SceneError;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    mesh: Vec<MeshEntry>,
    #[serde(default)]
    materials: BTreeMap<String, Spanned<MaterialEntry>>,
    #[serde(default)]
    sun: SunSection,
    #[serde(default)]
    background: BackgroundSection,
    camera: Option<Spanned<CameraModel>>,
    camera_file: Option<Spanned<PathBuf>>,
    /// Optics and detector; replaces the camera file's `[sensor]` when given.
    sensor: Option<Spanned<SensorConfig>>,
    #[serde(default)]
    pose: PoseSection,
    #[serde(default)]
    render: RenderSection,
    /// Fold (wrinkle) every face of a material at load time.
    #[serde(default)]
    wrap: Vec<Spanned<WrapEntry>>,
    /// Point stars behind the target.
    stars: Option<Spanned<StarsSection>>,
    /// A sphere behind the target (`scene::planet`).
    planet: Option<Spanned<super::planet::PlanetSection>>,
    /// The largest pose range and mesh scale (`limits::SceneLimits`).
    #[serde(default)]
    limits: LimitsSection,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LimitsSection {
    #[serde(default = "default_max_range")]
    max_range_m: Spanned<f64>,
    #[serde(default = "default_max_scale")]
    max_scale: Spanned<f64>,
}

fn default_max_range() -> Spanned<f64> {
    Spanned::new(0..0, limits::MAX_RANGE_M)
}

fn default_max_scale() -> Spanned<f64> {
    Spanned::new(0..0, limits::SCALE.1)
}

impl Default for LimitsSection {
    fn default() -> Self {
        LimitsSection { max_range_m: default_max_range(), max_scale: default_max_scale() }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StarsSection {
    catalogue: Spanned<PathBuf>,
    /// Keep stars with min_vmag ≤ V ≤ max_vmag.
    #[serde(default = "brightest")]
    min_vmag: f64,
    #[serde(default = "faintest")]
    max_vmag: f64,
    /// Band irradiance of a V = 0 star, W/m² (default: Johnson V zero point × the band).
    zero_point_w_m2: Option<Spanned<f64>>,
}

fn brightest() -> f64 {
    -30.0
}
fn faintest() -> f64 {
    30.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SunSection {
    #[serde(default = "default_irradiance")]
    irradiance: Spanned<f64>,
}

impl Default for SunSection {
    fn default() -> Self {
        SunSection { irradiance: default_irradiance() }
    }
}

fn default_irradiance() -> Spanned<f64> {
    Spanned::new(0..0, super::SOLAR_BAND_IRRADIANCE)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BackgroundSection {
    #[serde(default = "zero")]
    radiance: Spanned<f64>,
}

impl Default for BackgroundSection {
    fn default() -> Self {
        BackgroundSection { radiance: zero() }
    }
}

fn zero() -> Spanned<f64> {
    Spanned::new(0..0, 0.0)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseSection {
    /// Each field has its default, whether the table is absent or only lacks the field.
    #[serde(default = "ahead")]
    position: Spanned<[f64; 3]>,
    #[serde(default = "identity")]
    attitude: Spanned<[f64; 4]>,
    #[serde(default = "sun_behind")]
    sun: Spanned<[f64; 3]>,
    /// Relative velocity of the target origin, camera frame, m/s (a camera that
    /// integrates over its exposure smears the motion).
    velocity: Option<Spanned<[f64; 3]>>,
    /// Angular rate of the body relative to the camera, camera frame, rad/s.
    angular_rate: Option<Spanned<[f64; 3]>>,
    /// Camera → inertial rotation, w, x, y, z (places the star field).
    camera_to_inertial: Option<Spanned<[f64; 4]>>,
}

/// The default pose (docs/scene.md): the target 10 m ahead, unrotated, lit from behind
/// the camera.
fn ahead() -> Spanned<[f64; 3]> {
    Spanned::new(0..0, [0.0, 0.0, 10.0])
}

fn identity() -> Spanned<[f64; 4]> {
    Spanned::new(0..0, [1.0, 0.0, 0.0, 0.0])
}

fn sun_behind() -> Spanned<[f64; 3]> {
    Spanned::new(0..0, [0.0, 0.0, -1.0])
}

impl Default for PoseSection {
    fn default() -> Self {
        PoseSection {
            position: ahead(),
            attitude: identity(),
            sun: sun_behind(),
            velocity: None,
            angular_rate: None,
            camera_to_inertial: None,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderSection {
    #[serde(default = "default_spp")]
    /// A number ≥ 1 (checked below, so that the error names `render.spp`).
    spp: Spanned<f64>,
    #[serde(default = "default_depth")]
    depth: Spanned<u32>,
    #[serde(default)]
    sampler: SamplerKind,
    #[serde(default)]
    sequence: Sequence,
    #[serde(default = "yes")]
    roulette: bool,
    #[serde(default = "yes")]
    adaptive: bool,
    /// `"fixed"` (spp samples) or `"sensor"` (samples until the Monte Carlo noise is below
    /// `sensor_k` × the camera's; spp is then the budget).
    #[serde(default = "default_quality")]
    quality: Spanned<QualityMode>,
    #[serde(default = "default_sensor_k")]
    sensor_k: Spanned<f64>,
    /// `"path"` (path tracing) or `"hybrid"` (rasterised coverage + the sun per fragment).
    #[serde(default)]
    method: Method,
    #[serde(default)]
    seed: u64,
    /// Any of the four names; a lab layout in a build without it is refused below.
    #[serde(default = "default_bvh")]
    bvh: Spanned<BvhLayout>,
    /// `"mip"` (camera hits prefiltered over the spp-scaled pixel footprint) or
    /// `"bilinear"` (full resolution everywhere).
    #[serde(default)]
    texture_filter: TextureFilter,
}

fn yes() -> bool {
    true
}

fn default_spp() -> Spanned<f64> {
    Spanned::new(0..0, RenderSettings::default().spp.get())
}
fn default_quality() -> Spanned<QualityMode> {
    Spanned::new(0..0, QualityMode::default())
}
fn default_sensor_k() -> Spanned<f64> {
    Spanned::new(0..0, f64::from(QualityGoal::DEFAULT_K))
}
fn default_depth() -> Spanned<u32> {
    Spanned::new(0..0, RenderSettings::default().depth)
}
fn default_bvh() -> Spanned<BvhLayout> {
    Spanned::new(0..0, BvhLayout::default())
}

impl Default for RenderSection {
    fn default() -> Self {
        RenderSection {
            spp: default_spp(),
            depth: default_depth(),
            sampler: SamplerKind::default(),
            sequence: Sequence::default(),
            roulette: true,
            adaptive: true,
            quality: default_quality(),
            sensor_k: default_sensor_k(),
            method: Method::default(),
            seed: 0,
            bvh: default_bvh(),
            texture_filter: TextureFilter::default(),
        }
    }
}

/// Load and build a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with_layout(path, None)
}

/// Load a scene file, overriding its BVH layout (refused, as in the file, when this build
/// does not have it).
pub fn load_with_layout(path: &Path, layout: Option<BvhLayout>) -> Result<Scene, SceneError> {
    let src = std::fs::read_to_string(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    let mut parts = parse(path, &src)?;
    if let Some(l) = layout {
        let refused = |message| SceneError::Missing { path: path.to_path_buf(), field: "render.bvh".into(), message };
        parts.layout = l.check().map_err(refused)?;
    }
    Ok(Scene::build(parts))
}

/// Parse a scene file's text (`path` names it in errors and anchors relative paths).
pub fn parse(path: &Path, src: &str) -> Result<SceneParts, SceneError> {
    let file: SceneFile =
        toml::from_str(src).map_err(|e| SceneError::Parse { path: path.to_path_buf(), message: e.to_string() })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let at = At { path, src };

    let l = &file.limits;
    let scene_limits =
        limits::SceneLimits::checked(*l.max_range_m.get_ref(), *l.max_scale.get_ref()).map_err(|(key, m)| {
            let span = if key == "max_range_m" { l.max_range_m.span() } else { l.max_scale.span() };
            at.field(span, &format!("limits.{key}"), m)
        })?;
    let irradiance = *file.sun.irradiance.get_ref();
    limits::in_range(irradiance, limits::IRRADIANCE_W_M2, " W/m²")
        .map_err(|m| at.field(file.sun.irradiance.span(), "sun.irradiance", m))?;
    // A model file's emission is relative to sunlit white: E/π × its value.
    let sunlit_white = irradiance / std::f64::consts::PI;

    let mut materials = materials_from(&file.materials, at)?;
    let meshes = load_meshes(&file.mesh, dir, &scene_limits, sunlit_white, &mut materials, at)?;
    let mut textures = meshes.textures;
    if !file.wrap.is_empty() {
        for (_, _, t) in textures.drain(..) {
            tracing::warn!(
                "texture `{}` ignored: [[wrap]] re-triangulates the mesh and does not carry texture coordinates yet; its factor is used: {}",
                t.name(),
                t.at
            );
        }
    }
    let mesh = apply_wraps(&file.wrap, meshes.mesh, &materials, at)?;

    let (camera, sensor) = camera_and_sensor(&file, dir, at)?;
    let planet = match &file.planet {
        None => None,
        Some(p) => Some(p.get_ref().build(p.span()).map_err(|(span, f, m)| at.field(span, &f, m))?),
    };
    let pose_limits = scene_limits.pose_limits(planet.map(|p| p.radius_m));
    let pose = pose_from(&file.pose, &pose_limits).map_err(|(span, f, m)| at.field(span, &f, m))?;
    let background = *file.background.radiance.get_ref();
    limits::in_range(background, limits::BACKGROUND_W_SR_M2, " W·sr⁻¹·m⁻²")
        .map_err(|m| at.field(file.background.radiance.span(), "background.radiance", m))?;
    let render = render_settings(&file.render, &sensor, at)?;
    let layout = file.render.bvh.get_ref().check().map_err(|m| at.field(file.render.bvh.span(), "render.bvh", m))?;
    let stars = match &file.stars {
        None => None,
        Some(s) => Some(stars_from(at, dir, s, &pose, &sensor, camera.focal_px())?),
    };
    let texturing = super::textures::build(&materials, textures, meshes.uv, file.render.texture_filter);
    Ok(SceneParts {
        texturing,
        mesh,
        materials,
        sun_irradiance: irradiance,
        background,
        camera,
        sensor,
        pose,
        render,
        layout,
        stars,
        planet,
        limits: scene_limits,
    })
}

/// The `[materials.NAME]` tables, in name order (a BTreeMap) so that indices are stable.
fn materials_from(tables: &BTreeMap<String, Spanned<MaterialEntry>>, at: At) -> Result<Vec<Material>, SceneError> {
    let mut materials = Vec::new();
    for (name, spec) in tables {
        let entry = spec.get_ref();
        let bsdf =
            entry.bsdf.build().map_err(|e| at.field(spec.span(), &format!("materials.{name}"), e.to_string()))?;
        materials.push(Material { name: name.clone(), bsdf, emission: entry.emission as f32 });
    }
    Ok(materials)
}

/// The camera (an inline `[camera]` or a camera file's) and the sensor (`[sensor]`, else
/// the camera file's, else none), each checked.
fn camera_and_sensor(file: &SceneFile, dir: &Path, at: At) -> Result<(CameraModel, SensorConfig), SceneError> {
    let (camera, file_sensor) = match (&file.camera, &file.camera_file) {
        (Some(c), None) => (c.get_ref().clone(), SensorConfig::default()),
        (None, Some(f)) => {
            let preset = load_camera_file(&dir.join(f.get_ref())).map_err(|m| at.field(f.span(), "camera_file", m))?;
            (preset.camera, preset.sensor)
        }
        (Some(c), Some(_)) => {
            return Err(at.field(c.span(), "camera", "give either [camera] or camera_file, not both".into()));
        }
        (None, None) => return Err(at.missing("camera", "give a [camera] table or camera_file".into())),
    };
    let sensor = match &file.sensor {
        Some(s) => s.get_ref().clone(),
        None => file_sensor,
    };
    if let Err(e) = sensor.validate(&camera) {
        let span =
            file.sensor.as_ref().map(|s| s.span()).or(file.camera_file.as_ref().map(|f| f.span())).unwrap_or(0..0);
        return Err(at.field(span, "sensor", e.to_string()));
    }
    validate_camera(&camera).map_err(|(f, m)| match &file.camera {
        Some(c) => at.field(c.span(), &format!("camera.{f}"), m),
        None => at.missing(&format!("camera.{f}"), m),
    })?;
    Ok((camera, sensor))
}

/// `[render]`: samples, depth, sampler, quality goal (checked against the sensor), method, seed.
fn render_settings(r: &RenderSection, sensor: &SensorConfig, at: At) -> Result<RenderSettings, SceneError> {
    let render = RenderSettings {
        spp: Spp::try_from(*r.spp.get_ref()).map_err(|e| at.field(r.spp.span(), "render.spp", e.to_string()))?,
        depth: *r.depth.get_ref(),
        sampler: r.sampler,
        sequence: r.sequence,
        roulette: r.roulette,
        adaptive: r.adaptive,
        quality: QualityGoal {
            mode: *r.quality.get_ref(),
            k: QualityGoal::checked_k(*r.sensor_k.get_ref())
                .map_err(|m| at.field(r.sensor_k.span(), "render.sensor_k", m))?,
        },
        method: r.method,
        seed: r.seed,
    };
    if let Err(m) = crate::sensor::check_quality(&render, sensor) {
        return Err(at.field(r.quality.span(), "render.quality", m));
    }
    if !(1..=limits::MAX_DEPTH).contains(&render.depth) {
        return Err(at.field(
            r.depth.span(),
            "render.depth",
            format!("must be in 1..={} (1 = direct sunlight only), got {}", limits::MAX_DEPTH, render.depth),
        ));
    }
    Ok(render)
}

/// The `[stars]` section's star field: the catalogue read, the zero point from the sensor's
/// band (or the scene's solar band, 0.45–0.75 µm, without one), placed by the pose's
/// camera → inertial rotation, which the scene's `[pose]` must give.
fn stars_from(
    at: At,
    dir: &Path,
    s: &Spanned<StarsSection>,
    pose: &Pose,
    sensor: &SensorConfig,
    focal_px: f64,
) -> Result<StarField, SceneError> {
    let Some(q) = pose.camera_to_inertial else {
        return Err(at.missing(
            "pose.camera_to_inertial",
            "[stars] needs the camera's inertial attitude: give [pose] camera_to_inertial = [w, x, y, z]".into(),
        ));
    };
    let st = s.get_ref();
    if st.min_vmag.is_nan() || st.max_vmag.is_nan() || st.min_vmag > st.max_vmag {
        let m = format!("{} must be ≤ max_vmag {}", st.min_vmag, st.max_vmag);
        return Err(at.field(s.span(), "stars.min_vmag", m));
    }
    let (lo, hi) = sensor.band.as_ref().map_or((0.45, 0.75), |b| (b.min_um, b.max_um));
    let zero_point_w_m2 = match &st.zero_point_w_m2 {
        None => band_zero_point_w_m2(lo, hi),
        Some(z) => {
            let v = *z.get_ref();
            if !(v.is_finite() && v > 0.0) {
                return Err(at.field(z.span(), "stars.zero_point_w_m2", format!("must be > 0 W/m², got {v}")));
            }
            v
        }
    };
    let sel =
        Selection { min_vmag: st.min_vmag, max_vmag: st.max_vmag, zero_point_w_m2, default_camera_to_inertial: q };
    let file = dir.join(st.catalogue.get_ref());
    let stars =
        StarField::load(&file, &sel).map_err(|e| at.field(st.catalogue.span(), "stars.catalogue", e.to_string()))?;
    // Finite inputs can still make infinite pixels: the brightest star's radiance
    // E / Ω_pixel = E · focal_px² must be an f32 (the radiance image's type).
    if let Some(b) = stars.stars.iter().min_by(|a, b| a.vmag.total_cmp(&b.vmag)) {
        let radiance = b.irradiance_w_m2 * focal_px * focal_px;
        if !(radiance as f32).is_finite() {
            let span = st.zero_point_w_m2.as_ref().map_or(st.catalogue.span(), |z| z.span());
            let m = format!(
                "zero point {zero_point_w_m2:e} W/m² makes star HR {} (V = {}) {radiance:e} W·m⁻²·sr⁻¹ on its pixel \
                 (irradiance {:e} W/m² × focal² {:e} px²), beyond an f32 radiance: not finite",
                b.hr,
                b.vmag,
                b.irradiance_w_m2,
                focal_px * focal_px
            );
            return Err(at.field(span, "stars.zero_point_w_m2", m));
        }
    }
    Ok(stars)
}

type FieldErr = (std::ops::Range<usize>, String, String);

fn pose_from(p: &PoseSection, lim: &crate::pose::validate::PoseLimits) -> Result<Pose, FieldErr> {
    let [w, x, y, z] = *p.attitude.get_ref();
    let pose = Pose {
        position: DVec3::from_array(*p.position.get_ref()),
        attitude: DQuat::from_xyzw(x, y, z, w),
        sun_dir: DVec3::from_array(*p.sun.get_ref()),
        velocity: p.velocity.as_ref().map(|v| DVec3::from_array(*v.get_ref())),
        angular_rate: p.angular_rate.as_ref().map(|v| DVec3::from_array(*v.get_ref())),
        ..Pose::ahead(0.0)
    };
    let pose = match &p.camera_to_inertial {
        None => pose,
        Some(q) => {
            let [w, x, y, z] = *q.get_ref();
            let n = (w * w + x * x + y * y + z * z).sqrt();
            let unit = (n - 1.0).abs() <= 1e-3;
            if !unit {
                let m = format!("norm {n}, must be within 1e-3 of 1 (w, x, y, z)");
                return Err((q.span(), "pose.camera_to_inertial".into(), m));
            }
            Pose { camera_to_inertial: Some(DQuat::from_xyzw(x, y, z, w) / n), ..pose }
        }
    };
    limits::gate_pose(&pose, lim).map_err(|e| {
        let rates = p.velocity.as_ref().or(p.angular_rate.as_ref()).map(Spanned::span);
        let span = match e.field {
            "pose.attitude" => p.attitude.span(),
            "pose.sun" => p.sun.span(),
            "pose.velocity" | "pose" if rates.is_some() => rates.expect("checked"),
            _ => p.position.span(),
        };
        (span, e.field.to_string(), e.message)
    })
}

/// One of the names a scene file uses for a setting (`cosine`, `sobol`, `bvh8`, `png`, …),
/// parsed the way the scene file parses it, so the command line takes the same words; the
/// error lists the names allowed.
pub fn parse_name<T: serde::de::DeserializeOwned>(name: &str) -> Result<T, String> {
    use serde::de::IntoDeserializer;
    T::deserialize(IntoDeserializer::<serde::de::value::Error>::into_deserializer(name)).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_built_in_cameras_are_the_shipped_files() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/cameras");
        let files = std::fs::read_dir(&dir)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "toml"));
        assert_eq!(files.count(), CAMERA_PRESETS.len(), "a camera file of config/cameras/ is not built in");
        for (name, _) in CAMERA_PRESETS {
            let file = load_camera_file(&dir.join(format!("{name}.toml"))).unwrap();
            let built_in = camera_preset(name).unwrap();
            assert_eq!(format!("{built_in:?}"), format!("{file:?}"), "{name}");
            assert_eq!(format!("{:?}", camera_by_name_or_file(name).unwrap()), format!("{file:?}"));
        }
        assert_eq!(
            camera_preset("nav4096").unwrap_err(),
            "unknown camera preset `nav4096` (known: nav1024, nav2048, paper)"
        );
        let e = camera_by_name_or_file("no/such.toml").unwrap_err();
        assert!(e.starts_with("no/such.toml"), "{e}");
    }
}
