//! A Jason-like satellite (the paper's Jason-1 scene), built procedurally.
//!
//! Body frame: origin at the bus centre, +Z along the bus's long axis (toward the
//! instrument deck and altimeter dish), +X the side the solar cells face, +Y along the
//! +Y solar wing. Metres.
//!
//! - Bus: 1.0 × 1.0 × 1.5 m box. Sides and bottom wrapped in gold polyimide MLI
//!   (`mli_gold`, folded at a fold level), a flush radiator window (`white_paint`) on −X,
//!   and the +Z instrument deck in `white_paint`.
//! - Solar wings: a metal boom from each ±Y face, then four 0.8 × 1.4 m panels per wing
//!   (cells `solar_cell` on +X, everything else `array_back`), 9.5 m tip to tip. With
//!   the sun low over ±Y from +X, the wings shade the −X half of the ±Y bus faces.
//! - Altimeter dish: a 1.2 m paraboloid (`antenna`) on a metal pedestal above the deck,
//!   a feed at its focus on three metal struts; a DORIS-like mast and a launch-adapter
//!   ring (`metal`) below the bus.

use super::prims::{Place, cuboid, cylinder, dish, strut};
use crate::obj::MtlEntry;
use glam::Vec3;
use hilcam_core::render::geometry::TriMesh;
use hilcam_core::scene::fold::{FoldError, FoldParams, wrap_faces_report};

pub const MLI_GOLD: u32 = 0;
pub const WHITE_PAINT: u32 = 1;
pub const SOLAR_CELL: u32 = 2;
pub const ARRAY_BACK: u32 = 3;
pub const ANTENNA: u32 = 4;
pub const METAL: u32 = 5;
/// Material names, indexed by the constants above.
pub const MATERIALS: [&str; 6] = ["mli_gold", "white_paint", "solar_cell", "array_back", "antenna", "metal"];

/// Bus half extents (m).
pub const BUS_HALF: Vec3 = Vec3::new(0.5, 0.5, 0.75);

/// Materials for the MTL (viewer colours; the scene assigns BRDFs by name).
pub fn mtl_entries() -> Vec<MtlEntry> {
    let e = |name: &str, kd: [f32; 3], comment: &str| MtlEntry { name: name.into(), kd, comment: comment.into() };
    vec![
        e("mli_gold", [0.80, 0.62, 0.25], "gold polyimide MLI (paper: improved Blinn-Phong)"),
        e("white_paint", [0.522, 0.522, 0.522], "white thermal paint (paper: Lambert, rho = 0.522)"),
        e("solar_cell", [0.05, 0.07, 0.18], "solar cells (front of the array panels)"),
        e("array_back", [0.35, 0.35, 0.35], "array panel back and edges"),
        e("antenna", [0.85, 0.85, 0.85], "altimeter dish"),
        e("metal", [0.60, 0.60, 0.62], "booms, struts, pedestal, mast, adapter"),
    ]
}

/// The bus as a box whose faces are cut on shared coordinate lines, so that vertices on
/// the box edges are bit-identical between faces (the fold wrap welds by position).
fn bus(m: &mut TriMesh) {
    let h = BUS_HALF;
    let xs = [-h.x, -0.2, 0.2, h.x];
    let ys = [-h.y, -0.2, 0.2, h.y];
    let zs = [-h.z, -0.3, 0.3, h.z];
    // Face on the plane axis = value; (a, b) are the in-plane axes with a × b = outward.
    let mut face = |axis: usize, side: usize, mat: &dyn Fn(usize, usize) -> u32| {
        let lists = [&xs, &ys, &zs];
        let (a, b) = if side == 1 { ((axis + 1) % 3, (axis + 2) % 3) } else { ((axis + 2) % 3, (axis + 1) % 3) };
        let fixed = lists[axis][if side == 1 { 3 } else { 0 }];
        let (la, lb) = (lists[a], lists[b]);
        let base = m.positions.len() as u32;
        for &vb in lb.iter() {
            for &va in la.iter() {
                let mut p = [0.0f32; 3];
                p[axis] = fixed;
                p[a] = va;
                p[b] = vb;
                m.positions.push(Vec3::from_array(p));
            }
        }
        let idx = |i: usize, j: usize| base + (j * 4 + i) as u32;
        for j in 0..3 {
            for i in 0..3 {
                let mt = mat(i, j);
                m.indices.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                m.indices.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
                m.material.extend([mt, mt]);
            }
        }
    };
    let mli = |_: usize, _: usize| MLI_GOLD;
    face(0, 0, &|i, j| {
        if i == 1 && j == 1 { WHITE_PAINT } else { MLI_GOLD }
    }); // −X radiator
    face(0, 1, &mli);
    face(1, 0, &mli);
    face(1, 1, &mli);
    face(2, 0, &mli);
    face(2, 1, &|_, _| WHITE_PAINT); // +Z instrument deck
}

/// One solar wing along `sign`·Y: boom, four panels, hinges.
fn wing(m: &mut TriMesh, sign: f32) {
    let y = |v: f32| sign * v;
    strut(m, Vec3::new(0.0, y(BUS_HALF.y), 0.0), Vec3::new(0.0, y(1.4), 0.0), 0.035, 48, 24, METAL);
    for k in 0..4 {
        let y0 = 1.4 + 0.85 * k as f32;
        let centre = Vec3::new(0.0, y(y0 + 0.4), 0.0);
        cuboid(m, Place::at(centre), Vec3::new(0.015, 0.4, 0.7), |f| if f == 1 { SOLAR_CELL } else { ARRAY_BACK });
        if k < 3 {
            for z in [-0.5, 0.5] {
                strut(m, Vec3::new(0.0, y(y0 + 0.8), z), Vec3::new(0.0, y(y0 + 0.85), z), 0.012, 16, 2, METAL);
            }
        }
    }
}

/// The altimeter dish, pedestal, feed and struts above the deck.
fn altimeter(m: &mut TriMesh) {
    let deck = BUS_HALF.z;
    let (diameter, focal, vertex_z) = (1.2f32, 0.45f32, deck + 0.12);
    cylinder(m, Place::at(Vec3::new(0.0, 0.0, deck)), 0.15, 0.12, 0.12, 64, 4, false, METAL);
    dish(m, Place::at(Vec3::new(0.0, 0.0, vertex_z)), diameter, focal, 112, 256, ANTENNA);
    let rim_z = vertex_z + 0.25 * diameter * diameter / (4.0 * focal);
    let feed_z = vertex_z + focal;
    cylinder(m, Place::at(Vec3::new(0.0, 0.0, feed_z - 0.08)), 0.06, 0.05, 0.16, 48, 6, true, METAL);
    for k in 0..3 {
        let a = std::f32::consts::TAU * (0.25 + k as f32 / 3.0);
        let (c, s) = (a.cos(), a.sin());
        strut(m, Vec3::new(0.6 * c, 0.6 * s, rim_z), Vec3::new(0.05 * c, 0.05 * s, feed_z), 0.012, 24, 16, METAL);
    }
}

/// Below the bus: launch-adapter ring and a DORIS-like mast.
fn underside(m: &mut TriMesh) {
    let z = -BUS_HALF.z;
    cylinder(m, Place::along(-Vec3::Z, Vec3::new(0.0, 0.0, z)), 0.32, 0.34, 0.1, 96, 4, true, METAL);
    strut(m, Vec3::new(0.35, 0.35, z), Vec3::new(0.35, 0.35, z - 0.35), 0.03, 32, 12, METAL);
    cylinder(m, Place::along(-Vec3::Z, Vec3::new(0.35, 0.35, z - 0.35)), 0.06, 0.01, 0.12, 32, 6, true, METAL);
}

/// The unfolded satellite.
pub fn satellite_flat() -> TriMesh {
    let mut m = TriMesh::default();
    bus(&mut m);
    wing(&mut m, 1.0);
    wing(&mut m, -1.0);
    altimeter(&mut m);
    underside(&mut m);
    m
}

/// The satellite with its MLI folded by `params`/`seed` at `edge_m`.
///
/// # Errors
/// Invalid fold parameters.
pub fn satellite(params: &FoldParams, seed: u64, edge_m: f32) -> Result<TriMesh, FoldError> {
    params.validate()?;
    let (m, report) = wrap_faces_report(&satellite_flat(), &[MLI_GOLD], params, seed, edge_m);
    tracing::info!(?report, "satellite MLI folded");
    Ok(m)
}
