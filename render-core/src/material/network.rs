//! Material networks in the shape of Hydra's `HdMaterialNetwork`, and their resolution to
//! a [`Material`].

use super::Material;
pub use super::desc::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue, UDIM_TILES};
pub(crate) use super::inputs::Inputs;
pub use super::inputs::ResolveReport;
use super::inputs::{Overrides, evaluable};

/// One resolution's state: what it has visited and reported, and the point's varying inputs.
struct Walk<'a> {
    material_path: &'a str,
    used: Vec<String>,
    /// The material of each node feeding several inputs, resolved once: a node shared by many
    /// layers (a "diamond") costs one resolution, not one per path to it.
    memo: std::collections::HashMap<String, Material>,
    /// Materials of the nodes no varying input reaches, resolved once per material at
    /// compile time ([`super::graph::TexturedMaterial`]): per shading point only the nodes
    /// between a varying input and the surface are resolved again.
    fixed: Option<&'a std::collections::HashMap<String, Material>>,
    report: ResolveReport,
    overrides: Overrides<'a>,
}

/// Deepest chain of `tessera:Layer` nodes followed (a cycle is reported, not followed).
const MAX_LAYER_DEPTH: usize = 32;

/// Most nodes one network may hold: production materials have tens to a few hundred; a
/// limit keeps resolution, which runs per shading point for textured materials, bounded.
pub const MAX_NODES: usize = 1024;
/// Most connections one network may hold.
pub const MAX_CONNECTIONS: usize = 4 * MAX_NODES;
/// Longest chain of connections from the surface node upstream.
pub const MAX_CHAIN_DEPTH: usize = 64;
/// Longest node path, input or output name.
const MAX_NAME_BYTES: usize = 4096;

/// Why a network is refused before any resolution: the message names the material, the node
/// or input at fault, and the limit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct NetworkError(pub String);

impl MaterialNetwork {
    /// Checks what a client controls before anything walks the network: sizes and names, no
    /// duplicate nodes, no cycles and no chain deeper than [`MAX_CHAIN_DEPTH`] (so every walk
    /// is bounded), and finite parameters. Linear in the network's size.
    pub fn validate(&self, material: &str) -> Result<(), NetworkError> {
        let too_large = |what, count, limit| NetworkError(format!("{material}: {count} {what} exceed the limit of {limit}"));
        if self.nodes.len() > MAX_NODES {
            return Err(too_large("nodes", self.nodes.len(), MAX_NODES));
        }
        if self.connections.len() > MAX_CONNECTIONS {
            return Err(too_large("connections", self.connections.len(), MAX_CONNECTIONS));
        }
        let bad_name = |what, name: &str| {
            let shown: String = name.chars().take(80).collect();
            NetworkError(format!(
                "{material}: {what} \"{}\" is not a valid name (empty, longer than {MAX_NAME_BYTES} bytes, or with a control character)",
                shown.escape_debug()
            ))
        };
        let check = |what, name: &str| {
            if name.is_empty() || name.len() > MAX_NAME_BYTES || name.chars().any(char::is_control) {
                Err(bad_name(what, name))
            } else {
                Ok(())
            }
        };
        let mut index = std::collections::HashMap::with_capacity(self.nodes.len());
        for (i, n) in self.nodes.iter().enumerate() {
            check("node path", &n.path)?;
            if index.insert(n.path.as_str(), i).is_some() {
                return Err(NetworkError(format!("{material}: node path {} appears twice", n.path)));
            }
            for (input, value) in &n.parameters {
                check("input name", input)?;
                if let Some(v) = non_finite(value) {
                    return Err(NetworkError(format!("{material}: {}: input '{input}' is not finite or beyond ±1e18 ({v})", n.path)));
                }
                if let ParamValue::Udim { tiles, .. } = value
                    && let Some(why) = bad_udim_tiles(tiles)
                {
                    return Err(NetworkError(format!("{material}: {}: input '{input}': {why}", n.path)));
                }
            }
        }
        let mut upstream: Vec<Vec<usize>> = vec![Vec::new(); self.nodes.len()];
        for c in &self.connections {
            check("connection input", &c.downstream_input)?;
            check("connection output", &c.upstream_output)?;
            // Connections to nodes the network lacks are reported by resolution.
            if let (Some(&down), Some(&up)) = (index.get(c.downstream_node.as_str()), index.get(c.upstream_node.as_str())) {
                upstream[down].push(up);
            }
        }
        self.check_acyclic_and_shallow(material, &upstream)
    }

    /// Depth-first over the upstream edges, without recursion: a node met again while on the
    /// current path is a cycle; otherwise each node's depth is computed once.
    fn check_acyclic_and_shallow(&self, material: &str, upstream: &[Vec<usize>]) -> Result<(), NetworkError> {
        const NEW: u32 = 0;
        const ON_PATH: u32 = u32::MAX;
        // 0: not visited; ON_PATH: on the current path; otherwise 1 + the depth below it.
        let mut depth = vec![NEW; self.nodes.len()];
        for root in 0..self.nodes.len() {
            if depth[root] != NEW {
                continue;
            }
            let mut stack = vec![(root, 0usize)];
            depth[root] = ON_PATH;
            while let Some(&mut (node, ref mut next)) = stack.last_mut() {
                if let Some(&up) = upstream[node].get(*next) {
                    *next += 1;
                    match depth[up] {
                        ON_PATH => {
                            let start = stack.iter().position(|&(n, _)| n == up).expect("on the path");
                            let mut cycle: Vec<String> = stack[start..].iter().map(|&(n, _)| self.nodes[n].path.clone()).collect();
                            cycle.push(self.nodes[up].path.clone());
                            return Err(NetworkError(format!("{material}: connections form a cycle: {}", cycle.join(" -> "))));
                        }
                        NEW => {
                            depth[up] = ON_PATH;
                            stack.push((up, 0));
                        }
                        _ => {}
                    }
                    continue;
                }
                stack.pop();
                let d = 1 + upstream[node].iter().map(|&u| depth[u] as usize).max().unwrap_or(0);
                if d > MAX_CHAIN_DEPTH {
                    return Err(NetworkError(format!(
                        "{material}: {}: connections chain {d} nodes deep, more than {MAX_CHAIN_DEPTH}",
                        self.nodes[node].path
                    )));
                }
                depth[node] = d as u32;
            }
        }
        Ok(())
    }

    fn node(&self, path: &str) -> Option<&MaterialNode> {
        self.nodes.iter().find(|n| n.path == path)
    }

    /// The node connected to `input` of `node`, if any.
    fn upstream(&self, node: &str, input: &str) -> Option<&MaterialConnection> {
        self.connections.iter().find(|c| c.downstream_node == node && c.downstream_input == input)
    }

    /// Resolves the network into the uber-material, top-down from the surface node:
    /// a `tessera:Layer` evaluates its mask first and then only the sub-materials it shows
    /// (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.2). Unknown nodes, unmapped inputs and connected inputs that
    /// cannot be evaluated yet are reported, never silently dropped.
    pub fn resolve(&self, material_path: &str) -> (Material, ResolveReport) {
        self.resolve_with(material_path, Overrides::default(), true)
    }

    /// [`Self::resolve`] with connected inputs evaluated at a shading point.
    pub(crate) fn resolve_with(&self, material_path: &str, overrides: Overrides, report_unused: bool) -> (Material, ResolveReport) {
        self.resolve_using(material_path, overrides, report_unused, None)
    }

    /// The material node `path` stands for on its own (what its subtree resolves to), with
    /// the authored values.
    pub(crate) fn resolve_subtree(&self, material_path: &str, path: &str) -> Material {
        let mut walk = Walk {
            material_path,
            used: Vec::new(),
            memo: Default::default(),
            fixed: None,
            report: ResolveReport::default(),
            overrides: Overrides::default(),
        };
        self.resolve_node(path, 0, &mut walk)
    }

    /// [`Self::resolve_with`], taking the materials of the nodes in `fixed` as given.
    pub(crate) fn resolve_using(
        &self,
        material_path: &str,
        overrides: Overrides,
        report_unused: bool,
        fixed: Option<&std::collections::HashMap<String, Material>>,
    ) -> (Material, ResolveReport) {
        let mut report = ResolveReport::default();
        if self.node(&self.surface_node).is_none() {
            report.warnings.push(format!("{material_path}: no surface shader; using the UsdPreviewSurface defaults"));
            return (Material::preview_surface_default(), report);
        }
        let mut walk = Walk { material_path, used: vec![self.surface_node.clone()], memo: Default::default(), fixed, report, overrides };
        let m = self.resolve_node(&self.surface_node, 0, &mut walk);
        let Walk { used, mut report, .. } = walk;
        if !report_unused {
            return (m, report);
        }
        for n in &self.nodes {
            if !used.contains(&n.path) && !self.connections.iter().any(|c| c.upstream_node == n.path) {
                report.warnings.push(format!("{}: node '{}' is not connected to the surface and is ignored", n.path, n.node_type_id));
            }
        }
        (m, report)
    }

    fn resolve_node(&self, path: &str, depth: usize, walk: &mut Walk) -> Material {
        if let Some(m) = walk.fixed.and_then(|f| f.get(path)) {
            return m.clone();
        }
        if !walk.memo.is_empty()
            && let Some(m) = walk.memo.get(path)
        {
            return m.clone();
        }
        let m = self.resolve_node_once(path, depth, walk);
        // Only nodes that feed more than one input can be met again: the rest (all of most
        // networks, resolved per shading point when textured) skip the map entirely.
        if self.connections.iter().filter(|c| c.upstream_node == path).nth(1).is_some() {
            walk.memo.insert(path.to_string(), m.clone());
        }
        m
    }

    fn resolve_node_once(&self, path: &str, depth: usize, walk: &mut Walk) -> Material {
        let (material_path, overrides) = (walk.material_path, walk.overrides);
        let Some(node) = self.node(path) else {
            let report = &mut walk.report;
            report.warnings.push(format!("{path}: connected shader is missing from {material_path}; using the UsdPreviewSurface defaults"));
            return Material::preview_surface_default();
        };
        if !walk.used.iter().any(|u| u == path) {
            walk.used.push(path.to_string());
        }
        let id = node.node_type_id.as_str();
        let inputs = Inputs { node, overrides };
        if id == "tessera:Layer" {
            return self.resolve_layer(inputs, depth, walk);
        }
        if id == "tessera:Glitter"
            && let Some(c) = self.upstream(&node.path, "base")
        {
            let glitter = super::native::resolve(inputs, &mut walk.report).expect("tessera:Glitter is declared");
            if depth >= MAX_LAYER_DEPTH {
                walk.report
                    .warnings
                    .push(format!("{}: materials nest deeper than {MAX_LAYER_DEPTH} (a cycle?); 'base' is not followed", node.path));
                return glitter;
            }
            let base = self.resolve_node(&c.upstream_node.clone(), depth + 1, walk);
            return base.under_glitter(&glitter);
        }
        let report = &mut walk.report;
        let m = match id {
            "UsdPreviewSurface" | "tessera:Principled" => super::preview::resolve(inputs, report),
            _ => match super::native::resolve(inputs, report) {
                Some(m) => m,
                None => {
                    report.warnings.push(format!(
                        "{}: shader id '{id}' is not supported yet; rendering {material_path} with UsdPreviewSurface defaults",
                        node.path
                    ));
                    return Material::preview_surface_default();
                }
            },
        };
        for c in self.connections.iter().filter(|c| c.downstream_node == node.path) {
            if overrides.get(&node.path, &c.downstream_input).is_some() || evaluable(self, c) {
                continue;
            }
            let upstream = self.node(&c.upstream_node).map_or("?", |n| n.node_type_id.as_str());
            report.warnings.push(format!(
                "{}: input '{}' is connected to {} ({upstream}); texture and primvar inputs are not supported yet, so its fallback value is used",
                node.path, c.downstream_input, c.upstream_node
            ));
        }
        m
    }

    /// `tessera:Layer`: A over B with one mask (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.2). A sub-material is
    /// evaluated only when the mask shows it.
    fn resolve_layer(&self, node: Inputs, depth: usize, walk: &mut Walk) -> Material {
        let report = &mut walk.report;
        let mask = match node.get("mask") {
            None => 1.0,
            Some(ParamValue::Float(x)) if x.is_finite() => x.clamp(0.0, 1.0),
            Some(v) => {
                report.warnings.push(format!("{}: input 'mask' has the wrong type {v:?}; using 1", node.path));
                1.0
            }
        };
        for (name, _) in node.iter().filter(|(n, _)| !matches!(n.as_str(), "mask" | "a" | "b")) {
            report.warnings.push(format!("{}: unknown tessera:Layer input '{name}'", node.path));
        }
        if let Some(c) = self.upstream(&node.path, "mask").filter(|c| !evaluable(self, c)) {
            report.warnings.push(format!(
                "{}: input 'mask' is connected to {}, which cannot be evaluated; its value {mask} is used",
                node.path, c.upstream_node
            ));
        }
        let side = |input: &str, shown: bool, walk: &mut Walk| -> Material {
            let Some(c) = self.upstream(&node.path, input) else {
                if shown {
                    walk.report
                        .warnings
                        .push(format!("{}: input '{input}' is not connected; using the UsdPreviewSurface defaults", node.path));
                }
                return Material::preview_surface_default();
            };
            if !shown {
                walk.used.push(c.upstream_node.clone());
                return Material::preview_surface_default();
            }
            if depth >= MAX_LAYER_DEPTH {
                walk.report
                    .warnings
                    .push(format!("{}: layers nest deeper than {MAX_LAYER_DEPTH} (a cycle?); '{input}' is not followed", node.path));
                return Material::preview_surface_default();
            }
            self.resolve_node(&c.upstream_node, depth + 1, walk)
        };
        let a = side("a", mask > 0.0, walk);
        let b = side("b", mask < 1.0, walk);
        b.layered_under(&a, mask)
    }
}

/// Largest parameter magnitude accepted: beyond any physical value (emission in nits, IOR,
/// scales), and far enough below f32's 3.4e38 that products of a few parameters stay finite.
const MAX_PARAM_MAGNITUDE: f32 = 1e18;

/// The printed value of a parameter with a NaN, infinite or absurdly large component.
/// What is wrong with a UDIM set's tiles, if anything: each must be one of
/// [`super::desc::UDIM_TILES`], each once, in increasing order.
fn bad_udim_tiles(tiles: &[(u16, String)]) -> Option<String> {
    let range = super::desc::UDIM_TILES;
    if let Some((tile, _)) = tiles.iter().find(|(t, _)| !range.contains(t)) {
        return Some(format!("UDIM tile {tile} is outside {}-{}", range.start(), range.end()));
    }
    tiles
        .windows(2)
        .find(|w| w[0].0 >= w[1].0)
        .map(|w| format!("UDIM tile {} follows tile {} (tiles go once each, in increasing order)", w[1].0, w[0].0))
}

fn non_finite(v: &ParamValue) -> Option<String> {
    let ok = |x: &[f32]| x.iter().all(|c| c.is_finite() && c.abs() <= MAX_PARAM_MAGNITUDE);
    let finite = match v {
        ParamValue::Float(x) => ok(&[*x]),
        ParamValue::Float2(x) => ok(&x.to_array()),
        ParamValue::Float3(x) => ok(&x.to_array()),
        ParamValue::Float4(x) => ok(&x.to_array()),
        _ => true,
    };
    (!finite).then(|| format!("{v:?}"))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::material::preview::tests::preview;
    use glam::Vec3;

    /// A node from (input, value) pairs.
    pub(crate) fn node(path: &str, id: &str, params: &[(&str, ParamValue)]) -> MaterialNode {
        MaterialNode {
            path: path.into(),
            node_type_id: id.into(),
            parameters: params.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
        }
    }

    fn link(down: &str, input: &str, up: &str) -> MaterialConnection {
        MaterialConnection {
            downstream_node: down.into(),
            downstream_input: input.into(),
            upstream_node: up.into(),
            upstream_output: "surface".into(),
        }
    }

    /// Layer(mask) of A over B, where A and B are the given nodes.
    fn layer(mask: f32, a: MaterialNode, b: MaterialNode) -> MaterialNetwork {
        let (pa, pb) = (a.path.clone(), b.path.clone());
        MaterialNetwork {
            nodes: vec![node("/M/L", "tessera:Layer", &[("mask", ParamValue::Float(mask))]), a, b],
            connections: vec![link("/M/L", "a", &pa), link("/M/L", "b", &pb)],
            surface_node: "/M/L".into(),
        }
    }

    #[test]
    fn unknown_shader_is_reported_by_path() {
        let mut n = preview(&[]);
        n.nodes[0].node_type_id = "ND_standard_surface".into();
        let (m, r) = n.resolve("/M");
        assert_eq!(m, Material::preview_surface_default());
        assert!(r.warnings[0].contains("/M/S") && r.warnings[0].contains("ND_standard_surface"));
    }

    /// Dirt over glass: the glass keeps its own IOR and roughness, the dirt's dielectric
    /// parameters stay in the plastic family (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Putting it all together").
    #[test]
    fn layers_blend_within_families_without_contaminating_glass() {
        let dirt = node(
            "/M/Dirt",
            "tessera:SolidDielectric",
            &[
                ("refractiveIndex", ParamValue::Float(1.3)),
                ("roughness", ParamValue::Float(0.9)),
                ("albedo", ParamValue::Float3(Vec3::new(0.3, 0.2, 0.1))),
            ],
        );
        let glass =
            node("/M/Glass", "tessera:Refractive", &[("refractiveIndex", ParamValue::Float(1.8)), ("roughness", ParamValue::Float(0.1))]);
        let (m, r) = layer(0.4, dirt, glass).resolve("/M");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        let u = &m.surface;
        assert!((u.plastic.weight - 0.4).abs() < 1e-6 && (u.glass.weight - 0.6).abs() < 1e-6);
        assert_eq!((u.glass.params.ior, u.glass.params.roughness), (1.8, 0.1));
        assert_eq!(u.plastic.params.diffuse, Vec3::new(0.3, 0.2, 0.1));
        assert!(m.bsdf(true).transmits());
    }

    /// Mask 0 is exactly B and mask 1 exactly A, whatever families each holds: the same lobes
    /// with the same parameters (families at weight 0 may keep the other side's values; they
    /// build nothing).
    #[test]
    fn mask_zero_and_one_give_exactly_one_side() {
        let a = node("/M/A", "tessera:Metal", &[("roughness", ParamValue::Float(0.2))]);
        let b = node("/M/B", "tessera:Refractive", &[("refractiveIndex", ParamValue::Float(1.7))]);
        let alone = |n: &MaterialNode| {
            MaterialNetwork { nodes: vec![n.clone()], connections: vec![], surface_node: n.path.clone() }.resolve("/M").0
        };
        let lobes = |m: &Material| format!("{:?}", m.bsdf(true));
        assert_eq!(lobes(&layer(0.0, a.clone(), b.clone()).resolve("/M").0), lobes(&alone(&b)));
        assert_eq!(lobes(&layer(1.0, a.clone(), b.clone()).resolve("/M").0), lobes(&alone(&a)));
    }

    /// Within one family the parameters interpolate: gold over silver at mask 0.25.
    #[test]
    fn same_family_parameters_interpolate_by_the_mask() {
        let metal = |p: &str, r: f32, c: f32| {
            node(p, "tessera:Metal", &[("roughness", ParamValue::Float(r)), ("reflectivity", ParamValue::Float3(Vec3::splat(c)))])
        };
        let (m, _) = layer(0.25, metal("/M/A", 0.2, 1.0), metal("/M/B", 0.6, 0.5)).resolve("/M");
        let s = m.surface.metal.params;
        assert!((s.roughness - 0.5).abs() < 1e-6 && m.surface.metal.weight == 1.0, "{s:?}");
        match s.fresnel {
            crate::bsdf::SpecularFresnel::Gulbrandsen { r, .. } => assert!((r.x - 0.625).abs() < 1e-6),
            f => panic!("{f:?}"),
        }
    }

    /// Only the shown sub-materials are evaluated: a hidden side's problems are not reported.
    #[test]
    fn a_fully_masked_side_is_not_evaluated() {
        let bad = node("/M/Bad", "ND_unknown", &[]);
        let ok = node("/M/Ok", "tessera:Metal", &[]);
        let (m, r) = layer(1.0, ok.clone(), bad.clone()).resolve("/M");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert_eq!(m.surface.metal.weight, 1.0);
        let (_, r) = layer(0.0, bad.clone(), ok.clone()).resolve("/M");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        let (_, r) = layer(0.5, bad, ok).resolve("/M");
        assert!(r.warnings.iter().any(|w| w.contains("/M/Bad") && w.contains("ND_unknown")));
    }

    #[test]
    fn nested_layers_resolve_and_cycles_are_reported() {
        // (gold over plastic) over glass.
        let mut n =
            layer(0.5, node("/M/Inner", "tessera:Layer", &[("mask", ParamValue::Float(0.5))]), node("/M/Glass", "tessera:Refractive", &[]));
        n.nodes.push(node("/M/Gold", "tessera:Metal", &[]));
        n.nodes.push(node("/M/Plastic", "tessera:SolidDielectric", &[]));
        n.connections.push(link("/M/Inner", "a", "/M/Gold"));
        n.connections.push(link("/M/Inner", "b", "/M/Plastic"));
        let (m, r) = n.resolve("/M");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        let u = &m.surface;
        assert_eq!((u.metal.weight, u.plastic.weight, u.glass.weight), (0.25, 0.25, 0.5));
        // A layer whose input leads back to itself stops with a warning instead of recursing.
        let mut cyclic = layer(0.5, node("/M/X", "tessera:Metal", &[]), node("/M/Y", "tessera:Metal", &[]));
        cyclic.connections[0].upstream_node = "/M/L".into();
        let (_, r) = cyclic.resolve("/M");
        assert!(r.warnings.iter().any(|w| w.contains("nest deeper")), "{:?}", r.warnings);
    }

    #[test]
    fn layered_materials_conserve_energy() {
        use crate::bsdf::testing;
        let white_metal =
            node("/M/A", "tessera:Metal", &[("reflectivity", ParamValue::Float3(Vec3::ONE)), ("roughness", ParamValue::Float(0.7))]);
        let white_plastic = node(
            "/M/B",
            "tessera:SolidDielectric",
            &[("albedo", ParamValue::Float3(Vec3::ONE)), ("clearcoat", ParamValue::Float(1.0)), ("sheen", ParamValue::Float(1.0))],
        );
        let (m, _) = layer(0.5, white_metal, white_plastic).resolve("/M");
        let bsdf = m.bsdf(true);
        for wo in testing::probe_directions() {
            let a = testing::albedo_estimate(&bsdf, wo, 40_000).x;
            assert!(a <= 1.0 + 1e-3 + 0.01, "at {wo:?}: {a}");
        }
        testing::assert_reciprocal(&bsdf);
    }

    /// A UDIM set's tiles are checked: within 1001-1100, each once, in increasing order.
    #[test]
    fn udim_tiles_out_of_range_or_repeated_are_refused() {
        let set = |tiles: &[u16]| {
            let tiles = tiles.iter().map(|&t| (t, "sha256:x".to_string())).collect();
            MaterialNetwork {
                nodes: vec![node("/M/Tex", "UsdUVTexture", &[("file", ParamValue::Udim { tiles, source: "t.<UDIM>.png".into() })])],
                connections: vec![],
                surface_node: "/M/Tex".into(),
            }
            .validate("/M")
        };
        assert!(set(&[1001, 1002, 1100]).is_ok());
        for (tiles, said) in [
            (&[1000][..], "UDIM tile 1000 is outside"),
            (&[1101], "UDIM tile 1101"),
            (&[1002, 1001], "follows tile 1002"),
            (&[1005, 1005], "follows tile 1005"),
        ] {
            let e = set(tiles).expect_err("refused").to_string();
            assert!(e.contains("/M/Tex") && e.contains(said), "{tiles:?}: {e}");
        }
    }
}
