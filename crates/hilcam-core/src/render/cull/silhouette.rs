//! Per-row column spans of the target's bounding sphere on the image.
//!
//! [`View::pixel_rect`] bounds the target by a rectangle; for an oblique, elongated
//! target most of that rectangle lies outside the bounding sphere's image, where every
//! primary ray misses and a sample would still pay for its random numbers and ray set-up.
//! The sphere's image through a pinhole is an ellipse (when the sphere lies wholly in
//! front of the camera); this module gives, for each pixel row, the columns whose pixel
//! area meets that ellipse, so the renderer skips the rest without touching them.
//!
//! In normalised image coordinates `(u, v)` (direction `(u, v, 1)` in the camera frame)
//! with the sphere centre `c` (camera frame) and radius `r`, a direction meets the sphere
//! iff `Q(u, v) = (c·d)² − (|c|² − r²)|d|² ≥ 0` (and `c·d > 0`, implied when `c_z > r`).
//! For fixed `v`, `Q` is a concave quadratic in `u`: the row's chord is between its roots.
//!
//! The target's axis-aligned box gives a second bound: its image is the convex hull of the
//! eight projected corners (when all lie in front of the camera), and a row band meets
//! that hull between the extreme abscissae of the corners inside the band and of the
//! band edges' crossings of the 28 corner-to-corner segments (the hull's edges are among
//! them; the other segments lie inside it). A span is the intersection of both bounds.
//! Through a distorting lens the same two regions are bent; `lens_spans` bounds them.

use super::lens_spans::lens_spans;
use crate::render::camera::View;
use glam::DVec3;

/// The bounding sphere's image, ready to answer per-row column spans.
#[derive(Clone, Debug)]
pub struct Silhouette {
    c: DVec3,
    /// `|c|² − r²`.
    k: f64,
    /// Leftmost / rightmost points of the ellipse, `(u, v)`.
    left: (f64, f64),
    right: (f64, f64),
    /// Projected box corners `(u, v)`, when all eight lie in front of the camera.
    corners: Option<[(f64, f64); 8]>,
    /// Through a distorting lens: per-row pixel x-ranges (`lens_spans`), used instead.
    lens: Option<Vec<(f64, f64)>>,
    pp: [f64; 2],
    focal_px: f64,
    width: u32,
}

/// Columns added on each side of a span: the roots are rounded, the span never narrowed.
const MARGIN_PX: f64 = 1.0;
/// Through a lens the boundaries are sampled: a wider margin covers chords and Newton's
/// tolerance in the renderer's undistortion.
const LENS_MARGIN_PX: f64 = 2.0;

/// The buffers of a lens silhouette's rows, kept from frame to frame by a renderer that
/// allocates nothing per frame ([`Silhouette::new_reusing`], [`Silhouette::recycle`]).
#[derive(Debug, Default)]
pub struct SilhouetteBuffers {
    rows: Vec<(f64, f64)>,
    hull: Vec<(f64, f64)>,
}

impl Silhouette {
    /// `None` when the span test does not apply: a sphere not wholly in front of the
    /// camera (its image is then not an ellipse), or, through a lens, bounds reaching
    /// beyond the field the lens is valid over; use the rectangle then.
    pub fn new(view: &View) -> Option<Silhouette> {
        Self::new_reusing(view, &mut SilhouetteBuffers::default())
    }

    /// [`Silhouette::new`] with its row buffers (through a lens) taken from `spare`; give
    /// them back with [`Silhouette::recycle`] and the next frame allocates nothing.
    pub fn new_reusing(view: &View, spare: &mut SilhouetteBuffers) -> Option<Silhouette> {
        let c = view.cam_to_render.transpose() * (view.bounds.centre - view.origin);
        let r = view.bounds.radius;
        if c.z.is_nan() || c.z <= r * 1.000_001 {
            return None;
        }
        let k = c.length_squared() - r * r;
        // Leftmost/rightmost image points: tangent planes through the camera's Y axis, at
        // u = tan(atan2(cx, cz) ∓ asin(r/ρ)), ρ = |(cx, cz)| > r because cz > r. There the
        // ellipse's tangent is vertical: ∂Q/∂v = 0 ⇒ v = cy(cx·u + cz)/(k − cy²).
        let rho = (c.x * c.x + c.z * c.z).sqrt();
        let (mid, half) = (c.x.atan2(c.z), (r / rho).asin());
        let v_at = |u: f64| c.y * (c.x * u + c.z) / (k - c.y * c.y);
        let (ul, ur) = ((mid - half).tan(), (mid + half).tan());
        let corners = view.box_corners_image();
        let focal_px = 1.0 / view.inv_focal_px;
        let lens = match &view.distortion {
            None => None,
            Some(d) => {
                // The field `Distortion::validate` is run over by the sensor config: the
                // half-diagonal from the principal point, 5 % margin, normalised.
                let hw = f64::from(view.width) / 2.0 + (view.pp[0] - f64::from(view.width) / 2.0).abs();
                let hh = f64::from(view.height) / 2.0 + (view.pp[1] - f64::from(view.height) / 2.0).abs();
                let max_r = 1.05 * (hw * hw + hh * hh).sqrt() / focal_px;
                let mut rows = std::mem::take(&mut spare.rows);
                let (pp, height, hull) = (view.pp, view.height, &mut spare.hull);
                if !lens_spans(d, c, r, corners.as_ref(), pp, focal_px, height, max_r, &mut rows, hull) {
                    spare.rows = rows;
                    return None;
                }
                Some(rows)
            }
        };
        Some(Silhouette {
            c,
            k,
            left: (ul, v_at(ul)),
            right: (ur, v_at(ur)),
            corners,
            lens,
            pp: view.pp,
            focal_px,
            width: view.width,
        })
    }

    /// Hand the lens rows' buffer back to `spare` for the next frame.
    pub fn recycle(self, spare: &mut SilhouetteBuffers) {
        if let Some(rows) = self.lens {
            spare.rows = rows;
        }
    }

    /// The ellipse's chord `[u0, u1]` at image height `v`, if the line meets it.
    fn chord(&self, v: f64) -> Option<(f64, f64)> {
        let c = self.c;
        let s = c.y * v + c.z;
        let a = c.x * c.x - self.k; // < 0: cz > r makes k − cx² = cy² + cz² − r² > 0
        let b = 2.0 * c.x * s;
        let cc = s * s - self.k * (v * v + 1.0);
        let disc = b * b - 4.0 * a * cc;
        if disc < 0.0 {
            return None;
        }
        let (r0, r1) = ((-b + disc.sqrt()) / (2.0 * a), (-b - disc.sqrt()) / (2.0 * a));
        Some((r0.min(r1), r0.max(r1)))
    }

    /// Columns `[col0, col1)` of pixel row `row` whose area `[col, col+1) × [row, row+1)`
    /// can meet the sphere's image (one pixel of margin), or `None` if none can.
    pub fn columns(&self, row: u32) -> Option<(u32, u32)> {
        if let Some(rows) = &self.lens {
            let &(lo, hi) = rows.get(row as usize)?;
            return self.to_columns(lo, hi, LENS_MARGIN_PX);
        }
        let v_of = |y: f64| (y - self.pp[1]) / self.focal_px;
        let (v0, v1) = (v_of(f64::from(row)), v_of(f64::from(row) + 1.0));
        // The u-extremes of (ellipse ∩ band) lie on the band's edges or at the ellipse's
        // leftmost/rightmost points when those fall inside the band.
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for (a, b) in [self.chord(v0), self.chord(v1)].into_iter().flatten() {
            lo = lo.min(a);
            hi = hi.max(b);
        }
        for (u, v) in [self.left, self.right] {
            if (v0..=v1).contains(&v) {
                lo = lo.min(u);
                hi = hi.max(u);
            }
        }
        if let Some(corners) = &self.corners {
            let (blo, bhi) = box_span(corners, v0, v1)?;
            lo = lo.max(blo);
            hi = hi.min(bhi);
        }
        self.to_columns(lo * self.focal_px + self.pp[0], hi * self.focal_px + self.pp[0], MARGIN_PX)
    }

    /// Pixel x-range → columns `[col0, col1)` with `margin` on each side.
    fn to_columns(&self, lo: f64, hi: f64, margin: f64) -> Option<(u32, u32)> {
        if lo > hi {
            return None;
        }
        let x0 = lo.floor() - margin;
        let x1 = hi.ceil() + margin;
        let w = f64::from(self.width);
        let (c0, c1) = (x0.clamp(0.0, w) as u32, x1.clamp(0.0, w) as u32);
        (c0 < c1).then_some((c0, c1))
    }
}

/// Abscissa range of the convex hull of `pts` within the band `v0 ≤ v ≤ v1`.
fn box_span(pts: &[(f64, f64); 8], v0: f64, v1: f64) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |u: f64| {
        lo = lo.min(u);
        hi = hi.max(u);
    };
    for (i, &(ua, va)) in pts.iter().enumerate() {
        if (v0..=v1).contains(&va) {
            take(ua);
        }
        for &(ub, vb) in &pts[i + 1..] {
            for v in [v0, v1] {
                if (va - v) * (vb - v) < 0.0 {
                    take(ua + (ub - ua) * (v - va) / (vb - va));
                }
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}
