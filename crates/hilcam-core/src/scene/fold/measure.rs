//! Fold statistics of a mesh: `E_PLANE`, `Var`, and the normal-angle histogram.
//!
//! Following the paper (§3.1), `E_PLANE` is the plain mean over triangles of
//! `cos θ = n̂_tri · n̂_plane`, **not** area-weighted, and `Var` is the population variance
//! of the same cosines (divide by T). The cosine is signed: a triangle facing away from
//! the plane normal counts negative. Degenerate (zero-area or non-finite) triangles have
//! no normal; they are counted and left out of the statistics.

use super::FoldError;
use crate::render::geometry::TriMesh;
use glam::DVec3;

/// Number of histogram bins over the normal angle 0°..90° (5° each); the last bin also
/// collects angles above 90°.
pub const HIST_BINS: usize = 18;

/// Statistics of the triangle normals of a mesh relative to a plane normal.
#[derive(Clone, Debug, PartialEq)]
pub struct FoldStats {
    /// Mean cosine between triangle normals and the plane normal.
    pub e_plane: f64,
    /// Population variance of that cosine.
    pub var: f64,
    /// Triangles measured (non-degenerate).
    pub triangles: usize,
    /// Triangles skipped because their normal is undefined.
    pub degenerate: usize,
    /// Counts of triangles by normal angle, 5° bins from 0°.
    pub histogram: [usize; HIST_BINS],
    /// Largest normal angle (degrees).
    pub max_angle_deg: f64,
}

/// Twice-area normal of triangle `i` in f64 (f32 cross products lose digits on fine meshes).
pub fn normal_f64(mesh: &TriMesh, i: usize) -> DVec3 {
    let [a, b, c] = mesh.triangle(i).map(|p| p.as_dvec3());
    (b - a).cross(c - a)
}

/// Cosines of all non-degenerate triangles' normals with `normal`, and the degenerate count.
pub fn cosines(mesh: &TriMesh, normal: DVec3) -> (Vec<f64>, usize) {
    let n = normal.normalize();
    let mut out = Vec::with_capacity(mesh.indices.len());
    let mut degenerate = 0;
    for i in 0..mesh.indices.len() {
        let m = normal_f64(mesh, i);
        let len = m.length();
        if len > 0.0 && len.is_finite() {
            out.push(m.dot(n) / len);
        } else {
            degenerate += 1;
        }
    }
    (out, degenerate)
}

/// Mean and population variance of a slice (two-pass, exact enough for 10⁶ values).
pub fn mean_var(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    (mean, var)
}

/// Measure a mesh against the plane normal `normal` (need not be unit).
///
/// # Errors
/// [`FoldError::EmptyMesh`] when no triangle has a defined normal.
pub fn measure(mesh: &TriMesh, normal: DVec3) -> Result<FoldStats, FoldError> {
    let (cos, degenerate) = cosines(mesh, normal);
    if cos.is_empty() {
        return Err(FoldError::EmptyMesh);
    }
    if degenerate > 0 {
        tracing::warn!(degenerate, "fold measure: skipped triangles without a normal");
    }
    let (e_plane, var) = mean_var(&cos);
    let mut histogram = [0; HIST_BINS];
    let mut max_angle_deg: f64 = 0.0;
    for c in &cos {
        let deg = c.clamp(-1.0, 1.0).acos().to_degrees();
        max_angle_deg = max_angle_deg.max(deg);
        histogram[((deg / 5.0) as usize).min(HIST_BINS - 1)] += 1;
    }
    Ok(FoldStats { e_plane, var, triangles: cos.len(), degenerate, histogram, max_angle_deg })
}

impl FoldStats {
    /// A text report: the statistics and a bar chart of the angle histogram.
    pub fn report(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "E_PLANE    {:.4}", self.e_plane);
        let _ = writeln!(s, "Var        {:.4}", self.var);
        let _ = writeln!(s, "triangles  {}", self.triangles);
        if self.degenerate > 0 {
            let _ = writeln!(s, "degenerate {} (skipped)", self.degenerate);
        }
        let _ = writeln!(s, "max angle  {:.1}°", self.max_angle_deg);
        let _ = writeln!(s, "normal angle histogram (share of triangles):");
        let total = self.triangles as f64;
        for (b, &count) in self.histogram.iter().enumerate() {
            let share = count as f64 / total;
            let bar = "#".repeat((share * 60.0).round() as usize);
            let label = if b + 1 == HIST_BINS {
                format!("{:>3}°+    ", 5 * b)
            } else {
                format!("{:>3}–{:<3}°", 5 * b, 5 * (b + 1))
            };
            let _ = writeln!(s, "  {label} {:>7} {:>6.2}% {bar}", count, 100.0 * share);
        }
        s
    }

    /// The histogram as a bar-chart PNG, `HIST_BINS` bars, heights ∝ sqrt(count).
    pub fn histogram_png(&self, path: &std::path::Path) -> Result<(), FoldError> {
        let (bar_w, h) = (24u32, 200u32);
        let w = bar_w * HIST_BINS as u32;
        let max = *self.histogram.iter().max().unwrap_or(&1) as f64;
        let mut img = image::GrayImage::from_pixel(w, h, image::Luma([255]));
        for (b, &count) in self.histogram.iter().enumerate() {
            // sqrt scale so the tail bins stay visible next to the near-flat majority.
            let bar = ((count as f64 / max).sqrt() * f64::from(h - 4)) as u32;
            for x in b as u32 * bar_w + 2..(b as u32 + 1) * bar_w - 2 {
                for y in h - bar..h {
                    img.put_pixel(x, y, image::Luma([40]));
                }
            }
        }
        img.save(path).map_err(|source| FoldError::Png { path: path.display().to_string(), source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn tilted_triangle_has_its_cosine() {
        let a = 0.3f32;
        let mesh = TriMesh {
            positions: vec![Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), Vec3::new(a.tan(), 0.0, 1.0)],
            indices: vec![[0, 1, 2]],
            material: vec![0],
        };
        let s = measure(&mesh, DVec3::X).unwrap();
        assert!((s.e_plane - f64::from(a).cos()).abs() < 1e-6, "{}", s.e_plane);
        assert_eq!(s.var, 0.0);
    }

    #[test]
    fn degenerate_triangles_are_counted_not_averaged() {
        let mesh = TriMesh {
            positions: vec![Vec3::ZERO, Vec3::Y, Vec3::Z, Vec3::Y * 2.0],
            indices: vec![[0, 1, 2], [0, 1, 3]],
            material: vec![0, 0],
        };
        let s = measure(&mesh, DVec3::X).unwrap();
        assert_eq!((s.triangles, s.degenerate), (1, 1));
        assert_eq!(s.e_plane, 1.0);
    }

    #[test]
    fn plain_mean_is_not_area_weighted() {
        // One big flat triangle and one small one tilted 60°: plain mean = (1 + 0.5)/2.
        let t = 60f32.to_radians().tan();
        let mesh = TriMesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::new(0.0, 10.0, 0.0),
                Vec3::new(0.0, 0.0, 10.0),
                Vec3::new(0.0, 20.0, 0.0),
                Vec3::new(0.0, 21.0, 0.0),
                Vec3::new(t, 20.0, 1.0),
            ],
            indices: vec![[0, 1, 2], [3, 4, 5]],
            material: vec![0, 0],
        };
        let s = measure(&mesh, DVec3::X).unwrap();
        assert!((s.e_plane - 0.75).abs() < 1e-6, "{}", s.e_plane);
        assert!((s.var - 0.0625).abs() < 1e-6, "{}", s.var);
    }
}
