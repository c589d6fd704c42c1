//! Inputs that vary over a surface: the UsdPreviewSurface texture nodes (`UsdUVTexture`,
//! `UsdPrimvarReader_float2`, `UsdTransform2d`) compiled at commit into small expressions and
//! evaluated at each shading point, whose values then go through the same parameter
//! resolution as constant inputs (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.2: parameters first, then closures).

use std::sync::Arc;

use glam::{Mat2, Vec2, Vec3, Vec4};

use super::Material;
use super::desc::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};
use super::inputs::{EVALUATED, Overrides, ResolveReport};
use crate::bsdf::SpecularFresnel;
use crate::bsdf::thin_film::ConductorAverages;
use crate::texture::{ColorSpace, Texture, Wrap, ray_cone_lod, texels_a_side};

/// What a texture lookup needs to know about the point it shades.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint<'a> {
    /// The mesh's texture coordinates here, if it has any.
    pub st: Option<Vec2>,
    /// Where primvar readers read the mesh's other primvars; None reads their fallbacks.
    pub primvars: Option<PrimvarSource<'a>>,
    /// World-space width of the ray's footprint (its cone) at the point.
    pub width: f32,
    /// |cos| between the ray and the surface normal.
    pub cos: f32,
    /// Texture-space length per world-space length on this triangle (√ of the area ratio).
    pub uv_density: f32,
}

impl ShadingPoint<'_> {
    /// A footprint covering the whole texture: lookups return its mean (the coarsest mip);
    /// primvar readers give their fallbacks.
    pub fn whole_texture() -> Self {
        ShadingPoint { st: Some(Vec2::splat(0.5)), primvars: None, width: f32::INFINITY, cos: 1.0, uv_density: 1.0 }
    }
}

/// A point on a mesh, for primvar readers.
#[derive(Clone, Copy, Debug)]
pub struct PrimvarSource<'a> {
    /// The mesh.
    pub mesh: &'a crate::geometry::Mesh,
    /// Triangle index.
    pub triangle: usize,
    /// Barycentrics (b1, b2).
    pub bary: Vec2,
}

/// A compiled node output.
#[derive(Clone, Debug)]
enum Expr {
    Const(Vec4),
    /// A float2 primvar reader: the mesh's primvar of that name where it carries one (curves
    /// send their authored texture coordinates so, keeping their tubes' own as `st` for the
    /// hair frame), else the mesh's texture coordinates, else the reader's fallback.
    St {
        name: Option<String>,
        fallback: Vec2,
    },
    /// A float, float3 or int primvar of the mesh (the client sends those readers name), or
    /// the reader's fallback where the mesh lacks it.
    Primvar {
        name: String,
        fallback: Vec4,
    },
    Texture {
        texture: Arc<Texture>,
        st: Box<Expr>,
        wrap: [Wrap; 2],
        scale: Vec4,
        bias: Vec4,
    },
    Transform2d {
        input: Box<Expr>,
        linear: Mat2,
        translation: Vec2,
    },
    /// The slope of a height along the mesh's s and t (`scale` world units per unit of
    /// height), by central differences `step` apart in st: one texel of the finest texture
    /// the height reads.
    Bump {
        height: Box<Expr>,
        channel: usize,
        scale: f32,
        step: f32,
    },
    /// A UDIM set: the tile under `st` (its texel grid clamped at the tile's edges, so
    /// neighbouring tiles never bleed into each other), or the fallback where no tile is.
    Udim {
        tiles: Box<UdimGrid>,
        st: Box<Expr>,
        scale: Vec4,
        bias: Vec4,
        fallback: Vec4,
    },
}

/// A UDIM set's tiles by unit square of texture space: `[u + 10·v]` for tile
/// `1001 + u + 10·v`.
type UdimGrid = [Option<Arc<Texture>>; 100];

/// The tile of `grid` under `st` and `st` within it.
fn udim_tile(grid: &UdimGrid, st: Vec2) -> Option<(&Texture, Vec2)> {
    let cell = st.floor();
    let inside = (0.0..10.0).contains(&cell.x) && (0.0..10.0).contains(&cell.y);
    let tile = grid.get(cell.x as usize + 10 * cell.y as usize).filter(|_| inside)?.as_deref()?;
    Some((tile, st - cell))
}

impl Expr {
    /// Texels of the finest texture this reads per unit of the mesh's texture coordinates.
    fn texels_per_st(&self) -> f32 {
        let side = |t: &Texture| texels_a_side(t.size());
        match self {
            Expr::Const(_) | Expr::St { .. } | Expr::Primvar { .. } => 0.0,
            Expr::Texture { texture, st, .. } => (side(texture) * st.st_stretch()).max(st.texels_per_st()),
            Expr::Udim { tiles, st, .. } => {
                (tiles.iter().flatten().map(|t| side(t)).fold(0.0, f32::max) * st.st_stretch()).max(st.texels_per_st())
            }
            Expr::Transform2d { input, .. } | Expr::Bump { height: input, .. } => input.texels_per_st(),
        }
    }

    /// How much texture coordinates computed by this are stretched against the mesh's.
    fn st_stretch(&self) -> f32 {
        match self {
            Expr::Transform2d { input, linear, .. } => input.st_stretch() * linear.determinant().abs().sqrt(),
            _ => 1.0,
        }
    }

    /// The value and how much the texture coordinates it carries are stretched relative to
    /// the mesh's (for the footprint of lookups downstream).
    fn eval(&self, sp: &ShadingPoint) -> (Vec4, f32) {
        match self {
            Expr::Const(v) => (*v, 1.0),
            Expr::St { name, fallback } => {
                let named = name.as_ref().zip(sp.primvars).and_then(|(name, p)| p.mesh.primvar(name, p.triangle, p.bary));
                (named.map(|v| v.truncate()).or(sp.st).unwrap_or(*fallback).extend(0.0).extend(0.0), 1.0)
            }
            Expr::Primvar { name, fallback } => {
                let v = sp.primvars.and_then(|p| p.mesh.primvar(name, p.triangle, p.bary));
                (v.map_or(*fallback, |v| v.extend(0.0)), 1.0)
            }
            Expr::Texture { texture, st, wrap, scale, bias } => {
                let (st, stretch) = st.eval(sp);
                let lod = if sp.width.is_infinite() {
                    f32::INFINITY
                } else {
                    ray_cone_lod(sp.width, sp.cos, sp.uv_density * stretch, texture.size())
                };
                (texture.lookup(Vec2::new(st.x, st.y), lod, *wrap) * *scale + *bias, 1.0)
            }
            Expr::Udim { tiles, st, scale, bias, fallback } => {
                let (st, stretch) = st.eval(sp);
                let clamp = [Wrap::Clamp; 2];
                if sp.width.is_infinite() {
                    // The whole set: the mean of its tiles' means (compile checked it has one).
                    let (sum, n) = tiles
                        .iter()
                        .flatten()
                        .fold((Vec4::ZERO, 0.0), |(sum, n), t| (sum + t.lookup(Vec2::splat(0.5), f32::INFINITY, clamp), n + 1.0));
                    return (if n > 0.0 { sum / n * *scale + *bias } else { *fallback }, 1.0);
                }
                match udim_tile(tiles, Vec2::new(st.x, st.y)) {
                    Some((tile, local)) => {
                        let lod = ray_cone_lod(sp.width, sp.cos, sp.uv_density * stretch, tile.size());
                        (tile.lookup(local, lod, clamp) * *scale + *bias, 1.0)
                    }
                    None => (*fallback, 1.0),
                }
            }
            Expr::Transform2d { input, linear, translation } => {
                let (v, stretch) = input.eval(sp);
                let st = *linear * Vec2::new(v.x, v.y) + *translation;
                (st.extend(0.0).extend(0.0), stretch * linear.determinant().abs().sqrt())
            }
            Expr::Bump { height, channel, scale, step } => {
                // Without texture coordinates (or far enough that lookups return the mean) the
                // height has no slope to read.
                let Some(st) = sp.st.filter(|_| sp.width.is_finite()) else { return (Vec4::ZERO, 1.0) };
                let h = |d: Vec2| height.eval(&ShadingPoint { st: Some(st + d), ..*sp }).0[*channel];
                let (ds, dt) = (Vec2::new(*step, 0.0), Vec2::new(0.0, *step));
                let slope = Vec2::new(h(ds) - h(-ds), h(dt) - h(-dt)) * (*scale / (2.0 * *step));
                (slope.extend(0.0).extend(0.0), 1.0)
            }
        }
    }
}

/// Which part of a node's value an output names.
#[derive(Clone, Copy, Debug)]
enum Output {
    Float(usize),
    Float2,
    Float3,
}

impl Output {
    fn of(node: &MaterialNode, output: &str) -> Option<Output> {
        Some(match (node.node_type_id.as_str(), output) {
            ("UsdUVTexture", "r") => Output::Float(0),
            ("UsdUVTexture", "g") => Output::Float(1),
            ("UsdUVTexture", "b") => Output::Float(2),
            ("UsdUVTexture", "a") => Output::Float(3),
            ("UsdUVTexture", "rgb") => Output::Float3,
            ("UsdPrimvarReader_float2" | "UsdTransform2d", "result") => Output::Float2,
            ("UsdPrimvarReader_float" | "UsdPrimvarReader_int", "result") => Output::Float(0),
            ("UsdPrimvarReader_float3", "result") => Output::Float3,
            (BUMP, "out") => Output::Float3,
            _ => return None,
        })
    }

    fn value(self, v: Vec4) -> ParamValue {
        match self {
            Output::Float(k) => ParamValue::Float(v[k]),
            Output::Float2 => ParamValue::Float2(Vec2::new(v.x, v.y)),
            Output::Float3 => ParamValue::Float3(v.truncate()),
        }
    }
}

/// Looks up a texture by content hash in a colour space.
pub type TextureSource<'a> = dyn Fn(&str, ColorSpace) -> Option<Arc<Texture>> + 'a;

/// Inputs whose lobes build a table when the BSDF is built (a thin film's albedo, thousands of
/// samples): varying per shading point they would cost milliseconds a vertex, so a texture on
/// them is read at its mean.
const PER_MATERIAL: &[&str] =
    &["filmThickness", "filmRefractiveIndex", "iridescenceThickness", "iridescenceRefractiveIndex", "iridescenceRoughness"];

/// A material some of whose inputs vary over the surface.
#[derive(Clone, Debug)]
pub struct TexturedMaterial {
    path: String,
    /// The network with a placeholder value on every connected input.
    network: MaterialNetwork,
    /// (node, input) of each varying input, and its expression.
    keys: Vec<(String, String)>,
    exprs: Vec<(Expr, Output)>,
    /// Each varying input's value over the whole texture.
    means: Vec<ParamValue>,
    /// The film averages' grid of each filmed `tessera:Metal` whose colours vary.
    film_averages: Vec<(String, ConductorAverages)>,
    /// Index of the surface node's `normal` input, if varying, and what feeds it.
    normal: Option<(usize, NormalInput)>,
    /// The material of each node no varying input reaches but a varying node reads (a
    /// layer's constant side, a glitter's constant base), resolved once here: per shading
    /// point only the path from the varying inputs to the surface is resolved again.
    fixed: std::collections::HashMap<String, Material>,
}

impl TexturedMaterial {
    /// Compiles the varying inputs of `network`; `None` when it has none. Inputs that cannot
    /// be evaluated are reported and keep their authored values (or their defaults).
    pub fn compile(network: &MaterialNetwork, path: &str, textures: &TextureSource, report: &mut ResolveReport) -> Option<Self> {
        let mut keys = Vec::new();
        let mut exprs = Vec::new();
        let mut compiled = network.clone();
        // A node feeding several inputs compiles once.
        let mut cache = std::collections::HashMap::<String, Expr>::new();
        // A texture read at its mean on a per-material input still makes the material differ
        // from its authored values.
        let mut at_mean = false;
        for c in &network.connections {
            // Displacement moves the mesh at commit, once; shading points never read it.
            if c.downstream_node == network.surface_node && c.downstream_input == DISPLACEMENT {
                continue;
            }
            let Some((expr, output)) = compile_connection(network, c, textures, report, &mut cache) else { continue };
            // A texture node's own inputs are compiled into its expression; only the shaders'
            // inputs are set per shading point.
            if network.nodes.iter().any(|n| n.path == c.downstream_node && EVALUATED.contains(&n.node_type_id.as_str())) {
                continue;
            }
            let placeholder = output.value(expr.eval(&ShadingPoint::whole_texture()).0);
            if let Some(node) = compiled.nodes.iter_mut().find(|n| n.path == c.downstream_node) {
                node.parameters.insert(c.downstream_input.clone(), placeholder);
            }
            if PER_MATERIAL.contains(&c.downstream_input.as_str()) {
                report.warnings.push(format!(
                    "{}: input '{}' is read at its texture's mean: a thin film's tables are built once per material",
                    c.downstream_node, c.downstream_input
                ));
                at_mean = true;
                continue;
            }
            keys.push((c.downstream_node.clone(), c.downstream_input.clone()));
            exprs.push((expr, output));
        }
        if keys.is_empty() && !at_mean {
            return None;
        }
        let surface = network.nodes.iter().find(|n| n.path == network.surface_node);
        let normal = surface.filter(|n| super::native::takes_normal_map(&n.node_type_id)).and_then(|s| {
            let k = keys.iter().position(|(n, i)| *n == s.path && i == "normal")?;
            let c = network.connections.iter().find(|c| c.downstream_node == s.path && c.downstream_input == "normal")?;
            let bump = network.nodes.iter().any(|n| n.path == c.upstream_node && n.node_type_id == BUMP);
            Some((k, if bump { NormalInput::Bump } else { NormalInput::Map }))
        });
        let means = exprs.iter().map(|(e, o)| o.value(e.eval(&ShadingPoint::whole_texture()).0)).collect();
        let fixed = constant_frontier(&compiled, &keys).into_iter().map(|n| (n.clone(), compiled.resolve_subtree(path, &n))).collect();
        let film_averages = metal_film_averages(&compiled, path, &keys);
        Some(TexturedMaterial { path: path.to_string(), network: compiled, keys, exprs, means, film_averages, normal, fixed })
    }

    /// True when a tangent-space normal map perturbs the shading normal.
    pub fn has_normal_map(&self) -> bool {
        matches!(self.normal, Some((_, NormalInput::Map)))
    }

    /// True when a bump height tilts the shading normal.
    pub fn has_bump(&self) -> bool {
        matches!(self.normal, Some((_, NormalInput::Bump)))
    }

    /// True when the emission varies over the surface (lights look it up per point).
    pub fn emission_varies(&self) -> bool {
        self.keys.iter().any(|(_, i)| matches!(i.as_str(), "emissiveColor" | "emission"))
    }

    /// True when opacity varies on a surface with a cut-out threshold or partial presence, so
    /// rays may pass some points and not others.
    pub fn may_see_through(&self) -> bool {
        self.keys.iter().any(|(n, i)| {
            i == "opacity"
                && self.network.nodes.iter().any(|node| {
                    node.path == *n
                        && (matches!(node.parameters.get("opacityThreshold"), Some(ParamValue::Float(t)) if *t > 0.0)
                            || matches!(node.parameters.get("opacityMode"), Some(ParamValue::String(m)) if m == "presence"))
                })
        })
    }

    /// The material as seen from far away: every texture at its mean (its coarsest level).
    /// The render plan, light power and similar whole-surface decisions use it.
    pub fn mean(&self) -> (Material, ResolveReport) {
        self.network.resolve_with(&self.path, Overrides { keys: &self.keys, values: &self.means, film_averages: &self.film_averages }, true)
    }

    /// The material at one shading point, and what tilts its shading normal there if
    /// anything does.
    pub fn at(&self, sp: &ShadingPoint) -> (Material, Option<Tilt>) {
        let values: Vec<ParamValue> = self.exprs.iter().map(|(e, o)| o.value(e.eval(sp).0)).collect();
        let normal = self.normal.and_then(|(i, kind)| match (&values[i], kind) {
            (ParamValue::Float3(n), NormalInput::Map) => Some(Tilt::NormalMap(*n)),
            (ParamValue::Float3(g), NormalInput::Bump) => Some(Tilt::Bump(g.truncate())),
            _ => None,
        });
        let (m, _) = self.network.resolve_using(
            &self.path,
            Overrides { keys: &self.keys, values: &values, film_averages: &self.film_averages },
            false,
            Some(&self.fixed),
        );
        (m, normal)
    }
}

/// A grid of film averages for each `tessera:Metal` under a film whose colours vary (its film
/// is the same everywhere: a textured thickness is read at its mean). The average sizes a
/// rough metal's energy compensation (Kulla & Conty 2017, "Revisiting Physically Based Shading
/// at Imageworks", "Conductors"); integrated at each shading point it cost 16 µs, three times
/// the rest of a ramp-textured filmed metal's render.
fn metal_film_averages(compiled: &MaterialNetwork, path: &str, keys: &[(String, String)]) -> Vec<(String, ConductorAverages)> {
    let varies = |node: &str| keys.iter().any(|(n, i)| n == node && matches!(i.as_str(), "reflectivity" | "edgeTint"));
    let metals = compiled.nodes.iter().filter(|n| n.node_type_id == "tessera:Metal" && varies(&n.path));
    metals
        .filter_map(|n| match compiled.resolve_subtree(path, &n.path).surface.metal.params.fresnel {
            SpecularFresnel::ThinFilmConductor { film, thickness, .. } => Some((n.path.clone(), ConductorAverages::new(film, thickness))),
            _ => None,
        })
        .collect()
}

/// What feeds a surface's varying `normal` input.
#[derive(Clone, Copy, Debug, PartialEq)]
enum NormalInput {
    /// A tangent-space normal map.
    Map,
    /// A [`BUMP`] node.
    Bump,
}

/// What tilts the shading normal at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tilt {
    /// A normal map's tangent-space normal (+Z up; not normalised).
    NormalMap(Vec3),
    /// A bump height's slope: world units of height per unit of the mesh's s and t.
    Bump(Vec2),
}

/// Tessera's bump node. Its `height` (a float output: a texture channel) is read around the
/// shading point, and the shading normal is tilted as if the surface were moved along it by
/// `scale` × height world units (`scale` defaults to 1). Its `out` feeds a surface's `normal`.
pub const BUMP: &str = "tessera:Bump";

/// The surface node's input that moves the mesh rather than shading it.
const DISPLACEMENT: &str = "displacement";

/// A texture network connected to one input, evaluated on its own: the displacement a mesh
/// is moved by at commit.
#[derive(Clone, Debug)]
pub struct VaryingInput {
    expr: Expr,
    output: Output,
}

impl VaryingInput {
    /// The texture network connected to the surface node's `displacement`, if one is. Its
    /// problems are reported as the other inputs' are.
    pub fn displacement(network: &MaterialNetwork, textures: &TextureSource, report: &mut ResolveReport) -> Option<Self> {
        let c = network.connections.iter().find(|c| c.downstream_node == network.surface_node && c.downstream_input == DISPLACEMENT)?;
        let (expr, output) = compile_connection(network, c, textures, report, &mut Default::default())?;
        if !matches!(output, Output::Float(_)) {
            let problem = format!(
                "{}: input 'displacement' reads {}.{}, which is not a float; the mesh is not displaced",
                c.downstream_node, c.upstream_node, c.upstream_output
            );
            report.warnings.push(problem);
            return None;
        }
        Some(VaryingInput { expr, output })
    }

    /// The value at `sp`.
    pub fn at(&self, sp: &ShadingPoint) -> ParamValue {
        self.output.value(self.expr.eval(sp).0)
    }

    /// Texels of the finest texture read, per unit of the mesh's texture coordinates (0 when
    /// no texture is read): how finely the input varies over a surface.
    pub fn texels_per_st(&self) -> f32 {
        self.expr.texels_per_st()
    }
}

/// The expression and output of the texture node `c` reads, or None when `c` reads no texture
/// node (a shader's output) or an output the node lacks (reported). `cache` holds nodes compiled
/// already, as one node may feed several inputs.
fn compile_connection(
    network: &MaterialNetwork,
    c: &MaterialConnection,
    textures: &TextureSource,
    report: &mut ResolveReport,
    cache: &mut std::collections::HashMap<String, Expr>,
) -> Option<(Expr, Output)> {
    let up = network.nodes.iter().find(|n| n.path == c.upstream_node)?;
    if !EVALUATED.contains(&up.node_type_id.as_str()) {
        return None;
    }
    if up.node_type_id == BUMP && c.downstream_input != "normal" {
        report
            .warnings
            .push(format!("{}: a tessera:Bump feeds only a surface's normal, not '{}'; it is ignored", up.path, c.downstream_input));
        return None;
    }
    let Some(output) = Output::of(up, &c.upstream_output) else {
        report.warnings.push(format!(
            "{}: {} has no output '{}'; {} keeps its value",
            up.path, up.node_type_id, c.upstream_output, c.downstream_input
        ));
        return None;
    };
    let expr = match cache.get(&up.path) {
        Some(e) => e.clone(),
        None => {
            let e = compile_node(network, up, textures, report, 0);
            cache.insert(up.path.clone(), e.clone());
            e
        }
    };
    Some((expr, output))
}

/// The material nodes no varying input reaches (directly or through the nodes they read)
/// that a varying node reads: resolving these once covers every constant subtree a shading
/// point's resolution meets. The surface node counts as read.
fn constant_frontier(network: &MaterialNetwork, keys: &[(String, String)]) -> Vec<String> {
    let shader = |path: &str| network.nodes.iter().any(|n| n.path == path && !EVALUATED.contains(&n.node_type_id.as_str()));
    let mut varying: std::collections::HashSet<&str> = keys.iter().map(|(n, _)| n.as_str()).collect();
    // Downstream of a varying node is varying; the set only grows, so this ends (cycles were
    // refused by validation, and would end here too).
    loop {
        let before = varying.len();
        for c in &network.connections {
            if varying.contains(c.upstream_node.as_str()) {
                varying.insert(c.downstream_node.as_str());
            }
        }
        if varying.len() == before {
            break;
        }
    }
    let mut frontier: Vec<String> = network
        .connections
        .iter()
        .filter(|c| varying.contains(c.downstream_node.as_str()) && !varying.contains(c.upstream_node.as_str()) && shader(&c.upstream_node))
        .map(|c| c.upstream_node.clone())
        .collect();
    if !varying.contains(network.surface_node.as_str()) && shader(&network.surface_node) {
        frontier.push(network.surface_node.clone());
    }
    frontier.sort();
    frontier.dedup();
    frontier
}

/// Deepest chain of texture nodes followed (a cycle is cut there).
const MAX_CHAIN: usize = 16;

/// The primvar a reader node's `varname` names, when it names one.
fn varname(node: &MaterialNode) -> Option<String> {
    match node.parameters.get("varname") {
        Some(ParamValue::String(name)) if !name.is_empty() => Some(name.clone()),
        _ => None,
    }
}

/// A float, float3 or int primvar reader: the mesh's primvar its `varname` names, or its
/// fallback where it names none.
fn primvar_reader(node: &MaterialNode, id: &str, report: &mut ResolveReport) -> Expr {
    let fallback = match node.parameters.get("fallback") {
        Some(ParamValue::Float(x)) => Vec4::new(*x, 0.0, 0.0, 0.0),
        Some(ParamValue::Int(i)) => Vec4::new(*i as f32, 0.0, 0.0, 0.0),
        Some(ParamValue::Float3(v)) => v.extend(0.0),
        _ => Vec4::ZERO,
    };
    match varname(node) {
        Some(name) => Expr::Primvar { name, fallback },
        None => {
            report.warnings.push(format!("{}: {id} has no varname; its fallback is used", node.path));
            Expr::Const(fallback)
        }
    }
}

/// A node's float2 parameter (a float3's first two components), else `default`.
fn float2_param(node: &MaterialNode, name: &str, default: Vec2) -> Vec2 {
    match node.parameters.get(name) {
        Some(ParamValue::Float2(v)) => *v,
        Some(ParamValue::Float3(v)) => v.truncate(),
        _ => default,
    }
}

/// A node's float4 parameter (a float3 with `default`'s w, a float splatted), else `default`.
fn float4_param(node: &MaterialNode, name: &str, default: Vec4) -> Vec4 {
    match node.parameters.get(name) {
        Some(ParamValue::Float4(v)) => *v,
        Some(ParamValue::Float3(v)) => v.extend(default.w),
        Some(ParamValue::Float(x)) => Vec4::splat(*x),
        _ => default,
    }
}

/// A float2 input as a constant expression: its authored value, else zero.
fn const_float2(node: &MaterialNode, name: &str) -> Expr {
    Expr::Const(float2_param(node, name, Vec2::ZERO).extend(0.0).extend(0.0))
}

fn compile_node(net: &MaterialNetwork, node: &MaterialNode, textures: &TextureSource, report: &mut ResolveReport, depth: usize) -> Expr {
    // An input fed by another evaluated node, else its authored value.
    let upstream = |input: &str, report: &mut ResolveReport| -> Option<Expr> {
        let c = net.connections.iter().find(|c| c.downstream_node == node.path && c.downstream_input == input)?;
        let up = net.nodes.iter().find(|n| n.path == c.upstream_node && EVALUATED.contains(&n.node_type_id.as_str()));
        match up {
            Some(up) if depth < MAX_CHAIN => Some(compile_node(net, up, textures, report, depth + 1)),
            _ => {
                report
                    .warnings
                    .push(format!("{}: input '{input}' is connected to {}, which cannot be evaluated", node.path, c.upstream_node));
                None
            }
        }
    };
    match node.node_type_id.as_str() {
        // Each bump reads its height four times: one inside another's height would multiply
        // the lookups a shading point makes by four a level.
        BUMP if depth > 0 => {
            report.warnings.push(format!("{}: a tessera:Bump feeds only a surface's normal, not another node; it is ignored", node.path));
            Expr::Const(Vec4::ZERO)
        }
        BUMP => bump(net, node, upstream("height", report), report),
        "UsdPrimvarReader_float2" => {
            // The client sends the float2 primvar the readers name as the mesh's st, or (on
            // curves) as a primvar of that name.
            Expr::St { name: varname(node), fallback: float2_param(node, "fallback", Vec2::ZERO) }
        }
        id @ ("UsdPrimvarReader_float" | "UsdPrimvarReader_float3" | "UsdPrimvarReader_int") => primvar_reader(node, id, report),
        "UsdTransform2d" => transform2d(node, upstream("in", report).unwrap_or_else(|| const_float2(node, "in"))),
        _ => {
            let st = upstream("st", report).unwrap_or_else(|| const_float2(node, "st"));
            uv_texture(node, st, textures, report)
        }
    }
}

/// A `UsdTransform2d` over its compiled `input`: result = in · scale · rotate + translation
/// (rotation in degrees, counter-clockwise).
fn transform2d(node: &MaterialNode, input: Expr) -> Expr {
    let rotation = match node.parameters.get("rotation") {
        Some(ParamValue::Float(r)) => r.to_radians(),
        _ => 0.0,
    };
    let linear = Mat2::from_angle(rotation) * Mat2::from_diagonal(float2_param(node, "scale", Vec2::ONE));
    Expr::Transform2d { input: Box::new(input), linear, translation: float2_param(node, "translation", Vec2::ZERO) }
}

/// A `UsdUVTexture` (a single file or a UDIM set) read at its compiled `st`; its fallback where
/// the file is not on the server, each case reported.
fn uv_texture(node: &MaterialNode, st: Expr, textures: &TextureSource, report: &mut ResolveReport) -> Expr {
    let p = |name: &str| node.parameters.get(name);
    let fallback = float4_param(node, "fallback", Vec4::new(0.0, 0.0, 0.0, 1.0));
    let (scale, bias) = (float4_param(node, "scale", Vec4::ONE), float4_param(node, "bias", Vec4::ZERO));
    let wrap = |name: &str, report: &mut ResolveReport| match p(name) {
        Some(ParamValue::String(t)) => Wrap::from_token(t).unwrap_or_else(|| {
            report.warnings.push(format!("{}: {name} '{t}' is not a wrap mode; using repeat", node.path));
            Wrap::Repeat
        }),
        _ => Wrap::Repeat,
    };
    let wrap = [wrap("wrapS", report), wrap("wrapT", report)];
    let space = match p("sourceColorSpace") {
        Some(ParamValue::String(t)) => ColorSpace::from_token(t).unwrap_or_else(|| {
            report.warnings.push(format!("{}: sourceColorSpace '{t}' is unknown; using auto", node.path));
            ColorSpace::Auto
        }),
        _ => ColorSpace::Auto,
    };
    if let Some(ParamValue::Udim { tiles, source }) = p("file") {
        let grid = udim_grid(tiles, space, textures);
        if grid.iter().all(Option::is_none) {
            report.warnings.push(format!("{}: no tile of UDIM texture '{source}' is on the server; using the fallback", node.path));
            return Expr::Const(fallback);
        }
        return Expr::Udim { tiles: grid, st: Box::new(st), scale, bias, fallback };
    }
    let texture = match p("file") {
        Some(ParamValue::Texture { hash, source }) => {
            let t = textures(hash, space);
            if t.is_none() {
                report.warnings.push(format!("{}: texture '{source}' is not on the server; using the fallback", node.path));
            }
            t
        }
        Some(ParamValue::Asset(a)) => {
            report.warnings.push(format!("{}: texture '{a}' could not be read by the client; using the fallback", node.path));
            None
        }
        _ => {
            report.warnings.push(format!("{}: no file; using the fallback", node.path));
            None
        }
    };
    match texture {
        Some(texture) => Expr::Texture { texture, st: Box::new(st), wrap, scale, bias },
        None => Expr::Const(fallback),
    }
}

/// A [`BUMP`] node over its compiled `height`. A height that is not a float, or a scale that
/// is not finite, is reported and the surface stays unbumped.
fn bump(net: &MaterialNetwork, node: &MaterialNode, height: Option<Expr>, report: &mut ResolveReport) -> Expr {
    let scale = match node.parameters.get("scale") {
        Some(ParamValue::Float(s)) => *s,
        _ => 1.0,
    };
    let c = net.connections.iter().find(|c| c.downstream_node == node.path && c.downstream_input == "height");
    let output = c.and_then(|c| net.nodes.iter().find(|n| n.path == c.upstream_node).and_then(|up| Output::of(up, &c.upstream_output)));
    let flat = Expr::Const(Vec4::ZERO);
    match (height, output) {
        (None, _) => flat,
        (Some(_), _) if !scale.is_finite() => {
            report.warnings.push(format!("{}: scale {scale} is not finite; the surface is not bumped", node.path));
            flat
        }
        (Some(height), Some(Output::Float(channel))) => {
            let texels = height.texels_per_st();
            // One texel (the geometric mean of a non-square texture's two); without a texture
            // the height is smooth at any scale: a thousandth of st.
            let step = if texels > 0.0 { 1.0 / texels } else { 1e-3 };
            Expr::Bump { height: Box::new(height), channel, scale, step }
        }
        (Some(_), _) => {
            report.warnings.push(format!("{}: input 'height' does not read a float output; the surface is not bumped", node.path));
            flat
        }
    }
}

/// The tiles of a UDIM set looked up by hash in `space`, placed by tile number.
fn udim_grid(tiles: &[(u16, String)], space: ColorSpace, textures: &TextureSource) -> Box<UdimGrid> {
    let mut grid: Box<UdimGrid> = Box::new(std::array::from_fn(|_| None));
    for (tile, hash) in tiles {
        if let Some(slot) = tile.checked_sub(*super::desc::UDIM_TILES.start()).and_then(|i| grid.get_mut(i as usize)) {
            *slot = textures(hash, space);
        }
    }
    grid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::MaterialConnection;
    use crate::material::network::tests::node;
    use crate::texture::Image;

    fn connect(down: &str, input: &str, up: &str, output: &str) -> MaterialConnection {
        MaterialConnection {
            downstream_node: down.into(),
            downstream_input: input.into(),
            upstream_node: up.into(),
            upstream_output: output.into(),
        }
    }

    /// A UsdPreviewSurface whose diffuseColor reads a 2 × 1 texture (red | blue) through a
    /// primvar reader and a transform.
    fn textured(transform: &[(&str, ParamValue)]) -> MaterialNetwork {
        let tex = ParamValue::Texture { hash: "sha256:x".into(), source: "rb.png".into() };
        MaterialNetwork {
            nodes: vec![
                node("/M/S", "UsdPreviewSurface", &[("roughness", ParamValue::Float(1.0))]),
                node("/M/T", "UsdUVTexture", &[("file", tex), ("sourceColorSpace", ParamValue::String("raw".into()))]),
                node("/M/X", "UsdTransform2d", transform),
                node("/M/P", "UsdPrimvarReader_float2", &[("varname", ParamValue::String("st".into()))]),
            ],
            connections: vec![
                connect("/M/S", "diffuseColor", "/M/T", "rgb"),
                connect("/M/T", "st", "/M/X", "result"),
                connect("/M/X", "in", "/M/P", "result"),
            ],
            surface_node: "/M/S".into(),
        }
    }

    fn source() -> impl Fn(&str, ColorSpace) -> Option<Arc<Texture>> {
        let t = Arc::new(Texture::new(&Image::from_f32(2, 1, 3, &[1., 0., 0., 0., 0., 1.]), ColorSpace::Raw));
        move |h: &str, _| (h == "sha256:x").then(|| t.clone())
    }

    fn diffuse_at(m: &TexturedMaterial, st: Vec2) -> Vec3 {
        let sp = ShadingPoint { st: Some(st), primvars: None, width: 0.0, cos: 1.0, uv_density: 1.0 };
        m.at(&sp).0.surface.plastic.params.diffuse
    }

    /// The textured plastic of [`textured`] under `depth` `tessera:Layer`s (mask 0.3), each
    /// with a constant metal of its own roughness as its other side.
    fn layer_stack(depth: usize) -> MaterialNetwork {
        let mut net = textured(&[]);
        let mut below = "/M/S".to_string();
        for k in 0..depth {
            let (layer, metal) = (format!("/M/L{k}"), format!("/M/Metal{k}"));
            net.nodes.push(node(&layer, "tessera:Layer", &[("mask", ParamValue::Float(0.3))]));
            net.nodes.push(node(&metal, "tessera:Metal", &[("roughness", ParamValue::Float(0.05 * k as f32))]));
            net.connections.push(connect(&layer, "a", &metal, "surface"));
            net.connections.push(connect(&layer, "b", &below, "surface"));
            below = layer;
        }
        net.surface_node = below;
        net
    }

    /// A textured plastic under eight `tessera:Layer`s, each with a constant metal as its
    /// other side: the constant sides are resolved once at compile time (the frontier), and
    /// the per-point material is what resolving the whole network at that point gives.
    #[test]
    fn constant_subtrees_resolve_once_and_change_nothing() {
        let m = TexturedMaterial::compile(&layer_stack(8), "/M", &source(), &mut ResolveReport::default()).expect("varying");
        let frontier: Vec<&str> = m.fixed.keys().map(String::as_str).collect();
        assert_eq!(m.fixed.len(), 8, "the eight constant metals, nothing on the varying path: {frontier:?}");
        for st in [Vec2::new(0.25, 0.5), Vec2::new(0.75, 0.5)] {
            let sp = ShadingPoint { st: Some(st), primvars: None, width: 0.0, cos: 1.0, uv_density: 1.0 };
            let values: Vec<ParamValue> = m.exprs.iter().map(|(e, o)| o.value(e.eval(&sp).0)).collect();
            let (whole, _) =
                m.network.resolve_with("/M", Overrides { keys: &m.keys, values: &values, film_averages: &m.film_averages }, false);
            assert_eq!(m.at(&sp).0, whole, "at {st}");
        }
    }

    /// What resolving the constant sides once saves per shading point, on sixteen layers
    /// (prints; run with `--ignored --nocapture` in release).
    #[test]
    #[ignore]
    fn measure_per_point_resolution_of_a_deep_layer_stack() {
        let mut m = TexturedMaterial::compile(&layer_stack(16), "/M", &source(), &mut ResolveReport::default()).expect("varying");
        let sp = ShadingPoint { st: Some(Vec2::new(0.25, 0.5)), primvars: None, width: 0.0, cos: 1.0, uv_density: 1.0 };
        let n = 20_000;
        let time = |m: &TexturedMaterial| {
            let t = std::time::Instant::now();
            (0..n).for_each(|_| {
                std::hint::black_box(m.at(&sp));
            });
            t.elapsed().as_secs_f64() / n as f64 * 1e6
        };
        let with = time(&m);
        m.fixed.clear();
        let without = time(&m);
        println!(
            "16 layers: {with:.2} µs per shading point with the constant sides resolved once, {without:.2} µs without ({:.2}x)",
            without / with
        );
    }

    #[test]
    fn a_texture_drives_the_diffuse_colour_per_point_and_its_mean_far_away() {
        let mut report = ResolveReport::default();
        let m = TexturedMaterial::compile(&textured(&[]), "/M", &source(), &mut report).expect("varying");
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_eq!(diffuse_at(&m, Vec2::new(0.25, 0.5)), Vec3::X);
        assert_eq!(diffuse_at(&m, Vec2::new(0.75, 0.5)), Vec3::Z);
        let (mean, r) = m.mean();
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert!((mean.surface.plastic.params.diffuse - Vec3::new(0.5, 0.0, 0.5)).abs().max_element() < 1e-3);
    }

    /// A texture on a thin film's thickness is read at its mean, said once: the film's albedo
    /// table is built with the BSDF, milliseconds a shading point if it varied. The material
    /// still takes the mean when nothing else of it varies.
    #[test]
    fn a_textured_film_is_read_at_its_mean() {
        let mut net = textured(&[]);
        net.nodes[0] = node("/M/S", "tessera:SolidDielectric", &[]);
        net.nodes[1].parameters.insert("scale".into(), ParamValue::Float4(Vec4::splat(800.0)));
        net.connections[0] = connect("/M/S", "filmThickness", "/M/T", "r");
        let mut report = ResolveReport::default();
        let m = TexturedMaterial::compile(&net, "/M", &source(), &mut report).expect("the mean differs from the authored values");
        assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
        assert!(report.warnings[0].starts_with("/M/S: input 'filmThickness' is read at its texture's mean"), "{:?}", report.warnings);
        let film = |mat: &Material| match mat.surface.plastic.params.specular.map(|s| s.fresnel) {
            Some(crate::bsdf::SpecularFresnel::ThinFilm { thickness, .. }) => thickness,
            other => panic!("{other:?}"),
        };
        // The red channel is 1 and 0 on the two texels: 400 nm on average.
        assert_eq!(film(&m.mean().0), 400.0);
        for s in [0.25, 0.75] {
            let sp = ShadingPoint { st: Some(Vec2::new(s, 0.5)), primvars: None, width: 0.0, cos: 1.0, uv_density: 1.0 };
            assert_eq!(film(&m.at(&sp).0), 400.0, "at s = {s}");
        }
    }

    /// A filmed metal whose colours vary reads its film's average from the material's grid at
    /// each point (within the grid's 0.01 of the integrated one), with the point's own metal
    /// under the film; the material keeps no average of its mean colours.
    #[test]
    fn a_filmed_metal_with_textured_colours_reads_its_average_per_point() {
        use crate::bsdf::thin_film::Conductor;
        let mut net = textured(&[]);
        let film = [("filmThickness", ParamValue::Float(350.0)), ("edgeTint", ParamValue::Float3(Vec3::splat(0.6)))];
        net.nodes[0] = node("/M/S", "tessera:Metal", &film);
        net.connections[0] = connect("/M/S", "reflectivity", "/M/T", "rgb");
        let mut report = ResolveReport::default();
        let m = TexturedMaterial::compile(&net, "/M", &source(), &mut report).expect("varying");
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_eq!(m.film_averages.len(), 1);
        for (s, r) in [(0.25, Vec3::X), (0.5, Vec3::new(0.5, 0.0, 0.5)), (0.75, Vec3::Z)] {
            let sp = ShadingPoint { st: Some(Vec2::new(s, 0.5)), primvars: None, width: 0.0, cos: 1.0, uv_density: 1.0 };
            let SpecularFresnel::ThinFilmConductor { metal, avg, .. } = m.at(&sp).0.surface.metal.params.fresnel else { panic!("no film") };
            let point = Conductor::gulbrandsen(r, Vec3::splat(0.6));
            assert_eq!(metal, point, "at s = {s}");
            assert_eq!(avg, m.film_averages[0].1.at(r, Vec3::splat(0.6)), "at s = {s}: not the grid's");
            let SpecularFresnel::ThinFilmConductor { avg: exact, .. } = SpecularFresnel::thin_film_conductor(1.33, 350.0, point) else {
                panic!()
            };
            assert!((avg - exact).abs().max_element() < 0.01, "at s = {s}: {avg} against {exact}");
        }
    }

    #[test]
    fn transform2d_scales_rotates_then_translates() {
        let m = TexturedMaterial::compile(
            &textured(&[("translation", ParamValue::Float2(Vec2::new(0.5, 0.0)))]),
            "/M",
            &source(),
            &mut ResolveReport::default(),
        )
        .unwrap();
        assert_eq!(diffuse_at(&m, Vec2::new(0.25, 0.5)), Vec3::Z, "translated onto the blue half");
        let m = TexturedMaterial::compile(
            &textured(&[("scale", ParamValue::Float2(Vec2::new(-1.0, 1.0))), ("translation", ParamValue::Float2(Vec2::new(1.0, 0.0)))]),
            "/M",
            &source(),
            &mut ResolveReport::default(),
        )
        .unwrap();
        assert_eq!(diffuse_at(&m, Vec2::new(0.25, 0.5)), Vec3::Z, "mirrored");
        // 90° counter-clockwise: (s, t) → (−t, s); with translation (1, 0), (0.6, 0.25) → (0.75, 0.6).
        let m = TexturedMaterial::compile(
            &textured(&[("rotation", ParamValue::Float(90.0)), ("translation", ParamValue::Float2(Vec2::new(1.0, 0.0)))]),
            "/M",
            &source(),
            &mut ResolveReport::default(),
        )
        .unwrap();
        assert_eq!(diffuse_at(&m, Vec2::new(0.6, 0.25)), Vec3::Z);
        assert_eq!(diffuse_at(&m, Vec2::new(0.6, 0.75)), Vec3::X, "(0.6, 0.75) → (0.25, 0.6)");
    }

    #[test]
    fn a_missing_texture_is_reported_and_the_fallback_used() {
        let mut net = textured(&[]);
        net.nodes[1].parameters.insert("fallback".into(), ParamValue::Float4(Vec4::new(0.0, 1.0, 0.0, 1.0)));
        let mut report = ResolveReport::default();
        let m = TexturedMaterial::compile(&net, "/M", &|_: &str, _| None, &mut report).unwrap();
        assert!(report.warnings.iter().any(|w| w.contains("/M/T") && w.contains("rb.png")), "{:?}", report.warnings);
        assert_eq!(diffuse_at(&m, Vec2::new(0.25, 0.5)), Vec3::Y);
    }

    /// A surface whose `normal` reads a [`BUMP`] over the red channel of a 4 × 4 raw ramp along
    /// s (texel centres 0, 1/3, 2/3, 1 at s = 1/8, 3/8, 5/8, 7/8), `scale` 0.5.
    fn bumped(scale: ParamValue, output: &str) -> (Option<TexturedMaterial>, ResolveReport) {
        compile_ramp(&bump_network(scale, output))
    }

    fn bump_network(scale: ParamValue, output: &str) -> MaterialNetwork {
        let tex = ParamValue::Texture { hash: "sha256:ramp".into(), source: "ramp.png".into() };
        MaterialNetwork {
            nodes: vec![
                node("/M/S", "UsdPreviewSurface", &[]),
                node("/M/B", BUMP, &[("scale", scale)]),
                node("/M/T", "UsdUVTexture", &[("file", tex), ("sourceColorSpace", ParamValue::String("raw".into()))]),
                node("/M/P", "UsdPrimvarReader_float2", &[("varname", ParamValue::String("st".into()))]),
            ],
            connections: vec![
                connect("/M/S", "normal", "/M/B", "out"),
                connect("/M/B", "height", "/M/T", output),
                connect("/M/T", "st", "/M/P", "result"),
            ],
            surface_node: "/M/S".into(),
        }
    }

    fn compile_ramp(net: &MaterialNetwork) -> (Option<TexturedMaterial>, ResolveReport) {
        let ramp: Vec<f32> = (0..16).flat_map(|i| [(i % 4) as f32 / 3.0, 0.0, 0.0]).collect();
        let t = Arc::new(Texture::new(&Image::from_f32(4, 4, 3, &ramp), ColorSpace::Raw));
        let mut report = ResolveReport::default();
        let m = TexturedMaterial::compile(net, "/M", &move |h: &str, _| (h == "sha256:ramp").then(|| t.clone()), &mut report);
        (m, report)
    }

    /// Between texel centres the ramp rises 1/3 a quarter of s: a slope of 4/3 along s, 0
    /// along t (every row is the same), times `scale`.
    #[test]
    fn a_bump_node_reads_its_heights_slope_along_s_and_t() {
        let (m, report) = bumped(ParamValue::Float(0.5), "r");
        let m = m.expect("varying");
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert!(m.has_bump() && !m.has_normal_map());
        let sp = |s: f32, width: f32| ShadingPoint { st: Some(Vec2::new(s, 0.5)), primvars: None, width, cos: 1.0, uv_density: 1.0 };
        for s in [0.375, 0.5, 0.625] {
            match m.at(&sp(s, 0.0)).1 {
                // 1e-3: the texels are kept as half floats (1/3 is 0.33325).
                Some(Tilt::Bump(slope)) => assert!((slope - Vec2::new(0.5 * 4.0 / 3.0, 0.0)).abs().max_element() < 1e-3, "{s}: {slope}"),
                other => panic!("{other:?}"),
            }
        }
        // Seen from afar (the whole texture in the footprint) the surface has no slope.
        assert_eq!(m.at(&sp(0.5, f32::INFINITY)).1, Some(Tilt::Bump(Vec2::ZERO)));
        assert_eq!(m.at(&ShadingPoint { st: None, ..sp(0.5, 0.0) }).1, Some(Tilt::Bump(Vec2::ZERO)), "no st, no slope");
    }

    #[test]
    fn a_bump_over_a_colour_or_with_a_bad_scale_is_reported_and_flat() {
        for (scale, output, says) in
            [(ParamValue::Float(1.0), "rgb", "does not read a float"), (ParamValue::Float(f32::INFINITY), "r", "is not finite")]
        {
            let (m, report) = bumped(scale, output);
            assert!(report.warnings.iter().any(|w| w.contains("/M/B") && w.contains(says)), "{:?}", report.warnings);
            let sp = ShadingPoint { st: Some(Vec2::new(0.5, 0.5)), primvars: None, width: 0.0, cos: 1.0, uv_density: 1.0 };
            assert_eq!(m.expect("still varying").at(&sp).1, Some(Tilt::Bump(Vec2::ZERO)));
        }
    }

    /// Hostile input: bumps chained through texture coordinates (each bump's height a texture
    /// whose `st` is the next bump) would cost 4ⁿ lookups a point; a bump below the first is
    /// reported and reads nothing.
    #[test]
    fn a_bump_inside_a_bumps_height_is_refused() {
        let tex = ParamValue::Texture { hash: "sha256:x".into(), source: "rb.png".into() };
        let mut net =
            MaterialNetwork { nodes: vec![node("/M/S", "UsdPreviewSurface", &[])], connections: vec![], surface_node: "/M/S".into() };
        let mut below = ("/M/S".to_string(), "normal");
        for k in 0..8 {
            let (b, t) = (format!("/M/B{k}"), format!("/M/T{k}"));
            net.nodes.push(node(&b, BUMP, &[]));
            net.nodes.push(node(&t, "UsdUVTexture", &[("file", tex.clone())]));
            net.connections.push(connect(&below.0, below.1, &b, "out"));
            net.connections.push(connect(&b, "height", &t, "r"));
            below = (t, "st");
        }
        let mut report = ResolveReport::default();
        let m = TexturedMaterial::compile(&net, "/M", &source(), &mut report).expect("varying");
        assert!(
            report.warnings.iter().any(|w| w.contains("/M/B1") && w.contains("feeds only a surface's normal")),
            "{:?}",
            report.warnings
        );
        let Some((Expr::Bump { height, .. }, _)) = m.exprs.first() else { panic!("{:?}", m.exprs) };
        let Expr::Texture { st, .. } = height.as_ref() else { panic!("{height:?}") };
        assert!(matches!(st.as_ref(), Expr::Const(_)), "the second bump reads nothing: {st:?}");
    }

    /// Nor may a bump feed anything but a normal (a colour here): reported, and the input
    /// keeps its value.
    #[test]
    fn a_bump_feeding_a_colour_is_refused() {
        let mut net = bump_network(ParamValue::Float(1.0), "r");
        net.connections[0].downstream_input = "diffuseColor".into();
        let (m, report) = compile_ramp(&net);
        assert!(report.warnings.iter().any(|w| w.contains("/M/B") && w.contains("not 'diffuseColor'")), "{:?}", report.warnings);
        assert!(m.is_none(), "nothing else varies");
    }

    #[test]
    fn constant_networks_do_not_compile() {
        let net = MaterialNetwork { nodes: vec![node("/M/S", "UsdPreviewSurface", &[])], connections: vec![], surface_node: "/M/S".into() };
        assert!(TexturedMaterial::compile(&net, "/M", &source(), &mut ResolveReport::default()).is_none());
    }
}
