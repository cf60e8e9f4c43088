//! An indexed triangle mesh in one frame (the target body frame once a scene is loaded).

use glam::Vec3;

/// Triangles sharing a vertex array; `material[i]` is the scene material index of triangle `i`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
    pub material: Vec<u32>,
}

impl TriMesh {
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Geometric normal of triangle `i` (right-handed winding), unnormalised: its length is
    /// twice the area.
    pub fn face_normal_area2(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.triangle(i);
        (b - a).cross(c - a)
    }

    /// Append another mesh, keeping its material indices.
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.indices.extend(other.indices.iter().map(|t| t.map(|i| i + base)));
        self.material.extend_from_slice(&other.material);
    }
}
