//! Reading a USD stage (`.usda`, `.usdc`, `.usdz`) with the `openusd` crate and translating
//! it into render-core's scene description.
//!
//! openusd's stage is `Rc`-based, so the whole read happens on one thread and only our own
//! `Send` structs leave this module. openusd does not synthesise schema fallbacks: an
//! unauthored attribute reads as `None`, and the UsdLux / UsdGeom defaults below are the
//! schema's documented ones.

mod mesh;
mod values;

use std::collections::HashMap;
use std::sync::Arc;

use anyhow::{Context, Result};
use glam::{Affine3A, DMat4, Mat4, Vec3};
use openusd::schemas::geom::{Imageable, Purpose, Visibility, Xformable};
use openusd::schemas::shade::{Material, MaterialBindingAPI};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, PrimPredicate, SchemaBase, SchemaKind, Stage};
use render_core::camera::CameraDesc;
use render_core::light::{LightDesc, LightKind};
use render_core::material::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};
use render_core::scene::{MeshDesc, SceneDesc};

pub use mesh::{MeshSource, triangulate};

/// A stage translated into what the renderer consumes, plus what it could not render.
#[derive(Clone, Debug, Default)]
pub struct Translation {
    /// Meshes by prim path.
    pub meshes: Vec<(String, MeshDesc)>,
    /// Material networks by material path.
    pub materials: Vec<(String, MaterialNetwork)>,
    /// Lights by prim path.
    pub lights: Vec<(String, LightDesc)>,
    /// Cameras by prim path.
    pub cameras: Vec<(String, CameraDesc)>,
    /// Things the user should know, each naming a prim.
    pub warnings: Vec<String>,
    /// Prims that exist but are not rendered (unsupported types), by path.
    pub skipped: Vec<String>,
}

impl Translation {
    /// The scene description, for rendering in-process without the server.
    pub fn to_scene_desc(&self) -> SceneDesc {
        let mut d = SceneDesc::default();
        d.meshes.extend(self.meshes.iter().cloned());
        d.materials.extend(self.materials.iter().cloned());
        d.lights.extend(self.lights.iter().cloned());
        d.cameras.extend(self.cameras.iter().cloned());
        d
    }
}

/// Any prim viewed as `Xformable`, to compose its `xformOp`s whatever its type.
struct AnyXformable(Prim);

impl SchemaBase for AnyXformable {
    const KIND: SchemaKind = SchemaKind::ConcreteTyped;
    fn prim(&self) -> &Prim {
        &self.0
    }
}
impl Imageable for AnyXformable {}
impl Xformable for AnyXformable {}

/// Types that only organise the scene or feed materials: read, never reported as skipped.
const STRUCTURAL: &[&str] = &["", "Xform", "Scope", "Material", "Shader", "NodeGraph", "GeomSubset"];
const LIGHTS: &[&str] = &["SphereLight", "RectLight", "DiskLight", "DistantLight", "DomeLight"];

/// Reads and translates the stage at `path`.
pub fn load(path: &std::path::Path) -> Result<Translation> {
    let _span = tracing::info_span!("usd_load", path = %path.display()).entered();
    let path_str = path.to_str().context("scene path is not valid UTF-8")?;
    if !path.exists() {
        anyhow::bail!("{}: no such file", path.display());
    }
    let stage = Stage::open(path_str).map_err(|e| anyhow::anyhow!("{}: cannot read USD: {e:#}", path.display()))?;
    let time = openusd::usd::TimeCode::new(if stage.has_authored_time_code_range() { stage.start_time_code() } else { 0.0 });
    let mut reader = Reader { stage: &stage, time, world: HashMap::new(), out: Translation::default(), materials_seen: HashMap::new() };
    for e in stage.composition_errors() {
        reader.out.warnings.push(format!("composition: {e}"));
    }
    let mut paths = Vec::new();
    stage
        .traverse(PrimPredicate::DEFAULT_PROXIES, |p| paths.push(p.clone()))
        .map_err(|e| anyhow::anyhow!("{}: traversal failed: {e:#}", path.display()))?;
    for p in paths {
        reader.visit(&p).with_context(|| format!("{}: {}", path.display(), p.as_str()))?;
    }
    Ok(reader.out)
}

struct Reader<'s> {
    stage: &'s Stage,
    /// Time at which time-sampled transforms are read: the stage's start time.
    time: openusd::usd::TimeCode,
    world: HashMap<String, DMat4>,
    out: Translation,
    materials_seen: HashMap<String, ()>,
}

fn get(prim: &Prim, name: &str) -> Result<Option<Value>> {
    prim.attribute(name).get::<Value>().map_err(|e| anyhow::anyhow!("attribute '{name}': {e:#}"))
}

impl Reader<'_> {
    fn visit(&mut self, path: &sdf::Path) -> Result<()> {
        let prim = self.stage.prim(path.clone());
        let type_name = prim.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
        let p = path.as_str().to_string();
        if STRUCTURAL.contains(&type_name.as_str()) {
            return Ok(());
        }
        let view = AnyXformable(prim.clone());
        let purpose = view.compute_purpose()?;
        if matches!(purpose, Purpose::Proxy | Purpose::Guide) {
            return Ok(());
        }
        let visible = view.compute_visibility()? != Visibility::Invisible;
        match type_name.as_str() {
            "Mesh" => self.mesh(&prim, &p, visible),
            "Camera" => self.camera(&prim, &p),
            t if LIGHTS.contains(&t) => self.light(&prim, &p, t, visible),
            other => {
                self.out.warnings.push(format!("{p}: prim type '{other}' is not supported yet and is not rendered"));
                self.out.skipped.push(p);
                Ok(())
            }
        }
    }

    /// Local-to-world, composing parents and honouring `!resetXformStack!`.
    fn world_transform(&mut self, path: &sdf::Path) -> Result<DMat4> {
        if let Some(m) = self.world.get(path.as_str()) {
            return Ok(*m);
        }
        let view = AnyXformable(self.stage.prim(path.clone()));
        let local = values::matrix(&view.local_to_parent_transform(self.time)?);
        let parent = match path.parent() {
            Some(parent) if !view.resets_xform_stack()? && parent.as_str() != "/" && !parent.as_str().is_empty() => {
                self.world_transform(&parent)?
            }
            _ => DMat4::IDENTITY,
        };
        let m = parent * local;
        self.world.insert(path.as_str().to_string(), m);
        Ok(m)
    }

    fn affine(&mut self, prim: &Prim, p: &str) -> Result<Affine3A> {
        let m = self.world_transform(prim.path())?;
        let m = Mat4::from_cols_array(&m.to_cols_array().map(|x| x as f32));
        let a = Affine3A::from_mat4(m);
        if !a.is_finite() {
            anyhow::bail!("{p}: xformOps compose to a non-finite transform");
        }
        Ok(a)
    }

    fn mesh(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let req = |name: &str| -> Result<Value> { get(prim, name)?.with_context(|| format!("{p}: attribute '{name}' is missing")) };
        let points = req("points")?;
        let points = values::vec3_array(&points)
            .with_context(|| format!("{p}: attribute 'points' has type {}, expected point3f[]", values::type_of(&points)))?;
        if let Some((i, v)) = points.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            anyhow::bail!("{p}: attribute 'points': point {i} is {v} (NaN or Inf)");
        }
        let counts = req("faceVertexCounts")?;
        let counts = values::int_array(&counts).with_context(|| format!("{p}: attribute 'faceVertexCounts' is not an int array"))?;
        let indices = req("faceVertexIndices")?;
        let indices = values::int_array(&indices).with_context(|| format!("{p}: attribute 'faceVertexIndices' is not an int array"))?;
        let normals = self.normals(prim, p)?;
        let left_handed = get(prim, "orientation")?.as_ref().and_then(values::token).is_some_and(|t| t == "leftHanded");
        // UsdGeomMesh's default subdivisionScheme is catmullClark: smooth normals stand in for the limit surface.
        let smooth = get(prim, "subdivisionScheme")?.as_ref().and_then(values::token).is_none_or(|s| s != "none");
        let src = MeshSource { points, counts, indices, normals, left_handed, smooth };
        let mut warnings = Vec::new();
        let mesh = triangulate(&src, |w| warnings.push(format!("{p}: {w}"))).map_err(|e| anyhow::anyhow!("{p}: {e}"))?;
        self.out.warnings.extend(warnings);
        let transform = self.affine(prim, p)?;
        let material = self.bound_material(prim)?.unwrap_or_default();
        if !material.is_empty() {
            self.material(&material)?;
        }
        self.out.meshes.push((p.to_string(), MeshDesc { mesh: Arc::new(mesh), transform, material, visible }));
        Ok(())
    }

    fn normals(&self, prim: &Prim, p: &str) -> Result<Option<(Vec<Vec3>, String)>> {
        let interp = |name: &str, default: &str| -> String {
            prim.attribute(name)
                .get_metadata::<openusd::tf::Token>("interpolation")
                .ok()
                .flatten()
                .map(|t| t.as_str().to_string())
                .unwrap_or_else(|| default.to_string())
        };
        if let Some(v) = get(prim, "primvars:normals")? {
            let n = values::vec3_array(&v).with_context(|| format!("{p}: primvars:normals is not a normal3f[]"))?;
            let n = match get(prim, "primvars:normals:indices")?.as_ref().and_then(values::int_array) {
                Some(idx) => idx.iter().map(|&i| n.get(i as usize).copied().unwrap_or(Vec3::ZERO)).collect(),
                None => n,
            };
            return Ok(Some((n, interp("primvars:normals", "constant"))));
        }
        match get(prim, "normals")? {
            Some(v) => Ok(Some((
                values::vec3_array(&v).with_context(|| format!("{p}: normals is not a normal3f[]"))?,
                interp("normals", "vertex"),
            ))),
            None => Ok(None),
        }
    }

    /// The bound material: the prim's own binding, else the nearest ancestor's (purpose
    /// `full`, falling back to all-purpose).
    fn bound_material(&self, prim: &Prim) -> Result<Option<String>> {
        let mut cur = Some(prim.path().clone());
        while let Some(path) = cur {
            if path.as_str() == "/" || path.as_str().is_empty() {
                break;
            }
            if let Some(api) = MaterialBindingAPI::get(self.stage, path.clone())? {
                if let Some(m) = api.compute_bound_material("full")? {
                    return Ok(Some(m.as_str().to_string()));
                }
            }
            cur = path.parent();
        }
        Ok(None)
    }

    /// Collects the network feeding the material's surface terminal, as Hydra does.
    fn material(&mut self, path: &str) -> Result<()> {
        if self.materials_seen.contains_key(path) {
            return Ok(());
        }
        self.materials_seen.insert(path.to_string(), ());
        let mut network = MaterialNetwork::default();
        let Some(material) = Material::get(self.stage, sdf::path(path)?)? else {
            self.out.warnings.push(format!("{path}: bound material is not a Material prim; the default material is used"));
            return Ok(());
        };
        let Some(surface) = material.compute_surface_source()? else {
            self.out.warnings.push(format!("{path}: material has no surface shader; the default material is used"));
            self.out.materials.push((path.to_string(), network));
            return Ok(());
        };
        network.surface_node = surface.path().as_str().to_string();
        let mut stack = vec![surface.path().clone()];
        let mut seen = std::collections::HashSet::new();
        while let Some(node_path) = stack.pop() {
            if !seen.insert(node_path.as_str().to_string()) {
                continue;
            }
            let prim = self.stage.prim(node_path.clone());
            let id = get(&prim, "info:id")?.as_ref().and_then(values::token).unwrap_or_default();
            let mut node = MaterialNode { path: node_path.as_str().to_string(), node_type_id: id, ..Default::default() };
            for name in prim.property_names()? {
                let Some(input) = name.strip_prefix("inputs:") else {
                    continue;
                };
                let attr = prim.attribute(name.as_str());
                for src in attr.connections()? {
                    let (up_prim, up_output) = (src.prim_path(), src.name().unwrap_or_default().trim_start_matches("outputs:").to_string());
                    network.connections.push(MaterialConnection {
                        downstream_node: node.path.clone(),
                        downstream_input: input.to_string(),
                        upstream_node: up_prim.as_str().to_string(),
                        upstream_output: up_output,
                    });
                    stack.push(up_prim);
                }
                if let Some(v) = attr.get::<Value>()? {
                    match param(&v) {
                        Some(pv) => {
                            node.parameters.insert(input.to_string(), pv);
                        }
                        None => {
                            self.out.warnings.push(format!("{}: input '{input}' has unsupported type {}", node.path, values::type_of(&v)))
                        }
                    }
                }
            }
            network.nodes.push(node);
        }
        self.out.materials.push((path.to_string(), network));
        Ok(())
    }

    fn light(&mut self, prim: &Prim, p: &str, type_name: &str, visible: bool) -> Result<()> {
        // UsdLux inputs; pre-2021 files spell them without the `inputs:` prefix.
        let input = |name: &str| -> Result<Option<Value>> {
            match get(prim, &format!("inputs:{name}"))? {
                Some(v) => Ok(Some(v)),
                None => get(prim, name),
            }
        };
        let float =
            |name: &str, default: f32| -> Result<f32> { Ok(input(name)?.as_ref().and_then(values::scalar).map_or(default, |v| v as f32)) };
        let kind = match type_name {
            "SphereLight" => LightKind::Sphere { radius: float("radius", 0.5)? },
            "RectLight" => LightKind::Rect { width: float("width", 1.0)?, height: float("height", 1.0)? },
            "DiskLight" => LightKind::Disk { radius: float("radius", 0.5)? },
            "DistantLight" => LightKind::Distant { angle_degrees: float("angle", 0.53)? },
            _ => LightKind::Dome,
        };
        if type_name == "RectLight" || type_name == "DomeLight" {
            if input("texture:file")?.is_some() {
                self.out.warnings.push(format!("{p}: inputs:texture:file is not supported yet; the light's constant colour is used"));
            }
        }
        if input("enableColorTemperature")?.as_ref().and_then(values::scalar).unwrap_or(0.0) != 0.0 {
            self.out.warnings.push(format!("{p}: colour temperature is not supported yet and is ignored"));
        }
        let desc = LightDesc {
            kind,
            transform: self.affine(prim, p)?,
            // UsdLux: DistantLight's intensity defaults to 50000, every other light's to 1.
            intensity: float("intensity", if type_name == "DistantLight" { 50000.0 } else { 1.0 })?,
            exposure: float("exposure", 0.0)?,
            color: input("color")?.as_ref().and_then(values::vec3).unwrap_or(Vec3::ONE),
            normalize: input("normalize")?.as_ref().and_then(values::scalar).unwrap_or(0.0) != 0.0,
            visible_to_camera: visible,
        };
        if !visible {
            return Ok(());
        }
        self.out.lights.push((p.to_string(), desc));
        Ok(())
    }

    fn camera(&mut self, prim: &Prim, p: &str) -> Result<()> {
        let d = CameraDesc::default();
        let float = |name: &str, default: f32| -> Result<f32> {
            Ok(get(prim, name)?.as_ref().and_then(values::scalar).map_or(default, |v| v as f32))
        };
        if get(prim, "projection")?.as_ref().and_then(values::token).is_some_and(|t| t == "orthographic") {
            self.out.warnings.push(format!("{p}: orthographic projection is not supported yet; rendering as perspective"));
        }
        let clip = get(prim, "clippingRange")?.as_ref().and_then(values::vec2).unwrap_or([d.near as f64, d.far as f64]);
        let desc = CameraDesc {
            transform: self.affine(prim, p)?,
            focal_length: float("focalLength", d.focal_length)?,
            horizontal_aperture: float("horizontalAperture", d.horizontal_aperture)?,
            vertical_aperture: float("verticalAperture", d.vertical_aperture)?,
            horizontal_aperture_offset: float("horizontalApertureOffset", 0.0)?,
            vertical_aperture_offset: float("verticalApertureOffset", 0.0)?,
            near: clip[0] as f32,
            far: clip[1] as f32,
        };
        self.out.cameras.push((p.to_string(), desc));
        Ok(())
    }
}

fn param(v: &Value) -> Option<ParamValue> {
    Some(match v {
        Value::Float(_) | Value::Double(_) | Value::Half(_) => ParamValue::Float(values::scalar(v)? as f32),
        Value::Int(i) => ParamValue::Int(*i),
        Value::Bool(b) => ParamValue::Bool(*b),
        Value::Token(_) | Value::String(_) => ParamValue::String(values::token(v)?),
        Value::AssetPath(a) => ParamValue::Asset(format!("{a:?}")),
        _ => ParamValue::Float3(values::vec3(v)?),
    })
}
