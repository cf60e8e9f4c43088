//! A mesh cut into its spatially separate parts (bodies far apart from each other).
//!
//! The render frame is centred on the largest part, and each part keeps its own bounding
//! sphere for the camera rays' start (`render::target`), so a small body far away (debris,
//! a distant vehicle) changes neither the coordinates nor the rays of the others.
//!
//! Rule: a set of triangles is cut in two where, along some axis, an empty gap between
//! their boxes is wider than the larger of the two sides' extents along that axis; each
//! side is cut again the same way. A satellite's panels, booms and MLI patches are never
//! that far apart, so a single body stays one part.

use super::TriMesh;
use glam::DVec3;

/// No more parts than this (further cuts are not made): each costs a sphere test per
/// camera ray.
pub const MAX_PARTS: usize = 16;

/// One part: its triangles (indices into the mesh) and its bounding box (the mesh's
/// frame, f64).
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub triangles: Vec<u32>,
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Part {
    /// Half the diagonal of the box.
    pub fn half_diagonal(&self) -> f64 {
        (self.hi - self.lo).length() * 0.5
    }
}

/// The mesh's parts (one part holding every triangle when nothing is far apart; none for
/// an empty mesh), in a deterministic order.
pub fn split(mesh: &TriMesh) -> Vec<Part> {
    let boxes: Vec<(DVec3, DVec3)> = (0..mesh.indices.len())
        .map(|i| {
            let [a, b, c] = mesh.triangle(i).map(|v| v.as_dvec3());
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    if boxes.is_empty() {
        return Vec::new();
    }
    let mut done = Vec::new();
    let mut todo = vec![(0..boxes.len() as u32).collect::<Vec<u32>>()];
    while let Some(set) = todo.pop() {
        if done.len() + todo.len() + 1 < MAX_PARTS
            && let Some((a, b)) = cut(&set, &boxes)
        {
            todo.push(b);
            todo.push(a);
            continue;
        }
        let (lo, hi) = set.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &t| {
            let (l, h) = boxes[t as usize];
            (lo.min(l), hi.max(h))
        });
        done.push(Part { triangles: set, lo, hi });
    }
    done
}

/// The widest qualifying cut of `set`, if any: the triangles below the gap and above it.
fn cut(set: &[u32], boxes: &[(DVec3, DVec3)]) -> Option<(Vec<u32>, Vec<u32>)> {
    let mut best: Option<(f64, usize, Vec<u32>)> = None;
    for axis in 0..3 {
        let mut order = set.to_vec();
        order
            .sort_unstable_by(|&a, &b| boxes[a as usize].0[axis].total_cmp(&boxes[b as usize].0[axis]).then(a.cmp(&b)));
        let lo = boxes[order[0] as usize].0[axis];
        // Highest box top among the first k triangles, and among the last n − k.
        let mut below = vec![f64::NEG_INFINITY; order.len()];
        let mut top = f64::NEG_INFINITY;
        for (k, &t) in order.iter().enumerate() {
            top = top.max(boxes[t as usize].1[axis]);
            below[k] = top;
        }
        let hi = top;
        for k in 1..order.len() {
            let (left_top, right_bottom) = (below[k - 1], boxes[order[k] as usize].0[axis]);
            let gap = right_bottom - left_top;
            let sides = (left_top - lo).max(hi - right_bottom);
            if gap > sides && best.as_ref().is_none_or(|b| gap > b.0) {
                best = Some((gap, k, order.clone()));
            }
        }
    }
    best.map(|(_, k, mut order)| {
        let above = order.split_off(k);
        (order, above)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn tri_at(m: &mut TriMesh, c: Vec3, s: f32) {
        let base = m.positions.len() as u32;
        m.positions.extend([c, c + Vec3::new(s, 0.0, 0.0), c + Vec3::new(0.0, s, 0.0)]);
        m.indices.push([base, base + 1, base + 2]);
        m.material.push(0);
    }

    /// Neighbouring triangles stay one part; a triangle 1e5 m away is its own.
    #[test]
    fn a_far_triangle_is_its_own_part() {
        let mut m = TriMesh::default();
        for i in 0..10 {
            tri_at(&mut m, Vec3::new(i as f32 * 0.1, 0.0, 0.0), 0.1);
        }
        assert_eq!(split(&m).len(), 1);
        tri_at(&mut m, Vec3::new(1e5, 3.0, -2.0), 1e-3);
        let parts = split(&m);
        assert_eq!(parts.len(), 2, "{parts:?}");
        let near = parts.iter().find(|p| p.triangles.len() == 10).expect("the near part");
        assert_eq!(near.triangles, (0..10).collect::<Vec<u32>>());
        assert_eq!((near.lo, near.hi), (DVec3::ZERO, DVec3::new(1.0, f64::from(0.1f32), 0.0)));
    }

    /// Two bodies whose gap is smaller than the larger body stay one part.
    #[test]
    fn close_bodies_stay_together() {
        let mut m = TriMesh::default();
        tri_at(&mut m, Vec3::ZERO, 2.0);
        tri_at(&mut m, Vec3::new(3.5, 0.0, 0.0), 0.1);
        assert_eq!(split(&m).len(), 1);
    }
}
