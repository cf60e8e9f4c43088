//! Which surface cells ([`super::cells`]) the sun's light reaches whole, not at all, or
//! in part — kept while the sun's direction in the body frame stays the same (a memo: the
//! same classes whatever frame asked first, and no shadow ray in the frames after it).
//!
//! A cell is tested by shadow rays from four points: its centroid and a point just inside
//! each corner. All four lit: lit; all four shadowed: dark; else partial, and the
//! fragments over it test the sun sample by sample. A shadow narrower than about half a
//! cell can slip between the four points of a cell it crosses (docs/render.md gives the
//! cell size and this limit).

use super::cells::Cells;
use crate::render::geometry::Ray;
use crate::render::integrator::PathContext;
use glam::Vec3;
use rayon::prelude::*;

/// How the sun's light reaches a cell's sun-facing side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Class {
    Lit,
    Dark,
    Partial,
}

/// Cell edge as a fraction of the bounding radius of the target's largest part.
pub const CELL_FRACTION: f32 = 0.005;

/// The classes of every cell for one sun direction, kept between frames.
#[derive(Default)]
pub struct ShadowMemo {
    key: Option<([u32; 3], usize, usize)>,
    pub cells: Cells,
    class: Vec<Class>,
}

impl ShadowMemo {
    /// The classes for `ctx`'s target and sun, computed unless they are held. Returns the
    /// shadow rays traced now (0 when held).
    pub fn update(&mut self, ctx: &PathContext) -> u64 {
        let mesh = &ctx.scene.mesh;
        let key = (ctx.sun.to_array().map(f32::to_bits), mesh.indices.len(), mesh.positions.len());
        if self.key == Some(key) {
            return 0;
        }
        let size = CELL_FRACTION * ctx.scene.detail_radius as f32;
        if self.key.is_none_or(|k| (k.1, k.2) != (key.1, key.2)) || self.cells.size != size {
            self.cells = Cells::new(mesh, size);
        }
        let cells = &self.cells;
        let per_tri: Vec<Vec<Class>> = (0..mesh.indices.len() as u32)
            .into_par_iter()
            .map(|t| {
                let v = mesh.indices[t as usize].map(|i| mesh.positions[i as usize]);
                cells.of(t).map(|c| cells.corners(t, c, v).map_or(Class::Dark, |k| classify(ctx, t, k))).collect()
            })
            .collect();
        self.class.clear();
        self.class.extend(per_tri.into_iter().flatten());
        self.key = Some(key);
        4 * self.class.len() as u64
    }

    #[inline]
    pub fn class(&self, cell: u32) -> Class {
        self.class[cell as usize]
    }
}

/// One cell's class (four shadow rays, in one packet).
fn classify(ctx: &PathContext, t: u32, [a, b, c]: [Vec3; 3]) -> Class {
    let mut n = ctx.scene.normals[t as usize];
    if n.dot(ctx.sun) < 0.0 {
        n = -n;
    }
    if n.dot(ctx.sun) <= 0.0 {
        return Class::Dark; // edge-on to the sun: no direct light on either side
    }
    let g = (a + b + c) / 3.0;
    // Just inside each corner (1 % of the way to the centroid).
    let near = |v: Vec3| v + (g - v) * 0.01;
    let points = [g, near(a), near(b), near(c)];
    let n_face = ctx.scene.normals[t as usize];
    let rays = points.map(|p| Ray { origin: ctx.spawn(p, t, n_face, n), dir: ctx.sun, tmax: f32::INFINITY });
    match ctx.occluded_packet(&rays) {
        0 => Class::Lit,
        0b1111 => Class::Dark,
        _ => Class::Partial,
    }
}
