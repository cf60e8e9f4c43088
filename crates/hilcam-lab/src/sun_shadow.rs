//! Occlusion of rays that all travel along one direction `s` (the parallel sun): every
//! triangle is projected orthographically onto the plane ⊥ `s` and binned into a 2D grid;
//! a shadow ray only tests the triangles of the cell its origin projects into, and in
//! that cell only those that can lie ahead of the origin along `s` (entries sorted by the
//! largest origin depth at which they can be hit, so the scan stops early). Each entry also
//! carries its region's box and the triangle's plane (an origin in front of it gives
//! `t < 0`), so most candidates are rejected without reading the triangle.
//! A lab structure: measured against the 8-wide BVH, which now answers shadow rays faster
//! (docs/performance.md), it is not part of the renderer; `hilcam bench render` keeps
//! comparing the two on a frame's recorded shadow rays.
//!
//! Exactness. A query runs obvhs's own triangle test (`RtTriangle::intersect`, the same
//! stored triangles and the same `Ray` the BVH passes it) on its candidates, and any-hit
//! does not depend on order, so the answer equals testing every triangle — provided no
//! triangle the f32 test would report is left out. The binning therefore covers, per
//! triangle, every origin for which the *rounded* test can pass, not just the exact
//! projected triangle. With `c = v0 − o`, `U = (s × c)·e2`, `V = (s × c)·e1`, `D = ng·s`,
//! the test passes only if `u = U/D`, `v = V/D` and `1 − u − v` are ≥ 0 and `t = (ng·c)/D`
//! is ≥ 0 and finite. `D` does not depend on the origin, so it is computed exactly as
//! obvhs does at build: triangles with `1/D` not finite can never give a finite `t` and
//! are dropped. For the rest, forward error bounds of the f32 arithmetic (a safety
//! factor 4 above the bounds derived for `c`, the cross and the dot products, relative to
//! |c| ≤ |v0| + the largest allowed origin radius) turn the three sign conditions into
//! three half-planes in the projection plane and the sign of `t` into a largest origin
//! depth. Triangles nearly edge-on to `s`, whose widened region is long and thin, are
//! binned row by row along a strip that contains it and are never cut by depth. Origins
//! outside the gridded region, and rays whose direction is not bit-identical to `s`,
//! return `None` so the caller uses the BVH.

use glam::{DVec2, DVec3, Vec3, Vec3A};
use hilcam_core::render::geometry::{Ray, TriMesh};
use obvhs::{ray::Ray as ObRay, rt_triangle::RtTriangle};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

use std::time::{Duration, Instant};

/// f32 unit roundoff, 2⁻²⁴.
const UNIT: f64 = f32::EPSILON as f64 * 0.5;
/// Rounding-error factor: ~8 from the analysis of `c`, `s × c` and the dot product,
/// times a safety factor of 4.
const K_ERR: f64 = 32.0 * UNIT;
/// Grid cells per binned triangle (measured on the satellite; see docs/performance.md).
const CELLS_PER_TRIANGLE: f64 = 0.5;
/// Largest grid side, cells.
const MAX_SIDE: usize = 4096;
/// Origins farther than this × the farthest vertex from the render-frame origin fall
/// back to the BVH (shadow-ray origins sit a hair off the surface).
const ORIGIN_RADIUS: f64 = 1.25;

/// What one build produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SunShadowStats {
    pub triangles: usize,
    /// Triangles for which the f32 test can never report a hit along `s` (`1/(ng·s)` not
    /// finite: edge-on exactly), left out.
    pub dropped: usize,
    /// Triangles nearly edge-on to `s`, binned along a strip and never cut by depth.
    pub strips: usize,
    pub cells: usize,
    /// Triangle references over all cells.
    pub entries: usize,
    pub build_time: Duration,
}

/// A cell entry: the largest origin depth along `s` at which the triangle can still be
/// hit (rounded up), the triangle, the bounding box of its region in the projection
/// plane (rounded outward), and the half-space of origins behind its plane (`n·o ≤ d`,
/// `t ≥ 0` possible), so most candidates are rejected without touching the triangle.
#[derive(Clone, Copy, Debug)]
struct Entry {
    key: f32,
    tri: u32,
    lo: [f32; 2],
    hi: [f32; 2],
    n: [f32; 3],
    d: f32,
}

impl Entry {
    /// False when the triangle cannot be hit from an origin at `o` (projected `x`, `y`).
    #[inline(always)]
    fn may_hit(&self, o: DVec3, x: f64, y: f64) -> bool {
        let n = DVec3::new(self.n[0].into(), self.n[1].into(), self.n[2].into());
        x >= f64::from(self.lo[0])
            && x <= f64::from(self.hi[0])
            && y >= f64::from(self.lo[1])
            && y <= f64::from(self.hi[1])
            && n.dot(o) <= f64::from(self.d)
    }
}

/// How one triangle is binned (absolute projection coordinates, already widened).
#[derive(Clone, Copy, Debug)]
enum Bin {
    Skip,
    /// The region's bounding box.
    Rect {
        lo: DVec2,
        hi: DVec2,
    },
    /// The region lies in the strip `lo ≤ a·X ≤ hi`; `vlo`, `vhi` bound the projected
    /// triangle itself (for the grid's extent).
    Strip {
        a: DVec2,
        lo: f64,
        hi: f64,
        vlo: DVec2,
        vhi: DVec2,
    },
}

/// The grid's placement in the projection plane.
#[derive(Clone, Copy, Debug, Default)]
struct Grid {
    x0: f64,
    y0: f64,
    h: f64,
    inv_h: f64,
    nx: usize,
    ny: usize,
    /// Absolute widening of every binned region against f64 rounding.
    pad: f64,
}

impl Grid {
    fn cell_x(&self, x: f64) -> isize {
        ((x - self.x0) * self.inv_h).floor() as isize
    }
    fn cell_y(&self, y: f64) -> isize {
        ((y - self.y0) * self.inv_h).floor() as isize
    }
    /// Clamped inclusive cell range of `[lo, hi]` along one axis, `None` if outside.
    fn range(&self, lo: isize, hi: isize, n: usize) -> Option<[u32; 2]> {
        let (lo, hi) = (lo.max(0), hi.min(n as isize - 1));
        (lo <= hi).then_some([lo as u32, hi as u32])
    }

    /// Calls `f` with every cell index the bin covers.
    #[inline]
    fn for_each_cell(&self, bin: &Bin, mut f: impl FnMut(usize)) {
        match *bin {
            Bin::Skip => {}
            Bin::Rect { lo, hi } => {
                let (Some(cx), Some(cy)) = (
                    self.range(self.cell_x(lo.x), self.cell_x(hi.x), self.nx),
                    self.range(self.cell_y(lo.y), self.cell_y(hi.y), self.ny),
                ) else {
                    return;
                };
                for y in cy[0]..=cy[1] {
                    let row = y as usize * self.nx;
                    for x in cx[0]..=cx[1] {
                        f(row + x as usize);
                    }
                }
            }
            Bin::Strip { a, lo, hi, .. } => {
                for y in 0..self.ny {
                    // The row's slab, widened, and the strip's x extent over it.
                    let ylo = self.y0 + y as f64 * self.h - self.pad;
                    let yhi = ylo + self.h + 2.0 * self.pad;
                    let (xlo, xhi) = if a.x == 0.0 {
                        let (l, u) = (a.y * ylo, a.y * yhi);
                        if l.max(u) < lo || l.min(u) > hi {
                            continue;
                        }
                        (f64::NEG_INFINITY, f64::INFINITY)
                    } else {
                        let xs = [
                            (lo - a.y * ylo) / a.x,
                            (lo - a.y * yhi) / a.x,
                            (hi - a.y * ylo) / a.x,
                            (hi - a.y * yhi) / a.x,
                        ];
                        let (l, u) =
                            xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, u), &x| (l.min(x), u.max(x)));
                        let slack = self.pad + (u - l) * 1e-9;
                        (l - slack, u + slack)
                    };
                    let xlo = if xlo.is_finite() { self.cell_x(xlo.max(self.x0 - self.h)) } else { 0 };
                    let xhi = if xhi.is_finite() {
                        self.cell_x(xhi.min(self.x0 + self.h * (self.nx + 1) as f64))
                    } else {
                        self.nx as isize
                    };
                    if let Some([x0, x1]) = self.range(xlo, xhi, self.nx) {
                        for x in x0..=x1 {
                            f(y * self.nx + x as usize);
                        }
                    }
                }
            }
        }
    }
}

/// The occlusion structure for rays along one direction.
pub struct SunShadow {
    /// The direction, exactly as the rays carry it.
    dir: Vec3,
    /// Orthonormal basis: `u`, `v` span the projection plane, `w` = normalised `dir`.
    u: DVec3,
    v: DVec3,
    w: DVec3,
    /// Squared radius beyond which origins fall back to the BVH.
    origin_r2: f64,
    grid: Grid,
    /// `cell_start[c]..cell_start[c + 1]` are cell `c`'s entries, largest key first.
    cell_start: Vec<u32>,
    entries: Vec<Entry>,
    /// The mesh's triangles in obvhs's layout, original order.
    tris: Vec<RtTriangle>,
    /// Farthest vertex from the render-frame origin.
    r_max: f64,
    /// Build scratch kept for reuse: per-triangle binning, per-cell counters, ids.
    bins: Vec<(Bin, Entry)>,
    counts: Vec<AtomicU32>,
    ids: Vec<AtomicU32>,
    pub stats: SunShadowStats,
}

impl SunShadow {
    /// Build for rays along `dir` (need not be unit length; must be finite and non-zero).
    pub fn build(mesh: &TriMesh, dir: Vec3) -> Self {
        let mut s = SunShadow {
            dir,
            u: DVec3::ZERO,
            v: DVec3::ZERO,
            w: DVec3::ZERO,
            origin_r2: 0.0,
            grid: Grid::default(),
            cell_start: Vec::new(),
            entries: Vec::new(),
            tris: Vec::new(),
            r_max: 0.0,
            bins: Vec::new(),
            counts: Vec::new(),
            ids: Vec::new(),
            stats: SunShadowStats::default(),
        };
        s.tris = (0..mesh.indices.len())
            .into_par_iter()
            .map(|i| {
                let [a, b, c] = mesh.triangle(i);
                RtTriangle::new(a.into(), b.into(), c.into())
            })
            .collect();
        s.r_max = s
            .tris
            .par_iter()
            .map(|t| {
                let v0 = DVec3::from(Vec3::from(t.v0));
                let (v1, v2) = (v0 - DVec3::from(Vec3::from(t.e1)), v0 + DVec3::from(Vec3::from(t.e2)));
                v0.length().max(v1.length()).max(v2.length())
            })
            .reduce(|| 0.0, f64::max);
        s.rebuild(dir);
        s
    }

    /// The direction this structure answers for.
    pub fn dir(&self) -> Vec3 {
        self.dir
    }

    /// Rebuild for another direction over the same triangles, reusing the buffers.
    pub fn rebuild(&mut self, dir: Vec3) {
        let t0 = Instant::now();
        self.dir = dir;
        let w = dir.as_dvec3().normalize_or_zero();
        let (u, v) =
            if w == DVec3::ZERO || !w.is_finite() { (DVec3::ZERO, DVec3::ZERO) } else { w.any_orthonormal_pair() };
        (self.u, self.v, self.w) = (u, v, w);
        let tris = &self.tris;
        let r_origin = self.r_max * ORIGIN_RADIUS;
        self.origin_r2 = r_origin * r_origin;
        let usable = w != DVec3::ZERO && w.is_finite();

        // Each triangle's region (parallel); the grid covers them plus a margin for
        // origin offsets.
        let pad = 1e-9 * r_origin;
        let basis = Basis { dir, u, v, w, r_origin, pad };
        self.bins.clear();
        if usable {
            self.bins.par_extend(tris.par_iter().enumerate().map(|(i, t)| bin_triangle(t, i as u32, &basis)));
        }
        let (lo, hi) = self
            .bins
            .par_iter()
            .map(|(b, _)| match *b {
                Bin::Skip => (DVec2::INFINITY, DVec2::NEG_INFINITY),
                Bin::Rect { lo, hi } => (lo, hi),
                Bin::Strip { vlo, vhi, .. } => (vlo, vhi),
            })
            .reduce(|| (DVec2::INFINITY, DVec2::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
        let kept = self.bins.iter().filter(|(b, _)| !matches!(b, Bin::Skip)).count();
        let margin = 0.01 * self.r_max + f64::MIN_POSITIVE;
        let (lo, hi) = (lo - margin, hi + margin);
        let ext = (hi - lo).max(DVec2::splat(margin));
        let grid = if !usable || kept == 0 || !ext.is_finite() {
            Grid { nx: 0, ny: 0, ..Grid::default() }
        } else {
            let target = (kept as f64 * CELLS_PER_TRIANGLE).max(1.0);
            let h = (ext.x * ext.y / target).sqrt().max(ext.max_element() / MAX_SIDE as f64);
            let (nx, ny) = (((ext.x / h).ceil() as usize).max(1), ((ext.y / h).ceil() as usize).max(1));
            Grid { x0: lo.x, y0: lo.y, h, inv_h: 1.0 / h, nx, ny, pad }
        };
        self.grid = grid;
        let t_bin = t0.elapsed();

        // Count per cell, place triangle ids (both parallel, atomic counters), then per
        // row of cells (parallel) write the entries and sort each cell.
        let cells = grid.nx * grid.ny;
        let bins = &self.bins;
        let counts = &mut self.counts;
        counts.clear();
        counts.resize_with(cells, || AtomicU32::new(0));
        bins.par_iter().for_each(|(b, _)| grid.for_each_cell(b, |c| _ = counts[c].fetch_add(1, Ordering::Relaxed)));
        self.cell_start.clear();
        self.cell_start.reserve(cells + 1);
        self.cell_start.push(0);
        let mut acc = 0u32;
        for c in counts.iter_mut() {
            acc += *c.get_mut();
            self.cell_start.push(acc);
            // Reused below as each cell's write cursor.
            *c.get_mut() = acc - *c.get_mut();
        }
        let n_entries = acc as usize;
        let ids = &mut self.ids;
        ids.clear();
        ids.resize_with(n_entries, || AtomicU32::new(0));
        bins.par_iter().enumerate().for_each(|(i, (b, _))| {
            grid.for_each_cell(b, |c| {
                let at = counts[c].fetch_add(1, Ordering::Relaxed);
                ids[at as usize].store(i as u32, Ordering::Relaxed);
            })
        });
        let t_fill = t0.elapsed();
        self.entries.clear();
        self.entries.resize(n_entries, Entry { key: 0.0, tri: 0, lo: [0.0; 2], hi: [0.0; 2], n: [0.0; 3], d: 0.0 });
        let starts = &self.cell_start;
        let mut rows: Vec<(usize, &mut [Entry])> = Vec::with_capacity(grid.ny);
        let mut rest: &mut [Entry] = &mut self.entries;
        for y in 0..grid.ny {
            let (a, b) = (starts[y * grid.nx] as usize, starts[(y + 1) * grid.nx] as usize);
            let (row, tail) = rest.split_at_mut(b - a);
            rows.push((y, row));
            rest = tail;
        }
        rows.par_iter_mut().for_each(|(y, row)| {
            let base = starts[*y * grid.nx] as usize;
            for (k, e) in row.iter_mut().enumerate() {
                let i = ids[base + k].load(Ordering::Relaxed);
                *e = bins[i as usize].1;
            }
            for x in 0..grid.nx {
                let c = *y * grid.nx + x;
                let (a, b) = (starts[c] as usize - base, starts[c + 1] as usize - base);
                row[a..b].sort_unstable_by(|p, q| q.key.total_cmp(&p.key).then(p.tri.cmp(&q.tri)));
            }
        });
        tracing::trace!(bin = ?t_bin, place = ?t_fill, total = ?t0.elapsed(), "sun shadow grid build phases");
        let strips = self.bins.iter().filter(|(b, _)| matches!(b, Bin::Strip { .. })).count();
        self.stats = SunShadowStats {
            triangles: tris.len(),
            dropped: tris.len() - kept,
            strips,
            cells,
            entries: n_entries,
            build_time: t0.elapsed(),
        };
        tracing::debug!(stats = ?self.stats, "sun shadow grid built");
    }

    /// Whether anything blocks `ray` within `(0, tmax]`, exactly as
    /// `Accel::occluded` answers; `None` when the ray is not one this structure answers
    /// for (direction not bit-identical to [`Self::dir`], origin outside the grid or
    /// farther out than the mesh allows for).
    #[inline]
    pub fn occluded(&self, r: &Ray) -> Option<bool> {
        if r.dir.to_array().map(f32::to_bits) != self.dir.to_array().map(f32::to_bits) {
            return None;
        }
        let o = r.origin.as_dvec3();
        // A NaN origin fails this too.
        if o.length_squared().partial_cmp(&self.origin_r2) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        let g = &self.grid;
        let (cx, cy) = (g.cell_x(o.dot(self.u)), g.cell_y(o.dot(self.v)));
        if cx < 0 || cy < 0 || cx >= g.nx as isize || cy >= g.ny as isize {
            return None;
        }
        let c = cy as usize * g.nx + cx as usize;
        let (x, y, z) = (o.dot(self.u), o.dot(self.v), o.dot(self.w));
        let ray = ObRay::new(Vec3A::from(r.origin), Vec3A::from(r.dir), 0.0, r.tmax);
        let (a, b) = (self.cell_start[c] as usize, self.cell_start[c + 1] as usize);
        for e in &self.entries[a..b] {
            if f64::from(e.key) < z {
                break;
            }
            if e.may_hit(o, x, y) && self.tris[e.tri as usize].intersect(&ray) < ray.tmax {
                return Some(true);
            }
        }
        Some(false)
    }
}

impl SunShadow {
    /// Entries a query for `r` reads and triangle tests it runs (until its first hit), or
    /// `None` as for [`Self::occluded`]; for benchmarks and tuning.
    pub fn cost_of(&self, r: &Ray) -> Option<(usize, usize)> {
        self.occluded(r)?;
        let o = r.origin.as_dvec3();
        let g = &self.grid;
        let c = g.cell_y(o.dot(self.v)) as usize * g.nx + g.cell_x(o.dot(self.u)) as usize;
        let (x, y, z) = (o.dot(self.u), o.dot(self.v), o.dot(self.w));
        let ray = ObRay::new(Vec3A::from(r.origin), Vec3A::from(r.dir), 0.0, r.tmax);
        let (mut read, mut n) = (0, 0);
        for e in &self.entries[self.cell_start[c] as usize..self.cell_start[c + 1] as usize] {
            read += 1;
            if f64::from(e.key) < z {
                break;
            }
            if !e.may_hit(o, x, y) {
                continue;
            }
            n += 1;
            if self.tris[e.tri as usize].intersect(&ray) < ray.tmax {
                break;
            }
        }
        Some((read, n))
    }
}

/// The projection the triangles are binned in.
#[derive(Clone, Copy)]
struct Basis {
    dir: Vec3,
    u: DVec3,
    v: DVec3,
    w: DVec3,
    /// Largest origin distance from the render-frame origin answered.
    r_origin: f64,
    /// Absolute widening of every region against f64 rounding.
    pad: f64,
}

/// How triangle `t` is binned: the region of origins (projected) for which its f32 test
/// along `dir` can pass, and the largest origin depth at which it can.
#[inline]
fn bin_triangle(t: &RtTriangle, i: u32, b: &Basis) -> (Bin, Entry) {
    let Basis { dir, u, v, w, r_origin, pad } = *b;
    // Exactly obvhs's determinant and its reciprocal.
    let det_c = t.ng.dot(Vec3A::from(dir));
    let never = Entry { key: f32::NEG_INFINITY, tri: i, lo: [0.0; 2], hi: [0.0; 2], n: [0.0; 3], d: f32::NEG_INFINITY };
    if !(1.0 / det_c).is_finite() {
        return (Bin::Skip, never);
    }
    let f = |a: Vec3A| DVec3::from(Vec3::from(a));
    let (v0, e1, e2, ng) = (f(t.v0), f(t.e1), f(t.e2), f(t.ng));
    let d = dir.as_dvec3();
    let sigma = if det_c > 0.0 { 1.0 } else { -1.0 };
    let dc = f64::from(det_c.abs());
    // |c| = |v0 − o| is at most this for any origin answered.
    let c_max = v0.length() + r_origin;
    let d_len = d.length();
    // Bounds on the f32 error of U, V (and of ng·c below), plus underflow of the products.
    let tiny = dc * 1e-40 + 1e-300;
    let e_u = (K_ERR + 1e-12) * d_len * c_max * e2.length() + tiny;
    let e_v = (K_ERR + 1e-12) * d_len * c_max * e1.length() + tiny;
    let m = dc * (1.0 + 8.0 * UNIT) + e_u + e_v;
    // t ≥ 0 possible only if σ ng·(v0 − o) ≥ −e_t: the origin is behind the plane.
    let e_t = (K_ERR + 1e-12) * ng.length() * c_max + tiny;
    let sn = Vec3::from(t.ng) * sigma as f32;
    let plane_d = round_up_f32(sn.as_dvec3().dot(v0) + e_t);
    let entry = |key: f32, lo: DVec2, hi: DVec2| Entry {
        key,
        tri: i,
        lo: [round_down_f32(lo.x), round_down_f32(lo.y)],
        hi: [round_up_f32(hi.x), round_up_f32(hi.y)],
        n: sn.to_array(),
        d: plane_d,
    };
    // Gradients (projection coordinates, relative to v0) of σU and σV: σU = aU·y.
    let gu = -(e2.cross(d)) * sigma;
    let gv = -(e1.cross(d)) * sigma;
    let (au, av) = (DVec2::new(gu.dot(u), gu.dot(v)), DVec2::new(gv.dot(u), gv.dot(v)));
    let p0 = DVec2::new(v0.dot(u), v0.dot(v));
    // Pass ⇒ aU·y ≥ −e_u, aV·y ≥ −e_v, (aU + aV)·y ≤ m: a triangle in y when aU, aV are
    // independent, with these corners (solve for (aU·y, aV·y)).
    let det = au.perp_dot(av);
    let corner = |p: f64, q: f64| DVec2::new(av.y * p - au.y * q, -av.x * p + au.x * q) / det;
    let well = det.abs() >= 1e-4 * au.length() * av.length();
    if well {
        let ys = [corner(-e_u, -e_v), corner(-e_u, m + e_u), corner(m + e_v, -e_v)];
        if ys.iter().all(|y| y.abs().max_element() <= c_max) {
            // Largest origin depth over the region with t ≥ 0 possible.
            let nw = sigma * ng.dot(w);
            let key = if nw >= 1e-6 * ng.length() {
                let n2 = DVec2::new(ng.dot(u), ng.dot(v)) * sigma;
                let dz = ys.iter().map(|y| (e_t - n2.dot(*y)) / nw).fold(f64::NEG_INFINITY, f64::max);
                round_up_f32(v0.dot(w) + dz + pad * 10.0 + 1e-9 * c_max)
            } else {
                f32::INFINITY
            };
            let (lo, hi) =
                ys.iter().fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), y| (lo.min(*y), hi.max(*y)));
            let (lo, hi) = (p0 + lo - pad, p0 + hi + pad);
            return (Bin::Rect { lo, hi }, entry(key, lo, hi));
        }
    }
    // Nearly edge-on: the region lies in each of the strips −e ≤ a·y ≤ m + e' implied by
    // the three conditions; bin along the narrowest (all have the same height).
    let au_pv = au + av;
    let (a, lo, hi) = if au.length() >= av.length() && au.length() >= au_pv.length() {
        (au, -e_u, m + e_v)
    } else if av.length() >= au_pv.length() {
        (av, -e_v, m + e_u)
    } else {
        (au_pv, -e_u - e_v, m)
    };
    let (p1, p2) = (p0 - DVec2::new(e1.dot(u), e1.dot(v)), p0 + DVec2::new(e2.dot(u), e2.dot(v)));
    let (vlo, vhi) = (p0.min(p1).min(p2), p0.max(p1).max(p2));
    if a == DVec2::ZERO || !a.is_finite() {
        // No usable strip (cannot happen with 1/D finite); cover every cell.
        return (
            Bin::Strip { a: DVec2::ZERO, lo: -1.0, hi: 1.0, vlo, vhi },
            entry(f32::INFINITY, DVec2::NEG_INFINITY, DVec2::INFINITY),
        );
    }
    // In absolute projection coordinates: a·X ∈ [lo + a·p0, hi + a·p0], widened for f64.
    let off = a.dot(p0);
    let slack = 1e-12 * (a.length() * (p0.length() + c_max));
    let strip = Bin::Strip { a, lo: lo + off - slack, hi: hi + off + slack, vlo, vhi };
    (strip, entry(f32::INFINITY, DVec2::NEG_INFINITY, DVec2::INFINITY))
}

/// The largest f32 ≤ `x`.
fn round_down_f32(x: f64) -> f32 {
    let k = x as f32;
    if f64::from(k) > x { k.next_down() } else { k }
}

/// The smallest f32 ≥ `x` (f32 keys compared against f64 depths stay conservative).
fn round_up_f32(x: f64) -> f32 {
    let k = x as f32;
    if f64::from(k) < x { k.next_up() } else { k }
}
