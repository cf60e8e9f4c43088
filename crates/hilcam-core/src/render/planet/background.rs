//! The planet as the background of pixels the path tracer does not sample.
//!
//! The frame loop samples only pixels that can see the target (`cull`); every other pixel
//! used to be the constant sky. With a planet, each of them is the mean of the planet's
//! radiance over the same camera samples (positions in the pixel from the same random
//! streams) that tracing the pixel would draw, so a pixel has the same expected value
//! whether it is culled or traced. Rows of pixels whose area cannot reach the planet's
//! disc cost one direction test per pixel.

use super::PlacedPlanet;
use crate::render::camera::View;
use crate::render::film::RadianceImage;
use crate::render::sampling::PerSample;
use glam::DVec3;
use rayon::prelude::*;

/// Fill `img` (already `background` everywhere) with the planet's radiance averaged over
/// `samples` camera samples per pixel (sample indices `0..samples` of each pixel's
/// streams under `seed` and `frame`).
pub fn fill<S: PerSample>(
    img: &mut RadianceImage,
    view: &View,
    planet: &PlacedPlanet,
    background: f32,
    samples: u32,
    (seed, frame): (u64, u64),
) {
    let w = img.width as usize;
    if w == 0 {
        return;
    }
    let reach = Reach::new(view, planet);
    img.data.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        let row = row as u32;
        for (col, px) in out.iter_mut().enumerate() {
            let col = col as u32;
            if !reach.may_see(view, row, col) {
                continue;
            }
            let key = view.pixel_key(row, col);
            let mut sum = 0.0f32;
            for index in 0..samples {
                let mut rng = S::for_sample(seed, frame, key, index);
                let j = rng.next_2d();
                let (x, y) = (f64::from(col) + f64::from(j.x), f64::from(row) + f64::from(j.y));
                sum += planet.seen_by_camera(view, x, y).unwrap_or(background);
            }
            *px = sum * (1.0 / samples as f32);
        }
    });
}

/// A conservative test of whether a pixel's area can see the planet: the angle between
/// the pixel's centre direction and the planet's centre is within the disc's angular
/// radius plus a pixel's (the largest angle from a pixel's centre to its corners, over the
/// pixels at the image's corners, edge midpoints and centre, × 1.5: a lens's radial
/// distortion changes a pixel's angular size monotonically from the centre out).
struct Reach {
    /// Unit vector toward the planet's centre, camera frame.
    toward: DVec3,
    /// Angular radius of the disc plus a pixel's, radians (π when the camera is inside:
    /// it sees it all).
    limit: f64,
}

impl Reach {
    fn new(view: &View, planet: &PlacedPlanet) -> Reach {
        let c = view.to_camera(planet.centre);
        let dist = c.length();
        let disc = if dist > planet.radius { (planet.radius / dist).asin() } else { std::f64::consts::PI };
        let (w, h) = view.size();
        let (w, h) = (w.saturating_sub(1), h.saturating_sub(1));
        let pixel = [0, w / 2, w]
            .iter()
            .flat_map(|&col| [0, h / 2, h].map(|row| pixel_half_angle(view, row, col)))
            .fold(0.0, f64::max);
        // 1e-9 rad: rounding.
        Reach { toward: c / dist, limit: disc + 1.5 * pixel + 1e-9 }
    }

    #[inline]
    fn may_see(&self, view: &View, row: u32, col: u32) -> bool {
        let centre = view.camera_dir(f64::from(col) + 0.5, f64::from(row) + 0.5).normalize();
        angle(centre, self.toward) <= self.limit || !self.toward.is_finite()
    }
}

/// The largest angle from pixel (`row`, `col`)'s centre direction to one of its corners.
fn pixel_half_angle(view: &View, row: u32, col: u32) -> f64 {
    let (x, y) = (f64::from(col), f64::from(row));
    let centre = view.camera_dir(x + 0.5, y + 0.5).normalize();
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .iter()
        .map(|&(u, v)| angle(centre, view.camera_dir(x + u, y + v).normalize()))
        .fold(0.0, f64::max)
}

/// Angle between unit vectors, accurate at small angles (atan2 of |a×b| and a·b).
#[inline]
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}
