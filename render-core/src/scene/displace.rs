//! The displacement step of commit: a mesh whose UsdPreviewSurface has a `displacement` moves
//! each vertex along its normal by that many object-space units, before its BLAS is built.
//!
//! A mesh too coarse for its displacement texture is diced first, every triangle alike, until
//! an edge spans a texel ([`dicing_rate`]), within one budget for the scene. A textured amount
//! is looked up with a footprint as wide as the triangle around each corner (finer texels could
//! not be represented), and averaged over a vertex's corners so that a texture seam cannot
//! tear the surface apart.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::materials::Materials;
use super::{BlasCache, MeshDesc, SceneDesc, validate_mesh};
use crate::geometry::{Attribute, Mesh, area_weighted_normals};
use crate::material::graph::PrimvarSource;
use crate::material::{MaterialNetwork, ParamValue, ShadingPoint, VaryingInput};

/// What moves a material's surfaces.
#[derive(Clone, Copy)]
pub(super) enum Amount<'a> {
    /// The same distance everywhere.
    Constant(f32),
    /// A texture network connected to the surface node's `displacement`.
    Textured(&'a VaryingInput),
}

/// The displacement material `path` asks for, or None when it asks for none (no
/// UsdPreviewSurface, or `displacement` 0 as exporters write it).
pub(super) fn amount_of<'a>(network: &'a MaterialNetwork, path: &str, materials: &'a Materials) -> Option<Amount<'a>> {
    let surface = network.nodes.iter().find(|n| n.path == network.surface_node && n.node_type_id == "UsdPreviewSurface")?;
    if let Some(input) = materials.displacement_at(path) {
        return Some(Amount::Textured(input));
    }
    match surface.parameters.get("displacement") {
        Some(ParamValue::Float(d)) if *d != 0.0 => Some(Amount::Constant(*d)),
        _ => None,
    }
}

/// A displaced mesh kept between commits with what it was displaced from.
#[derive(Clone)]
pub(super) struct Displaced {
    source: Arc<Mesh>,
    network: MaterialNetwork,
    /// Segments each edge was diced into.
    dice: u32,
    mesh: Arc<Mesh>,
}

/// Texels of the displacement texture a diced edge spans at most: finer dicing would sample
/// the same texels again.
const TEXELS_PER_EDGE: f32 = 1.0;

/// Most segments a triangle's edge is diced into.
const MAX_DICE: u32 = 1024;

/// Most triangles dicing may make in one scene, over all its displaced meshes: a client's
/// displacement texture must not grow the scene without bound (about 180 MB at the 92 bytes
/// a triangle of `docs/benchmarks.md`).
pub const MAX_DICED_TRIANGLES: u64 = 2 << 20;

/// Segments each edge of `mesh` is diced into so that no diced edge spans more than
/// [`TEXELS_PER_EDGE`] of the texture `amount` reads (the whole mesh alike: triangles diced
/// differently would meet at T-junctions and tear apart). 1 for a constant or a texture-free
/// amount, or a mesh without texture coordinates.
fn dicing_rate(mesh: &Mesh, amount: Amount) -> u32 {
    let texels = match amount {
        Amount::Textured(input) => input.texels_per_st(),
        Amount::Constant(_) => 0.0,
    };
    if texels <= 0.0 {
        return 1;
    }
    let longest = (0..mesh.indices.len())
        .filter_map(|t| mesh.uvs.corners(t, mesh.indices[t]))
        .map(|[a, b, c]| (b - a).length().max((c - b).length()).max((a - c).length()))
        .fold(0.0f32, f32::max);
    let want = (longest * texels / TEXELS_PER_EDGE).ceil();
    if want.is_finite() { (want as u32).clamp(1, MAX_DICE) } else { MAX_DICE }
}

/// A mesh to displace: what it is, what displaces it, and how finely it asks to be diced.
struct Wanted<'d, 'm> {
    path: &'d str,
    mesh: &'d MeshDesc,
    network: &'d MaterialNetwork,
    amount: Amount<'m>,
    dice: u32,
}

/// The rates `wanted` asks for, scaled down together (and each reported) where they would
/// make more than [`MAX_DICED_TRIANGLES`].
fn within_budget(wanted: &[Wanted], warnings: &mut Vec<String>) -> Vec<u32> {
    let made = |w: &Wanted| w.mesh.mesh.indices.len() as u64 * (w.dice as u64).pow(2);
    let total: u64 = wanted.iter().filter(|w| w.dice > 1).map(made).sum();
    if total <= MAX_DICED_TRIANGLES {
        return wanted.iter().map(|w| w.dice).collect();
    }
    let scale = (MAX_DICED_TRIANGLES as f64 / total as f64).sqrt();
    wanted
        .iter()
        .map(|w| {
            let n = ((w.dice as f64 * scale).floor() as u32).max(1);
            if n < w.dice {
                warnings.push(format!(
                    "{}: displacement diced {n} segments an edge where its texture asks for {}: the scene's displaced meshes would make more than {MAX_DICED_TRIANGLES} triangles",
                    w.path, w.dice
                ));
            }
            n
        })
        .collect()
}

/// The displaced geometry of every mesh whose material displaces it, by mesh path. A mesh
/// keeps the last commit's displaced `Arc` (and so its BLAS) while its geometry and material
/// network are unchanged. A displacement that would carry points past what the renderer takes
/// (or a non-finite amount) is reported, and the mesh renders undisplaced.
pub(super) fn displaced_meshes<'d>(
    desc: &'d SceneDesc,
    materials: &Materials,
    cache: &mut BlasCache,
    warnings: &mut Vec<String>,
) -> HashMap<&'d str, Arc<Mesh>> {
    let _span = tracing::info_span!("displace").entered();
    let prototypes: HashSet<&str> = desc.instancers.values().map(|i| i.prototype.as_str()).collect();
    let mut wanted = Vec::new();
    for (path, m) in &desc.meshes {
        // Only meshes that render, as the geometry step builds them.
        if !(m.visible || prototypes.contains(path.as_str())) {
            continue;
        }
        let Some(network) = desc.materials.get(&m.material) else { continue };
        let Some(amount) = amount_of(network, &m.material, materials) else { continue };
        // An invalid mesh is the geometry step's error to report; it cannot be displaced.
        if validate_mesh(path, &m.mesh).is_err() {
            continue;
        }
        wanted.push(Wanted { path, mesh: m, network, amount, dice: dicing_rate(&m.mesh, amount) });
    }
    let rates = within_budget(&wanted, warnings);
    let mut jobs = Vec::new();
    let mut kept = HashMap::new();
    for (w, dice) in wanted.into_iter().zip(rates) {
        let unchanged = |d: &&Displaced| Arc::ptr_eq(&d.source, &w.mesh.mesh) && d.network == *w.network && d.dice == dice;
        match cache.displaced.get(w.path).filter(unchanged) {
            Some(d) => {
                kept.insert(w.path, d.clone());
            }
            None => jobs.push(Wanted { dice, ..w }),
        }
    }
    let done: Vec<_> = jobs.into_par_iter().map(|w| (displace(&w.mesh.mesh, w.amount, w.dice), w)).collect();
    for (mesh, w) in done {
        match validate_mesh(w.path, &mesh) {
            Ok(()) => {
                let entry = Displaced { source: w.mesh.mesh.clone(), network: w.network.clone(), dice: w.dice, mesh: Arc::new(mesh) };
                kept.insert(w.path, entry);
            }
            Err(e) => warnings.push(format!("{e} after displacement by {}; the mesh renders undisplaced", w.mesh.material)),
        }
    }
    let out = kept.iter().map(|(p, d)| (*p, d.mesh.clone())).collect();
    cache.displaced = kept.into_iter().map(|(p, d)| (p.to_string(), d)).collect();
    out
}

/// `mesh`, its edges diced into `dice` segments, with every vertex (and every deformation
/// sample's) moved along its normal by `amount`; shading normals recomputed where the mesh had
/// any.
pub(super) fn displace(mesh: &Mesh, amount: Amount, dice: u32) -> Mesh {
    let mut out = if dice > 1 { dice_mesh(mesh, dice) } else { mesh.clone() };
    let sites = Sites::of(&out.positions);
    let distances = match amount {
        Amount::Constant(d) => vec![d; sites.count],
        Amount::Textured(input) => site_distances(&out, &sites, input),
    };
    let n = out.positions.len();
    let deformation = match n {
        0 => Vec::new(),
        _ => out.deformation.chunks(n).flat_map(|pose| moved(pose, &out.indices, &sites, &distances)).collect(),
    };
    out.positions = moved(&out.positions, &out.indices, &sites, &distances);
    out.deformation = deformation;
    if !out.normals.is_empty() {
        let normals = site_normals(&out.positions, &mesh.indices, &sites);
        out.normals = Attribute::Vertex(sites.of.iter().map(|&s| normals[s as usize]).collect());
    }
    out
}

/// The vertices of a mesh grouped by where they are in its rest pose: exporters split a
/// vertex where its texture coordinates or normals do (a UV seam, a hard edge, a sphere's
/// pole), and the copies must move as one or the surface tears there.
struct Sites {
    /// Site of each vertex.
    of: Vec<u32>,
    count: usize,
}

/// Copies of a vertex are those within this share of the mesh's extent: a pole written as
/// sin(π) is 1e-7 from its copies, not 0.
const WELD: f32 = 1.0 / (1 << 20) as f32;

impl Sites {
    fn of(positions: &[Vec3]) -> Sites {
        let (lo, hi) = positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let cell = ((hi - lo).max_element() * WELD).max(f32::MIN_POSITIVE);
        // Points on either side of a cell's edge stay apart; copies that close are rare.
        let key = |p: &Vec3| ((*p - lo) / cell).round().to_array().map(|c| c as i64);
        let mut index = HashMap::with_capacity(positions.len());
        let of = positions
            .iter()
            .map(|p| {
                let next = index.len() as u32;
                *index.entry(key(p)).or_insert(next)
            })
            .collect();
        Sites { of, count: index.len() }
    }
}

/// `mesh` with each triangle split into `n`² by the regular grid of barycentric points i/n, j/n.
/// Every new vertex lies in one triangle, so every attribute (texture coordinates, normals,
/// primvars, deformation samples) becomes per-vertex, interpolated there; the copies of a point
/// on a shared edge are welded again by [`Sites`].
fn dice_mesh(mesh: &Mesh, n: u32) -> Mesh {
    let points: Vec<Vec2> = (0..=n).flat_map(|j| (0..=n - j).map(move |i| Vec2::new(i as f32, j as f32) / n as f32)).collect();
    // Point (i, j) of the grid: rows of n + 1, n, … points.
    let at = |i: u32, j: u32| j * (n + 1) - j * j.saturating_sub(1) / 2 + i;
    let mut local = Vec::with_capacity((n * n) as usize);
    for j in 0..n {
        for i in 0..n - j {
            local.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
            if i + j + 1 < n {
                local.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }
    let tris = mesh.indices.len();
    let per = points.len() as u32;
    let over = |f: &dyn Fn(usize, Vec2) -> Vec3| -> Vec<Vec3> { (0..tris).flat_map(|t| points.iter().map(move |&b| f(t, b))).collect() };
    let lerp = |[a, b, c]: [Vec3; 3], w: Vec2| a * (1.0 - w.x - w.y) + b * w.x + c * w.y;
    let vertex_attr = |a: &Attribute<Vec3>| match a {
        Attribute::None => Attribute::None,
        _ => Attribute::Vertex(over(&|t, b| a.interpolate(t, mesh.indices[t], b).unwrap_or(Vec3::ZERO))),
    };
    let n_points = mesh.positions.len();
    let deformation = if n_points == 0 {
        Vec::new()
    } else {
        mesh.deformation.chunks(n_points).flat_map(|pose| over(&|t, b| lerp(mesh.indices[t].map(|i| pose[i as usize]), b))).collect()
    };
    Mesh {
        positions: over(&|t, b| lerp(mesh.triangle(t), b)),
        indices: (0..tris as u32).flat_map(|t| local.iter().map(move |l| l.map(|k| t * per + k))).collect(),
        normals: vertex_attr(&mesh.normals),
        uvs: match &mesh.uvs {
            Attribute::None => Attribute::None,
            uvs => Attribute::Vertex(
                (0..tris).flat_map(|t| points.iter().map(move |&b| uvs.interpolate(t, mesh.indices[t], b).unwrap_or(Vec2::ZERO))).collect(),
            ),
        },
        primvars: mesh.primvars.iter().map(|p| crate::geometry::Primvar { name: p.name.clone(), values: vertex_attr(&p.values) }).collect(),
        deformation,
    }
}

/// `positions` each moved by its site's distance along the site's area-weighted normal in
/// this pose.
fn moved(positions: &[Vec3], indices: &[[u32; 3]], sites: &Sites, distances: &[f32]) -> Vec<Vec3> {
    let normals = site_normals(positions, indices, sites);
    positions.iter().zip(&sites.of).map(|(p, &s)| *p + normals[s as usize] * distances[s as usize]).collect()
}

/// Unit normal of each site, the sum of its triangles' area-weighted normals (zero for a site
/// no triangle with area uses).
fn site_normals(positions: &[Vec3], indices: &[[u32; 3]], sites: &Sites) -> Vec<Vec3> {
    area_weighted_normals(positions, indices, |v| sites.of[v as usize] as usize, sites.count)
}

/// The textured distance at each site: the mean of the lookups at its vertices' corners.
fn site_distances(mesh: &Mesh, sites: &Sites, input: &VaryingInput) -> Vec<f32> {
    let corners = 3 * mesh.indices.len();
    let vertex_of = |c: usize| mesh.indices[c / 3][c % 3];
    // Where every corner of a vertex reads the same texture coordinates and primvars, one
    // lookup per vertex (at its first corner) stands for them all: a sixth of the lookups on
    // a grid.
    let looked_up: Vec<(u32, f32)> =
        if matches!(mesh.uvs, Attribute::FaceVarying(_)) || mesh.primvars.iter().any(|p| matches!(p.values, Attribute::FaceVarying(_))) {
            (0..corners).into_par_iter().map(|c| (vertex_of(c), corner_distance(mesh, c, input))).collect()
        } else {
            let mut first = vec![usize::MAX; mesh.positions.len()];
            for c in (0..corners).rev() {
                first[vertex_of(c) as usize] = c;
            }
            first.into_par_iter().filter(|&c| c != usize::MAX).map(|c| (vertex_of(c), corner_distance(mesh, c, input))).collect()
        };
    let mut sum = vec![(0.0f32, 0u32); sites.count];
    for (v, d) in looked_up {
        let s = &mut sum[sites.of[v as usize] as usize];
        *s = (s.0 + d, s.1 + 1);
    }
    sum.into_iter().map(|(s, k)| if k > 0 { s / k as f32 } else { 0.0 }).collect()
}

/// The displacement looked up at corner `c` (corner `c % 3` of triangle `c / 3`), filtered
/// over its triangle's size in texture space.
fn corner_distance(mesh: &Mesh, c: usize, input: &VaryingInput) -> f32 {
    let (t, k) = (c / 3, c % 3);
    let [a, b, p] = mesh.triangle(t);
    let area = 0.5 * (b - a).cross(p - a).length();
    let uvs = mesh.uvs.corners(t, mesh.indices[t]);
    let uv_area = uvs.map_or(0.0, |[p, q, r]| 0.5 * (q - p).perp_dot(r - p).abs());
    let (width, uv_density) = if area > 0.0 && uv_area > 0.0 { ((2.0 * area).sqrt(), (uv_area / area).sqrt()) } else { (0.0, 1.0) };
    let bary = [Vec2::ZERO, Vec2::X, Vec2::Y][k];
    let sp =
        ShadingPoint { st: uvs.map(|uv| uv[k]), primvars: Some(PrimvarSource { mesh, triangle: t, bary }), width, cos: 1.0, uv_density };
    match input.at(&sp) {
        ParamValue::Float(d) => d,
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_displacement_grows_a_sphere_by_its_amount() {
        // A closed unit sphere: every vertex moves out along its radius, so it lands at
        // 1 + d (the area-weighted normal's tilt from the radius is zero by symmetry). Its
        // poles are 48 copies of one point each, which must move as one.
        let sphere = Mesh::uv_sphere(24, 48);
        let out = displace(&sphere, Amount::Constant(0.1), 1);
        for p in &out.positions {
            assert!((p.length() - 1.1).abs() < 1e-4, "{p} at radius {}", p.length());
        }
        let inward = displace(&sphere, Amount::Constant(-0.25), 1);
        assert!(inward.positions.iter().all(|p| (p.length() - 0.75).abs() < 1e-4));
    }

    #[test]
    fn deformation_samples_are_displaced_each_along_its_own_normals() {
        let mut sphere = Mesh::uv_sphere(8, 16);
        let n = sphere.positions.len();
        // Two poses: the sphere where it is, then moved by 5 along x.
        sphere.deformation = sphere.positions.iter().copied().chain(sphere.positions.iter().map(|p| *p + Vec3::X * 5.0)).collect();
        let out = displace(&sphere, Amount::Constant(0.5), 1);
        assert_eq!(out.deformation.len(), 2 * n);
        for (i, p) in out.deformation.iter().enumerate() {
            let centre = if i < n { Vec3::ZERO } else { Vec3::X * 5.0 };
            assert!(((*p - centre).length() - 1.5).abs() < 1e-3, "sample {} vertex {}: {p}", i / n, i % n);
        }
    }

    #[test]
    fn shading_normals_follow_the_displaced_surface_and_flat_meshes_stay_flat() {
        let mut sphere = Mesh::uv_sphere(8, 16);
        let flat = displace(&sphere, Amount::Constant(0.2), 1);
        assert!(flat.normals.is_empty(), "a flat-shaded mesh stays flat-shaded");
        sphere.normals = Attribute::Vertex(vec![Vec3::X; sphere.positions.len()]);
        let smooth = displace(&sphere, Amount::Constant(0.2), 1);
        let Attribute::Vertex(normals) = &smooth.normals else { panic!("vertex normals expected") };
        for (p, n) in smooth.positions.iter().zip(normals) {
            assert!(n.dot(p.normalize()) > 0.99, "normal {n} at {p} should point out of the sphere");
        }
    }

    #[test]
    fn degenerate_triangles_and_unused_vertices_stay_finite() {
        let mesh = Mesh {
            positions: vec![Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::new(1e30, 0.0, 0.0)],
            indices: vec![[0, 1, 2]],
            ..Default::default()
        };
        let out = displace(&mesh, Amount::Constant(3.0), 1);
        assert!(out.positions.iter().all(|p| p.is_finite()));
        assert_eq!(out.positions[..3], [Vec3::ZERO; 3], "no direction to move along: the points stay");
    }

    /// A displacement read from the mesh's float primvar `height` (no texture needed).
    fn height_primvar_displacement() -> VaryingInput {
        use crate::material::{MaterialConnection, MaterialNode};
        let node = |path: &str, id: &str| MaterialNode { path: path.into(), node_type_id: id.into(), ..Default::default() };
        let mut reader = node("/M/H", "UsdPrimvarReader_float");
        reader.parameters.insert("varname".into(), ParamValue::String("height".into()));
        let network = MaterialNetwork {
            nodes: vec![node("/M/S", "UsdPreviewSurface"), reader],
            connections: vec![MaterialConnection {
                downstream_node: "/M/S".into(),
                downstream_input: "displacement".into(),
                upstream_node: "/M/H".into(),
                upstream_output: "result".into(),
            }],
            surface_node: "/M/S".into(),
        };
        VaryingInput::displacement(&network, &|_, _| None, &mut Default::default()).expect("a varying displacement")
    }

    /// Two triangles of a unit square in the z = 0 plane facing +z, sharing the diagonal 0-2.
    fn square(height: Attribute<Vec3>) -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            primvars: vec![crate::geometry::Primvar { name: "height".into(), values: height }],
            ..Default::default()
        }
    }

    #[test]
    fn a_vertex_primvar_moves_each_vertex_by_its_value() {
        let heights = [0.1, 0.2, 0.3, 0.4].map(|h| Vec3::new(h, 0.0, 0.0)).to_vec();
        let out = displace(&square(Attribute::Vertex(heights)), Amount::Textured(&height_primvar_displacement()), 1);
        let z: Vec<f32> = out.positions.iter().map(|p| p.z).collect();
        assert_eq!(z, [0.1, 0.2, 0.3, 0.4]);
    }

    #[test]
    fn face_varying_values_are_averaged_over_a_vertex_s_corners() {
        // Corners of triangle 0 (vertices 0, 1, 2) read 1; of triangle 1 (0, 2, 3) read 3: the
        // shared vertices 0 and 2 move by the mean, 2; vertex 1 by 1 and vertex 3 by 3.
        let corners = [1.0, 1.0, 1.0, 3.0, 3.0, 3.0].map(|h| Vec3::new(h, 0.0, 0.0)).to_vec();
        let out = displace(&square(Attribute::FaceVarying(corners)), Amount::Textured(&height_primvar_displacement()), 1);
        let z: Vec<f32> = out.positions.iter().map(|p| p.z).collect();
        assert_eq!(z, [2.0, 1.0, 2.0, 3.0]);
    }

    #[test]
    fn dicing_splits_each_triangle_into_n_squared_with_its_attributes_interpolated() {
        let tri = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X * 3.0, Vec3::Z * -3.0],
            indices: vec![[0, 1, 2]],
            uvs: Attribute::FaceVarying(vec![Vec2::ZERO, Vec2::X, Vec2::Y]),
            deformation: vec![Vec3::ZERO, Vec3::X * 3.0, Vec3::Z * -3.0, Vec3::Y, Vec3::Y + Vec3::X * 3.0, Vec3::Y + Vec3::Z * -3.0],
            ..Default::default()
        };
        let diced = dice_mesh(&tri, 3);
        assert_eq!((diced.indices.len(), diced.positions.len()), (9, 10));
        // The same surface, every piece facing the way the triangle does.
        let area = |m: &Mesh, t: usize| {
            let [a, b, c] = m.triangle(t);
            (b - a).cross(c - a) * 0.5
        };
        let whole = area(&tri, 0);
        let sum: Vec3 = (0..9).map(|t| area(&diced, t)).sum();
        assert!((sum - whole).length() < 1e-5, "{sum} against {whole}");
        assert!((0..9).all(|t| area(&diced, t).dot(whole) > 0.0));
        // Texture coordinates follow the positions: st = (x, -z) / 3 on this triangle.
        let Attribute::Vertex(st) = &diced.uvs else { panic!("per-vertex st expected") };
        for (p, uv) in diced.positions.iter().zip(st) {
            assert!((*uv - Vec2::new(p.x, -p.z) / 3.0).length() < 1e-6, "{p}: {uv}");
        }
        // Both deformation poses diced alike: the second is the first moved up by 1.
        assert_eq!(diced.deformation.len(), 20);
        assert!(diced.deformation[..10].iter().zip(&diced.deformation[10..]).all(|(a, b)| (*b - *a - Vec3::Y).length() < 1e-6));
    }

    #[test]
    fn a_diced_closed_mesh_stays_closed_when_displaced() {
        // Dicing copies the points of shared edges into each triangle. Welded, the copies move
        // as one: points that were one place before displacement are one place after.
        let sphere = Mesh::uv_sphere(12, 24);
        let out = displace(&sphere, Amount::Constant(0.1), 4);
        assert_eq!(out.indices.len(), sphere.indices.len() * 16);
        let before = dice_mesh(&sphere, 4);
        let sites = Sites::of(&before.positions);
        let mut place = vec![None; sites.count];
        for (p, &s) in out.positions.iter().zip(&sites.of) {
            let first = *place[s as usize].get_or_insert(*p);
            assert!((first - *p).length() < 1e-6, "copies of one point apart: {first} and {p}");
        }
        // Every point 0.1 out from the facet it lay on: the facets of this 15° sphere lie at
        // least cos(15°) = 0.966 from the centre.
        assert!(out.positions.iter().all(|p| p.length() > 0.966 + 0.1 - 1e-3 && p.length() < 1.1 + 1e-4));
    }
}
