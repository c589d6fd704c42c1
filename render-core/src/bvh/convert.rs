//! A binary BVH collapsed into a compressed eight-wide one (CWBVH) on every core.
//!
//! The collapse is Ylitie et al.'s ("Efficient Incoherent Ray Traversal on GPUs Through
//! Compressed Wide BVHs", HPG 2017, §3): a bottom-up pass prices, for every binary node and
//! every number of wide children it could contribute (1 to 7), whether it becomes a leaf, a
//! wide node, or hands the slots down to its two children; a top-down pass then lays the wide
//! nodes out. obvhs's `bvh2_to_cwbvh` runs both passes on one thread, and on a 1M-triangle mesh
//! they took 22% of a commit. Here every subtree is worked on separately (the pricing of two
//! siblings does not depend on each other, and a wide node's place in the arrays follows from
//! the sizes of the subtrees laid out before it), and the result is obvhs's to the bit: the
//! same prices, the same nodes at the same indices, the same primitive order (a test compares
//! them), so the walk and every image stay as they were.

use super::{TASKS_FROM, gathered, shared::Shared};
use glam::{UVec3, Vec3A};
use obvhs::{
    PerComponent,
    bvh2::Bvh2,
    bvh2::node::Bvh2Node,
    cwbvh::{CwBvh, node::CwBvhNode},
};

/// Children of a wide node.
const BRANCHING: usize = 8;
/// obvhs's price of a primitive against a node visit (`PRIM_COST`).
const PRIM_COST: f32 = 0.3;
/// 1 / 255: child boxes are quantised to eight bits per plane.
const DENOM: f32 = 1.0 / 255.0;
/// Subtrees at most this deep below the root are worked on as tasks of their own; below, one
/// thread finishes a subtree (2^12 tasks at most, plenty to balance two or sixty-four cores).
const TASK_DEPTH: u32 = 12;

/// What a binary node becomes when it may fill `i + 1` slots of its wide parent.
#[derive(Clone, Copy, Default)]
struct Choice {
    cost: f32,
    kind: Kind,
    left: u8,
    right: u8,
}

#[derive(Clone, Copy, Default, PartialEq, Eq)]
enum Kind {
    Leaf,
    Internal,
    /// Its slots are split between its two children (`left` and `right` slots, less one).
    #[default]
    Distribute,
}

/// Wide nodes and primitives a wide node's subtree lays out below it.
#[derive(Clone, Copy, Default)]
struct Sizes {
    nodes: u32,
    primitives: u32,
}

impl Sizes {
    fn add(self, other: Sizes) -> Sizes {
        Sizes { nodes: self.nodes + other.nodes, primitives: self.primitives + other.primitives }
    }
}

/// `bvh2` (one primitive per leaf) collapsed into a CWBVH with at most `max_prims_per_leaf`
/// (1 to 3) primitives per leaf, children in octant order: `bvh2_to_cwbvh(bvh2,
/// max_prims_per_leaf, true, false)`, to the bit.
pub(super) fn to_cwbvh(bvh2: &Bvh2, max_prims_per_leaf: u32) -> CwBvh {
    if bvh2.nodes.is_empty() {
        return CwBvh::default();
    }
    if !children_in_pairs(bvh2) {
        return obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(bvh2, max_prims_per_leaf, true, false);
    }
    // Written side by side for big trees: 175 MB for a 3.1M-triangle mesh's, most of whose
    // filling is page faults. (Huge pages for them, tried, cost more: the kernel compacts
    // memory to find that many.)
    let mut choices = gathered(bvh2.nodes.len() / 2 * 7, |_| Choice::default());
    // The passes split work into tasks down to TASK_DEPTH levels; a small tree starts there.
    let top = if bvh2.nodes.len() < TASKS_FROM { TASK_DEPTH } else { 0 };
    price(bvh2, max_prims_per_leaf, 0, Shared::new(&mut choices), top);
    let plan = Plan { bvh2, choices: &choices };
    // Kept at the children's pair too (the root, a lone leaf or not, at 0): 25 MB, not 50, for
    // a 3.1M-triangle mesh.
    let mut sizes = gathered(bvh2.nodes.len().div_ceil(2), |_| Sizes::default());
    let total = plan.measure(0, Shared::new(&mut sizes), top);
    // The walk reads the nodes at random: in huge pages ([`super::pages`]).
    let mut nodes = super::pages::huge_vec(1 + total.nodes as usize);
    nodes.resize(1 + total.nodes as usize, CwBvhNode::default());
    let mut primitives = vec![0u32; total.primitives as usize];
    let out = Out { nodes: Shared::new(&mut nodes), primitives: Shared::new(&mut primitives), sizes: &sizes };
    plan.lay_out(0, 0, Sizes { nodes: 1, primitives: 0 }, &out, top);
    CwBvh {
        nodes,
        primitive_indices: primitives,
        total_aabb: *bvh2.nodes[0].aabb(),
        exact_node_aabbs: None,
        uses_spatial_splits: bvh2.uses_spatial_splits,
    }
}

/// True when every inner node's children sit in a pair from an odd index (the root at 0, then
/// pairs at 1 and 2, 3 and 4, ...), as obvhs's builders and ours lay them out: an inner node's
/// choices are then kept at its children's pair, `first_index / 2`, and a leaf keeps none (its
/// seven are all the same leaf). That halves the choices of a 3.1M-triangle tree, 350 MB
/// before, the biggest scratch array of a commit.
fn children_in_pairs(bvh2: &Bvh2) -> bool {
    bvh2.nodes.iter().all(|n| n.is_leaf() || n.first_index % 2 == 1)
}

/// Where inner node `n`'s choices start.
fn choices_of(n: &Bvh2Node) -> usize {
    pair_of(n) * 7
}

/// Inner node `n`'s index among the pairs of children: its own, as no other node has those
/// children.
fn pair_of(n: &Bvh2Node) -> usize {
    n.first_index as usize / 2
}

/// What binary node `n` becomes given `i + 1` slots: for a leaf, whatever its slots, a leaf of
/// its one primitive; for an inner node, its `i`th choice, which `read` gives by index.
fn choice_of(n: &Bvh2Node, i: usize, read: impl FnOnce(usize) -> Choice) -> Choice {
    match n.is_leaf() {
        true => Choice { cost: n.aabb().half_area() * n.prim_count as f32 * PRIM_COST, kind: Kind::Leaf, ..Default::default() },
        false => read(choices_of(n) + i),
    }
}

/// The bottom-up pass for the subtree of binary node `node`: its seven choices, after its
/// children's (in parallel near the root). Returns the subtree's primitive count.
fn price(bvh2: &Bvh2, max_prims: u32, node: usize, choices: Shared<'_, Choice>, depth: u32) -> u32 {
    let n = &bvh2.nodes[node];
    let half_area = n.aabb().half_area();
    if n.prim_count != 0 {
        assert_eq!(n.prim_count, 1, "the CWBVH collapse expects one primitive per binary leaf");
        return n.prim_count;
    }
    let (l, r) = (n.first_index as usize, n.first_index as usize + 1);
    let primitives = match depth < TASK_DEPTH {
        true => {
            let (a, b) = rayon::join(|| price(bvh2, max_prims, l, choices, depth + 1), || price(bvh2, max_prims, r, choices, depth + 1));
            a + b
        }
        false => price(bvh2, max_prims, l, choices, depth + 1) + price(bvh2, max_prims, r, choices, depth + 1),
    };
    // SAFETY: the children's subtrees are finished (joined above); nothing else touches them.
    let child = |c: usize, i: usize| choice_of(&bvh2.nodes[c], i, |k| unsafe { choices.get(k) });
    // One slot: a leaf of every primitive, or a wide node whose eight slots the children share.
    let cost_leaf = if primitives <= max_prims { primitives as f32 * half_area * PRIM_COST } else { f32::INFINITY };
    let (mut cost_split, mut left, mut right) = (f32::INFINITY, u8::MAX, u8::MAX);
    for k in 0..7 {
        let c = child(l, k).cost + child(r, 6 - k).cost;
        if c < cost_split {
            (cost_split, left, right) = (c, k as u8, 6 - k as u8);
        }
    }
    let cost_internal = cost_split + half_area;
    let (cost, kind) = if cost_leaf < cost_internal { (cost_leaf, Kind::Leaf) } else { (cost_internal, Kind::Internal) };
    let mut previous = Choice { cost, kind, left, right };
    let mine = choices_of(n);
    // SAFETY: only this call writes `node`'s choices.
    unsafe { choices.set(mine, previous) };
    // i + 1 slots: the best of i slots, or the slots shared between the two children.
    for i in 1..7 {
        let mut best = Choice { cost: previous.cost, ..previous };
        let mut split = None;
        for k in 0..i {
            let c = child(l, k).cost + child(r, i - k - 1).cost;
            if c < best.cost {
                best.cost = c;
                split = Some((k as u8, (i - k - 1) as u8));
            }
        }
        if let Some((left, right)) = split {
            best = Choice { cost: best.cost, kind: Kind::Distribute, left, right };
        }
        // SAFETY: as above.
        unsafe { choices.set(mine + i, best) };
        previous = best;
    }
    primitives
}

/// The priced binary tree, to be laid out.
struct Plan<'a> {
    bvh2: &'a Bvh2,
    choices: &'a [Choice],
}

/// Where the top-down pass writes.
struct Out<'a> {
    nodes: Shared<'a, CwBvhNode>,
    primitives: Shared<'a, u32>,
    sizes: &'a [Sizes],
}

impl Plan<'_> {
    /// The binary nodes that become the children of the wide node made of binary `node`, in
    /// the order the collapse finds them (`Bvh2Converter::get_children`).
    fn children(&self, node: usize) -> ([u32; BRANCHING], usize) {
        let mut children = [u32::MAX; BRANCHING];
        let mut count = 0;
        self.gather(node, 0, &mut children, &mut count);
        (children, count)
    }

    /// [`Plan::children`] below binary `node`, given `i + 1` slots.
    fn gather(&self, node: usize, i: usize, children: &mut [u32; BRANCHING], count: &mut usize) {
        let n = &self.bvh2.nodes[node];
        if n.is_leaf() {
            children[*count] = node as u32;
            *count += 1;
            return;
        }
        let choice = self.choice(node, i);
        for (child, slots) in [(n.first_index as usize, choice.left), (n.first_index as usize + 1, choice.right)] {
            if self.choice(child, slots as usize).kind == Kind::Distribute {
                self.gather(child, slots as usize, children, count);
            } else {
                children[*count] = child as u32;
                *count += 1;
            }
        }
    }

    /// What binary `node` becomes given `i + 1` slots.
    fn choice(&self, node: usize, i: usize) -> Choice {
        choice_of(&self.bvh2.nodes[node], i, |k| self.choices[k])
    }

    /// True when binary `node`, as a child of a wide node, is a leaf of it.
    fn is_leaf(&self, node: u32) -> bool {
        self.choice(node as usize, 0).kind == Kind::Leaf
    }

    /// Binary leaves below `node`.
    fn leaf_count(&self, node: usize) -> u32 {
        let n = &self.bvh2.nodes[node];
        match n.is_leaf() {
            true => n.prim_count,
            false => self.leaf_count(n.first_index as usize) + self.leaf_count(n.first_index as usize + 1),
        }
    }

    /// Wide nodes and primitives laid out below the wide node made of binary `node`, noted in
    /// `sizes` (at its pair of children) for every wide node of the subtree.
    fn measure(&self, node: usize, sizes: Shared<'_, Sizes>, depth: u32) -> Sizes {
        let (children, count) = self.children(node);
        let children = &children[..count];
        let below = |&c: &u32| match self.is_leaf(c) {
            true => Sizes { nodes: 0, primitives: self.leaf_count(c as usize) },
            false => {
                let s = self.measure(c as usize, sizes, depth + 1);
                Sizes { nodes: 1 + s.nodes, primitives: s.primitives }
            }
        };
        let total = match depth < TASK_DEPTH {
            true => {
                use rayon::prelude::*;
                children.par_iter().map(below).reduce(Sizes::default, Sizes::add)
            }
            false => children.iter().map(below).fold(Sizes::default(), Sizes::add),
        };
        // SAFETY: each wide node is measured once, by one call, and has a pair of its own.
        unsafe { sizes.set(pair_of(&self.bvh2.nodes[node]), total) };
        total
    }

    /// Writes the wide node made of binary `node` at `index`, its children from `at.nodes` and
    /// its leaves' primitives from `at.primitives`, then their subtrees after them.
    fn lay_out(&self, node: usize, index: usize, at: Sizes, out: &Out, depth: u32) {
        let (mut children, count) = self.children(node);
        self.order(node, &mut children, count);
        let (wide, mut next) = self.wide_node(node, &children, at, out);
        // SAFETY: `index` is this node's own place, written by this call alone.
        unsafe { out.nodes.set(index, wide) };
        // Each inner child at its slot among the node's children, its subtree after the
        // subtrees of the children before it.
        let mut subtrees = [(0, 0, Sizes::default()); BRANCHING];
        let mut len = 0;
        for c in children.into_iter().filter(|&c| c != u32::MAX && !self.is_leaf(c)) {
            subtrees[len] = (c as usize, at.nodes as usize + len, next);
            next = next.add(out.sizes[pair_of(&self.bvh2.nodes[c as usize])]);
            len += 1;
        }
        let subtrees = &subtrees[..len];
        let go = |&(c, i, from): &(usize, usize, Sizes)| self.lay_out(c, i, from, out, depth + 1);
        match depth < TASK_DEPTH {
            true => {
                use rayon::prelude::*;
                subtrees.par_iter().for_each(go);
            }
            false => subtrees.iter().for_each(go),
        }
    }

    /// The wide node of binary `node` with `children` in their slots, its leaves' primitives
    /// written from `at.primitives`; returns it and where its first subtree starts.
    fn wide_node(&self, node: usize, children: &[u32; BRANCHING], at: Sizes, out: &Out) -> (CwBvhNode, Sizes) {
        let aabb = self.bvh2.nodes[node].aabb();
        let mut wide = CwBvhNode { p: aabb.min.into(), ..Default::default() };
        let e = ((aabb.max - aabb.min).max(Vec3A::splat(1e-20)) * DENOM).log2().ceil().exp2();
        let rcp_e = 1.0 / e;
        let e: UVec3 = e.per_comp(|c: f32| c.to_bits() >> 23);
        wide.e = [e.x as u8, e.y as u8, e.z as u8];
        let internal = children.iter().filter(|&&c| c != u32::MAX && !self.is_leaf(c)).count() as u32;
        wide.primitive_base_idx = at.primitives;
        wide.child_base_idx = at.nodes;
        let mut written = 0u32;
        for (i, &c) in children.iter().enumerate().filter(|(_, c)| **c != u32::MAX) {
            let b = self.bvh2.nodes[c as usize].aabb();
            let lo = ((b.min - aabb.min) * rcp_e).floor().clamp(Vec3A::ZERO, Vec3A::splat(255.0));
            let hi = ((b.max - aabb.min) * rcp_e).ceil().clamp(Vec3A::ZERO, Vec3A::splat(255.0));
            (wide.child_min_x[i], wide.child_min_y[i], wide.child_min_z[i]) = (lo.x as u8, lo.y as u8, lo.z as u8);
            (wide.child_max_x[i], wide.child_max_y[i], wide.child_max_z[i]) = (hi.x as u8, hi.y as u8, hi.z as u8);
            if self.is_leaf(c) {
                let count = self.write_leaves(c as usize, at.primitives + written, out);
                wide.child_meta[i] = written as u8 | [0, 0b0010_0000, 0b0110_0000, 0b1110_0000][count as usize];
                written += count;
            } else {
                wide.imask |= 1 << i;
                wide.child_meta[i] = (24 + i as u8) | 0b0010_0000;
            }
        }
        (wide, Sizes { nodes: at.nodes + internal, primitives: at.primitives + written })
    }

    /// Writes the primitives of the binary leaves below `node` from `from`, left first;
    /// returns how many.
    fn write_leaves(&self, node: usize, from: u32, out: &Out) -> u32 {
        let n = &self.bvh2.nodes[node];
        if n.is_leaf() {
            // SAFETY: the primitive range of a wide node's leaves belongs to its call alone.
            unsafe { out.primitives.set(from as usize, self.bvh2.primitive_indices[n.first_index as usize]) };
            return 1;
        }
        let left = self.write_leaves(n.first_index as usize, from, out);
        left + self.write_leaves(n.first_index as usize + 1, from + left, out)
    }

    /// Puts `children` in the slots whose octant direction points at them from the node's
    /// centre, greedily cheapest first (`Bvh2Converter::order_children`): a ray then meets a
    /// node's children nearest first by reading the slots in its octant's order.
    fn order(&self, node: usize, children: &mut [u32; BRANCHING], count: usize) {
        let p = self.bvh2.nodes[node].aabb().center();
        let mut cost = [[f32::MAX; 8]; BRANCHING];
        for (s, d) in DIRECTIONS.iter().enumerate() {
            for c in 0..count {
                cost[c][s] = d.dot(self.bvh2.nodes[children[c] as usize].aabb().center() - p);
            }
        }
        let mut assignment = [usize::MAX; BRANCHING];
        let mut filled = [false; 8];
        loop {
            let (mut min_cost, mut min_slot, mut min_child) = (f32::MAX, usize::MAX, usize::MAX);
            for c in (0..count).filter(|&c| assignment[c] == usize::MAX) {
                for s in (0..8).filter(|&s| !filled[s]) {
                    if cost[c][s] < min_cost {
                        (min_cost, min_slot, min_child) = (cost[c][s], s, c);
                    }
                }
            }
            if min_slot == usize::MAX {
                break;
            }
            filled[min_slot] = true;
            assignment[min_child] = min_slot;
        }
        let original = std::mem::replace(children, [u32::MAX; BRANCHING]);
        for c in 0..count {
            children[assignment[c]] = original[c];
        }
    }
}

/// The eight octant directions, slot `s` negative along x, y, z for bits 2, 1, 0 of `s`.
const DIRECTIONS: [Vec3A; 8] = {
    const fn sign(s: usize, bit: usize) -> f32 {
        if s & bit != 0 { -1.0 } else { 1.0 }
    }
    let mut d = [Vec3A::ONE; 8];
    let mut s = 0;
    while s < 8 {
        d[s] = Vec3A::new(sign(s, 0b100), sign(s, 0b010), sign(s, 0b001));
        s += 1;
    }
    d
};

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::{
        BvhBuildParams, aabb::Aabb, bvh2::reinsertion::ReinsertionOptimizer, cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh, ploc::PlocBuilder,
    };

    fn boxes(seed: u32, n: usize) -> Vec<Aabb> {
        let mut s = seed;
        let mut next = move || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1 << 24) as f32
        };
        (0..n)
            .map(|_| {
                let c = Vec3A::new(next(), next(), next()) * 100.0;
                let half = Vec3A::new(next(), next(), next()) * next() * 3.0;
                Aabb::new(c - half, c + half)
            })
            .collect()
    }

    /// The same nodes, byte for byte, and the same primitive order as obvhs's one-thread
    /// conversion, on trees from one box to big enough for the pricing and layout to split
    /// into tasks, at each leaf size: PLOC trees before and after reinsertion (as
    /// `BuildQuality::Fast` builds them) and our SAH and median trees (as commits build them),
    /// all with their children in pairs, so that the fast path is the one compared.
    #[test]
    fn the_collapse_on_every_core_is_obvhs_to_the_bit() {
        for (seed, n) in [(1, 1), (2, 2), (3, 9), (4, 1000), (5, 60_000)] {
            let aabbs = boxes(seed, n);
            let p = BvhBuildParams::medium_build();
            let ploc = || {
                let indices = (0..n as u32).collect();
                PlocBuilder::with_capacity(n).build(p.ploc_search_distance, &aabbs, indices, p.sort_precision, p.search_depth_threshold)
            };
            let mut reinserted = ploc();
            ReinsertionOptimizer::default().run(&mut reinserted, p.reinsertion_batch_ratio, None);
            let trees = [
                ploc(),
                reinserted,
                super::super::split_bvh2(&aabbs, super::super::sah_split),
                super::super::split_bvh2(&aabbs, super::super::median_split),
            ];
            for (t, bvh2) in trees.iter().enumerate() {
                assert!(children_in_pairs(bvh2), "tree {t} of {n} boxes");
                for max_prims in 1..=3 {
                    let theirs = bvh2_to_cwbvh(bvh2, max_prims, true, false);
                    let ours = to_cwbvh(bvh2, max_prims);
                    assert_eq!(ours.primitive_indices, theirs.primitive_indices, "tree {t}, {n} boxes, {max_prims} per leaf");
                    assert!(ours.nodes == theirs.nodes, "tree {t}, {n} boxes, {max_prims} per leaf: nodes differ");
                    assert_eq!(ours.total_aabb.min, theirs.total_aabb.min);
                    assert_eq!(ours.total_aabb.max, theirs.total_aabb.max);
                }
            }
        }
    }
}
