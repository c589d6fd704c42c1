//! MaterialX networks in their UsdShade form (`outputs:mtlx:surface`, shader ids `ND_…`), as
//! Blender, Houdini and the USD-WG assets write them, rewritten onto the shaders the renderer
//! knows. The surface node — Autodesk Standard Surface, OpenPBR Surface or MaterialX's
//! UsdPreviewSurface — becomes a `UsdPreviewSurface` when that expresses it (diffuse,
//! metal, dielectric specular, coat, emission, opacity, normal map), else Tessera's own
//! `tessera:SolidDielectric` or `tessera:Metal` (an opaque dielectric or full metal with a rough
//! diffuse, a sheen/fuzz, a tinted specular, a thin film or anisotropy), a
//! `tessera:Principled` (transmission, thin walls, a specular weight), or a
//! `tessera:SolidDielectric` with a scattering medium (subsurface, without those); a
//! plain `surface` over `chiang_hair_bsdf` becomes `tessera:Hair` ([`super::materialx_hair`]).
//!
//! Inputs are followed upstream and folded into `scale · texture + bias`: constants, images
//! (`UsdUVTexture`), texture coordinates and primvars, multiply/add/subtract/mix with at most one
//! texture among the operands, `divide` by a constant, `invert` and `remap` with constant
//! bounds, sRGB decoding, `dot` and `convert` pass-throughs, one channel (`extract`,
//! `separate`), `place2d` (as a `UsdTransform2d`), `normalmap`, and `bump` (through a
//! `tessera:Bump`). Anything else is reported by node path and id, and the input keeps its
//! default.
//! The parameter table is in `docs/materials.md` ("MaterialX").

use std::collections::BTreeMap;

use glam::{Vec2, Vec3, Vec4};
use render_core::material::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};

/// The surface shaders this module maps.
const STANDARD_SURFACE: &str = "ND_standard_surface_surfaceshader";
const OPEN_PBR: &str = "ND_open_pbr_surface_surfaceshader";
const PREVIEW: &str = "ND_UsdPreviewSurface_surfaceshader";
/// The plain `surface` node over a BSDF: hair (`chiang_hair_bsdf`).
const SURFACE: &str = "ND_surface";

/// Longest upstream chain followed from one input (deeper is a cycle or a generated graph).
const MAX_DEPTH: usize = 64;

/// MaterialX's scalar displacement shader: the surface moves by `displacement · scale` along
/// its normal.
pub const DISPLACEMENT: &str = "ND_displacement_float";

/// The connection that hands a displacement shader to the surface it displaces: the mapping
/// reads it as the surface's `displacement` input.
pub fn displaced_by(surface: &str, shader: &str) -> MaterialConnection {
    MaterialConnection {
        downstream_node: surface.to_string(),
        downstream_input: "displacement".into(),
        upstream_node: shader.to_string(),
        upstream_output: "out".into(),
    }
}

/// Whether the network's surface is a MaterialX node (and so needs [`translate`]).
pub fn is_materialx(net: &MaterialNetwork) -> bool {
    net.nodes.iter().any(|n| n.path == net.surface_node && n.node_type_id.starts_with("ND_"))
}

/// Rewrites a MaterialX network in place. `Err` names a surface shader no mapping exists for
/// (the caller falls back to the gprim's displayColor). Unsupported nodes upstream are
/// warnings naming each node once.
pub fn translate(net: &mut MaterialNetwork, warnings: &mut Vec<String>) -> Result<(), String> {
    let surface = net.nodes.iter().find(|n| n.path == net.surface_node).cloned().ok_or("no surface node")?;
    let graph = Graph {
        net,
        warned: std::cell::RefCell::new(Vec::new()),
        bumped: std::cell::Cell::new(false),
        read: std::cell::RefCell::new(Vec::new()),
    };
    let mut inputs = match surface.node_type_id.as_str() {
        STANDARD_SURFACE => standard_surface(&graph, &surface.path),
        OPEN_PBR => open_pbr(&graph, &surface.path),
        PREVIEW => preview(&graph, &surface.path),
        SURFACE => {
            let values = super::materialx_hair::hair_inputs(net, &surface.path, warnings)?;
            let color = |name: &str| name == "absorptionCoefficient" || name.starts_with("tint");
            Inputs { id: "tessera:Hair", values: values.into_iter().map(|(name, v)| (name, Lin::constant(v), color(name))).collect() }
        }
        other => {
            return Err(format!(
                "{}: MaterialX surface '{other}' is not supported (standard_surface, open_pbr_surface, UsdPreviewSurface and surface over chiang_hair_bsdf are)",
                surface.path
            ));
        }
    };
    if let Some(amount) = graph.displacement(&surface.path) {
        match inputs.id {
            "UsdPreviewSurface" => inputs.values.push(("displacement", amount, false)),
            id => warnings
                .push(format!("{}: its displacement has no place on the {id} it maps to; the surface is not displaced", surface.path)),
        }
    }
    // A bump's height goes through a tessera:Bump; a constant one has no slope to bump with.
    if graph.bumped.get()
        && let Some(k) = inputs.values.iter().position(|(name, ..)| *name == "normal")
    {
        match inputs.values[k].1.texture {
            Some(_) => (inputs.values[k].0, inputs.values[k].2) = (BUMP_HEIGHT, false),
            None => drop(inputs.values.remove(k)),
        }
    }
    warnings.extend(graph.warned.take());
    if surface.node_type_id != SURFACE {
        for name in graph.unread(&surface.path) {
            warnings.push(format!("{}: input '{name}' is not carried (Tessera's shaders have no place for it)", surface.path));
        }
    }
    *net = emit(&surface.path, inputs, net, warnings);
    Ok(())
}

/// A value as the network computes it: `scale · texture + bias`, per component (floats in x).
#[derive(Clone, Debug, PartialEq)]
struct Lin {
    texture: Option<Texture>,
    scale: Vec4,
    bias: Vec4,
}

/// An image node read through, whether its texels are sRGB-encoded, and the one channel read
/// (an `extract` or `separate`), if one is.
#[derive(Clone, Debug, PartialEq)]
struct Texture {
    node: String,
    srgb: bool,
    channel: Option<usize>,
}

impl Lin {
    fn constant(v: Vec4) -> Self {
        Lin { texture: None, scale: Vec4::ONE, bias: v }
    }
    fn value(&self) -> Option<Vec4> {
        self.texture.is_none().then_some(self.bias)
    }
    /// Channel `k` alone, as a float; None for a channel of a texture's channel other than
    /// its first (the float itself).
    fn channel(self, k: usize) -> Option<Lin> {
        let pick = |v: Vec4| Vec4::splat(v[k]);
        match &self.texture {
            None => Some(Lin::constant(pick(self.bias))),
            Some(t) if t.channel.is_none() => {
                Some(Lin { texture: Some(Texture { channel: Some(k), ..t.clone() }), scale: pick(self.scale), bias: pick(self.bias) })
            }
            Some(_) => (k == 0).then_some(self),
        }
    }
    fn times(self, k: Vec4) -> Self {
        Lin { scale: self.scale * k, bias: self.bias * k, ..self }
    }
    fn mul(a: Lin, b: Lin) -> Option<Lin> {
        match (a.value(), b.value()) {
            (_, Some(k)) => Some(a.times(k)),
            (Some(k), None) => Some(b.times(k)),
            (None, None) => None,
        }
    }
    fn add(a: Lin, b: Lin) -> Option<Lin> {
        match (&a.texture, &b.texture) {
            // One image read twice (a base and a subsurface colour from one map) stays one.
            (Some(x), Some(y)) if x == y => Some(Lin { scale: a.scale + b.scale, bias: a.bias + b.bias, ..a }),
            (Some(_), Some(_)) => None,
            (_, None) => Some(Lin { bias: a.bias + b.bias, ..a }),
            (None, _) => Some(Lin { bias: a.bias + b.bias, ..b }),
        }
    }
}

/// The MaterialX inputs a surface input is computed from.
struct Graph<'n> {
    net: &'n MaterialNetwork,
    warned: std::cell::RefCell<Vec<String>>,
    /// Whether the surface's normal came from a `bump` node.
    bumped: std::cell::Cell<bool>,
    /// The surface inputs its mapping read: the authored rest are reported.
    read: std::cell::RefCell<Vec<String>>,
}

impl Graph<'_> {
    fn node(&self, path: &str) -> Option<&MaterialNode> {
        self.net.nodes.iter().find(|n| n.path == path)
    }

    /// `node.input`: its connection followed, else its authored value, else `default`.
    fn input(&self, node: &str, input: &str, default: Vec4, depth: usize) -> Option<Lin> {
        if let Some(c) = self.net.connections.iter().find(|c| c.downstream_node == node && c.downstream_input == input) {
            return self.output(&c.upstream_node, &c.upstream_output, depth + 1);
        }
        Some(match self.node(node).and_then(|n| n.parameters.get(input)) {
            Some(v) => Lin::constant(vec4_of(v).unwrap_or(default)),
            None => Lin::constant(default),
        })
    }

    /// The output `out` of `path`, folded; `None` (reported) where it cannot be.
    fn output(&self, path: &str, out: &str, depth: usize) -> Option<Lin> {
        let node = self.node(path)?;
        let id = node.node_type_id.as_str();
        if depth > MAX_DEPTH {
            return self.unsupported(path, id, "the graph is deeper than 64 nodes");
        }
        let input = |name: &str, default: f32| self.input(path, name, Vec4::splat(default), depth);
        let family = id.strip_prefix("ND_").unwrap_or(id);
        let kind = family.split('_').next().unwrap_or("");
        match kind {
            "constant" => input("value", 0.0),
            "image" | "tiledimage" => {
                if kind == "tiledimage" && tiling_of(node).is_err() {
                    self.unsupported(path, id, "a zero or non-finite realworldimagesize");
                }
                Some(Lin {
                    texture: Some(Texture { node: path.to_string(), srgb: false, channel: None }),
                    scale: Vec4::ONE,
                    bias: Vec4::ZERO,
                })
            }
            "multiply" => Lin::mul(input("in1", 1.0)?, input("in2", 1.0)?).or_else(|| self.unsupported(path, id, "two textures")),
            "add" => Lin::add(input("in1", 0.0)?, input("in2", 0.0)?).or_else(|| self.unsupported(path, id, "two textures")),
            "subtract" => Lin::add(input("in1", 0.0)?, input("in2", 0.0)?.times(Vec4::splat(-1.0)))
                .or_else(|| self.unsupported(path, id, "two textures")),
            "mix" => {
                let Some(m) = input("mix", 0.0)?.value() else {
                    return self.unsupported(path, id, "a textured mix amount");
                };
                Lin::add(input("fg", 0.0)?.times(m), input("bg", 0.0)?.times(Vec4::ONE - m))
                    .or_else(|| self.unsupported(path, id, "two textures"))
            }
            "dot" | "convert" => input("in", 0.0),
            "divide" => match input("in2", 1.0)?.value() {
                Some(d) if (Vec4::ONE / d).is_finite() => Some(input("in1", 0.0)?.times(Vec4::ONE / d)),
                _ => self.unsupported(path, id, "a textured or zero divisor"),
            },
            // amount − in.
            "invert" => Lin::add(input("amount", 1.0)?, input("in", 0.0)?.times(Vec4::splat(-1.0)))
                .or_else(|| self.unsupported(path, id, "a textured amount")),
            // outlow + (in − inlow)·(outhigh − outlow)/(inhigh − inlow), with constant bounds.
            "remap" => {
                let bound = |name: &str, default: f32| input(name, default).and_then(|l| l.value());
                let (Some(il), Some(ih), Some(ol), Some(oh)) =
                    (bound("inlow", 0.0), bound("inhigh", 1.0), bound("outlow", 0.0), bound("outhigh", 1.0))
                else {
                    return self.unsupported(path, id, "textured bounds");
                };
                let k = (oh - ol) / (ih - il);
                if !k.is_finite() {
                    return self.unsupported(path, id, "an empty input range");
                }
                Lin::add(input("in", 0.0)?.times(k), Lin::constant(ol - il * k))
            }
            // One channel of a colour or vector: a packed map's roughness or metalness.
            "extract" => {
                let index = match node.parameters.get("index") {
                    Some(ParamValue::Int(i)) => *i,
                    _ => 0,
                };
                let x = input("in", 0.0)?;
                (0..4)
                    .contains(&index)
                    .then(|| x.channel(index as usize))
                    .flatten()
                    .or_else(|| self.unsupported(path, id, "an index past the fourth channel, or a channel of a channel"))
            }
            "separate2" | "separate3" | "separate4" => {
                let index = ["r", "g", "b", "a"]
                    .iter()
                    .zip(["x", "y", "z", "w"])
                    .position(|(c, v)| out == format!("out{c}") || out == format!("out{v}"));
                let x = input("in", 0.0)?;
                index
                    .and_then(|k| x.channel(k))
                    .or_else(|| self.unsupported(path, id, &format!("its output '{out}', or a channel of a channel")))
            }
            "srgb" if family.starts_with("srgb_texture_to_lin_rec709") => {
                let x = input("in", 0.0)?;
                match (&x.texture, x.value()) {
                    (None, Some(v)) => Some(Lin::constant(srgb_to_linear(v))),
                    (Some(t), _) if x.scale == Vec4::ONE && x.bias == Vec4::ZERO => {
                        Some(Lin { texture: Some(Texture { srgb: true, ..t.clone() }), ..x })
                    }
                    _ => self.unsupported(path, id, "sRGB decoding of a scaled texture"),
                }
            }
            _ => self.unsupported(path, id, "no mapping"),
        }
    }

    fn unsupported(&self, path: &str, id: &str, why: &str) -> Option<Lin> {
        let w = format!("{path}: MaterialX node '{id}' is not supported ({why}); the input it feeds keeps its default");
        let mut warned = self.warned.borrow_mut();
        if !warned.contains(&w) {
            warned.push(w);
        }
        None
    }

    /// Marks the surface input `name` as read by the mapping.
    fn mark(&self, name: &str) {
        self.read.borrow_mut().push(name.to_string());
    }

    /// The inputs authored on `surface` (values and connections) that its mapping never read,
    /// each once, in the order authored.
    fn unread(&self, surface: &str) -> Vec<String> {
        let read = self.read.borrow();
        let node = self.node(surface);
        let values = node.into_iter().flat_map(|n| n.parameters.keys().cloned());
        let connected = self.net.connections.iter().filter(|c| c.downstream_node == surface).map(|c| c.downstream_input.clone());
        let mut out: Vec<String> = Vec::new();
        for name in values.chain(connected) {
            if !read.contains(&name) && !out.contains(&name) {
                out.push(name);
            }
        }
        out
    }

    /// A surface input: its folded value, or `default` when it cannot be folded.
    fn get(&self, surface: &str, name: &str, default: f32) -> Lin {
        self.mark(name);
        self.input(surface, name, Vec4::splat(default), 0).unwrap_or(Lin::constant(Vec4::splat(default)))
    }

    fn get3(&self, surface: &str, name: &str, default: Vec3) -> Lin {
        self.mark(name);
        self.input(surface, name, default.extend(1.0), 0).unwrap_or(Lin::constant(default.extend(1.0)))
    }

    /// The amount a `displacement` shader handed to the surface (see [`displaced_by`]) moves it:
    /// `displacement · scale`, folded. None without one, or (reported) when it cannot be folded.
    fn displacement(&self, surface: &str) -> Option<Lin> {
        self.mark("displacement");
        let c = self.net.connections.iter().find(|c| c.downstream_node == surface && c.downstream_input == "displacement")?;
        let shader = &c.upstream_node;
        let amount = self.input(shader, "displacement", Vec4::ZERO, 1)?;
        let scale = self.input(shader, "scale", Vec4::ONE, 1)?;
        Lin::mul(amount, scale).or_else(|| self.unsupported(shader, DISPLACEMENT, "a textured scale of a textured displacement"))
    }

    /// A `normalmap` node's tangent-space normal (its image decoded as 2·t − 1), or a `bump`
    /// node's height × scale (noted in `bumped`, so the surface's normal is emitted through a
    /// `tessera:Bump`), when the surface's `input` is connected to one.
    fn normal_map(&self, surface: &str, input: &str) -> Option<Lin> {
        self.mark(input);
        let c = self.net.connections.iter().find(|c| c.downstream_node == surface && c.downstream_input == input)?;
        let node = self.node(&c.upstream_node)?;
        if node.node_type_id.starts_with("ND_bump") {
            return self.bump(node);
        }
        if !node.node_type_id.starts_with("ND_normalmap") {
            return self.output(&c.upstream_node, &c.upstream_output, 1).filter(|l| l.texture.is_some());
        }
        let image = self.input(&node.path, "in", Vec4::new(0.5, 0.5, 1.0, 1.0), 1)?;
        let scale = self.input(&node.path, "scale", Vec4::ONE, 1)?.value().unwrap_or(Vec4::ONE).x;
        // n = 2·texel − 1, with x and y scaled by the node's `scale`.
        let k = Vec4::new(2.0 * scale, 2.0 * scale, 2.0, 1.0);
        let mut n = image.times(k);
        n.bias -= Vec4::new(scale, scale, 1.0, 0.0);
        Some(n)
    }

    /// A `bump` node: its `height` × `scale` (a constant scale), a world-space height as
    /// `displacement`'s; reported when it bends a normal of its own (its `normal` input
    /// connected) or its scale is textured.
    fn bump(&self, node: &MaterialNode) -> Option<Lin> {
        let (path, id) = (node.path.as_str(), node.node_type_id.as_str());
        if self.net.connections.iter().any(|c| c.downstream_node == path && c.downstream_input == "normal") {
            return self.unsupported(path, id, "a bump of a normal of its own (its `normal` input connected)");
        }
        let height = self.input(path, "height", Vec4::ZERO, 1)?;
        let Some(scale) = self.input(path, "scale", Vec4::ONE, 1)?.value() else {
            return self.unsupported(path, id, "a textured scale");
        };
        self.bumped.set(true);
        Some(height.times(Vec4::splat(scale.x)))
    }
}

/// The name a bump's height takes among a surface's inputs until [`emit`] puts a `tessera:Bump`
/// between it and the surface's `normal`.
const BUMP_HEIGHT: &str = "normal:bumpHeight";

/// What a surface asks of the target shader: its id and inputs, each a folded value and
/// whether it is a colour.
struct Inputs {
    id: &'static str,
    values: Vec<(&'static str, Lin, bool)>,
}

/// Autodesk Standard Surface 1.0.1 (defaults from its specification).
fn standard_surface(g: &Graph, s: &str) -> Inputs {
    let base = Lin::mul(g.get(s, "base", 0.8), g.get3(s, "base_color", Vec3::ONE)).unwrap_or(Lin::constant(Vec4::splat(0.8)));
    let emission = Lin::mul(g.get(s, "emission", 0.0), g.get3(s, "emission_color", Vec3::ONE)).unwrap_or(Lin::constant(Vec4::ZERO));
    let opacity = g.get3(s, "opacity", Vec3::ONE);
    let opacity = Lin::constant(Vec4::splat(opacity.value().map_or(1.0, |o| (o.x + o.y + o.z) / 3.0)));
    let lobes = Lobes {
        base,
        metalness: g.get(s, "metalness", 0.0),
        diffuse_roughness: g.get(s, "diffuse_roughness", 0.0),
        specular_color: g.get3(s, "specular_color", Vec3::ONE),
        specular_weight: g.get(s, "specular", 1.0),
        roughness: g.get(s, "specular_roughness", 0.2),
        ior: g.get(s, "specular_IOR", 1.5),
        anisotropy: g.get(s, "specular_anisotropy", 0.0),
        stretch: Stretch::StandardSurface,
        rotation: g.get(s, "specular_rotation", 0.0),
        transmission: g.get(s, "transmission", 0.0),
        transmission_color: g.get3(s, "transmission_color", Vec3::ONE),
        coat: g.get(s, "coat", 0.0),
        coat_color: g.get3(s, "coat_color", Vec3::ONE),
        coat_roughness: g.get(s, "coat_roughness", 0.1),
        sheen: g.get(s, "sheen", 0.0),
        sheen_color: g.get3(s, "sheen_color", Vec3::ONE),
        sheen_roughness: g.get(s, "sheen_roughness", 0.3),
        // Standard Surface's sheen is Estevez & Kulla's microfibre (Charlie) sheen.
        sheen_names: ["sheen", "sheenColor", "sheenRoughness"],
        // Its metals take specular_color as Gulbrandsen's edge tint.
        edge_f82: false,
        subsurface: g.get(s, "subsurface", 0.0),
        medium: Medium {
            color: g.get3(s, "subsurface_color", Vec3::ONE),
            radius: Lin::mul(g.get3(s, "subsurface_radius", Vec3::ONE), g.get(s, "subsurface_scale", 1.0)),
            anisotropy: g.get(s, "subsurface_anisotropy", 0.0),
        },
        coat_ior: g.get(s, "coat_IOR", 1.5),
        thin: g.get(s, "thin_walled", 0.0),
        emission,
        opacity,
        normal: g.normal_map(s, "normal"),
        film: Some(g.get(s, "thin_film_thickness", 0.0)),
        film_ior: g.get(s, "thin_film_IOR", 1.5),
    };
    lobes.inputs(s, &mut g.warned.borrow_mut())
}

/// OpenPBR Surface 1.1 (defaults from its specification). Emission luminance is taken as the
/// radiance scale, as UsdLux intensities are.
fn open_pbr(g: &Graph, s: &str) -> Inputs {
    let base = Lin::mul(g.get(s, "base_weight", 1.0), g.get3(s, "base_color", Vec3::splat(0.8))).unwrap_or(Lin::constant(Vec4::splat(0.8)));
    let emission =
        Lin::mul(g.get(s, "emission_luminance", 0.0), g.get3(s, "emission_color", Vec3::ONE)).unwrap_or(Lin::constant(Vec4::ZERO));
    let lobes = Lobes {
        base,
        metalness: g.get(s, "base_metalness", 0.0),
        diffuse_roughness: g.get(s, "base_diffuse_roughness", 0.0),
        specular_color: g.get3(s, "specular_color", Vec3::ONE),
        specular_weight: g.get(s, "specular_weight", 1.0),
        roughness: g.get(s, "specular_roughness", 0.3),
        ior: g.get(s, "specular_ior", 1.5),
        anisotropy: g.get(s, "specular_roughness_anisotropy", 0.0),
        stretch: Stretch::OpenPbr,
        // OpenPBR turns its anisotropy only through `geometry_tangent`.
        rotation: Lin::constant(Vec4::ZERO),
        transmission: g.get(s, "transmission_weight", 0.0),
        transmission_color: g.get3(s, "transmission_color", Vec3::ONE),
        coat: g.get(s, "coat_weight", 0.0),
        coat_color: g.get3(s, "coat_color", Vec3::ONE),
        coat_roughness: g.get(s, "coat_roughness", 0.0),
        sheen: g.get(s, "fuzz_weight", 0.0),
        sheen_color: g.get3(s, "fuzz_color", Vec3::ONE),
        sheen_roughness: g.get(s, "fuzz_roughness", 0.5),
        // OpenPBR's fuzz is Zeltner et al.'s LTC sheen.
        sheen_names: ["fuzz", "fuzzColor", "fuzzRoughness"],
        // Its metals take specular_color as the F82 tint.
        edge_f82: true,
        subsurface: g.get(s, "subsurface_weight", 0.0),
        medium: Medium {
            color: g.get3(s, "subsurface_color", Vec3::splat(0.8)),
            radius: Lin::mul(g.get3(s, "subsurface_radius_scale", Vec3::new(1.0, 0.5, 0.25)), g.get(s, "subsurface_radius", 1.0)),
            anisotropy: g.get(s, "subsurface_scatter_anisotropy", 0.0),
        },
        coat_ior: g.get(s, "coat_ior", 1.6),
        thin: g.get(s, "geometry_thin_walled", 0.0),
        emission,
        opacity: g.get(s, "geometry_opacity", 1.0),
        normal: g.normal_map(s, "geometry_normal"),
        film: open_pbr_film(g, s),
        film_ior: g.get(s, "thin_film_ior", 1.4),
    };
    lobes.inputs(s, &mut g.warned.borrow_mut())
}

/// OpenPBR's thin film as a thickness in nanometres (its `thin_film_thickness` is in
/// micrometres): 0 at weight 0, the film at weight 1, None between.
fn open_pbr_film(g: &Graph, s: &str) -> Option<Lin> {
    let (weight, thickness) = (g.get(s, "thin_film_weight", 0.0), g.get(s, "thin_film_thickness", 0.5));
    match weight.value().map(|w| w.x) {
        Some(0.0) => Some(Lin::constant(Vec4::ZERO)),
        Some(1.0) => Some(thickness.times(Vec4::splat(1000.0))),
        _ => None,
    }
}

/// MaterialX's UsdPreviewSurface node: the same inputs as the USD shader.
fn preview(g: &Graph, s: &str) -> Inputs {
    let colors = [("diffuseColor", Vec3::splat(0.18)), ("emissiveColor", Vec3::ZERO), ("specularColor", Vec3::ZERO)];
    let floats = [
        ("metallic", 0.0),
        ("roughness", 0.5),
        ("clearcoat", 0.0),
        ("clearcoatRoughness", 0.01),
        ("opacity", 1.0),
        ("opacityThreshold", 0.0),
        ("ior", 1.5),
        ("useSpecularWorkflow", 0.0),
    ];
    let mut values: Vec<(&'static str, Lin, bool)> = colors.iter().map(|&(n, d)| (n, g.get3(s, n, d), true)).collect();
    values.extend(floats.iter().map(|&(n, d)| (n, g.get(s, n, d), false)));
    if let Some(n) = g.normal_map(s, "normal") {
        values.push(("normal", n, true));
    }
    Inputs { id: "UsdPreviewSurface", values }
}

/// The coat thickness at which a head-on round trip through Tessera's absorbing clearcoat is
/// tinted exactly by its attenuation colour: the meaning both specifications give the coat's
/// colour (the tint seen head-on, deeper at grazing angles).
const COAT_THICKNESS: f32 = 1.0;

/// True when `l` is a constant whose first channel is `v`.
fn is_constant(l: &Lin, v: f32) -> bool {
    l.value().is_some_and(|x| x.x == v)
}

/// True when `l` is the constant white.
fn white(l: &Lin) -> bool {
    l.value().is_some_and(|c| c.truncate() == Vec3::ONE)
}

/// Tessera's own shaders a MaterialX surface may map onto whole.
enum Native {
    /// `tessera:SolidDielectric`.
    Dielectric,
    /// `tessera:Metal`.
    Metal,
}

/// The lobes Standard Surface and OpenPBR share, by their meaning.
struct Lobes {
    base: Lin,
    metalness: Lin,
    /// Oren-Nayar roughness of the diffuse base.
    diffuse_roughness: Lin,
    /// Tint of the dielectric specular's head-on reflectance.
    specular_color: Lin,
    specular_weight: Lin,
    roughness: Lin,
    ior: Lin,
    /// The specification's anisotropy a: αy/αx = 1 − a (Tessera's own is set from it by
    /// [`Lobes::as_disney_anisotropy`]).
    anisotropy: Lin,
    /// How the specification keeps the lobe's width as a stretches it.
    stretch: Stretch,
    /// Turn of the tangent about the normal, in fractions of a full turn.
    rotation: Lin,
    transmission: Lin,
    transmission_color: Lin,
    coat: Lin,
    /// The coat's colour: what a head-on round trip through it lets through.
    coat_color: Lin,
    coat_roughness: Lin,
    sheen: Lin,
    sheen_color: Lin,
    sheen_roughness: Lin,
    /// `tessera:SolidDielectric`'s inputs for this sheen's model: weight, colour, roughness.
    sheen_names: [&'static str; 3],
    /// A metal's `specular_color` is an F82 tint (OpenPBR), not Gulbrandsen's edge tint.
    edge_f82: bool,
    subsurface: Lin,
    medium: Medium,
    coat_ior: Lin,
    thin: Lin,
    emission: Lin,
    opacity: Lin,
    normal: Option<Lin>,
    /// A thin film on the specular: its thickness in nanometres at full weight (0: none), or
    /// None when its weight is neither 0 nor 1 (OpenPBR blends the two Fresnels then).
    film: Option<Lin>,
    film_ior: Lin,
}

/// How a surface's anisotropy a stretches its GGX lobe. Both specifications make αy/αx = 1 − a;
/// Standard Surface (MaterialX's `roughness_anisotropy`) keeps √(αx·αy) = r², OpenPBR
/// (`open_pbr_anisotropy`: αx = r²·√(2/(1 + (1 − a)²)), αy = (1 − a)·αx) keeps the mean of
/// αx² and αy² at r⁴.
#[derive(Clone, Copy)]
enum Stretch {
    StandardSurface,
    OpenPbr,
}

/// The most anisotropy Tessera's GGX takes, as a: Disney's mapping (Schutte, "Specular
/// BRDF") makes αy/αx = 1 − 0.9·anisotropic, at most 10:1.
const MAX_STRETCH: f32 = 0.9;

/// The warning for a thin film a surface does not carry.
const FILM_NOT_CARRIED: &str = "a thin film is carried only on a dielectric without thin walls or opacity (opaque or glass, metalness 0) or on an opaque full metal, at full weight and of constant thickness; the specular has none";

impl Lobes {
    /// UsdPreviewSurface when it can say everything; `tessera:SolidDielectric` with a medium
    /// for subsurface it can say the rest of; `tessera:Principled` otherwise.
    fn inputs(mut self, surface: &str, warnings: &mut Vec<String>) -> Inputs {
        self.as_disney_anisotropy(surface, warnings);
        let beyond_preview = !is_constant(&self.transmission, 0.0)
            || !is_constant(&self.sheen, 0.0)
            || !is_constant(&self.thin, 0.0)
            || !is_constant(&self.specular_weight, 1.0);
        if !is_constant(&self.subsurface, 0.0) {
            if !beyond_preview && is_constant(&self.metalness, 0.0) {
                warnings.extend(self.film_lost(surface, true));
                return self.solid_dielectric(surface, warnings);
            }
            warnings.push(format!(
                "{surface}: subsurface is rendered as diffuse reflection (a scattering medium needs no metalness, transmission, sheen, thin walls or specular weight other than 1)"
            ));
        }
        match self.native_shader() {
            Some(Native::Dielectric) => {
                warnings.extend(self.film_lost(surface, true));
                return self.opaque_dielectric();
            }
            Some(Native::Metal) => {
                warnings.extend(self.film_lost(surface, true));
                return self.metal();
            }
            None => warnings.extend(self.uncarried(surface)),
        }
        let principled = beyond_preview || !is_constant(&self.anisotropy, 0.0);
        if !principled {
            let mut values = vec![
                ("diffuseColor", self.base, true),
                ("metallic", self.metalness, false),
                ("roughness", self.roughness, false),
                ("ior", self.ior, false),
                ("clearcoat", self.coat, false),
                ("clearcoatRoughness", self.coat_roughness, false),
                ("emissiveColor", self.emission, true),
                ("opacity", self.opacity, false),
            ];
            if let Some(n) = self.normal {
                values.push(("normal", n, true));
            }
            return Inputs { id: "UsdPreviewSurface", values };
        }
        // Disney's specular is F0 / 0.08; the MaterialX specular weight scales F0.
        let f0 = |ior: f32| ((ior - 1.0) / (ior + 1.0)).powi(2);
        let ior = self.ior.value().map_or(1.5, |v| v.x);
        let specular = self.specular_weight.value().map_or(1.0, |w| w.x) * f0(ior) / 0.08;
        let gloss = Lin::constant(Vec4::splat(1.0 - self.coat_roughness.value().map_or(0.0, |r| r.x)));
        let thin = self.thin.value().is_some_and(|t| t.x > 0.5);
        let film = self.principled_film().map(|nm| (nm, self.film_ior.clone()));
        // Disney tints transmission by the base colour; MaterialX by its own transmission
        // colour: blend the two by the transmission weight (a textured weight keeps the base).
        let base = match self.transmission.value() {
            Some(t) => Lin::add(self.base.clone().times(Vec4::ONE - t), self.transmission_color.times(t)).unwrap_or(self.base),
            None => self.base,
        };
        let mut values = vec![
            ("baseColor", base, true),
            ("metallic", self.metalness, false),
            ("roughness", self.roughness, false),
            ("ior", self.ior, false),
            ("specular", Lin::constant(Vec4::splat(specular.clamp(0.0, 1.0))), false),
            ("specTrans", self.transmission, false),
            ("clearcoat", self.coat, false),
            ("clearcoatGloss", gloss, false),
            ("sheen", self.sheen, false),
            ("anisotropic", self.anisotropy, false),
            ("emission", self.emission, true),
            ("thin", Lin::constant(Vec4::splat(if thin { 1.0 } else { 0.0 })), false),
        ];
        if let Some((nm, ior)) = film {
            values.push(("filmThickness", Lin::constant(Vec4::splat(nm)), false));
            values.push(("filmRefractiveIndex", ior, false));
        }
        if let Some(n) = self.normal {
            values.push(("normal", n, true));
        }
        Inputs { id: "tessera:Principled", values }
    }

    /// Which of Tessera's own shaders carries what UsdPreviewSurface cannot say of this surface
    /// (a rough diffuse, a sheen in its own model, a specular colour, anisotropy along the
    /// texture coordinates): an opaque dielectric or a full metal; None when it has none of
    /// these or is neither.
    fn native_shader(&self) -> Option<Native> {
        let sheen = !is_constant(&self.sheen, 0.0);
        let tinted = !white(&self.specular_color) || (!is_constant(&self.coat, 0.0) && !white(&self.coat_color));
        let plain = is_constant(&self.transmission, 0.0) && is_constant(&self.thin, 0.0) && is_constant(&self.opacity, 1.0);
        // Only Tessera's own shaders turn anisotropy with the texture coordinates.
        let anisotropic = !is_constant(&self.anisotropy, 0.0);
        if plain
            && is_constant(&self.metalness, 0.0)
            && is_constant(&self.specular_weight, 1.0)
            && (sheen || tinted || anisotropic || !is_constant(&self.diffuse_roughness, 0.0) || self.carried_film().is_some())
        {
            return Some(Native::Dielectric);
        }
        let film = self.carried_film().is_some();
        (plain && is_constant(&self.metalness, 1.0) && (sheen || tinted || anisotropic || film)).then_some(Native::Metal)
    }

    /// What a surface that maps onto neither of Tessera's own shaders loses of them, said.
    fn uncarried(&self, surface: &str) -> Vec<String> {
        let mut said = Vec::new();
        if !is_constant(&self.coat, 0.0) && !white(&self.coat_color) {
            said.push(format!(
                "{surface}: coat_color is carried only on an opaque dielectric or a full metal (no transmission, thin walls or opacity, metalness 0 or 1); the coat is clear"
            ));
        }
        if !white(&self.specular_color) {
            said.push(format!(
                "{surface}: specular_color is carried only on an opaque dielectric or a full metal (no transmission, thin walls or opacity, metalness 0 or 1); the specular is untinted"
            ));
        }
        said.extend(self.film_lost(surface, false));
        // A full metal has no diffuse to be rough.
        if !is_constant(&self.diffuse_roughness, 0.0) && !is_constant(&self.metalness, 1.0) {
            said.push(format!(
                "{surface}: diffuse roughness is carried only on an opaque dielectric (no metalness, transmission, thin walls, opacity or specular weight other than 1); this diffuse is smooth"
            ));
        }
        if !is_constant(&self.sheen, 0.0) {
            said.push(format!(
                "{surface}: {} on a surface that is neither an opaque dielectric nor a full metal is Disney's sheen here; its colour and roughness are not carried",
                self.sheen_names[0]
            ));
        }
        if !is_constant(&self.anisotropy, 0.0) {
            said.push(format!(
                "{surface}: anisotropy follows the texture coordinates (MaterialX's default tangent) and its rotation only on an opaque dielectric or a full metal; here it runs around the object's up axis, unturned"
            ));
        }
        said
    }

    /// `anisotropy` and `roughness` as Tessera's (Disney's) parameters for the same αx and αy:
    /// anisotropic = a / 0.9, and OpenPBR's roughness scaled by (2(1 − a)/(1 + (1 − a)²))^¼ so
    /// that √(αx·αy), which Disney's roughness sets, is OpenPBR's. A constant a is clamped to
    /// [0, 0.9] (above 0.9, said); with a textured a, OpenPBR's roughness is kept (said).
    fn as_disney_anisotropy(&mut self, surface: &str, warnings: &mut Vec<String>) {
        let open_pbr = matches!(self.stretch, Stretch::OpenPbr);
        match self.anisotropy.value().map(|v| v.x) {
            Some(a) => {
                if a > MAX_STRETCH {
                    warnings.push(format!(
                        "{surface}: specular anisotropy {a} is rendered at {MAX_STRETCH}: Tessera's GGX stretches at most 10:1"
                    ));
                }
                let a = a.clamp(0.0, MAX_STRETCH);
                if open_pbr {
                    let k = 1.0 - a;
                    self.roughness = self.roughness.clone().times(Vec4::splat((2.0 * k / (1.0 + k * k)).powf(0.25)));
                }
                self.anisotropy = Lin::constant(Vec4::splat(a * (1.0 / MAX_STRETCH)));
            }
            None => {
                if open_pbr {
                    warnings.push(format!(
                        "{surface}: with a textured specular_roughness_anisotropy the roughness is not narrowed as OpenPBR narrows it (by up to 16% at 0.9)"
                    ));
                }
                self.anisotropy = self.anisotropy.clone().times(Vec4::splat(1.0 / MAX_STRETCH));
            }
        }
    }

    /// Which way the anisotropy runs on Tessera's own shaders: along the texture coordinate s
    /// (dP/ds, MaterialX's default tangent `Tworld`), turned by the rotation. Nothing when the
    /// surface is isotropic.
    fn frame_inputs(&self) -> Vec<(&'static str, Lin, bool)> {
        match is_constant(&self.anisotropy, 0.0) {
            true => Vec::new(),
            false => vec![("anisotropyRotation", self.rotation.clone(), false), ("stTangent", Lin::constant(Vec4::ONE), false)],
        }
    }

    /// The warning for a film this surface has and does not carry: any film where the target
    /// is not one of Tessera's own opaque shaders (`native`), one it cannot take (partial
    /// weight, textured) where it is.
    fn film_lost(&self, surface: &str, native: bool) -> Option<String> {
        let any = self.film.as_ref().is_none_or(|f| !is_constant(f, 0.0));
        let carried = if native { self.carried_film().is_some() } else { self.principled_film().is_some() };
        (any && !carried).then(|| format!("{surface}: {FILM_NOT_CARRIED}"))
    }

    /// The film `tessera:Principled` carries on its dielectric specular and its glass (not on
    /// its metal, and thin walls take none): [`Self::carried_film`] on a surface without
    /// metalness, thin walls or opacity.
    fn principled_film(&self) -> Option<f32> {
        let dielectric = is_constant(&self.metalness, 0.0) && is_constant(&self.thin, 0.0) && is_constant(&self.opacity, 1.0);
        self.carried_film().filter(|_| dielectric)
    }

    /// The film `tessera:SolidDielectric` carries: a constant thickness above 0 at full weight.
    fn carried_film(&self) -> Option<f32> {
        self.film.as_ref()?.value().map(|f| f.x).filter(|&nm| nm > 0.0)
    }

    /// The surface film of `tessera:SolidDielectric` or `tessera:Metal`, when carried.
    fn film_inputs(&self) -> Vec<(&'static str, Lin, bool)> {
        match self.carried_film() {
            Some(nm) => {
                vec![("filmThickness", Lin::constant(Vec4::splat(nm)), false), ("filmRefractiveIndex", self.film_ior.clone(), false)]
            }
            None => Vec::new(),
        }
    }

    /// What Tessera's own shaders share: the coat (its colour as the absorption of a coat of
    /// thickness 1), emission, the normal map, and with `sheen` the sheen in its model's inputs.
    fn shared_inputs(&self, sheen: bool) -> Vec<(&'static str, Lin, bool)> {
        let mut values = vec![
            ("clearcoat", self.coat.clone(), false),
            ("clearcoatRoughness", self.coat_roughness.clone(), false),
            ("clearcoatRefractiveIndex", self.coat_ior.clone(), false),
            ("clearcoatAttenuationColor", self.coat_color.clone(), true),
            ("clearcoatThickness", Lin::constant(Vec4::splat(COAT_THICKNESS)), false),
            ("emission", self.emission.clone(), true),
        ];
        if sheen {
            let [weight, color, roughness] = self.sheen_names;
            values.extend([
                (weight, self.sheen.clone(), false),
                (color, self.sheen_color.clone(), true),
                (roughness, self.sheen_roughness.clone(), false),
            ]);
        }
        values.extend(self.normal.clone().map(|n| ("normal", n, true)));
        values
    }

    /// An opaque dielectric with a rough (Oren-Nayar) diffuse, a sheen or a tinted specular:
    /// `tessera:SolidDielectric`, the same Lambertian-under-specular model UsdPreviewSurface
    /// resolves to, plus the roughness, the sheen in its own model (Charlie or fuzz) and the
    /// specular's tint.
    fn opaque_dielectric(self) -> Inputs {
        let shared = self.shared_inputs(true);
        let film = self.film_inputs();
        let frame = self.frame_inputs();
        let mut values = vec![
            ("albedo", self.base, true),
            ("diffuseRoughness", self.diffuse_roughness, false),
            ("specularColor", self.specular_color, true),
            ("refractiveIndex", self.ior, false),
            ("roughness", self.roughness, false),
            ("anisotropy", self.anisotropy, false),
        ];
        values.extend(film);
        values.extend(shared);
        values.extend(frame);
        Inputs { id: "tessera:SolidDielectric", values }
    }

    /// A full metal with a tinted edge or a sheen: `tessera:Metal`, the base colour its
    /// reflectivity and `specular_color` its edge tint (Gulbrandsen's for Standard Surface, the
    /// F82 tint for OpenPBR).
    fn metal(self) -> Inputs {
        let shared = self.shared_inputs(true);
        let frame = self.frame_inputs();
        let film = self.film_inputs();
        let f82 = Lin::constant(Vec4::splat(if self.edge_f82 { 1.0 } else { 0.0 }));
        let mut values = vec![
            ("reflectivity", self.base, true),
            ("edgeTint", self.specular_color, true),
            ("f82", f82, false),
            ("roughness", self.roughness, false),
            ("anisotropy", self.anisotropy, false),
        ];
        values.extend(film);
        values.extend(shared);
        values.extend(frame);
        Inputs { id: "tessera:Metal", values }
    }

    /// A dielectric whose base is partly or wholly a scattering medium: `tessera:SolidDielectric`
    /// with its random walk (docs/materials.md, "Subsurface scattering"). The weight becomes
    /// `scatteringWeight`; the medium and the diffuse beside it share one colour, the two
    /// colours mixed by the weight (exact at weights 0 and 1, and for their mean under even
    /// light).
    fn solid_dielectric(self, surface: &str, warnings: &mut Vec<String>) -> Inputs {
        let shared = self.shared_inputs(false);
        let film = self.film_inputs();
        let frame = self.frame_inputs();
        let m = self.medium;
        let albedo = match self.subsurface.value() {
            Some(w) if w.x >= 1.0 => Some(m.color.clone()),
            Some(w) => Lin::add(self.base.clone().times(Vec4::splat(1.0 - w.x)), m.color.clone().times(Vec4::splat(w.x))),
            None => None,
        }
        .unwrap_or_else(|| {
            warnings.push(format!(
                "{surface}: the diffuse beside the medium shows subsurface_color (its weight or colours are textured apart)"
            ));
            m.color
        });
        // One radius scaled per channel: the largest channel's path, the others relative to it.
        let mfp = m.radius.and_then(|r| r.value()).map(|r| r.truncate().max(Vec3::ZERO)).unwrap_or_else(|| {
            warnings.push(format!("{surface}: a textured subsurface radius is not read; using 1 in each channel"));
            Vec3::ONE
        });
        let longest = mfp.max_element();
        let spread = if longest > 0.0 && longest.is_finite() { mfp / longest } else { Vec3::ONE };
        if !self.opacity.value().is_some_and(|o| o.x >= 1.0) {
            warnings.push(format!("{surface}: opacity is not applied to a surface with subsurface scattering"));
        }
        let mut values = vec![
            ("albedo", albedo, true),
            ("diffuseRoughness", self.diffuse_roughness, false),
            ("refractiveIndex", self.ior, false),
            ("roughness", self.roughness, false),
            ("anisotropy", self.anisotropy, false),
            ("scatteringRadius", Lin::constant(Vec4::splat(if longest.is_finite() { longest } else { 0.0 })), false),
            ("scatteringColor", Lin::constant(spread.extend(1.0)), true),
            ("scatteringWeight", self.subsurface, false),
            ("scatteringAnisotropy", m.anisotropy, false),
        ];
        values.extend(film);
        values.extend(shared);
        values.extend(frame);
        Inputs { id: "tessera:SolidDielectric", values }
    }
}

/// The subsurface inputs: the colour the medium shows, its mean free path per channel (the
/// radius times its scale) and its phase function's eccentricity.
struct Medium {
    color: Lin,
    radius: Option<Lin>,
    anisotropy: Lin,
}

/// The rewritten network: the surface node with constant inputs as parameters, and one
/// `UsdUVTexture` (fed by a `UsdPrimvarReader_float2`) per textured input.
fn emit(surface: &str, inputs: Inputs, old: &MaterialNetwork, warnings: &mut Vec<String>) -> MaterialNetwork {
    let mut net = MaterialNetwork { surface_node: surface.to_string(), ..Default::default() };
    let mut params = BTreeMap::new();
    for (name, lin, color) in inputs.values {
        let Some(texture) = &lin.texture else {
            let v = lin.bias;
            let p = match (name, color) {
                ("thin" | "f82", _) => ParamValue::Bool(v.x > 0.5),
                ("useSpecularWorkflow", _) => ParamValue::Int(v.x as i32),
                (_, true) => ParamValue::Float3(v.truncate()),
                (_, false) => ParamValue::Float(v.x),
            };
            params.insert(name.to_string(), p);
            continue;
        };
        let Some(image) = old.nodes.iter().find(|n| n.path == texture.node) else { continue };
        let output = match texture.channel {
            Some(k) if !color => ["r", "g", "b", "a"][k],
            Some(_) => {
                warnings.push(format!(
                    "{surface}: input '{name}' reads one channel of {} as a colour, which is not carried; it keeps its default",
                    texture.node
                ));
                continue;
            }
            None if color => "rgb",
            None => "r",
        };
        let tex_path = format!("{}_{}", texture.node, name.replace(':', "_"));
        net.nodes.push(uv_texture(&tex_path, image, &lin, texture.srgb, name == "normal"));
        if name == BUMP_HEIGHT {
            let bump = format!("{surface}_bump");
            net.nodes.push(MaterialNode {
                path: bump.clone(),
                node_type_id: render_core::material::BUMP.into(),
                parameters: BTreeMap::new(),
            });
            net.connections.push(connection(&bump, "height", &tex_path, output));
            net.connections.push(connection(surface, "normal", &bump, "out"));
        } else {
            net.connections.push(connection(surface, name, &tex_path, output));
        }
        let (reader, placed) = texcoord_reader(&tex_path, image, old, warnings);
        // A tiled image reads its coordinates through its placement, as does one behind a
        // place2d (both at once are reported, and the tiling kept).
        let tiling = tiling_of(image).ok().flatten().map(|(scale, translation)| Place {
            rotation: 0.0,
            scale,
            translation,
            node: image.path.clone(),
        });
        if let (Some(_), Some(p)) = (&tiling, &placed) {
            warnings.push(format!("{}: a place2d into a tiledimage is not supported; the tiling alone places it", p.node));
        }
        let coordinates = match tiling.or(placed) {
            Some(place) => {
                let placement = placement(&tex_path, &place);
                net.connections.push(result_into(&placement.path, "in", &reader.path));
                let path = placement.path.clone();
                net.nodes.push(placement);
                path
            }
            None => reader.path.clone(),
        };
        net.connections.push(result_into(&tex_path, "st", &coordinates));
        net.nodes.push(reader);
    }
    net.nodes.push(MaterialNode { path: surface.to_string(), node_type_id: inputs.id.to_string(), parameters: params });
    net
}

fn connection(downstream: &str, input: &str, upstream: &str, output: &str) -> MaterialConnection {
    MaterialConnection {
        downstream_node: downstream.to_string(),
        downstream_input: input.to_string(),
        upstream_node: upstream.to_string(),
        upstream_output: output.to_string(),
    }
}

/// A `UsdUVTexture` for `image`, with the folded scale and bias.
fn uv_texture(path: &str, image: &MaterialNode, lin: &Lin, srgb: bool, normal: bool) -> MaterialNode {
    let mut p = BTreeMap::new();
    if let Some(file) = image.parameters.get("file") {
        p.insert("file".to_string(), file.clone());
    }
    if let Some(fallback) = image.parameters.get("default").and_then(vec4_of) {
        p.insert("fallback".to_string(), ParamValue::Float4(fallback));
    }
    for (mx, usd) in [("uaddressmode", "wrapS"), ("vaddressmode", "wrapT")] {
        let mode = match image.parameters.get(mx) {
            Some(ParamValue::String(m)) if m == "clamp" => "clamp",
            Some(ParamValue::String(m)) if m == "mirror" => "mirror",
            Some(ParamValue::String(m)) if m == "constant" => "black",
            _ => "repeat",
        };
        p.insert(usd.to_string(), ParamValue::String(mode.into()));
    }
    // Normal maps are raw; otherwise the file's MaterialX colour space decides (sRGB-encoded
    // or linear), else an sRGB-decoding node, else UsdUVTexture's rule by bit depth.
    // MaterialX's names (`srgb_texture`, `lin_rec709`...) or USD's (`sRGB`, `raw`...): the
    // sRGB-encoded ones decode, the rest read as they are.
    let declared = match image.parameters.get("colorspace") {
        Some(ParamValue::String(s)) if s.to_ascii_lowercase().contains("srgb") => Some("sRGB"),
        Some(ParamValue::String(s)) if !s.is_empty() && s != "auto" => Some("raw"),
        _ => None,
    };
    let space = if normal {
        "raw"
    } else if srgb {
        "sRGB"
    } else {
        declared.unwrap_or("auto")
    };
    p.insert("sourceColorSpace".to_string(), ParamValue::String(space.into()));
    p.insert("scale".to_string(), ParamValue::Float4(lin.scale));
    p.insert("bias".to_string(), ParamValue::Float4(lin.bias));
    MaterialNode { path: path.to_string(), node_type_id: "UsdUVTexture".into(), parameters: p }
}

/// The primvar reader for an image's `texcoord`: the primvar a `geompropvalue` names, else
/// `st` (MaterialX's default texture coordinates, UV set 0).
fn texcoord_reader(
    texture: &str,
    image: &MaterialNode,
    old: &MaterialNetwork,
    warnings: &mut Vec<String>,
) -> (MaterialNode, Option<Place>) {
    let feeding = |node: &str| {
        let c = old.connections.iter().find(|c| c.downstream_node == node && c.downstream_input == "texcoord")?;
        old.nodes.iter().find(|n| n.path == c.upstream_node)
    };
    let mut upstream = feeding(&image.path);
    // A place2d between: its transform, and the coordinates it reads.
    let mut placed = None;
    if let Some(place2d) = upstream.filter(|n| n.node_type_id.starts_with("ND_place2d")) {
        match place_of(place2d, old) {
            Ok(place) => placed = Some(place),
            Err(why) => warnings.push(format!(
                "{}: MaterialX node '{}' is not supported ({why}); its coordinates are used unplaced",
                place2d.path, place2d.node_type_id
            )),
        }
        upstream = feeding(&place2d.path);
    }
    let varname = match upstream {
        Some(n) if n.node_type_id.starts_with("ND_geompropvalue") => match n.parameters.get("geomprop") {
            Some(ParamValue::String(name)) => name.clone(),
            _ => "st".into(),
        },
        Some(n) if n.node_type_id.starts_with("ND_texcoord") => "st".into(),
        Some(n) => {
            warnings.push(format!("{}: MaterialX node '{}' as texture coordinates is not supported; st is used", n.path, n.node_type_id));
            "st".into()
        }
        None => "st".into(),
    };
    let parameters = BTreeMap::from([("varname".to_string(), ParamValue::String(varname))]);
    (MaterialNode { path: format!("{texture}_st"), node_type_id: "UsdPrimvarReader_float2".into(), parameters }, placed)
}

/// A texture placement as `UsdTransform2d` says one: st · scale, turned `rotation` degrees
/// counter-clockwise, plus `translation`; `node` is the place2d it came from, if one.
#[derive(Clone, Debug, PartialEq)]
struct Place {
    rotation: f32,
    scale: Vec2,
    translation: Vec2,
    node: String,
}

/// A `place2d` with constant inputs as a [`Place`]. MaterialX's graph for it (NG_place2d_vector2):
/// SRT moves by −pivot, divides by `scale`, turns by `rotate` degrees clockwise, moves by
/// −`offset` and +pivot; TRS takes the offset before the turn and the scale after it, which
/// UsdTransform2d's scale-then-rotate holds only for a uniform scale or no turn (else `Err`).
fn place_of(node: &MaterialNode, net: &MaterialNetwork) -> Result<Place, String> {
    let connected = ["pivot", "scale", "rotate", "offset", "operationorder"]
        .into_iter()
        .find(|i| net.connections.iter().any(|c| c.downstream_node == node.path && c.downstream_input == *i));
    if let Some(input) = connected {
        return Err(format!("its {input} is connected"));
    }
    let v2 = |name: &str, default: Vec2| float2_of(node, name, default);
    let (pivot, scale, offset) = (v2("pivot", Vec2::ZERO), v2("scale", Vec2::ONE), v2("offset", Vec2::ZERO));
    let rotate = match node.parameters.get("rotate") {
        Some(ParamValue::Float(r)) => *r,
        _ => 0.0,
    };
    let trs = matches!(node.parameters.get("operationorder"), Some(ParamValue::Int(1)));
    let inverse = Vec2::ONE / scale;
    if !(inverse.is_finite() && rotate.is_finite() && pivot.is_finite() && offset.is_finite()) {
        return Err("a zero or non-finite scale, or a non-finite input".into());
    }
    if trs && rotate != 0.0 && inverse.x != inverse.y {
        return Err("TRS order with a turn and a non-uniform scale, a shear".into());
    }
    let linear = glam::Mat2::from_angle(-rotate.to_radians()) * glam::Mat2::from_diagonal(inverse);
    let translation = if trs { pivot - linear * (pivot + offset) } else { pivot - offset - linear * pivot };
    Ok(Place { rotation: -rotate, scale: inverse, translation, node: node.path.clone() })
}

/// `downstream`'s `input` fed by `upstream`'s `result` (a reader's or a transform's output).
fn result_into(downstream: &str, input: &str, upstream: &str) -> MaterialConnection {
    connection(downstream, input, upstream, "result")
}

/// A `tiledimage`'s placement as MaterialX's own graph for it computes it, (texcoord · uvtiling
/// − uvoffset) / realworldimagesize · realworldtilesize: a scale and a translation, None when
/// they change nothing; `Err` for an image size that cannot divide.
fn tiling_of(image: &MaterialNode) -> Result<Option<(Vec2, Vec2)>, ()> {
    if !image.node_type_id.starts_with("ND_tiledimage") {
        return Ok(None);
    }
    let v2 = |name: &str, default: Vec2| float2_of(image, name, default);
    let k = v2("realworldtilesize", Vec2::ONE) / v2("realworldimagesize", Vec2::ONE);
    let (scale, translation) = (v2("uvtiling", Vec2::ONE) * k, -v2("uvoffset", Vec2::ZERO) * k);
    if !(scale.is_finite() && translation.is_finite()) {
        return Err(());
    }
    Ok((scale != Vec2::ONE || translation != Vec2::ZERO).then_some((scale, translation)))
}

/// The `UsdTransform2d` that places texture `texture`'s coordinates.
fn placement(texture: &str, place: &Place) -> MaterialNode {
    let parameters = BTreeMap::from([
        ("scale".to_string(), ParamValue::Float2(place.scale)),
        ("rotation".to_string(), ParamValue::Float(place.rotation)),
        ("translation".to_string(), ParamValue::Float2(place.translation)),
    ]);
    MaterialNode { path: format!("{texture}_placement"), node_type_id: "UsdTransform2d".into(), parameters }
}

/// A node's float2 parameter, else `default`.
fn float2_of(node: &MaterialNode, name: &str, default: Vec2) -> Vec2 {
    match node.parameters.get(name) {
        Some(ParamValue::Float2(v)) => *v,
        _ => default,
    }
}

pub(super) fn vec4_of(v: &ParamValue) -> Option<Vec4> {
    Some(match v {
        ParamValue::Float(x) => Vec4::splat(*x),
        ParamValue::Int(i) => Vec4::splat(*i as f32),
        ParamValue::Bool(b) => Vec4::splat(if *b { 1.0 } else { 0.0 }),
        ParamValue::Float2(v) => Vec4::new(v.x, v.y, 0.0, 1.0),
        ParamValue::Float3(v) => v.extend(1.0),
        ParamValue::Float4(v) => *v,
        _ => return None,
    })
}

/// The sRGB transfer function's inverse, per component (IEC 61966-2-1).
fn srgb_to_linear(v: Vec4) -> Vec4 {
    let f = |c: f32| if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) };
    Vec4::new(f(v.x), f(v.y), f(v.z), v.w)
}
