//! Shaded orthographic previews (documentation images, not renders).
//!
//! Flat-shaded triangles (two-sided, a fixed light) with a z-buffer, so that crease
//! flanks show as light/dark bands.

use glam::Vec3;
use hilcam_core::render::geometry::TriMesh;
use hilcam_core::scene::fold::FoldError;

/// An orthographic view: looking along `dir` with `up` roughly up, `half` metres from the
/// centre to the image edge.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub dir: Vec3,
    pub up: Vec3,
    pub centre: Vec3,
    pub half: f32,
    /// Direction toward the light.
    pub light: Vec3,
}

impl View {
    /// The fold plane seen from +X (looking down −X), grazing light.
    pub fn fold_plane() -> Self {
        View {
            dir: -Vec3::X,
            up: Vec3::Z,
            centre: Vec3::ZERO,
            half: 1.05,
            light: Vec3::new(1.0, -0.6, 0.5).normalize(),
        }
    }
}

/// Write a `size`×`size` 8-bit PNG of `mesh` seen in `view`. Material `m` is tinted by
/// `albedo[m]` (1.0 when absent).
pub fn preview_view(
    mesh: &TriMesh,
    view: View,
    albedo: &[f32],
    size: u32,
    path: &std::path::Path,
) -> Result<(), FoldError> {
    let d = view.dir.normalize();
    let right = d.cross(view.up).normalize();
    let up = right.cross(d);
    let s = size as f32;
    let to_px = |p: Vec3| {
        let q = p - view.centre;
        Vec3::new((q.dot(right) / view.half + 1.0) * 0.5 * s, (1.0 - q.dot(up) / view.half) * 0.5 * s, q.dot(d))
    };
    let mut depth = vec![f32::INFINITY; (size * size) as usize];
    let mut img = image::GrayImage::from_pixel(size, size, image::Luma([0]));
    for (i, t) in mesh.indices.iter().enumerate() {
        let n = hilcam_core::scene::fold::measure::normal_f64(mesh, i).normalize_or_zero();
        let n = if n.dot(d.as_dvec3()) > 0.0 { -n } else { n }; // two-sided
        let lit = n.dot(view.light.as_dvec3()).max(0.0);
        let a = albedo.get(mesh.material[i] as usize).copied().unwrap_or(1.0);
        let v = (255.0 * (0.12 + 0.88 * lit) * f64::from(a)).min(255.0) as u8;
        let p = t.map(|k| to_px(mesh.positions[k as usize]));
        rasterise(p, size, |x, y, z| {
            let k = (y * size + x) as usize;
            if z < depth[k] {
                depth[k] = z;
                img.put_pixel(x, y, image::Luma([v]));
            }
        });
    }
    img.save(path).map_err(|source| FoldError::Png { path: path.display().to_string(), source })
}

/// Visit pixel centres inside a screen-space triangle with interpolated depth.
fn rasterise(p: [Vec3; 3], size: u32, mut visit: impl FnMut(u32, u32, f32)) {
    let edge = |a: Vec3, b: Vec3, x: f32, y: f32| (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
    let area = edge(p[0], p[1], p[2].x, p[2].y);
    if area == 0.0 {
        return;
    }
    let lo = p[0].min(p[1]).min(p[2]).floor().max(Vec3::ZERO);
    let hi = p[0].max(p[1]).max(p[2]).ceil().min(Vec3::splat(size as f32 - 1.0));
    if lo.x > hi.x || lo.y > hi.y {
        return;
    }
    for y in lo.y as u32..=hi.y as u32 {
        for x in lo.x as u32..=hi.x as u32 {
            let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
            let w = [edge(p[1], p[2], cx, cy), edge(p[2], p[0], cx, cy), edge(p[0], p[1], cx, cy)].map(|w| w / area);
            if w.iter().all(|&w| w >= 0.0) {
                visit(x, y, w[0] * p[0].z + w[1] * p[1].z + w[2] * p[2].z);
            }
        }
    }
}

/// The fold-plane preview used by `hilcam fold generate --preview`.
pub fn preview_png(mesh: &TriMesh, size: u32, path: &std::path::Path) -> Result<(), FoldError> {
    preview_view(mesh, View::fold_plane(), &[], size, path)
}
