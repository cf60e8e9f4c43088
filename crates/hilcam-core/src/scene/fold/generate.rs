//! A fold plane at a paper level (or any target) for a seed.

use super::disk::reference_disk;
use super::fit::{FitReport, PlaneSampler, fit_params};
use super::measure::{FoldStats, measure};
use super::{FoldError, FoldParams, FoldTarget};
use crate::render::geometry::TriMesh;
use glam::{DVec2, DVec3};

/// A generated fold plane: the mesh, the fitted parameters and its measured statistics.
#[derive(Clone, Debug)]
pub struct FoldPlane {
    pub mesh: TriMesh,
    pub fit: FitReport,
    /// Measured on `mesh` itself (f32 positions), against +X.
    pub stats: FoldStats,
}

/// Plane coordinates of the YZ plane: (y, z).
pub fn yz(p: DVec3) -> DVec2 {
    DVec2::new(p.y, p.z)
}

/// Fit fold parameters for `target` on the reference disk with `seed`, and return the
/// folded disk. Heights displace along +X; the disk's rim is folded too (it is free film).
///
/// # Errors
/// See [`fit_params`].
pub fn generate_plane(target: FoldTarget, seed: u64) -> Result<FoldPlane, FoldError> {
    let base = reference_disk();
    let shape = FoldParams::new(1.0, 1.0);
    let sampler = PlaneSampler::new(&base, DVec3::X, yz, shape, seed)?;
    let fit = fit_params(&sampler, shape, target, seed)?;
    let mesh = sampler.displaced(&sampler.heights(fit.params.slope, fit.params.density));
    let stats = measure(&mesh, DVec3::X)?;
    tracing::info!(
        seed,
        slope = fit.params.slope,
        density = fit.params.density,
        iterations = fit.iterations,
        e_plane = stats.e_plane,
        var = stats.var,
        "fold plane fitted"
    );
    Ok(FoldPlane { mesh, fit, stats })
}

/// Side of the square reference panel used by [`fit_for_edge`] (m).
pub const PANEL_SIDE_M: f32 = 2.0;

/// Triangles [`fit_for_edge`]'s test panel (two right triangles, `PANEL_SIDE_M` legs)
/// becomes at `edge_m` (as [`super::wrap::wrap_triangle_estimate`]).
pub fn fit_panel_triangle_estimate(edge_m: f32) -> f64 {
    let n = (f64::from(PANEL_SIDE_M) * std::f64::consts::SQRT_2 / f64::from(edge_m)).ceil().max(1.0);
    2.0 * n * n
}

/// Fit fold parameters for `target` at the resolution [`super::wrap_faces`] will use:
/// on a flat `PANEL_SIDE_M` square in the YZ plane (two triangles), subdivided exactly as
/// `wrap_faces` subdivides it at `edge_m`. The crease tents are only a few edges wide,
/// so the statistics of fixed parameters drift with the edge length (medium fitted on the
/// disk reads 0.9651 / 0.0090 at 1 cm, 0.9716 / 0.0056 at 3 cm); this removes the drift.
///
/// # Errors
/// See [`fit_params`]; `InvalidParam` for a non-positive `edge_m`, or one so small that
/// the panel would exceed [`super::wrap::MAX_WRAP_TRIANGLES`].
pub fn fit_for_edge(target: FoldTarget, seed: u64, edge_m: f32) -> Result<FitReport, FoldError> {
    if !(edge_m.is_finite() && edge_m > 0.0) {
        return Err(FoldError::InvalidParam {
            field: "edge_m",
            value: f64::from(edge_m),
            why: "must be finite and > 0",
        });
    }
    if fit_panel_triangle_estimate(edge_m) > super::wrap::MAX_WRAP_TRIANGLES as f64 {
        return Err(FoldError::InvalidParam {
            field: "edge_m",
            value: f64::from(edge_m),
            why: "would subdivide the fit panel into more triangles than MAX_WRAP_TRIANGLES",
        });
    }
    let h = 0.5 * PANEL_SIDE_M;
    let panel = TriMesh {
        positions: vec![
            glam::Vec3::new(0.0, -h, -h),
            glam::Vec3::new(0.0, h, -h),
            glam::Vec3::new(0.0, h, h),
            glam::Vec3::new(0.0, -h, h),
        ],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material: vec![0, 0],
    };
    let shape = FoldParams::new(0.0, 0.0);
    let flat = super::wrap_faces(&panel, &[0], &shape, seed, edge_m);
    let sampler = PlaneSampler::new(&flat, DVec3::X, yz, shape, seed)?;
    fit_params(&sampler, shape, target, seed)
}
