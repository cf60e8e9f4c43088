//! Procedural models shipped with hilcam (built from primitives, written as OBJ + MTL).
//!
//! - [`prims`]: tessellated primitives (quad grids, cylinders, paraboloid dishes).
//! - [`satellite`]: the Jason-like satellite of the shipped scenes.

pub mod prims;
pub mod satellite;
