//! The acceleration structure: a BVH over the scene's triangles, built by obvhs. Only this
//! module, `alt` (and the lab's `sun_shadow`, which must run the very same triangle test)
//! import obvhs.
//!
//! The product traces `bvh8`: obvhs's binary `Bvh2`, collapsed into our 8-wide tree and
//! walked eight boxes per step (AVX2; `wide` says why its hits are obvhs's). Builds with the
//! `alt-bvh` feature (the lab's) also have three alternative layouts (`alt`): obvhs's own
//! `Bvh2` and CWBVH traversals and our SSE 4-wide `bvh4`, which `bvh8` supersedes (~15 %
//! cheaper bounce and shadow rays, ~5 % faster frames). All run the same triangle test on
//! the same triangle order; `hilcam bench render` measures them on the same rays
//! (`docs/performance.md`).

use super::TriMesh;
#[cfg(feature = "alt-bvh")]
use super::alt::AltTree;
use super::bvh8::Bvh8;
pub use super::leaves::Leaf;
use super::leaves::bvh2_leaves;
use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    bvh2::builder::build_bvh2_from_tris,
    ray::{Ray as ObRay, RayHit},
    rt_triangle::RtTriangle,
    triangle::Triangle,
};
use std::time::Duration;

/// Which tree layout to build. Every build knows the four names; only `bvh8` is built
/// without the `alt-bvh` feature ([`BvhLayout::check`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BvhLayout {
    /// Binary BVH (obvhs `Bvh2`), a lab layout.
    Bvh2,
    /// Compressed 8-wide BVH (obvhs `CwBvh`), a lab layout.
    Cwbvh,
    /// 4-wide BVH collapsed from the obvhs `Bvh2`, four boxes per step in SSE (`Bvh4`), a
    /// lab layout.
    Bvh4,
    /// 8-wide BVH collapsed from the obvhs `Bvh2`, eight boxes per step in AVX2 when the
    /// CPU has it, else a scalar loop (`Bvh8`): two thirds of the levels of `Bvh4`, the
    /// same box test; the fastest for the incoherent bounce and shadow rays that dominate
    /// once primary hits are rasterised.
    #[default]
    Bvh8,
}

impl BvhLayout {
    /// The name a scene file uses (`[render] bvh`).
    pub fn name(self) -> &'static str {
        match self {
            BvhLayout::Bvh2 => "bvh2",
            BvhLayout::Cwbvh => "cwbvh",
            BvhLayout::Bvh4 => "bvh4",
            BvhLayout::Bvh8 => "bvh8",
        }
    }

    /// Whether this build can build the layout: `bvh8` always, the others with the
    /// `alt-bvh` feature (which the binary's `lab` feature enables).
    pub fn available(self) -> bool {
        self == BvhLayout::Bvh8 || cfg!(feature = "alt-bvh")
    }

    /// `Err` with the reason when this build cannot build the layout ([`Accel::build`]
    /// refuses it).
    pub fn check(self) -> Result<Self, String> {
        if self.available() {
            Ok(self)
        } else {
            Err(format!("this build has only bvh8; {} is a lab layout, build with the `lab` feature", self.name()))
        }
    }
}

/// A ray in the render frame (f32). `dir` need not be normalised; `t` is in its units.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmax: f32,
}

/// The closest hit: `tri` indexes the mesh's triangles (original order). The unit face
/// normal and material come from data stored in BVH order next to the triangle that was
/// just intersected, so shading touches no cold memory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub tri: u32,
    pub t: f32,
    pub normal: Vec3,
    pub material: u32,
}

enum Tree {
    Bvh8(Bvh8),
    #[cfg(feature = "alt-bvh")]
    Alt(AltTree),
}

/// A ray prepared once for many triangle tests ([`Accel::primitive_t`]).
#[derive(Clone, Copy)]
pub struct TestRay(ObRay);

impl TestRay {
    #[inline]
    pub fn new(r: &Ray) -> Self {
        TestRay(Accel::ob_ray(r))
    }
}

/// BVH plus the triangles laid out in the BVH's primitive order (no indirection while
/// intersecting; one lookup of the original index per hit).
pub struct Accel {
    tree: Tree,
    tris: Vec<RtTriangle>,
    original: Vec<u32>,
    /// Material of each primitive, BVH order.
    material: Vec<u32>,
    /// Vertex indices of each primitive into the mesh's positions, BVH order.
    vertices: Vec<[u32; 3]>,
    /// Each leaf's box and primitives (for the traced frames' pixel coverage,
    /// `render::cull::coverage`): the `Bvh2`'s leaves, which the wide trees keep; for the CWBVH
    /// each triangle.
    leaves: Vec<Leaf>,
    pub build_time: Duration,
}

impl Accel {
    /// Builds `layout` over the mesh. Panics on a layout this build does not have: callers
    /// check [`BvhLayout::check`] first (scene files do, naming the field).
    pub fn build(mesh: &TriMesh, layout: BvhLayout) -> Self {
        if let Err(m) = layout.check() {
            panic!("Accel::build: {m}");
        }
        let t0 = std::time::Instant::now();
        let tris: Vec<Triangle> = (0..mesh.indices.len())
            .map(|i| {
                let [a, b, c] = mesh.triangle(i);
                Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
            })
            .collect();
        let params = BvhBuildParams::medium_build();
        let mut core = Duration::ZERO;
        let (tree, original, leaves) = if tris.is_empty() {
            (Tree::Bvh8(Bvh8::default()), Vec::new(), Vec::new())
        } else {
            match layout {
                BvhLayout::Bvh8 => {
                    let b = build_bvh2_from_tris(&tris, params, &mut core);
                    let (tree, leaves) = (Tree::Bvh8(Bvh8::from_bvh2(&b)), bvh2_leaves(&b));
                    (tree, b.primitive_indices, leaves)
                }
                #[cfg(feature = "alt-bvh")]
                _ => {
                    let (tree, original, leaves) = AltTree::build(layout, &tris, params, &mut core);
                    (Tree::Alt(tree), original, leaves)
                }
                #[cfg(not(feature = "alt-bvh"))]
                _ => unreachable!("refused above"),
            }
        };
        let rt = original.iter().map(|&i| RtTriangle::from(&tris[i as usize])).collect();
        let material = original.iter().map(|&i| mesh.material.get(i as usize).copied().unwrap_or(0)).collect();
        let vertices = original.iter().map(|&i| mesh.indices[i as usize]).collect();
        Accel { tree, tris: rt, original, material, vertices, leaves, build_time: t0.elapsed() }
    }

    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    #[inline(always)]
    fn ob_ray(r: &Ray) -> ObRay {
        ObRay::new(Vec3A::from(r.origin), Vec3A::from(r.dir), 0.0, r.tmax)
    }

    /// Closest hit along the ray within `(0, tmax]`.
    #[inline]
    pub fn intersect(&self, r: &Ray) -> Option<Hit> {
        self.closest(r).map(|(k, t)| self.primitive_hit(k, t))
    }

    /// [`Accel::intersect`] as the hit's primitive (BVH order) and `t`.
    #[inline]
    fn closest(&self, r: &Ray) -> Option<(u32, f32)> {
        if self.tris.is_empty() {
            return None;
        }
        let ray = Self::ob_ray(r);
        let mut hit = RayHit::none();
        let tris = &self.tris;
        let found = match &self.tree {
            Tree::Bvh8(b) => b.intersect(&ray, tris).map(|(k, t)| (hit.primitive_id, hit.t) = (k, t)).is_some(),
            #[cfg(feature = "alt-bvh")]
            Tree::Alt(a) => a.intersect(ray, &mut hit, tris),
        };
        found.then_some((hit.primitive_id, hit.t))
    }

    /// The tree's leaves (every primitive lies in exactly one).
    pub fn leaves(&self) -> &[Leaf] {
        &self.leaves
    }

    /// Number of triangles; primitive `k` (BVH order, `0..len`) is the k-th one laid out.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Original triangle index of primitive `k`.
    #[inline]
    pub fn original(&self, k: u32) -> u32 {
        self.original[k as usize]
    }

    /// Vertex indices (into the mesh's positions) of primitive `k`.
    #[inline]
    pub fn vertex_indices(&self, k: u32) -> [u32; 3] {
        self.vertices[k as usize]
    }

    /// Distance at which `ray` hits primitive `k` by exactly the test the traversal runs,
    /// or infinity: callers that pick candidates some other way (rasterised primary
    /// visibility) get the same hits as the tree.
    #[inline(always)]
    pub fn primitive_t(&self, k: u32, ray: &TestRay) -> f32 {
        self.tris[k as usize].intersect(&ray.0)
    }

    /// The [`Hit`] record of primitive `k` at distance `t` (what [`Accel::intersect`]
    /// returns when `k` is the closest).
    #[inline]
    pub fn primitive_hit(&self, k: u32, t: f32) -> Hit {
        let k = k as usize;
        let normal = Vec3::from(self.tris[k].compute_normal());
        Hit { tri: self.original[k], t, normal, material: self.material[k] }
    }

    /// True when anything blocks the ray within `(0, tmax]` (stops at the first hit).
    #[inline]
    pub fn occluded(&self, r: &Ray) -> bool {
        if self.tris.is_empty() {
            return false;
        }
        let ray = Self::ob_ray(r);
        let tris = &self.tris;
        match &self.tree {
            Tree::Bvh8(b) => b.occluded(&ray, tris),
            #[cfg(feature = "alt-bvh")]
            Tree::Alt(a) => a.occluded(ray, tris),
        }
    }
}

impl Accel {
    /// Occlusion of up to [`shadow_packet::PACKET`](super::shadow_packet::PACKET) rays that
    /// share one direction (the shadow rays toward the sun): bit `i` set when ray `i` is
    /// blocked, the same answers as [`Accel::occluded`] ray by ray. On the 8-wide (and the
    /// lab's 4-wide) tree with AVX2 the rays walk it together (`shadow_packet`); otherwise one by one.
    pub fn occluded_packet(&self, rays: &[Ray]) -> u32 {
        use super::shadow_packet::{PACKET, one_by_one};
        let one_by_one = || one_by_one(rays, |r| self.occluded(r));
        if self.tris.is_empty() || rays.len() > PACKET {
            return one_by_one();
        }
        let mut ob = [ObRay::new_inf(Vec3A::ZERO, Vec3A::X); PACKET];
        for (o, r) in ob.iter_mut().zip(rays) {
            *o = Self::ob_ray(r);
        }
        let ob = &ob[..rays.len()];
        let walked = match &self.tree {
            Tree::Bvh8(b) => b.occluded_packet(ob, &self.tris),
            #[cfg(feature = "alt-bvh")]
            Tree::Alt(a) => a.occluded_packet(ob, &self.tris),
        };
        walked.unwrap_or_else(one_by_one)
    }
}

impl Accel {
    /// Whether [`Accel::intersect_packet`] walks its rays together (the 8-wide tree with
    /// AVX2) rather than one by one.
    pub fn walks_packets(&self) -> bool {
        matches!(&self.tree, Tree::Bvh8(b) if b.uses_avx2())
    }

    /// Closest hits of up to [`shadow_packet::PACKET`](super::shadow_packet::PACKET) rays
    /// (`out[i]` for `rays[i]`): the same hits as [`Accel::intersect`] ray by ray (the same
    /// `t` bit for bit; of triangles tied at exactly the same `t`, possibly another). On the
    /// 8-wide tree with AVX2 the rays walk it together (`closest_packet`: neighbouring
    /// primary rays); otherwise one by one.
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        use super::shadow_packet::PACKET;
        assert!(out.len() >= rays.len(), "{} rays, room for {} hits", rays.len(), out.len());
        if rays.len() <= PACKET {
            let mut prims = [None; PACKET];
            self.closest_prims(rays, &mut prims);
            for (o, p) in out.iter_mut().zip(&prims[..rays.len()]) {
                *o = p.map(|(k, t)| self.primitive_hit(k, t));
            }
        } else {
            for (r, o) in rays.iter().zip(out.iter_mut()) {
                *o = self.intersect(r);
            }
        }
    }

    /// [`Accel::intersect_packet`] of up to eight rays, each hit as its primitive (BVH
    /// order) and `t`: for callers that read the primitive's own data next
    /// ([`Accel::primitive_hit`], [`Accel::primitive_v0`]).
    pub fn closest_prims(&self, rays: &[Ray], out: &mut [Option<(u32, f32)>; super::shadow_packet::PACKET]) {
        use super::shadow_packet::PACKET;
        let walked = match &self.tree {
            Tree::Bvh8(b) if !self.tris.is_empty() && rays.len() <= PACKET => {
                let mut ob = [ObRay::new_inf(Vec3A::ZERO, Vec3A::X); PACKET];
                for (o, r) in ob.iter_mut().zip(rays) {
                    *o = Self::ob_ray(r);
                }
                b.intersect_packet(&ob[..rays.len()], &self.tris)
            }
            _ => None,
        };
        match walked {
            Some((prim, t)) => {
                for (i, o) in out[..rays.len()].iter_mut().enumerate() {
                    *o = (prim[i] != super::closest_packet::MISS).then_some((prim[i], t[i]));
                }
            }
            None => {
                for (r, o) in rays.iter().zip(out.iter_mut()) {
                    *o = self.closest(r);
                }
            }
        }
    }

    /// Primitive `k`'s first vertex, the mesh's bit for bit, read from the triangle the
    /// walk has just tested (the mesh's copy is two dependent cache misses away).
    #[inline]
    pub fn primitive_v0(&self, k: u32) -> Vec3 {
        Vec3::from(self.tris[k as usize].v0)
    }
}

/// Reference answers for tests and validation: the same triangle test over every
/// triangle, with obvhs's convention that a hit counts when `t < tmax`.
pub mod brute_force {
    use super::*;

    fn rt(mesh: &TriMesh, i: usize) -> RtTriangle {
        let [a, b, c] = mesh.triangle(i);
        RtTriangle::new(a.into(), b.into(), c.into())
    }

    pub fn intersect(mesh: &TriMesh, r: &Ray) -> Option<Hit> {
        let ray = Accel::ob_ray(r);
        let mut best: Option<Hit> = None;
        for i in 0..mesh.indices.len() {
            let t = rt(mesh, i).intersect(&ray);
            if t < best.map_or(ray.tmax, |h| h.t) {
                let normal = mesh.face_normal_area2(i).normalize_or_zero();
                best = Some(Hit { tri: i as u32, t, normal, material: mesh.material[i] });
            }
        }
        best
    }

    pub fn occluded(mesh: &TriMesh, r: &Ray) -> bool {
        let ray = Accel::ob_ray(r);
        (0..mesh.indices.len()).any(|i| rt(mesh, i).intersect(&ray) < ray.tmax)
    }
}

#[cfg(test)]
mod tests {
    use super::BvhLayout;

    /// `bvh8` is in every build; the others exactly when the `alt-bvh` feature is on, and
    /// otherwise refused with a message naming the layout and the feature to build with.
    #[test]
    fn layouts_this_build_has() {
        assert_eq!(BvhLayout::Bvh8.check(), Ok(BvhLayout::Bvh8));
        for layout in [BvhLayout::Bvh2, BvhLayout::Cwbvh, BvhLayout::Bvh4] {
            if cfg!(feature = "alt-bvh") {
                assert_eq!(layout.check(), Ok(layout));
            } else {
                let refusal = layout.check().unwrap_err();
                let expected = format!("this build has only bvh8; {} is a lab layout", layout.name());
                assert!(refusal.starts_with(&expected) && refusal.contains("`lab` feature"), "{refusal}");
            }
        }
    }

    /// Building a layout this build lacks panics with the refusal rather than falling back.
    #[test]
    #[cfg(not(feature = "alt-bvh"))]
    #[should_panic(expected = "this build has only bvh8; bvh4 is a lab layout")]
    fn build_refuses_a_missing_layout() {
        super::Accel::build(&super::TriMesh::default(), BvhLayout::Bvh4);
    }
}
