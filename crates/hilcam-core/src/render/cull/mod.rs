//! Pixel culling: which pixels, and which camera samples, can see the target at all. The
//! rest keep the background without a sample being generated, so a frame costs in
//! proportion to the pixels the target covers. Every rule here is conservative: a pixel it
//! drops could not have seen a triangle.
//!
//! - `silhouette`: per row, the columns whose pixel area meets the image of the target's
//!   bounding sphere and box (pinhole, solved exactly per row).
//! - `lens_spans`: the same spans through a distorting lens (the bent boundaries sampled
//!   and rasterised).
//! - `coverage`: per pixel, whether any triangle (or, when primary rays are traced, any
//!   BVH leaf box) projects onto it.
//! - `lens_coverage`: carries those marks from the ideal image plane through the lens to
//!   the real pixels.
//! - `visibility`: the primary hits themselves, by rasterising the triangles (exact for
//!   the sample positions used); it marks `coverage` as it bins.

pub mod coverage;
mod ideal_plane;
mod lens_coverage;
mod lens_spans;
pub mod silhouette;
pub mod visibility;

pub use silhouette::{Silhouette, SilhouetteBuffers};
