//! One frame from pose to pixels: render (radiance) → sensor (optics, detector, ADC).
//!
//! The single path every producer of frames goes through — `hilcam serve`, offline
//! replay and `hilcam render --sensor` — so a frame rendered live and the same frame
//! replayed offline are the same bytes. Synchronous; callers choose the thread.

use crate::pose::Pose;
use crate::render::camera::{CameraModel, View};
use crate::render::film::{Pixels, RadianceImage};
use crate::render::integrator::RenderSettings;
use crate::render::sampling::mix64;
use crate::render::{FrameBuffers, PrimaryVisibility, RenderOptions, RenderStats, render, render_into};
use crate::scene::Scene;
use crate::sensor::{AutoExposure, Sensor, SensorError};
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
    /// Integration time the sensor used (None without a detector).
    pub integration_s: Option<f64>,
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
}

impl FramePipeline {
    /// The scene's camera and sensor at a possibly different resolution (`camera`).
    pub fn new(scene: Arc<Scene>, camera: CameraModel) -> Result<Self, SensorError> {
        let sensor = Sensor::new(&camera, &scene.sensor)?;
        let auto_exposure = sensor.auto_exposure();
        Ok(FramePipeline {
            scene,
            camera,
            sensor,
            auto_exposure,
            primary: PrimaryVisibility::default(),
            buffers: FrameBuffers::default(),
        })
    }

    /// Find primary hits this way (default: rasterised where exact; tracing is for
    /// comparisons).
    pub fn with_primary(mut self, primary: PrimaryVisibility) -> Self {
        self.primary = primary;
        self
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

    fn view(&self, pose: &Pose) -> View {
        self.scene.view(&self.camera, pose).with_distortion(self.scene.sensor.optics.distortion)
    }

    fn options(&self, settings: &RenderSettings, index: u64) -> RenderOptions {
        RenderOptions::new(*settings, index).with_primary(self.primary)
    }

    /// Render the radiance only (no sensor), into a new image.
    pub fn radiance(&self, pose: &Pose, settings: &RenderSettings, index: u64) -> (RadianceImage, RenderStats) {
        render(&self.scene, &self.view(pose), &self.options(settings, index))
    }

    /// [`FramePipeline::radiance`] into the pipeline's own buffers: after the first frame
    /// it allocates nothing (what `hilcam render --repeat` times). Same bytes.
    pub fn radiance_warm(
        &mut self,
        pose: &Pose,
        settings: &RenderSettings,
        index: u64,
    ) -> (&RadianceImage, RenderStats) {
        let (view, options) = (self.view(pose), self.options(settings, index));
        let stats = render_into(&mut self.buffers, &self.scene, &view, &options);
        (self.buffers.image(), stats)
    }

    /// Render and convert frame `index` at `pose`.
    pub fn frame(&mut self, pose: &Pose, settings: &RenderSettings, index: u64) -> Result<RenderedFrame, SensorError> {
        self.frame_exposed(pose, settings, index, None)
    }

    /// [`FramePipeline::frame`] with the integration time set from outside (a camera
    /// client's ExposureTime): it replaces the configured or auto-exposure time for this
    /// frame and leaves the auto-exposure state alone. Ignored without a detector.
    pub fn frame_exposed(
        &mut self,
        pose: &Pose,
        settings: &RenderSettings,
        index: u64,
        integration_s: Option<f64>,
    ) -> Result<RenderedFrame, SensorError> {
        let (view, options) = (self.view(pose), self.options(settings, index));
        let render = render_into(&mut self.buffers, &self.scene, &view, &options);
        let radiance = self.buffers.image();
        let t0 = Instant::now();
        let seed = Self::sensor_seed(settings, index);
        let fixed = integration_s.filter(|_| self.scene.sensor.detector.is_some());
        let out = match (fixed, &mut self.auto_exposure) {
            (Some(t), _) => self.sensor.apply_with_integration(radiance, seed, t)?,
            (None, Some(ae)) => self.sensor.apply_auto(radiance, seed, ae)?.0,
            (None, None) => self.sensor.apply(radiance, seed)?,
        };
        Ok(RenderedFrame {
            pixels: out.pixels,
            width: self.camera.width,
            height: self.camera.height,
            settings: *settings,
            render,
            sensor_time: t0.elapsed(),
            integration_s: out.integration_time_s,
        })
    }
}
