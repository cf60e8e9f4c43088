//! The truth pass: one ray through each pixel centre that may see a triangle.
//!
//! Only pixels inside `View::pixel_rect` and marked by the BVH leaves' projected boxes
//! (`cull::coverage`, both conservative) get a ray; every other pixel is a miss without
//! one. Rows run in parallel, each writing its own slices of the channel planes; along a
//! row the covered pixels' rays go eight at a time through one walk of the 8-wide tree
//! ([`Accel::intersect_packet`]: each ray's `t` is the single-ray walk's bit for bit).
//! Every pixel is a pure function of (target, view), so any thread count gives the same
//! values.

use super::{TruthChannel, TruthChannels, TruthImage};
use crate::render::camera::{PixelRect, View};
use crate::render::cull::coverage::Coverage;
use crate::render::geometry::{Hit, Ray};
use crate::render::target::Target;
use glam::DVec3;
use rayon::prelude::*;

/// Rays walked together (the 8-wide tree's packet).
const PACKET: usize = 8;

/// One row's slices of the channel planes (None for a channel not asked for).
struct RowOut<'a> {
    row: u32,
    mask: &'a mut [u32],
    depth: Option<&'a mut [f32]>,
    normal: Option<[&'a mut [f32]; 3]>,
    body: Option<[&'a mut [f32]; 3]>,
}

/// The truth of `target` through `view` (its exposure-start instant): see the module
/// doc. Rayon over rows; the same values for any thread count.
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
    let (width, height) = view.size();
    let n = width as usize * height as usize;
    // The planes start as misses.
    let plane = |c, miss: f32| {
        if !channels.contains(c) {
            return Vec::new();
        }
        // Zeroed pages from the allocator, then filled by both threads.
        vec![miss; n]
    };
    let planes3 = |c| [plane(c, f32::NAN), plane(c, f32::NAN), plane(c, f32::NAN)];
    let mut out = TruthImage {
        width,
        height,
        channels,
        mask: vec![0; n],
        materials: Some(super::materials_table(&target.materials).into()),
        depth: plane(TruthChannel::Depth, f32::INFINITY),
        normal: planes3(TruthChannel::Normal),
        body_xyz: planes3(TruthChannel::BodyXyz),
    };
    let Some(rect) = (if target.accel.is_empty() { None } else { view.pixel_rect() }) else { return out };
    let mut own = Coverage::default();
    let coverage = coverage.or_else(|| own.from_leaf_boxes(target, view, rect).then_some(&own));
    rows(&mut out, rect).into_par_iter().for_each(|mut r| trace_row(target, view, rect, coverage, &mut r));
    out
}

/// The rows of `rect`, each with its slices of `out`'s planes.
fn rows(out: &mut TruthImage, rect: PixelRect) -> Vec<RowOut<'_>> {
    let w = out.width as usize;
    let (r0, r1) = (rect.row0 as usize, rect.row1 as usize);
    let [nx, ny, nz] = &mut out.normal;
    let [bx, by, bz] = &mut out.body_xyz;
    let mut depth = split(&mut out.depth, w, r0, r1);
    let mut n = [split(nx, w, r0, r1), split(ny, w, r0, r1), split(nz, w, r0, r1)];
    let mut b = [split(bx, w, r0, r1), split(by, w, r0, r1), split(bz, w, r0, r1)];
    let mut rows = Vec::with_capacity(r1 - r0);
    for (k, mask) in out.mask[r0 * w..r1 * w].chunks_mut(w).enumerate() {
        let (depth, normal, body) = (depth.next().flatten(), three(&mut n), three(&mut b));
        rows.push(RowOut { row: (r0 + k) as u32, mask, depth, normal, body });
    }
    rows
}

type Rows<'a> = std::vec::IntoIter<Option<&'a mut [f32]>>;

/// Rows `r0..r1` of a plane `w` wide, or None per row for a channel not asked for.
fn split(v: &mut [f32], w: usize, r0: usize, r1: usize) -> Rows<'_> {
    let rows: Vec<_> = if v.is_empty() {
        (r0..r1).map(|_| None).collect()
    } else {
        v[r0 * w..r1 * w].chunks_mut(w).map(Some).collect()
    };
    rows.into_iter()
}

/// The next row of three planes.
fn three<'a>(p: &mut [Rows<'a>; 3]) -> Option<[&'a mut [f32]; 3]> {
    let [x, y, z] = p.each_mut().map(|it| it.next().flatten());
    Some([x?, y?, z?])
}

/// The covered pixels of one row (all of `rect`'s without a coverage), in packets along it.
fn trace_row(target: &Target, view: &View, rect: PixelRect, coverage: Option<&Coverage>, r: &mut RowOut) {
    let y = f64::from(r.row) + 0.5;
    let mut cols = [0u32; PACKET];
    let mut dirs = [DVec3::ZERO; PACKET];
    let mut rays = [Ray { origin: glam::Vec3::ZERO, dir: glam::Vec3::Z, tmax: 0.0 }; PACKET];
    let mut k = 0;
    let mut visit = |col: u32, r: &mut RowOut| {
        // One lens inversion per pixel: the ray and the f64 line share the direction.
        let d = view.camera_dir(f64::from(col) + 0.5, y);
        let Some(ray) = view.ray_along(d) else { return };
        (cols[k], dirs[k], rays[k]) = (col, d, ray);
        k += 1;
        if k == PACKET {
            write_hits(target, view, &cols, &dirs, &rays, r);
            k = 0;
        }
    };
    match coverage {
        Some(c) => c.columns(r.row, rect.col0..rect.col1).for_each(|col| visit(col, r)),
        None => (rect.col0..rect.col1).for_each(|col| visit(col, r)),
    }
    write_hits(target, view, &cols[..k], &dirs[..k], &rays[..k], r);
}

/// Trace `rays` (pixel columns `cols`, camera directions `dirs`) and write their hits.
fn write_hits(target: &Target, view: &View, cols: &[u32], dirs: &[DVec3], rays: &[Ray], r: &mut RowOut) {
    if rays.is_empty() {
        return;
    }
    let mut hits = [None; PACKET];
    target.accel.intersect_packet(rays, &mut hits);
    for (i, hit) in hits[..rays.len()].iter().enumerate() {
        let Some(hit) = hit else { continue };
        let c = cols[i] as usize;
        let p = pixel(target, view, dirs[i], &rays[i], hit);
        r.mask[c] = p.mask;
        if let Some(d) = r.depth.as_deref_mut() {
            d[c] = p.depth;
        }
        for (plane, v) in [(&mut r.normal, p.normal), (&mut r.body, p.body)] {
            if let Some(pl) = plane {
                for a in 0..3 {
                    pl[a][c] = v[a];
                }
            }
        }
    }
}

/// What one pixel-centre ray hits.
struct TruthPixel {
    mask: u32,
    depth: f32,
    normal: [f32; 3],
    body: [f32; 3],
}

/// Truth of the pixel whose camera-frame direction is `d_cam` and whose f32 ray found
/// `hit`: the hit point recomputed in f64 on that triangle's plane.
fn pixel(target: &Target, view: &View, d_cam: DVec3, ray: &Ray, hit: &Hit) -> TruthPixel {
    // The line in f64: camera centre `o`, direction `d` (render frame).
    let d = view.cam_to_render * d_cam;
    let o = view.origin;
    let [a, _, _] = target.mesh.triangle(hit.tri as usize);
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
            let p = pixel(target, view, view.camera_dir(x, y), &ray, &hit);
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
