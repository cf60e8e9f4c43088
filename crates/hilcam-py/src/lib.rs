//! hilcam from Python (`import hilcam`): scenes, cameras, the renderer with its sensor
//! model and the ground truth, returning numpy arrays. A thin shell over hilcam-core's
//! [`FramePipeline`]: the same code path as `hilcam render`, so the same inputs give the
//! same bytes. The GIL is released while a frame renders; every refusal is a
//! `hilcam.HilcamError` (a `ValueError`) carrying the core's message, the text the CLI
//! prints. Reference: docs/python.md.

use hilcam_core::pipeline::{FramePipeline, FrameRequest};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::film::{Pixels, RadianceImage, write_pixels, write_radiance};
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::planet::{Planet as CorePlanet, PlanetModel};
use hilcam_core::render::truth::{TruthChannels, TruthImage};
use hilcam_core::scene::Scene as CoreScene;
use hilcam_core::scene::file::{camera_by_name_or_file, camera_preset, parse_name};
use hilcam_core::scene::limits::{checked_scaled_camera, pose_from_numbers};
use hilcam_core::scene::planet::{body_preset, checked_planet};
use hilcam_core::sensor::CameraPreset;
use numpy::{AllowTypeChange, PyArray1, PyArrayLikeDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Arc;

pyo3::create_exception!(
    hilcam,
    HilcamError,
    PyValueError,
    "An input hilcam refuses (pose, scene, camera, settings): the message is the core's, as the CLI prints it."
);

fn refused(message: impl std::fmt::Display) -> PyErr {
    HilcamError::new_err(message.to_string())
}

/// A camera: its pixel geometry (`[camera]`) and its optics and detector (`[sensor]`).
#[pyclass(module = "hilcam", frozen)]
#[derive(Clone)]
struct Camera {
    preset: CameraPreset,
}

#[pymethods]
impl Camera {
    /// A built-in camera (`nav1024`, `nav2048`, `paper`: the files of config/cameras/).
    #[staticmethod]
    fn preset(name: &str) -> PyResult<Camera> {
        Ok(Camera { preset: camera_preset(name).map_err(refused)? })
    }

    /// A camera TOML file (`[camera]` and an optional `[sensor]`), as `hilcam render --camera
    /// FILE` reads it.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Camera> {
        let s = path.to_string_lossy();
        let s = if s.contains('/') || s.ends_with(".toml") { s.into_owned() } else { format!("./{s}") };
        Ok(Camera { preset: camera_by_name_or_file(&s).map_err(refused)? })
    }

    /// The same camera at another resolution, same field of view (`hilcam render
    /// --width/--height`); the sensor's pixel-based values are kept.
    #[pyo3(signature = (width=None, height=None))]
    fn scaled(&self, width: Option<u32>, height: Option<u32>) -> PyResult<Camera> {
        let camera = checked_scaled_camera(&self.preset.camera, width, height).map_err(refused)?;
        Ok(Camera { preset: CameraPreset { camera, sensor: self.preset.sensor.clone() } })
    }

    #[getter]
    fn width(&self) -> u32 {
        self.preset.camera.width
    }

    #[getter]
    fn height(&self) -> u32 {
        self.preset.camera.height
    }

    #[getter]
    fn pitch_um(&self) -> f64 {
        self.preset.camera.pitch_um
    }

    #[getter]
    fn focal_mm(&self) -> f64 {
        self.preset.camera.focal_mm
    }

    fn __repr__(&self) -> String {
        let c = &self.preset.camera;
        format!("Camera({}x{}, pitch {} µm, focal {} mm)", c.width, c.height, c.pitch_um, c.focal_mm)
    }
}

/// A loaded scene file (meshes, materials, sun, planet, stars and its defaults).
#[pyclass(module = "hilcam", frozen)]
struct Scene {
    scene: Arc<CoreScene>,
}

#[pymethods]
impl Scene {
    /// Load and build a scene TOML (`hilcam render SCENE`); the GIL is released meanwhile.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
        let scene = py.detach(|| hilcam_core::scene::load(&path)).map_err(refused)?;
        Ok(Scene { scene: Arc::new(scene) })
    }

    /// The scene's own camera and sensor.
    #[getter]
    fn camera(&self) -> Camera {
        Camera { preset: CameraPreset { camera: self.scene.camera.clone(), sensor: self.scene.sensor.clone() } }
    }

    /// The scene's `[pose]`: position (m), attitude `[w, x, y, z]`, sun.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        pose_dict(py, &self.scene.pose)
    }

    #[getter]
    fn triangles(&self) -> usize {
        self.scene.mesh.indices.len()
    }

    /// The materials in mask order: mask value i + 1 is `materials[i]`.
    #[getter]
    fn materials(&self) -> Vec<String> {
        self.scene.materials.iter().map(|m| m.name.clone()).collect()
    }
}

fn pose_dict<'py>(py: Python<'py>, p: &Pose) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("position", p.position.to_array())?;
    d.set_item("attitude", [p.attitude.w, p.attitude.x, p.attitude.y, p.attitude.z])?;
    d.set_item("sun", p.sun_dir.to_array())?;
    Ok(d)
}

/// A planet for `Renderer.render(planet=…)`: a sphere whose centre is given in the camera
/// frame (m) for that frame, so that it can move from frame to frame. A `body` (`earth`,
/// `moon`) gives the radius and albedo; `radius_m` and `albedo` override them. Checked as a
/// scene's `[planet]` is (the same messages, keyed `planet.…`).
#[pyclass(module = "hilcam", frozen)]
#[derive(Clone)]
struct Planet {
    planet: CorePlanet,
}

#[pymethods]
impl Planet {
    #[new]
    #[pyo3(signature = (center_m, *, body=None, radius_m=None, albedo=None, model="lambert"))]
    fn new(
        center_m: PyArrayLikeDyn<'_, f64, AllowTypeChange>,
        body: Option<&str>,
        radius_m: Option<f64>,
        albedo: Option<f64>,
        model: &str,
    ) -> PyResult<Planet> {
        let c = numbers("planet.center_m", &center_m, &[3], "x, y, z in the camera frame, m")?;
        let preset = body.map(body_preset).transpose().map_err(|m| refused(format!("planet.body: {m}")))?;
        let model = parse_name::<PlanetModel>(model).map_err(|m| refused(format!("planet.model: {m}")))?;
        let radius =
            radius_m.or(preset.map(|p| p.0)).ok_or_else(|| refused("planet.radius_m: give radius_m or body"))?;
        let albedo = albedo.or(preset.map(|p| p.1)).ok_or_else(|| refused("planet.albedo: give albedo or body"))?;
        let planet = checked_planet(glam::DVec3::new(c[0], c[1], c[2]), radius, albedo, model)
            .map_err(|(key, m)| refused(format!("planet.{key}: {m}")))?;
        Ok(Planet { planet })
    }

    #[getter]
    fn center_m(&self) -> [f64; 3] {
        self.planet.centre_cam.to_array()
    }

    #[getter]
    fn radius_m(&self) -> f64 {
        self.planet.radius_m
    }

    #[getter]
    fn albedo(&self) -> f64 {
        self.planet.albedo
    }

    fn __repr__(&self) -> String {
        let p = &self.planet;
        format!(
            "Planet(center_m={:?}, radius_m={}, albedo={}, {:?})",
            p.centre_cam.to_array(),
            p.radius_m,
            p.albedo,
            p.model
        )
    }
}

/// One rendered frame: `radiance` (H×W float32, W·sr⁻¹·m⁻², entrance pupil) and, with
/// the sensor, `dn` (what the camera sends: uint16 or uint8 digital numbers, or float32
/// radiance after the optics for a camera whose output is radiance).
#[pyclass(module = "hilcam", frozen)]
struct Frame {
    radiance: Py<PyAny>,
    dn: Option<Py<PyAny>>,
    #[pyo3(get)]
    width: u32,
    #[pyo3(get)]
    height: u32,
    /// Significant bits of a uint16 `dn` (the ADC's).
    #[pyo3(get)]
    bits: Option<u8>,
    /// The detector's integration time, s (None without a detector).
    #[pyo3(get)]
    integration_s: Option<f64>,
    /// Time the renderer took (core-measured), s.
    #[pyo3(get)]
    render_s: f64,
    /// Time the sensor model took, s.
    #[pyo3(get)]
    sensor_s: f64,
    /// The frame index (keys every random number with the seed).
    #[pyo3(get)]
    frame: u64,
}

#[pymethods]
impl Frame {
    #[getter]
    fn radiance(&self, py: Python<'_>) -> Py<PyAny> {
        self.radiance.clone_ref(py)
    }

    #[getter]
    fn dn(&self, py: Python<'_>) -> Option<Py<PyAny>> {
        self.dn.as_ref().map(|d| d.clone_ref(py))
    }

    /// Write the frame with the CLI's writers: the sensor output when there is one
    /// (`hilcam render --sensor`: PNG/TIFF for DN, EXR/PFM for float), else the radiance
    /// (`hilcam render`: EXR/PFM exact, PNG/TIFF a preview scaled to its brightest).
    #[pyo3(signature = (path, radiance=false, png16=false))]
    fn save(&self, py: Python<'_>, path: PathBuf, radiance: bool, png16: bool) -> PyResult<()> {
        let (w, h) = (self.width, self.height);
        match (&self.dn, radiance) {
            (Some(dn), false) => {
                let dn = dn.bind(py);
                let px = if let Ok(a) = dn.cast::<numpy::PyArray2<u16>>() {
                    Pixels::Mono16 { data: a.to_vec()?, bits: self.bits.unwrap_or(16) }
                } else if let Ok(a) = dn.cast::<numpy::PyArray2<u8>>() {
                    Pixels::Mono8(a.to_vec()?)
                } else {
                    Pixels::Float32(dn.cast::<numpy::PyArray2<f32>>()?.to_vec()?)
                };
                py.detach(|| write_pixels(&path, w, h, &px)).map_err(refused)
            }
            _ => {
                let data = self.radiance.bind(py).cast::<numpy::PyArray2<f32>>()?.to_vec()?;
                let img = RadianceImage { width: w, height: h, data };
                py.detach(|| write_radiance(&path, &img, None, png16)).map(|_| ()).map_err(refused)
            }
        }
    }

    fn __repr__(&self) -> String {
        format!("Frame({}x{}, frame {}, render {:.3} s)", self.width, self.height, self.frame, self.render_s)
    }
}

/// A numpy array owning `v` (no copy), shaped `shape`.
fn array<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>, shape: &[usize]) -> PyResult<Py<PyAny>> {
    Ok(PyArray1::from_vec(py, v).reshape(shape)?.into_any().unbind())
}

/// `n` numbers from an array-like of shape (n,) for each allowed n.
fn numbers(
    arg: &str,
    v: &PyArrayLikeDyn<'_, f64, AllowTypeChange>,
    allowed: &[usize],
    what: &str,
) -> PyResult<Vec<f64>> {
    let shape = v.shape();
    if shape.len() != 1 || !allowed.contains(&shape[0]) {
        let lens: Vec<_> = allowed.iter().map(|n| n.to_string()).collect();
        return Err(refused(format!("{arg}: expected {} numbers ({what}), got shape {shape:?}", lens.join(" or "))));
    }
    Ok(v.as_array().iter().copied().collect())
}

/// The renderer: a scene seen by a camera, with render settings. Holds the pipeline's
/// warm buffers and its auto-exposure state from frame to frame, as a camera does.
#[pyclass(module = "hilcam")]
struct Renderer {
    pipeline: FramePipeline,
    settings: RenderSettings,
    pool: Option<rayon::ThreadPool>,
}

#[pymethods]
impl Renderer {
    /// `camera`: a `Camera` (default: the scene's). Settings not given are the scene's
    /// `[render]` ones; `threads`: rayon worker threads for this renderer (default: all
    /// cores, rayon's global pool).
    #[new]
    #[pyo3(signature = (scene, camera=None, *, spp=None, depth=None, seed=None, sampler=None, adaptive=None, roulette=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scene: &Scene,
        camera: Option<&Camera>,
        spp: Option<f64>,
        depth: Option<u32>,
        seed: Option<u64>,
        sampler: Option<&str>,
        adaptive: Option<bool>,
        roulette: Option<bool>,
        threads: Option<usize>,
    ) -> PyResult<Renderer> {
        let s = &scene.scene;
        let spp = spp.map(Spp::try_from).transpose().map_err(|e| refused(format!("spp: {e}")))?;
        let sampler =
            sampler.map(parse_name::<SamplerKind>).transpose().map_err(|e| refused(format!("sampler: {e}")))?;
        let mut settings = s.render.overridden(spp, depth, sampler, seed);
        if let Some(a) = adaptive {
            settings.adaptive = a;
        }
        if let Some(r) = roulette {
            settings.roulette = r;
        }
        let (cam, sensor): (CameraModel, _) = match camera {
            Some(c) => (c.preset.camera.clone(), c.preset.sensor.clone()),
            None => (s.camera.clone(), s.sensor.clone()),
        };
        let pipeline = FramePipeline::with_sensor(s.clone(), cam, &sensor).map_err(refused)?;
        let pool = match threads {
            None => None,
            Some(0) => return Err(refused("threads: must be ≥ 1")),
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new().num_threads(n).build().map_err(|e| refused(format!("threads: {e}")))?,
            ),
        };
        Ok(Renderer { pipeline, settings, pool })
    }

    #[getter]
    fn width(&self) -> u32 {
        self.pipeline.camera().width
    }

    #[getter]
    fn height(&self) -> u32 {
        self.pipeline.camera().height
    }

    /// The settings in force: spp, depth, seed, sampler, adaptive, roulette.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("spp", self.settings.spp.get())?;
        d.set_item("depth", self.settings.depth)?;
        d.set_item("seed", self.settings.seed)?;
        d.set_item("sampler", format!("{:?}", self.settings.sampler).to_lowercase())?;
        d.set_item("adaptive", self.settings.adaptive)?;
        d.set_item("roulette", self.settings.roulette)?;
        Ok(d)
    }

    /// Render frame `frame` at `pose` (`[px, py, pz]` or `[px, py, pz, qw, qx, qy, qz]`:
    /// target origin in the camera frame, m; attitude body → camera, scalar first; what
    /// is left out is the scene's) with the sun toward `sun` (camera frame; default: the
    /// scene's). With `sensor` (default) the camera's optics and detector run too
    /// (`Frame.dn`). The pose passes the gate every pose passes (`HilcamError` otherwise).
    /// `planet`: a `Planet` for this frame in place of the scene's `[planet]` (None: the
    /// scene's). `integration_s`: this frame's exposure (s) in place of the configured or
    /// auto-exposure one, the auto-exposure state left alone (as a GigE client's
    /// ExposureTime); ignored without a detector.
    #[pyo3(signature = (pose, sun=None, *, planet=None, integration_s=None, frame=0, sensor=true))]
    #[allow(clippy::too_many_arguments)]
    fn render(
        &mut self,
        py: Python<'_>,
        pose: PyArrayLikeDyn<'_, f64, AllowTypeChange>,
        sun: Option<PyArrayLikeDyn<'_, f64, AllowTypeChange>>,
        planet: Option<&Planet>,
        integration_s: Option<f64>,
        frame: u64,
        sensor: bool,
    ) -> PyResult<Frame> {
        let pose = self.pose(&pose, sun.as_ref())?;
        if let Some(t) = integration_s.filter(|t| !(t.is_finite() && *t >= 0.0)) {
            // The detector's own rule for sensor.detector.integration_time_s.
            return Err(refused(format!("integration_s: must be a finite number ≥ 0 (got {t})")));
        }
        let request = FrameRequest { integration_s, ..FrameRequest::default() };
        self.pipeline.set_planet(planet.map(|p| p.planet));
        let (settings, pool, pipeline) = (self.settings, &self.pool, &mut self.pipeline);
        let (w, h) = (pipeline.camera().width, pipeline.camera().height);
        let shape = [h as usize, w as usize];
        if !sensor {
            let (img, stats) = py.detach(|| {
                in_pool(pool, || {
                    let (img, stats) = pipeline.radiance_warm(&pose, &settings, frame);
                    (img.data.clone(), stats)
                })
            });
            return Ok(Frame {
                radiance: array(py, img, &shape)?,
                dn: None,
                width: w,
                height: h,
                bits: None,
                integration_s: None,
                render_s: stats.time.as_secs_f64(),
                sensor_s: 0.0,
                frame,
            });
        }
        let (f, radiance) = py
            .detach(|| {
                in_pool(pool, || {
                    let f = pipeline.frame_requested(&pose, &settings, frame, &request)?;
                    Ok::<_, hilcam_core::sensor::SensorError>((f, pipeline.last_render().0.data.clone()))
                })
            })
            .map_err(refused)?;
        let (dn, bits) = match f.pixels {
            Pixels::Mono16 { data, bits } => (array(py, data, &shape)?, Some(bits)),
            Pixels::Mono8(data) => (array(py, data, &shape)?, Some(8)),
            Pixels::Float32(data) => (array(py, data, &shape)?, None),
        };
        Ok(Frame {
            radiance: array(py, radiance, &shape)?,
            dn: Some(dn),
            width: w,
            height: h,
            bits,
            integration_s: f.integration_s,
            render_s: f.render.time.as_secs_f64(),
            sensor_s: f.sensor_time.as_secs_f64(),
            frame,
        })
    }

    /// Ground truth at `pose` (one ray per pixel centre): a dict of numpy arrays
    /// `depth` (H×W float32, m, inf on a miss), `mask` (H×W uint32, material + 1, 0 on a
    /// miss), `normal` and `body_xyz` (H×W×3 float32, NaN on a miss) — the channels asked
    /// for — and the target's `footprint` (`centroid_px`, `bbox_px`, `pixels`; None when
    /// it is not in view).
    #[pyo3(signature = (pose, sun=None, channels=vec!["depth".to_string(), "mask".into(), "normal".into(), "body_xyz".into()]))]
    fn truth<'py>(
        &self,
        py: Python<'py>,
        pose: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        sun: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
        channels: Vec<String>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let pose = self.pose(&pose, sun.as_ref())?;
        let channels = TruthChannels::from_names(channels.iter().map(String::as_str)).map_err(refused)?;
        let (pool, pipeline) = (&self.pool, &self.pipeline);
        let t = py
            .detach(|| in_pool(pool, || pipeline.truth(&pose, &FrameRequest::default(), channels)))
            .map_err(refused)?;
        truth_dict(py, t, channels)
    }

    /// Back to a new renderer's state: fresh buffers and auto-exposure (the first frame
    /// after it is the CLI's frame for the same inputs).
    fn reset(&mut self) {
        self.pipeline.reset();
    }
}

impl Renderer {
    /// The gated pose of `pose` and `sun` over the scene's `[pose]`.
    fn pose(
        &self,
        pose: &PyArrayLikeDyn<'_, f64, AllowTypeChange>,
        sun: Option<&PyArrayLikeDyn<'_, f64, AllowTypeChange>>,
    ) -> PyResult<Pose> {
        let p = numbers("pose", pose, &[3, 7], "px, py, pz[, qw, qx, qy, qz]")?;
        let attitude = (p.len() == 7).then(|| [p[3], p[4], p[5], p[6]]);
        let sun = match sun {
            None => None,
            Some(s) => {
                let s = numbers("sun", s, &[3], "sx, sy, sz")?;
                Some([s[0], s[1], s[2]])
            }
        };
        let scene = self.pipeline.scene();
        pose_from_numbers(&scene.pose_limits(), &scene.pose, [p[0], p[1], p[2]], attitude, sun).map_err(refused)
    }
}

fn in_pool<R: Send>(pool: &Option<rayon::ThreadPool>, f: impl FnOnce() -> R + Send) -> R {
    match pool {
        Some(p) => p.install(f),
        None => f(),
    }
}

fn truth_dict(py: Python<'_>, t: TruthImage, channels: TruthChannels) -> PyResult<Bound<'_, PyDict>> {
    use hilcam_core::render::truth::TruthChannel;
    let d = PyDict::new(py);
    let (h, w) = (t.height as usize, t.width as usize);
    let footprint = t.footprint();
    let planes = |p: [Vec<f32>; 3]| -> Vec<f32> {
        let mut out = Vec::with_capacity(3 * w * h);
        for ((x, y), z) in p[0].iter().zip(&p[1]).zip(&p[2]) {
            out.extend([*x, *y, *z]);
        }
        out
    };
    if channels.contains(TruthChannel::Depth) {
        d.set_item("depth", array(py, t.depth, &[h, w])?)?;
    }
    if channels.contains(TruthChannel::Mask) {
        d.set_item("mask", array(py, t.mask, &[h, w])?)?;
    }
    if channels.contains(TruthChannel::Normal) {
        d.set_item("normal", array(py, planes(t.normal), &[h, w, 3])?)?;
    }
    if channels.contains(TruthChannel::BodyXyz) {
        d.set_item("body_xyz", array(py, planes(t.body_xyz), &[h, w, 3])?)?;
    }
    match footprint {
        None => d.set_item("footprint", py.None())?,
        Some(f) => {
            let fp = PyDict::new(py);
            fp.set_item("centroid_px", f.centroid_px)?;
            fp.set_item("bbox_px", f.bbox_px)?;
            fp.set_item("pixels", f.pixels)?;
            d.set_item("footprint", fp)?;
        }
    }
    Ok(d)
}

/// The built-in camera presets' names.
#[pyfunction]
fn camera_presets() -> Vec<&'static str> {
    hilcam_core::scene::file::CAMERA_PRESETS.iter().map(|(n, _)| *n).collect()
}

#[pymodule]
fn _hilcam(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Camera>()?;
    m.add_class::<Scene>()?;
    m.add_class::<Renderer>()?;
    m.add_class::<Frame>()?;
    m.add_class::<Planet>()?;
    m.add("HilcamError", m.py().get_type::<HilcamError>())?;
    m.add_function(wrap_pyfunction!(camera_presets, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
