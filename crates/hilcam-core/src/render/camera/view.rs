//! A camera placed by a pose: primary rays in the render frame.
//!
//! The render frame is the target body frame shifted so that its origin sits at the
//! centre of the target's bounds. Pose maths and ray set-up are f64; each primary ray's
//! origin is then moved (in f64) to where the ray enters the target's bounding sphere, so
//! the f32 ray that is traced has small coordinates whatever the range (0.5 m … 10⁶ m).

use super::CameraModel;
use super::distortion::Distortion;
use super::motion::{Motion, MovingPose};
use super::window::{PixelKeys, Window};
use crate::pose::Pose;
use crate::render::geometry::Ray;
use glam::{DMat3, DVec3, Vec3};

/// Pixels `[col0, col1) × [row0, row1)` whose area can see the target's bounds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelRect {
    pub col0: u32,
    pub col1: u32,
    pub row0: u32,
    pub row1: u32,
}

impl PixelRect {
    pub fn area(&self) -> u64 {
        u64::from(self.col1 - self.col0) * u64::from(self.row1 - self.row0)
    }
}

/// Bounds of the target in the render frame: a sphere (centre near 0) and an AABB.
#[derive(Clone, Copy, Debug)]
pub struct TargetBounds {
    pub centre: DVec3,
    pub radius: f64,
    pub min: DVec3,
    pub max: DVec3,
}

/// The bounds of one spatially separate part of the target (render frame): its sphere
/// and its box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartSphere {
    pub centre: DVec3,
    pub radius: f64,
    pub min: DVec3,
    pub max: DVec3,
}

/// One camera, one pose: everything needed to make primary rays.
#[derive(Clone, Debug)]
pub struct View {
    pub(in crate::render) width: u32,
    pub(in crate::render) height: u32,
    /// Pixel coordinate of the principal point (continuous, 0 at the array's corner).
    pub(in crate::render) pp: [f64; 2],
    pub(in crate::render) inv_focal_px: f64,
    /// Camera centre in the render frame, metres.
    pub(in crate::render) origin: DVec3,
    /// Camera frame → render frame.
    pub(in crate::render) cam_to_render: DMat3,
    pub(in crate::render) bounds: TargetBounds,
    /// The target's separate parts, when it has several: a camera ray starts where it
    /// first enters one of their spheres instead of the whole target's (so a far body does
    /// not move the start, nor round the ray, of a near one). None: `bounds`.
    pub(in crate::render) parts: Option<std::sync::Arc<[PartSphere]>>,
    /// Lens distortion: sample positions on the (distorted) focal plane are mapped to the
    /// ideal pinhole directions that a real lens would image there.
    pub(in crate::render) distortion: Option<Distortion>,
    /// Unit vector toward the sun, render frame.
    pub sun: Vec3,
    /// Random-number key of each pixel: its index on the full sensor.
    pub(in crate::render) keys: PixelKeys,
    /// The target's motion over the exposure (None: the frame is one instant).
    pub(in crate::render) motion: Option<MovingPose>,
    /// The pose's camera → inertial rotation (places a star field).
    pub(in crate::render) camera_to_inertial: Option<glam::DQuat>,
}

impl View {
    /// `frame_origin_body` is where the render frame's origin sits in the body frame.
    ///
    /// Poses reach here through the pose gate (`pose::validate::check_pose`); a caller that
    /// bypasses it still gets a view that cannot fail: a position, attitude or sun that
    /// cannot be used gives a blind view (every ray misses: the background), and a sun
    /// direction too large to square is scaled before it is normalised.
    pub fn new(cam: &CameraModel, pose: &Pose, frame_origin_body: DVec3, bounds: TargetBounds) -> View {
        let q = pose.attitude;
        let q_usable = q.is_finite() && q.length_squared().is_finite() && q.length_squared() > 0.0;
        let sun_body = unit_or_none(pose.sun_dir);
        let usable = q_usable && pose.position.is_finite() && sun_body.is_some();
        let body_to_cam = if usable { DMat3::from_quat(q.normalize()) } else { DMat3::IDENTITY };
        let cam_to_body = body_to_cam.transpose();
        // Camera centre: x_c = R x_b + p = 0  ⇒  x_b = −Rᵀ p. A blind view's origin is NaN,
        // which `ray_along` and `pixel_rect` treat as "sees nothing".
        let origin = if usable { -(cam_to_body * pose.position) - frame_origin_body } else { DVec3::splat(f64::NAN) };
        let sun = (cam_to_body * sun_body.unwrap_or(DVec3::NEG_Z)).as_vec3();
        View {
            width: cam.width,
            height: cam.height,
            pp: [
                f64::from(cam.width) * 0.5 + cam.principal_point_px[0],
                f64::from(cam.height) * 0.5 + cam.principal_point_px[1],
            ],
            inv_focal_px: 1.0 / cam.focal_px(),
            origin,
            cam_to_render: cam_to_body,
            bounds,
            parts: None,
            distortion: None,
            sun,
            keys: PixelKeys::full(cam.width),
            motion: None,
            camera_to_inertial: pose.camera_to_inertial,
        }
    }

    /// The same view integrating over an exposure during which the target moves
    /// (`pose` is the exposure start's, as given to [`View::new`]). A still motion, or a
    /// blind view, stays the instant view: the same bytes as without it.
    pub fn with_motion(mut self, motion: Motion, pose: &Pose, frame_origin_body: DVec3) -> View {
        if motion.is_still() || !self.origin.is_finite() {
            return self;
        }
        let mut moving = MovingPose::new(motion, pose.position, pose.attitude, frame_origin_body);
        moving.first_row = self.keys.first_row();
        self.motion = Some(moving);
        self
    }

    /// The same view with the target's separate parts (camera rays start on the first
    /// part sphere they enter; none or empty: on the whole target's).
    pub fn with_parts(mut self, parts: Option<std::sync::Arc<[PartSphere]>>) -> View {
        self.parts = parts.filter(|p| !p.is_empty());
        self
    }

    /// The motion integrated over the exposure, if the frame is not one instant.
    pub fn motion(&self) -> Option<&Motion> {
        self.motion.as_ref().map(MovingPose::motion)
    }

    /// This view's camera as it is `dt` seconds after the exposure start, as an instant
    /// view (itself when nothing moves).
    pub fn instant(&self, dt: f64) -> View {
        let mut v = self.clone();
        if let Some(m) = v.motion.take() {
            (v.origin, v.cam_to_render) = m.at(dt);
        }
        v
    }

    /// The same view cropped to `window` of its image (`window` inside it, see
    /// [`Window::inside`]): the same sensor coordinates and random numbers per pixel, only
    /// fewer pixels. The image's pixel (0, 0) is the sensor's (`window.y`, `window.x`).
    pub fn window(mut self, window: &Window) -> View {
        // `pp - x` is exact (both are on pp's grid when x ≤ 2·pp), so each primary ray's
        // `(col + u) - pp'` rounds the same real number as the full view's `(x + col + u) - pp`.
        self.pp = [self.pp[0] - f64::from(window.x), self.pp[1] - f64::from(window.y)];
        self.keys = self.keys.shifted(window);
        if let Some(m) = &mut self.motion {
            m.first_row += window.y;
        }
        (self.width, self.height) = (window.width, window.height);
        self
    }

    /// True when `other` makes the same primary rays as this view through every pixel:
    /// the same image, lens, camera placement and target bounds, neither moving.
    pub fn same_rays(&self, other: &View) -> bool {
        let b = |v: &View| (v.bounds.centre, v.bounds.radius, v.bounds.min, v.bounds.max);
        (self.width, self.height, self.pp, self.inv_focal_px)
            == (other.width, other.height, other.pp, other.inv_focal_px)
            && (self.origin, self.cam_to_render, self.distortion, self.keys)
                == (other.origin, other.cam_to_render, other.distortion, other.keys)
            && b(self) == b(other)
            && self.parts == other.parts
            && self.motion.is_none()
            && other.motion.is_none()
    }

    /// Random-number key of the image's pixel (`row`, `col`).
    #[inline]
    pub fn pixel_key(&self, row: u32, col: u32) -> u64 {
        self.keys.key(row, col)
    }

    /// The image's width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The same view through a distorting lens (identity coefficients are ignored).
    pub fn with_distortion(mut self, d: Option<Distortion>) -> View {
        self.distortion = d.filter(|d| !d.is_identity());
        self
    }

    /// Direction (camera frame, not normalised: z = 1) through continuous pixel coordinate
    /// `(x, y)` (`x = col + u`, `y = row + v`).
    #[inline]
    pub fn camera_dir(&self, x: f64, y: f64) -> DVec3 {
        let (mut u, mut v) = ((x - self.pp[0]) * self.inv_focal_px, (y - self.pp[1]) * self.inv_focal_px);
        if let Some(d) = &self.distortion {
            let ideal = d.undistort(glam::DVec2::new(u, v));
            (u, v) = (ideal.x, ideal.y);
        }
        DVec3::new(u, v, 1.0)
    }

    /// [`View::camera_dir`] of four points on row `y`, bit for bit (the lens inverted four
    /// at a time, `Distortion::undistort4`).
    pub fn camera_dirs4(&self, xs: [f64; 4], y: f64) -> [DVec3; 4] {
        let v = (y - self.pp[1]) * self.inv_focal_px;
        let uv = xs.map(|x| glam::DVec2::new((x - self.pp[0]) * self.inv_focal_px, v));
        let ideal = match &self.distortion {
            Some(d) => d.undistort4(uv),
            None => uv,
        };
        ideal.map(|p| DVec3::new(p.x, p.y, 1.0))
    }

    /// Continuous pixel coordinate where a camera-frame point projects (pinhole).
    pub fn project_camera_point(cam: &CameraModel, p: DVec3) -> Option<[f64; 2]> {
        (p.z > 0.0).then(|| {
            let f = cam.focal_px();
            [
                p.x / p.z * f + f64::from(cam.width) * 0.5 + cam.principal_point_px[0],
                p.y / p.z * f + f64::from(cam.height) * 0.5 + cam.principal_point_px[1],
            ]
        })
    }

    /// The f32 primary ray through `(x, y)`, starting where it enters the target's
    /// bounding sphere; `None` if it misses the sphere (background).
    ///
    /// The line is set up in f64 with the unnormalised direction `d` (one square root and
    /// one division per ray): entry at `s₀ = c / (−b + √(b² − a·c))` with `a = |d|²`,
    /// `b = oc·d`, `c = |oc|² − r²` (the stable root: no cancellation for a far camera).
    /// The f32 direction is normalised in f32: its rounding tilts the ray by ~1e-7 rad
    /// about the exact entry point, i.e. micrometres across the target, whatever the range.
    #[inline]
    pub fn primary_ray(&self, x: f64, y: f64) -> Option<Ray> {
        self.ray_along(self.camera_dir(x, y))
    }

    /// [`View::primary_ray`] of a moving view's sample in image row `row` whose time
    /// coordinate is `u ∈ [0, 1)`: the camera where it is at that sample's time in the
    /// row's integration window (the instant ray without motion).
    #[inline]
    pub fn primary_ray_at(&self, x: f64, y: f64, row: u32, u: f32) -> Option<Ray> {
        let Some(m) = &self.motion else { return self.primary_ray(x, y) };
        let (origin, cam_to_render) = m.at(m.time_of(row, u));
        self.ray_from(origin, cam_to_render, self.camera_dir(x, y))
    }

    /// [`View::primary_ray`] and where its line crosses the ideal (undistorted) image
    /// plane, in pixels (`(x, y)` itself for a pinhole): rasterised visibility bins the
    /// samples there, where triangles project to triangles.
    #[inline]
    pub fn primary_ray_ideal(&self, x: f64, y: f64) -> Option<(Ray, [f64; 2])> {
        let dir = self.camera_dir(x, y);
        self.ray_along(dir).map(|r| (r, self.ideal_along(x, y, dir)))
    }

    /// Where the sample at pixel coordinate `(x, y)` lies on the ideal image plane.
    pub fn ideal_of_pixel(&self, x: f64, y: f64) -> [f64; 2] {
        self.ideal_along(x, y, self.camera_dir(x, y))
    }

    /// Ideal image point of the sample at `(x, y)` whose camera direction is `dir`: the
    /// pixel coordinate itself for a pinhole (no rounding through the direction).
    #[inline]
    fn ideal_along(&self, x: f64, y: f64, dir: DVec3) -> [f64; 2] {
        if self.distortion.is_some() { self.ideal_px(dir) } else { [x, y] }
    }

    /// Where the lens images the ideal image point `(x, y)` (pixels): the forward map that
    /// [`View::ideal_of_pixel`] inverts (`(x, y)` itself for a pinhole).
    #[inline]
    pub fn pixel_of_ideal(&self, x: f64, y: f64) -> [f64; 2] {
        let Some(d) = &self.distortion else { return [x, y] };
        d.distort_px(glam::DVec2::new(x, y), glam::DVec2::from(self.pp), self.focal_px()).to_array()
    }

    /// True when a lens model bends the rays.
    pub fn has_distortion(&self) -> bool {
        self.distortion.is_some()
    }

    /// A render-frame point in the camera frame (x right, y down, z along the boresight).
    #[inline]
    pub fn to_camera(&self, p: DVec3) -> DVec3 {
        self.cam_to_render.transpose() * (p - self.origin)
    }

    /// Ideal-image pixel coordinate of a camera-frame point with `z > 0`.
    #[inline]
    pub fn ideal_px(&self, q: DVec3) -> [f64; 2] {
        let f = 1.0 / self.inv_focal_px;
        [q.x / q.z * f + self.pp[0], q.y / q.z * f + self.pp[1]]
    }

    /// Focal length in pixels.
    pub fn focal_px(&self) -> f64 {
        1.0 / self.inv_focal_px
    }

    /// Always inlined: in the camera-ray loop the view's constants (`oc`, `c`) are then
    /// computed once, not per ray (a 1-spp goal frame ~3 % faster, same bytes).
    ///
    /// Every ray it returns is finite (origin and unit direction): a NaN or infinite
    /// input, or a line whose entry point does not fit an f32, is a miss. When the squares
    /// overflow (a camera beyond ~1e154 m, a pixel coordinate near f64::MAX) the
    /// intersection is redone on scaled vectors ([`View::ray_along_scaled`]); the common
    /// path's arithmetic is unchanged.
    #[inline(always)]
    pub(in crate::render) fn ray_along(&self, dir_cam: DVec3) -> Option<Ray> {
        self.ray_from(self.origin, self.cam_to_render, dir_cam)
    }

    /// [`View::ray_along`] from a camera at `origin` turned by `cam_to_render`.
    #[inline(always)]
    fn ray_from(&self, origin: DVec3, cam_to_render: DMat3, dir_cam: DVec3) -> Option<Ray> {
        let d = cam_to_render * dir_cam;
        if let Some(parts) = &self.parts {
            return self.ray_from_parts(parts, origin, d);
        }
        self.ray_into(origin, d, self.bounds.centre, self.bounds.radius)
    }

    /// The ray from `origin` along `d` starting where it enters the sphere (`centre`, `r`).
    #[inline(always)]
    fn ray_into(&self, origin: DVec3, d: DVec3, centre: DVec3, r: f64) -> Option<Ray> {
        let oc = origin - centre;
        let a = d.length_squared();
        let b = oc.dot(d);
        let c = oc.length_squared() - r * r;
        let disc = b * b - a * c;
        // Finite `disc` means `a`, `b²` and `a·c` are finite (any inf or NaN among them
        // makes it inf or NaN).
        if !disc.is_finite() {
            return self.ray_along_scaled(origin, d, oc, r);
        }
        if disc < 0.0 {
            return None;
        }
        let q = -b + disc.sqrt(); // a × (exit distance in units of d)
        if q <= 0.0 {
            return None; // the sphere is behind the camera
        }
        let start = if c > 0.0 { c / q } else { 0.0 }; // camera inside the sphere: start there
        finite_ray(origin + d * start, d)
    }

    /// [`View::ray_into`] the part sphere the line enters first: each part's own sphere
    /// gives the same f32 ray as a target of that part alone would.
    #[inline(never)]
    fn ray_from_parts(&self, parts: &[PartSphere], origin: DVec3, d: DVec3) -> Option<Ray> {
        let mut best: Option<(f64, Ray)> = None;
        for s in parts {
            let Some(ray) = self.ray_into(origin, d, s.centre, s.radius) else { continue };
            // Distance of the start from the camera along the line (f64, only to order).
            let along = (ray.origin.as_dvec3() - origin).dot(d);
            if best.is_none_or(|(b, _)| along < b) {
                best = Some((along, ray));
            }
        }
        best.map(|(_, r)| r)
    }

    /// [`View::ray_into`] for lines whose squares overflow: `oc` and the radius scaled by
    /// the largest of their magnitudes, `d` by its own (the entry parameter scales back),
    /// so nothing squared exceeds 3. A non-finite input is a miss.
    #[cold]
    #[inline(never)]
    fn ray_along_scaled(&self, origin: DVec3, d: DVec3, oc: DVec3, r: f64) -> Option<Ray> {
        if !(d.is_finite() && oc.is_finite() && r.is_finite()) {
            return None;
        }
        let (sd, so) = (d.abs().max_element(), oc.abs().max_element().max(r));
        if !(sd > 0.0 && so > 0.0) {
            return None;
        }
        let (d1, oc1, r1) = (d / sd, oc / so, r / so);
        let (a, b) = (d1.length_squared(), oc1.dot(d1));
        let c = oc1.length_squared() - r1 * r1;
        let disc = b * b - a * c;
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let q = -b + disc.sqrt();
        if q.is_nan() || q <= 0.0 {
            return None;
        }
        // Entry at `s₁·so` along `d1`.
        let start = if c > 0.0 { c / q * so } else { 0.0 };
        finite_ray(origin + d1 * start, d1)
    }

    /// The target box's eight corners on the ideal image plane, `(x/z, y/z)` in the camera
    /// frame, or `None` unless all lie in front of the camera.
    pub(in crate::render) fn box_corners_image(&self) -> Option<[(f64, f64); 8]> {
        self.box_corners_from(self.origin, self.cam_to_render.transpose())
    }

    /// [`View::box_corners_image`] of the box `min`–`max` (render frame).
    fn corners_of(&self, min: DVec3, max: DVec3) -> Option<[(f64, f64); 8]> {
        box_corners(min, max, self.origin, self.cam_to_render.transpose())
    }

    /// [`View::box_corners_image`] seen from a camera at `origin` turned by `render_to_cam`.
    fn box_corners_from(&self, origin: DVec3, render_to_cam: DMat3) -> Option<[(f64, f64); 8]> {
        box_corners(self.bounds.min, self.bounds.max, origin, render_to_cam)
    }

    /// Where the camera is across the exposure, as the culling bounds it: camera centre and
    /// render → camera rotation at [`MOTION_STEPS`] + 1 evenly spaced instants over the
    /// frame's span (one, the view's own, for a still view). Stack-held: the serving loop
    /// allocates nothing per frame.
    pub(in crate::render) fn exposure_instants(&self) -> ExposureInstants {
        let mut out = ExposureInstants { at: [(self.origin, self.cam_to_render.transpose()); INSTANTS], len: 1 };
        let Some(m) = &self.motion else { return out };
        let span = m.span_s(self.height);
        let at = |k: u32, steps: u32| {
            let (origin, cam_to_render) = m.at(span * f64::from(k) / f64::from(steps));
            (origin, cam_to_render.transpose())
        };
        for (k, slot) in out.at.iter_mut().enumerate() {
            *slot = at(k as u32, MOTION_STEPS);
        }
        // As few instants as keep the bounds' corners within about a pixel between two
        // (each costs a pass over the leaf boxes); all of them when that is unknown.
        let steps = match self.box_path_px(&out.at) {
            Some(px) if px.is_finite() => (px.ceil() as u32).clamp(1, MOTION_STEPS),
            _ => MOTION_STEPS,
        };
        for k in 0..=steps {
            out.at[k as usize] = at(k, steps);
        }
        out.len = steps as usize + 1;
        out
    }

    /// The longest image path (pixels) a corner of the target's bounds travels through
    /// the camera poses `at`, or `None` when a corner is behind the camera at one of them.
    fn box_path_px(&self, at: &[(DVec3, DMat3)]) -> Option<f64> {
        let f = self.focal_px();
        let mut path = [0.0f64; 8];
        let mut prev: Option<[(f64, f64); 8]> = None;
        for &(origin, render_to_cam) in at {
            let now = self.box_corners_from(origin, render_to_cam)?;
            if let Some(was) = prev {
                for ((p, n), w) in path.iter_mut().zip(&now).zip(&was) {
                    *p += (n.0 * f - w.0 * f).hypot(n.1 * f - w.1 * f);
                }
            }
            prev = Some(now);
        }
        Some(path.into_iter().fold(0.0, f64::max))
    }

    /// Conservative pixel rectangle that can see the bounds (1 px margin), or `None` if
    /// the bounds are entirely outside the image or behind the camera. A moving view's
    /// rectangle covers the whole exposure: the union of the instant rectangles at
    /// [`MOTION_STEPS`] + 1 times across it, grown by the most any edge moved between
    /// two of them.
    pub fn pixel_rect(&self) -> Option<PixelRect> {
        let Some(m) = &self.motion else { return self.instant_rect() };
        let span = m.span_s(self.height);
        let rects: [Option<PixelRect>; MOTION_STEPS as usize + 1] =
            std::array::from_fn(|k| self.instant(span * k as f64 / f64::from(MOTION_STEPS)).instant_rect());
        let mut union: Option<PixelRect> = None;
        let mut step = 0u32;
        for pair in rects.windows(2) {
            if let [Some(a), Some(b)] = pair {
                step = step
                    .max(a.col0.abs_diff(b.col0))
                    .max(a.col1.abs_diff(b.col1))
                    .max(a.row0.abs_diff(b.row0))
                    .max(a.row1.abs_diff(b.row1));
            } else if pair[0].is_some() != pair[1].is_some() {
                // The bounds enter or leave the image between two steps: no bound on how far.
                return Some(PixelRect { col0: 0, col1: self.width, row0: 0, row1: self.height });
            }
        }
        for r in rects.iter().flatten() {
            union = Some(match union {
                None => *r,
                Some(u) => PixelRect {
                    col0: u.col0.min(r.col0),
                    col1: u.col1.max(r.col1),
                    row0: u.row0.min(r.row0),
                    row1: u.row1.max(r.row1),
                },
            });
        }
        union.map(|u| PixelRect {
            col0: u.col0.saturating_sub(step),
            col1: (u.col1 + step).min(self.width),
            row0: u.row0.saturating_sub(step),
            row1: (u.row1 + step).min(self.height),
        })
    }

    /// Where the sphere (`centre`, `r`, render frame) lies on the ideal image plane.
    fn sphere_image(&self, centre: DVec3, r: f64) -> SphereImage {
        let c = self.cam_to_render.transpose() * (centre - self.origin);
        if c.length() <= r * 1.000001 {
            return SphereImage::Inside;
        }
        // Exact extent of x/z (and y/z) over the sphere: tangent lines in the XZ (YZ) plane.
        let extent = |a: f64| -> Option<(f64, f64)> {
            let rho = (a * a + c.z * c.z).sqrt();
            if rho <= r {
                return Some((f64::NEG_INFINITY, f64::INFINITY));
            }
            let mid = a.atan2(c.z);
            let half = (r / rho).asin();
            let (lo, hi) = (mid - half, mid + half);
            let q = std::f64::consts::FRAC_PI_2;
            if hi <= -q || lo >= q {
                return None; // entirely behind the camera plane in this projection
            }
            Some((if lo <= -q { f64::NEG_INFINITY } else { lo.tan() }, if hi >= q { f64::INFINITY } else { hi.tan() }))
        };
        match (extent(c.x), extent(c.y)) {
            (Some((x0, x1)), Some((y0, y1))) => SphereImage::Box((x0, x1, y0, y1)),
            _ => SphereImage::Behind,
        }
    }

    /// [`View::pixel_rect`] of the view's pose (ignoring motion).
    fn instant_rect(&self) -> Option<PixelRect> {
        if !self.origin.is_finite() {
            return None; // a blind view (see `View::new`)
        }
        let full = PixelRect { col0: 0, col1: self.width, row0: 0, row1: self.height };
        if self.distortion.is_some() {
            return Some(full); // the pinhole bound does not hold through a distorting lens
        }
        let Some(parts) = &self.parts else {
            let corners = self.box_corners_image();
            return self.sphere_rect(self.sphere_image(self.bounds.centre, self.bounds.radius), corners.as_ref());
        };
        // A target of several parts: the union of the rectangles of their spheres in the
        // image (a far part off the image does not widen the near one's).
        let mut union: Option<PixelRect> = None;
        for s in parts.iter() {
            match self.sphere_image(s.centre, s.radius) {
                SphereImage::Inside => return Some(full),
                SphereImage::Behind => {}
                image => {
                    if let Some(r) = self.sphere_rect(image, self.corners_of(s.min, s.max).as_ref()) {
                        union = Some(union.map_or(r, |u| PixelRect {
                            col0: u.col0.min(r.col0),
                            col1: u.col1.max(r.col1),
                            row0: u.row0.min(r.row0),
                            row1: u.row1.max(r.row1),
                        }));
                    }
                }
            }
        }
        union
    }

    /// The pixel rectangle of a sphere's image (1 px margin), cut to the target box's
    /// `corners` when they are all in front of the camera; `None` when it is empty.
    fn sphere_rect(&self, image: SphereImage, corners: Option<&[(f64, f64); 8]>) -> Option<PixelRect> {
        let (mut x0, mut x1, mut y0, mut y1) = match image {
            SphereImage::Inside => return Some(PixelRect { col0: 0, col1: self.width, row0: 0, row1: self.height }),
            SphereImage::Behind => return None,
            SphereImage::Box(b) => b,
        };
        // The AABB's corners give a tighter box for elongated targets when all are in front.
        if let Some(corners) = corners {
            let xs = corners.iter().map(|p| p.0);
            let ys = corners.iter().map(|p| p.1);
            x0 = x0.max(xs.clone().fold(f64::INFINITY, f64::min));
            x1 = x1.min(xs.fold(f64::NEG_INFINITY, f64::max));
            y0 = y0.max(ys.clone().fold(f64::INFINITY, f64::min));
            y1 = y1.min(ys.fold(f64::NEG_INFINITY, f64::max));
        }
        let f = 1.0 / self.inv_focal_px;
        let to_px = |v: f64, pp: f64, n: u32, up: bool| -> u32 {
            let p = v * f + pp;
            let p = if up { p.ceil() + 1.0 } else { p.floor() - 1.0 };
            p.clamp(0.0, f64::from(n)) as u32
        };
        let rect = PixelRect {
            col0: to_px(x0, self.pp[0], self.width, false),
            col1: to_px(x1, self.pp[0], self.width, true),
            row0: to_px(y0, self.pp[1], self.height, false),
            row1: to_px(y1, self.pp[1], self.height, true),
        };
        (rect.col0 < rect.col1 && rect.row0 < rect.row1).then_some(rect)
    }
}

/// The eight corners of the box `min`–`max` (render frame) on the ideal image plane of a
/// camera at `origin` turned by `render_to_cam`, or `None` unless all lie in front of it.
fn box_corners(min: DVec3, max: DVec3, origin: DVec3, render_to_cam: DMat3) -> Option<[(f64, f64); 8]> {
    let mut corners = [(0.0, 0.0); 8];
    for (i, out) in corners.iter_mut().enumerate() {
        let p = DVec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        );
        let q = render_to_cam * (p - origin);
        if q.z <= 0.0 || q.z.is_nan() {
            return None;
        }
        *out = (q.x / q.z, q.y / q.z);
    }
    Some(corners)
}

/// A sphere's image: the camera inside it, wholly behind the camera, or a box
/// `(x0, x1, y0, y1)` on the ideal image plane (`x/z`, `y/z`).
#[derive(Clone, Copy)]
enum SphereImage {
    Inside,
    Behind,
    Box((f64, f64, f64, f64)),
}

/// Instants across a moving view's exposure at which its pixel rectangle and coverage
/// are evaluated.
const MOTION_STEPS: u32 = 32;
const INSTANTS: usize = MOTION_STEPS as usize + 1;

/// A view's camera at the instants of [`View::exposure_instants`].
pub(in crate::render) struct ExposureInstants {
    at: [(DVec3, DMat3); INSTANTS],
    len: usize,
}

impl ExposureInstants {
    /// `(camera centre, render → camera rotation)` per instant, in time order.
    pub(in crate::render) fn as_slice(&self) -> &[(DVec3, DMat3)] {
        &self.at[..self.len]
    }
}

/// The f32 ray from `origin` along `d`, or `None` unless both fit an f32 and the direction
/// normalises.
///
/// The direction is normalised in f32 (the rays' bytes depend on it); a direction whose
/// f32 square overflows or underflows (a pixel coordinate far off the sensor) is scaled
/// by its largest component first, so every ray returned has a unit direction.
#[inline(always)]
fn finite_ray(origin: DVec3, d: DVec3) -> Option<Ray> {
    let d32 = d.as_vec3();
    let l2 = d32.length_squared();
    let dir = if l2.is_finite() && l2 > f32::MIN_POSITIVE {
        d32.normalize()
    } else {
        (d / d.abs().max_element()).as_vec3().normalize()
    };
    let ray = Ray { origin: origin.as_vec3(), dir, tmax: f32::INFINITY };
    (ray.origin.is_finite() && ray.dir.is_finite() && ray.dir.length_squared() > 0.5).then_some(ray)
}

/// `v` as a unit vector, scaled by its largest component first when its square would
/// overflow or underflow; `None` for a zero or non-finite `v`. The common case is
/// `v.normalize()` exactly.
pub fn unit_or_none(v: DVec3) -> Option<DVec3> {
    if !v.is_finite() {
        return None;
    }
    let l2 = v.length_squared();
    let u =
        if l2.is_finite() && l2 > f64::MIN_POSITIVE { v.normalize() } else { (v / v.abs().max_element()).normalize() };
    u.is_finite().then_some(u)
}
