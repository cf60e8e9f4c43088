//! Drawing the stars of one frame into its radiance image.

use super::{StarField, StarStats};
use crate::render::camera::View;
use crate::render::film::RadianceImage;
use crate::render::geometry::Accel;
use crate::render::planet::PlacedPlanet;
use glam::{DMat3, DVec3};

/// Stars whose ideal (undistorted) image point lies farther outside the image than this
/// fraction of its larger side are not projected through the lens: a distortion
/// polynomial is only meaningful over the field it was fitted to.
const IDEAL_MARGIN: f64 = 0.25;

impl StarField {
    /// The continuous pixel coordinate (`col + u`, `row + v`, pixel centres at `.5`) of
    /// every star in front of the camera whose image point is near the image, with its
    /// index and camera-frame direction, for the view's camera → inertial rotation (else
    /// the field's default). Nothing for an unusable rotation. Allocates nothing.
    pub fn image_points<'a>(&'a self, view: &'a View) -> impl Iterator<Item = (usize, DVec3, [f64; 2])> + 'a {
        let q = view.camera_to_inertial.unwrap_or(self.default_camera_to_inertial);
        let usable = q.is_finite() && q.length_squared() > 0.0;
        let inertial_to_cam = DMat3::from_quat(if usable { q.normalize() } else { glam::DQuat::IDENTITY }).transpose();
        let (w, h) = (f64::from(view.width), f64::from(view.height));
        let m = IDEAL_MARGIN * w.max(h);
        let stars = if usable { &self.stars[..] } else { &[] };
        stars.iter().enumerate().filter_map(move |(i, s)| {
            let d = inertial_to_cam * s.dir;
            if d.z <= 0.0 {
                return None;
            }
            let [x, y] = view.ideal_px(d);
            if !(-m..=w + m).contains(&x) || !(-m..=h + m).contains(&y) {
                return None;
            }
            Some((i, d, view.pixel_of_ideal(x, y)))
        })
    }

    /// Add every visible star to `img` (the frame `view` renders): the radiance
    /// `E / Ω_pixel` split bilinearly over the four pixels around its image point, so its
    /// centroid is the image point exactly; a star whose line of sight hits the target
    /// (`accel`) or the planet's disc is hidden. In catalogue order, one thread: the same
    /// bytes every time.
    pub fn deposit(
        &self,
        img: &mut RadianceImage,
        view: &View,
        accel: &Accel,
        planet: Option<&PlacedPlanet>,
    ) -> StarStats {
        let mut stats = StarStats { rows: (u32::MAX, 0), ..StarStats::default() };
        let (w, h) = (i64::from(img.width), i64::from(img.height));
        // Solid angle of a pixel on the axis, (pitch / f)², in units where pitch = 1.
        let per_irradiance = 1.0 / (view.inv_focal_px * view.inv_focal_px);
        for (i, dir, [x, y]) in self.image_points(view) {
            // Bilinear weights about the four pixel centres around (x, y).
            let (fx, fy) = (x - 0.5, y - 0.5);
            let (c0, r0) = (fx.floor(), fy.floor());
            let (tx, ty) = (fx - c0, fy - r0);
            let (c0, r0) = (c0 as i64, r0 as i64);
            if c0 + 1 < 0 || r0 + 1 < 0 || c0 >= w || r0 >= h {
                continue;
            }
            stats.in_view += 1;
            let behind_planet =
                planet.is_some_and(|p| p.radiance(view.origin, (view.cam_to_render * dir).normalize()).is_some());
            if behind_planet || view.ray_along(dir).is_some_and(|ray| accel.occluded(&ray)) {
                stats.hidden += 1;
                continue;
            }
            let l = self.stars[i].irradiance_w_m2 * per_irradiance;
            for (dr, wy) in [(0, 1.0 - ty), (1, ty)] {
                for (dc, wx) in [(0, 1.0 - tx), (1, tx)] {
                    let (c, r) = (c0 + dc, r0 + dr);
                    if (0..w).contains(&c) && (0..h).contains(&r) && wx * wy > 0.0 {
                        let p = &mut img.data[(r * w + c) as usize];
                        *p = (f64::from(*p) + l * wx * wy) as f32;
                        stats.rows = (stats.rows.0.min(r as u32), stats.rows.1.max(r as u32 + 1));
                    }
                }
            }
        }
        if stats.rows.0 >= stats.rows.1 {
            stats.rows = (0, 0);
        }
        stats
    }
}
