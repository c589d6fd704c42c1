//! Material networks in the shape of Hydra's `HdMaterialNetwork`, and their resolution to
//! a [`Material`].

use std::collections::BTreeMap;

use glam::Vec3;

use super::Material;

/// A parameter value on a node.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    /// A float.
    Float(f32),
    /// A colour or vector.
    Float3(Vec3),
    /// An integer.
    Int(i32),
    /// A boolean.
    Bool(bool),
    /// A string or token.
    String(String),
    /// An asset path, already resolved by the client.
    Asset(String),
}

/// One shader node.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialNode {
    /// The node's USD path.
    pub path: String,
    /// Shader id, e.g. `UsdPreviewSurface`.
    pub node_type_id: String,
    /// Authored input values by input name (without the `inputs:` prefix).
    pub parameters: BTreeMap<String, ParamValue>,
}

/// An edge from an upstream output to a downstream input.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialConnection {
    /// Downstream node path.
    pub downstream_node: String,
    /// Downstream input name.
    pub downstream_input: String,
    /// Upstream node path.
    pub upstream_node: String,
    /// Upstream output name.
    pub upstream_output: String,
}

/// A whole material network.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialNetwork {
    /// Nodes.
    pub nodes: Vec<MaterialNode>,
    /// Connections between node inputs and outputs.
    pub connections: Vec<MaterialConnection>,
    /// Path of the node connected to the material's surface terminal.
    pub surface_node: String,
}

/// What resolution could not honour, each naming the node and input.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ResolveReport {
    /// Human-readable warnings.
    pub warnings: Vec<String>,
}

/// UsdPreviewSurface inputs this slice maps; everything else is reported once.
const PREVIEW_SURFACE_MAPPED: &[&str] = &["diffuseColor", "emissiveColor"];
/// UsdPreviewSurface inputs that are known but not yet mapped to lobes.
const PREVIEW_SURFACE_KNOWN: &[&str] = &[
    "useSpecularWorkflow",
    "specularColor",
    "metallic",
    "roughness",
    "clearcoat",
    "clearcoatRoughness",
    "opacity",
    "opacityMode",
    "opacityThreshold",
    "ior",
    "normal",
    "displacement",
    "occlusion",
];

impl MaterialNetwork {
    fn node(&self, path: &str) -> Option<&MaterialNode> {
        self.nodes.iter().find(|n| n.path == path)
    }

    /// Resolves the network into the uber-material. Unknown nodes, unmapped inputs and
    /// connected inputs the slice cannot evaluate are reported, never silently dropped.
    pub fn resolve(&self, material_path: &str) -> (Material, ResolveReport) {
        let mut report = ResolveReport::default();
        let mut m = Material::default();
        let Some(surface) = self.node(&self.surface_node) else {
            report.warnings.push(format!("{material_path}: no surface shader; using the UsdPreviewSurface defaults"));
            return (m, report);
        };
        if surface.node_type_id != "UsdPreviewSurface" {
            report.warnings.push(format!(
                "{}: shader id '{}' is not supported yet; rendering {material_path} with UsdPreviewSurface defaults",
                surface.path, surface.node_type_id
            ));
            return (m, report);
        }
        for (name, value) in &surface.parameters {
            match (name.as_str(), value) {
                ("diffuseColor", ParamValue::Float3(c)) => m.diffuse = c.clamp(Vec3::ZERO, Vec3::ONE),
                ("emissiveColor", ParamValue::Float3(c)) => m.emission = c.max(Vec3::ZERO),
                (n, _) if PREVIEW_SURFACE_MAPPED.contains(&n) => {
                    report.warnings.push(format!("{}: input '{n}' has the wrong type {value:?}; using its default", surface.path))
                }
                (n, _) if PREVIEW_SURFACE_KNOWN.contains(&n) => {
                    report.warnings.push(format!("{}: input '{n}' is not supported yet and has no effect", surface.path))
                }
                (n, _) => report.warnings.push(format!("{}: unknown UsdPreviewSurface input '{n}'", surface.path)),
            }
        }
        for c in self.connections.iter().filter(|c| c.downstream_node == surface.path) {
            let upstream = self.node(&c.upstream_node).map_or("?", |n| n.node_type_id.as_str());
            report.warnings.push(format!(
                "{}: input '{}' is connected to {} ({upstream}); texture and primvar inputs are not supported yet, so its fallback value is used",
                surface.path, c.downstream_input, c.upstream_node
            ));
        }
        for n in &self.nodes {
            if n.path != surface.path && !self.connections.iter().any(|c| c.upstream_node == n.path) {
                report.warnings.push(format!("{}: node '{}' is not connected to the surface and is ignored", n.path, n.node_type_id));
            }
        }
        (m, report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn preview(params: &[(&str, ParamValue)]) -> MaterialNetwork {
        MaterialNetwork {
            nodes: vec![MaterialNode {
                path: "/M/S".into(),
                node_type_id: "UsdPreviewSurface".into(),
                parameters: params.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
            }],
            connections: vec![],
            surface_node: "/M/S".into(),
        }
    }

    #[test]
    fn maps_diffuse_and_emission_and_reports_the_rest() {
        let (m, r) = preview(&[
            ("diffuseColor", ParamValue::Float3(Vec3::new(0.5, 2.0, -1.0))),
            ("emissiveColor", ParamValue::Float3(Vec3::splat(3.0))),
            ("metallic", ParamValue::Float(1.0)),
            ("bogus", ParamValue::Float(1.0)),
        ])
        .resolve("/M");
        assert_eq!(m.diffuse, Vec3::new(0.5, 1.0, 0.0));
        assert_eq!(m.emission, Vec3::splat(3.0));
        assert!(r.warnings.iter().any(|w| w.contains("'metallic'") && w.contains("/M/S")));
        assert!(r.warnings.iter().any(|w| w.contains("unknown UsdPreviewSurface input 'bogus'")));
    }

    #[test]
    fn unknown_shader_is_reported_by_path() {
        let mut n = preview(&[]);
        n.nodes[0].node_type_id = "ND_standard_surface".into();
        let (m, r) = n.resolve("/M");
        assert_eq!(m, Material::default());
        assert!(r.warnings[0].contains("/M/S") && r.warnings[0].contains("ND_standard_surface"));
    }
}
