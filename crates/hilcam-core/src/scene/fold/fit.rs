//! Fitting the two fold knobs (`slope`, `density`) to a target (`E_PLANE`, `Var`).
//!
//! `E_PLANE` and `Var` are two constraints, so two knobs: `slope` mostly sets *how
//! tilted* a crease flank is (the ratio Var/(1−E_PLANE)), `density` mostly sets *how much*
//! of the surface is creased (1−E_PLANE at a given tilt). The fit is a damped Newton
//! iteration on the statistics measured on the actual mesh for the actual seed, with a
//! forward-difference Jacobian, in (ln slope, density). It is deterministic: same mesh,
//! seed and target give the same parameters, bit for bit.
//!
//! For speed, each vertex's crease shapes are computed once ([`PlaneSampler`]); a trial
//! (slope, density) then costs one sparse sum per vertex plus one normal per triangle.

use super::field::{FoldField, FoldParams, crease_at, weight};
use super::{FoldError, FoldTarget};
use crate::render::geometry::TriMesh;
use glam::{DVec2, DVec3};

/// Statistics are fitted to within these (10× tighter than the brief's ±0.002 / ±0.001).
pub const TOL_E: f64 = 2e-4;
pub const TOL_VAR: f64 = 1e-4;
const MAX_ITER: u32 = 60;

/// Precomputed crease shapes at the vertices of a flat mesh lying in a plane.
pub struct PlaneSampler<'a> {
    base: &'a TriMesh,
    normal: DVec3,
    /// Per crease: (rank, signed amplitude).
    creases: Vec<(f64, f64)>,
    /// CSR over vertices: `offsets[v]..offsets[v+1]` index `entries` = (crease, shape).
    offsets: Vec<usize>,
    entries: Vec<(u32, f64)>,
}

impl<'a> PlaneSampler<'a> {
    /// `to_plane` maps a vertex position to plane coordinates (m); `normal` is the unit
    /// direction heights displace along. `shape_params` supplies width, spacing and
    /// anisotropy (its slope and density are ignored).
    pub fn new(
        base: &'a TriMesh,
        normal: DVec3,
        to_plane: impl Fn(DVec3) -> DVec2,
        shape_params: FoldParams,
        seed: u64,
    ) -> Result<Self, FoldError> {
        let field = FoldField::new(FoldParams { slope: 1.0, density: 1.0, ..shape_params }, seed)?;
        let mut index = std::collections::HashMap::new();
        let mut creases = Vec::new();
        let mut offsets = vec![0];
        let mut entries = Vec::new();
        for p in &base.positions {
            let q = to_plane(p.as_dvec3());
            let (i0, i1, j0, j1) = field.cell_range(q);
            for i in i0..=i1 {
                for j in j0..=j1 {
                    let c = crease_at(seed, field.theta0, &field.params, i, j);
                    let s = c.shape(q, field.params.width_m);
                    if s != 0.0 {
                        let id = *index.entry((i, j)).or_insert_with(|| {
                            creases.push((c.rank, c.amp));
                            creases.len() as u32 - 1
                        });
                        entries.push((id, s));
                    }
                }
            }
            offsets.push(entries.len());
        }
        Ok(PlaneSampler { base, normal: normal.normalize(), creases, offsets, entries })
    }

    /// Vertex heights for (slope, density), identical to `FoldField::height`.
    pub fn heights(&self, slope: f64, density: f64) -> Vec<f64> {
        let w: Vec<f64> = self.creases.iter().map(|&(rank, amp)| weight(density, rank) * amp).collect();
        (0..self.base.positions.len())
            .map(|v| {
                let e = &self.entries[self.offsets[v]..self.offsets[v + 1]];
                // Same summation order as FoldField::height (cells in i, then j order).
                slope * e.iter().map(|&(c, s)| w[c as usize] * s).sum::<f64>()
            })
            .collect()
    }

    /// The base mesh displaced by heights along the normal (f32 positions).
    pub fn displaced(&self, heights: &[f64]) -> TriMesh {
        let positions =
            self.base.positions.iter().zip(heights).map(|(p, &h)| (p.as_dvec3() + self.normal * h).as_vec3()).collect();
        TriMesh { positions, ..self.base.clone() }
    }

    /// (E_PLANE, Var) of the displaced mesh, computed in f64 without building it.
    pub fn stats(&self, slope: f64, density: f64) -> (f64, f64) {
        let h = self.heights(slope, density);
        let pos = |v: u32| self.base.positions[v as usize].as_dvec3() + self.normal * h[v as usize];
        let cos: Vec<f64> = self
            .base
            .indices
            .iter()
            .map(|&[a, b, c]| {
                let (pa, pb, pc) = (pos(a), pos(b), pos(c));
                let n = (pb - pa).cross(pc - pa);
                n.dot(self.normal) / n.length()
            })
            .collect();
        super::measure::mean_var(&cos)
    }
}

/// The outcome of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    pub params: FoldParams,
    pub e_plane: f64,
    pub var: f64,
    pub iterations: u32,
}

/// Check that a target is one a height field can have: the cosines lie in (0, 1], so
/// 0 < Var < E·(1 − E).
pub fn check_target(t: FoldTarget) -> Result<(), FoldError> {
    let ok = t.e_plane > 0.0 && t.e_plane < 1.0 && t.var > 0.0 && t.var < t.e_plane * (1.0 - t.e_plane);
    if ok { Ok(()) } else { Err(FoldError::InfeasibleTarget { e_plane: t.e_plane, var: t.var }) }
}

/// Fit (slope, density) so that the sampler's displaced mesh has the target statistics.
///
/// # Errors
/// [`FoldError::InfeasibleTarget`] for impossible targets, [`FoldError::FitFailed`]
/// (with the best statistics reached) when the iteration does not converge.
pub fn fit_params(
    sampler: &PlaneSampler,
    shape_params: FoldParams,
    target: FoldTarget,
    seed: u64,
) -> Result<FitReport, FoldError> {
    check_target(target)?;
    // Residuals scaled by the tolerances so both constraints weigh alike.
    let resid = |x: [f64; 2]| {
        let (e, v) = sampler.stats(x[0].exp(), x[1]);
        ([(e - target.e_plane) / TOL_E, (v - target.var) / TOL_VAR], e, v)
    };
    let norm = |r: [f64; 2]| r[0].hypot(r[1]);
    let clamp = |x: [f64; 2]| [x[0].clamp(0.05f64.ln(), 10f64.ln()), x[1].clamp(0.0, 1.0 + super::field::FADE)];

    // Start from a two-point model: a share p of triangles tilted to cosine c0, the rest
    // flat, gives Var/(1−E) + (1−E) ≈ 1 − c0 and p ≈ (1−E)/(1−c0).
    let one_m_e = 1.0 - target.e_plane;
    let q = (target.var / one_m_e + one_m_e).clamp(0.02, 0.9);
    let slope0 = (1.0 - q).acos().tan();
    let density0 = (2.5 * one_m_e / q).clamp(0.02, 1.0);
    let mut x = clamp([slope0.ln(), density0]);
    let (mut r, mut e, mut v) = resid(x);
    let mut iterations = 0;
    while iterations < MAX_ITER && (r[0].abs() > 0.1 || r[1].abs() > 0.1) {
        iterations += 1;
        // Forward-difference Jacobian.
        let h = [1e-3, 4e-3];
        let mut jac = [[0.0; 2]; 2];
        for k in 0..2 {
            let mut xk = x;
            xk[k] += h[k];
            let (rk, _, _) = resid(xk);
            for i in 0..2 {
                jac[i][k] = (rk[i] - r[i]) / h[k];
            }
        }
        let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
        let step = if det.abs() > 1e-12 {
            [-(jac[1][1] * r[0] - jac[0][1] * r[1]) / det, -(-jac[1][0] * r[0] + jac[0][0] * r[1]) / det]
        } else {
            // Singular (e.g. no crease present yet): grow density.
            [0.0, 0.05]
        };
        // Damped: halve the step until the residual norm drops.
        let mut lambda = 1.0;
        let mut accepted = false;
        for _ in 0..12 {
            let xn = clamp([x[0] + lambda * step[0], x[1] + lambda * step[1]]);
            let (rn, en, vn) = resid(xn);
            if norm(rn) < norm(r) {
                (x, r, e, v) = (xn, rn, en, vn);
                accepted = true;
                break;
            }
            lambda *= 0.5;
        }
        // Newton failed to descend (a kink where creases fade in, or a poor start):
        // Levenberg–Marquardt steps, (JᵀJ + μ·diag JᵀJ) δ = −Jᵀr, with growing μ.
        if !accepted {
            let a = [
                jac[0][0] * jac[0][0] + jac[1][0] * jac[1][0],
                jac[0][0] * jac[0][1] + jac[1][0] * jac[1][1],
                jac[0][1] * jac[0][1] + jac[1][1] * jac[1][1],
            ];
            let g = [jac[0][0] * r[0] + jac[1][0] * r[1], jac[0][1] * r[0] + jac[1][1] * r[1]];
            for mu in [1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3, 1e4] {
                let (d0, d1) = (a[0] * (1.0 + mu), a[2] * (1.0 + mu));
                let det = d0 * d1 - a[1] * a[1];
                if det.abs() < 1e-300 {
                    continue;
                }
                let dx = [-(d1 * g[0] - a[1] * g[1]) / det, -(d0 * g[1] - a[1] * g[0]) / det];
                let xn = clamp([x[0] + dx[0], x[1] + dx[1]]);
                let (rn, en, vn) = resid(xn);
                if norm(rn) < norm(r) {
                    (x, r, e, v) = (xn, rn, en, vn);
                    accepted = true;
                    break;
                }
            }
        }
        tracing::debug!(iterations, slope = x[0].exp(), density = x[1], e, v, "fold fit step");
        if !accepted {
            break;
        }
    }
    let params = FoldParams { slope: x[0].exp(), density: x[1], ..shape_params };
    if r[0].abs() > 1.0 || r[1].abs() > 1.0 {
        return Err(FoldError::FitFailed {
            seed,
            target_e: target.e_plane,
            target_var: target.var,
            best_e: e,
            best_var: v,
            iterations,
        });
    }
    Ok(FitReport { params, e_plane: e, var: v, iterations })
}
