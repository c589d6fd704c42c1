//! Eight-wide ray tests for the BVH walk: all eight children of a CWBVH node against a ray in
//! one pass, and the triangles of a node's leaves eight at a time from component arrays.
//!
//! obvhs's own node test converts its quantised child planes to floats one lane at a time
//! (`cwbvh/simd.rs`: 48 scalar conversions a node) and tests four children per pass; its
//! primitive callback sees one triangle at a time. With AVX2 (the release target,
//! `.cargo/config.toml`) a node is six byte-to-float widenings and one pass, and a leaf group
//! one Möller-Trumbore pass over up to eight triangles. Both compute exactly what the scalar
//! code computes, operation for operation and rounding for rounding (the scalar tests are the
//! reference in this module's tests), so hits, and therefore images, stay bit-identical.

use glam::{Vec2, Vec3A};
use obvhs::{cwbvh::node::CwBvhNode, ray::Ray as BvhRay};

use super::RtTriangle;

/// Entry distance below which obvhs's node test culls a child box (`cwbvh/node.rs`,
/// `EPSILON`, crate-private): the wide test uses the same so both find the same nodes.
#[cfg_attr(not(all(target_arch = "x86_64", target_feature = "avx2")), allow(dead_code))]
const NODE_TMIN: f32 = 1e-4;

/// Triangles in BVH order, in chunks of [`LANES`]: each chunk holds the `v0.x` of its eight
/// triangles, then their `v0.y`, ..., then their `e2.z`, then their original (mesh) indices;
/// the test loads a chunk as nine vectors and reads an index only for the hit. Chunks are
/// 320 bytes, five cache lines from a line boundary, and the indices share the last line
/// with the `e2.z` row the test has just read: mapping a hit back to its mesh triangle
/// through an array of its own took a cache miss at the end of most closest-hit rays (11% of
/// a lone ray's samples on the 1M-triangle bench). A CWBVH node's triangles sit next to each
/// other and span one to four chunks; a layout of nine whole-mesh rows would touch nine or
/// more cache lines for every node, which showed on meshes bigger than the cache. The last
/// chunk is padded with zero triangles, which never hit (their determinant is 0).
pub(super) struct TriangleLanes {
    chunks: Vec<Chunk>,
    count: usize,
    /// Each chunk's bounds, when the mesh has [`BOUNDED_CHUNKS`] chunks.
    bounds: Option<ChunkBounds>,
}

/// Triangles tested per pass, and per chunk.
pub(super) const LANES: usize = 8;

/// The bounds of a small mesh's chunks (lane `c`: chunk `c`), padded outwards by
/// [`BOUNDS_PAD`] of the chunk's size. The whole-mesh scan meets them eight to an AVX2 pass and
/// skips the chunks the ray misses.
#[derive(Clone, Debug, PartialEq)]
struct ChunkBounds {
    /// Chunk `c`'s bounds are lane `c % LANES` of pass `c / LANES`: as many passes as the
    /// mesh has chunks for (24 bytes a chunk, three a triangle).
    passes: Box<[BoundsPass]>,
    /// Bit `c` set for each chunk that exists.
    chunks: u32,
}

/// The bounds of [`LANES`] chunks, rows of lanes, met in one pass: 192 bytes, three lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct BoundsPass {
    lo: [[f32; LANES]; 3],
    hi: [[f32; LANES]; 3],
}

/// Meshes with this many chunks keep [`ChunkBounds`]. Measured on the `rays` bench's small UV
/// spheres (one thread, alternating builds): the bounds test cost the scan 40% at two chunks
/// and 1-16% at five (a dependent chain and unpredictable skips, where the chunk tests it
/// spares would have overlapped), and gained 3-12% at six and 19-27% at eight. On the Cornell
/// box (five chunks, a ray misses 2.9 of them) it saved 5% of the instructions and about 1.5%
/// of the time. With the bounds, the scan also beats the walk up to thirty-two chunks
/// ([`super::SCAN_MAX_CHUNKS`]).
const BOUNDED_CHUNKS: std::ops::RangeInclusive<usize> = 6..=MAX_BOUNDED;

/// The most chunks [`ChunkBounds`] holds: four passes.
pub(super) const MAX_BOUNDED: usize = 4 * LANES;

/// How far a chunk's bounds are pushed out, relative to its size (the larger of its extent
/// and its coordinates' magnitude). A hit found with rounding just outside the exact bounds
/// (Möller-Trumbore accepts edges, and the box test rounds too) must not be skipped: 2⁻¹² of
/// the size covers the rounding of rays up to about a thousand sizes long, and costs the
/// culling nothing measurable.
const BOUNDS_PAD: f32 = 1.0 / 4096.0;

/// Directions closer to zero than this along an axis count as parallel to it: the slab test
/// then asks whether the origin lies between the planes instead of dividing by the component
/// (which makes 0·∞ = NaN on a plane).
const PARALLEL: f32 = 1e-30;

/// Floats per chunk that the test reads: nine components of eight triangles.
const CHUNK: usize = 9 * LANES;
/// Row of a chunk holding the triangles' original indices (as `f32` bits).
const ID_ROW: usize = 9;

/// One chunk: [`CHUNK`] floats of triangle components, then a row of original indices.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Chunk([f32; CHUNK + LANES]);

/// A triangle hit: distance, BVH-order index, barycentrics.
pub(super) type LaneHit = (f32, u32, Vec2);

impl TriangleLanes {
    /// The triangles `tris` (BVH order), the mesh's index of each in `ids`.
    #[cfg(test)]
    pub(super) fn new(tris: &[RtTriangle], ids: &[u32]) -> Self {
        assert_eq!(tris.len(), ids.len(), "one original index per triangle");
        Self::from_fn(tris.len(), |i| (tris[i], ids[i]))
    }

    /// `count` triangles in BVH order, triangle `i` and its mesh index given by `triangle(i)`;
    /// chunks filled side by side on the thread pool for big meshes, each written once (their
    /// first write is also what maps a huge page's memory: a 3.1M-triangle mesh's 124 MB of
    /// chunks took 0.5 s on one thread).
    pub(super) fn from_fn(count: usize, triangle: impl Fn(usize) -> (RtTriangle, u32) + Sync) -> Self {
        use rayon::prelude::*;
        let chunk_count = count.div_ceil(LANES);
        let mut chunks = super::pages::huge_vec(chunk_count);
        let chunk = |c: usize| {
            let mut chunk = Chunk([0.0; CHUNK + LANES]);
            for i in (c * LANES..count).take(LANES) {
                let (t, id) = triangle(i);
                for (k, v) in [t.v0, t.e1, t.e2].iter().flat_map(|v| v.to_array()).enumerate() {
                    chunk.0[Self::at(i, k)] = v;
                }
                chunk.0[Self::at(i, ID_ROW)] = f32::from_bits(id);
            }
            chunk
        };
        match count < super::TASKS_FROM {
            true => chunks.extend((0..chunk_count).map(chunk)),
            false => chunks.par_extend((0..chunk_count).into_par_iter().with_min_len(1024).map(chunk)),
        }
        let mut lanes = TriangleLanes { chunks, count, bounds: None };
        lanes.bounds = BOUNDED_CHUNKS.contains(&chunk_count).then(|| ChunkBounds::of(&lanes));
        lanes
    }

    /// Where component `c` of triangle `i` is stored in its chunk.
    #[inline(always)]
    fn at(i: usize, c: usize) -> usize {
        c * LANES + i % LANES
    }

    /// Component `c` of triangle `i`.
    #[inline(always)]
    fn component(&self, i: usize, c: usize) -> f32 {
        self.chunks[i / LANES].0[Self::at(i, c)]
    }

    /// The mesh's index of triangle `i` (BVH order).
    #[inline(always)]
    pub(super) fn id(&self, i: usize) -> u32 {
        self.component(i, ID_ROW).to_bits()
    }

    /// Asks for the chunks to be kept in huge pages ([`super::pages`]).
    pub(super) fn ask_for_huge_pages(&self) {
        super::pages::ask_for_huge_pages(&self.chunks);
    }

    /// Bytes the chunks take.
    pub(super) fn bytes(&self) -> usize {
        size_of_val(self.chunks.as_slice())
    }

    pub(super) fn len(&self) -> usize {
        self.count
    }

    /// Triangle `i` (BVH order).
    #[inline(always)]
    pub(super) fn triangle(&self, i: usize) -> RtTriangle {
        let c = |k: usize| self.component(i, k);
        RtTriangle { v0: Vec3A::new(c(0), c(1), c(2)), e1: Vec3A::new(c(3), c(4), c(5)), e2: Vec3A::new(c(6), c(7), c(8)) }
    }

    /// The triangles `base + j` for the set bits `j` of `mask` (below 32) as (chunk, lane
    /// mask) pairs, the highest chunk first.
    #[inline(always)]
    fn chunks(base: u32, mask: u32) -> impl Iterator<Item = (usize, u32)> {
        let first = base as usize / LANES;
        let mut lanes = u64::from(mask) << (base as usize % LANES);
        // One step per chunk with a set lane (a group spans up to five chunks, most one or two).
        std::iter::from_fn(move || {
            (lanes != 0).then(|| {
                let k = (63 - lanes.leading_zeros() as usize) / LANES;
                let byte = (lanes >> (LANES * k)) & 0xff;
                lanes &= !(0xff << (LANES * k));
                (first + k, byte as u32)
            })
        })
    }

    /// Closest hit before `ray.tmax` among triangles `base + j` for the set bits `j` of
    /// `mask` (a CWBVH primitive group, bits below 32). Equal distances resolve as obvhs's
    /// one-at-a-time walk resolves them (highest index first, strict `<`): the triangle with
    /// the highest index among the nearest.
    #[inline(always)]
    pub(super) fn closest(&self, base: u32, mask: u32, ray: &BvhRay) -> Option<LaneHit> {
        self.closest_in(Self::chunks(base, mask), ray)
    }

    /// Closest hit before `ray.tmax` among all the triangles, chunk by chunk with no tree:
    /// the same hit as [`Self::closest`] over every triangle (highest chunk first, so equal
    /// distances resolve alike).
    #[inline(always)]
    pub(super) fn closest_of_all(&self, ray: &BvhRay) -> Option<LaneHit> {
        match &self.bounds {
            Some(b) => self.closest_in(self.chunks_met(b, ray), ray),
            None => self.closest_in(self.every_chunk(), ray),
        }
    }

    /// Closest hit before `ray.tmax` among the lanes of `chunks`, (chunk, lane mask) pairs,
    /// taken in the order given.
    #[inline(always)]
    fn closest_in(&self, chunks: impl Iterator<Item = (usize, u32)>, ray: &BvhRay) -> Option<LaneHit> {
        let mut best: Option<LaneHit> = None;
        let mut tmax = ray.tmax;
        for (chunk, lanes) in chunks {
            if let Some((t, j, bary)) = self.closest_in_chunk(chunk, lanes, ray, tmax) {
                tmax = t;
                best = Some((t, (chunk * LANES) as u32 + j, bary));
            }
        }
        best
    }

    /// True when any triangle lies on the ray before `ray.tmax`, chunk by chunk with no tree.
    #[inline(always)]
    pub(super) fn any_of_all(&self, ray: &BvhRay) -> bool {
        match &self.bounds {
            Some(b) => self.any_in(self.chunks_met(b, ray), ray),
            None => self.any_in(self.every_chunk(), ray),
        }
    }

    /// The chunks whose bounds `b` the ray meets within (`tmin`, `tmax`), with the lanes that
    /// hold triangles, the highest chunk first as [`Self::every_chunk`] gives them (so equal
    /// distances resolve alike).
    #[inline(always)]
    fn chunks_met(&self, b: &ChunkBounds, ray: &BvhRay) -> impl Iterator<Item = (usize, u32)> + '_ {
        super::bits_high_first(b.met(ray)).map(|chunk| (chunk as usize, self.lanes_in(chunk as usize)))
    }

    /// True when any triangle in the lanes of `chunks` lies on the ray before `ray.tmax`.
    #[inline(always)]
    fn any_in(&self, mut chunks: impl Iterator<Item = (usize, u32)>, ray: &BvhRay) -> bool {
        chunks.any(|(chunk, lanes)| self.closest_in_chunk(chunk, lanes, ray, ray.tmax).is_some())
    }

    /// Every chunk with the lanes that hold triangles, the highest chunk first.
    #[inline(always)]
    fn every_chunk(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        (0..self.chunks.len()).rev().map(|chunk| (chunk, self.lanes_in(chunk)))
    }

    /// The lanes of chunk `chunk` that hold triangles.
    #[inline(always)]
    fn lanes_in(&self, chunk: usize) -> u32 {
        let held = (self.count - chunk * LANES).min(LANES);
        (1u32 << held) - 1
    }

    /// Chunks of triangles.
    pub(super) fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// True when any of the triangles `base + j` (set bits `j` of `mask`) lies on the ray
    /// within (`tmin`, `tmax`).
    #[inline(always)]
    pub(super) fn any(&self, base: u32, mask: u32, ray: &BvhRay) -> bool {
        self.any_in(Self::chunks(base, mask), ray)
    }

    /// Asks the cache for the chunks holding triangles `base + j` (set bits `j` of `mask`),
    /// every cache line of each: a walk with other rays in flight tests them a few turns later.
    #[inline(always)]
    pub(super) fn prefetch(&self, base: u32, mask: u32) {
        for (chunk, _) in Self::chunks(base, mask) {
            self.prefetch_chunk(chunk);
        }
    }

    /// Asks the cache for chunks `first..=last`.
    #[inline(always)]
    pub(super) fn prefetch_chunks(&self, first: u32, last: u32) {
        for chunk in first..=last {
            self.prefetch_chunk(chunk as usize);
        }
    }

    /// Asks the cache for every cache line of chunk `chunk`.
    #[inline(always)]
    fn prefetch_chunk(&self, chunk: usize) {
        #[cfg(target_arch = "x86_64")]
        if let Some(c) = self.chunks.get(chunk) {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let p = (c as *const Chunk).cast::<i8>();
            for offset in (0..size_of::<Chunk>()).step_by(64) {
                // SAFETY: prefetching has no architectural effect; the address lies inside
                // the chunk, which starts on a cache line.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(p.add(offset)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = chunk;
    }

    /// The chunks (first, last) holding the triangles of `node`'s leaves, or None.
    pub(super) fn chunks_of(node: &CwBvhNode) -> Option<(u32, u32)> {
        let inner = u32::from(node.imask);
        let (mut lo, mut hi) = (u32::MAX, 0);
        for (j, &meta) in node.child_meta.iter().enumerate() {
            if meta == 0 || inner & (1 << j) != 0 {
                continue;
            }
            let (offset, count) = (u32::from(meta & 0x1f), (meta >> 5).count_ones());
            if count == 0 {
                continue;
            }
            lo = lo.min(node.primitive_base_idx + offset);
            hi = hi.max(node.primitive_base_idx + offset + count - 1);
        }
        (lo <= hi).then(|| (lo / LANES as u32, hi / LANES as u32))
    }

    /// Closest of the triangles of `chunk` whose lanes are set in `lanes`: lane and
    /// barycentrics.
    #[inline(always)]
    fn closest_in_chunk(&self, chunk: usize, lanes: u32, ray: &BvhRay, tmax: f32) -> Option<(f32, u32, Vec2)> {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"))]
        {
            // SAFETY: the target has AVX2 and FMA (checked at compile time), and `chunk` holds
            // a triangle of the mesh (a set lane), so the chunk exists.
            unsafe { avx2::closest_in_chunk(&self.chunks[chunk].0[..CHUNK], lanes, ray, tmax) }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma")))]
        {
            self.closest_in_chunk_scalar(chunk * LANES, lanes, ray, tmax)
        }
    }

    /// [`Self::closest_in_chunk`] one triangle at a time, highest lane first.
    #[cfg_attr(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"), allow(dead_code))]
    fn closest_in_chunk_scalar(&self, first: usize, block: u32, ray: &BvhRay, mut tmax: f32) -> Option<(f32, u32, Vec2)> {
        let mut best = None;
        for j in super::bits_high_first(block) {
            if let Some((t, u, v)) = self.triangle(first + j as usize).intersect(ray.origin, ray.direction, ray.tmin, tmax) {
                tmax = t;
                best = Some((t, j, Vec2::new(u, v)));
            }
        }
        best
    }
}

/// Children of `node` the ray enters before `ray.tmax`, as the CWBVH hit mask obvhs's
/// traversal expects (`CwBvhNode::intersect_ray`'s result). With `fetch_inner`, the inner
/// children entered are prefetched from `nodes` and handed to `ahead` by index: obvhs's walk
/// visits every one of them (it keeps no distances to skip any), and a mesh bigger than the
/// cache waited on each node in turn. A BVH that stays in the core's own caches walks without
/// ([`super::NODES_AHEAD_BYTES`]).
#[inline(always)]
pub(super) fn node_hits(
    nodes: &[CwBvhNode],
    node: &CwBvhNode,
    ray: &BvhRay,
    oct_inv4: u32,
    fetch_inner: bool,
    ahead: impl Fn(usize),
) -> u32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        // SAFETY: the target has AVX2 (checked at compile time).
        let (entered, hits) = unsafe { avx2::children_entered(node, ray, oct_inv4) };
        if fetch_inner {
            prefetch_inner(nodes, node, entered, ahead);
        }
        hits
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        let _ = (nodes, fetch_inner, ahead);
        node.intersect_ray(ray, oct_inv4)
    }
}

/// Asks the cache for the inner children of `node` whose slot bits are set in `entered`
/// (both cache lines of each 80-byte node), so their fetches overlap with each other and with
/// the work before they are visited.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn prefetch_inner(nodes: &[CwBvhNode], node: &CwBvhNode, entered: u32, ahead: impl Fn(usize)) {
    use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
    let imask = u32::from(node.imask);
    let mut inner = entered & imask;
    while inner != 0 {
        let j = inner.trailing_zeros();
        inner &= inner - 1;
        // Inner children are stored in slot order from `child_base_idx`.
        let child = node.child_base_idx as usize + (imask & ((1 << j) - 1)).count_ones() as usize;
        if let Some(c) = nodes.get(child) {
            let p = (c as *const CwBvhNode).cast::<i8>();
            // SAFETY: prefetching has no architectural effect; `p + 64` lies within the
            // node's 80 bytes.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.add(64));
            }
            ahead(child);
        }
    }
}

impl ChunkBounds {
    /// The padded bounds of the chunks of `lanes` (at most [`MAX_BOUNDED`] of them).
    fn of(lanes: &TriangleLanes) -> Self {
        let empty = BoundsPass { lo: [[f32::MAX; LANES]; 3], hi: [[-f32::MAX; LANES]; 3] };
        let mut b = ChunkBounds { passes: vec![empty; lanes.chunks.len().div_ceil(LANES)].into(), chunks: 0 };
        for i in 0..lanes.count {
            let (t, c) = (lanes.triangle(i), i / LANES);
            b.chunks |= 1 << c;
            let (pass, j) = (&mut b.passes[c / LANES], c % LANES);
            for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
                for k in 0..3 {
                    pass.lo[k][j] = pass.lo[k][j].min(v[k]);
                    pass.hi[k][j] = pass.hi[k][j].max(v[k]);
                }
            }
        }
        for c in 0..lanes.chunks.len() {
            let (pass, j) = (&mut b.passes[c / LANES], c % LANES);
            let size =
                (0..3).map(|k| (pass.hi[k][j] - pass.lo[k][j]).max(pass.lo[k][j].abs()).max(pass.hi[k][j].abs())).fold(0.0, f32::max);
            for k in 0..3 {
                pass.lo[k][j] -= size * BOUNDS_PAD;
                pass.hi[k][j] += size * BOUNDS_PAD;
            }
        }
        b
    }

    /// The chunks (bit `c`: chunk `c`) whose bounds the ray meets within (`tmin`, `tmax`).
    #[inline(always)]
    fn met(&self, ray: &BvhRay) -> u32 {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        {
            // SAFETY (both calls): the target has AVX2 (checked at compile time).
            let mut met = unsafe { avx2::chunks_met(&self.passes[0], ray) };
            for p in 1..self.passes.len() {
                met |= unsafe { avx2::chunks_met(&self.passes[p], ray) } << (p * LANES);
            }
            met & self.chunks
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
        {
            self.met_scalar(ray)
        }
    }

    /// [`Self::met`] one chunk at a time, the same operations lane by lane.
    #[cfg_attr(all(target_arch = "x86_64", target_feature = "avx2"), allow(dead_code))]
    fn met_scalar(&self, ray: &BvhRay) -> u32 {
        let mut met = 0;
        for c in (0..self.passes.len() * LANES).filter(|c| self.chunks & (1 << c) != 0) {
            let (pass, j) = (&self.passes[c / LANES], c % LANES);
            let (mut near, mut far, mut inside) = (ray.tmin, ray.tmax, true);
            for k in 0..3 {
                let (o, d, lo, hi) = (ray.origin[k], ray.direction[k], pass.lo[k][j], pass.hi[k][j]);
                if d.abs() < PARALLEL {
                    inside &= lo <= o && o <= hi;
                } else {
                    let inv = 1.0 / d;
                    let (t0, t1) = ((lo - o) * inv, (hi - o) * inv);
                    let (t_in, t_out) = if d < 0.0 { (t1, t0) } else { (t0, t1) };
                    near = near.max(t_in);
                    far = far.min(t_out);
                }
            }
            if inside && near <= far {
                met |= 1 << c;
            }
        }
        met
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod avx2 {
    use std::arch::x86_64::*;

    use glam::{Vec2, Vec3A};
    use obvhs::{cwbvh::node::CwBvhNode, ray::Ray as BvhRay};

    use super::{BoundsPass, LANES, NODE_TMIN, PARALLEL};

    /// [`super::ChunkBounds::met`] for all eight lanes in one pass: the same operations as
    /// the scalar test, lane by lane (`_mm256_max_ps`/`_mm256_min_ps` meet no NaN: the
    /// distances are finite or infinite, never 0·∞).
    #[inline(always)]
    pub(super) unsafe fn chunks_met(pass: &BoundsPass, ray: &BvhRay) -> u32 {
        unsafe {
            let (mut near, mut far) = (_mm256_set1_ps(ray.tmin), _mm256_set1_ps(ray.tmax));
            let mut inside = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
            for k in 0..3 {
                let (o, d) = (ray.origin[k], ray.direction[k]);
                let (lo, hi) = (_mm256_load_ps(pass.lo[k].as_ptr()), _mm256_load_ps(pass.hi[k].as_ptr()));
                let o8 = _mm256_set1_ps(o);
                if d.abs() < PARALLEL {
                    let between = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(lo, o8), _mm256_cmp_ps::<_CMP_LE_OQ>(o8, hi));
                    inside = _mm256_and_ps(inside, between);
                } else {
                    // Not `ray.inv_direction`: obvhs clamps it for components below ε, which
                    // would bring a face the ray runs almost along within its reach.
                    let inv = _mm256_set1_ps(1.0 / d);
                    let (t0, t1) = (_mm256_mul_ps(_mm256_sub_ps(lo, o8), inv), _mm256_mul_ps(_mm256_sub_ps(hi, o8), inv));
                    let (t_in, t_out) = if d < 0.0 { (t1, t0) } else { (t0, t1) };
                    // The scalar `near.max(t_in)`: the same value when neither is NaN.
                    near = _mm256_max_ps(near, t_in);
                    far = _mm256_min_ps(far, t_out);
                }
            }
            let met = _mm256_and_ps(inside, _mm256_cmp_ps::<_CMP_LE_OQ>(near, far));
            _mm256_movemask_ps(met) as u32
        }
    }

    /// Eight quantised planes widened to floats.
    #[inline(always)]
    unsafe fn planes(q: &[u8; 8]) -> __m256 {
        unsafe { _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(q.as_ptr().cast()))) }
    }

    /// Entry and exit distances of the ray through the eight child slabs of one axis: near
    /// and far plane chosen by the direction's sign, `plane * scale + offset` unfused, as
    /// obvhs computes them.
    #[inline(always)]
    unsafe fn slab(lo: &[u8; 8], hi: &[u8; 8], negative: bool, scale: f32, offset: f32) -> (__m256, __m256) {
        unsafe {
            let (near, far) = if negative { (planes(hi), planes(lo)) } else { (planes(lo), planes(hi)) };
            let (scale, offset) = (_mm256_set1_ps(scale), _mm256_set1_ps(offset));
            (_mm256_add_ps(_mm256_mul_ps(near, scale), offset), _mm256_add_ps(_mm256_mul_ps(far, scale), offset))
        }
    }

    /// The child slots of `node` the ray enters (bit `j`: slot `j`), and the CWBVH hit mask
    /// of those children as obvhs's node test builds it (empty slots, all-zero boxes, add
    /// nothing to it). The max/min order is obvhs's, so NaN lanes (an axis the ray runs
    /// parallel to) resolve the same way.
    #[inline(always)]
    pub(super) unsafe fn children_entered(node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32) -> (u32, u32) {
        let scale = node.compute_extent() * ray.inv_direction;
        let offset = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
        unsafe {
            let (near_x, far_x) = slab(&node.child_min_x, &node.child_max_x, ray.direction.x < 0.0, scale.x, offset.x);
            let (near_y, far_y) = slab(&node.child_min_y, &node.child_max_y, ray.direction.y < 0.0, scale.y, offset.y);
            let (near_z, far_z) = slab(&node.child_min_z, &node.child_max_z, ray.direction.z < 0.0, scale.z, offset.z);
            let enter = _mm256_max_ps(near_x, _mm256_max_ps(near_y, near_z));
            let exit = _mm256_min_ps(far_x, _mm256_min_ps(far_y, far_z));
            let enter = _mm256_max_ps(enter, _mm256_set1_ps(NODE_TMIN));
            let exit = _mm256_min_ps(exit, _mm256_set1_ps(ray.tmax));
            let entered = _mm256_cmp_ps::<_CMP_LE_OS>(enter, exit);
            (_mm256_movemask_ps(entered) as u32, hit_mask(node, oct_inv4, _mm256_castps_si256(entered)))
        }
    }

    /// The CWBVH hit mask of the children whose lanes are set in `entered`: obvhs's
    /// `get_child_and_index_bits` and its per-child loop, all eight slots in one pass. An inner
    /// child sets its traversal-order bit in the top byte (its meta index, biased by 24, XOR
    /// the inverse ray octant); a leaf sets its primitives' bits in the low 24 (its unary
    /// primitive count shifted by its first primitive's offset).
    #[inline(always)]
    unsafe fn hit_mask(node: &CwBvhNode, oct_inv4: u32, entered: __m256i) -> u32 {
        unsafe {
            let meta = _mm256_cvtepu8_epi32(_mm_loadl_epi64(node.child_meta.as_ptr().cast()));
            // An inner child's meta index is 24..32, so bits 3 and 4 are both set; a leaf's
            // offset (below 24) never sets both.
            let inner_bit = _mm256_and_si256(_mm256_and_si256(meta, _mm256_slli_epi32::<1>(meta)), _mm256_set1_epi32(0x10));
            let inner = _mm256_cmpeq_epi32(inner_bit, _mm256_set1_epi32(0x10));
            let octant = _mm256_and_si256(inner, _mm256_set1_epi32((oct_inv4 & 0xff) as i32));
            let shift = _mm256_and_si256(_mm256_xor_si256(meta, octant), _mm256_set1_epi32(0x1f));
            let child_bits = _mm256_and_si256(_mm256_srli_epi32::<5>(meta), _mm256_set1_epi32(0b111));
            let bits = _mm256_and_si256(_mm256_sllv_epi32(child_bits, shift), entered);
            let half = _mm_or_si128(_mm256_castsi256_si128(bits), _mm256_extracti128_si256::<1>(bits));
            let quarter = _mm_or_si128(half, _mm_shuffle_epi32::<0b01_00_11_10>(half));
            let all = _mm_or_si128(quarter, _mm_shuffle_epi32::<0b10_11_00_01>(quarter));
            _mm_cvtsi128_si32(all) as u32
        }
    }

    /// Components `row .. row + 3` of a chunk's eight triangles.
    #[inline(always)]
    fn load3(chunk: &[f32], row: usize) -> [__m256; 3] {
        let at = |c: usize| {
            let lanes = &chunk[(row + c) * LANES..][..LANES];
            // SAFETY: AVX2 is on (the module's cfg) and `lanes` holds eight floats.
            unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
        };
        [at(0), at(1), at(2)]
    }

    /// `a × b` lane by lane, rounded as glam's `Vec3A::cross` with FMA rounds it:
    /// `x = a.y·b.z − b.y·a.z` with the first product rounded and the second fused.
    #[inline(always)]
    unsafe fn cross(a: [__m256; 3], b: [__m256; 3]) -> [__m256; 3] {
        unsafe {
            [
                _mm256_fnmadd_ps(b[1], a[2], _mm256_mul_ps(a[1], b[2])),
                _mm256_fnmadd_ps(b[2], a[0], _mm256_mul_ps(a[2], b[0])),
                _mm256_fnmadd_ps(b[0], a[1], _mm256_mul_ps(a[0], b[1])),
            ]
        }
    }

    /// `a · b` lane by lane, summed as glam's `Vec3A::dot`: `(x·x' + y·y') + z·z'`, unfused.
    #[inline(always)]
    unsafe fn dot(a: [__m256; 3], b: [__m256; 3]) -> __m256 {
        unsafe {
            let xy = _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1]));
            _mm256_add_ps(xy, _mm256_mul_ps(a[2], b[2]))
        }
    }

    #[inline(always)]
    fn splat3(v: Vec3A) -> [__m256; 3] {
        unsafe { [_mm256_set1_ps(v.x), _mm256_set1_ps(v.y), _mm256_set1_ps(v.z)] }
    }

    /// Möller-Trumbore over eight triangles at once, the same operations as
    /// [`super::RtTriangle::intersect`] lane by lane; returns the nearest hit among the
    /// lanes set in `block` (ties: the highest lane) as (t, lane, barycentrics).
    #[inline(always)]
    pub(super) unsafe fn closest_in_chunk(chunk: &[f32], block: u32, ray: &BvhRay, tmax: f32) -> Option<(f32, u32, Vec2)> {
        unsafe {
            let [v0, e1, e2] = [load3(chunk, 0), load3(chunk, 3), load3(chunk, 6)];
            let (o, d) = (splat3(ray.origin), splat3(ray.direction));
            let p = cross(d, e2);
            let det = dot(e1, p);
            let abs_det = _mm256_andnot_ps(_mm256_set1_ps(-0.0), det);
            let mut ok = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_NEQ_OQ>(det, _mm256_setzero_ps()),
                _mm256_cmp_ps::<_CMP_LT_OQ>(abs_det, _mm256_set1_ps(f32::INFINITY)),
            );
            let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
            let s = [_mm256_sub_ps(o[0], v0[0]), _mm256_sub_ps(o[1], v0[1]), _mm256_sub_ps(o[2], v0[2])];
            let u = _mm256_mul_ps(dot(s, p), inv);
            let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
            ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(u, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(u, one)));
            let q = cross(s, e1);
            let v = _mm256_mul_ps(dot(d, q), inv);
            // Rejected when v < 0 or u + v > 1, both false for NaN, as in the scalar test.
            let outside = _mm256_or_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(v, zero), _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_add_ps(u, v), one));
            ok = _mm256_andnot_ps(outside, ok);
            let t = _mm256_mul_ps(dot(e2, q), inv);
            ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_set1_ps(ray.tmin)));
            ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(tmax)));
            let hits = _mm256_movemask_ps(ok) as u32 & block;
            if hits == 0 {
                return None;
            }
            nearest(hits, t, u, v)
        }
    }

    /// The hit lane with the smallest `t`, the highest such lane on ties.
    #[inline(always)]
    unsafe fn nearest(hits: u32, t: __m256, u: __m256, v: __m256) -> Option<(f32, u32, Vec2)> {
        let mut ts = [0.0f32; 8];
        unsafe { _mm256_storeu_ps(ts.as_mut_ptr(), t) };
        let (mut best, mut lane) = (f32::INFINITY, 0);
        for j in super::super::bits_high_first(hits) {
            if ts[j as usize] < best {
                (best, lane) = (ts[j as usize], j);
            }
        }
        let (mut us, mut vs) = ([0.0f32; 8], [0.0f32; 8]);
        unsafe {
            _mm256_storeu_ps(us.as_mut_ptr(), u);
            _mm256_storeu_ps(vs.as_mut_ptr(), v);
        }
        Some((best, lane, Vec2::new(us[lane as usize], vs[lane as usize])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Pcg32, uniform_sphere};
    use obvhs::{aabb::Aabb, ray::Ray as BvhRay};

    fn point(rng: &mut Pcg32, size: f32) -> Vec3A {
        Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * size - Vec3A::splat(size / 2.0)
    }

    /// Random rays through a unit-sized scene, a fifth of them along an axis (their slab
    /// tests meet 0·∞ = NaN, which the node tests must resolve alike).
    fn rays(rng: &mut Pcg32, n: usize) -> Vec<BvhRay> {
        (0..n)
            .map(|i| {
                let mut d = Vec3A::from(uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())));
                if i % 5 == 0 {
                    d = Vec3A::AXES[i / 5 % 3] * if i % 2 == 0 { 1.0 } else { -1.0 };
                }
                super::super::bvh_ray(point(rng, 3.0), d, if i % 3 == 0 { f32::INFINITY } else { 2.0 * rng.next_f32() })
            })
            .collect()
    }

    /// Small random triangles, some degenerate (a repeated corner, a sliver).
    fn soup(rng: &mut Pcg32, n: usize) -> Vec<RtTriangle> {
        (0..n)
            .map(|i| {
                let v0 = point(rng, 2.0);
                let e1 = point(rng, 0.3);
                let e2 = match i % 17 {
                    0 => Vec3A::ZERO,
                    1 => e1 * 2.0,
                    _ => point(rng, 0.3),
                };
                RtTriangle { v0, e1, e2 }
            })
            .collect()
    }

    #[test]
    fn node_test_finds_the_children_obvhs_finds() {
        let mut rng = Pcg32::new(3, 1);
        let tris = soup(&mut rng, 3000);
        let aabbs: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let mut a = Aabb::empty();
                [t.v0, t.v0 + t.e1, t.v0 + t.e2].into_iter().for_each(|v| {
                    a.extend(v);
                });
                a
            })
            .collect();
        let bvh = super::super::build_bounded(&aabbs, super::super::BuildQuality::Medium);
        let mut compared = 0;
        for ray in rays(&mut rng, 400) {
            let oct = bvh.new_traversal(ray.direction).oct_inv4;
            for node in &bvh.nodes {
                assert_eq!(node_hits(&bvh.nodes, node, &ray, oct, true, |_| {}), node.intersect_ray(&ray, oct), "{ray:?}\n{node:?}");
                compared += 1;
            }
        }
        assert!(compared > 100_000, "{compared} node tests");
    }

    /// Every triangle a node's test lets a ray into lies in the chunks `chunks_of` names for
    /// the node, which a walk prefetches before the node arrives; a node with leaves names
    /// some, one without names none.
    #[test]
    fn a_nodes_leaf_chunks_hold_every_triangle_its_test_enters() {
        let mut rng = Pcg32::new(5, 3);
        let tris = soup(&mut rng, 2000);
        let aabbs: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(&[t.v0, t.v0 + t.e1, t.v0 + t.e2])).collect();
        let bvh = super::super::build_bounded(&aabbs, super::super::BuildQuality::Medium);
        let mut entered = 0;
        for ray in rays(&mut rng, 600) {
            let oct = bvh.new_traversal(ray.direction).oct_inv4;
            for node in &bvh.nodes {
                let leaves = node_hits(&bvh.nodes, node, &ray, oct, true, |_| {}) & 0x00ff_ffff;
                let chunks = TriangleLanes::chunks_of(node);
                let has_leaves = node.child_meta.iter().enumerate().any(|(j, &m)| m != 0 && node.imask & (1 << j) == 0);
                assert_eq!(chunks.is_some(), has_leaves, "{node:?}");
                for j in super::super::bits_high_first(leaves) {
                    let (first, last) = chunks.expect("a node whose test enters leaves has leaf chunks");
                    let chunk = (node.primitive_base_idx + j) / LANES as u32;
                    assert!((first..=last).contains(&chunk), "triangle {} outside chunks {first}..={last}", node.primitive_base_idx + j);
                    entered += 1;
                }
            }
        }
        assert!(entered > 1000, "{entered} leaf triangles entered");
    }

    /// The wide closest-hit and any-hit tests against the scalar Möller-Trumbore applied one
    /// triangle at a time, highest index first with the distance shortened at each hit (the
    /// walk they replace): the same hit, bit for bit, over random groups of triangles.
    #[test]
    fn triangle_lanes_hit_what_the_scalar_test_hits() {
        let mut rng = Pcg32::new(9, 2);
        let tris = soup(&mut rng, 40);
        let ids: Vec<u32> = (0..tris.len() as u32).map(|i| 7 * i + 3).collect();
        let lanes = TriangleLanes::new(&tris, &ids);
        let mut hits = 0;
        for (i, mut ray) in rays(&mut rng, 20_000).into_iter().enumerate() {
            let base = (rng.next_f32() * 16.0) as u32;
            let group = (rng.next_f32() * (1 << 24) as f32) as u32 | 1;
            // Most rays aimed at a point near one of the group's triangles, some of them just
            // outside it; the rest random.
            if i % 4 != 0 {
                let t = &tris[(base + 31 - group.leading_zeros()) as usize];
                let target = t.v0 + t.e1 * (1.2 * rng.next_f32() - 0.1) + t.e2 * (0.6 * rng.next_f32() - 0.05);
                ray = super::super::bvh_ray(ray.origin, (target - ray.origin).normalize(), ray.tmax.max(4.0));
            }
            let mut tmax = ray.tmax;
            let mut expected = None;
            for j in (0..24).rev().filter(|j| group & (1 << j) != 0) {
                if let Some((t, u, v)) = tris[(base + j) as usize].intersect(ray.origin, ray.direction, ray.tmin, tmax) {
                    tmax = t;
                    expected = Some((t.to_bits(), base + j, u.to_bits(), v.to_bits()));
                }
            }
            let found = lanes.closest(base, group, &ray).map(|(t, id, b)| (t.to_bits(), id, b.x.to_bits(), b.y.to_bits()));
            assert_eq!(found, expected, "{ray:?} base {base} group {group:#x}");
            assert_eq!(lanes.any(base, group, &ray), expected.is_some());
            hits += expected.is_some() as usize;
        }
        // Enough hits that a wrong lane or rounding would show (about half the rays hit).
        assert!(hits > 5_000, "{hits} hits");
    }

    /// Rays that make the chunk bounds' test meet its edge cases: aimed at the triangles'
    /// corners and edges (hits on the bounds' faces), along the axes, lying in an axis plane
    /// through a corner (a direction component of exactly zero, the origin on a face), and
    /// random ones; short and endless.
    fn bounds_rays(rng: &mut Pcg32, tris: &[RtTriangle], n: usize) -> Vec<BvhRay> {
        let corners: Vec<Vec3A> = tris.iter().flat_map(|t| [t.v0, t.v0 + t.e1, t.v0 + t.e2]).collect();
        let mut out = rays(rng, n / 2);
        for i in 0..n / 2 {
            let c = corners[i % corners.len()];
            let target = match i % 4 {
                0 => c,
                1 => c.lerp(corners[(i * 7 + 1) % corners.len()], rng.next_f32()),
                _ => c + (point(rng, 0.02)),
            };
            let mut o = point(rng, 3.0);
            if i % 5 == 0 {
                // In the plane of a corner's coordinate: the ray never leaves it.
                let k = i / 5 % 3;
                o[k] = target[k];
            }
            let d = (target - o).normalize_or(Vec3A::X);
            let tmax = if i % 3 == 0 { f32::INFINITY } else { (target - o).length() * (0.5 + rng.next_f32()) };
            out.push(super::super::bvh_ray(o, d, tmax));
        }
        for (i, axis) in Vec3A::AXES.into_iter().cycle().take(600).enumerate() {
            let c = corners[i % corners.len()];
            let o = c - axis * 2.0 + if i % 2 == 0 { Vec3A::ZERO } else { point(rng, 0.01) };
            out.push(super::super::bvh_ray(o, axis, if i % 3 == 0 { 1.5 } else { f32::INFINITY }));
        }
        out
    }

    /// The scan of a bounded mesh skips only chunks that hold no hit: it finds what the scan
    /// of every chunk finds, bit for bit, closest hit and occlusion alike, on meshes of six
    /// to thirty-two chunks (the bounded ones; one to four passes) made of random triangles, a
    /// closed box and spheres, unless that hit lies outside its own chunk's bounds (a rounding
    /// artefact); and the eight-wide bounds test agrees with the scalar one lane for lane,
    /// rays skimming a face included.
    #[test]
    fn bounds_skip_only_chunks_without_a_hit() {
        let mut rng = Pcg32::new(23, 5);
        let sphere = |rings: u32, segments: u32| {
            let m = crate::geometry::Mesh::uv_sphere(rings, segments);
            m.indices
                .iter()
                .map(|&[a, b, c]| tri(m.positions[a as usize].into(), m.positions[b as usize].into(), m.positions[c as usize].into()))
                .collect::<Vec<_>>()
        };
        let meshes = [
            soup(&mut rng, 41),
            soup(&mut rng, 64),
            soup(&mut rng, 121),
            soup(&mut rng, 250),
            sphere(4, 6),
            sphere(4, 8),
            sphere(4, 12),
            sphere(8, 8),
            sphere(8, 16),
            cornell_like(),
        ];
        let (mut hits, mut skipped, mut spurious) = (0, 0, 0);
        for tris in meshes {
            let ids: Vec<u32> = (0..tris.len() as u32).collect();
            let lanes = TriangleLanes::new(&tris, &ids);
            let bounds = lanes.bounds.as_ref().expect("six to thirty-two chunks are bounded");
            for ray in bounds_rays(&mut rng, &tris, 6000) {
                let every = lanes.closest_in(lanes.every_chunk(), &ray);
                let culled = lanes.closest_of_all(&ray);
                let bits = |h: Option<LaneHit>| h.map(|(t, id, b)| (t.to_bits(), id, b.x.to_bits(), b.y.to_bits()));
                if bits(culled) != bits(every) {
                    // Möller-Trumbore's rounding can accept a ray grazing a sliver (a UV
                    // sphere's pole) at a point nowhere near it. Only such a hit, outside
                    // its own chunk's bounds, may be skipped.
                    let (t, id, _) = every.expect("the scan of every chunk finds what the culled scan finds");
                    let (p, c) = (ray.origin + ray.direction * t, id as usize / LANES);
                    let (pass, j) = (&bounds.passes[c / LANES], c % LANES);
                    assert!((0..3).any(|k| p[k] < pass.lo[k][j] || p[k] > pass.hi[k][j]), "{ray:?} skipped a hit inside its bounds");
                    spurious += 1;
                }
                assert_eq!(lanes.any_of_all(&ray), culled.is_some(), "{ray:?}");
                assert_eq!(lanes.any_in(lanes.every_chunk(), &ray), every.is_some(), "{ray:?}");
                assert_eq!(bounds.met(&ray), bounds.met_scalar(&ray), "{ray:?}");
                hits += usize::from(every.is_some());
                skipped += (bounds.chunks & !bounds.met(&ray)).count_ones() as usize;
            }
            // Rays that run almost parallel to a face of a chunk's bounds, just outside it, reach
            // the face long after they have left the box along it. A reciprocal clamped for
            // small components (obvhs's `safe_inverse`, 1/ε) would bring the face within reach
            // (at t ≈ 8) and meet the chunk.
            for ray in skimming_rays(bounds) {
                assert_eq!(bounds.met(&ray), bounds.met_scalar(&ray), "{ray:?}");
                assert_eq!(bounds.met(&ray) & 1, 0, "{ray:?} met the chunk it skims");
            }
        }
        // Both kinds are there to compare: hits, and chunks the bounds let the scan skip.
        assert!(hits > 10_000 && skipped > 10_000, "{hits} hits, {skipped} chunks skipped");
        // 24 of 23 494 here, rays aimed at the spheres' poles, where slivers meet.
        assert!(spurious <= hits / 500, "{spurious} spurious hits skipped of {hits}");
    }

    /// Rays skimming the faces of chunk 0's bounds from just outside (1e-6 of the face's
    /// coordinate away), along the face across the box at 1e-3 a unit of t, with a component of
    /// 1e-12 towards the face: each crosses the box's span along the face between t = 500 and
    /// 1500 extents and reaches the face only at t = 1e6, so none meets the chunk.
    fn skimming_rays(bounds: &ChunkBounds) -> Vec<BvhRay> {
        let pass = &bounds.passes[0];
        let (lo, hi) = (Vec3A::from_array([0, 1, 2].map(|k| pass.lo[k][0])), Vec3A::from_array([0, 1, 2].map(|k| pass.hi[k][0])));
        let mut out = Vec::new();
        for k in 0..3 {
            for (face, inwards) in [(lo[k], 1.0f32), (hi[k], -1.0)] {
                let (u, v) = ((k + 1) % 3, (k + 2) % 3);
                let scale = face.abs().max(1.0);
                let mut o = (lo + hi) * 0.5;
                o[k] = face - inwards * 1e-6 * scale;
                o[u] = lo[u] - 0.5 * (hi[u] - lo[u]);
                let mut d = Vec3A::ZERO;
                d[u] = 1e-3;
                d[k] = inwards * 1e-12 * scale;
                out.push(super::super::bvh_ray(o, d, f32::INFINITY));
                o[v] = lo[v] + 0.25 * (hi[v] - lo[v]);
                out.push(super::super::bvh_ray(o, d, f32::INFINITY));
            }
        }
        out
    }

    /// The triangle with corners `a`, `b`, `c`.
    fn tri(a: Vec3A, b: Vec3A, c: Vec3A) -> RtTriangle {
        RtTriangle { v0: a, e1: b - a, e2: c - a }
    }

    /// A closed box of unit quads around the origin and two boxes inside it (the Cornell box's
    /// shape, 36 triangles, five chunks), with a sixth chunk of small quads: 48 triangles.
    fn cornell_like() -> Vec<RtTriangle> {
        let quad = |c: Vec3A, u: Vec3A, v: Vec3A| [tri(c - u - v, c + u - v, c + u + v), tri(c - u - v, c + u + v, c - u + v)];
        let (x, y, z) = (Vec3A::X, Vec3A::Y, Vec3A::Z);
        let mut tris = Vec::new();
        for (size, at) in [
            (1.0, Vec3A::ZERO),
            (0.3, Vec3A::new(0.4, -0.7, 0.2)),
            (0.25, Vec3A::new(-0.4, -0.75, -0.3)),
            (0.05, Vec3A::new(0.0, 0.9, 0.0)),
        ] {
            for (n, u, v) in [(x, y, z), (y, z, x), (z, x, y)] {
                tris.extend(quad(at + n * size, u * size, v * size));
                tris.extend(quad(at - n * size, u * size, v * size));
            }
        }
        tris.truncate(48);
        tris
    }

    /// Each triangle's components and original index come back as stored, across chunk
    /// boundaries and in the padded last chunk, and every chunk starts on a cache line.
    #[test]
    fn triangle_lanes_keep_each_triangle_and_its_index() {
        let mut rng = Pcg32::new(4, 1);
        let tris = soup(&mut rng, 21);
        let ids: Vec<u32> = (0..21).map(|i| u32::MAX - 5 * i).collect();
        let lanes = TriangleLanes::new(&tris, &ids);
        for (i, (t, &id)) in tris.iter().zip(&ids).enumerate() {
            let back = lanes.triangle(i);
            assert_eq!([back.v0, back.e1, back.e2], [t.v0, t.e1, t.e2], "triangle {i}");
            assert_eq!(lanes.id(i), id, "triangle {i}");
        }
        assert_eq!(lanes.bytes(), 3 * 320);
        assert!(lanes.chunks.iter().all(|c| (c as *const Chunk as usize).is_multiple_of(64)));
    }

    #[test]
    fn equal_distances_resolve_to_the_highest_index() {
        let quad = RtTriangle { v0: Vec3A::new(-1.0, -1.0, 0.0), e1: Vec3A::new(2.0, 0.0, 0.0), e2: Vec3A::new(0.0, 2.0, 0.0) };
        let lanes = TriangleLanes::new(&[quad; 20], &[0; 20]);
        let ray = super::super::bvh_ray(Vec3A::new(-0.5, -0.5, 1.0), Vec3A::NEG_Z, f32::INFINITY);
        assert_eq!(lanes.closest(0, 0b1001_0000_0000_0110_0001, &ray).map(|h| h.1), Some(19));
        assert_eq!(lanes.closest(2, 0b11, &ray).map(|h| h.1), Some(3));
    }
}
