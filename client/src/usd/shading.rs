//! Shading networks: a bound Material's shaders and connections as a render-core material network, and the texture files it reads.

use anyhow::Result;

use super::*;
use super::{materialx, mtlx_document};

pub(super) fn param(v: &Value) -> Option<ParamValue> {
    Some(match v {
        Value::Float(_) | Value::Double(_) | Value::Half(_) => ParamValue::Float(values::scalar(v)? as f32),
        Value::Int(i) => ParamValue::Int(*i),
        Value::Bool(b) => ParamValue::Bool(*b),
        Value::Token(_) | Value::String(_) => ParamValue::String(values::token(v)?),
        Value::AssetPath(a) => ParamValue::Asset(a.as_str().to_string()),
        Value::Vec2f(_) | Value::Vec2d(_) | Value::Vec2h(_) => {
            let [x, y] = values::vec2(v)?;
            ParamValue::Float2(glam::Vec2::new(x as f32, y as f32))
        }
        Value::Vec4f(_) | Value::Vec4d(_) => ParamValue::Float4(values::vec4(v)?),
        _ => ParamValue::Float3(values::vec3(v)?),
    })
}

/// The bytes of an asset as the stage resolved it: a file, or a member of a `.usdz` package
/// (`scene.usdz[textures/wood.png]`).
pub(super) fn read_asset(a: &openusd::sdf::AssetPath) -> std::io::Result<Vec<u8>> {
    use openusd::ar::Resolver;
    let resolved = a.resolved_path().filter(|r| !r.is_empty()).ok_or_else(|| {
        std::io::Error::new(std::io::ErrorKind::NotFound, "the path does not resolve (no such file next to the layer that authored it)")
    })?;
    let mut asset = openusd::ar::DefaultResolver::new().open_asset(&openusd::ar::ResolvedPath::new(resolved))?;
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut asset, &mut bytes)?;
    Ok(bytes)
}

impl Reader<'_> {
    /// The `varname`s that the materials bound to `prim` (and to its GeomSubsets) read
    /// through nodes of the given ids, in order of first use.
    pub(super) fn reader_varnames(&mut self, prim: &Prim, ids: &[&str]) -> Result<Vec<String>> {
        let mut bound = Vec::new();
        if let Some(m) = self.bound_material(prim)? {
            bound.push(m);
        }
        for child in prim.children()? {
            if child.type_name()?.is_some_and(|t| t.as_str() == "GeomSubset")
                && let Some(m) = self.bound_material(&child)?
            {
                bound.push(m);
            }
        }
        let mut names: Vec<String> = Vec::new();
        for m in &bound {
            self.material(m)?;
            let Some((_, net)) = self.out.materials.iter().find(|(path, _)| path == m) else { continue };
            for n in net.nodes.iter().filter(|n| ids.contains(&n.node_type_id.as_str())) {
                if let Some(ParamValue::String(v)) = n.parameters.get("varname")
                    && !names.contains(v)
                {
                    names.push(v.clone());
                }
            }
        }
        Ok(names)
    }

    /// Collects the network feeding the material's surface terminal, as Hydra does (through
    /// NodeGraphs, which carry no shading of their own).
    pub(super) fn material(&mut self, path: &str) -> Result<()> {
        if self.materials_seen.contains_key(path) {
            return Ok(());
        }
        self.materials_seen.insert(path.to_string(), ());
        let mut network = MaterialNetwork::default();
        let Some(material) = Material::get(self.stage, sdf::path(path)?)? else {
            if !self.material_from_document(path)? {
                self.out.warnings.push(format!("{path}: bound material is not a Material prim; the default material is used"));
            }
            return Ok(());
        };
        if !self.outputs_well_formed(path)? {
            return Ok(());
        }
        let Some(surface) = self.surface_shader(&material)? else {
            // `def Material "M" (references = @m.mtlx@</MaterialX/Materials/M>)`: the
            // document holds the network.
            if self.material_from_document(path)? {
                return Ok(());
            }
            // The empty network goes on: resolving it reports the missing surface, once.
            self.out.materials.push((path.to_string(), network));
            return Ok(());
        };
        let displacement = self.displacement_shader(path, &material, &surface)?;
        network.surface_node = surface.as_str().to_string();
        let mut stack = vec![surface];
        if let Some(d) = displacement {
            network.connections.push(super::materialx::displaced_by(&network.surface_node, d.as_str()));
            stack.push(d);
        }
        let mut seen = std::collections::HashSet::new();
        while let Some(node_path) = stack.pop() {
            if seen.insert(node_path.as_str().to_string()) {
                let node = self.shader_node(&node_path, &mut network.connections, &mut stack)?;
                network.nodes.push(node);
            }
        }
        self.keep_material(path, network);
        Ok(())
    }

    /// Keeps a material's network, MaterialX mapped first; one that cannot be mapped is
    /// left out, and meshes bound to it show their displayColor (geometry.rs asks).
    fn keep_material(&mut self, path: &str, mut network: MaterialNetwork) {
        if materialx::is_materialx(&network) {
            let authored = network.nodes.iter().find(|n| n.path == network.surface_node).map(|n| n.node_type_id.clone());
            self.out.materialx_surfaces.push((path.to_string(), authored.unwrap_or_default()));
            if let Err(e) = materialx::translate(&mut network, &mut self.out.warnings) {
                self.out.warnings.push(format!("{e}; meshes bound to {path} show their displayColor"));
                self.unmappable.insert(path.to_string());
                return;
            }
        }
        self.out.materials.push((path.to_string(), network));
    }

    /// A material prim that references a MaterialX document (`@file.mtlx@</MaterialX/
    /// Materials/Name>`, usdMtlx's form), which the openusd crate cannot compose: read from the
    /// document. False when the prim references none.
    fn material_from_document(&mut self, path: &str) -> Result<bool> {
        let Some((file, target)) = self.mtlx_reference(path)? else { return Ok(false) };
        // Reported here, whatever happens: not again as an arc the crate could not compose.
        self.mtlx_documents.insert(file.display().to_string());
        let fail = |reader: &mut Self, why: String| {
            reader
                .out
                .warnings
                .push(format!("{path}: MaterialX document {}: {why}; meshes bound to it show their displayColor", file.display()));
            reader.unmappable.insert(path.to_string());
        };
        let xml = match std::fs::read_to_string(&file) {
            Ok(x) => x,
            Err(e) => {
                fail(self, e.to_string());
                return Ok(true);
            }
        };
        let dir = file.parent().unwrap_or(std::path::Path::new("."));
        match mtlx_document::read(&xml, &target, dir, path) {
            Ok(doc) => {
                self.out.warnings.extend(doc.unread);
                let mut network = doc.network;
                for (node, input, image) in doc.files {
                    let value = self.texture_file(&node, &input, &image);
                    if let Some(n) = network.nodes.iter_mut().find(|n| n.path == node) {
                        n.parameters.insert(input, value);
                    }
                }
                self.keep_material(path, network);
            }
            Err(e) => fail(self, e),
        }
        Ok(true)
    }

    /// The `.mtlx` file that supplies the material at `path` (resolved against the layer that
    /// authors the reference) and the material's path in the document's namespace. The
    /// reference may sit on the material itself or on an ancestor (`</MaterialX>` referenced
    /// whole, the material bound below it, as the USD-WG's MaterialXTest does).
    pub(super) fn mtlx_reference(&self, path: &str) -> Result<Option<(std::path::PathBuf, String)>> {
        let mut at = sdf::path(path)?;
        loop {
            if let Some((file, target)) = self.mtlx_reference_on(&at)? {
                let below = path.strip_prefix(at.as_str()).unwrap_or("");
                return Ok(Some((file, format!("{target}{below}"))));
            }
            match at.parent() {
                Some(parent) if !parent.as_str().is_empty() && parent != at && parent.as_str() != "/" => at = parent,
                _ => return Ok(None),
            }
        }
    }

    /// A `.mtlx` reference authored on the prim at `at`, in any layer of its prim stack.
    fn mtlx_reference_on(&self, at: &sdf::Path) -> Result<Option<(std::path::PathBuf, String)>> {
        for (layer_id, value) in self.opinions(&self.stage.prim(at.clone()), "references") {
            let Value::ReferenceListOp(op) = value else { continue };
            let items = op.explicit_items.iter().chain(&op.prepended_items).chain(&op.appended_items).chain(&op.added_items);
            if let Some(r) = items.into_iter().find(|r| r.asset_path.ends_with(".mtlx")) {
                let dir = std::path::Path::new(&layer_id).parent().unwrap_or(std::path::Path::new("."));
                return Ok(Some((lexically_normal(&dir.join(&r.asset_path)), r.prim_path.as_str().to_string())));
            }
        }
        Ok(None)
    }

    /// The shader prim behind the material's surface terminal (`outputs:surface`, else the
    /// first render context's `outputs:<context>:surface`), followed through NodeGraph
    /// outputs at any depth.
    fn surface_shader(&mut self, material: &Material) -> Result<Option<sdf::Path>> {
        let prim = self.stage.prim(material.path().clone());
        for terminal in terminals(&prim, "surface")? {
            let Some(target) = prim.attribute(&terminal).connections()?.into_iter().next() else {
                continue;
            };
            return Ok(match self.resolve_source(&target)? {
                Some(Source::Output(shader, _)) => Some(shader),
                _ => None,
            });
        }
        Ok(None)
    }

    /// The displacement shader a displacement terminal leads to, when it is one Tessera reads:
    /// MaterialX's `displacement` (float) under a MaterialX surface, which the MaterialX mapping
    /// folds into the surface's displacement. Any other shader there (a vector displacement, a
    /// renderer's own) is reported. UsdPreviewSurface's own `displacement` needs none of this:
    /// its terminal leads back to the surface.
    fn displacement_shader(&mut self, path: &str, material: &Material, surface: &sdf::Path) -> Result<Option<sdf::Path>> {
        let prim = self.stage.prim(material.path().clone());
        let materialx_surface = self.shader_id(surface)?.starts_with("ND_");
        for terminal in terminals(&prim, "displacement")? {
            for target in prim.attribute(&terminal).connections()? {
                let Some(Source::Output(shader, _)) = self.resolve_source(&target)? else { continue };
                if shader == *surface {
                    continue;
                }
                if materialx_surface && self.shader_id(&shader)? == super::materialx::DISPLACEMENT {
                    return Ok(Some(shader));
                }
                let shader = shader.as_str();
                self.out.warnings.push(format!(
                    "{path}: {terminal} leads to {shader}, a displacement shader Tessera does not read; the surface is not displaced"
                ));
            }
        }
        Ok(None)
    }

    /// A shader prim's `info:id` (empty when it has none).
    fn shader_id(&self, shader: &sdf::Path) -> Result<String> {
        Ok(get(&self.stage.prim(shader.clone()), "info:id", self.time)?.as_ref().and_then(values::token).unwrap_or_default())
    }

    /// Where a connection target leads once NodeGraph (and Material) outputs and interface
    /// inputs are followed, as UsdShadeConnectableAPI resolves them: a shader's output, or
    /// the value authored on the last interface input of the chain. `None` for a chain that
    /// ends on nothing, or is longer than [`MAX_INTERFACE_HOPS`] (a cycle, reported).
    fn resolve_source(&mut self, target: &sdf::Path) -> Result<Option<Source>> {
        let mut target = target.clone();
        for _ in 0..MAX_INTERFACE_HOPS {
            if !well_formed_path(target.as_str()) {
                return Ok(None);
            }
            let property = property_name(&target);
            let prim = self.stage.prim(target.prim_path());
            let interface = prim.type_name()?.is_some_and(|t| t.as_str() == "Material" || t.as_str() == "NodeGraph");
            if !interface {
                return Ok(Some(Source::Output(target.prim_path(), property.trim_start_matches("outputs:").to_string())));
            }
            let attr = prim.attribute(property.as_str());
            match attr.connections()?.into_iter().next() {
                Some(next) => target = next,
                None if property.starts_with("inputs:") => return Ok(Some(Source::Value(attr.get_at::<Value>(self.time)?))),
                None => return Ok(None),
            }
        }
        self.out.warnings.push(format!(
            "{}: the connections through NodeGraphs from here go on for more than {MAX_INTERFACE_HOPS} steps (a cycle?); not followed",
            target.as_str()
        ));
        Ok(None)
    }

    /// The material's outputs are followed by the openusd crate itself: their connections
    /// are checked first (a malformed one sent it into endless recursion, found by fuzzing).
    /// False, with a warning, when one is malformed.
    fn outputs_well_formed(&mut self, path: &str) -> Result<bool> {
        let material_prim = self.stage.prim(sdf::path(path)?);
        for name in material_prim.property_names()? {
            if !name.as_str().starts_with("outputs:") {
                continue;
            }
            for src in material_prim.attribute(name.as_str()).connections()? {
                if !well_formed_path(src.as_str()) {
                    let (name, src) = (name.as_str(), src.as_str());
                    let w = format!("{path}: '{name}' connects to '{src}', which is not a valid path; the default material is used");
                    self.out.warnings.push(w);
                    return Ok(false);
                }
            }
        }
        Ok(true)
    }

    /// One shader node: its authored inputs as parameters, its connected inputs as
    /// connections (their upstream nodes pushed on `stack` to be read next).
    fn shader_node(
        &mut self,
        node_path: &sdf::Path,
        connections: &mut Vec<MaterialConnection>,
        stack: &mut Vec<sdf::Path>,
    ) -> Result<MaterialNode> {
        let prim = self.stage.prim(node_path.clone());
        let mut node =
            MaterialNode { path: node_path.as_str().to_string(), node_type_id: self.shader_id(node_path)?, ..Default::default() };
        for name in prim.property_names()? {
            let Some(input) = name.strip_prefix("inputs:") else {
                continue;
            };
            let attr = prim.attribute(name.as_str());
            for src in attr.connections()? {
                if let Some(c) = self.connection(&mut node, input, &src)? {
                    stack.push(sdf::path(&c.upstream_node)?);
                    connections.push(c);
                }
            }
            if node.parameters.contains_key(input) {
                continue; // set through the material interface
            }
            if let Some(v) = attr.get_at::<Value>(self.time)? {
                self.input_value(&mut node, input, &v);
            }
        }
        if node.node_type_id == "UsdUVTexture" {
            self.file_color_space(&prim, &mut node)?;
        } else if node.node_type_id.starts_with("ND_image") || node.node_type_id.starts_with("ND_tiledimage") {
            // MaterialX's own `colorspace` attribute, as the USD form carries it.
            if let Some(name) = prim.attribute("inputs:file").get_metadata::<Value>("colorSpace")?.as_ref().and_then(values::token) {
                node.parameters.insert("colorspace".to_string(), ParamValue::String(name));
            }
        }
        Ok(node)
    }

    /// A texture file's own `colorSpace` metadata (`asset inputs:file = @n.png@ (colorSpace =
    /// "raw")`) decides its decoding where `sourceColorSpace` is left at `auto`, as Hydra reads
    /// it. USD's colour-space names say a transfer function and primaries: linear ones and
    /// `data` read raw, sRGB-encoded ones decode sRGB ([`decoding_of`]; what that leaves out
    /// is a warning).
    fn file_color_space(&mut self, prim: &Prim, node: &mut MaterialNode) -> Result<()> {
        if matches!(node.parameters.get("sourceColorSpace"), Some(ParamValue::String(s)) if s != "auto") {
            return Ok(());
        }
        let declared = match prim.attribute("inputs:file").get_metadata::<Value>("colorSpace")? {
            Some(own) => Some(own),
            None => self.interface_color_space(prim)?,
        };
        let Some(name) = declared.as_ref().and_then(values::token) else { return Ok(()) };
        let Some((space, caveat)) = decoding_of(&name) else {
            self.out
                .warnings
                .push(format!("{}: the file's colorSpace '{name}' is not one USD names; sourceColorSpace auto applies", node.path));
            return Ok(());
        };
        if let Some(caveat) = caveat {
            self.out.warnings.push(format!("{}: the file's colorSpace '{name}' has {caveat}", node.path));
        }
        node.parameters.insert("sourceColorSpace".to_string(), ParamValue::String(space.to_string()));
        Ok(())
    }

    /// The `colorSpace` metadata of the material interface input (on a Material or NodeGraph)
    /// that a texture's `inputs:file` takes its value from: the first found along the chain of
    /// connections, as the asset is declared there.
    fn interface_color_space(&self, prim: &Prim) -> Result<Option<Value>> {
        let mut next = prim.attribute("inputs:file").connections()?.into_iter().next();
        for _ in 0..MAX_INTERFACE_HOPS {
            let Some(target) = next.take().filter(|t| well_formed_path(t.as_str())) else { break };
            let property = property_name(&target);
            let attr = self.stage.prim(target.prim_path()).attribute(property.as_str());
            if let Some(declared) = attr.get_metadata::<Value>("colorSpace")? {
                return Ok(Some(declared));
            }
            next = attr.connections()?.into_iter().next();
        }
        Ok(None)
    }

    /// A connection of `node`'s `input` to `src`: to another shader's output, returned; to the
    /// material's own interface (`inputs:` on the Material or a NodeGraph), that input's
    /// value set on the node; malformed, ignored with a warning.
    fn connection(&mut self, node: &mut MaterialNode, input: &str, src: &sdf::Path) -> Result<Option<MaterialConnection>> {
        if !well_formed_path(src.as_str()) {
            let w = format!(
                "{}: input '{input}' connects to '{}', which is not a valid path; the connection is ignored",
                node.path,
                src.as_str()
            );
            self.out.warnings.push(w);
            return Ok(None);
        }
        match self.resolve_source(src)? {
            Some(Source::Output(up, output)) => {
                return Ok(Some(MaterialConnection {
                    downstream_node: node.path.clone(),
                    downstream_input: input.to_string(),
                    upstream_node: up.as_str().to_string(),
                    upstream_output: output,
                }));
            }
            Some(Source::Value(v)) => {
                if let Some(pv) = v.as_ref().and_then(param) {
                    node.parameters.insert(input.to_string(), pv);
                    return Ok(None);
                }
            }
            None => {}
        }
        self.out.warnings.push(format!(
            "{}: input '{input}' connects to {}, which leads to no shader output or value; its own value is used",
            node.path,
            src.as_str()
        ));
        Ok(None)
    }

    /// An authored input value on `node`: a texture file, or a parameter of a supported type
    /// (others reported by name).
    fn input_value(&mut self, node: &mut MaterialNode, input: &str, v: &Value) {
        if let Value::AssetPath(a) = v {
            let pv = self.texture_param(&node.path, input, a);
            node.parameters.insert(input.to_string(), pv);
            return;
        }
        match param(v) {
            Some(pv) => {
                node.parameters.insert(input.to_string(), pv);
            }
            None => self.out.warnings.push(format!("{}: input '{input}' has unsupported type {}", node.path, values::type_of(v))),
        }
    }

    /// An asset input of a shader: the file's content hash once its bytes are read (and kept
    /// for upload), else the authored path with a warning naming the node and input.
    pub(super) fn texture_param(&mut self, node: &str, input: &str, a: &openusd::sdf::AssetPath) -> ParamValue {
        if a.is_empty() {
            return ParamValue::Asset(String::new());
        }
        if a.as_str().contains(super::udim::UDIM_TOKEN) {
            return self.udim_param(node, input, a);
        }
        if let Some(resolved) = a.resolved_path() {
            self.out.texture_paths.push((format!("{node}.inputs:{input}"), resolved.to_string()));
        }
        self.keep_texture(node, input, a.as_str(), read_asset(a))
    }

    /// An image file a MaterialX document names, read as [`Self::texture_param`] reads assets.
    fn texture_file(&mut self, node: &str, input: &str, file: &std::path::Path) -> ParamValue {
        let source = file.display().to_string();
        if super::udim::names_tiles(&source) {
            return self.udim_tiles(node, input, &source, &source);
        }
        self.keep_texture(node, input, &source, std::fs::read(file))
    }

    /// A texture's bytes kept for upload by content hash, or the failure reported.
    pub(super) fn keep_texture(&mut self, node: &str, input: &str, source: &str, bytes: std::io::Result<Vec<u8>>) -> ParamValue {
        match bytes {
            Ok(bytes) => {
                let hash = tessera_wire::content_hash(&bytes);
                self.out.textures.entry(hash.clone()).or_insert(TextureFile { source: source.to_string(), bytes: Arc::new(bytes) });
                ParamValue::Texture { hash, source: source.to_string() }
            }
            Err(e) => {
                self.out.warnings.push(format!("{node}: input '{input}': cannot read '{source}': {e}"));
                ParamValue::Asset(source.to_string())
            }
        }
    }
}

/// The property a connection `target` names (`inputs:tex` of `/M.inputs:tex`).
fn property_name(target: &sdf::Path) -> String {
    target.as_str().rsplit_once('.').map_or("", |(_, p)| p).to_string()
}

/// The `sourceColorSpace` a USD colour-space name decodes as (`raw`, `sRGB` or `auto`), and
/// what that decoding leaves out, if anything; None for a name USD does not define. The names
/// are the OpenUSD Color User's Guide's canonical ones, the older `raw` and `sRGB`, and
/// MaterialX's `lin_srgb` and `srgb_texture`.
fn decoding_of(name: &str) -> Option<(&'static str, Option<&'static str>)> {
    const PRIMARIES: &str = "primaries other than Rec.709's, read as Rec.709's (not converted)";
    const GAMMA: &str = "a pure gamma curve, decoded with sRGB's (the nearest one here)";
    const BOTH: &str = "a pure gamma curve, decoded with sRGB's, and primaries other than Rec.709's (not converted)";
    let scene = |prefix: &str| name.strip_prefix(prefix).and_then(|n| n.strip_suffix("_scene"));
    Some(match name {
        "raw" | "data" | "identity" | "lin_srgb" | "lin_rec709_scene" => ("raw", None),
        "sRGB" | "srgb_texture" | "srgb_rec709_scene" => ("sRGB", None),
        "auto" | "unknown" => ("auto", None),
        _ if scene("lin_").is_some() => ("raw", Some(PRIMARIES)),
        _ if scene("srgb_").is_some() => ("sRGB", Some(PRIMARIES)),
        _ => match scene("g22_").or(scene("g18_"))? {
            "rec709" => ("sRGB", Some(GAMMA)),
            _ => ("sRGB", Some(BOTH)),
        },
    })
}

/// `path` without `.` components and with each `..` taking its parent off, as the stage
/// names resolved layers (so a document read matches the arc the crate reports).
fn lexically_normal(path: &std::path::Path) -> std::path::PathBuf {
    let mut out = std::path::PathBuf::new();
    for c in path.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// What a connection leads to after NodeGraph outputs and interface inputs.
enum Source {
    /// A shader prim and the name of its output (without `outputs:`).
    Output(sdf::Path, String),
    /// The value on the interface input that ends the chain (`None` when it has none).
    Value(Option<Value>),
}

/// Longest chain of NodeGraph outputs and interface inputs followed from one connection.
const MAX_INTERFACE_HOPS: usize = 64;

/// The material's terminals of one kind (`surface`, `displacement`): the universal
/// `outputs:<kind>` first, then render contexts' `outputs:<context>:<kind>` in name order (as
/// the openusd crate's compute_surface_source picks them).
fn terminals(prim: &openusd::usd::Prim, kind: &str) -> Result<Vec<String>> {
    let universal = format!("outputs:{kind}");
    let mut names: Vec<String> = prim
        .property_names()?
        .into_iter()
        .map(|n| n.as_str().to_string())
        .filter(|n| n.strip_prefix("outputs:").and_then(|r| r.strip_suffix(kind)).is_some_and(|ctx| ctx.is_empty() || ctx.ends_with(':')))
        .collect();
    names.sort_by_key(|n| (*n != universal, n.clone()));
    Ok(names)
}
