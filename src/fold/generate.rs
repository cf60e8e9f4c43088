//! A fold plane at a paper level (or any target) for a seed.

use super::disk::reference_disk;
use super::fit::{FitReport, PlaneSampler, fit_params};
use super::measure::{FoldStats, measure};
use super::{FoldError, FoldParams, FoldTarget};
use crate::geometry::TriMesh;
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
