//! MaterialX documents (`.mtlx`) that USD references as materials
//! (`references = @chess.mtlx@</MaterialX/Materials/M_Board>`, as usdMtlx composes them): a
//! `surfacematerial` and the nodes and node graphs behind its surface shader, read with
//! `roxmltree` into the same UsdShade-form network a Material prim gives (node ids
//! `ND_<category>_<type>`), which [`super::materialx`] then maps.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3, Vec4};
use render_core::material::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};

/// Most nodes read from one material (a guard against generated or hostile documents).
const MAX_NODES: usize = 4096;

/// A material read from a document, with the image files its nodes name.
pub struct DocumentMaterial {
    pub network: MaterialNetwork,
    /// (node path, input, file path resolved against the document's folder).
    pub files: Vec<(String, String, PathBuf)>,
    /// What the material asks for that is not read (a displacement shader).
    pub unread: Vec<String>,
}

/// Reads `material` (a `surfacematerial` name, or usdMtlx's `/MaterialX/Materials/<name>`)
/// from the document text `xml` in folder `dir`. Nodes are named under `prim` (the USD prim
/// that references the document), so messages name them as USD would.
pub fn read(xml: &str, material: &str, dir: &Path, prim: &str) -> Result<DocumentMaterial, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("not a MaterialX document: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "materialx" {
        return Err(format!("the root element is <{}>, not <materialx>", root.tag_name().name()));
    }
    let name = material.rsplit('/').next().unwrap_or(material);
    let materials: Vec<_> = root.children().filter(|n| n.tag_name().name() == "surfacematerial").collect();
    let found = materials
        .iter()
        .find(|m| m.attribute("name") == Some(name))
        .or(if materials.len() == 1 { materials.first() } else { None })
        .ok_or_else(|| format!("no surfacematerial named '{name}' (it has {})", names(&materials)))?;
    let shader = input_of(*found, "surfaceshader")
        .and_then(|i| i.attribute("nodename"))
        .ok_or_else(|| format!("surfacematerial '{name}' has no surfaceshader input connected to a node"))?;
    let mut reader = Reader { dir, prim, network: MaterialNetwork::default(), files: Vec::new(), seen: Vec::new() };
    let surface = reader.node(root, shader)?;
    reader.network.surface_node = surface;
    let mut unread = Vec::new();
    if let Some(d) = input_of(*found, "displacementshader").and_then(|i| i.attribute("nodename")) {
        let shader = reader.node(root, d)?;
        if reader.network.nodes.iter().any(|n| n.path == shader && n.node_type_id == super::materialx::DISPLACEMENT) {
            let surface = reader.network.surface_node.clone();
            reader.network.connections.push(super::materialx::displaced_by(&surface, &shader));
        } else {
            unread.push(format!(
                "{prim}: the displacement shader '{d}' of surfacematerial '{name}' is not read; the surface is not displaced"
            ));
        }
    }
    Ok(DocumentMaterial { network: reader.network, files: reader.files, unread })
}

fn names(nodes: &[roxmltree::Node]) -> String {
    let n: Vec<&str> = nodes.iter().filter_map(|m| m.attribute("name")).collect();
    if n.is_empty() { "none".into() } else { n.join(", ") }
}

fn input_of<'a, 'i>(node: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    node.children().find(|c| c.tag_name().name() == "input" && c.attribute("name") == Some(name))
}

struct Reader<'p> {
    dir: &'p Path,
    prim: &'p str,
    network: MaterialNetwork,
    files: Vec<(String, String, PathBuf)>,
    /// Nodes read so far, by path (each once, however many inputs use it).
    seen: Vec<String>,
}

impl Reader<'_> {
    /// Reads the node `name` of `scope` (the document or a nodegraph) and everything upstream
    /// of it; returns its path.
    fn node(&mut self, scope: roxmltree::Node, name: &str) -> Result<String, String> {
        let element = scope
            .children()
            .find(|c| c.is_element() && c.attribute("name") == Some(name) && !matches!(c.tag_name().name(), "input" | "output"))
            .ok_or_else(|| format!("no node named '{name}' in {}", scope_name(scope)))?;
        let path = format!("{}/{}", self.scope_path(scope), name);
        if self.seen.contains(&path) {
            return Ok(path);
        }
        if self.seen.len() >= MAX_NODES {
            return Err(format!("more than {MAX_NODES} nodes behind one material"));
        }
        self.seen.push(path.clone());
        let category = element.tag_name().name();
        let kind = match category {
            // Its node definitions are named by the displacement's type (ND_displacement_float,
            // ND_displacement_vector3), not by the shader type every one of them outputs.
            "displacement" => input_of(element, "displacement").and_then(|i| i.attribute("type")).unwrap_or("float"),
            _ => element.attribute("type").unwrap_or(""),
        };
        let mut node = MaterialNode { path: path.clone(), node_type_id: format!("ND_{category}_{kind}"), parameters: BTreeMap::new() };
        for input in element.children().filter(|c| c.tag_name().name() == "input") {
            if let Some(name) = input.attribute("name") {
                self.input(scope, &mut node, name, input)?;
            }
        }
        self.network.nodes.push(node);
        Ok(path)
    }

    /// One `<input>`: a connection (`nodename`, `nodegraph` + `output`, a node graph's
    /// `interfacename`) or a value.
    fn input(&mut self, scope: roxmltree::Node, node: &mut MaterialNode, name: &str, input: roxmltree::Node) -> Result<(), String> {
        let upstream = if let Some(up) = input.attribute("nodename") {
            Some(self.node(scope, up)?)
        } else if let Some(graph) = input.attribute("nodegraph") {
            Some(self.graph_output(scope, graph, input.attribute("output").unwrap_or("out"))?)
        } else if let Some(interface) = input.attribute("interfacename") {
            // The node graph's own input of that name: its value or its connection.
            let Some(outer) = input_of(scope, interface) else { return Ok(()) };
            let parent = scope.parent_element().unwrap_or(scope);
            return self.input(parent, node, name, outer);
        } else {
            None
        };
        if let Some(upstream) = upstream {
            self.network.connections.push(MaterialConnection {
                downstream_node: node.path.clone(),
                downstream_input: name.to_string(),
                upstream_node: upstream,
                upstream_output: input.attribute("output").unwrap_or("out").to_string(),
            });
            return Ok(());
        }
        let (Some(kind), Some(value)) = (input.attribute("type"), input.attribute("value")) else { return Ok(()) };
        if kind == "filename" {
            let prefix = inherited(input, "fileprefix").unwrap_or_default();
            self.files.push((node.path.clone(), name.to_string(), self.dir.join(format!("{prefix}{value}"))));
            // The file's colour space: on the input, else the nearest ancestor that says.
            if let Some(space) = inherited(input, "colorspace") {
                node.parameters.insert("colorspace".to_string(), ParamValue::String(space));
            }
            return Ok(());
        }
        if let Some(v) = parse_value(kind, value) {
            node.parameters.insert(name.to_string(), v);
        }
        Ok(())
    }

    /// The node behind output `output` of node graph `graph`.
    fn graph_output(&mut self, scope: roxmltree::Node, graph: &str, output: &str) -> Result<String, String> {
        let ng = scope
            .children()
            .find(|c| c.tag_name().name() == "nodegraph" && c.attribute("name") == Some(graph))
            .ok_or_else(|| format!("no nodegraph named '{graph}'"))?;
        let out = ng
            .children()
            .find(|c| c.tag_name().name() == "output" && c.attribute("name") == Some(output))
            .and_then(|o| o.attribute("nodename"))
            .ok_or_else(|| format!("nodegraph '{graph}' has no output '{output}' connected to a node"))?;
        self.node(ng, out)
    }

    fn scope_path(&self, scope: roxmltree::Node) -> String {
        match scope.tag_name().name() {
            "nodegraph" => format!("{}/{}", self.prim, scope.attribute("name").unwrap_or("nodegraph")),
            _ => self.prim.to_string(),
        }
    }
}

fn scope_name(scope: roxmltree::Node) -> String {
    match scope.attribute("name") {
        Some(n) => format!("nodegraph '{n}'"),
        None => "the document".into(),
    }
}

/// An attribute on the element or its nearest ancestor that has it (MaterialX scoping).
fn inherited(node: roxmltree::Node, attribute: &str) -> Option<String> {
    node.ancestors().find_map(|a| a.attribute(attribute)).map(str::to_string)
}

/// A MaterialX value string of `kind`.
fn parse_value(kind: &str, value: &str) -> Option<ParamValue> {
    let floats: Vec<f32> = value.split(',').map(|s| s.trim().parse::<f32>()).collect::<Result<_, _>>().ok().unwrap_or_default();
    Some(match (kind, floats.as_slice()) {
        ("float", [x]) => ParamValue::Float(*x),
        ("integer", _) => ParamValue::Int(value.trim().parse().ok()?),
        ("boolean", _) => ParamValue::Bool(value.trim() == "true"),
        ("vector2", [x, y]) => ParamValue::Float2(Vec2::new(*x, *y)),
        ("color3" | "vector3", [x, y, z]) => ParamValue::Float3(Vec3::new(*x, *y, *z)),
        ("color4" | "vector4", [x, y, z, w]) => ParamValue::Float4(Vec4::new(*x, *y, *z, *w)),
        ("string", _) => ParamValue::String(value.to_string()),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = r#"<?xml version="1.0"?>
<materialx version="1.39" fileprefix="maps/" colorspace="lin_rec709">
  <nodegraph name="NG">
    <input name="tint" type="color3" value="0.9, 0.9, 0.9"/>
    <image name="tex" type="color3">
      <input name="file" type="filename" value="checker.png" colorspace="srgb_texture"/>
    </image>
    <multiply name="tinted" type="color3">
      <input name="in1" type="color3" nodename="tex"/>
      <input name="in2" type="color3" interfacename="tint"/>
    </multiply>
    <output name="out" type="color3" nodename="tinted"/>
  </nodegraph>
  <open_pbr_surface name="SR" type="surfaceshader">
    <input name="base_color" type="color3" nodegraph="NG" output="out"/>
    <input name="specular_roughness" type="float" value="0.4"/>
  </open_pbr_surface>
  <surfacematerial name="Board" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR"/>
  </surfacematerial>
  <surfacematerial name="Other" type="material"/>
</materialx>"#;

    #[test]
    fn a_surfacematerial_reads_as_a_usd_shade_network() {
        let m = read(DOC, "/MaterialX/Materials/Board", Path::new("/assets"), "/World/Looks/Board").unwrap();
        let net = &m.network;
        assert_eq!(net.surface_node, "/World/Looks/Board/SR");
        let id = |p: &str| net.nodes.iter().find(|n| n.path == p).map(|n| n.node_type_id.as_str());
        assert_eq!(id("/World/Looks/Board/SR"), Some("ND_open_pbr_surface_surfaceshader"));
        assert_eq!(id("/World/Looks/Board/NG/tinted"), Some("ND_multiply_color3"));
        let tinted = net.nodes.iter().find(|n| n.path.ends_with("tinted")).unwrap();
        assert_eq!(tinted.parameters.get("in2"), Some(&ParamValue::Float3(Vec3::splat(0.9))), "the interface value");
        assert!(net.connections.iter().any(|c| c.downstream_input == "base_color" && c.upstream_node.ends_with("NG/tinted")));
        let tex = net.nodes.iter().find(|n| n.path.ends_with("/tex")).unwrap();
        assert_eq!(
            tex.parameters.get("colorspace"),
            Some(&ParamValue::String("srgb_texture".into())),
            "the input's own, not the document's"
        );
        assert_eq!(m.files, vec![("/World/Looks/Board/NG/tex".to_string(), "file".to_string(), PathBuf::from("/assets/maps/checker.png"))]);
    }

    #[test]
    fn bad_documents_are_errors_naming_what_is_missing() {
        let e = |xml: &str, name: &str| read(xml, name, Path::new("."), "/M").err().unwrap();
        assert!(e(DOC, "Nope").contains("no surfacematerial named 'Nope'"));
        assert!(e(DOC, "Other").contains("no surfaceshader input"));
        assert!(
            e(
                "<materialx><surfacematerial name=\"A\"><input name=\"surfaceshader\" nodename=\"ghost\"/></surfacematerial></materialx>",
                "A"
            )
            .contains("no node named 'ghost'")
        );
        assert!(e("<usd/>", "A").contains("not <materialx>"));
        assert!(e("<materialx", "A").contains("not a MaterialX document"));
    }

    #[test]
    fn a_cycle_of_nodes_is_read_once_each() {
        let xml = r#"<materialx>
  <add name="a" type="float"><input name="in1" type="float" nodename="b"/></add>
  <add name="b" type="float"><input name="in1" type="float" nodename="a"/></add>
  <standard_surface name="S" type="surfaceshader"><input name="base" type="float" nodename="a"/></standard_surface>
  <surfacematerial name="M"><input name="surfaceshader" nodename="S"/></surfacematerial>
</materialx>"#;
        let m = read(xml, "M", Path::new("."), "/M").unwrap();
        assert_eq!(m.network.nodes.len(), 3);
    }

    #[test]
    fn a_float_displacement_shader_is_handed_to_the_surface_and_a_vector_one_reported() {
        let doc = |kind: &str| {
            format!(
                r#"<materialx>
  <standard_surface name="S" type="surfaceshader"/>
  <displacement name="D" type="displacementshader"><input name="displacement" type="{kind}" value="0.5"/></displacement>
  <surfacematerial name="M"><input name="surfaceshader" nodename="S"/><input name="displacementshader" nodename="D"/></surfacematerial>
</materialx>"#
            )
        };
        let m = read(&doc("float"), "M", Path::new("."), "/World/M").unwrap();
        assert!(m.unread.is_empty(), "{:?}", m.unread);
        let d = m.network.nodes.iter().find(|n| n.path.ends_with("/D")).expect("the displacement node is read");
        assert_eq!(d.node_type_id, "ND_displacement_float");
        let c = m.network.connections.iter().find(|c| c.downstream_input == "displacement").expect("handed to the surface");
        assert_eq!((c.downstream_node.as_str(), c.upstream_node.as_str()), (m.network.surface_node.as_str(), d.path.as_str()));
        let v = read(&doc("vector3"), "M", Path::new("."), "/World/M").unwrap();
        assert_eq!(v.unread.len(), 1);
        assert!(v.unread[0].contains("/World/M") && v.unread[0].contains("'D'") && v.unread[0].contains("not displaced"), "{:?}", v.unread);
        let plain = read(DOC, "Board", Path::new("."), "/World/M").unwrap();
        assert!(plain.unread.is_empty());
    }
}
