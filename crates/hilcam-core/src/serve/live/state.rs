//! What the live page shows beside the image: the newest frame's pose, sun, quality and
//! where the target is, and the last minute of render time, latency and samples per
//! pixel. Updated once per delivered frame (a short lock), read per page poll.

use crate::frame::EncodedFrame;
use crate::pose::Pose;
use crate::render::camera::{CameraModel, View};
use glam::DVec3;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The plots' time span.
pub const WINDOW: Duration = Duration::from_secs(60);
/// At most this many points per plot (a 100 Hz run keeps the newest 60 s).
const MAX_POINTS: usize = 6000;

/// The target's bounding sphere in the body frame (its centre, radius in metres).
#[derive(Clone, Copy, Debug)]
pub struct TargetSphere {
    pub centre_body: DVec3,
    pub radius_m: f64,
}

struct Point {
    at: Instant,
    render_ms: f64,
    latency_ms: f64,
    spp: f64,
}

pub struct LiveState {
    camera: CameraModel,
    sphere: TargetSphere,
    last: Option<Last>,
    points: VecDeque<Point>,
}

struct Last {
    pose: Pose,
    frame_seq: u64,
    width: u32,
    height: u32,
    spp: f64,
    depth: u16,
    flags: crate::frame::FrameFlags,
    render_ms: f64,
    latency_ms: f64,
}

impl LiveState {
    pub fn new(camera: CameraModel, sphere: TargetSphere) -> Self {
        LiveState { camera, sphere, last: None, points: VecDeque::new() }
    }

    /// A frame was delivered: `render_time` is the render thread's time for it; the
    /// latency is pose arrival → the frame handed to the outputs (from its header).
    pub fn frame(&mut self, pose: &Pose, frame: &EncodedFrame, render_time: Duration) {
        let m = &frame.meta;
        let latency_ms = if m.pose_arrival_unix_ns == 0 {
            f64::NAN
        } else {
            m.emit_unix_ns.saturating_sub(m.pose_arrival_unix_ns) as f64 / 1e6
        };
        let render_ms = render_time.as_secs_f64() * 1e3;
        let spp = m.spp.get();
        let now = Instant::now();
        self.points.push_back(Point { at: now, render_ms, latency_ms, spp });
        while self.points.len() > MAX_POINTS || self.points.front().is_some_and(|p| now - p.at > WINDOW) {
            self.points.pop_front();
        }
        self.last = Some(Last {
            pose: *pose,
            frame_seq: m.frame_seq,
            width: m.width,
            height: m.height,
            spp,
            depth: m.depth,
            flags: m.flags,
            render_ms,
            latency_ms,
        });
    }

    /// Where the target's bounding sphere projects (pinhole, full-frame pixels): its
    /// centre and the radius `f·r/z` (the small-angle size of the sphere's outline).
    /// None behind the camera, or for a frame cut to a client's region of interest.
    fn target_px(&self, last: &Last) -> Option<([f64; 2], f64)> {
        if (last.width, last.height) != (self.camera.width, self.camera.height) {
            return None;
        }
        let centre = last.pose.position + last.pose.attitude * self.sphere.centre_body;
        let at = View::project_camera_point(&self.camera, centre)?;
        Some((at, self.camera.focal_px() * self.sphere.radius_m / centre.z))
    }

    /// The page's view of it (`/live/state.json` without the counters).
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let now = Instant::now();
        let num = |x: f64| if x.is_finite() { json!(x) } else { serde_json::Value::Null };
        let series = json!({
            "age_s": self.points.iter().map(|p| -(now - p.at).as_secs_f64()).collect::<Vec<_>>(),
            "render_ms": self.points.iter().map(|p| num(p.render_ms)).collect::<Vec<_>>(),
            "latency_ms": self.points.iter().map(|p| num(p.latency_ms)).collect::<Vec<_>>(),
            "spp": self.points.iter().map(|p| p.spp).collect::<Vec<_>>(),
        });
        let Some(l) = &self.last else {
            return json!({ "frame": null, "pose": null, "target": null, "series": series });
        };
        let p = &l.pose;
        let q = p.attitude;
        json!({
            "frame": {
                "seq": l.frame_seq, "width": l.width, "height": l.height, "spp": l.spp, "depth": l.depth,
                "late": l.flags.late(), "degraded": l.flags.degraded(), "extrapolated": l.flags.extrapolated(),
                "render_ms": num(l.render_ms), "latency_ms": num(l.latency_ms),
            },
            "pose": {
                "seq": p.seq, "t_ns": p.t_ns, "position_m": [p.position.x, p.position.y, p.position.z],
                "range_m": p.position.length(), "attitude_wxyz": [q.w, q.x, q.y, q.z],
                "sun": [p.sun_dir.x, p.sun_dir.y, p.sun_dir.z],
            },
            "target": self.target_px(l).map(|(c, r)| json!({ "centre_px": c, "radius_px": r })),
            "series": series,
        })
    }
}
