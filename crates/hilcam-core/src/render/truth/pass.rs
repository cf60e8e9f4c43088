//! The truth pass: one ray through each pixel centre that may see a triangle.
//!
//! Only pixels inside `View::pixel_rect` and marked by the BVH leaves' projected boxes
//! (`cull::coverage`, both conservative) get a ray; every other pixel is a miss without
//! one. Bands of two rows run in parallel, each writing its own slices of the channel
//! planes (`planes`); a band's covered pixels, their lens inverted four at a time, go in
//! blocks of 4 × 2 through one walk of the 8-wide tree ([`Accel::closest_prims`]: each
//! ray's `t` is the single-ray walk's bit for bit). Every pixel is a pure function of
//! (target, view), so any thread count gives the same values.
//!
//! [`Accel::closest_prims`]: crate::render::geometry::Accel::closest_prims

use super::planes::{self, Band, TruthPixel, TruthPlanes};
use super::{TruthChannels, TruthImage};
use crate::render::camera::{PixelRect, View};
use crate::render::cull::coverage::Coverage;
use crate::render::geometry::{Hit, Ray};
use crate::render::target::Target;
use glam::{DVec3, Vec3};

/// Rays walked together (the 8-wide tree's packet).
const PACKET: usize = 8;

/// Image rows a packet spans: 4 × 2 pixels walk the tree with fewer node visits than
/// 8 × 1 (`hilcam bench sensor`, docs/performance.md).
const PACKET_ROWS: u32 = 2;

/// The truth of `target` through `view` (its exposure-start instant): see the module
/// doc. Rayon over bands of rows; the same values for any thread count.
pub fn render_truth(target: &Target, view: &View, channels: TruthChannels) -> TruthImage {
    render_truth_with(target, view, channels, None)
}

/// [`render_truth`] with the pixels that may see a triangle given (`coverage`: the last
/// frame's, when it was rendered through this very view, `FrameBuffers::coverage_for`)
/// rather than marked anew. Either way the same values: a coverage only leaves out
/// pixels that cannot see the target.
pub fn render_truth_with(
    target: &Target,
    view: &View,
    channels: TruthChannels,
    coverage: Option<&Coverage>,
) -> TruthImage {
    let mut planes = TruthPlanes::default();
    render_truth_into(target, view, channels, coverage, &mut planes);
    planes.take().expect("the truth was just computed")
}

/// [`render_truth_with`] into `planes` kept from earlier truths (of any view, size or
/// channels): the same bytes as a new truth's, without allocating or filling the planes
/// again ([`TruthPlanes`]).
pub fn render_truth_into<'p>(
    target: &Target,
    view: &View,
    channels: TruthChannels,
    coverage: Option<&Coverage>,
    planes: &'p mut TruthPlanes,
) -> &'p TruthImage {
    let (width, height) = view.size();
    let rect = if target.accel.is_empty() { None } else { view.pixel_rect() };
    let mut own = Coverage::default();
    let coverage = match rect {
        Some(rect) => coverage.or_else(|| own.from_leaf_boxes(target, view, rect).then_some(&own)),
        None => None,
    };
    let out = planes::fill(planes, width, height, channels, PACKET_ROWS, |band| {
        if let Some(rect) = rect {
            trace_band(target, view, rect, coverage, band);
        }
    });
    out.materials = Some(super::materials_table(&target.materials).into());
    out
}

/// One covered pixel whose ray enters the target's bounds.
#[derive(Clone, Copy)]
struct Pending {
    row: u32,
    col: u32,
    /// Camera-frame direction of its centre.
    dir: DVec3,
    ray: Ray,
}

/// The covered pixels of `band`'s rows inside `rect` (all of `rect`'s without a
/// coverage), walked in packets of [`PACKET`]: blocks of `PACKET / rows` columns, the
/// band's rows in turn, so that a packet's pixels neighbour each other both ways.
fn trace_band(target: &Target, view: &View, rect: PixelRect, coverage: Option<&Coverage>, band: &mut Band) {
    let rows = band.row0.max(rect.row0)..(band.row0 + band.rows).min(rect.row1);
    if rows.is_empty() {
        return;
    }
    // Each row's covered columns and their directions.
    let lines: Vec<(u32, Vec<u32>, Vec<DVec3>)> = rows
        .map(|row| {
            let cols: Vec<u32> = match coverage {
                Some(c) => c.columns(row, rect.col0..rect.col1).collect(),
                None => (rect.col0..rect.col1).collect(),
            };
            let dirs = directions(view, row, &cols);
            (row, cols, dirs)
        })
        .collect();
    let block = (PACKET / lines.len()).max(1) as u32;
    let mut next = vec![0usize; lines.len()];
    let none = Ray { origin: glam::Vec3::ZERO, dir: glam::Vec3::Z, tmax: 0.0 };
    let mut packet = [Pending { row: 0, col: 0, dir: DVec3::ZERO, ray: none }; PACKET];
    let mut k = 0;
    // The leftmost block any row still has pixels in, each row's pixels there in turn.
    while let Some(b) = lines.iter().zip(&next).filter_map(|((_, cols, _), &i)| cols.get(i)).map(|c| c / block).min() {
        for ((row, cols, dirs), i) in lines.iter().zip(next.iter_mut()) {
            while let Some(&col) = cols.get(*i).filter(|&&c| c / block == b) {
                let dir = dirs[*i];
                *i += 1;
                let Some(ray) = view.ray_along(dir) else { continue };
                packet[k] = Pending { row: *row, col, dir, ray };
                k += 1;
                if k == PACKET {
                    write_hits(target, view, &packet, band);
                    k = 0;
                }
            }
        }
    }
    write_hits(target, view, &packet[..k], band);
}

/// [`View::camera_dir`] of the pixel centres `(col + 0.5, row + 0.5)` of `cols`, the lens
/// inverted four at a time.
fn directions(view: &View, row: u32, cols: &[u32]) -> Vec<DVec3> {
    let y = f64::from(row) + 0.5;
    let mut dirs = Vec::with_capacity(cols.len());
    for quad in cols.chunks(4) {
        // A short last chunk repeats its last column; the extra directions are dropped.
        let x = |i: usize| f64::from(quad[i.min(quad.len() - 1)]) + 0.5;
        let d = view.camera_dirs4([x(0), x(1), x(2), x(3)], y);
        dirs.extend_from_slice(&d[..quad.len()]);
    }
    dirs
}

/// Trace the packet's rays and record their hits.
fn write_hits(target: &Target, view: &View, packet: &[Pending], band: &mut Band) {
    let Some(first) = packet.first() else { return };
    let mut rays = [first.ray; PACKET];
    for (r, p) in rays.iter_mut().zip(packet) {
        *r = p.ray;
    }
    let mut prims = [None; PACKET];
    let accel = &target.accel;
    accel.closest_prims(&rays[..packet.len()], &mut prims);
    for (p, prim) in packet.iter().zip(prims) {
        if let Some((k, t)) = prim {
            band.put(
                p.row,
                p.col,
                &pixel(target, view, p.dir, &p.ray, accel.primitive_v0(k), &accel.primitive_hit(k, t)),
            );
        }
    }
}

/// Truth of the pixel whose camera-frame direction is `d_cam` and whose f32 ray found
/// `hit`: the hit point recomputed in f64 on that triangle's plane (through its first
/// vertex `a`).
fn pixel(target: &Target, view: &View, d_cam: DVec3, ray: &Ray, a: Vec3, hit: &Hit) -> TruthPixel {
    // The line in f64: camera centre `o`, direction `d` (render frame).
    let d = view.cam_to_render * d_cam;
    let o = view.origin;
    let n = hit.normal.as_dvec3();
    let denom = n.dot(d);
    let s = n.dot(a.as_dvec3() - o) / denom;
    // A line grazing the plane: keep the tracer's own f32 point.
    let p = if s.is_finite() && s > 0.0 { o + d * s } else { (ray.origin + ray.dir * hit.t).as_dvec3() };
    let depth = (p - o).length();
    let mut n_cam = view.cam_to_render.transpose() * n;
    if n_cam.dot(d_cam) > 0.0 {
        n_cam = -n_cam;
    }
    let body: DVec3 = p + target.frame_origin_body;
    TruthPixel {
        mask: hit.material + 1,
        depth: depth as f32,
        normal: n_cam.as_vec3().to_array(),
        body: body.as_vec3().to_array(),
    }
}

/// The truth pass as a plain loop: every pixel of the rect, one single-ray walk each,
/// the line's direction taken anew. Slow; the reference [`render_truth`]'s packets and
/// shared coverage are tested against, bit for bit (tests/render/truth.rs).
pub fn render_truth_reference(target: &Target, view: &View, channels: TruthChannels) -> TruthImage {
    let (w, h) = view.size();
    let n = (w * h) as usize;
    let nan = || vec![f32::NAN; n];
    let mut out = TruthImage {
        width: w,
        height: h,
        channels,
        mask: vec![0; n],
        materials: Some(crate::render::truth::materials_table(&target.materials).into()),
        depth: vec![f32::INFINITY; n],
        normal: [nan(), nan(), nan()],
        body_xyz: [nan(), nan(), nan()],
    };
    let Some(rect) = view.pixel_rect() else { return out };
    for row in rect.row0..rect.row1 {
        for col in rect.col0..rect.col1 {
            let (x, y) = (f64::from(col) + 0.5, f64::from(row) + 0.5);
            let Some(ray) = view.primary_ray(x, y) else { continue };
            let Some(hit) = target.accel.intersect(&ray) else { continue };
            let [a, _, _] = target.mesh.triangle(hit.tri as usize);
            let p = pixel(target, view, view.camera_dir(x, y), &ray, a, &hit);
            let i = (row * w + col) as usize;
            out.mask[i] = p.mask;
            out.depth[i] = p.depth;
            for a in 0..3 {
                out.normal[a][i] = p.normal[a];
                out.body_xyz[a][i] = p.body[a];
            }
        }
    }
    out
}
