//! Where frames go: the TCP stream (always), the recorder and the camera transports
//! (GigE Vision, when configured), and the pose-to-last-byte latency the stream measures.
//! A camera transport is started here and its [`CameraControl`] handed to
//! [`super::camera::connect`]; nothing else here knows the transport.

use super::camera::{self, CameraRequests};
use super::config::ServeConfig;
use crate::link::InputEvent;
use crate::metrics::{Histogram, Registry};
use crate::render::camera::CameraModel;
use crate::scene::Scene;
use crate::sink::camera_control::CameraControl;
use crate::sink::{Recorder, RecorderConfig, Sink, StreamConfig, StreamServer, WriteHook};
use std::net::SocketAddr;
use std::sync::Arc;
use tokio::sync::mpsc;

pub(super) struct Outputs {
    pub sinks: Vec<Sink>,
    pub stream_addr: SocketAddr,
    /// Pose arrival → last byte written to a stream client.
    pub latency: Arc<Histogram>,
    /// The inputs, with the camera clients' software triggers merged in.
    pub inputs: mpsc::Receiver<InputEvent>,
    /// What a camera client asks of each frame and of the frame rate.
    pub camera: CameraRequests,
}

impl Outputs {
    pub async fn start(
        cfg: &ServeConfig,
        scene: &Scene,
        camera: &CameraModel,
        registry: &Arc<Registry>,
        inputs: mpsc::Receiver<InputEvent>,
    ) -> anyhow::Result<Outputs> {
        let latency = registry.histogram(
            "hilcam_frame_latency_seconds",
            "Pose arrival to the frame's last byte written to a client",
            &[],
        );
        let stream = start_stream(cfg, registry, latency.clone()).await?;
        let stream_addr = stream.local_addr();
        let mut out = Outputs {
            sinks: vec![Sink::Stream(stream)],
            stream_addr,
            latency,
            inputs,
            camera: CameraRequests::default(),
        };
        if let Some(r) = &cfg.record
            && let Some(dir) = &r.dir
        {
            out.sinks.push(Sink::Recorder(Recorder::start(RecorderConfig::new(dir, r.format), registry)?));
        }
        if let Some(g) = &cfg.output.gige {
            let (sink, control) = start_gige(g, cfg, scene, camera, registry).await?;
            out.add_camera(sink, control, registry)?;
        }
        Ok(out)
    }

    /// A started camera transport: its sink, and its clients' control merged.
    fn add_camera(&mut self, sink: Sink, control: CameraControl, registry: &Registry) -> anyhow::Result<()> {
        let inputs = std::mem::replace(&mut self.inputs, mpsc::channel(1).1);
        self.inputs = camera::connect(control, inputs, registry, &mut self.camera)?;
        self.sinks.push(sink);
        Ok(())
    }
}

/// The GigE Vision camera (`[output.gige]`): its sink and its clients' control.
async fn start_gige(
    g: &crate::sink::gige::GigeConfig,
    cfg: &ServeConfig,
    scene: &Scene,
    camera: &CameraModel,
    registry: &Arc<Registry>,
) -> anyhow::Result<(Sink, CameraControl)> {
    use crate::sink::gige::{CameraDescription, GigeDevice, request};
    let rate_sets_schedule = cfg.trigger.mode == super::scheduler::TriggerMode::Rate;
    let desc = CameraDescription::from_scene(camera, &scene.sensor, cfg.trigger.rate_hz, rate_sets_schedule)
        .map_err(anyhow::Error::msg)?;
    let table = crate::render::truth::materials_table(&scene.materials);
    let desc = CameraDescription { truth: cfg.output.truth, truth_materials_len: table.len() as u32, ..desc };
    let device = GigeDevice::start(g, desc, registry.clone()).await?;
    let control = request::camera_control(&device);
    Ok((Sink::Gige(device), control))
}

async fn start_stream(
    cfg: &ServeConfig,
    registry: &Arc<Registry>,
    latency: Arc<Histogram>,
) -> anyhow::Result<StreamServer> {
    let hook: WriteHook = Arc::new(move |w| {
        if w.pose_arrival_unix_ns != 0 {
            latency.record(w.latency_ns());
        }
    });
    let stream_cfg = StreamConfig {
        bind: cfg.stream.listen,
        queue_depth: cfg.stream.queue_depth,
        max_clients: cfg.stream.max_clients,
        evict_after: cfg.stream.evict_after(),
        ..StreamConfig::default()
    };
    Ok(StreamServer::bind(stream_cfg, registry.clone(), Some(hook)).await?)
}

/// Close every sink (a clean close on a frame boundary for stream clients); the frames
/// the stream's clients dropped (slow readers).
pub(super) async fn close(sinks: Arc<Vec<Sink>>) -> u64 {
    let mut client_drops = 0;
    if let Ok(sinks) = Arc::try_unwrap(sinks) {
        for s in sinks {
            if let Sink::Stream(st) = &s {
                client_drops = st.clients().iter().map(|c| c.dropped).sum();
            }
            s.close().await;
        }
    }
    client_drops
}
