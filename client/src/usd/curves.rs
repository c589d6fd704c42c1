//! `UsdGeomBasisCurves` as round tubes, or as flat ribbons where `normals` orient them (the
//! schema's rule: "widths are ribbon width" for oriented curves): each curve evaluated with its
//! basis (linear, or cubic `bezier`, `bspline`, `catmullRom`; `nonperiodic`, `periodic` or
//! `pinned`), sampled along every span (`--curve-samples` times, a quality knob:
//! docs/accuracy-vs-time.md), and swept by a polygon of its `widths` carried along by parallel
//! transport, or by a segment of its width across the curve and its normal.
//! One triangle mesh per prim, so curves render through the ordinary path with the bound
//! material; the primvars that material reads are carried onto the tube's vertices, float2
//! ones by name beside the tube's own (s, t), which the hair frame follows. The polygon's
//! circumradius is widened so its width averaged over directions is
//! the curve's width (a regular n-gon's mean width is its perimeter over π).

use anyhow::{Context, Result};
use glam::{Vec2, Vec3};
use render_core::geometry::{Attribute, Mesh, Primvar};

use super::*;

/// Points a cubic span is sampled at along its length when none are asked for
/// (`--curve-samples`; linear spans need only their ends).
pub const DEFAULT_CURVE_SAMPLES: usize = 8;
/// The most samples per span one may ask for.
pub const MAX_CURVE_SAMPLES: usize = 64;
/// Sides of the polygon swept along a curve.
pub const SIDES: usize = 12;
/// Most tube vertices one prim may make (32 bytes of position, normal and texture coordinate
/// each, before the BVH): a fur of a million 10-span curves is past it and is refused naming the prim.
pub const MAX_TUBE_VERTICES: usize = 24 << 20;

/// The curve types and bases UsdGeomBasisCurves defines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Basis {
    Linear,
    Bezier,
    Bspline,
    CatmullRom,
}

/// `wrap`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Wrap {
    Nonperiodic,
    Periodic,
    Pinned,
}

/// A prim's curves, read and checked.
pub struct Curves {
    pub basis: Basis,
    pub wrap: Wrap,
    pub counts: Vec<usize>,
    pub points: Vec<Vec3>,
    /// Widths and their interpolation (`constant`, `uniform`, `varying`, `vertex`).
    pub widths: (Vec<f32>, String),
    /// Normals and their interpolation, when they orient the curves as ribbons.
    pub normals: Option<(Vec<Vec3>, String)>,
    /// The primvars the bound material reads (float and int in x, float2 in xy, float3 in
    /// xyz): name without `primvars:`, values (de-indexed), interpolation (`faceVarying`
    /// read as `varying`, as UsdGeomBasisCurves defines it).
    pub primvars: Vec<(String, Vec<Vec3>, String)>,
    /// Samples per cubic span.
    pub samples: usize,
}

/// The weights of the four control points of a cubic span at `u` (USD's, RenderMan's bases).
fn cubic_weights(basis: Basis, u: f32) -> [f32; 4] {
    let (u2, u3, v) = (u * u, u * u * u, 1.0 - u);
    match basis {
        Basis::Bezier => [v * v * v, 3.0 * u * v * v, 3.0 * u2 * v, u3],
        Basis::Bspline => [v * v * v / 6.0, (3.0 * u3 - 6.0 * u2 + 4.0) / 6.0, (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) / 6.0, u3 / 6.0],
        Basis::CatmullRom => {
            [(-u3 + 2.0 * u2 - u) / 2.0, (3.0 * u3 - 5.0 * u2 + 2.0) / 2.0, (-3.0 * u3 + 4.0 * u2 + u) / 2.0, (u3 - u2) / 2.0]
        }
        Basis::Linear => [v, u, 0.0, 0.0],
    }
}

/// The control points a curve's spans read, padded for `pinned` B-spline and Catmull-Rom
/// curves (P₋₁ = 2P₀ − P₁ and likewise at the end, so the curve reaches its end points), and
/// the number of spans; `None` when the count does not make a curve of this kind.
fn spans<T: Copy + std::ops::Sub<Output = T> + std::ops::Add<Output = T>>(basis: Basis, wrap: Wrap, cv: &[T]) -> Option<(Vec<T>, usize)> {
    let n = cv.len();
    let pad = |v: &[T]| {
        let (first, last) = (v[0] + (v[0] - v[1]), v[n - 1] + (v[n - 1] - v[n - 2]));
        std::iter::once(first).chain(v.iter().copied()).chain(std::iter::once(last)).collect::<Vec<T>>()
    };
    let wrapped = |extra: usize| cv.iter().chain(cv.iter().take(extra)).copied().collect::<Vec<T>>();
    let count = span_count(basis, wrap, n)?;
    let ctrl = match (basis, wrap) {
        (Basis::Linear | Basis::Bezier, Wrap::Periodic) => wrapped(1),
        (Basis::Linear | Basis::Bezier, _) => cv.to_vec(),
        (_, Wrap::Periodic) => wrapped(3),
        (_, Wrap::Pinned) => pad(cv),
        (_, Wrap::Nonperiodic) => cv.to_vec(),
    };
    Some((ctrl, count))
}

/// The spans of a curve of `n` vertices, as UsdGeomBasisCurves counts its segments; `None`
/// when `n` makes no curve of this kind (pinned linear and Bézier curves are nonperiodic ones).
fn span_count(basis: Basis, wrap: Wrap, n: usize) -> Option<usize> {
    match (basis, wrap) {
        (Basis::Linear, Wrap::Periodic) if n >= 2 => Some(n),
        (Basis::Linear, _) if n >= 2 => Some(n - 1),
        (Basis::Bezier, Wrap::Periodic) if n >= 3 && n.is_multiple_of(3) => Some(n / 3),
        (Basis::Bezier, _) if n >= 4 && (n - 4).is_multiple_of(3) => Some((n - 1) / 3),
        (Basis::Linear | Basis::Bezier, _) => None,
        (_, Wrap::Periodic) if n >= 3 => Some(n),
        (_, Wrap::Pinned) if n >= 2 => Some(n - 1),
        (_, Wrap::Nonperiodic) if n >= 4 => Some(n - 3),
        _ => None,
    }
}

/// The first control point of span `k` in [`spans`]'s list.
fn span_start(basis: Basis, k: usize) -> usize {
    match basis {
        Basis::Bezier => 3 * k,
        _ => k,
    }
}

impl Curves {
    /// The tube mesh of every curve, or an error naming what does not fit.
    pub fn tessellate(&self) -> Result<Mesh, String> {
        // Counted before anything is built: one curve may ask for billions of rings.
        let closing = usize::from(self.wrap == Wrap::Periodic);
        let vertices =
            self.counts.iter().map(|&n| self.rings(n)).try_fold(0usize, |a, r| a.checked_add((r + closing).checked_mul(SIDES + 1)?));
        if vertices.is_none_or(|v| v > MAX_TUBE_VERTICES) {
            return Err(format!("the tubes of its curves need more than {MAX_TUBE_VERTICES} vertices"));
        }
        let mut mesh = Mesh::default();
        let (mut normals, mut uvs) = (Vec::new(), Vec::new());
        let mut primvars = vec![Vec::new(); self.primvars.len()];
        let (mut first, mut first_varying) = (0, 0);
        let closed = self.wrap == Wrap::Periodic;
        for (c, &count) in self.counts.iter().enumerate() {
            let cv = &self.points[first..first + count];
            let line = self.centreline(c, cv, first, &mut first_varying)?;
            let before = mesh.positions.len();
            match line.normals.is_empty() {
                true => sweep(&line.centres, &line.widths, closed, &mut mesh, &mut normals, &mut uvs),
                false => sweep_ribbon(&line, closed, &mut mesh, &mut normals, &mut uvs),
            }
            line.spread_primvars(mesh.positions.len() - before, closed, &mut primvars);
            first += count;
        }
        mesh.normals = Attribute::Vertex(normals);
        mesh.uvs = Attribute::Vertex(uvs);
        mesh.primvars = self
            .primvars
            .iter()
            .zip(primvars)
            .map(|((name, _, _), values)| Primvar { name: name.clone(), values: Attribute::Vertex(values) })
            .collect();
        Ok(mesh)
    }

    /// Rings (samples along the centre line) of a curve of `n` vertices; 0 when it is no curve.
    fn rings(&self, n: usize) -> usize {
        let spans = span_count(self.basis, self.wrap, n).unwrap_or(0);
        let samples = if self.basis == Basis::Linear { 1 } else { self.samples };
        spans * samples + usize::from(self.wrap != Wrap::Periodic && spans > 0)
    }

    /// Curve `c`'s sampled centre line, with its widths (and normals) along it. `first`
    /// indexes its first control point; `first_varying` its first `varying` value, advanced past
    /// its own.
    fn centreline(&self, c: usize, cv: &[Vec3], first: usize, first_varying: &mut usize) -> Result<Centreline, String> {
        let (ctrl, n_spans) = spans(self.basis, self.wrap, cv)
            .ok_or_else(|| format!("curve {c} has {} vertices, which make no {:?} {:?} curve", cv.len(), self.wrap, self.basis))?;
        let samples = if self.basis == Basis::Linear { 1 } else { self.samples };
        let at = Along { curves: self, c, first, count: cv.len(), first_varying: *first_varying, n_spans };
        let width = at.attribute(&self.widths.0, &self.widths.1);
        let normal = self.normals.as_ref().map(|(v, interp)| at.attribute(v, interp));
        let primvars: Vec<_> = self.primvars.iter().map(|(_, v, interp)| at.attribute(v, interp)).collect();
        let mut line = Centreline { primvars: vec![Vec::new(); primvars.len()], ..Default::default() };
        for k in 0..n_spans {
            let s = span_start(self.basis, k);
            let last = k + 1 == n_spans && self.wrap != Wrap::Periodic;
            for j in 0..samples + usize::from(last) {
                let u = j as f32 / samples as f32;
                let b = cubic_weights(self.basis, u);
                line.centres.push((0..4).filter(|&i| b[i] != 0.0).map(|i| ctrl[s + i] * b[i]).sum());
                line.widths.push(width(k, u, b));
                if let Some(normal) = &normal {
                    line.normals.push(normal(k, u, b));
                }
                for (values, primvar) in line.primvars.iter_mut().zip(&primvars) {
                    values.push(primvar(k, u, b));
                }
            }
        }
        *first_varying += if self.wrap == Wrap::Periodic { n_spans } else { n_spans + 1 };
        Ok(line)
    }
}

/// A curve's samples along its centre line.
#[derive(Default)]
struct Centreline {
    centres: Vec<Vec3>,
    widths: Vec<f32>,
    /// Empty for a tube.
    normals: Vec<Vec3>,
    /// Each primvar's value at each sample.
    primvars: Vec<Vec<Vec3>>,
}

impl Centreline {
    /// Appends each primvar's values for the `added` vertices a sweep made of this line: rings
    /// of equal size, one per sample (and, on a closed curve, the first sample's again).
    fn spread_primvars(&self, added: usize, closed: bool, out: &mut [Vec<Vec3>]) {
        let n = self.centres.len();
        if added == 0 {
            return;
        }
        let rings = n + usize::from(closed);
        for (values, out) in self.primvars.iter().zip(out) {
            out.extend((0..rings).flat_map(|i| std::iter::repeat_n(values[i % n], added / rings)));
        }
    }
}

/// Where one curve's values sit in a prim's attribute arrays.
struct Along<'c> {
    curves: &'c Curves,
    c: usize,
    first: usize,
    count: usize,
    first_varying: usize,
    n_spans: usize,
}

impl Along<'_> {
    /// An attribute of `interp` interpolation along the curve, at span k, parameter u and
    /// basis weights b: per-vertex values follow the curve's own basis, varying ones are
    /// linear per span, as UsdGeomBasisCurves interpolates primvars.
    fn attribute<'v, T>(&self, values: &'v [T], interp: &'v str) -> impl Fn(usize, f32, [f32; 4]) -> T + 'v
    where
        T: Copy + std::ops::Add<Output = T> + std::ops::Sub<Output = T> + std::ops::Mul<f32, Output = T>,
    {
        let (basis, periodic) = (self.curves.basis, self.curves.wrap == Wrap::Periodic);
        let spanned: Vec<T> = match interp {
            "vertex" => spans(basis, self.curves.wrap, &values[self.first..self.first + self.count]).map(|(v, _)| v).unwrap_or_default(),
            _ => Vec::new(),
        };
        let (c, first_varying, n_spans) = (self.c, self.first_varying, self.n_spans);
        move |k, u, b| match interp {
            "constant" => values[0],
            "uniform" => values[c],
            "varying" => {
                let at = |i: usize| values[first_varying + if periodic { i % n_spans } else { i }];
                at(k) * (1.0 - u) + at(k + 1) * u
            }
            _ => {
                let s = span_start(basis, k);
                (0..4).filter(|&i| b[i] != 0.0).map(|i| spanned[s + i] * b[i]).reduce(|a, b| a + b).expect("a cubic weight is nonzero")
            }
        }
    }
}

/// The tangent of a sampled centre line at sample `i`, by central differences.
fn tangent_at(centres: &[Vec3], closed: bool, i: usize) -> Vec3 {
    let n = centres.len();
    let (a, b) = match (i, closed) {
        (0, false) => (centres[0], centres[1]),
        (i, false) if i == n - 1 => (centres[n - 2], centres[n - 1]),
        (i, _) => (centres[(i + n - 1) % n], centres[(i + 1) % n]),
    };
    (b - a).normalize_or(Vec3::X)
}

/// Sweeps a segment of each sample's width across the curve, perpendicular to its tangent and
/// its normal, appending the ribbon's quads to `mesh`, the normals (made perpendicular to the
/// tangent) to `normals` and texture coordinates to `uvs`: s across the ribbon, t along it as
/// on tubes.
fn sweep_ribbon(line: &Centreline, closed: bool, mesh: &mut Mesh, normals: &mut Vec<Vec3>, uvs: &mut Vec<Vec2>) {
    let n = line.centres.len();
    if n < 2 {
        return;
    }
    let base = mesh.positions.len() as u32;
    let rings = n + usize::from(closed);
    for i in 0..rings {
        let j = i % n;
        let t = tangent_at(&line.centres, closed, j);
        let normal = (line.normals[j] - t * line.normals[j].dot(t)).normalize_or(t.any_orthonormal_vector());
        let half = t.cross(normal) * (0.5 * line.widths[j]);
        let t_coord = i as f32 / (rings - 1) as f32;
        for (s, p) in [(0.0, line.centres[j] - half), (1.0, line.centres[j] + half)] {
            mesh.positions.push(p);
            normals.push(normal);
            uvs.push(Vec2::new(s, t_coord));
        }
    }
    for i in 0..rings as u32 - 1 {
        let (a, b) = (base + 2 * i, base + 2 * (i + 1));
        mesh.indices.push([a, b, b + 1]);
        mesh.indices.push([a, b + 1, a + 1]);
    }
}

/// Sweeps a polygon of [`SIDES`] along `centres` (closed when `closed`), appending its quads
/// to `mesh`, its radial normals to `normals` and its texture coordinates to `uvs`: s around
/// the tube, t from 0 at the curve's first point to 1 at its last. The fibre's direction is
/// ∂p/∂t, which the hair BSDF's frame follows; the seams (s = 1, and a closed curve's last
/// ring) repeat their vertices so that t and s never jump inside a triangle.
fn sweep(centres: &[Vec3], widths: &[f32], closed: bool, mesh: &mut Mesh, normals: &mut Vec<Vec3>, uvs: &mut Vec<Vec2>) {
    let n = centres.len();
    if n < 2 {
        return;
    }
    let tangent = |i: usize| tangent_at(centres, closed, i);
    // The mean width of a regular n-gon of circumradius ρ is 2nρ·sin(π/n)/π.
    let widen = std::f32::consts::PI / (SIDES as f32 * (std::f32::consts::PI / SIDES as f32).sin());
    let base = mesh.positions.len() as u32;
    let rings = n + usize::from(closed);
    let mut normal = tangent(0).any_orthonormal_vector();
    let mut first_ring = Vec::new();
    for i in 0..rings {
        let t_coord = i as f32 / (rings - 1) as f32;
        if i == n {
            // A closed curve's last ring is its first again, at t = 1.
            for (k, &(p, r)) in first_ring.iter().enumerate() {
                mesh.positions.push(p);
                normals.push(r);
                uvs.push(Vec2::new(k as f32 / SIDES as f32, 1.0));
            }
            break;
        }
        let t = tangent(i);
        // Parallel transport: the previous normal, made perpendicular to this tangent.
        normal = (normal - t * normal.dot(t)).normalize_or(t.any_orthonormal_vector());
        let binormal = t.cross(normal);
        let rho = 0.5 * widths[i] * widen;
        for s in 0..=SIDES {
            let (sin, cos) = (std::f32::consts::TAU * (s % SIDES) as f32 / SIDES as f32).sin_cos();
            let radial = normal * cos + binormal * sin;
            let p = centres[i] + radial * rho;
            if i == 0 {
                first_ring.push((p, radial));
            }
            mesh.positions.push(p);
            normals.push(radial);
            uvs.push(Vec2::new(s as f32 / SIDES as f32, t_coord));
        }
    }
    let stride = (SIDES + 1) as u32;
    for i in 0..rings as u32 - 1 {
        let (a, b) = (base + i * stride, base + (i + 1) * stride);
        for s in 0..SIDES as u32 {
            mesh.indices.push([a + s, b + s, b + s + 1]);
            mesh.indices.push([a + s, b + s + 1, a + s + 1]);
        }
    }
}

/// How many values an attribute of `interp` interpolation holds on these curves.
fn values_needed(curves: &Curves, interp: &str) -> Option<usize> {
    Some(match interp {
        "constant" => 1,
        "uniform" => curves.counts.len(),
        "vertex" => curves.points.len(),
        "varying" => curves
            .counts
            .iter()
            .map(|&n| {
                let spans = span_count(curves.basis, curves.wrap, n).unwrap_or(0);
                if curves.wrap == Wrap::Periodic { spans } else { spans + 1 }
            })
            .sum(),
        _ => return None,
    })
}

impl Reader<'_> {
    pub(super) fn basis_curves(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let mut curves = self.read_curves(prim, p)?;
        let material = self.usable_material(prim)?;
        // The hair BSDF integrates over a round fibre's cross-section.
        let hair = |(path, n): &(String, render_core::material::MaterialNetwork)| {
            Some(path) == material.as_ref() && n.nodes.iter().any(|node| node.path == n.surface_node && node.node_type_id == "tessera:Hair")
        };
        if curves.normals.is_some() && self.out.materials.iter().any(hair) {
            curves.normals = None;
            self.out
                .warnings
                .push(format!("{p}: tessera:Hair shades round fibres; these curves' 'normals' are ignored and they render as tubes"));
        }
        let mesh = curves.tessellate().map_err(|e| anyhow::anyhow!("{p}: {e}"))?;
        self.out.curves.push(p.to_string());
        self.out.curve_samples = self.curve_samples;
        self.add_mesh_with(prim, p, mesh, visible, material)
    }

    /// The prim's curves, checked: counts against the points, each count against the curve's
    /// kind, widths against their interpolation.
    fn read_curves(&mut self, prim: &Prim, p: &str) -> Result<Curves> {
        let time = self.time;
        let token = |name: &str, fallback: &str| -> Result<String> {
            Ok(get(prim, name, time)?.as_ref().and_then(values::token).unwrap_or_else(|| fallback.to_string()))
        };
        let basis = match (token("type", "cubic")?.as_str(), token("basis", "bezier")?.as_str()) {
            ("linear", _) => Basis::Linear,
            ("cubic", "bezier") => Basis::Bezier,
            ("cubic", "bspline") => Basis::Bspline,
            ("cubic", "catmullRom") => Basis::CatmullRom,
            (t, b) => anyhow::bail!("{p}: attributes 'type' and 'basis' are '{t}' and '{b}', not a curve type USD defines"),
        };
        let wrap = match token("wrap", "nonperiodic")?.as_str() {
            "nonperiodic" => Wrap::Nonperiodic,
            "periodic" => Wrap::Periodic,
            "pinned" => Wrap::Pinned,
            other => anyhow::bail!("{p}: attribute 'wrap' is '{other}', not nonperiodic, periodic or pinned"),
        };
        let points = get(prim, "points", time)?
            .as_ref()
            .and_then(values::vec3_array)
            .with_context(|| format!("{p}: attribute 'points' is missing or not a point3f[]"))?;
        if let Some((i, v)) = points.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            anyhow::bail!("{p}: attribute 'points': point {i} is {v} (NaN or Inf)");
        }
        let counts =
            get_ints(prim, p, "curveVertexCounts", time)?.with_context(|| format!("{p}: attribute 'curveVertexCounts' is missing"))?;
        if let Some(bad) = counts.iter().find(|&&c| c < 0) {
            anyhow::bail!("{p}: attribute 'curveVertexCounts' holds {bad}");
        }
        let counts: Vec<usize> = counts.into_iter().map(|c| c as usize).collect();
        let total = counts.iter().try_fold(0usize, |a, &c| a.checked_add(c)).unwrap_or(usize::MAX);
        anyhow::ensure!(
            total == points.len(),
            "{p}: attribute 'curveVertexCounts' adds up to {total} vertices for {} points",
            points.len()
        );
        let mut curves = Curves {
            basis,
            wrap,
            counts,
            points,
            widths: (vec![1.0], "constant".into()),
            normals: None,
            primvars: Vec::new(),
            samples: self.curve_samples,
        };
        let interpolation = |name: &str| {
            prim.attribute(name)
                .get_metadata::<openusd::tf::Token>("interpolation")
                .ok()
                .flatten()
                .map_or_else(|| "vertex".to_string(), |t| t.as_str().to_string())
        };
        if let Some(normals) = get(prim, "normals", time)? {
            let normals = values::vec3_array(&normals).with_context(|| format!("{p}: attribute 'normals' is not a normal3f[]"))?;
            let interp = interpolation("normals");
            let want = values_needed(&curves, &interp).with_context(|| format!("{p}: attribute 'normals' has interpolation '{interp}'"))?;
            anyhow::ensure!(normals.len() == want, "{p}: attribute 'normals' has {} {interp} values for {want}", normals.len());
            if let Some((i, n)) = normals.iter().enumerate().find(|(_, n)| !n.is_finite() || n.length_squared() == 0.0) {
                anyhow::bail!("{p}: attribute 'normals': normal {i} is {n}, which orients nothing");
            }
            curves.normals = Some((normals, interp));
        }
        if let Some(widths) = get_floats(prim, p, "widths", time)? {
            let interp = interpolation("widths");
            let want = values_needed(&curves, &interp).with_context(|| format!("{p}: attribute 'widths' has interpolation '{interp}'"))?;
            if let Some((i, w)) = widths.iter().enumerate().find(|(_, w)| !(w.is_finite() && **w >= 0.0)) {
                anyhow::bail!("{p}: attribute 'widths': width {i} is {w}; widths are finite and not negative");
            }
            anyhow::ensure!(widths.len() == want, "{p}: attribute 'widths' has {} {interp} values for {want}", widths.len());
            curves.widths = (widths, interp);
        }
        curves.primvars = self.curve_primvars(prim, p, &curves)?;
        Ok(curves)
    }

    /// The primvars the curves' material reads (its float2 texture coordinates among them),
    /// checked against their interpolation: one whose count does not fit is a warning naming
    /// it, and its readers use their fallbacks.
    fn curve_primvars(&mut self, prim: &Prim, p: &str, curves: &Curves) -> Result<Vec<(String, Vec<Vec3>, String)>> {
        let mut read = self.primvars(prim, p)?;
        let reads_float2 = !self.reader_varnames(prim, &["UsdPrimvarReader_float2"])?.is_empty();
        if reads_float2 && let Some((attr, st, interp)) = self.uvs(prim, p)? {
            read.push((attr.trim_start_matches("primvars:").to_string(), st.iter().map(|v| v.extend(0.0)).collect(), interp));
        }
        let mut kept = Vec::new();
        for (name, values, interp) in read {
            let interp = if interp == "faceVarying" { "varying".to_string() } else { interp };
            match values_needed(curves, &interp) {
                Some(want) if want == values.len() => kept.push((name, values, interp)),
                want => self.out.warnings.push(format!(
                    "{p}: primvars:{name} has {} {interp} values{}; its readers use their fallbacks",
                    values.len(),
                    want.map_or(String::new(), |w| format!(" for {w}"))
                )),
            }
        }
        Ok(kept)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(basis: Basis, wrap: Wrap, points: Vec<Vec3>, widths: (Vec<f32>, &str)) -> Curves {
        Curves {
            basis,
            wrap,
            counts: vec![points.len()],
            points,
            widths: (widths.0, widths.1.into()),
            normals: None,
            primvars: Vec::new(),
            samples: DEFAULT_CURVE_SAMPLES,
        }
    }

    #[test]
    fn every_basis_weighs_to_one() {
        for basis in [Basis::Bezier, Basis::Bspline, Basis::CatmullRom, Basis::Linear] {
            for k in 0..=10 {
                let s: f32 = cubic_weights(basis, k as f32 / 10.0).iter().sum();
                assert!((s - 1.0).abs() < 1e-6, "{basis:?}");
            }
        }
    }

    #[test]
    fn bezier_and_catmull_rom_pass_through_their_end_points_and_knots() {
        let p = vec![Vec3::ZERO, Vec3::new(1.0, 2.0, 0.0), Vec3::new(3.0, 2.0, 0.0), Vec3::new(4.0, 0.0, 0.0)];
        let c = curve(Basis::Bezier, Wrap::Nonperiodic, p.clone(), (vec![0.1], "constant"));
        let centres = c.centreline(0, &p, 0, &mut 0).unwrap().centres;
        assert_eq!((centres[0], *centres.last().unwrap()), (p[0], p[3]));
        // Pinned Catmull-Rom interpolates every control point, ends included.
        let c = curve(Basis::CatmullRom, Wrap::Pinned, p.clone(), (vec![0.1], "constant"));
        let centres = c.centreline(0, &p, 0, &mut 0).unwrap().centres;
        for (k, q) in p.iter().enumerate() {
            assert!((centres[k * DEFAULT_CURVE_SAMPLES] - *q).length() < 1e-5, "knot {k}");
        }
    }

    /// A straight ribbon along +X with normals +Z: its corners sit half its width to either
    /// side along ±Y, its normals are +Z, and its area is its length times its width.
    #[test]
    fn a_ribbon_lies_across_its_normal_at_its_width() {
        let p = vec![Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)];
        let mut c = curve(Basis::Bspline, Wrap::Pinned, p, (vec![0.4], "constant"));
        c.normals = Some((vec![Vec3::Z], "constant".into()));
        let mesh = c.tessellate().unwrap();
        assert!(mesh.positions.iter().all(|q| q.z == 0.0 && (q.y.abs() - 0.2).abs() < 1e-6), "{:?}", mesh.positions);
        let Attribute::Vertex(normals) = &mesh.normals else { panic!("vertex normals") };
        assert!(normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
        let area: f32 = mesh
            .indices
            .iter()
            .map(|t| {
                0.5 * (mesh.positions[t[1] as usize] - mesh.positions[t[0] as usize])
                    .cross(mesh.positions[t[2] as usize] - mesh.positions[t[0] as usize])
                    .length()
            })
            .sum();
        // A pinned B-spline runs from its first to its last point: 3 units.
        assert!((area - 3.0 * 0.4).abs() < 1e-4, "area {area}");
        // A normal along the curve itself orients nothing: the ribbon still gets a side.
        c.normals = Some((vec![Vec3::X], "constant".into()));
        assert!(c.tessellate().unwrap().positions.iter().all(|q| q.is_finite()));
    }

    #[test]
    fn span_counts_follow_the_kind_of_curve() {
        let n = |basis, wrap, count| spans(basis, wrap, &vec![0.0f32; count]).map(|(_, s)| s);
        assert_eq!(n(Basis::Linear, Wrap::Nonperiodic, 5), Some(4));
        assert_eq!(n(Basis::Linear, Wrap::Periodic, 5), Some(5));
        assert_eq!(n(Basis::Bezier, Wrap::Nonperiodic, 7), Some(2));
        assert_eq!(n(Basis::Bezier, Wrap::Nonperiodic, 6), None);
        assert_eq!(n(Basis::Bezier, Wrap::Pinned, 5), None);
        assert_eq!(n(Basis::Linear, Wrap::Nonperiodic, 1), None);
        assert_eq!(n(Basis::Bezier, Wrap::Periodic, 6), Some(2));
        assert_eq!(n(Basis::Bspline, Wrap::Nonperiodic, 6), Some(3));
        assert_eq!(n(Basis::Bspline, Wrap::Periodic, 6), Some(6));
        assert_eq!(n(Basis::CatmullRom, Wrap::Pinned, 6), Some(5));
        assert_eq!(n(Basis::Bspline, Wrap::Nonperiodic, 3), None);
    }

    #[test]
    fn a_periodic_curve_closes_its_tube() {
        let ring: Vec<Vec3> = (0..6).map(|k| Vec3::new((k as f32).cos(), (k as f32).sin(), 0.0)).collect();
        let c = curve(Basis::Bspline, Wrap::Periodic, ring, (vec![0.1], "constant"));
        let m = c.tessellate().unwrap();
        // 6 spans of 8 samples, a ring each, every ring joined to the next and the last to the
        // first again (repeated at t = 1), each ring's seam vertex repeated at s = 1.
        let rings = 6 * DEFAULT_CURVE_SAMPLES;
        assert_eq!(m.positions.len(), (rings + 1) * (SIDES + 1));
        assert_eq!(m.indices.len(), rings * SIDES * 2);
        assert_eq!(m.positions[..SIDES + 1], m.positions[rings * (SIDES + 1)..]);
    }

    /// The texture coordinates run s around the tube and t from root to tip, so ∂p/∂t on every
    /// triangle points along the curve, as the hair BSDF's frame needs, seams included.
    #[test]
    fn texture_t_runs_along_the_curve() {
        let p = vec![Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 1.0, 0.5)];
        let m = curve(Basis::CatmullRom, Wrap::Nonperiodic, p, (vec![0.05], "constant")).tessellate().unwrap();
        let Attribute::Vertex(uv) = &m.uvs else { panic!("tube has vertex texture coordinates") };
        for tri in &m.indices {
            let [a, b, c] = tri.map(|i| m.positions[i as usize]);
            let [ta, tb, tc] = tri.map(|i| uv[i as usize]);
            let (d1, d2, e1, e2) = (tb - ta, tc - ta, b - a, c - a);
            let dpdt = (e2 * d1.x - e1 * d2.x) / d1.perp_dot(d2);
            // The centre line's direction here: from the triangle's first ring to the next.
            let along = (m.positions[tri[1] as usize] - m.positions[tri[0] as usize]).normalize();
            assert!(dpdt.normalize().dot(along) > 0.9, "∂p/∂t {dpdt:?} against the curve {along:?}");
        }
    }

    /// Primvars reach every vertex of their curve's tube: a uniform one is its curve's value
    /// on each of its vertices, a vertex one on a linear curve runs linearly from root to tip
    /// (each ring carries its sample's value), and a periodic tube's closing ring repeats
    /// the first ring's.
    #[test]
    fn primvars_follow_their_interpolation_onto_the_tubes() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 0.0), Vec3::new(2.0, 2.0, 0.0)];
        let mut c = curve(Basis::Linear, Wrap::Nonperiodic, p, (vec![0.1], "constant"));
        c.counts = vec![2, 3];
        let roots = vec![Vec3::new(0.25, 0.5, 0.0), Vec3::new(0.75, 0.5, 0.0)];
        let along = vec![Vec3::ZERO, Vec3::ONE, Vec3::ZERO, Vec3::splat(0.5), Vec3::ONE];
        c.primvars = vec![("st".into(), roots.clone(), "uniform".into()), ("heat".into(), along, "vertex".into())];
        let m = c.tessellate().unwrap();
        let ring = SIDES + 1;
        assert_eq!(m.positions.len(), 5 * ring);
        let [st, heat] = [0, 1].map(|k| match &m.primvars[k].values {
            Attribute::Vertex(v) => v.clone(),
            _ => panic!("vertex primvar"),
        });
        assert_eq!((m.primvars[0].name.as_str(), m.primvars[1].name.as_str()), ("st", "heat"));
        assert_eq!(st.len(), m.positions.len());
        assert!(st[..2 * ring].iter().all(|v| *v == roots[0]) && st[2 * ring..].iter().all(|v| *v == roots[1]));
        let ring_heat: Vec<f32> = (0..5).map(|r| heat[r * ring].x).collect();
        assert_eq!(ring_heat, [0.0, 1.0, 0.0, 0.5, 1.0]);
        assert!(heat.chunks(ring).all(|r| r.iter().all(|v| *v == r[0])));

        let loop_points: Vec<Vec3> = (0..4).map(|k| Vec3::new((k as f32).cos(), (k as f32).sin(), 0.0)).collect();
        let mut c = curve(Basis::Linear, Wrap::Periodic, loop_points, (vec![0.1], "constant"));
        c.primvars = vec![("heat".into(), (0..4).map(|k| Vec3::splat(k as f32)).collect(), "vertex".into())];
        let m = c.tessellate().unwrap();
        let Attribute::Vertex(heat) = &m.primvars[0].values else { panic!("vertex primvar") };
        assert_eq!(heat.len(), m.positions.len());
        assert_eq!(heat[..ring], heat[4 * ring..]);
    }

    #[test]
    fn a_curve_asking_for_too_many_rings_is_refused_before_any_is_built() {
        // 3M linear spans: 36M ring vertices, past the limit.
        let c = curve(Basis::Linear, Wrap::Nonperiodic, vec![Vec3::ZERO; 3_000_000], (vec![0.1], "constant"));
        assert!(c.tessellate().unwrap_err().contains("more than"));
    }

    #[test]
    fn the_tube_widens_its_polygon_to_the_mean_width() {
        let c = curve(Basis::Linear, Wrap::Nonperiodic, vec![Vec3::ZERO, Vec3::X], (vec![0.5, 2.0], "vertex"));
        let m = c.tessellate().unwrap();
        let widen = std::f32::consts::PI / (SIDES as f32 * (std::f32::consts::PI / SIDES as f32).sin());
        assert!((m.positions[0].length() - 0.25 * widen).abs() < 1e-6);
        assert!((m.positions[SIDES + 1].distance(Vec3::X) - 1.0 * widen).abs() < 1e-6);
    }
}
