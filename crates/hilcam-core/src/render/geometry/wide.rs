//! What the wide trees (`bvh8`, and the lab's `bvh4`) share: the node layout, the collapse
//! of obvhs's `Bvh2` into it, the slab test's reference form and the single-ray walk. Each
//! tree brings its own SIMD box test ([`Slab`]) and says when it runs.
//!
//! Why the answers are obvhs's. Only the tree changes: leaves are the `Bvh2` leaves (ranges
//! of the same primitive order) and every triangle is tested with obvhs's own
//! `RtTriangle::intersect` on the same prepared ray, with obvhs's closest-hit rule
//! (`t < current`). The box test is therefore the only new arithmetic, and it is made
//! conservative (a relative [`SLACK`] on the exit distance; a ray lying in a box's face
//! plane is not culled) so it never culls a box holding a triangle the triangle test would
//! accept: the closest `t` equals the brute-force minimum bit for bit (up to the sign of a
//! zero `t` when two triangles tie at the origin; which of exactly tied triangles is
//! reported depends on visit order, which differs between the widths). Every SIMD form of
//! the test is [`scalar_test`] lane for lane (sub then mul, no fused multiply-add; the same
//! min/max operand order), so all widths are exactly as conservative.
//!
//! Zero direction components: the reciprocal is ±inf, and `(bound - origin) * inv` is NaN
//! exactly when the origin lies on that bound's plane. Such an axis must not constrain the
//! interval (the ray runs inside the slab's face), so the NaN is dropped by the min/max
//! order: the SIMD forms pass the accumulator as the second operand (`maxps`/`minps`
//! return the second operand when either is NaN), as `f32::max`/`min` ignore a NaN.
//! Clamping the direction (Embree's `rcp_safe`, obvhs's `safe_inverse`) would instead make
//! the face plane an exit at `t = 0` for one sign of zero and cull the box (obvhs's `Bvh2`
//! misses such a hit; see `tests/render/bvh_wide.rs`'s axis rays). Not covered: a tiny
//! non-zero component with the origin exactly on a face, where the triangle test's
//! rounding could accept a point just outside the box.

use obvhs::{bvh2::Bvh2, ray::Ray as ObRay, rt_triangle::RtTriangle};
use std::mem::MaybeUninit;

/// Exit distances are scaled by this before `entry <= exit`: covers the few roundings of
/// the slab test and of the triangle's own `t` (a hit on a box face must not be culled).
pub(super) const SLACK: f32 = 1.0 + 1.0 / (1u32 << 20) as f32;
/// Traversal stack entries kept on the machine stack; deeper trees use a heap stack.
pub(super) const STACK: usize = 256;

/// `W` children: boxes in SoA form (`bounds[axis][0]` = min, `[1]` = max, one lane per
/// child) and per child either an inner node index (`count == 0`) or a leaf's primitive
/// range `first..first + count`. Unused slots have an inverted (empty) box and the child
/// index [`EMPTY_SLOT`], which no node has: a ray with a NaN coordinate passes every slab
/// test (the min/max drop NaN), so the walks skip such a slot by its index rather than
/// trust the box (as node 0, the root, it would restart the walk without end).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct Node<const W: usize> {
    pub bounds: [[[f32; W]; 2]; 3],
    pub child: [u32; W],
    pub count: [u32; W],
}

/// Child index of an unused slot (with `count == 0`); never a node's index.
pub(super) const EMPTY_SLOT: u32 = u32::MAX;

impl<const W: usize> Node<W> {
    /// Every slot empty: its box contains nothing, so no finite ray enters it.
    pub const EMPTY: Self =
        Node { bounds: [[[f32::INFINITY; W], [f32::NEG_INFINITY; W]]; 3], child: [EMPTY_SLOT; W], count: [0; W] };

    /// True for an unused slot.
    #[inline(always)]
    pub fn is_empty_slot(&self, slot: usize) -> bool {
        self.child[slot] == EMPTY_SLOT && self.count[slot] == 0
    }
}

/// A child: inner node (`count == 0`) or leaf range, and its entry distance.
#[derive(Clone, Copy, Default)]
pub(super) struct Entry {
    pub index: u32,
    pub count: u32,
    pub t: f32,
}

/// Collapse a `Bvh2` into `W`-wide nodes (root first): each node takes a binary node's two
/// children and keeps opening its largest-area inner child until it has `W`. Leaves are the
/// `Bvh2`'s (ranges of its primitive order). Returns the nodes and the depth (root = 1; 0
/// for an empty tree).
pub(super) fn collapse<const W: usize>(b: &Bvh2) -> (Vec<Node<W>>, usize) {
    let mut nodes = Vec::new();
    if b.nodes.is_empty() {
        return (nodes, 0);
    }
    let root = if b.nodes[0].is_leaf() {
        vec![0]
    } else {
        vec![b.nodes[0].first_index as usize, b.nodes[0].first_index as usize + 1]
    };
    let depth = add(&mut nodes, b, root, 1);
    (nodes, depth)
}

/// Appends the node holding the binary subtrees `kids`; returns the subtree depth.
fn add<const W: usize>(nodes: &mut Vec<Node<W>>, b: &Bvh2, mut kids: Vec<usize>, level: usize) -> usize {
    while kids.len() < W {
        let area = |k: usize| b.nodes[k].aabb().half_area();
        let open = kids
            .iter()
            .enumerate()
            .filter(|(_, k)| !b.nodes[**k].is_leaf())
            .max_by(|x, y| area(*x.1).total_cmp(&area(*y.1)));
        let Some((i, &k)) = open else { break };
        let first = b.nodes[k].first_index as usize;
        kids[i] = first;
        kids.insert(i + 1, first + 1);
    }
    let me = nodes.len();
    nodes.push(Node::EMPTY);
    let mut depth = level;
    for (slot, &k) in kids.iter().enumerate() {
        let n = &b.nodes[k];
        let (lo, hi) = (n.aabb().min.to_array(), n.aabb().max.to_array());
        for axis in 0..3 {
            nodes[me].bounds[axis][0][slot] = lo[axis];
            nodes[me].bounds[axis][1][slot] = hi[axis];
        }
        let (child, count) = if n.is_leaf() {
            (n.first_index, n.prim_count)
        } else {
            let idx = nodes.len() as u32;
            depth = depth.max(add(nodes, b, vec![n.first_index as usize, n.first_index as usize + 1], level + 1));
            (idx, 0)
        };
        nodes[me].child[slot] = child;
        nodes[me].count[slot] = count;
    }
    depth
}

/// Per-ray constants of the slab test.
pub(super) struct Prep {
    pub org: [f32; 3],
    pub inv: [f32; 3],
    /// 0 when the direction component is positive (near plane = min), else 1.
    pub near: [usize; 3],
}

impl Prep {
    #[inline(always)]
    pub fn new(ray: &ObRay) -> Self {
        let d = ray.direction.to_array();
        let inv = d.map(|x| 1.0 / x);
        Prep { org: ray.origin.to_array(), inv, near: d.map(|x| x.is_sign_negative() as usize) }
    }
}

/// A `W`-box slab test for one ray.
pub(super) trait Slab<const W: usize> {
    /// # Safety
    /// The CPU has the features the implementation is compiled for.
    unsafe fn new(p: &Prep, tmin: f32) -> Self;
    /// Bit `i` set when child `i`'s box overlaps `[tmin, tmax]` (conservatively); the
    /// entry distance of each child.
    ///
    /// # Safety
    /// As [`Slab::new`].
    unsafe fn test(&self, node: &Node<W>, p: &Prep, tmax: f32) -> (u32, [f32; W]);
}

/// The reference (and fallback) slab test.
pub(super) struct Scalar {
    tmin: f32,
}

impl<const W: usize> Slab<W> for Scalar {
    #[inline(always)]
    unsafe fn new(_: &Prep, tmin: f32) -> Self {
        Scalar { tmin }
    }

    #[inline(always)]
    unsafe fn test(&self, node: &Node<W>, p: &Prep, tmax: f32) -> (u32, [f32; W]) {
        scalar_test(node, p, self.tmin, tmax)
    }
}

/// Reference form of the slab test; the SIMD forms do the same operations in the same
/// order, lane by lane.
#[inline(always)]
pub(super) fn scalar_test<const W: usize>(node: &Node<W>, p: &Prep, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
    let mut mask = 0;
    let mut tnear = [0.0; W];
    for (slot, entry) in tnear.iter_mut().enumerate() {
        let t = |axis: usize, side: usize| (node.bounds[axis][side][slot] - p.org[axis]) * p.inv[axis];
        let (nx, ny, nz) = (t(0, p.near[0]), t(1, p.near[1]), t(2, p.near[2]));
        let (fx, fy, fz) = (t(0, 1 - p.near[0]), t(1, 1 - p.near[1]), t(2, 1 - p.near[2]));
        // `f32::max`/`min` ignore a NaN operand (see the module comment).
        let near = nx.max(ny.max(nz.max(tmin)));
        let far = fx.min(fy.min(fz.min(tmax))) * SLACK;
        mask |= ((near <= far) as u32) << slot;
        *entry = near;
    }
    (mask, tnear)
}

/// Stack entries a walk of a `W`-wide tree of `depth` levels can need: each level leaves at
/// most `W - 1` siblings behind.
pub(super) const fn stack_need(w: usize, depth: usize) -> usize {
    (w - 1) * depth + 2
}

/// Runs `walk` with a traversal stack of `need` entries: on the machine stack when it fits
/// [`STACK`], else on the heap. Left uninitialised (zeroing it costs as much as a short
/// traversal): the walk reads only entries it wrote.
#[inline(always)]
pub(super) fn with_stack<R>(need: usize, walk: impl FnOnce(&mut [MaybeUninit<Entry>]) -> R) -> R {
    if need <= STACK { walk(&mut [MaybeUninit::uninit(); STACK]) } else { walk(&mut vec![MaybeUninit::uninit(); need]) }
}

/// The single-ray walk of a `W`-wide tree (root = `nodes[0]`) with the box test `S`: the
/// closest hit within `[ray.tmin, ray.tmax)` as `(primitive index, t)`, a triangle
/// replacing the current hit only when its `t` is strictly smaller (as obvhs's `Bvh2`);
/// with `ANY`, the first hit found. `stack` holds at least [`stack_need`] entries.
///
/// # Safety
/// The CPU has the features `S` is compiled for.
#[inline(always)]
pub(super) unsafe fn walk<const W: usize, const ANY: bool, S: Slab<W>>(
    nodes: &[Node<W>],
    ray: &ObRay,
    tris: &[RtTriangle],
    stack: &mut [MaybeUninit<Entry>],
) -> Option<(u32, f32)> {
    if nodes.is_empty() {
        return None;
    }
    let p = Prep::new(ray);
    // SAFETY: the caller guarantees `S`'s features.
    let boxes = unsafe { S::new(&p, ray.tmin) };
    let mut ray = *ray;
    let mut best: Option<(u32, f32)> = None;
    // Tests a leaf's triangles in order; true when one was hit.
    let leaf = |c: &Entry, ray: &mut ObRay, best: &mut Option<(u32, f32)>| {
        if c.t > ray.tmax * SLACK {
            return false;
        }
        let mut found = false;
        for k in c.index..c.index + c.count {
            let t = tris[k as usize].intersect(ray);
            if t < ray.tmax {
                ray.tmax = t;
                *best = Some((k, t));
                found = true;
                if ANY {
                    break;
                }
            }
        }
        found
    };
    let mut sp = 0;
    let mut node = &nodes[0];
    loop {
        // SAFETY: as above.
        let (mut mask, tnear) = unsafe { boxes.test(node, &p, ray.tmax) };
        if ANY {
            // A yes/no answer does not depend on the order, so nothing is sorted: leaves
            // are tested as they come and inner children pushed as they come (`tmax`
            // changes only when the walk ends). Sorting cost 25 % of a shadow ray.
            let mut next = None;
            while mask != 0 {
                let slot = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if node.is_empty_slot(slot) {
                    continue; // entered only by a ray with a NaN coordinate
                }
                let c = Entry { index: node.child[slot], count: node.count[slot], t: tnear[slot] };
                if c.count > 0 {
                    if leaf(&c, &mut ray, &mut best) {
                        return best;
                    }
                } else if let Some(i) = next.replace(c.index) {
                    stack[sp] = MaybeUninit::new(Entry { index: i, count: 0, t: 0.0 });
                    sp += 1;
                }
            }
            let next = match next {
                Some(i) => i,
                None if sp == 0 => return best,
                None => {
                    sp -= 1;
                    // SAFETY: `stack[..sp]` has been written (pushed children).
                    unsafe { stack[sp].assume_init() }.index
                }
            };
            node = &nodes[next as usize];
            continue;
        }
        // Hit children sorted far to near (`hit[n - 1]` is the nearest).
        // Left uninitialised past `n` (zeroing eight entries per visit costs more than
        // the sort); `hit[..n]` has been written.
        let mut hit = [MaybeUninit::<Entry>::uninit(); W];
        let mut n = 0;
        while mask != 0 {
            let slot = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if node.is_empty_slot(slot) {
                continue;
            }
            let c = Entry { index: node.child[slot], count: node.count[slot], t: tnear[slot] };
            let mut j = n;
            // SAFETY: `j - 1 < n`: written.
            while j > 0 && unsafe { hit[j - 1].assume_init() }.t < c.t {
                hit[j] = hit[j - 1];
                j -= 1;
            }
            hit[j] = MaybeUninit::new(c);
            n += 1;
        }
        // SAFETY: `k < n`: written.
        let hit_at = |k: usize| unsafe { hit[k].assume_init() };
        // Leaves first, near to far (as obvhs's Bvh2): a hit shortens the ray before the
        // inner children are visited. Only the leaves nearer than every inner child;
        // farther ones wait on the stack in distance order.
        let mut rest = n;
        while rest > 0 && hit_at(rest - 1).count > 0 {
            leaf(&hit_at(rest - 1), &mut ray, &mut best);
            rest -= 1;
        }
        // The nearest of the rest next; the others pushed far to near. All `W - 1` slots
        // are copied, saving a branch per child (-7 % per ray on the 4-wide tree);
        // `rest - 1` of them count. In bounds: at tree level L at most (W - 1)(L - 1)
        // entries are held, and the stack has room for `stack_need`.
        let mut next = None;
        if rest > 0 {
            stack[sp..sp + W - 1].copy_from_slice(&hit[..W - 1]);
            sp += rest - 1;
            next = Some(hit_at(rest - 1));
        }
        let mut next = next.filter(|c| c.t <= ray.tmax * SLACK);
        while next.is_none() {
            if sp == 0 {
                return best;
            }
            sp -= 1;
            // SAFETY: `stack[..sp]` has been written (pushed children).
            let e = unsafe { stack[sp].assume_init() };
            if e.count > 0 {
                leaf(&e, &mut ray, &mut best);
            } else {
                next = Some(e).filter(|c| c.t <= ray.tmax * SLACK);
            }
        }
        node = &nodes[next.map_or(0, |c| c.index) as usize];
    }
}
