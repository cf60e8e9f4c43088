//! One tile's coverage: every sample of its pixels finds its nearest triangle (edge
//! functions and a depth plane per triangle, [`super::setup`]), then each pixel's samples
//! are resolved into fragments — one per triangle that a sample of the pixel sees, with
//! how many samples see it and where they are on average.

use super::pattern::{self, SAMPLES};
use super::sample_loops::{PixelSamples, Triangle, depth_portable, edges_portable};
#[cfg(target_arch = "x86_64")]
use super::sample_loops::{depth_avx2, edges_avx2};
use super::setup::{Setup, TILE, TriSetup};

/// No triangle: the sample sees the background.
pub const NONE: u32 = u32::MAX;

/// A tile's per-sample buffers (kept from tile to tile).
pub struct TileBuffers {
    /// Sample offsets in each pixel (tile-local pixel `p` = `row · TILE + col`).
    pub sx: Vec<[f32; SAMPLES]>,
    pub sy: Vec<[f32; SAMPLES]>,
    /// Nearest depth key so far (larger is nearer) and its triangle (index into the setup).
    depth: Vec<[f32; SAMPLES]>,
    pub id: Vec<[u32; SAMPLES]>,
    /// Each pixel's ideal image point of its corner and the ideal offsets of a unit step
    /// in x and in y (an affine map of the pixel, exact for a pinhole).
    pub map: Vec<[f64; 6]>,
    /// Whether a triangle's box reached the pixel (its samples were set up).
    pub touched: Vec<bool>,
    /// The triangles that may overlap each pixel (its square not wholly outside them) and
    /// how many of its samples each has inside (nearest there or not); `None` once more
    /// than [`MAX_INSIDE`] did.
    pub inside: Vec<Option<InsideList>>,
}

/// Triangles inside a pixel that are tracked (more: the pixel is not resolved exactly).
pub const MAX_INSIDE: usize = 32;

/// Up to [`MAX_INSIDE`] (setup index, samples inside) pairs.
#[derive(Clone, Copy, Debug, Default)]
pub struct InsideList {
    pub len: u8,
    pub entries: [(u32, u32); MAX_INSIDE],
}

impl InsideList {
    /// How many of the pixel's samples lie inside triangle `id` (0 if untracked).
    pub fn inside(&self, id: u32) -> u32 {
        self.entries[..self.len as usize].iter().find(|e| e.0 == id).map_or(0, |e| e.1)
    }
}

impl Default for TileBuffers {
    fn default() -> Self {
        let n = (TILE * TILE) as usize;
        TileBuffers {
            sx: vec![[0.0; SAMPLES]; n],
            sy: vec![[0.0; SAMPLES]; n],
            depth: vec![[0.0; SAMPLES]; n],
            id: vec![[NONE; SAMPLES]; n],
            map: vec![[0.0; 6]; n],
            touched: vec![false; n],
            inside: vec![None; n],
        }
    }
}

/// A triangle's share of one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    /// Index into the setup's triangles.
    pub setup: u32,
    /// Samples of the pixel that see it.
    pub count: u32,
    /// Where in the pixel it is seen on average (x, y offsets): its samples' mean, or the
    /// centroid of its exact area.
    pub mean: [f32; 2],
    /// Its share of the pixel's area: `count / SAMPLES`, or its exact area.
    pub weight: f32,
}

/// The tile at tile coordinates (`tx`, `ty`): its pixels (image coordinates, inclusive
/// start, exclusive end).
pub fn tile_pixels(setup: &Setup, tx: u32, ty: u32) -> ([u32; 2], [u32; 2]) {
    let r = setup.rect;
    let (c0, r0) = (r.col0 + tx * TILE, r.row0 + ty * TILE);
    ([c0, (c0 + TILE).min(r.col1)], [r0, (r0 + TILE).min(r.row1)])
}

/// The triangles binned to tile (`tx`, `ty`).
pub fn tile_list(setup: &Setup, tx: u32, ty: u32) -> &[u32] {
    let t = (ty * setup.tiles_x + tx) as usize;
    &setup.tile_tris[setup.tile_start[t] as usize..setup.tile_start[t + 1] as usize]
}

/// Rasterise tile (`tx`, `ty`): fill `buf` with each sample's nearest triangle (pixels
/// no triangle's box reaches are left untouched: `buf.touched`). Pixel keys come from
/// `key(row, col)`; the depth key is `(w − w_ref)·scale` (larger is nearer), which keeps
/// f32 depth resolution relative to the target's size, not its range.
#[allow(clippy::too_many_arguments)]
pub fn rasterise(
    setup: &Setup,
    tx: u32,
    ty: u32,
    seed: u64,
    frame: u64,
    key: &dyn Fn(u32, u32) -> u64,
    depth_key: (f64, f64),
    buf: &mut TileBuffers,
) {
    #[cfg(target_arch = "x86_64")]
    if crate::render::geometry::shadow_packet::avx2() {
        // SAFETY: the CPU has AVX2 (checked at run time). No FMA: the same IEEE
        // operations, so the same bits, as the baseline path.
        unsafe { rasterise_avx2(setup, tx, ty, seed, frame, key, depth_key, buf) };
        return;
    }
    rasterise_body::<false>(setup, tx, ty, seed, frame, key, depth_key, buf);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn rasterise_avx2(
    setup: &Setup,
    tx: u32,
    ty: u32,
    seed: u64,
    frame: u64,
    key: &dyn Fn(u32, u32) -> u64,
    depth_key: (f64, f64),
    buf: &mut TileBuffers,
) {
    rasterise_body::<true>(setup, tx, ty, seed, frame, key, depth_key, buf);
}

/// `AVX2`: the sample loops in AVX2 (the caller runs with it), else portable; the same bits.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn rasterise_body<const AVX2: bool>(
    setup: &Setup,
    tx: u32,
    ty: u32,
    seed: u64,
    frame: u64,
    key: &dyn Fn(u32, u32) -> u64,
    (w_ref, scale): (f64, f64),
    buf: &mut TileBuffers,
) {
    let ([c0, c1], [r0, r1]) = tile_pixels(setup, tx, ty);
    // The tile's four ideal corners; each pixel's affine map by bilinear interpolation.
    let stride = (setup.tiles_x + 1) as usize;
    let corner = |i: u32, j: u32| setup.corners[(ty + j) as usize * stride + (tx + i) as usize];
    let (p00, p10, p01, p11) = (corner(0, 0), corner(1, 0), corner(0, 1), corner(1, 1));
    let at = |u: f64, v: f64| -> [f64; 2] {
        let (a, b) = (u / f64::from(TILE), v / f64::from(TILE));
        std::array::from_fn(|k| (1.0 - b) * ((1.0 - a) * p00[k] + a * p10[k]) + b * ((1.0 - a) * p01[k] + a * p11[k]))
    };
    buf.touched.iter_mut().for_each(|t| *t = false);
    for &i in tile_list(setup, tx, ty) {
        let s = &setup.tris[i as usize];
        let (y0, y1) = (s.bbox[1].max(r0), s.bbox[3].min(r1 - 1));
        for row in y0..=y1 {
            let Some((a, b)) = s.row_span(row) else { continue };
            let (x0, x1) = (a.max(c0), b.min(c1 - 1));
            for col in x0..=x1 {
                let p = ((row - r0) * TILE + (col - c0)) as usize;
                if !buf.touched[p] {
                    buf.touched[p] = true;
                    let (u, v) = (f64::from(col - c0), f64::from(row - r0));
                    let (o, ex, ey) = (at(u, v), at(u + 1.0, v), at(u, v + 1.0));
                    buf.map[p] = [o[0], o[1], ex[0] - o[0], ex[1] - o[1], ey[0] - o[0], ey[1] - o[1]];
                    pattern::fill(seed, frame, key(row, col), &mut buf.sx[p], &mut buf.sy[p]);
                    buf.depth[p] = [f32::NEG_INFINITY; SAMPLES];
                    buf.id[p] = [NONE; SAMPLES];
                    buf.inside[p] = Some(InsideList::default());
                }
                let px = PixelSamples { sx: &buf.sx[p], sy: &buf.sy[p], depth: &mut buf.depth[p], ids: &mut buf.id[p] };
                let n = pixel::<AVX2>(s, i, &buf.map[p], (w_ref, scale), px);
                // In place: the list is a few hundred bytes, visited per triangle.
                if let (Some(n), Some(l)) = (n, &mut buf.inside[p]) {
                    let k = l.len as usize;
                    if k < MAX_INSIDE {
                        l.entries[k] = (i, n);
                        l.len += 1;
                    } else {
                        buf.inside[p] = None; // untracked from here: sampled shares
                    }
                }
            }
        }
    }
}

/// The samples of one pixel against one triangle; returns how many lie inside it, or None
/// when the pixel's square lies wholly outside the triangle.
#[inline(always)]
fn pixel<const AVX2: bool>(
    s: &TriSetup,
    id: u32,
    m: &[f64; 6],
    (w_ref, scale): (f64, f64),
    px: PixelSamples,
) -> Option<u32> {
    // Each edge as e + α·sx + β·sy over the pixel; the same numbers for both triangles
    // of a shared edge (canonical edge, same pixel map).
    let mut e = [[0.0f32; 3]; 3];
    let mut pos = [false; 3];
    let mut all_inside = true;
    for (k, ed) in s.edges.iter().enumerate() {
        e[k] = [ed.at(m[0], m[1]) as f32, (ed.a * m[2] + ed.b * m[3]) as f32, (ed.a * m[4] + ed.b * m[5]) as f32];
        pos[k] = ed.k_pos;
        // The pixel's square against this edge, with a margin above the rounding of the
        // sample loop's evaluation (so the shortcuts never decide a sample it would not).
        let [c, a, b] = e[k];
        let corners = [c, c + a, c + b, c + a + b];
        let margin = 1e-5 * (c.abs() + a.abs() + b.abs());
        let sign = if ed.k_pos { 1.0 } else { -1.0 };
        if corners.iter().all(|&v| sign * v < -margin) {
            return None; // wholly outside
        }
        all_inside &= corners.iter().all(|&v| sign * v > margin);
    }
    let wd = [
        ((s.w_at(m[0], m[1]) - w_ref) * scale) as f32,
        ((s.w_dx * m[2] + s.w_dy * m[3]) * scale) as f32,
        ((s.w_dx * m[4] + s.w_dy * m[5]) * scale) as f32,
    ];
    let t = Triangle { e, pos, wd, id };
    Some(match (AVX2, all_inside) {
        #[cfg(target_arch = "x86_64")]
        (true, true) => {
            // SAFETY: AVX2 is only true inside `rasterise_avx2`, run on an AVX2 CPU.
            unsafe { depth_avx2(&t, px) };
            SAMPLES as u32
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        (true, false) => unsafe { edges_avx2(&t, px) },
        (_, true) => {
            depth_portable(&t, px);
            SAMPLES as u32
        }
        (_, false) => edges_portable(&t, px),
    })
}

/// Resolve one pixel's samples into fragments (in order of first appearance), appended
/// to `out`; returns how many samples see the background.
#[inline(never)]
pub fn resolve(ids: &[u32; SAMPLES], sx: &[f32; SAMPLES], sy: &[f32; SAMPLES], out: &mut Vec<Fragment>) -> u32 {
    let start = out.len();
    let id0 = ids[0];
    if id0 != NONE && ids.iter().all(|&i| i == id0) {
        let mean = |v: &[f32; SAMPLES]| v.iter().sum::<f32>() / SAMPLES as f32;
        out.push(Fragment { setup: id0, count: SAMPLES as u32, mean: [mean(sx), mean(sy)], weight: 1.0 });
        return 0;
    }
    let mut background = 0;
    for j in 0..SAMPLES {
        let id = ids[j];
        if id == NONE {
            background += 1;
            continue;
        }
        match out[start..].iter_mut().find(|f| f.setup == id) {
            Some(f) => {
                f.count += 1;
                f.mean[0] += sx[j];
                f.mean[1] += sy[j];
            }
            None => out.push(Fragment { setup: id, count: 1, mean: [sx[j], sy[j]], weight: 0.0 }),
        }
    }
    for f in &mut out[start..] {
        let n = f.count as f32;
        f.mean = [f.mean[0] / n, f.mean[1] / n];
        f.weight = n / SAMPLES as f32;
    }
    background
}

/// Replace the sampled shares of `fragments` (one pixel's) by exact areas when every one
/// is seen whole in the pixel — it is the nearest at every sample inside it (`inside`) —
/// so that no triangle's area there is hidden by another's. A triangle that overlaps the
/// pixel but holds none of its samples (a sliver between them) is added as a fragment
/// unless another triangle over the pixel covers its centroid nearer to the camera.
/// Returns the background's share, or None (the sampled shares stand) when some fragment
/// is partly hidden, a triangle went untracked, or the areas do not add up.
pub fn exact_shares(
    setup: &Setup,
    inside: &Option<InsideList>,
    map: &[f64; 6],
    fragments: &mut Vec<Fragment>,
) -> Option<f32> {
    let inside = inside.as_ref()?;
    if fragments.iter().any(|f| inside.inside(f.setup) != f.count) {
        return None;
    }
    let sampled = fragments.len();
    let mut total = 0.0;
    for f in fragments.iter_mut() {
        let (area, c) = super::area::clipped(&setup.tris[f.setup as usize].ideal, map)?;
        total += area;
        f.weight = area as f32;
        f.mean = [(c[0] as f32).clamp(0.0, 1.0), (c[1] as f32).clamp(0.0, 1.0)];
    }
    for &(id, n) in &inside.entries[..inside.len as usize] {
        if n > 0 {
            continue;
        }
        let (area, c) = super::area::clipped(&setup.tris[id as usize].ideal, map)?;
        if area <= 0.0 {
            continue;
        }
        // Seen unless another triangle over the pixel covers the sliver's centroid and is
        // nearer there (larger w = 1/z; the same plane within rounding counts as seen).
        // Only triangles that contain the point count: a neighbour's plane extended past
        // its edge lies in front of a convex surface.
        let (cx, cy) = (c[0] as f32, c[1] as f32);
        let ideal = [map[0] + map[2] * c[0] + map[4] * c[1], map[1] + map[3] * c[0] + map[5] * c[1]];
        let w_sliver = setup.tris[id as usize].w_at(ideal[0], ideal[1]);
        let seen = inside.entries[..inside.len as usize].iter().all(|&(other, _)| {
            let t = &setup.tris[other as usize];
            other == id || !contains(&t.ideal, ideal) || t.w_at(ideal[0], ideal[1]) <= w_sliver * (1.0 + 1e-7)
        });
        if seen {
            total += area;
            fragments.push(Fragment {
                setup: id,
                count: 0,
                mean: [cx.clamp(0.0, 1.0), cy.clamp(0.0, 1.0)],
                weight: area as f32,
            });
        }
    }
    // Whole triangles that do not overlap cannot cover more than the pixel.
    if total > 1.0 + 1e-6 {
        fragments.truncate(sampled);
        return None;
    }
    Some((1.0 - total).max(0.0) as f32)
}

/// True when point `p` lies inside or on the triangle `v` (either winding).
fn contains(v: &[[f64; 2]; 3], p: [f64; 2]) -> bool {
    let cross = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    let (d0, d1, d2) = (cross(v[0], v[1]), cross(v[1], v[2]), cross(v[2], v[0]));
    (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)
}
