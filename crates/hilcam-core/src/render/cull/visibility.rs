//! Primary visibility by rasterisation, exact for the sample positions used.
//!
//! Primary rays are more than half the rays of a frame and most of the pixels they start
//! in miss the target, yet each walks the BVH from its root. Here the triangles are
//! projected once per frame onto the ideal (undistorted) image plane, where a triangle in
//! front of the camera is a triangle, and each one tests only the camera samples whose
//! ideal image point lies in its (slightly enlarged) bounding box — with the very
//! triangle test the BVH runs ([`Accel::primitive_t`]) on the very f32 ray that would be
//! traced. The closest of those hits is the BVH's closest hit: the boxes only decide which
//! triangles are tried, and every triangle a ray can hit is tried. (Two triangles hit at
//! bit-identical distances — a sample exactly on a shared edge — may be resolved in a
//! different order than the traversal's; `tests/render/primary_raster.rs` measures that.)
//!
//! Through a distorting lens the samples' ideal image points are where the lens model
//! sends them, so the same binning holds; samples whose ideal point falls outside the
//! region binned at frame start are traced through the BVH instead.

use super::coverage::{Coverage, ray_margin, set_bits, triangle_row_cells};
use super::ideal_plane::{floor_i32, ideal_region};
use crate::render::camera::{PixelRect, View};
use crate::render::geometry::{Accel, Hit, Ray, TestRay};
use crate::render::target::Target;
use rayon::prelude::*;

/// Ideal-image rows per bucket of the per-frame triangle binning (the renderer's bands are
/// 8 rows, so a pinhole band reads one bucket).
const BUCKET_ROWS: i32 = 8;

/// One frame's triangles binned on the ideal image plane.
#[derive(Default)]
pub struct PrimaryRaster {
    /// Inclusive ideal-pixel cell range `[x0, x1, y0, y1]` of primitive `k` (BVH order),
    /// clipped to the binned region; `x0 > x1` when the triangle lies outside it.
    boxes: Vec<[i32; 4]>,
    /// The triangle's three edges on the ideal plane, pushed outward by the margin plus
    /// the f32 rounding of their evaluation (see [`Edges`]): a sample outside any of them
    /// cannot hit it, so its box's other samples skip the ray-triangle test.
    edges: Vec<Edges>,
    /// Bucket `b` covers rows `y_lo + b·BUCKET_ROWS ..`; its primitives are
    /// `bucket_tris[bucket_start[b]..bucket_start[b + 1]]`, in BVH order.
    bucket_start: Vec<u32>,
    bucket_tris: Vec<u32>,
    /// The binned region, ideal pixels (inclusive cells).
    x_lo: i32,
    x_hi: i32,
    y_lo: i32,
    y_hi: i32,
    /// The pixels a sample may hit a triangle from (for a pinhole the ideal cells whose
    /// square, grown by the margin, meets a triangle; through a lens the pixels the lens
    /// images such cells onto). A pixel outside it cannot see any triangle, so its samples
    /// are not even generated.
    pub(in crate::render) coverage: Coverage,
    /// Build-time buffers, kept so that a rebuild for the next frame allocates nothing:
    /// each vertex on the ideal plane (x, y, depth), and the bucket fill cursors.
    projected: Vec<(f64, f64, f64)>,
    fill: Vec<u32>,
}

/// Samples of one pass, binned into ideal-pixel cells (reused from band to band).
#[derive(Default)]
pub struct RasterScratch {
    cell_start: Vec<u32>,
    cell_samples: Vec<u32>,
    best_t: Vec<f32>,
    best_k: Vec<u32>,
    rays: Vec<TestRay>,
    coords: Vec<(i32, i32)>,
    /// Ideal image point of `cell_samples[j]`, relative to the binned region's corner.
    cell_xy: Vec<[f32; 2]>,
}

impl RasterScratch {
    /// Grow each buffer to at least the capacity of `other`'s (see
    /// `buffers::Workers::equalise`).
    pub(in crate::render) fn grow_like(&mut self, other: &Self) {
        use crate::heap::reserve_to;
        reserve_to(&mut self.cell_start, other.cell_start.capacity());
        reserve_to(&mut self.cell_samples, other.cell_samples.capacity());
        reserve_to(&mut self.best_t, other.best_t.capacity());
        reserve_to(&mut self.best_k, other.best_k.capacity());
        reserve_to(&mut self.rays, other.rays.capacity());
        reserve_to(&mut self.coords, other.coords.capacity());
        reserve_to(&mut self.cell_xy, other.cell_xy.capacity());
    }
}

/// Three half-planes `a·x + b·y + c ≥ 0` (ideal pixels relative to the binned region's
/// corner) whose intersection holds every point the f32 rays of the triangle's samples can
/// hit it from: its edges at unit normal scale, moved outward by the box margin and the
/// rounding of evaluating them in f32. A degenerate edge or triangle gets `a = b = 0`,
/// `c = +∞` (never rejects; the box alone decides).
#[derive(Clone, Copy, Default)]
struct Edges([[f32; 3]; 3]);

/// `√(x² + y²)` without `hypot`'s care for overflow, which costs ~20 ns a call in glibc
/// (it was called 6 times per triangle per frame: 2.5 % of a 1-spp goal frame). Image-plane coordinates
/// stay far from f64's overflow, and the edges only pre-filter (with a margin) what the
/// exact ray test decides.
#[inline]
fn length(x: f64, y: f64) -> f64 {
    (x * x + y * y).sqrt()
}

impl Edges {
    const PASS: [f32; 3] = [0.0, 0.0, f32::INFINITY];

    /// Edges of the triangle with ideal-plane vertices `p` (relative to the region's
    /// corner), pushed out by `tol` pixels.
    fn new(p: [[f64; 2]; 3], tol: f64) -> Edges {
        let cross =
            |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
        let area2 = cross(p[0], p[1], p[2]);
        // Each edge's vector and length, once.
        let d: [[f64; 2]; 3] = std::array::from_fn(|i| [p[(i + 1) % 3][0] - p[i][0], p[(i + 1) % 3][1] - p[i][1]]);
        let len = d.map(|[x, y]| length(x, y));
        let longest = len.into_iter().fold(0.0, f64::max);
        // Orientation is only trusted when the triangle is clearly wider than the f64
        // rounding of its vertices; a sliver seen edge-on keeps its box only.
        if area2.is_nan() || area2.abs() <= 1e-9 * longest * longest.max(1.0) {
            return Edges([Self::PASS; 3]);
        }
        let sign = area2.signum();
        Edges(std::array::from_fn(|i| {
            let (o, [dx, dy], len) = (p[i], d[i], len[i]);
            if len.is_nan() || len <= 0.0 {
                return Self::PASS;
            }
            // Signed distance from the edge line, positive toward the third vertex.
            let s = sign / len;
            let (a, b) = (-dy * s, dx * s);
            let c = -(a * o[0] + b * o[1]) + tol;
            [a as f32, b as f32, c as f32]
        }))
    }

    /// False when the point lies outside one of the (pushed-out) edges.
    #[inline(always)]
    fn may_contain(&self, [x, y]: [f32; 2]) -> bool {
        let e = &self.0;
        (e[0][0] * x + e[0][1] * y + e[0][2] >= 0.0)
            & (e[1][0] * x + e[1][1] * y + e[1][2] >= 0.0)
            & (e[2][0] * x + e[2][1] * y + e[2][2] >= 0.0)
    }
}

impl PrimaryRaster {
    /// Bin the scene's triangles for `view`, covering the ideal image points of pixels in
    /// `rect`. `None` when rasterising would not be exact or would not pay: a vertex at or
    /// behind the camera plane (camera among the triangles), or a lens whose ideal image
    /// of the rectangle is unbounded.
    pub fn new(scene: &Target, view: &View, rect: PixelRect) -> Option<PrimaryRaster> {
        let mut raster = PrimaryRaster::default();
        raster.rebuild(scene, view, rect).then_some(raster)
    }

    /// [`PrimaryRaster::new`] into this raster's buffers (no allocation once they have
    /// grown to the frame's size); false where `new` gives `None`, and the raster must then
    /// not be used.
    pub fn rebuild(&mut self, scene: &Target, view: &View, rect: PixelRect) -> bool {
        let mesh = &scene.mesh;
        let accel = &scene.accel;
        if accel.is_empty() {
            return false;
        }
        // Region of the ideal image plane the samples can fall in.
        let Some((x_lo, x_hi, y_lo, y_hi)) = ideal_region(view, rect) else { return false };
        let PrimaryRaster { boxes, edges, bucket_start, bucket_tris, coverage, projected, fill, .. } = self;
        // Each vertex on the ideal image plane; the nearest depth bounds the pixel size of
        // the f32 rays' own rounding (see `margin`).
        mesh.positions
            .par_iter()
            .map(|p| {
                let q = view.to_camera(p.as_dvec3());
                let [x, y] = view.ideal_px(q);
                (x, y, q.z)
            })
            .collect_into_vec(projected);
        let z_min = projected.par_iter().map(|v| v.2).reduce(|| f64::INFINITY, f64::min);
        if z_min.is_nan() || z_min <= 0.0 {
            return false; // a vertex at or behind the camera plane
        }
        // Every box grown by how far a traced ray can stray, seen from the nearest vertex.
        let margin = ray_margin(scene, view, z_min);
        if !margin.is_finite() || margin > 4.0 {
            return false; // camera almost touching the target: the boxes would be huge
        }
        // Evaluating an edge in f32 at coordinates up to the region's extent R rounds by a
        // few 1e-7·R (coefficients, sample point, four operations); 4e-6·R covers it.
        let extent = f64::from((x_hi - x_lo).max(y_hi - y_lo) + 1);
        let tol = margin + 1e-3 + 4e-6 * extent;
        (0..accel.len() as u32)
            .into_par_iter()
            .map(|k| {
                let [a, b, c] = accel.vertex_indices(k);
                let (pa, pb, pc) = (projected[a as usize], projected[b as usize], projected[c as usize]);
                let x0 = pa.0.min(pb.0).min(pc.0) - margin;
                let x1 = pa.0.max(pb.0).max(pc.0) + margin;
                let y0 = pa.1.min(pb.1).min(pc.1) - margin;
                let y1 = pa.1.max(pb.1).max(pc.1) + margin;
                let clip = |v: f64, lo: i32, hi: i32| floor_i32(v.clamp(f64::from(lo) - 1.0, f64::from(hi) + 1.0));
                let bx = [clip(x0, x_lo, x_hi), clip(x1, x_lo, x_hi), clip(y0, y_lo, y_hi), clip(y1, y_lo, y_hi)];
                let inside = bx[0] <= x_hi && bx[1] >= x_lo && bx[2] <= y_hi && bx[3] >= y_lo;
                if !inside {
                    return ([1, 0, 1, 0], Edges::default());
                }
                let rel = |p: (f64, f64, f64)| [p.0 - f64::from(x_lo), p.1 - f64::from(y_lo)];
                (
                    [bx[0].max(x_lo), bx[1].min(x_hi), bx[2].max(y_lo), bx[3].min(y_hi)],
                    Edges::new([rel(pa), rel(pb), rel(pc)], tol),
                )
            })
            .unzip_into_vecs(boxes, edges);
        // Bucket the boxes by rows (counting sort, BVH order within a bucket).
        let buckets = ((y_hi - y_lo) / BUCKET_ROWS + 1) as usize;
        bucket_start.clear();
        bucket_start.resize(buckets + 1, 0);
        let bucket_range =
            |b: &[i32; 4]| ((b[2] - y_lo) / BUCKET_ROWS) as usize..=((b[3] - y_lo) / BUCKET_ROWS) as usize;
        for b in boxes.iter().filter(|b| b[0] <= b[1]) {
            for i in bucket_range(b) {
                bucket_start[i + 1] += 1;
            }
        }
        for i in 0..buckets {
            bucket_start[i + 1] += bucket_start[i];
        }
        fill.clear();
        fill.extend_from_slice(bucket_start);
        bucket_tris.clear();
        bucket_tris.resize(bucket_start[buckets] as usize, 0);
        for (k, b) in boxes.iter().enumerate().filter(|(_, b)| b[0] <= b[1]) {
            for i in bucket_range(b) {
                bucket_tris[fill[i] as usize] = k as u32;
                fill[i] += 1;
            }
        }
        // Coverage bits, a row of `stride` words per ideal row; buckets own disjoint rows,
        // so they are filled in parallel.
        let stride = ((x_hi - x_lo + 1) as usize).div_ceil(64);
        let (bucket_start, bucket_tris, boxes, projected) = (&*bucket_start, &*bucket_tris, &*boxes, &*projected);
        let bits = coverage.cells(view, stride * (y_hi - y_lo + 1) as usize);
        // The box margin, plus the f64 rounding of the clipping below.
        let m = margin + 1e-6;
        bits.par_chunks_mut(stride * BUCKET_ROWS as usize).enumerate().for_each(|(bucket, rows)| {
            let first_row = y_lo + bucket as i32 * BUCKET_ROWS;
            let tris = &bucket_tris[bucket_start[bucket] as usize..bucket_start[bucket + 1] as usize];
            for &k in tris {
                let b = boxes[k as usize];
                let [ia, ib, ic] = accel.vertex_indices(k);
                let tri = [ia, ib, ic].map(|i| (projected[i as usize].0, projected[i as usize].1));
                let (y0, y1) = (b[2].max(first_row), b[3].min(first_row + BUCKET_ROWS - 1));
                triangle_row_cells(tri, (y0, y1), (b[0], b[1]), m, |y, c0, c1| {
                    let row = &mut rows[(y - first_row) as usize * stride..][..stride];
                    set_bits(row, (c0 - x_lo) as usize, (c1 - x_lo) as usize);
                });
            }
        });
        coverage.finish(view, rect, [x_lo, x_hi, y_lo, y_hi], stride);
        (self.x_lo, self.x_hi, self.y_lo, self.y_hi) = (x_lo, x_hi, y_lo, y_hi);
        true
    }

    /// False when no sample of pixel `(row, col)` can hit a triangle (it sees the
    /// background); true when it may.
    #[inline]
    pub fn may_hit(&self, row: u32, col: u32) -> bool {
        self.coverage.may_hit(row, col)
    }

    /// Closest hit of each ray `rays[i]`, whose sample lies at ideal pixel `ideal[i]`,
    /// written to `hits[i]`: the same as `accel.intersect(&rays[i])`.
    pub fn closest_hits(
        &self,
        accel: &Accel,
        rays: &[Ray],
        ideal: &[[f64; 2]],
        scratch: &mut RasterScratch,
        hits: &mut Vec<Option<Hit>>,
    ) {
        let n = rays.len();
        let RasterScratch { cell_start, cell_samples, best_t, best_k, rays: test_rays, coords, cell_xy } = scratch;
        hits.clear();
        hits.resize(n, None);
        test_rays.clear();
        test_rays.extend(rays.iter().map(TestRay::new));
        best_t.clear();
        best_t.resize(n, f32::INFINITY);
        best_k.clear();
        best_k.resize(n, 0);
        // The cell of each sample (`OUTSIDE` beyond the binned region), and their box.
        coords.clear();
        let (mut cx0, mut cx1, mut cy0, mut cy1) = (i32::MAX, i32::MIN, i32::MAX, i32::MIN);
        for (i, &[x, y]) in ideal.iter().enumerate() {
            let inside = x >= f64::from(self.x_lo)
                && x < f64::from(self.x_hi) + 1.0
                && y >= f64::from(self.y_lo)
                && y < f64::from(self.y_hi) + 1.0;
            if inside {
                let (cx, cy) = (floor_i32(x), floor_i32(y));
                (cx0, cx1, cy0, cy1) = (cx0.min(cx), cx1.max(cx), cy0.min(cy), cy1.max(cy));
                coords.push((cx, cy));
            } else {
                coords.push(OUTSIDE);
                hits[i] = accel.intersect(&rays[i]);
            }
        }
        if cx0 > cx1 {
            return;
        }
        // Counting sort of the samples into cells.
        let w = (cx1 - cx0 + 1) as usize;
        let h = (cy1 - cy0 + 1) as usize;
        let cell = |(cx, cy): (i32, i32)| (cy - cy0) as usize * w + (cx - cx0) as usize;
        cell_start.clear();
        cell_start.resize(w * h + 1, 0);
        for &c in coords.iter().filter(|&&c| c != OUTSIDE) {
            cell_start[cell(c) + 1] += 1;
        }
        for i in 0..w * h {
            cell_start[i + 1] += cell_start[i];
        }
        cell_samples.clear();
        cell_samples.resize(cell_start[w * h] as usize, 0);
        for (i, &c) in coords.iter().enumerate().filter(|&(_, &c)| c != OUTSIDE) {
            // `cell_start[c]` is used as the fill cursor, then restored below.
            let c = cell(c);
            cell_samples[cell_start[c] as usize] = i as u32;
            cell_start[c] += 1;
        }
        for c in (1..=w * h).rev() {
            cell_start[c] = cell_start[c - 1];
        }
        cell_start[0] = 0;
        let (x_lo, y_lo) = (f64::from(self.x_lo), f64::from(self.y_lo));
        cell_xy.clear();
        cell_xy.extend(cell_samples.iter().map(|&i| {
            let [x, y] = ideal[i as usize];
            [(x - x_lo) as f32, (y - y_lo) as f32]
        }));
        // Every triangle whose box meets the cells, once: in the first bucket of the cells'
        // rows that it overlaps.
        let b0 = ((cy0 - self.y_lo) / BUCKET_ROWS) as usize;
        let b1 = ((cy1 - self.y_lo) / BUCKET_ROWS) as usize;
        for b in b0..=b1 {
            let tris = &self.bucket_tris[self.bucket_start[b] as usize..self.bucket_start[b + 1] as usize];
            for &k in tris {
                let bx = self.boxes[k as usize];
                if ((bx[2].max(cy0) - self.y_lo) / BUCKET_ROWS) as usize != b {
                    continue;
                }
                let (x0, x1) = (bx[0].max(cx0), bx[1].min(cx1));
                let (y0, y1) = (bx[2].max(cy0), bx[3].min(cy1));
                if x0 > x1 || y0 > y1 {
                    continue;
                }
                let edges = &self.edges[k as usize];
                for cy in y0..=y1 {
                    let s0 = cell_start[cell((x0, cy))] as usize;
                    let s1 = cell_start[cell((x1, cy)) + 1] as usize;
                    for (&i, &xy) in cell_samples[s0..s1].iter().zip(&cell_xy[s0..s1]) {
                        if !edges.may_contain(xy) {
                            continue;
                        }
                        let i = i as usize;
                        let t = accel.primitive_t(k, &test_rays[i]);
                        // Exact ties (coplanar overlapping triangles) go to the lowest
                        // primitive, whatever order the buckets visit them in.
                        if t < best_t[i] || (t == best_t[i] && t < f32::INFINITY && k < best_k[i]) {
                            best_t[i] = t;
                            best_k[i] = k;
                        }
                    }
                }
            }
        }
        for (i, hit) in hits.iter_mut().enumerate() {
            if best_t[i] < f32::INFINITY {
                *hit = Some(accel.primitive_hit(best_k[i], best_t[i]));
            }
        }
    }
}

/// Cell of a sample outside the binned region.
const OUTSIDE: (i32, i32) = (i32::MIN, i32::MIN);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_bits_sets_exactly_the_range() {
        for (a, b) in [(0, 0), (3, 9), (0, 63), (63, 64), (5, 130), (64, 127), (70, 191)] {
            let mut row = [0u64; 3];
            set_bits(&mut row, a, b);
            for i in 0..192 {
                assert_eq!(row[i / 64] >> (i % 64) & 1 == 1, (a..=b).contains(&i), "bit {i} of {a}..={b}");
            }
        }
    }
}
