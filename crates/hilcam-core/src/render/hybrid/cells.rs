//! Surface cells: each triangle cut into an n × n barycentric grid of sub-triangles no
//! longer than a fixed size in the body frame, so that what is kept per cell (how the sun
//! reaches it) does not depend on the view. A small triangle is one cell.
//!
//! Cell `2·(j·n + i) + upper` of a triangle with resolution n: the grid points are
//! `v0 + (i/n)·e1 + (j/n)·e2`; the lower sub-triangle at (i, j) has corners (i, j),
//! (i + 1, j), (i, j + 1), the upper one (i + 1, j), (i, j + 1), (i + 1, j + 1).

use crate::render::geometry::TriMesh;
use glam::Vec3;

/// Most cells along a triangle's edge (bounds the memory of a huge triangle).
const MAX_RES: u32 = 256;

/// The cells of every triangle of a mesh.
#[derive(Clone, Debug, Default)]
pub struct Cells {
    /// First cell of triangle `t`; its cells are `start[t]..start[t] + 2·n²`.
    start: Vec<u32>,
    /// Resolution n of triangle `t`.
    res: Vec<u16>,
    /// The edge length the cells were made for.
    pub size: f32,
}

impl Cells {
    /// Cells no longer than `size` along any edge (at most [`MAX_RES`] per edge).
    pub fn new(mesh: &TriMesh, size: f32) -> Cells {
        let mut start = Vec::with_capacity(mesh.indices.len() + 1);
        let mut res = Vec::with_capacity(mesh.indices.len());
        let mut next = 0u32;
        for idx in &mesh.indices {
            let [a, b, c] = idx.map(|i| mesh.positions[i as usize]);
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            let n = if size > 0.0 && longest.is_finite() {
                (longest / size).ceil().clamp(1.0, MAX_RES as f32) as u32
            } else {
                1
            };
            start.push(next);
            res.push(n as u16);
            next = next.saturating_add(2 * n * n);
        }
        start.push(next);
        Cells { start, res, size }
    }

    /// Cells in all (including the unused slots of the grids' last diagonals).
    pub fn len(&self) -> usize {
        self.start.last().copied().unwrap_or(0) as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Resolution of triangle `t`.
    #[inline]
    pub fn res(&self, t: u32) -> u32 {
        u32::from(self.res[t as usize])
    }

    /// The cell of triangle `t` holding barycentric point (`u`, `v`) (weights of v1, v2).
    #[inline]
    pub fn cell_of(&self, t: u32, u: f32, v: f32) -> u32 {
        let n = self.res(t);
        let base = self.start[t as usize];
        if n == 1 {
            return base;
        }
        let nf = n as f32;
        let (fu, fv) = ((u * nf).clamp(0.0, nf - 1e-3), (v * nf).clamp(0.0, nf - 1e-3));
        let (mut i, mut j) = (fu as u32, fv as u32);
        if i + j > n - 1 {
            // Rounding past the hypotenuse: the last lower cell of that row.
            (i, j) = (i.min(n - 1), (n - 1).saturating_sub(i.min(n - 1)));
        }
        let upper = i + j < n - 1 && (fu - i as f32) + (fv - j as f32) > 1.0;
        base + 2 * (j * n + i) + u32::from(upper)
    }

    /// Cell (`i`, `j`, `upper`) of triangle `t`, or None where the grid has no such cell
    /// (past the hypotenuse).
    #[inline]
    pub fn cell(&self, t: u32, i: u32, j: u32, upper: bool) -> Option<u32> {
        let n = self.res(t);
        let used = if upper { i + j + 1 < n } else { i + j < n };
        used.then(|| self.start[t as usize] + 2 * (j * n + i) + u32::from(upper))
    }

    /// The corners of cell `c` of triangle `t` (whose vertices are `v`), or None for an
    /// unused slot.
    pub fn corners(&self, t: u32, c: u32, v: [Vec3; 3]) -> Option<[Vec3; 3]> {
        let n = self.res(t);
        let local = c - self.start[t as usize];
        let (upper, k) = (local & 1 == 1, local / 2);
        let (i, j) = (k % n, k / n);
        let limit = if upper { n.saturating_sub(2) } else { n - 1 };
        if i + j > limit || (upper && n < 2) {
            return None;
        }
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        let nf = n as f32;
        let at = |i: u32, j: u32| v[0] + e1 * (i as f32 / nf) + e2 * (j as f32 / nf);
        Some(if upper {
            [at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]
        } else {
            [at(i, j), at(i + 1, j), at(i, j + 1)]
        })
    }

    /// The cells of triangle `t`.
    pub fn of(&self, t: u32) -> std::ops::Range<u32> {
        self.start[t as usize]..self.start[t as usize + 1]
    }
}

/// Barycentric weights (of v1, v2) of point `p` on the plane of triangle `v`.
#[inline]
pub fn barycentric(p: Vec3, v: [Vec3; 3]) -> (f32, f32) {
    let (e1, e2, d) = (v[1] - v[0], v[2] - v[0], p - v[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det == 0.0 {
        return (0.0, 0.0);
    }
    ((d22 * d1 - d12 * d2) / det, (d11 * d2 - d12 * d1) / det)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(size: f32) -> (TriMesh, Cells) {
        let mesh = TriMesh {
            positions: vec![Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)],
            indices: vec![[0, 1, 2]],
            material: vec![0],
        };
        let cells = Cells::new(&mesh, size);
        (mesh, cells)
    }

    #[test]
    fn every_point_of_a_triangle_lies_in_the_cell_it_is_assigned_to() {
        let (mesh, cells) = one(0.26); // n = ceil(√2 / 0.26) = 6
        assert_eq!(cells.res(0), 6);
        let v = [mesh.positions[0], mesh.positions[1], mesh.positions[2]];
        let mut rng = crate::render::sampling::Rng::from_state(9);
        for _ in 0..5000 {
            let (mut u, mut w) = (rng.next_f32(), rng.next_f32());
            if u + w > 1.0 {
                (u, w) = (1.0 - u, 1.0 - w);
            }
            let p = v[0] + (v[1] - v[0]) * u + (v[2] - v[0]) * w;
            let c = cells.cell_of(0, u, w);
            let corners = cells.corners(0, c, v).expect("a used cell");
            let (a, b) = barycentric(p, corners);
            assert!(a >= -1e-4 && b >= -1e-4 && a + b <= 1.0 + 1e-4, "({u}, {w}) not in cell {c}: ({a}, {b})");
        }
    }

    #[test]
    fn cells_by_grid_position_are_the_cells_of_their_points() {
        let (_, cells) = one(0.26);
        let n = cells.res(0);
        for j in 0..n {
            for i in 0..n {
                let (u, w) = ((i as f32 + 0.25) / n as f32, (j as f32 + 0.25) / n as f32);
                assert_eq!(cells.cell(0, i, j, false), (i + j < n).then(|| cells.cell_of(0, u, w)));
                let (u, w) = ((i as f32 + 0.7) / n as f32, (j as f32 + 0.7) / n as f32);
                assert_eq!(cells.cell(0, i, j, true), (i + j + 1 < n).then(|| cells.cell_of(0, u, w)));
            }
        }
    }

    #[test]
    fn the_cells_tile_the_triangle_exactly() {
        let (mesh, cells) = one(0.3);
        let v = [mesh.positions[0], mesh.positions[1], mesh.positions[2]];
        let area = |t: [Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length() / 2.0;
        let total: f32 = cells.of(0).filter_map(|c| cells.corners(0, c, v)).map(area).sum();
        assert!((total - 0.5).abs() < 1e-5, "{total}");
        let used = cells.of(0).filter(|&c| cells.corners(0, c, v).is_some()).count() as u32;
        assert_eq!(used, cells.res(0).pow(2));
    }
}
