//! One frame from pose to pixels: render (radiance) → sensor (optics, detector, ADC).
//!
//! The single path every producer of frames goes through — `hilcam serve`, offline
//! replay and `hilcam render --sensor` — so a frame rendered live and the same frame
//! replayed offline are the same bytes. Synchronous; callers choose the thread.

use crate::pose::Pose;
use crate::render::camera::{CameraModel, View, Window};
use crate::render::film::{Pixels, RadianceImage};
use crate::render::integrator::RenderSettings;
use crate::render::planet::Planet;
use crate::render::sampling::mix64;
use crate::render::truth::{TruthChannels, TruthImage, TruthPlanes, render_truth_into};
use crate::render::{FrameBuffers, PrimaryVisibility, RenderOptions, RenderStats, render, render_into};
use crate::scene::Scene;
use crate::sensor::mc_noise::McNoiseStats;
use crate::sensor::{AutoExposure, ExposureMode, ExposureTiming, Sensor, SensorConfig, SensorError};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A frame's pixels and what it took to make them.
#[derive(Clone, Debug)]
pub struct RenderedFrame {
    pub pixels: Pixels,
    pub width: u32,
    pub height: u32,
    pub settings: RenderSettings,
    pub render: RenderStats,
    /// Time spent in the sensor model.
    pub sensor_time: Duration,
    /// Integration time the frame shows: the detector's, or, for radiance output from a
    /// camera whose exposure integrates over time (global, rolling), the exposure's
    /// duration. None when nothing integrated (no detector; float output of an instant
    /// exposure).
    pub integration_s: Option<f64>,
    /// When the rows integrated (what the frame's metadata reports for time-tagging).
    pub exposure: ExposureTiming,
    /// How the frame's Monte Carlo noise compares with the camera's (DN frames).
    pub mc_noise: Option<McNoiseStats>,
}

/// What a camera client asked of one frame besides its pose and render settings (a
/// GigE Vision client's ExposureTime and ROI). The default asks nothing: the frame is
/// the configured one.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameRequest {
    /// Integration time (s) replacing the configured or auto-exposure one for this frame;
    /// the auto-exposure state is left alone. Ignored without a detector.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integration_s: Option<f64>,
    /// Only this region of the sensor is rendered and converted (it must be inside it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roi: Option<Window>,
}

impl FrameRequest {
    /// Asks nothing: the configured frame.
    pub fn is_default(&self) -> bool {
        *self == FrameRequest::default()
    }
}

/// Render + sensor for one camera. Holds the auto-exposure state between frames.
pub struct FramePipeline {
    scene: Arc<Scene>,
    camera: CameraModel,
    sensor: Sensor,
    auto_exposure: Option<AutoExposure>,
    primary: PrimaryVisibility,
    /// Kept from frame to frame: [`FramePipeline::frame`] renders without allocating.
    buffers: FrameBuffers,
    /// The sensor of the last ROI's grown window, kept while the ROI stays.
    windowed: Option<Sensor>,
    /// The planet of the next frames in place of the scene's (see [`FramePipeline::set_planet`]).
    planet: Option<Planet>,
}

impl FramePipeline {
    /// The scene's camera and sensor at a possibly different resolution (`camera`).
    pub fn new(scene: Arc<Scene>, camera: CameraModel) -> Result<Self, SensorError> {
        let sensor = scene.sensor.clone();
        Self::with_sensor(scene, camera, &sensor)
    }

    /// The scene seen by another camera: `camera` and its optics and detector `sensor` (a
    /// camera preset or file, `hilcam render --camera`, Python's `Renderer(scene, camera)`)
    /// replace the scene's own.
    pub fn with_sensor(scene: Arc<Scene>, camera: CameraModel, sensor: &SensorConfig) -> Result<Self, SensorError> {
        let sensor = Sensor::new(&camera, sensor)?;
        let auto_exposure = sensor.auto_exposure();
        Ok(FramePipeline {
            scene,
            camera,
            sensor,
            auto_exposure,
            primary: PrimaryVisibility::default(),
            buffers: FrameBuffers::default(),
            windowed: None,
            planet: None,
        })
    }

    /// Find primary hits this way (default: rasterised where exact; tracing is for
    /// comparisons).
    pub fn with_primary(mut self, primary: PrimaryVisibility) -> Self {
        self.primary = primary;
        self
    }

    /// Render the next frames with `planet` (camera frame, checked by
    /// [`crate::scene::planet::checked_planet`]) in place of the scene's `[planet]`; None:
    /// the scene's again. A planet that moves is set before each frame.
    pub fn set_planet(&mut self, planet: Option<Planet>) {
        self.planet = planet;
    }

    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    pub fn sensor(&self) -> &Sensor {
        &self.sensor
    }

    /// The last frame's buffers (its image, coverage and sample counts), for checks.
    pub fn buffers(&self) -> &FrameBuffers {
        &self.buffers
    }

    /// Back to the state of a new pipeline: fresh buffers and auto-exposure. After a frame
    /// that stopped half-way (a caught panic) the buffers' bookkeeping of what the last
    /// frame wrote, and the exposure state, cannot be trusted.
    pub fn reset(&mut self) {
        self.buffers = FrameBuffers::default();
        self.auto_exposure = self.sensor.auto_exposure();
    }

    /// Seed of the sensor noise for frame `index`: derived from the render seed but in its
    /// own domain, so it never repeats the renderer's random streams.
    pub fn sensor_seed(settings: &RenderSettings, index: u64) -> u64 {
        mix64(settings.seed ^ mix64(index ^ 0x5e45_0e0a_11ce_0001))
    }

    /// The view of `pose`, moving over the exposure `timing` when the camera integrates
    /// motion and the pose has rates.
    fn view(&self, pose: &Pose, timing: &ExposureTiming) -> View {
        let view = self.scene.view(&self.camera, pose).with_distortion(self.sensor.config().optics.distortion);
        match timing.motion(pose) {
            Some(m) => view.with_motion(m, pose, self.scene.frame_origin_body),
            None => view,
        }
    }

    /// When the rows integrate for a frame whose integration time is `integration_s`
    /// (None: the configured or auto-exposure one).
    pub fn exposure_timing(&self, integration_s: Option<f64>) -> ExposureTiming {
        let Some(det) = &self.sensor.config().detector else { return ExposureTiming::default() };
        let auto = self.auto_exposure.as_ref().map(AutoExposure::integration_time_s);
        ExposureTiming {
            mode: det.exposure,
            integration_s: integration_s.or(auto).unwrap_or(det.integration_time_s),
            line_time_s: match det.exposure {
                ExposureMode::Rolling => det.line_time_us.unwrap_or(0.0) * 1e-6,
                _ => 0.0,
            },
        }
    }

    /// The ground truth of frame `pose` as `request` crops it (`render::truth`): one ray
    /// per pixel centre at the pose's instant, independent of the render settings.
    pub fn truth(
        &self,
        pose: &Pose,
        request: &FrameRequest,
        channels: TruthChannels,
    ) -> Result<TruthImage, SensorError> {
        let mut planes = TruthPlanes::default();
        self.truth_into(pose, request, channels, &mut planes)?;
        Ok(planes.take().expect("the truth was just computed"))
    }

    /// [`FramePipeline::truth`] into `planes` kept from frame to frame (the same bytes,
    /// without allocating or filling the planes again: [`TruthPlanes`]).
    pub fn truth_into<'p>(
        &self,
        pose: &Pose,
        request: &FrameRequest,
        channels: TruthChannels,
        planes: &'p mut TruthPlanes,
    ) -> Result<&'p TruthImage, SensorError> {
        let mut view = self.scene.view(&self.camera, pose).with_distortion(self.sensor.config().optics.distortion);
        if let Some(w) = request.roi.filter(|w| !w.is_full(&self.camera)) {
            let w = w
                .inside(&self.camera)
                .map_err(|e| SensorError::Invalid { field: "roi".into(), message: e.to_string() })?;
            view = view.window(&w);
        }
        // After a frame through this very view (no motion, no ROI), its coverage.
        Ok(render_truth_into(&self.scene, &view, channels, self.buffers.coverage_for(&view), planes))
    }

    /// The render options of frame `index` at `pose`: the planet is the one set by
    /// [`FramePipeline::set_planet`], else the scene's moved to the pose's planet centre.
    fn options(&self, pose: &Pose, settings: &RenderSettings, index: u64) -> RenderOptions {
        let planet = self.planet.or_else(|| self.scene.planet_at(pose));
        RenderOptions::new(*settings, index).with_primary(self.primary).with_planet(planet)
    }

    /// Render the radiance only (no sensor), into a new image.
    pub fn radiance(&self, pose: &Pose, settings: &RenderSettings, index: u64) -> (RadianceImage, RenderStats) {
        let view = self.view(pose, &self.exposure_timing(None));
        render(&self.scene, &view, &self.options(pose, settings, index))
    }

    /// [`FramePipeline::radiance`] into the pipeline's own buffers: after the first frame
    /// it allocates nothing (what `hilcam render --repeat` times). Same bytes.
    pub fn radiance_warm(
        &mut self,
        pose: &Pose,
        settings: &RenderSettings,
        index: u64,
    ) -> (&RadianceImage, RenderStats) {
        let (view, options) = (self.view(pose, &self.exposure_timing(None)), self.options(pose, settings, index));
        let stats = render_into(&mut self.buffers, &self.scene, &view, &options);
        (self.buffers.image(), stats)
    }

    /// The radiance and Monte Carlo variance of the last frame rendered into the
    /// pipeline's buffers (by [`FramePipeline::frame`] or [`FramePipeline::radiance_warm`];
    /// with an ROI, its grown window): to judge a frame after the fact, e.g. with
    /// [`Sensor::mc_noise_stats`] at another bound.
    pub fn last_render(&self) -> (&RadianceImage, Option<&[f32]>) {
        (self.buffers.image(), self.buffers.variance())
    }

    /// Render and convert frame `index` at `pose`.
    pub fn frame(&mut self, pose: &Pose, settings: &RenderSettings, index: u64) -> Result<RenderedFrame, SensorError> {
        self.frame_requested(pose, settings, index, &FrameRequest::default())
    }

    /// [`FramePipeline::frame`] as a camera client asked for it. With an ROI only the
    /// ROI is rendered, grown by the PSF's reach so that its pixels are converted as in
    /// the full frame: with uniform sampling they are the full frame's bytes there.
    /// The auto-exposure meters the ROI, as a camera's does.
    pub fn frame_requested(
        &mut self,
        pose: &Pose,
        settings: &RenderSettings,
        index: u64,
        request: &FrameRequest,
    ) -> Result<RenderedFrame, SensorError> {
        let roi = match request.roi.filter(|w| !w.is_full(&self.camera)) {
            None => None,
            Some(w) => Some(
                w.inside(&self.camera)
                    .map_err(|e| SensorError::Invalid { field: "roi".into(), message: e.to_string() })?,
            ),
        };
        // The integration time is chosen before rendering: a moving view needs it.
        let fixed = request.integration_s.filter(|_| self.sensor.config().detector.is_some());
        let timing = self.exposure_timing(fixed);
        // The camera's noise at this integration time: what `quality = "sensor"` samples
        // against and every DN frame's Monte Carlo noise report measures against.
        let noise = self.sensor.noise_bound(timing.integration_s, f64::from(settings.quality.k));
        if settings.quality.is_sensor() {
            crate::sensor::check_quality(settings, self.sensor.config())
                .map_err(|message| SensorError::Invalid { field: "render.quality".into(), message })?;
        }
        let (mut view, options) =
            (self.view(pose, &timing), self.options(pose, settings, index).with_noise(noise, noise.is_some()));
        if let Some(roi) = &roi {
            let (mx, my) = self.sensor.psf_margin();
            let area = roi.grown(mx, my, &self.camera);
            if self.windowed.as_ref().is_none_or(|s| s.window() != area) {
                self.windowed = Some(self.sensor.windowed(area));
            }
            view = view.window(&area);
        }
        let render = render_into(&mut self.buffers, &self.scene, &view, &options);
        let (radiance, variance) = (self.buffers.image(), self.buffers.variance());
        let sensor = if roi.is_some() { self.windowed.as_ref().expect("set above") } else { &self.sensor };
        let t0 = Instant::now();
        let seed = Self::sensor_seed(settings, index);
        let k = f64::from(settings.quality.k);
        let out = match fixed.or_else(|| self.auto_exposure.as_ref().map(AutoExposure::integration_time_s)) {
            Some(t) => sensor.apply_with_variance(radiance, variance, seed, t, k)?,
            None => {
                let t = self.sensor.config().detector.as_ref().map_or(0.0, |d| d.integration_time_s);
                sensor.apply_with_variance(radiance, variance, seed, t, k)?
            }
        };
        let (pixels, width, height) = match &roi {
            None => (out.pixels, self.camera.width, self.camera.height),
            Some(roi) => {
                let area = sensor.window();
                (out.pixels.crop(area.width, &area.relative(roi)), roi.width, roi.height)
            }
        };
        if fixed.is_none()
            && let Some(ae) = &mut self.auto_exposure
        {
            ae.update(&pixels);
        }
        Ok(RenderedFrame {
            pixels,
            width,
            height,
            settings: *settings,
            render,
            sensor_time: t0.elapsed(),
            // A float32 frame has no detector stage, but a timed exposure still
            // integrated its radiance over `timing`: it is tagged with that duration.
            integration_s: out.integration_time_s.or(timing.integrates_motion().then_some(timing.integration_s)),
            exposure: timing,
            mc_noise: out.stats.mc,
        })
    }
}
