//! Subdivision surfaces: a `UsdGeomMesh` whose `subdivisionScheme` is `catmullClark`, `loop`
//! or `bilinear` is a control cage. Pixar's OpenSubdiv (Far, through `opensubdiv-petite`)
//! applies the scheme with the mesh's creases, corners, holes and boundary rule, and its limit
//! stencils give points on the limit surface with their two tangents. We tessellate the limit
//! surface on a grid per ptex face (2^level segments per cage edge, the face count uniform
//! refinement to that level would make) and take each normal from the tangents, so normals are
//! the limit surface's own and stay discontinuous across sharp creases.
//!
//! Grid points on cage edges are shared with the neighbouring face by a topological key, so
//! the tessellation is watertight. Face-varying and varying primvars are interpolated linearly
//! over each ptex face (OpenSubdiv's `faceVaryingLinearInterpolation = all`): the binding does
//! not expose face-varying channels. Vertex primvars follow the limit stencils exactly.

use std::collections::HashMap;

use rayon::prelude::*;

use glam::{Vec2, Vec3};
use opensubdiv_petite::far::{
    AdaptiveRefinementOptions, BoundaryInterpolation, CreasingMethod, FaceVaryingLinearInterpolation, LimitStencilTable,
    LimitStencilTableOptions, LocationArray, Scheme, TopologyDescriptor, TopologyRefiner, TopologyRefinerOptions, TriangleSubdivision,
};

use super::mesh::{MeshSource, Sizes};

/// The subdivision attributes of a `UsdGeomMesh`, as authored.
#[derive(Clone, Debug, Default)]
pub struct SubdivTags {
    /// `subdivisionScheme`: `catmullClark` (USD's fallback), `loop` or `bilinear`.
    pub scheme: String,
    /// `interpolateBoundary`: `none`, `edgeOnly` or `edgeAndCorner` (the fallback).
    pub interpolate_boundary: String,
    /// `triangleSubdivisionRule`: `catmullClark` (the fallback) or `smooth`.
    pub triangle_subdivision_rule: String,
    /// `creaseIndices`, `creaseLengths`, `creaseSharpnesses`.
    pub crease_indices: Vec<i64>,
    pub crease_lengths: Vec<i64>,
    pub crease_sharpnesses: Vec<f32>,
    /// `cornerIndices`, `cornerSharpnesses`.
    pub corner_indices: Vec<i64>,
    pub corner_sharpnesses: Vec<f32>,
    /// `holeIndices`: faces left out of the surface.
    pub hole_indices: Vec<i64>,
}

impl SubdivTags {
    /// The schemes this module refines.
    pub fn is_subdivided(&self) -> bool {
        matches!(self.scheme.as_str(), "catmullClark" | "loop" | "bilinear")
    }
}

/// The highest refinement level accepted (4^8 = 65 536 faces per cage quad).
pub const MAX_LEVEL: u32 = 8;

/// Refined faces one mesh may produce; a higher level that would exceed it is lowered, with a
/// warning, so a client's level and cage size cannot together exhaust memory.
pub const MAX_REFINED_FACES: usize = 8 << 20;

/// Limit-stencil locations evaluated per OpenSubdiv call: stencils take a few hundred bytes
/// each, so large meshes are evaluated in chunks of at most this many.
const LOCATIONS_PER_CHUNK: usize = 1 << 18;

/// The fewest locations one call evaluates when a chunk is split among workers: each call
/// also builds OpenSubdiv's patch table, a few milliseconds for a 100k-face cage.
const MIN_LOCATIONS_PER_CALL: usize = 1 << 14;

/// A refiner lent to the pool thread that evaluates a chunk with it. OpenSubdiv's objects
/// have no thread affinity, and each refiner is used by one thread at a time (they are not
/// shared: whether its const methods may run concurrently is not documented).
struct Owned(TopologyRefiner);

// SAFETY: see above; the binding's type is !Send only because it holds a raw pointer.
unsafe impl Send for Owned {}

/// A refined mesh: polygons (quads, or triangles for Loop) on the limit surface with
/// face-varying limit normals, ready for [`super::mesh::triangulate_with_faces`].
pub struct Refined {
    pub mesh: MeshSource,
    /// The cage face of each refined face (GeomSubsets select by cage face).
    pub cage_face: Vec<u32>,
    /// The level used (lower than asked when [`MAX_REFINED_FACES`] required it).
    pub level: u32,
    /// Largest distance between two faces' evaluations of a point they share (welded into
    /// one vertex): a check that shared points are keyed right, near float rounding.
    pub weld_gap: f32,
}

/// Refines `src` by `tags` at `level` (clamped to 1..=[`MAX_LEVEL`]). Errors name the
/// attribute at fault; warnings (a level lowered, a primvar dropped) go to `warn`.
pub fn refine(src: &MeshSource, tags: &SubdivTags, level: u32, warn: impl FnMut(String)) -> Result<Refined, String> {
    refine_within(src, tags, level, MAX_REFINED_FACES, warn)
}

/// [`refine`] with a face budget of its own (benchmarks measure past the default one).
pub fn refine_within(
    src: &MeshSource,
    tags: &SubdivTags,
    level: u32,
    max_faces: usize,
    warn: impl FnMut(String),
) -> Result<Refined, String> {
    refine_in_chunks(src, tags, level, max_faces, LOCATIONS_PER_CHUNK, warn)
}

/// [`refine_within`] evaluating at most `chunk_locations` limit-stencil locations per
/// OpenSubdiv call, on as many pool threads as there are chunks (up to all of them).
fn refine_in_chunks(
    src: &MeshSource,
    tags: &SubdivTags,
    level: u32,
    max_faces: usize,
    chunk_locations: usize,
    mut warn: impl FnMut(String),
) -> Result<Refined, String> {
    let cage = Cage::new(src, tags)?;
    let asked = level.clamp(1, MAX_LEVEL);
    let level = (1..=asked)
        .rev()
        .find(|&l| cage.refined_faces(l) <= max_faces)
        .ok_or_else(|| format!("{} cage faces refine to more than {max_faces} faces even at level 1", src.counts.len()))?;
    if level < asked {
        warn(format!("refined at level {level}, not {asked}: level {asked} would make more than {max_faces} faces"));
    }
    let threads = rayon::current_num_threads();
    let chunks = cage.chunks(level, locations_per_call(chunk_locations, threads));
    let workers = threads.min(chunks.len()).max(1);
    let mut refiners: Vec<Owned> =
        (0..workers).into_par_iter().map(|_| build_refiner(src, tags, &cage).map(Owned)).collect::<Result<_, _>>()?;
    let primvars = Primvars::gather(src, &mut warn);
    let mut out = Tessellation::new(&cage, level, src.left_handed, &primvars);
    let evaluate = |refiners: &mut [Owned], batch: &[&[Ptex]]| -> Result<Vec<LimitStencilTable>, String> {
        refiners.par_iter_mut().zip(batch).map(|(r, chunk)| limit_stencils(&r.0, chunk, &cage, level)).collect()
    };
    let mut batches = chunks.chunks(workers);
    let mut ready = batches.next().map(|b| (b, evaluate(&mut refiners, b)));
    while let Some((batch, tables)) = ready {
        let tables = tables?;
        let weld = || batch.iter().zip(&tables).for_each(|(chunk, table)| out.add(chunk, table, &primvars));
        ready = rayon::join(weld, || batches.next().map(|b| (b, evaluate(&mut refiners, b)))).1;
    }
    Ok(out.finish(level))
}

/// Locations one OpenSubdiv call evaluates on `threads` pool threads. Two batches of chunks
/// are in flight (one evaluated while the last is welded), a chunk per worker each: smaller
/// chunks keep the stencils held at once near one `chunk_locations` chunk's.
fn locations_per_call(chunk_locations: usize, threads: usize) -> usize {
    (chunk_locations / (2 * threads)).max(chunk_locations.min(MIN_LOCATIONS_PER_CALL))
}

/// Whether refining `src` at `level` spreads over several pool threads (more than one call's
/// locations, estimated from the face counts), each worker holding a refiner of its own.
/// Callers refining many meshes at once run such meshes one at a time, so the refiners alive
/// stay one per thread.
pub fn spreads_over_threads(src: &MeshSource, level: u32) -> bool {
    let side = |level: u32| (1usize << level.min(MAX_LEVEL)) + 1;
    let per_face = |n: i64| if n == 4 { side(level).pow(2) } else { n.max(0) as usize * side(level.saturating_sub(1)).pow(2) };
    let locations: usize = src.counts.iter().map(|&n| per_face(n)).sum();
    locations > locations_per_call(LOCATIONS_PER_CHUNK, rayon::current_num_threads())
}

/// The cage's topology as the tessellation needs it.
struct Cage<'a> {
    src: &'a MeshSource,
    scheme: Scheme,
    /// Offset of each face's first face-vertex.
    starts: Vec<usize>,
    /// The ptex faces that are not holes, in ptex order.
    ptex: Vec<Ptex>,
    /// Crease edges as OpenSubdiv's vertex pairs, and their sharpnesses.
    creases: (Vec<u32>, Vec<f32>),
}

/// One ptex face: a whole quad (or a Loop triangle), or sub-quad `k` of an n-gon, which runs
/// from corner `k` (s along the edge to corner k+1, t along the edge to corner k-1) to the
/// face's centre, as OpenSubdiv parameterises non-quads.
#[derive(Clone, Copy, Debug)]
struct Ptex {
    index: usize,
    face: u32,
    sub: Option<u32>,
}

impl<'a> Cage<'a> {
    fn new(src: &'a MeshSource, tags: &SubdivTags) -> Result<Self, String> {
        let creases = validate(src, tags)?;
        let scheme = match tags.scheme.as_str() {
            "loop" => Scheme::Loop,
            "bilinear" => Scheme::Bilinear,
            _ => Scheme::CatmullClark,
        };
        let mut starts = Vec::with_capacity(src.counts.len());
        let mut at = 0usize;
        for &c in &src.counts {
            starts.push(at);
            at += c as usize;
        }
        let mut holes = vec![false; src.counts.len()];
        for &h in &tags.hole_indices {
            holes[h as usize] = true;
        }
        if tags.interpolate_boundary == "none" {
            // OpenSubdiv leaves faces on a boundary out of the surface under this rule.
            for f in boundary_faces(src, &starts) {
                holes[f] = true;
            }
        }
        let mut ptex = Vec::new();
        let mut index = 0usize;
        for (f, &c) in src.counts.iter().enumerate() {
            let subs = if c == 4 || matches!(scheme, Scheme::Loop) { 1 } else { c as usize };
            if !holes[f] {
                for k in 0..subs {
                    let sub = (subs > 1).then_some(k as u32);
                    ptex.push(Ptex { index: index + k, face: f as u32, sub });
                }
            }
            index += subs;
        }
        Ok(Self { src, scheme, starts, ptex, creases })
    }

    /// Faces uniform refinement to `level` would make (what the tessellation makes).
    /// The grid `p` is tessellated with at `level`.
    fn grid(&self, p: &Ptex, level: u32) -> Grid {
        let r = 1u32 << level;
        match p.sub {
            Some(_) => Grid { r: r / 2, triangle: false },
            None => Grid { r, triangle: matches!(self.scheme, Scheme::Loop) },
        }
    }

    /// The ptex faces in runs of at most `locations` grid points (a face more than that alone).
    fn chunks(&self, level: u32, locations: usize) -> Vec<&[Ptex]> {
        let mut out = Vec::new();
        let mut rest = &self.ptex[..];
        while !rest.is_empty() {
            let (mut take, mut total) = (0, 0);
            while let Some(p) = rest.get(take) {
                let n = self.grid(p, level).len();
                if take > 0 && total + n > locations {
                    break;
                }
                (take, total) = (take + 1, total + n);
            }
            let (chunk, tail) = rest.split_at(take);
            out.push(chunk);
            rest = tail;
        }
        out
    }

    fn refined_faces(&self, level: u32) -> usize {
        let per_quad = 1usize << (2 * level);
        self.ptex.iter().map(|p| if p.sub.is_some() { per_quad / 4 } else { per_quad }).sum()
    }

    /// Cage vertex at corner `k` (wrapping) of `face`.
    fn corner(&self, face: u32, k: i64) -> u32 {
        let n = self.src.counts[face as usize];
        self.src.indices[self.starts[face as usize] + k.rem_euclid(n) as usize] as u32
    }
}

/// Faces with an edge no other face shares.
fn boundary_faces(src: &MeshSource, starts: &[usize]) -> Vec<usize> {
    let mut uses: HashMap<(i64, i64), u32> = HashMap::new();
    let edges = |f: usize| {
        let n = src.counts[f] as usize;
        (0..n).map(move |k| {
            let (a, b) = (src.indices[starts[f] + k], src.indices[starts[f] + (k + 1) % n]);
            (a.min(b), a.max(b))
        })
    };
    for f in 0..src.counts.len() {
        for e in edges(f) {
            *uses.entry(e).or_default() += 1;
        }
    }
    (0..src.counts.len()).filter(|&f| edges(f).any(|e| uses[&e] == 1)).collect()
}

/// Checks everything OpenSubdiv would otherwise trust: counts, index ranges, crease chains,
/// sharpnesses, corners and holes; returns the crease edges. Errors name the attribute.
fn validate(src: &MeshSource, tags: &SubdivTags) -> Result<(Vec<u32>, Vec<f32>), String> {
    let points = src.points.len() as i64;
    let total: i64 = src.counts.iter().sum();
    if src.counts.iter().any(|&c| c < 3) {
        return Err("faceVertexCounts: a subdivision cage needs faces of 3 or more vertices".into());
    }
    if total != src.indices.len() as i64 {
        return Err(format!("faceVertexCounts add up to {total} but faceVertexIndices has {} entries", src.indices.len()));
    }
    if let Some((i, v)) = src.indices.iter().enumerate().find(|(_, v)| !(0..points).contains(*v)) {
        return Err(format!("faceVertexIndices[{i}] = {v} is out of range for {points} points"));
    }
    if tags.scheme == "loop"
        && let Some(f) = src.counts.iter().position(|&c| c != 3)
    {
        return Err(format!("faceVertexCounts: the loop scheme needs triangles, and face {f} has {} vertices", src.counts[f]));
    }
    let in_range = |name: &str, v: &[i64], n: i64| match v.iter().enumerate().find(|(_, x)| !(0..n).contains(*x)) {
        Some((i, x)) => Err(format!("{name}[{i}] = {x} is out of range (0..{n})")),
        None => Ok(()),
    };
    in_range("creaseIndices", &tags.crease_indices, points)?;
    in_range("cornerIndices", &tags.corner_indices, points)?;
    in_range("holeIndices", &tags.hole_indices, src.counts.len() as i64)?;
    let creases = crease_edges(tags)?;
    if tags.corner_sharpnesses.len() != tags.corner_indices.len() {
        return Err(format!(
            "cornerSharpnesses has {} values for {} cornerIndices",
            tags.corner_sharpnesses.len(),
            tags.corner_indices.len()
        ));
    }
    if tags.corner_sharpnesses.iter().any(|s| !s.is_finite()) {
        return Err("cornerSharpnesses: a value is NaN or infinite".into());
    }
    Ok(creases)
}

/// USD's crease chains as OpenSubdiv's vertex pairs with a sharpness each. USD gives one
/// sharpness per chain, or one per edge.
fn crease_edges(tags: &SubdivTags) -> Result<(Vec<u32>, Vec<f32>), String> {
    let lengths = &tags.crease_lengths;
    if let Some((i, l)) = lengths.iter().enumerate().find(|(_, l)| **l < 2) {
        return Err(format!("creaseLengths[{i}] = {l}: a crease runs through 2 or more vertices"));
    }
    let total: i64 = lengths.iter().sum();
    if total != tags.crease_indices.len() as i64 {
        return Err(format!("creaseLengths add up to {total} but creaseIndices has {} entries", tags.crease_indices.len()));
    }
    let edges: i64 = lengths.iter().map(|l| l - 1).sum();
    let sharp = &tags.crease_sharpnesses;
    let per_edge = sharp.len() as i64 == edges;
    if !per_edge && sharp.len() != lengths.len() {
        return Err(format!(
            "creaseSharpnesses has {} values: one per crease ({}) or one per crease edge ({edges}) expected",
            sharp.len(),
            lengths.len()
        ));
    }
    if sharp.iter().any(|s| !s.is_finite()) {
        return Err("creaseSharpnesses: a value is NaN or infinite".into());
    }
    let (mut pairs, mut weights) = (Vec::new(), Vec::new());
    let mut at = 0usize;
    for (chain, &l) in lengths.iter().enumerate() {
        for k in 0..(l as usize - 1) {
            pairs.extend([tags.crease_indices[at + k] as u32, tags.crease_indices[at + k + 1] as u32]);
            weights.push(sharp[if per_edge { weights.len() } else { chain }].max(0.0));
        }
        at += l as usize;
    }
    Ok((pairs, weights))
}

/// OpenSubdiv's refiner for the cage, adaptively refined around extraordinary vertices and
/// creases so limit stencils are exact there.
fn build_refiner(src: &MeshSource, tags: &SubdivTags, cage: &Cage) -> Result<TopologyRefiner, String> {
    let counts: Vec<u32> = src.counts.iter().map(|&c| c as u32).collect();
    let indices: Vec<u32> = src.indices.iter().map(|&i| i as u32).collect();
    let (crease_pairs, crease_weights) = &cage.creases;
    let corners: Vec<u32> = tags.corner_indices.iter().map(|&i| i as u32).collect();
    let corner_weights: Vec<f32> = tags.corner_sharpnesses.iter().map(|s| s.max(0.0)).collect();
    let holes: Vec<u32> = tags.hole_indices.iter().map(|&i| i as u32).collect();
    let mut desc = TopologyDescriptor::new(src.points.len(), &counts, &indices).map_err(|e| format!("OpenSubdiv: {e}"))?;
    if !crease_pairs.is_empty() {
        desc.creases(crease_pairs, crease_weights);
    }
    if !corners.is_empty() {
        desc.corners(&corners, &corner_weights);
    }
    if !holes.is_empty() {
        desc.holes(&holes);
    }
    let options = TopologyRefinerOptions {
        scheme: cage.scheme,
        boundary_interpolation: match tags.interpolate_boundary.as_str() {
            "none" => None,
            "edgeOnly" => Some(BoundaryInterpolation::EdgeOnly),
            _ => Some(BoundaryInterpolation::EdgeAndCorner),
        },
        face_varying_linear_interpolation: Some(FaceVaryingLinearInterpolation::All),
        creasing_method: CreasingMethod::Uniform,
        triangle_subdivision: match tags.triangle_subdivision_rule.as_str() {
            "smooth" => TriangleSubdivision::Smooth,
            _ => TriangleSubdivision::CatmullClark,
        },
    };
    let mut refiner = TopologyRefiner::new(desc, options).map_err(|e| format!("OpenSubdiv cannot refine this cage: {e}"))?;
    // Semi-sharp creases resolve after ceil(sharpness) levels; infinitely sharp ones (10 and
    // up) are exact patches of their own.
    let semi_sharp = crease_weights.iter().chain(&corner_weights).filter(|s| **s < 10.0).fold(0.0f32, |a, s| a.max(*s));
    let isolation = (semi_sharp.ceil() as usize).clamp(4, 10);
    let adaptive = AdaptiveRefinementOptions { isolation_level: isolation, infintely_sharp_patch: true, ..Default::default() };
    refiner.refine_adaptive(adaptive, &[]);
    Ok(refiner)
}

/// The limit stencils of every grid point of `chunk`, in order.
fn limit_stencils(refiner: &TopologyRefiner, chunk: &[Ptex], cage: &Cage, level: u32) -> Result<LimitStencilTable, String> {
    let grids: Vec<(Vec<f32>, Vec<f32>)> = chunk.iter().map(|p| cage.grid(p, level).params()).collect();
    let arrays: Vec<LocationArray> = chunk.iter().zip(&grids).map(|(p, (s, t))| LocationArray { ptex_index: p.index, s, t }).collect();
    let options = LimitStencilTableOptions { generate_1st_derivatives: true, ..Default::default() };
    LimitStencilTable::new(refiner, &arrays, None, None, options).map_err(|e| format!("OpenSubdiv limit stencils: {e}"))
}

/// The grid of one ptex face: `r` segments a side, on a quad or (Loop) a triangle.
#[derive(Clone, Copy)]
struct Grid {
    r: u32,
    triangle: bool,
}

impl Grid {
    fn len(&self) -> usize {
        let n = self.r as usize + 1;
        if self.triangle { n * (n + 1) / 2 } else { n * n }
    }

    /// Points row by row (`j`), `i` along the row.
    fn points(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (0..=self.r).flat_map(move |j| (0..=(if self.triangle { self.r - j } else { self.r })).map(move |i| (i, j)))
    }

    fn index(&self, i: u32, j: u32) -> usize {
        let (i, j, n) = (i as usize, j as usize, self.r as usize + 1);
        if self.triangle { j * n - j * j.saturating_sub(1) / 2 + i } else { j * n + i }
    }

    /// The (s, t) of every point, for OpenSubdiv.
    fn params(&self) -> (Vec<f32>, Vec<f32>) {
        let r = self.r as f32;
        self.points().map(|(i, j)| (i as f32 / r, j as f32 / r)).unzip()
    }

    /// Refined faces as grid points, wound as the cage face is.
    fn cells(&self) -> Vec<Vec<(u32, u32)>> {
        let mut cells = Vec::new();
        for j in 0..self.r {
            if !self.triangle {
                cells.extend((0..self.r).map(|i| vec![(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]));
                continue;
            }
            for i in 0..(self.r - j) {
                cells.push(vec![(i, j), (i + 1, j), (i, j + 1)]);
                if i + j + 1 < self.r {
                    cells.push(vec![(i + 1, j), (i + 1, j + 1), (i, j + 1)]);
                }
            }
        }
        cells
    }
}

/// A grid point shared between ptex faces, named by topology so every face that reaches it
/// uses one vertex: a cage vertex, a point `k` of `denominator` along a cage edge (from its
/// lower-numbered end), a point along spoke `k` of an n-gon (edge midpoint to centre), or an
/// n-gon's centre.
#[derive(Clone, Copy, Hash, PartialEq, Eq)]
enum Key {
    Vertex(u32),
    Edge(u32, u32, u32),
    Spoke(u32, u32, u32),
    Center(u32),
}

/// The point `from_a` of `d` along cage edge a→b.
fn edge_key(a: u32, b: u32, from_a: u32, d: u32) -> Option<Key> {
    Some(match from_a {
        0 => Key::Vertex(a),
        x if x == d => Key::Vertex(b),
        x if a < b => Key::Edge(a, b, x),
        x => Key::Edge(b, a, d - x),
    })
}

fn spoke_key(face: u32, k: u32, pos: u32, r: u32) -> Option<Key> {
    Some(if pos == r { Key::Center(face) } else { Key::Spoke(face, k, pos) })
}

/// How a primvar varies, and so how it is carried onto the limit surface.
#[derive(Clone, Copy, PartialEq)]
enum Interp {
    /// Limit stencils, as positions.
    Vertex,
    /// Linear over each ptex face from cage-vertex values.
    Varying,
    /// Linear over each ptex face from face-vertex values.
    FaceVarying,
    Uniform,
    Constant,
}

/// The texture coordinates and other primvars, as 3-vectors.
struct Primvars {
    list: Vec<(String, Vec<Vec3>, Interp)>,
    /// Whether `list[0]` is the texture coordinates.
    has_uvs: bool,
}

impl Primvars {
    fn gather(src: &MeshSource, warn: &mut impl FnMut(String)) -> Self {
        let mut list = Vec::new();
        let mut has_uvs = false;
        if let Some((name, uv, interp)) = &src.uvs
            && let Some(i) = Self::interp(src, name, uv.len(), interp, warn)
        {
            list.push((name.clone(), uv.iter().map(|u| u.extend(0.0)).collect(), i));
            has_uvs = true;
        }
        for (name, v, interp) in &src.primvars {
            if let Some(i) = Self::interp(src, &format!("primvars:{name}"), v.len(), interp, warn) {
                list.push((name.clone(), v.clone(), i));
            }
        }
        Self { list, has_uvs }
    }

    /// The interpolation, if `len` values fit it; else a warning naming the primvar.
    fn interp(src: &MeshSource, name: &str, len: usize, interp: &str, warn: &mut impl FnMut(String)) -> Option<Interp> {
        let sizes = Sizes { points: src.points.len(), face_vertices: src.indices.len(), faces: src.counts.len() };
        if !sizes.fits(name, len, interp, warn) {
            return None;
        }
        Some(match interp {
            "vertex" => Interp::Vertex,
            "varying" => Interp::Varying,
            "faceVarying" => Interp::FaceVarying,
            "uniform" => Interp::Uniform,
            _ => Interp::Constant,
        })
    }
}

/// The refined mesh being built, chunk by chunk.
struct Tessellation<'c> {
    cage: &'c Cage<'c>,
    level: u32,
    left_handed: bool,
    welded: HashMap<Key, u32>,
    /// Largest distance between two evaluations of one shared point (a check on the keys).
    weld_gap: f32,
    points: Vec<Vec3>,
    counts: Vec<i64>,
    indices: Vec<i64>,
    normals: Vec<Vec3>,
    /// Per primvar, one value per refined face-vertex.
    values: Vec<Vec<Vec3>>,
    cage_face: Vec<u32>,
    uv_name: Option<String>,
    names: Vec<String>,
}

/// One evaluated grid point.
struct Sample {
    vertex: u32,
    normal: Vec3,
    values: Vec<Vec3>,
}

impl<'c> Tessellation<'c> {
    fn new(cage: &'c Cage<'c>, level: u32, left_handed: bool, primvars: &Primvars) -> Self {
        let names: Vec<String> = primvars.list.iter().map(|(n, _, _)| n.clone()).collect();
        Self {
            cage,
            level,
            left_handed,
            welded: HashMap::new(),
            weld_gap: 0.0,
            points: Vec::new(),
            counts: Vec::new(),
            indices: Vec::new(),
            normals: Vec::new(),
            values: vec![Vec::new(); names.len()],
            cage_face: Vec::new(),
            uv_name: primvars.has_uvs.then(|| names[0].clone()),
            names,
        }
    }

    fn grid(&self, p: &Ptex) -> Grid {
        self.cage.grid(p, self.level)
    }

    /// The shared-point key of grid point (i, j) of `p`, or `None` inside the face.
    fn key(&self, p: &Ptex, g: Grid, i: u32, j: u32) -> Option<Key> {
        let d = 1u32 << self.level;
        let c = |k: i64| self.cage.corner(p.face, k);
        let r = g.r;
        match p.sub {
            None if g.triangle => match (i, j) {
                (_, 0) => edge_key(c(0), c(1), i, d),
                (0, _) => edge_key(c(0), c(2), j, d),
                _ if i + j == r => edge_key(c(1), c(2), j, d),
                _ => None,
            },
            None => match (i, j) {
                (_, 0) => edge_key(c(0), c(1), i, d),
                _ if i == r => edge_key(c(1), c(2), j, d),
                _ if j == r => edge_key(c(3), c(2), i, d),
                (0, _) => edge_key(c(0), c(3), j, d),
                _ => None,
            },
            Some(k) => {
                let n = self.cage.src.counts[p.face as usize] as u32;
                let k64 = k as i64;
                match (i, j) {
                    (_, 0) => edge_key(c(k64), c(k64 + 1), i, d),
                    (0, _) => edge_key(c(k64), c(k64 - 1), j, d),
                    _ if i == r => spoke_key(p.face, k, j, r),
                    _ if j == r => spoke_key(p.face, (k + n - 1) % n, i, r),
                    _ => None,
                }
            }
        }
    }

    /// Adds the refined faces of `chunk`, whose grid points `table` holds in order.
    fn add(&mut self, chunk: &[Ptex], table: &LimitStencilTable, primvars: &Primvars) {
        let stencils = Stencils {
            offsets: table.offsets(),
            sizes: table.sizes(),
            indices: table.control_indices(),
            w: table.weights(),
            du: table.du_weights(),
            dv: table.dv_weights(),
        };
        let mut at = 0usize;
        for p in chunk {
            let g = self.grid(p);
            let on_face: Vec<FacePrimvar> = primvars.list.iter().map(|(_, v, interp)| self.on_face(p, g.triangle, v, *interp)).collect();
            let samples: Vec<Sample> = g.points().enumerate().map(|(n, ij)| self.sample(p, g, ij, &stencils, at + n, &on_face)).collect();
            for cell in g.cells() {
                self.counts.push(cell.len() as i64);
                self.cage_face.push(p.face);
                for (i, j) in cell {
                    let s = &samples[g.index(i, j)];
                    self.indices.push(s.vertex as i64);
                    self.normals.push(s.normal);
                    for (out, v) in self.values.iter_mut().zip(&s.values) {
                        out.push(*v);
                    }
                }
            }
            at += g.len();
        }
    }

    /// Evaluates grid point `ij` of `p` (stencil `k`) and welds it.
    fn sample(&mut self, p: &Ptex, g: Grid, ij: (u32, u32), st: &Stencils, k: usize, on_face: &[FacePrimvar]) -> Sample {
        let (pos, du, dv) = st.eval(k, &self.cage.src.points);
        let mut normal = du.cross(dv);
        if self.left_handed {
            normal = -normal;
        }
        let normal = normal.try_normalize().unwrap_or_else(|| self.cage_normal(p.face));
        let vertex = match self.key(p, g, ij.0, ij.1) {
            Some(key) => match self.welded.get(&key) {
                Some(&v) => {
                    self.weld_gap = self.weld_gap.max(self.points[v as usize].distance(pos));
                    v
                }
                None => self.push_point(pos, Some(key)),
            },
            None => self.push_point(pos, None),
        };
        let (s, t) = (ij.0 as f32 / g.r as f32, ij.1 as f32 / g.r as f32);
        let values = on_face.iter().map(|f| f.at((s, t), st, k)).collect();
        Sample { vertex, normal, values }
    }

    fn push_point(&mut self, pos: Vec3, key: Option<Key>) -> u32 {
        let v = self.points.len() as u32;
        self.points.push(pos);
        if let Some(key) = key {
            self.welded.insert(key, v);
        }
        v
    }

    /// A primvar as one ptex face sees it: linear interpolations need the face's four corner
    /// values (an n-gon's sub-face: its corner, two edge midpoints and the centre), found
    /// once per face rather than per grid point.
    fn on_face<'v>(&self, p: &Ptex, triangle: bool, v: &'v [Vec3], interp: Interp) -> FacePrimvar<'v> {
        let f = p.face as usize;
        let start = self.cage.starts[f];
        let corner = |c: usize| match interp {
            Interp::FaceVarying => v[start + c],
            _ => v[self.cage.src.indices[start + c] as usize],
        };
        let corners = match (interp, p.sub) {
            (Interp::Varying | Interp::FaceVarying, None) => {
                [corner(0), corner(1), corner(2), if triangle { Vec3::ZERO } else { corner(3) }]
            }
            (Interp::Varying | Interp::FaceVarying, Some(k)) => {
                let (k, n) = (k as usize, self.cage.src.counts[f] as usize);
                let (here, next, prev) = (corner(k), corner((k + 1) % n), corner((k + n - 1) % n));
                let centre = (0..n).map(corner).sum::<Vec3>() / n as f32;
                [here, 0.5 * (here + next), centre, 0.5 * (here + prev)]
            }
            (Interp::Uniform, _) => [v[f]; 4],
            (Interp::Constant, _) => [v[0]; 4],
            (Interp::Vertex, _) => [Vec3::ZERO; 4],
        };
        FacePrimvar { values: v, interp, corners, triangle }
    }

    /// The cage face's own normal (Newell's), where the limit tangents are degenerate.
    fn cage_normal(&self, face: u32) -> Vec3 {
        let n = self.cage.src.counts[face as usize];
        let at = |k: i64| self.cage.src.points[self.cage.corner(face, k) as usize];
        let newell: Vec3 = (0..n).map(|k| at(k).cross(at(k + 1))).sum();
        let newell = if self.left_handed { -newell } else { newell };
        newell.try_normalize().unwrap_or(Vec3::Z)
    }

    fn finish(self, level: u32) -> Refined {
        let mut values = self.values.into_iter();
        let uvs = self.uv_name.map(|name| {
            let uv = values.next().unwrap_or_default().into_iter().map(|v| Vec2::new(v.x, v.y)).collect();
            (name, uv, "faceVarying".to_string())
        });
        let skip = usize::from(uvs.is_some());
        let primvars = self.names.into_iter().skip(skip).zip(values).map(|(n, v)| (n, v, "faceVarying".to_string())).collect();
        let mesh = MeshSource {
            points: self.points,
            counts: self.counts,
            indices: self.indices,
            normals: Some((self.normals, "faceVarying".to_string())),
            uvs,
            primvars,
            left_handed: self.left_handed,
            smooth: false,
        };
        Refined { mesh, cage_face: self.cage_face, level, weld_gap: self.weld_gap }
    }
}

/// Largest distance between two faces' unit limit normals at one vertex (about the angle
/// between them, in radians) for the two to count as one normal. Faces evaluate a shared
/// point's tangents on their own patches: at a smooth regular vertex they agree to 1e-5 or
/// better, at an extraordinary vertex the end-cap patches around it disagree by up to 2e-3 (the
/// 100k-face cube-sphere of the `subdivision` bench); a sharp crease or corner breaks them by
/// far more (0.3 and up in the tests below).
const SMOOTH_SPREAD: f32 = 1e-2;

/// The most distinct normals one vertex's corners are matched against: a crease meeting a
/// corner gives a handful; a cage with one vertex in thousands of sharp faces would otherwise
/// compare every corner with every other.
const MAX_NORMALS_PER_VERTEX: u32 = 8;

/// One way a vertex's faces see its normal: the first corner's normal, the vertex that carries
/// it, the sum of the corners' normals that agree with it, and the vertex's next such group.
struct NormalGroup {
    first: Vec3,
    vertex: u32,
    sum: Vec3,
    next: u32,
}

/// Turns `mesh`'s face-varying limit normals (as [`refine`] makes them) into one normal per
/// vertex, the mean of the corners that agree within [`SMOOTH_SPREAD`]. Where a vertex's faces
/// disagree (a sharp crease, a corner, a pinched pole), each further normal gets a copy of the
/// vertex at the same position, so the crease stays sharp. A smooth surface's normals then take
/// a third of the memory and of the bytes sent to the server, a creased one's little more. Not
/// for a mesh that deforms over the shutter: its motion samples must keep the frame's vertices.
pub fn share_normals(mesh: &mut MeshSource) {
    let Some((corners, _)) = mesh.normals.take_if(|(_, interp)| interp == "faceVarying") else { return };
    const NONE: u32 = u32::MAX;
    let mut head = vec![NONE; mesh.points.len()];
    let mut groups: Vec<NormalGroup> = Vec::with_capacity(mesh.points.len());
    let mut copies = Vec::new();
    for (index, &n) in mesh.indices.iter_mut().zip(&corners) {
        let v = *index as usize;
        let (mut at, mut last, mut seen) = (head[v], NONE, 0);
        while at != NONE && groups[at as usize].first.distance_squared(n) > SMOOTH_SPREAD * SMOOTH_SPREAD {
            (last, at, seen) = (at, groups[at as usize].next, seen + 1);
        }
        if at == NONE {
            at = groups.len() as u32;
            let vertex = match last {
                NONE => {
                    head[v] = at;
                    v as u32
                }
                _ => {
                    // Past a few normals a vertex is not a crease but a hostile fan: its further
                    // corners get copies of their own, unlinked, so no corner walks far.
                    if seen < MAX_NORMALS_PER_VERTEX {
                        groups[last as usize].next = at;
                    }
                    copies.push(v);
                    (mesh.points.len() + copies.len() - 1) as u32
                }
            };
            groups.push(NormalGroup { first: n, vertex, sum: Vec3::ZERO, next: NONE });
        }
        let g = &mut groups[at as usize];
        g.sum += n;
        *index = g.vertex as i64;
    }
    let copied: Vec<Vec3> = copies.iter().map(|&v| mesh.points[v]).collect();
    mesh.points.extend(copied);
    let mut normals = vec![Vec3::Z; mesh.points.len()];
    for g in &groups {
        normals[g.vertex as usize] = g.sum.try_normalize().unwrap_or(g.first);
    }
    mesh.normals = Some((normals, "vertex".to_string()));
}

/// A primvar on one ptex face: its values, how they vary, and the face's corner values.
struct FacePrimvar<'v> {
    values: &'v [Vec3],
    interp: Interp,
    corners: [Vec3; 4],
    triangle: bool,
}

impl FacePrimvar<'_> {
    /// The value at (s, t) of the face, stencil `k` being that point's.
    fn at(&self, (s, t): (f32, f32), st: &Stencils, k: usize) -> Vec3 {
        let c = &self.corners;
        match self.interp {
            Interp::Vertex => st.eval_values(k, self.values),
            Interp::Uniform | Interp::Constant => c[0],
            _ if self.triangle => (1.0 - s - t) * c[0] + s * c[1] + t * c[2],
            _ => (1.0 - s) * (1.0 - t) * c[0] + s * (1.0 - t) * c[1] + s * t * c[2] + (1.0 - s) * t * c[3],
        }
    }
}

/// A chunk's limit stencils: weights on cage vertices for the point and its two tangents.
struct Stencils<'t> {
    offsets: &'t [opensubdiv_petite::Index],
    sizes: &'t [i32],
    indices: &'t [opensubdiv_petite::Index],
    w: &'t [f32],
    du: &'t [f32],
    dv: &'t [f32],
}

impl Stencils<'_> {
    fn range(&self, k: usize) -> std::ops::Range<usize> {
        let o = self.offsets[k].0 as usize;
        o..o + self.sizes[k] as usize
    }

    /// Point, ∂/∂s and ∂/∂t of stencil `k` over `points`.
    fn eval(&self, k: usize, points: &[Vec3]) -> (Vec3, Vec3, Vec3) {
        self.range(k).fold((Vec3::ZERO, Vec3::ZERO, Vec3::ZERO), |(p, du, dv), j| {
            let c = points[self.indices[j].0 as usize];
            (p + self.w[j] * c, du + self.du[j] * c, dv + self.dv[j] * c)
        })
    }

    fn eval_values(&self, k: usize, values: &[Vec3]) -> Vec3 {
        self.range(k).map(|j| self.w[j] * values[self.indices[j].0 as usize]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cage(points: Vec<Vec3>, faces: &[&[i64]]) -> MeshSource {
        MeshSource {
            points,
            counts: faces.iter().map(|f| f.len() as i64).collect(),
            indices: faces.iter().flat_map(|f| f.iter().copied()).collect(),
            normals: None,
            uvs: None,
            primvars: Vec::new(),
            left_handed: false,
            smooth: true,
        }
    }

    fn tags(scheme: &str) -> SubdivTags {
        SubdivTags { scheme: scheme.into(), interpolate_boundary: "edgeAndCorner".into(), ..Default::default() }
    }

    /// A 5×5-vertex grid of 4×4 quads in the xy-plane, with heights `z(i, j)`.
    fn grid(z: impl Fn(i64, i64) -> f32) -> MeshSource {
        let points = (0..5).flat_map(|j| (0..5).map(move |i| (i, j))).map(|(i, j)| Vec3::new(i as f32, j as f32, z(i, j))).collect();
        let faces: Vec<Vec<i64>> = (0..4).flat_map(|j| (0..4).map(move |i| j * 5 + i)).map(|a| vec![a, a + 1, a + 6, a + 5]).collect();
        cage(points, &faces.iter().map(|f| f.as_slice()).collect::<Vec<_>>())
    }

    fn bump(i: i64, j: i64) -> f32 {
        match (i, j) {
            (2, 2) => 1.0,
            (1..=3, 2) | (2, 1..=3) => 0.5,
            _ => 0.0,
        }
    }

    /// The refined point nearest (x, y) in the plane.
    fn at(r: &Refined, x: f32, y: f32) -> Vec3 {
        *r.mesh
            .points
            .iter()
            .min_by(|a, b| (a.truncate().distance(Vec2::new(x, y))).total_cmp(&b.truncate().distance(Vec2::new(x, y))))
            .unwrap()
    }

    fn cube() -> MeshSource {
        let p = (0..8).map(|k| Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, (k >> 2) as f32) - 0.5).collect();
        cage(p, &[&[0, 2, 3, 1], &[4, 5, 7, 6], &[0, 1, 5, 4], &[2, 6, 7, 3], &[0, 4, 6, 2], &[1, 3, 7, 5]])
    }

    /// Every refined edge used by exactly two faces: no cracks, no T-junctions.
    fn assert_watertight(r: &Refined) {
        let mut uses: HashMap<(i64, i64), u32> = HashMap::new();
        let mut at = 0;
        for &c in &r.mesh.counts {
            let f = &r.mesh.indices[at..at + c as usize];
            for k in 0..f.len() {
                let (a, b) = (f[k], f[(k + 1) % f.len()]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
            at += c as usize;
        }
        assert!(uses.values().all(|&u| u == 2), "open or non-manifold edges in the tessellation");
    }

    #[test]
    fn a_regular_vertex_reaches_the_bicubic_b_spline_limit() {
        let r = refine(&grid(bump), &tags("catmullClark"), 3, |w| panic!("{w}")).unwrap();
        // The limit mask of a regular Catmull-Clark vertex: 16/36 itself, 4/36 each edge
        // neighbour, 1/36 each diagonal one (Halstead et al. 1993; OpenSubdiv's regular patch).
        let want = (16.0 * 1.0 + 4.0 * (4.0 * 0.5) + 0.0) / 36.0;
        assert!((at(&r, 2.0, 2.0).z - want).abs() < 1e-5, "{} vs {want}", at(&r, 2.0, 2.0).z);
        assert_eq!(r.mesh.counts.len(), 16 * 64, "4^3 quads per cage quad");
        assert!(r.weld_gap < 1e-5);
    }

    #[test]
    fn an_infinitely_sharp_crease_follows_its_cubic_b_spline_and_keeps_its_normal_break() {
        let mut t = tags("catmullClark");
        t.crease_indices = vec![10, 11, 12, 13, 14];
        t.crease_lengths = vec![5];
        t.crease_sharpnesses = vec![10.0];
        let r = refine(&grid(bump), &t, 3, |w| panic!("{w}")).unwrap();
        // On an infinitely sharp crease the limit is the crease polyline's cubic B-spline:
        // (1, 4, 1)/6 of the vertex and its two crease neighbours.
        let want = (0.5 + 4.0 * 1.0 + 0.5) / 6.0;
        assert!((at(&r, 2.0, 2.0).z - want).abs() < 1e-5, "{} vs {want}", at(&r, 2.0, 2.0).z);
        // The normals the two sides give the crease point at (1.5, 2) differ (the surface has
        // a ridge there); smooth, they agree.
        let spread = |r: &Refined| {
            let v = r.mesh.points.iter().position(|p| p.truncate().distance(Vec2::new(1.5, 2.0)) < 1e-4).unwrap() as i64;
            let normals: Vec<Vec3> =
                r.mesh.indices.iter().zip(&r.mesh.normals.as_ref().unwrap().0).filter(|(i, _)| **i == v).map(|(_, n)| *n).collect();
            normals.iter().flat_map(|a| normals.iter().map(move |b| a.angle_between(*b))).fold(0.0f32, f32::max)
        };
        assert!(spread(&r) > 0.3, "creased: {}", spread(&r));
        let smooth = refine(&grid(bump), &tags("catmullClark"), 3, |w| panic!("{w}")).unwrap();
        assert!(spread(&smooth) < 1e-3, "smooth: {}", spread(&smooth));
        // Shared per vertex, the smooth surface keeps its vertices; the creased one gets a copy
        // of the crease's points where its two sides bend apart (22 of its 4 × 8 + 1 points;
        // towards the cage's border both sides are flat and agree), so every corner keeps the
        // normal its face gave it.
        for (refined, copies) in [(&smooth, 0..=0), (&r, 1..=33)] {
            let mut shared = refined.mesh.clone();
            share_normals(&mut shared);
            let (normals, interp) = shared.normals.as_ref().unwrap();
            assert_eq!((interp.as_str(), normals.len()), ("vertex", shared.points.len()));
            assert!(copies.contains(&(shared.points.len() - refined.mesh.points.len())), "{}", shared.points.len());
            let corners = &refined.mesh.normals.as_ref().unwrap().0;
            for (k, (&v, &i)) in shared.indices.iter().zip(&refined.mesh.indices).enumerate() {
                assert_eq!(shared.points[v as usize], refined.mesh.points[i as usize], "a copy sits where its vertex does");
                assert!(normals[v as usize].distance(corners[k]) < SMOOTH_SPREAD, "corner {k}");
            }
        }
    }

    #[test]
    fn a_vertex_in_sixty_thousand_sharp_faces_is_shared_in_linear_time() {
        // Hostile: one vertex whose every corner has its own normal (a fan of sharp faces; the
        // normals on a Fibonacci sphere, 0.0145 apart, beyond SMOOTH_SPREAD). Matched against
        // at most MAX_NORMALS_PER_VERTEX normals, each corner costs 8 comparisons, not up to
        // 60 000, and keeps its normal on a copy of the vertex (debug build: 4 ms; 4.9 s with
        // the cap lifted).
        let corners = 60_000;
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let normals: Vec<Vec3> = (0..corners)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f32 + 0.5) / corners as f32;
                let r = (1.0 - z * z).sqrt();
                Vec3::new(r * (golden * k as f32).cos(), r * (golden * k as f32).sin(), z)
            })
            .collect();
        let mut fan = MeshSource {
            points: vec![Vec3::ZERO],
            counts: Vec::new(),
            indices: vec![0; corners],
            normals: Some((normals.clone(), "faceVarying".into())),
            uvs: None,
            primvars: Vec::new(),
            left_handed: false,
            smooth: false,
        };
        let t = std::time::Instant::now();
        share_normals(&mut fan);
        println!("{corners} corners shared in {:.3} s", t.elapsed().as_secs_f64());
        let (shared, _) = fan.normals.as_ref().unwrap();
        assert_eq!(fan.points.len(), corners, "one vertex per distinct normal");
        assert!(fan.indices.iter().zip(&normals).all(|(&v, n)| shared[v as usize].distance(*n) < 1e-6));
    }

    #[test]
    fn chunked_evaluation_refines_the_same_surface() {
        // A big mesh's limit stencils are evaluated in chunks of locations (several at once,
        // each worker with a refiner of its own), and points on the edges between two chunks'
        // faces are welded: in chunks of 50 locations, a cube
        // (valence-3 corners) and a grid with a semi-sharp crease and a sharp corner must give
        // the surface one call gives, to the bit.
        let mut creased = tags("catmullClark");
        (creased.crease_indices, creased.crease_lengths, creased.crease_sharpnesses) = (vec![10, 11, 12, 13, 14], vec![5], vec![2.5]);
        (creased.corner_indices, creased.corner_sharpnesses) = (vec![0], vec![10.0]);
        for (src, t) in [(cube(), tags("catmullClark")), (grid(bump), creased)] {
            let refine_with = |chunk| refine_in_chunks(&src, &t, 3, MAX_REFINED_FACES, chunk, |w| panic!("{w}")).unwrap();
            let (chunked, whole) = (refine_with(50), refine_with(usize::MAX));
            let bits = |r: &Refined| -> Vec<u32> {
                let normals = r.mesh.normals.as_ref().map_or(&[][..], |n| &n.0[..]);
                r.mesh.points.iter().chain(normals).flat_map(|v| v.to_array()).map(f32::to_bits).collect()
            };
            assert_eq!(
                (&chunked.mesh.counts, &chunked.mesh.indices, &chunked.cage_face),
                (&whole.mesh.counts, &whole.mesh.indices, &whole.cage_face)
            );
            assert!(bits(&chunked) == bits(&whole), "the surface differs between chunkings");
        }
    }

    #[test]
    fn semi_sharp_creases_lie_between_smooth_and_sharp() {
        let z = |sharpness: f32| {
            let mut t = tags("catmullClark");
            t.crease_indices = vec![10, 11, 12, 13, 14];
            t.crease_lengths = vec![5];
            t.crease_sharpnesses = vec![sharpness];
            at(&refine(&grid(bump), &t, 3, |w| panic!("{w}")).unwrap(), 2.0, 2.0).z
        };
        let (smooth, one, two, sharp) = (z(0.0), z(1.0), z(2.0), z(10.0));
        assert!(smooth < one && one < two && two < sharp, "{smooth} {one} {two} {sharp}");
    }

    #[test]
    fn a_sharp_corner_stays_put_and_a_smooth_cube_shrinks_towards_a_sphere() {
        let smooth = refine(&cube(), &tags("catmullClark"), 3, |w| panic!("{w}")).unwrap();
        assert_watertight(&smooth);
        // The limit of a valence-n vertex of an all-quad mesh: (n² v + 4 Σ edge neighbours +
        // Σ diagonal neighbours) / (n (n + 5)); for the cube's corner (0.5, 0.5, 0.5), n = 3,
        // that is (9·0.5 + 4·0.5 − 0.5) / 24 = 0.25 per axis.
        let corner = smooth.mesh.points.iter().copied().max_by(|a, b| a.dot(Vec3::ONE).total_cmp(&b.dot(Vec3::ONE))).unwrap();
        assert!(corner.distance(Vec3::splat(0.25)) < 1e-5, "{corner}");
        let mut t = tags("catmullClark");
        t.corner_indices = vec![7];
        t.corner_sharpnesses = vec![10.0];
        let cornered = refine(&cube(), &t, 3, |w| panic!("{w}")).unwrap();
        assert!(cornered.mesh.points.iter().any(|p| p.distance(Vec3::splat(0.5)) < 1e-6), "the sharp corner is interpolated");
        assert_watertight(&cornered);
    }

    #[test]
    fn n_gons_split_into_sub_quads_that_meet_their_neighbours() {
        // A pentagon between quads: its sub-faces' edges are halves of the cage edges, and
        // the quads' grids meet them point for point.
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.5, 1.5, 0.3),
            Vec3::new(1.0, 2.5, 0.0),
            Vec3::new(-0.5, 1.5, 0.3),
            Vec3::new(0.0, -1.0, 0.2),
            Vec3::new(2.0, -1.0, 0.2),
        ];
        let m = cage(p, &[&[0, 1, 2, 3, 4], &[5, 6, 1, 0]]);
        let r = refine(&m, &tags("catmullClark"), 2, |w| panic!("{w}")).unwrap();
        assert_eq!(r.mesh.counts.len(), 5 * 4 + 16, "5 sub-quads of 2×2 and a quad of 4×4");
        assert!(r.weld_gap < 1e-5, "shared points evaluate to {}", r.weld_gap);
        let boundary_vertices = r.mesh.points.len();
        assert_eq!(boundary_vertices, 5 * 9 - 5 * 3 + 1 + 25 - 5, "shared points are welded once");
    }

    #[test]
    fn loop_triangles_reach_the_loop_limit() {
        // A regular valence-6 vertex at the centre of a hexagonal fan ringed by a second
        // ring, so the centre's limit is interior: Loop's limit mask is 1/2 the vertex and
        // 1/12 each neighbour (β = 1/16 for valence 6).
        let mut points = vec![Vec3::new(0.0, 0.0, 1.0)];
        let ring = |r: f32, z: f32, phase: f32| {
            (0..6).map(move |k| {
                let a = (k as f32 + phase) * std::f32::consts::TAU / 6.0;
                Vec3::new(r * a.cos(), r * a.sin(), z)
            })
        };
        points.extend(ring(1.0, 0.4, 0.0));
        points.extend(ring(2.0, 0.0, 0.5));
        let mut faces: Vec<Vec<i64>> = (0..6).map(|k| vec![0, 1 + k, 1 + (k + 1) % 6]).collect();
        for k in 0..6 {
            let (a, b, o) = (1 + k, 1 + (k + 1) % 6, 7 + k);
            faces.push(vec![a, o, b]);
            faces.push(vec![o, 7 + (k + 1) % 6, b]);
        }
        let m = cage(points, &faces.iter().map(|f| f.as_slice()).collect::<Vec<_>>());
        let r = refine(&m, &tags("loop"), 3, |w| panic!("{w}")).unwrap();
        let want = 0.5 * 1.0 + 6.0 * 0.4 / 12.0;
        assert!((at(&r, 0.0, 0.0).z - want).abs() < 1e-5, "{} vs {want}", at(&r, 0.0, 0.0).z);
        assert!(r.weld_gap < 1e-5, "{}", r.weld_gap);
        assert_eq!(r.mesh.counts.len(), 18 * 64);
        assert!(r.mesh.counts.iter().all(|&c| c == 3));
    }

    #[test]
    fn holes_leave_faces_out() {
        let mut t = tags("catmullClark");
        t.hole_indices = vec![5, 6];
        let r = refine(&grid(bump), &t, 1, |w| panic!("{w}")).unwrap();
        assert_eq!(r.mesh.counts.len(), 14 * 4);
        assert!(r.cage_face.iter().all(|&f| f != 5 && f != 6));
        let mut none = tags("catmullClark");
        none.interpolate_boundary = "none".into();
        let r = refine(&grid(bump), &none, 1, |w| panic!("{w}")).unwrap();
        assert_eq!(r.mesh.counts.len(), 4 * 4, "boundary faces leave with interpolateBoundary = none");
    }

    #[test]
    fn face_varying_coordinates_interpolate_linearly_and_vertex_primvars_by_the_limit() {
        let mut m = grid(bump);
        let corner_uv: Vec<Vec2> = m.indices.iter().map(|&i| Vec2::new((i % 5) as f32 / 4.0, (i / 5) as f32 / 4.0)).collect();
        m.uvs = Some(("st".into(), corner_uv, "faceVarying".into()));
        m.primvars = vec![("height".into(), m.points.iter().map(|p| Vec3::new(p.z, 0.0, 0.0)).collect(), "vertex".into())];
        let r = refine(&m, &tags("catmullClark"), 2, |w| panic!("{w}")).unwrap();
        let (_, uv, interp) = r.mesh.uvs.as_ref().unwrap();
        assert_eq!(interp, "faceVarying");
        for (k, &v) in r.mesh.indices.iter().enumerate() {
            let p = r.mesh.points[v as usize];
            assert!((uv[k] - p.truncate() / 4.0).length() < 1e-5, "uv follows the planar layout");
            // A vertex primvar equal to the height goes through the same stencils.
            assert!((r.mesh.primvars[0].1[k].x - p.z).abs() < 1e-5);
        }
    }

    #[test]
    fn hostile_tags_are_errors_naming_the_attribute() {
        type Edit = fn(&mut SubdivTags);
        let cases: [(&str, Edit); 6] = [
            ("creaseIndices", |t| (t.crease_indices, t.crease_lengths, t.crease_sharpnesses) = (vec![0, 99], vec![2], vec![1.0])),
            ("creaseLengths", |t| (t.crease_indices, t.crease_lengths, t.crease_sharpnesses) = (vec![0, 1], vec![3], vec![1.0])),
            ("creaseSharpnesses", |t| (t.crease_indices, t.crease_lengths, t.crease_sharpnesses) = (vec![0, 1], vec![2], vec![f32::NAN])),
            ("cornerSharpnesses", |t| (t.corner_indices, t.corner_sharpnesses) = (vec![0], vec![])),
            ("holeIndices", |t| t.hole_indices = vec![-1]),
            ("faceVertexCounts", |t| t.scheme = "loop".into()),
        ];
        for (attr, edit) in cases {
            let mut t = tags("catmullClark");
            edit(&mut t);
            let e = refine(&grid(bump), &t, 2, |_| {}).err().unwrap_or_else(|| panic!("{attr}: accepted"));
            assert!(e.contains(attr), "{attr}: {e}");
        }
        let mut degenerate = grid(bump);
        degenerate.counts = vec![2; 32];
        assert!(refine(&degenerate, &tags("catmullClark"), 2, |_| {}).err().unwrap().contains("faceVertexCounts"));
    }

    #[test]
    fn the_worst_level_is_lowered_to_the_face_budget() {
        let mut warnings = Vec::new();
        let r = refine(&grid(bump), &tags("catmullClark"), u32::MAX, |w| warnings.push(w)).unwrap();
        assert_eq!(r.level, 8, "16 quads at level 8 are 1M faces, within budget");
        let big = grid(bump);
        let many = MeshSource { counts: big.counts.repeat(16), indices: big.indices.repeat(16), ..big };
        let r = refine(&many, &tags("catmullClark"), 8, |w| warnings.push(w)).unwrap();
        assert_eq!(r.level, 7, "256 quads at level 8 would be 16M faces");
        assert!(warnings.iter().any(|w| w.contains("level 7, not 8")), "{warnings:?}");
    }
}
