//! Random triangle soups for the BVH tests: mixed sizes, slivers, zero-area and
//! axis-aligned triangles.

use glam::Vec3;
use hilcam_core::render::geometry::TriMesh;
use hilcam_core::render::sampling::Rng;

pub fn random_vec(r: &mut Rng, scale: f32) -> Vec3 {
    (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 2.0 - 1.0) * scale
}

/// A soup of `n` triangles in a box of half-size `scale`: mixed sizes, slivers, zero-area
/// triangles, and axis-aligned triangles on a grid (so axis-aligned rays graze edges and
/// vertices and boxes are flat).
pub fn soup(n: usize, scale: f32, seed: u64) -> TriMesh {
    let mut r = Rng::from_state(seed);
    let mut m = TriMesh::default();
    let grid = |r: &mut Rng| ((r.next_f32() * 16.0).floor() - 8.0) * scale / 8.0;
    for i in 0..n {
        let c = random_vec(&mut r, scale);
        let size = scale * if i % 10 == 0 { 0.5 } else { 0.05 };
        let a = c + random_vec(&mut r, size);
        let b = c + random_vec(&mut r, size);
        let d = match i % 7 {
            // Sliver: third vertex almost on the first edge.
            0 => a + (b - a) * 0.5 + random_vec(&mut r, 1e-6 * scale),
            // Zero area: collinear, or a repeated vertex.
            1 if i % 2 == 0 => a + (b - a) * 0.25,
            1 => b,
            _ => c + random_vec(&mut r, size),
        };
        let [a, b, d] = if i % 5 == 0 {
            // Axis-aligned on grid coordinates: constant along one axis.
            let axis = i % 3;
            let level = grid(&mut r);
            let g = |r: &mut Rng| {
                let mut v = Vec3::new(grid(r), grid(r), grid(r));
                v[axis] = level;
                v
            };
            [g(&mut r), g(&mut r), g(&mut r)]
        } else {
            [a, b, d]
        };
        let base = m.positions.len() as u32;
        m.positions.extend([a, b, d]);
        m.indices.push([base, base + 1, base + 2]);
        m.material.push(0);
    }
    m
}

/// A point on triangle `i` (random barycentrics).
pub fn surface_point(m: &TriMesh, i: usize, r: &mut Rng) -> Vec3 {
    let [a, b, c] = m.triangle(i);
    let (mut u, mut v) = (r.next_f32(), r.next_f32());
    if u + v > 1.0 {
        (u, v) = (1.0 - u, 1.0 - v);
    }
    a + (b - a) * u + (c - a) * v
}
