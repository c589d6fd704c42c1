//! The CWBVH walk one node at a time, so one thread can keep several rays' walks in flight.
//!
//! A ray's walk through a BVH much bigger than the cache waits on memory at every node and
//! every leaf: on the 1M-triangle bench a closest-hit ray visits about five nodes, and each
//! visit costs about a miss. Walking [`LANES_IN_FLIGHT`] rays round robin, a node at a time,
//! lets the fetches one ray asked for (its children, its leaves' triangles) arrive while the
//! other rays take their steps.
//!
//! [`Walk`] is obvhs's `traverse!` loop (`cwbvh/traverse_macro.rs`, after Ylitie et al.,
//! "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG 2017) cut
//! at the point between two node visits: each ray visits its nodes in the same order and
//! tests the same leaves as in that loop, so interleaved it finds the same hits to the bit as
//! [`walk`], which runs the macro itself for one ray.

use glam::UVec2;
use obvhs::{
    cwbvh::{CwBvh, Traversal},
    faststack::FastStack,
    ray::Ray as BvhRay,
};

use super::wide;

/// One ray's walk, between two node visits.
pub(super) struct Walk {
    state: Traversal,
}

impl Walk {
    /// A walk from the root of `bvh` for a ray along `ray.direction`.
    #[inline(always)]
    pub fn new(bvh: &CwBvh, ray: &BvhRay) -> Self {
        Walk { state: bvh.new_traversal(ray.direction) }
    }

    /// The leaves the last node visited let the ray into, as (first primitive, bit mask of
    /// the primitives from it, bits below 24), handed out once.
    #[inline(always)]
    pub fn take_leaves(&mut self) -> Option<(u32, u32)> {
        let group = std::mem::take(&mut self.state.primitive_group);
        (group.y != 0).then_some((group.x, group.y))
    }

    /// The leaves waiting for [`Walk::take_leaves`], without taking them.
    #[inline(always)]
    pub fn pending_leaves(&self) -> Option<(u32, u32)> {
        let group = self.state.primitive_group;
        (group.y != 0).then_some((group.x, group.y))
    }

    /// Visits the next node the ray enters (the nearest-octant child first); false when
    /// nothing is left to visit and no leaves wait. Call [`Walk::take_leaves`] before each
    /// visit: the leaves of one node come before the next node, as in obvhs's loop.
    #[inline(always)]
    pub fn advance(&mut self, bvh: &CwBvh, ray: &BvhRay, ahead: impl Fn(usize)) -> bool {
        let s = &mut self.state;
        if s.current_group.y & 0xff00_0000 != 0 {
            let hits_imask = s.current_group.y;
            let child_offset = 31 - hits_imask.leading_zeros();
            s.current_group.y &= !(1u32 << child_offset);
            if s.current_group.y & 0xff00_0000 != 0 {
                s.stack.push(s.current_group);
            }
            let slot = (child_offset - 24) ^ (s.oct_inv4 & 0xff);
            let relative = (hits_imask & !(0xffff_ffffu32 << slot)).count_ones();
            let node = &bvh.nodes[(s.current_group.x + relative) as usize];
            // Walks in flight are for BVHs far bigger than the cache: every node is asked for.
            let hitmask = wide::node_hits(&bvh.nodes, node, ray, s.oct_inv4, true, ahead);
            s.current_group = UVec2::new(node.child_base_idx, (hitmask & 0xff00_0000) | u32::from(node.imask));
            s.primitive_group = UVec2::new(node.primitive_base_idx, hitmask & 0x00ff_ffff);
        } else {
            s.current_group = UVec2::ZERO;
        }
        if s.primitive_group.y == 0 && s.current_group.y & 0xff00_0000 == 0 {
            if s.stack.is_empty() {
                return false;
            }
            s.current_group = s.stack.pop_fast();
        }
        true
    }
}

/// Walks `bvh` front to back, handing the leaves each node lets the ray into to `leaves` as
/// (first primitive, bit mask of the primitives from it, bits below 24); `leaves` may shorten
/// `ray.tmax` and returns true to stop the walk. With `fetch_inner`, every inner node the ray
/// enters is prefetched when its parent is tested, and `ahead` is told its index (to prefetch
/// what the node leads to). A lone ray keeps obvhs's macro: through [`Walk`] it costs the same
/// (the Cornell box: +0.2% instructions under callgrind), and the macro stays an independent
/// reference that the interleaved walks are tested against.
#[inline(always)]
pub(super) fn walk(
    bvh: &CwBvh,
    ray: &mut BvhRay,
    fetch_inner: bool,
    ahead: impl Fn(usize),
    mut leaves: impl FnMut(&mut BvhRay, u32, u32) -> bool,
) {
    let mut state = bvh.new_traversal(ray.direction);
    let mut node;
    'walk: {
        obvhs::traverse!(bvh, node, state, wide::node_hits(&bvh.nodes, node, ray, state.oct_inv4, fetch_inner, &ahead), {
            // The macro hands primitives one at a time (highest bit first); take the node's
            // whole group at once instead.
            let base = state.primitive_group.x;
            let group = state.primitive_group.y | (1 << (state.primitive_id - base));
            state.primitive_group.y = 0;
            if leaves(ray, base, group) {
                break 'walk;
            }
        });
    }
}

/// Rays walked at once by [`walk_interleaved`]. Measured on the `rays` bench (see
/// `docs/benchmarks.md`).
pub(super) const LANES_IN_FLIGHT: usize = 8;

/// [`walk`] for each of `rays`, [`LANES_IN_FLIGHT`] of them at a time, round robin a node at
/// a time through [`Walk`]. `leaves` gets the ray's index too; `prefetch` is told of every leaf group a node
/// visit lets a ray into, turns before that ray tests it. Each ray's hits are those of [`walk`].
pub(super) fn walk_interleaved(
    bvh: &CwBvh,
    rays: &mut [BvhRay],
    mut leaves: impl FnMut(usize, &mut BvhRay, u32, u32) -> bool,
    prefetch: impl Fn(u32, u32),
) {
    in_flight(
        rays,
        |_, ray| Walk::new(bvh, ray),
        |w, i, ray| {
            let stopped = matches!(w.take_leaves(), Some((base, group)) if leaves(i, ray, base, group));
            // Nothing ahead: with eight walks in flight, asking for each entered node's
            // triangles too slowed batches by 14-17% (more fetches than the cache could take).
            let going = !stopped && w.advance(bvh, ray, |_| {});
            if going && let Some((base, group)) = w.pending_leaves() {
                prefetch(base, group);
            }
            going
        },
    );
}

/// Works through `items`, [`LANES_IN_FLIGHT`] at a time, round robin: `start` makes an
/// item's state when a lane takes it up, and `turn` advances it by one step (about one
/// memory fetch), returning false when the item is done.
#[inline(always)]
pub(super) fn in_flight<T, L>(items: &mut [T], start: impl Fn(usize, &T) -> L, mut turn: impl FnMut(&mut L, usize, &mut T) -> bool) {
    let mut lanes: [Option<(usize, L)>; LANES_IN_FLIGHT] = std::array::from_fn(|_| None);
    let (mut next, mut busy) = (0, 0);
    loop {
        for lane in lanes.iter_mut() {
            if lane.is_none() && next < items.len() {
                *lane = Some((next, start(next, &items[next])));
                (next, busy) = (next + 1, busy + 1);
            }
            let Some((i, state)) = lane else { continue };
            if !turn(state, *i, &mut items[*i]) {
                *lane = None;
                busy -= 1;
            }
        }
        if busy == 0 && next == items.len() {
            return;
        }
    }
}
