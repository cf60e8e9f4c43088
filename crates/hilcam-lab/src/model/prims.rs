//! Tessellated primitives, each appended to a [`TriMesh`] with one material, wound so
//! normals point outward (or along the stated side).

use glam::{Mat3, Vec3};
use hilcam_core::render::geometry::TriMesh;
use std::f32::consts::TAU;

/// A rigid placement: `p ↦ rot·p + at`.
#[derive(Clone, Copy, Debug)]
pub struct Place {
    pub rot: Mat3,
    pub at: Vec3,
}

impl Place {
    pub fn at(at: Vec3) -> Self {
        Place { rot: Mat3::IDENTITY, at }
    }
    /// Local +Z mapped onto `axis` (unit), with `at` as origin.
    pub fn along(axis: Vec3, at: Vec3) -> Self {
        let f = hilcam_core::render::sampling::ShadingBasis::from_normal(axis.normalize());
        Place { rot: Mat3::from_cols(f.t, f.b, f.n), at }
    }
    pub fn apply(&self, p: Vec3) -> Vec3 {
        self.rot * p + self.at
    }
}

/// A flat quad `corner + s·u + t·v` (s, t ∈ [0, 1]) as an `nu`×`nv` grid, normal `u × v`.
pub fn quad_grid(m: &mut TriMesh, corner: Vec3, u: Vec3, v: Vec3, nu: u32, nv: u32, mat: u32) {
    let base = m.positions.len() as u32;
    for j in 0..=nv {
        for i in 0..=nu {
            let (s, t) = (i as f32 / nu as f32, j as f32 / nv as f32);
            m.positions.push(corner + u * s + v * t);
        }
    }
    let idx = |i: u32, j: u32| base + j * (nu + 1) + i;
    for j in 0..nv {
        for i in 0..nu {
            m.indices.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            m.indices.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            m.material.extend([mat, mat]);
        }
    }
}

/// An axis-aligned box (centre, half extents); `mat(face)` picks each face's material,
/// faces in order −X, +X, −Y, +Y, −Z, +Z. Two triangles per face, shared corners.
pub fn cuboid(m: &mut TriMesh, place: Place, half: Vec3, mat: impl Fn(usize) -> u32) {
    let base = m.positions.len() as u32;
    for i in 0..8u32 {
        let s = |b: u32| if i & b != 0 { 1.0 } else { -1.0 };
        m.positions.push(place.apply(Vec3::new(s(1) * half.x, s(2) * half.y, s(4) * half.z)));
    }
    let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
    for (f, q) in quads.iter().enumerate() {
        m.indices.push([base + q[0], base + q[1], base + q[2]]);
        m.indices.push([base + q[0], base + q[2], base + q[3]]);
        m.material.extend([mat(f), mat(f)]);
    }
}

/// A cylinder (or cone frustum) along local +Z from z = 0 to `len`, radii `r0` → `r1`,
/// `seg` around, `rings` along, with end caps when `caps`.
#[allow(clippy::too_many_arguments)]
pub fn cylinder(m: &mut TriMesh, place: Place, r0: f32, r1: f32, len: f32, seg: u32, rings: u32, caps: bool, mat: u32) {
    let base = m.positions.len() as u32;
    for j in 0..=rings {
        let t = j as f32 / rings as f32;
        let r = r0 + (r1 - r0) * t;
        for i in 0..seg {
            let a = TAU * i as f32 / seg as f32;
            m.positions.push(place.apply(Vec3::new(r * a.cos(), r * a.sin(), len * t)));
        }
    }
    let idx = |i: u32, j: u32| base + j * seg + i % seg;
    for j in 0..rings {
        for i in 0..seg {
            m.indices.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            m.indices.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            m.material.extend([mat, mat]);
        }
    }
    if caps {
        for (j, z, flip) in [(0, 0.0, true), (rings, len, false)] {
            let c = m.positions.len() as u32;
            m.positions.push(place.apply(Vec3::new(0.0, 0.0, z)));
            for i in 0..seg {
                let t = if flip { [c, idx(i + 1, j), idx(i, j)] } else { [c, idx(i, j), idx(i + 1, j)] };
                m.indices.push(t);
                m.material.push(mat);
            }
        }
    }
}

/// A cylinder between two points.
pub fn strut(m: &mut TriMesh, a: Vec3, b: Vec3, r: f32, seg: u32, rings: u32, mat: u32) {
    cylinder(m, Place::along(b - a, a), r, r, (b - a).length(), seg, rings, true, mat);
}

/// A paraboloid dish z = ρ²/(4f), aperture `diameter`, opening toward local +Z (normals
/// +Z-ward), as one thin two-sided sheet: `radial` rings × `angular` segments.
pub fn dish(m: &mut TriMesh, place: Place, diameter: f32, focal: f32, radial: u32, angular: u32, mat: u32) {
    let base = m.positions.len() as u32;
    m.positions.push(place.apply(Vec3::ZERO));
    for j in 1..=radial {
        let rho = 0.5 * diameter * j as f32 / radial as f32;
        for i in 0..angular {
            let a = TAU * i as f32 / angular as f32;
            m.positions.push(place.apply(Vec3::new(rho * a.cos(), rho * a.sin(), rho * rho / (4.0 * focal))));
        }
    }
    let ring = |j: u32, i: u32| base + 1 + (j - 1) * angular + i % angular;
    for i in 0..angular {
        m.indices.push([base, ring(1, i), ring(1, i + 1)]);
        m.material.push(mat);
    }
    for j in 1..radial {
        for i in 0..angular {
            m.indices.push([ring(j, i), ring(j + 1, i), ring(j + 1, i + 1)]);
            m.indices.push([ring(j, i), ring(j + 1, i + 1), ring(j, i + 1)]);
            m.material.extend([mat, mat]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn edge_uses(m: &TriMesh) -> HashMap<(u32, u32), u32> {
        let mut e = HashMap::new();
        for t in &m.indices {
            for k in 0..3 {
                let (p, q) = (t[k], t[(k + 1) % 3]);
                *e.entry((p.min(q), p.max(q))).or_insert(0) += 1;
            }
        }
        e
    }

    #[test]
    fn capped_cylinder_is_closed_and_outward() {
        let mut m = TriMesh::default();
        cylinder(&mut m, Place::at(Vec3::ZERO), 0.5, 0.3, 2.0, 24, 5, true, 0);
        assert!(edge_uses(&m).values().all(|&c| c == 2));
        // Outward: the signed volume (divergence theorem) is positive and matches the
        // frustum's, up to the polygon's inscribed-area factor.
        let vol: f32 = (0..m.indices.len())
            .map(|i| {
                let [a, b, c] = m.triangle(i);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        let poly = 24.0 / (2.0 * std::f32::consts::PI) * (TAU / 24.0).sin();
        let exact = std::f32::consts::PI / 3.0 * 2.0 * (0.25 + 0.15 + 0.09) * poly;
        assert!((vol - exact).abs() < 1e-4 * exact.abs().max(1.0), "{vol} vs {exact}");
    }

    #[test]
    fn dish_faces_its_opening_and_lies_on_the_paraboloid() {
        let mut m = TriMesh::default();
        dish(&mut m, Place::at(Vec3::ZERO), 1.2, 0.45, 10, 32, 0);
        for i in 0..m.indices.len() {
            assert!(m.face_normal_area2(i).z > 0.0, "triangle {i}");
        }
        for p in &m.positions {
            let rho2 = p.x * p.x + p.y * p.y;
            assert!((p.z - rho2 / 1.8).abs() < 1e-6);
        }
        assert_eq!(m.indices.len(), 32 + 2 * 9 * 32);
    }

    #[test]
    fn cuboid_is_closed_with_outward_faces() {
        let mut m = TriMesh::default();
        cuboid(&mut m, Place::at(Vec3::new(1.0, 2.0, 3.0)), Vec3::new(0.1, 0.2, 0.3), |f| f as u32);
        assert!(edge_uses(&m).values().all(|&c| c == 2));
        for i in 0..12 {
            let [a, ..] = m.triangle(i);
            let n = m.face_normal_area2(i);
            assert!(n.dot(a - Vec3::new(1.0, 2.0, 3.0)) > 0.0);
        }
    }
}
