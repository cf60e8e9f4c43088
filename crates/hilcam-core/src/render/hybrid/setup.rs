//! The frame's triangles on the ideal image plane: edge functions, depth planes, and bins
//! of pixel tiles.
//!
//! Each vertex is projected once (f64) to ideal pixel coordinates (the undistorted image
//! plane, where a triangle stays a triangle) with `w = 1/z`, which is linear there. Each
//! edge function is built from its two vertices in a canonical order (the lower mesh
//! index first), so the two triangles that share an edge evaluate the very same numbers at
//! every sample and the tie rule gives a sample on the edge to exactly one of them: the
//! coverage is watertight, nothing is counted twice or lost between neighbours.

use crate::render::camera::{PixelRect, View};
use crate::render::target::Target;
use rayon::prelude::*;

/// Pixels per tile side: a tile's samples (64 per pixel) stay in the L1/L2 caches.
pub const TILE: u32 = 8;

/// Nearest depth (m, along the boresight) a vertex may have; a frame with a vertex nearer
/// (or behind the camera) is left to the path tracer.
const Z_MIN: f64 = 1e-3;

/// One edge `E(x, y) = a (x − x_r) + b (y − y_r)` in canonical orientation, and the sign
/// `k` that turns it into this triangle's inside (`k·E > 0`, ties go to `k > 0`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Edge {
    pub a: f64,
    pub b: f64,
    pub x_r: f64,
    pub y_r: f64,
    pub k_pos: bool,
}

impl Edge {
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> f64 {
        self.a * (x - self.x_r) + self.b * (y - self.y_r)
    }
}

/// A projected triangle ready to rasterise.
#[derive(Clone, Copy, Debug, Default)]
pub struct TriSetup {
    /// Mesh triangle index.
    pub tri: u32,
    pub edges: [Edge; 3],
    /// `w = 1/z` at (x_r, y_r) of edge 0 and its gradient on the ideal plane.
    pub w0: f64,
    pub w_dx: f64,
    pub w_dy: f64,
    /// Inclusive pixel box `[col0, row0, col1, row1]` (image pixels).
    pub bbox: [u32; 4],
    /// The triangle's vertices imaged through the lens (pixel coordinates) and how far
    /// its edges may bow away from the straight lines between them (pixels).
    pub px: [[f32; 2]; 3],
    pub bow: f32,
    /// Its vertices on the ideal image plane.
    pub ideal: [[f64; 2]; 3],
}

impl TriSetup {
    /// Columns `[c0, c1]` (inclusive, inside the box) of row `row` that the triangle may
    /// cover: its image's x-range within the band `[row, row + 1)`, grown by the bow.
    /// None when it misses the band.
    #[inline]
    pub fn row_span(&self, row: u32) -> Option<(u32, u32)> {
        let (y0, y1) = (row as f32 - self.bow, row as f32 + 1.0 + self.bow);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for e in 0..3 {
            let (p, q) = (self.px[e], self.px[(e + 1) % 3]);
            let (ya, yb) = (p[1].min(q[1]), p[1].max(q[1]));
            if yb < y0 || ya > y1 {
                continue;
            }
            // The edge clipped to the band: its x at the clipped ends.
            let x_at = |y: f32| if q[1] == p[1] { p[0] } else { p[0] + (q[0] - p[0]) * ((y - p[1]) / (q[1] - p[1])) };
            for y in [ya.max(y0), yb.min(y1)] {
                let x = x_at(y);
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
        if lo.is_nan() || hi.is_nan() || lo > hi {
            return None;
        }
        let c0 = ((lo - self.bow).floor().max(self.bbox[0] as f32)) as u32;
        let c1 = ((hi + self.bow).floor().min(self.bbox[2] as f32)) as u32;
        (c0 <= c1).then_some((c0, c1))
    }

    #[inline]
    pub fn w_at(&self, x: f64, y: f64) -> f64 {
        self.w0 + self.w_dx * (x - self.edges[0].x_r) + self.w_dy * (y - self.edges[0].y_r)
    }
}

/// The frame's triangles, set up and binned by tile; buffers kept from frame to frame.
#[derive(Default)]
pub struct Setup {
    /// Ideal pixel coordinates and `w` of each mesh vertex.
    verts: Vec<[f64; 3]>,
    pub tris: Vec<TriSetup>,
    /// Tiles cover `rect` from its corner, `tiles_x × tiles_y`.
    pub rect: PixelRect,
    pub tiles_x: u32,
    pub tiles_y: u32,
    /// Tile `t`'s triangles: `tile_tris[tile_start[t]..tile_start[t + 1]]` (indices into
    /// `tris`, ascending: the mesh order, so ties resolve the same on every run).
    pub tile_start: Vec<u32>,
    pub tile_tris: Vec<u32>,
    /// Ideal coordinates of the tile grid's corners, `(tiles_x + 1) × (tiles_y + 1)`.
    pub corners: Vec<[f64; 2]>,
    /// Per chunk of triangles while binning: each one's tile count, and their tiles.
    chunk_tiles: Vec<(Vec<u32>, Vec<u32>)>,
}

impl Setup {
    /// Set up `target`'s triangles as `view` sees them inside `rect`. False when the frame
    /// cannot be rasterised (a vertex at or behind the camera plane).
    pub fn build(&mut self, target: &Target, view: &View, rect: PixelRect) -> bool {
        let mesh = &target.mesh;
        // Vertices and triangles in parallel, each a pure function of its inputs, collected
        // in mesh order: the same setup for any thread count.
        mesh.positions
            .par_iter()
            .map(|p| {
                let q = view.to_camera(p.as_dvec3());
                if !q.is_finite() || q.z <= Z_MIN {
                    return [f64::NAN; 3]; // marks the frame as not rasterisable
                }
                let [x, y] = view.ideal_px(q);
                [x, y, 1.0 / q.z]
            })
            .collect_into_vec(&mut self.verts);
        if self.verts.par_iter().any(|v| v[2].is_nan()) {
            return false;
        }
        self.rect = rect;
        self.tiles_x = (rect.col1 - rect.col0).div_ceil(TILE);
        self.tiles_y = (rect.row1 - rect.row0).div_ceil(TILE);
        self.tris.clear();
        let verts = &self.verts;
        self.tris.par_extend(
            mesh.indices.par_iter().enumerate().filter_map(|(t, idx)| triangle(verts, t as u32, *idx, view, rect)),
        );
        self.bin();
        self.corners.clear();
        for ty in 0..=self.tiles_y {
            for tx in 0..=self.tiles_x {
                let (x, y) = (f64::from(rect.col0 + tx * TILE), f64::from(rect.row0 + ty * TILE));
                self.corners.push(view.ideal_of_pixel(x, y));
            }
        }
        true
    }
}

/// Triangle `tri` (vertex indices `idx` into `verts`) set up, or None when it covers no
/// area or lies outside `rect`.
fn triangle(verts: &[[f64; 3]], tri: u32, idx: [u32; 3], view: &View, rect: PixelRect) -> Option<TriSetup> {
    let v = idx.map(|i| verts[i as usize]);
    let area2 = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0]);
    if area2 == 0.0 || area2.is_nan() {
        return None; // seen edge-on (or degenerate): it covers no area
    }
    let (bbox, px, bow) = pixel_box(&v, view, rect)?;
    let orient = area2 > 0.0;
    let edges = std::array::from_fn(|e| {
        let (i, j) = (e, (e + 1) % 3);
        // Canonical: from the lower mesh index to the higher.
        let (p, q, forward) = if idx[i] < idx[j] { (v[i], v[j], true) } else { (v[j], v[i], false) };
        // cross(q − p, s − p) = (q.x − p.x)(s.y − p.y) − (q.y − p.y)(s.x − p.x)
        Edge { a: -(q[1] - p[1]), b: q[0] - p[0], x_r: p[0], y_r: p[1], k_pos: forward == orient }
    });
    // w = 1/z is linear on the ideal plane: its gradient from the three vertices.
    let (dx1, dy1, dw1) = (v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]);
    let (dx2, dy2, dw2) = (v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]);
    let w_dx = (dw1 * dy2 - dw2 * dy1) / area2;
    let w_dy = (dx1 * dw2 - dx2 * dw1) / area2;
    let ideal = v.map(|p| [p[0], p[1]]);
    let mut s = TriSetup { tri, edges, w0: 0.0, w_dx, w_dy, bbox, px, bow, ideal };
    let (xr, yr) = (edges[0].x_r, edges[0].y_r);
    s.w0 = v[0][2] + w_dx * (xr - v[0][0]) + w_dy * (yr - v[0][1]);
    Some(s)
}

impl Setup {
    /// Count-sort the triangles into the tiles their pixel boxes meet. Which tiles each
    /// triangle meets is found in parallel, chunk by chunk of triangles; the sort then runs
    /// over the chunks in order, so each tile lists its triangles ascending.
    fn bin(&mut self) {
        /// Triangles per parallel chunk.
        const CHUNK: usize = 2048;
        let n = (self.tiles_x * self.tiles_y) as usize;
        let (r, tx) = (self.rect, self.tiles_x);
        // The tiles a triangle's rows span meet, each once (ascending).
        let tiles = |s: &TriSetup, out: &mut Vec<u32>| {
            let (y0, y1) = ((s.bbox[1] - r.row0) / TILE, (s.bbox[3] - r.row0) / TILE);
            for ty in y0..=y1 {
                let rows = (r.row0 + ty * TILE).max(s.bbox[1])..=(r.row0 + ty * TILE + TILE - 1).min(s.bbox[3]);
                let span = rows.filter_map(|row| s.row_span(row)).fold(None, |acc: Option<(u32, u32)>, (a, b)| {
                    Some(acc.map_or((a, b), |(x, y)| (x.min(a), y.max(b))))
                });
                if let Some((a, b)) = span {
                    out.extend(((a - r.col0) / TILE..=(b - r.col0) / TILE).map(|x| ty * tx + x));
                }
            }
        };
        // Per chunk: each triangle's tile count, then its tiles, in triangle order.
        let chunks = self.tris.len().div_ceil(CHUNK);
        self.chunk_tiles.resize_with(chunks, Default::default);
        self.tris.par_chunks(CHUNK).zip(self.chunk_tiles.par_iter_mut()).for_each(|(tris, (counts, list))| {
            counts.clear();
            list.clear();
            for s in tris {
                let before = list.len();
                tiles(s, list);
                counts.push((list.len() - before) as u32);
            }
        });
        self.tile_start.clear();
        self.tile_start.resize(n + 1, 0);
        for (_, list) in &self.chunk_tiles[..chunks] {
            for &t in list {
                self.tile_start[t as usize + 1] += 1;
            }
        }
        for t in 0..n {
            self.tile_start[t + 1] += self.tile_start[t];
        }
        self.tile_tris.clear();
        self.tile_tris.resize(self.tile_start[n] as usize, 0);
        let mut fill: Vec<u32> = self.tile_start[..n].to_vec();
        for (c, (counts, list)) in self.chunk_tiles[..chunks].iter().enumerate() {
            let mut at = 0;
            for (k, &count) in counts.iter().enumerate() {
                let i = (c * CHUNK + k) as u32;
                for &t in &list[at..at + count as usize] {
                    self.tile_tris[fill[t as usize] as usize] = i;
                    fill[t as usize] += 1;
                }
                at += count as usize;
            }
        }
    }
}

/// The image pixels (inclusive box, inside `rect`) a triangle with ideal vertices `v` may
/// cover, its vertices imaged through the lens and the bow of its edges there. Through a
/// distorting lens a straight edge images to a curve that departs from the chord between
/// its ends by about |d²δ/dr²|·L²/8 for a chord of L pixels (δ the radial displacement):
/// for the shipped lenses well under 1e-5·L² px, so 0.25 px + 1e-5·L² is a safe bow. None
/// when outside `rect`.
fn pixel_box(v: &[[f64; 3]; 3], view: &View, rect: PixelRect) -> Option<([u32; 4], [[f32; 2]; 3], f32)> {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut add = |x: f64, y: f64| {
        let p = view.pixel_of_ideal(x, y);
        lo = [lo[0].min(p[0]), lo[1].min(p[1])];
        hi = [hi[0].max(p[0]), hi[1].max(p[1])];
    };
    if view.has_distortion() {
        for e in 0..3 {
            let (p, q) = (v[e], v[(e + 1) % 3]);
            for s in 0..4 {
                let f = f64::from(s) / 4.0;
                add(p[0] + f * (q[0] - p[0]), p[1] + f * (q[1] - p[1]));
            }
        }
    } else {
        for p in v {
            add(p[0], p[1]);
        }
    }
    let px = v.map(|p| {
        let q = view.pixel_of_ideal(p[0], p[1]);
        [q[0] as f32, q[1] as f32]
    });
    let longest = (0..3).map(|e| {
        let (p, q) = (px[e], px[(e + 1) % 3]);
        ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt()
    });
    let bow = if view.has_distortion() { 0.25 + 1e-5 * longest.fold(0.0f32, f32::max).powi(2) } else { 0.0 };
    let margin = f64::from(bow) + if view.has_distortion() { 1.0 } else { 0.0 };
    let clamp = |x: f64, a: u32, b: u32| x.floor().clamp(f64::from(a), f64::from(b)) as u32;
    let (c0, c1) = (lo[0] - margin, hi[0] + margin);
    let (r0, r1) = (lo[1] - margin, hi[1] + margin);
    if !(c1 >= f64::from(rect.col0)
        && c0 < f64::from(rect.col1)
        && r1 >= f64::from(rect.row0)
        && r0 < f64::from(rect.row1))
    {
        return None;
    }
    let bbox = [
        clamp(c0, rect.col0, rect.col1 - 1),
        clamp(r0, rect.row0, rect.row1 - 1),
        clamp(c1, rect.col0, rect.col1 - 1),
        clamp(r1, rect.row0, rect.row1 - 1),
    ];
    Some((bbox, px, bow))
}
