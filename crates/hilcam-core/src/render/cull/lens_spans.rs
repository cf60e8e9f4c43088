//! Per-row spans of the target's bounds through a distorting lens.
//!
//! Without a lens the bounds' image is an ellipse and a convex hexagon, solved exactly
//! per row (`silhouette.rs`). A Brown–Conrady lens bends both. The lens maps the ideal
//! image plane one-to-one onto the sensor within the field it was validated for (no fold
//! over: `Distortion::validate`), so the region the target can occupy on the sensor is
//! bounded by the distorted *boundaries* of the ideal regions. Those boundaries are
//! sampled densely (an ellipse of 512 points, each of the box's 28 corner-to-corner
//! segments in 32 pieces), mapped through the lens into pixels and rasterised into
//! per-row x-ranges: the extremes of a region within a row band lie on its boundary.
//! A chord cuts a curve by at most its sagitta, well under a pixel at these densities
//! (≈ 7.5e-5 of the curve's radius); the caller adds a margin for it.

use crate::render::camera::distortion::Distortion;
use glam::{DVec2, DVec3};

/// Points on the ideal ellipse boundary.
const ELLIPSE_POINTS: usize = 512;
/// Pieces per box segment.
const SEGMENT_PIECES: usize = 32;

/// Per-row `(x_lo, x_hi)` pixel ranges (empty when `lo > hi`) of the sphere's image ∩
/// the box's image through the lens, written into `rows` (`hull` is scratch; both keep
/// their buffers, so a renderer reusing them allocates nothing); false when the bounds
/// reach beyond the field the lens is valid over (then every pixel must be traced).
///
/// `c`: sphere centre (camera frame, `c.z > r`); `corners`: the box corners' ideal image
/// points when all are in front; `pp`: principal point (pixels); `f`: focal length
/// (pixels); `max_r`: normalised ideal radius over which the lens was validated.
#[allow(clippy::too_many_arguments)]
pub(super) fn lens_spans(
    lens: &Distortion,
    c: DVec3,
    r: f64,
    corners: Option<&[(f64, f64); 8]>,
    pp: [f64; 2],
    f: f64,
    height: u32,
    max_r: f64,
    rows: &mut Vec<(f64, f64)>,
    hull: &mut Vec<(f64, f64)>,
) -> bool {
    let to_px = |p: DVec2| -> DVec2 {
        let d = lens.distort(p);
        DVec2::new(pp[0] + d.x * f, pp[1] + d.y * f)
    };
    // The cone tangent to the sphere: directions ĉ cosθ + (e1 cosφ + e2 sinφ) sinθ.
    let len = c.length();
    let axis = c / len;
    let e1 = axis.any_orthonormal_vector();
    let e2 = axis.cross(e1);
    let sin_t = r / len;
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    // On the stack (8 KB): the ellipse, then its image in pixels.
    let mut ellipse = [DVec2::ZERO; ELLIPSE_POINTS];
    for (i, p) in ellipse.iter_mut().enumerate() {
        let phi = i as f64 / ELLIPSE_POINTS as f64 * std::f64::consts::TAU;
        let d = axis * cos_t + (e1 * phi.cos() + e2 * phi.sin()) * sin_t;
        *p = DVec2::new(d.x / d.z, d.y / d.z);
    }
    if ellipse.iter().any(|p| p.length().is_nan() || p.length() > max_r) {
        return false;
    }
    let empty = (f64::INFINITY, f64::NEG_INFINITY);
    rows.clear();
    rows.resize(height as usize, empty);
    let px = ellipse.map(&to_px);
    for i in 0..px.len() {
        rasterise(rows, px[i], px[(i + 1) % px.len()]);
    }
    // The box: only when its whole hull lies in the valid field (a disc, so the corners
    // being inside is enough); otherwise the sphere alone bounds the target.
    let Some(corners) = corners.filter(|cs| cs.iter().all(|&(u, v)| DVec2::new(u, v).length() <= max_r)) else {
        return true;
    };
    hull.clear();
    hull.resize(height as usize, empty);
    for (i, &(ua, va)) in corners.iter().enumerate() {
        for &(ub, vb) in &corners[i + 1..] {
            let (a, b) = (DVec2::new(ua, va), DVec2::new(ub, vb));
            let mut prev = to_px(a);
            for k in 1..=SEGMENT_PIECES {
                let next = to_px(a.lerp(b, k as f64 / SEGMENT_PIECES as f64));
                rasterise(hull, prev, next);
                prev = next;
            }
        }
    }
    for (s, h) in rows.iter_mut().zip(hull.iter()) {
        *s = (s.0.max(h.0), s.1.min(h.1));
    }
    true
}

/// Widen each row band `[row, row + 1]` that the segment `a`–`b` crosses to the
/// segment's x-range inside that band.
fn rasterise(rows: &mut [(f64, f64)], a: DVec2, b: DVec2) {
    let n = rows.len() as f64;
    let (y0, y1) = (a.y.min(b.y), a.y.max(b.y));
    if y1.is_nan() || y0.is_nan() || y1 < 0.0 || y0 > n {
        return;
    }
    let (r0, r1) = (y0.max(0.0).floor() as usize, (y1.min(n - 1e-9).floor() as usize).min(rows.len() - 1));
    for (row, span) in rows.iter_mut().enumerate().take(r1 + 1).skip(r0) {
        let (band0, band1) = (row as f64, row as f64 + 1.0);
        let (xa, xb) = if a.y == b.y {
            (a.x, b.x)
        } else {
            let t = |y: f64| ((y - a.y) / (b.y - a.y)).clamp(0.0, 1.0);
            (a.x + (b.x - a.x) * t(band0), a.x + (b.x - a.x) * t(band1))
        };
        span.0 = span.0.min(xa.min(xb));
        span.1 = span.1.max(xa.max(xb));
    }
}
