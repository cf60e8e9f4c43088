//! A shaded orthographic preview of a fold plane (a documentation image, not a render).
//!
//! Looks down −X at the YZ plane; each triangle is flat-shaded by a grazing light so that
//! crease flanks show as light/dark bands.

use super::FoldError;
use crate::geometry::TriMesh;
use glam::{DVec3, Vec2};

/// Write a `size`×`size` 8-bit PNG of `mesh` seen along −X, covering y, z ∈ [−1.05, 1.05].
pub fn preview_png(mesh: &TriMesh, size: u32, path: &std::path::Path) -> Result<(), FoldError> {
    let light = DVec3::new(1.0, -0.6, 0.5).normalize();
    let mut img = image::GrayImage::from_pixel(size, size, image::Luma([0]));
    let half = 1.05f32;
    let to_px = |y: f32, z: f32| {
        Vec2::new((y + half) / (2.0 * half) * size as f32, (half - z) / (2.0 * half) * size as f32)
    };
    for (i, t) in mesh.indices.iter().enumerate() {
        let n = super::measure::normal_f64(mesh, i).normalize_or_zero();
        let shade = (0.15 + 0.85 * n.dot(light).max(0.0)).min(1.0);
        let v = (255.0 * shade) as u8;
        let p = t.map(|k| {
            let q = mesh.positions[k as usize];
            to_px(q.y, q.z)
        });
        let lo = p[0].min(p[1]).min(p[2]).floor().max(Vec2::ZERO);
        let hi = p[0].max(p[1]).max(p[2]).ceil().min(Vec2::splat(size as f32 - 1.0));
        let edge = |a: Vec2, b: Vec2, c: Vec2| (b - a).perp_dot(c - a);
        let area = edge(p[0], p[1], p[2]);
        if area == 0.0 {
            continue;
        }
        for y in lo.y as u32..=hi.y as u32 {
            for x in lo.x as u32..=hi.x as u32 {
                let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let w = [edge(p[1], p[2], c), edge(p[2], p[0], c), edge(p[0], p[1], c)];
                if w.iter().all(|&w| w * area >= 0.0) {
                    img.put_pixel(x, y, image::Luma([v]));
                }
            }
        }
    }
    img.save(path).map_err(|source| FoldError::Png { path: path.display().to_string(), source })
}
