//! Fold surfaces: wrinkled multilayer-insulation (MLI) film, generated, measured and
//! wrapped onto meshes.
//!
//! The paper (Sun & Ding 2023, §3.1) quantifies a fold surface by `E_PLANE`, the plain
//! mean over triangles of the cosine between each triangle's normal and the plane
//! normal, and `Var`, the variance of that cosine. Its three reference levels are
//! slight 0.9803 / 0.0046, medium 0.9680 / 0.0077 and severe 0.9435 / 0.0124.
//!
//! - [`disk`]: the reference 1 m-radius circular plane (YZ plane, normal +X).
//! - [`field`]: the fold height field (sparse creases on a jittered grid).
//! - [`measure`]: `E_PLANE`, `Var` and the normal-angle histogram of a mesh.
//! - [`fit`]: the deterministic 2-D Newton fit of (slope, density) to a target.
//! - [`generate`]: a fold plane at a level (or any target) for a seed.
//! - [`wrap`]: folds applied to the faces of a [`crate::render::geometry::TriMesh`] by material.
//!
//! Writing planes to OBJ files and preview pictures is the lab's (`hilcam-lab`: `obj`,
//! `preview`).

pub mod disk;
pub mod field;
pub mod fit;
pub mod generate;
pub mod measure;
pub mod wrap;

pub use field::{FoldField, FoldParams};
pub use fit::{FitReport, fit_params};
pub use generate::{FoldPlane, fit_for_edge, fit_panel_triangle_estimate, generate_plane};
pub use measure::{FoldStats, measure};
pub use wrap::{MAX_WRAP_TRIANGLES, WrapReport, wrap_faces, wrap_faces_report, wrap_triangle_estimate};

use std::str::FromStr;

/// A fold-statistics target: `E_PLANE` (mean cosine) and `Var` (its variance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FoldTarget {
    pub e_plane: f64,
    pub var: f64,
}

/// The paper's three fold levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FoldLevel {
    Slight,
    Medium,
    Severe,
}

impl FoldLevel {
    pub const ALL: [FoldLevel; 3] = [FoldLevel::Slight, FoldLevel::Medium, FoldLevel::Severe];

    /// The paper's `E_PLANE` and `Var` for this level (§3.1, Fig. 4).
    pub fn target(self) -> FoldTarget {
        match self {
            FoldLevel::Slight => FoldTarget { e_plane: 0.9803, var: 0.0046 },
            FoldLevel::Medium => FoldTarget { e_plane: 0.9680, var: 0.0077 },
            FoldLevel::Severe => FoldTarget { e_plane: 0.9435, var: 0.0124 },
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            FoldLevel::Slight => "slight",
            FoldLevel::Medium => "medium",
            FoldLevel::Severe => "severe",
        }
    }
}

impl FromStr for FoldLevel {
    type Err = FoldError;
    fn from_str(s: &str) -> Result<Self, FoldError> {
        match s.to_ascii_lowercase().as_str() {
            "slight" => Ok(FoldLevel::Slight),
            "medium" => Ok(FoldLevel::Medium),
            "severe" => Ok(FoldLevel::Severe),
            _ => Err(FoldError::UnknownLevel(s.to_string())),
        }
    }
}

/// Errors of the fold module.
#[derive(Debug, thiserror::Error)]
pub enum FoldError {
    #[error("unknown fold level {0:?} (expected slight, medium or severe)")]
    UnknownLevel(String),
    #[error(
        "fold target E_PLANE={e_plane}, Var={var} is outside what a height field can have \
         (need 0 < E_PLANE < 1 and 0 < Var < E_PLANE·(1−E_PLANE))"
    )]
    InfeasibleTarget { e_plane: f64, var: f64 },
    #[error(
        "fold fit did not reach E_PLANE={target_e}, Var={target_var} for seed {seed}: \
         best E_PLANE={best_e:.5}, Var={best_var:.5} after {iterations} iterations"
    )]
    FitFailed { seed: u64, target_e: f64, target_var: f64, best_e: f64, best_var: f64, iterations: u32 },
    #[error("invalid fold parameter {field} = {value}: {why}")]
    InvalidParam { field: &'static str, value: f64, why: &'static str },
    #[error("mesh has no triangles to measure")]
    EmptyMesh,
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot load OBJ: {source}")]
    Obj {
        path: String,
        #[source]
        source: tobj::LoadError,
    },
    #[error("{path}: cannot write PNG: {source}")]
    Png {
        path: String,
        #[source]
        source: image::ImageError,
    },
}
