//! Which pixels can see a triangle at all: the others keep the background without a
//! camera sample being generated.
//!
//! The marks are made on the *ideal* (undistorted) image plane, where a pinhole's cells
//! are its pixels; through a lens each marked cell is carried to the pixels the lens
//! images it onto (`lens_coverage`). Two sources mark cells, both conservatively:
//! - the rasteriser (`visibility`), triangle by triangle, clipped to each row (exact up to
//!   a margin);
//! - [`Coverage::from_leaf_boxes`] when primary rays are traced: the projected bounding
//!   box of each BVH leaf. Looser (a leaf's box is larger than its triangles' outline),
//!   but ~40 k boxes instead of ~150 k triangles and no bucketing, so it is cheap enough
//!   for frames whose hits come from the tree.

use super::ideal_plane::{floor_i32, ideal_region, slab_x_extent};
use super::lens_coverage::{self, IdealCells};
use crate::render::camera::{PixelRect, View};
use crate::render::target::Target;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// A bit per pixel, set where a sample may hit a triangle.
#[derive(Default)]
pub struct Coverage {
    /// Bit per pixel of `cover` (`stride` words per row).
    covered: Vec<u64>,
    /// Inclusive pixel range `[x0, x1, y0, y1]` of `covered`.
    cover: [i32; 4],
    /// Words per row of `covered`.
    stride: usize,
    /// Through a lens: the ideal cells' bits (else the cells are marked in `covered`).
    ideal_bits: Vec<u64>,
    /// Atomic words marks are set in from several threads.
    marks: Vec<AtomicU64>,
}

/// How far (ideal pixels) a traced f32 ray can stray from the exact line through its
/// sample, for a triangle no nearer than `z_min` (camera frame): the f32 rounding of its
/// origin and direction is a few 1e-7 of the target's size at most; 40× that, seen from
/// `z_min`, plus 1e-3 px.
pub(super) fn ray_margin(scene: &Target, view: &View, z_min: f64) -> f64 {
    4e-6 * scene.bounds.radius * view.focal_px() / z_min + 1e-3
}

impl Coverage {
    /// The cleared cell bits to mark, `words` long (`stride` words per ideal row): the
    /// pixels themselves for a pinhole. [`Coverage::finish`] then makes them pixel marks.
    pub(super) fn cells(&mut self, view: &View, words: usize) -> &mut Vec<u64> {
        let bits = if view.has_distortion() { &mut self.ideal_bits } else { &mut self.covered };
        bits.clear();
        bits.resize(words, 0);
        bits
    }

    /// The cells of `region` (`[x_lo, x_hi, y_lo, y_hi]`, `stride` words per row) have been
    /// marked in [`Coverage::cells`]: through a lens, mark the pixels of `rect` they are
    /// imaged onto.
    pub(super) fn finish(&mut self, view: &View, rect: PixelRect, region: [i32; 4], stride: usize) {
        let [x_lo, x_hi, y_lo, y_hi] = region;
        (self.cover, self.stride) = if view.has_distortion() {
            let cells = IdealCells { bits: &self.ideal_bits, stride, x_lo, y_lo, x_hi, y_hi };
            let s = lens_coverage::mark_pixels(view, &cells, rect, &mut self.marks, &mut self.covered);
            ([rect.col0 as i32, rect.col1 as i32 - 1, rect.row0 as i32, rect.row1 as i32 - 1], s)
        } else {
            (region, stride)
        };
    }

    /// False when no sample of pixel `(row, col)` can hit a triangle.
    #[inline]
    pub fn may_hit(&self, row: u32, col: u32) -> bool {
        let (x, y) = (col as i32, row as i32);
        let [x0, x1, y0, y1] = self.cover;
        if x < x0 || x > x1 || y < y0 || y > y1 {
            return false;
        }
        let x = (x - x0) as usize;
        self.covered[(y - y0) as usize * self.stride + x / 64] & (1 << (x % 64)) != 0
    }

    /// The columns of `cols` in `row` that [`Coverage::may_hit`] accepts, in order (read
    /// from the bit words: a row's uncovered stretches cost a word per 64 pixels).
    pub fn columns(&self, row: u32, cols: std::ops::Range<u32>) -> impl Iterator<Item = u32> + '_ {
        let [x0, x1, y0, y1] = self.cover;
        let (y, a, b) =
            (row as i64, i64::from(cols.start).max(i64::from(x0)), i64::from(cols.end).min(i64::from(x1) + 1));
        let words = if y < i64::from(y0) || y > i64::from(y1) || a >= b {
            &[][..]
        } else {
            &self.covered[(y - i64::from(y0)) as usize * self.stride..][..self.stride]
        };
        let (a, b) = ((a - i64::from(x0)).max(0) as usize, (b - i64::from(x0)).max(0) as usize);
        words.iter().enumerate().flat_map(move |(w, &word)| {
            // This word's bits within [a, b).
            let lo = (w * 64).max(a);
            let hi = (w * 64 + 64).min(b);
            let word = if lo >= hi { 0 } else { word & (!0u64 >> (64 - (hi - lo))) << (lo - w * 64) };
            BitIter(word).map(move |bit| (x0 as usize + w * 64 + bit) as u32)
        })
    }

    /// Mark the cells each BVH leaf can be hit from: those its box projects onto (grown by
    /// [`ray_margin`] from its nearest corner), and for a leaf whose box spans more than
    /// [`BOX_CELLS`] cells, only those its triangles' outlines meet, row by row (as the
    /// rasteriser marks them). A ray that hits a triangle passes through its leaf's box, and
    /// a box in front of the camera projects inside the rectangle of its corners' images.
    /// False (and the coverage must not be used) when a box reaches the camera plane or
    /// the lens's ideal region is unbounded.
    pub fn from_leaf_boxes(&mut self, scene: &Target, view: &View, rect: PixelRect) -> bool {
        let accel = &scene.accel;
        let leaves = accel.leaves();
        let Some((x_lo, x_hi, y_lo, y_hi)) = ideal_region(view, rect) else { return false };
        if leaves.is_empty() {
            return false;
        }
        let stride = ((x_hi - x_lo + 1) as usize).div_ceil(64);
        let rows = (y_hi - y_lo + 1) as usize;
        self.marks.clear();
        self.marks.resize_with(stride * rows, || AtomicU64::new(0));
        let marks = &self.marks;
        // Cells `c0..=c1` of row `y` (clipped to the region).
        let mark = |y: i32, c0: i32, c1: i32| {
            let (c0, c1) = (c0.max(x_lo), c1.min(x_hi));
            if y >= y_lo && y <= y_hi && c0 <= c1 {
                let row = &marks[(y - y_lo) as usize * stride..][..stride];
                lens_coverage::set_bits_atomic(row, (c0 - x_lo) as usize, (c1 - x_lo) as usize);
            }
        };
        let clip = |v: f64, lo: i32, hi: i32| floor_i32(v.clamp(f64::from(lo) - 1.0, f64::from(hi) + 1.0));
        // A moving view marks what the target covers at any instant of its exposure: the
        // union over the instants, each grown by the most a point moved between two.
        let instants = view.exposure_instants();
        let instants = instants.as_slice();
        let project = |(origin, render_to_cam): &(DVec3, DMat3), p: DVec3| {
            let q = *render_to_cam * (p - *origin);
            let [x, y] = view.ideal_px(q);
            (x, y, q.z)
        };
        let in_front = leaves.par_iter().all(|leaf| {
            let (lo, hi) = (leaf.min.as_dvec3(), leaf.max.as_dvec3());
            let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
            let mut z_min = f64::INFINITY;
            let mut step = 0.0f64;
            for c in 0..8 {
                let corner = |bit: usize, a: f64, b: f64| if c & bit == 0 { a } else { b };
                let p = DVec3::new(corner(1, lo.x, hi.x), corner(2, lo.y, hi.y), corner(4, lo.z, hi.z));
                let mut prev: Option<(f64, f64)> = None;
                for at in instants {
                    let (x, y, z) = project(at, p);
                    z_min = z_min.min(z);
                    (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
                    if let Some((px, py)) = prev {
                        step = step.max((x - px).abs()).max((y - py).abs());
                    }
                    prev = Some((x, y));
                }
            }
            if z_min.is_nan() || z_min <= 0.0 {
                return false; // at or behind the camera plane
            }
            // The margin, plus the f64 rounding of these sums.
            let m = ray_margin(scene, view, z_min) + 1e-6;
            if !m.is_finite() || m > 4.0 {
                return false; // camera almost touching the target
            }
            if !step.is_finite() {
                return false;
            }
            let m = m + step;
            let b = [
                clip(x0 - m, x_lo, x_hi),
                clip(x1 + m, x_lo, x_hi),
                clip(y0 - m, y_lo, y_hi),
                clip(y1 + m, y_lo, y_hi),
            ];
            if b[0] > x_hi || b[1] < x_lo || b[2] > y_hi || b[3] < y_lo {
                return true; // outside the region
            }
            if i64::from(b[1] - b[0] + 1) * i64::from(b[3] - b[2] + 1) <= BOX_CELLS {
                for y in b[2]..=b[3] {
                    mark(y, b[0], b[1]);
                }
                return true;
            }
            for k in leaf.first..leaf.first + leaf.count {
                for at in instants {
                    let tri = accel.vertex_indices(k).map(|i| {
                        let (x, y, _) = project(at, scene.mesh.positions[i as usize].as_dvec3());
                        (x, y)
                    });
                    let ty0 = clip(tri.iter().map(|v| v.1).fold(f64::INFINITY, f64::min) - m, y_lo, y_hi).max(b[2]);
                    let ty1 = clip(tri.iter().map(|v| v.1).fold(f64::NEG_INFINITY, f64::max) + m, y_lo, y_hi).min(b[3]);
                    triangle_row_cells(tri, (ty0, ty1), (b[0], b[1]), m, &mark);
                }
            }
            true
        });
        if !in_front {
            return false;
        }
        let marks = std::mem::take(&mut self.marks);
        self.cells(view, 0).extend(marks.iter().map(|w| w.load(Relaxed)));
        self.marks = marks;
        self.finish(view, rect, [x_lo, x_hi, y_lo, y_hi], stride);
        true
    }
}

/// The set bits of a word, lowest first.
struct BitIter(u64);

impl Iterator for BitIter {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        (self.0 != 0).then(|| {
            let bit = self.0.trailing_zeros() as usize;
            self.0 &= self.0 - 1;
            bit
        })
    }
}

/// For each row `y` of `rows` (inclusive), the cells (inclusive, within `cols`) whose
/// square grown by `m` meets triangle `tri` (ideal-plane vertices): its x-extent within
/// the row's grown slab. `mark(y, c0, c1)` is called for each row that has any. The
/// rasteriser's rule and the leaf boxes' for large leaves.
pub(super) fn triangle_row_cells(
    tri: [(f64, f64); 3],
    rows: (i32, i32),
    cols: (i32, i32),
    m: f64,
    mut mark: impl FnMut(i32, i32, i32),
) {
    for y in rows.0..=rows.1 {
        let slab = (f64::from(y) - m, f64::from(y) + 1.0 + m);
        let Some((xa, xb)) = slab_x_extent(tri, slab) else { continue };
        let (c0, c1) = (floor_i32((xa - 1.0 - m).max(-1e9)).max(cols.0), floor_i32((xb + m).min(1e9)).min(cols.1));
        if c0 <= c1 {
            mark(y, c0, c1);
        }
    }
}

/// Leaves whose grown box spans at most this many cells are marked as their box; larger
/// ones (the panels' long triangles) triangle by triangle.
const BOX_CELLS: i64 = 64;

/// Set bits `a..=b` of a bit row.
pub(super) fn set_bits(row: &mut [u64], a: usize, b: usize) {
    let (wa, wb) = (a / 64, b / 64);
    let lo = !0u64 << (a % 64);
    let hi = !0u64 >> (63 - b % 64);
    if wa == wb {
        row[wa] |= lo & hi;
    } else {
        row[wa] |= lo;
        row[wa + 1..wb].fill(!0);
        row[wb] |= hi;
    }
}
