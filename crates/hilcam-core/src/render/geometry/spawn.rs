//! Where a ray leaving a surface (shadow ray, bounce) starts: a function of the hit point
//! and its triangle only, never of the ray that found it or of other geometry.
//!
//! The hit point is first put back on its triangle's plane (`p − n (n·p − d)`), which
//! removes the error of `origin + t·dir` along the normal (it grows with the ray's length
//! and its origin's magnitude). What error is left — the plane's `d = n·v₀`, `n·p`, and the
//! intersection test's own `v₀ − origin` — is a few f32 ulps of the triangle's largest
//! coordinate, so the point is then moved [`OFFSET_ULPS`] of those ulps along the normal on
//! the side the ray leaves from. On a 1 m body centred in the render frame that is ~4 µm.

use super::TriMesh;
use glam::Vec3;

/// The offset in units of `f32::EPSILON × scale` (scale: the triangle's largest vertex
/// coordinate). The error it must exceed is about 15 such units (plane distance, `n·p`,
/// the test's `v₀ − origin` and `ng·c`); 64 leaves a factor of four.
pub const OFFSET_ULPS: f32 = 64.0;

/// Per triangle: its plane's distance from the origin along its unit normal, and its
/// largest vertex coordinate magnitude (both render frame, metres).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TrianglePlane {
    pub d: f32,
    pub scale: f32,
}

impl TrianglePlane {
    /// The plane of triangle `i` of `mesh`, with unit normal `n` (its face normal).
    pub fn of(mesh: &TriMesh, i: usize, n: Vec3) -> Self {
        let [a, b, c] = mesh.triangle(i);
        let scale = a.abs().max(b.abs()).max(c.abs()).max_element();
        TrianglePlane { d: n.dot(a), scale }
    }

    /// The start of a ray leaving point `p` of this triangle (unit face normal `n_face`,
    /// the one `d` was computed with) on the side of `n_out` (`±n_face`, or a normal close
    /// to it).
    #[inline]
    pub fn spawn(&self, p: Vec3, n_face: Vec3, n_out: Vec3) -> Vec3 {
        let on_plane = p - n_face * (n_face.dot(p) - self.d);
        let scale = self.scale.max(on_plane.abs().max_element());
        on_plane + n_out * (OFFSET_ULPS * f32::EPSILON * scale)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point found far off the plane (a long ray's rounding) comes back to it, and
    /// leaves by the offset alone, whatever its error was.
    #[test]
    fn spawn_is_on_the_plane_plus_the_offset() {
        let mesh = TriMesh {
            positions: vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0), Vec3::new(0.0, 1.0, 2.0)],
            indices: vec![[0, 1, 2]],
            material: vec![0],
        };
        let plane = TrianglePlane::of(&mesh, 0, Vec3::Z);
        assert_eq!(plane, TrianglePlane { d: 2.0, scale: 2.0 });
        for err in [-1e-3, 0.0, 1e-3] {
            let o = plane.spawn(Vec3::new(0.25, 0.25, 2.0 + err), Vec3::Z, -Vec3::Z);
            assert_eq!(o.z, 2.0 - OFFSET_ULPS * f32::EPSILON * 2.0, "error {err}");
        }
    }
}
