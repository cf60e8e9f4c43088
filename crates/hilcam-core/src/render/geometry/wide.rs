//! What the 4- and 8-wide trees (`bvh4`, `bvh8`) share: the node layout and the collapse of
//! obvhs's `Bvh2` into it. Each tree keeps its own box test and walk.

use obvhs::bvh2::Bvh2;

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
