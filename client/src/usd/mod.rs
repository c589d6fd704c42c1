//! Reading a USD stage (`.usda`, `.usdc`, `.usdz`) with the `openusd` crate and translating
//! it into render-core's scene description.
//!
//! openusd's stage is `Rc`-based, so the whole read happens on one thread and only our own
//! `Send` structs leave this module. openusd does not synthesise schema fallbacks: an
//! unauthored attribute reads as `None`, and the UsdLux / UsdGeom defaults below are the
//! schema's documented ones.

mod lint;
use lint::{well_formed_name, well_formed_path};
mod mesh;
pub mod shapes;
mod values;

use std::collections::HashMap;
use std::sync::Arc;

use anyhow::{Context, Result};
use glam::{Affine3A, DMat4, Mat4, Vec3};
use openusd::schemas::geom::{Imageable, Purpose, Visibility, Xformable};
use openusd::schemas::shade::{Material, MaterialBindingAPI};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, PrimPredicate, SchemaBase, SchemaKind, Stage, TimeCode};
use render_core::camera::CameraDesc;
use render_core::light::{LightDesc, LightKind};
use render_core::material::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};
use render_core::scene::{InstancerDesc, MeshDesc, SceneDesc};

pub use mesh::{MeshSource, select_faces, triangulate, triangulate_with_faces};

/// A stage translated into what the renderer consumes, plus what it could not render.
#[derive(Clone, Debug, Default)]
pub struct Translation {
    /// Meshes by prim path.
    pub meshes: Vec<(String, MeshDesc)>,
    /// Material networks by material path.
    pub materials: Vec<(String, MaterialNetwork)>,
    /// Instancers (one per PointInstancer prototype mesh), by a key naming the instancer.
    pub instancers: Vec<(String, InstancerDesc)>,
    /// Lights by prim path.
    pub lights: Vec<(String, LightDesc)>,
    /// Cameras by prim path.
    pub cameras: Vec<(String, CameraDesc)>,
    /// Things the user should know, each naming a prim.
    pub warnings: Vec<String>,
    /// Prims that exist but are not rendered (unsupported types), by path.
    pub skipped: Vec<String>,
    /// The stage's `upAxis` is Z.
    pub z_up: bool,
    /// The stage's `metersPerUnit` (0.01, centimetres, when not authored, as USD's fallback
    /// says). USD composes without converting units, so geometry, positions and depths are in
    /// these units; the EXR header records them for compositing.
    pub meters_per_unit: f64,
    /// Meshes inside instanceable prims: each renders as an instance of one prototype mesh
    /// (one BLAS per prototype and material), listed here for `inspect`.
    pub native_instances: Vec<NativeInstance>,
    /// Where each texture input resolved: ("<node>.inputs:<input>", resolved path), for
    /// `inspect` (a file path, or `package.usdz[member]`).
    pub texture_paths: Vec<(String, String)>,
    /// Texture files the materials name, by content hash.
    pub textures: std::collections::BTreeMap<String, TextureFile>,
    /// The stage's `UsdRender` settings (the prim `renderSettingsPrimPath` names, else the
    /// first one), which supply defaults the command line overrides.
    pub render_settings: Option<RenderSettingsDesc>,
}

/// A mesh under an instanceable prim (an instance proxy), rendered through an instancer.
#[derive(Clone, Debug)]
pub struct NativeInstance {
    /// The proxy's path, as a flattened stage would name the mesh.
    pub path: String,
    /// Index into [`Translation::instancers`] of the instancer that draws it.
    pub instancer: usize,
    /// World transform.
    pub world: Affine3A,
    /// Bound material.
    pub material: String,
    /// Triangles of the shared mesh.
    pub triangles: usize,
    /// Visible (invisible instances are listed but not drawn).
    pub visible: bool,
}

/// A texture file read by the client, sent to the server once per content.
#[derive(Clone, Debug)]
pub struct TextureFile {
    /// The path as authored, for messages.
    pub source: String,
    /// The encoded file.
    pub bytes: Arc<Vec<u8>>,
}

/// What a `RenderSettings` prim asks for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderSettingsDesc {
    /// The prim's path.
    pub path: String,
    /// Its `camera` relationship's target.
    pub camera: Option<String>,
    /// `resolution`.
    pub resolution: Option<(u32, u32)>,
    /// `pixelAspectRatio`, when authored.
    pub pixel_aspect: Option<f32>,
    /// The `products` it names, in order.
    pub products: Vec<RenderProductDesc>,
}

/// A `UsdRender` `RenderProduct`: an output file and the AOVs (`RenderVar`s) it holds.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderProductDesc {
    /// The prim's path.
    pub path: String,
    /// `productName`: the file to write.
    pub name: Option<String>,
    /// Its own `camera`, overriding the settings'.
    pub camera: Option<String>,
    /// Its own `resolution`, overriding the settings'.
    pub resolution: Option<(u32, u32)>,
    /// Our AOV names for its `orderedVars`' `sourceName`s (beauty is always written).
    pub aovs: Vec<String>,
}

/// The targets of relationship `rel` of `prim` (at `p`); a malformed one is an error naming
/// the relationship (openusd recurses without end on some, see [`well_formed_path`]).
fn valid_targets(prim: &Prim, p: &str, rel: &str) -> Result<Vec<sdf::Path>> {
    let targets = prim.relationship(rel).targets()?;
    if let Some(bad) = targets.iter().find(|t| !well_formed_path(t.as_str())) {
        anyhow::bail!("{p}: relationship '{rel}' targets '{}', which is not a valid path", bad.as_str());
    }
    Ok(targets)
}

/// The first well-formed target of a RenderSettings' or RenderProduct's `camera`.
fn camera_target(prim: &Prim) -> Result<Option<String>> {
    Ok(prim.relationship("camera").targets()?.first().map(|t| t.as_str().to_string()).filter(|t| well_formed_path(t)))
}

/// Tessera's AOV for a `RenderVar` `sourceName` (Hydra's names, and ours).
fn aov_of_source(source: &str) -> Option<&'static str> {
    Some(match source {
        "color" | "Ci" | "beauty" => "beauty",
        "albedo" => "albedo",
        "normal" | "N" => "normal",
        "depth" | "z" | "Z" => "depth",
        "position" | "P" => "position",
        "primId" => "primId",
        "diffuse" => "diffuse",
        "specular" => "specular",
        "transmission" => "transmission",
        "subsurface" => "subsurface",
        "diffuse_direct" => "diffuse_direct",
        "diffuse_indirect" => "diffuse_indirect",
        "specular_direct" => "specular_direct",
        "specular_indirect" => "specular_indirect",
        "transmission_direct" => "transmission_direct",
        "transmission_indirect" => "transmission_indirect",
        "subsurface_direct" => "subsurface_direct",
        "subsurface_indirect" => "subsurface_indirect",
        "emission" => "emission",
        "sampleCount" => "sampleCount",
        "variance" => "variance",
        _ => return None,
    })
}

impl Translation {
    /// Path of the camera a Z-up stage without cameras gets.
    pub const DEFAULT_CAMERA: &'static str = "/TesseraDefaultCamera";

    /// A Z-up stage without cameras: the renderer's default view (from +Z, Y up) would look
    /// down on it, so the client frames it as viewers do, from −Y with Z up, the bounding
    /// sphere filling the default field of view. Returns whether it added one.
    pub fn add_default_camera(&mut self) -> bool {
        if !self.z_up || !self.cameras.is_empty() {
            return false;
        }
        self.add_z_up_camera();
        !self.cameras.is_empty()
    }

    fn add_z_up_camera(&mut self) {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for (_, m) in &self.meshes {
            for p in &m.mesh.positions {
                let w = m.transform.transform_point3(*p);
                (lo, hi) = (lo.min(w), hi.max(w));
            }
        }
        if !(lo.x <= hi.x) {
            return;
        }
        let (center, radius) = (0.5 * (lo + hi), (0.5 * (hi - lo).length()).max(1e-3));
        let d = CameraDesc::default();
        let half = (0.5 * d.vertical_aperture / d.focal_length).atan();
        let dist = radius / half.sin();
        // Camera looks down its local −Z: local +Z points back along −Y, local +Y is world +Z.
        let rotation = glam::Mat3::from_cols(Vec3::X, Vec3::Z, -Vec3::Y);
        let transform = Affine3A::from_mat3_translation(rotation, center - Vec3::Y * dist);
        self.cameras.push((Self::DEFAULT_CAMERA.to_string(), CameraDesc { transform, near: (dist - radius).max(1e-3) * 0.5, ..d }));
    }

    /// Path of the light [`Self::add_default_light`] adds.
    pub const DEFAULT_LIGHT: &'static str = "/TesseraDefaultDome";

    /// Adds a white `DomeLight` of radiance 1 when the stage has no light and no emissive
    /// material, as viewers do (usdview's default lighting): conformance assets and models
    /// exported without lights render lit instead of black. Returns whether it did.
    pub fn add_default_light(&mut self) -> bool {
        let emissive = self.materials.iter().any(|(path, net)| net.resolve(path).0.is_emissive());
        if !self.lights.is_empty() || emissive {
            return false;
        }
        let dome = LightDesc {
            kind: LightKind::Dome,
            transform: Affine3A::IDENTITY,
            intensity: 1.0,
            exposure: 0.0,
            color: Vec3::ONE,
            normalize: false,
            visible_to_camera: true,
            shaping: None,
            diffuse: 1.0,
            specular: 1.0,
            texture: None,
        };
        self.lights.push((Self::DEFAULT_LIGHT.to_string(), dome));
        true
    }

    /// The scene description, for rendering in-process without the server.
    pub fn to_scene_desc(&self) -> SceneDesc {
        let mut d = SceneDesc::default();
        d.meshes.extend(self.meshes.iter().cloned());
        d.instancers.extend(self.instancers.iter().cloned());
        d.materials.extend(self.materials.iter().cloned());
        d.lights.extend(self.lights.iter().cloned());
        d.cameras.extend(self.cameras.iter().cloned());
        for (hash, t) in &self.textures {
            match render_core::texture::Image::decode(&t.bytes, &t.source) {
                Ok(image) => {
                    d.textures.insert(hash.clone(), Arc::new(image));
                }
                // Commit then reports the texture as missing, naming the node.
                Err(e) => tracing::warn!("{e}"),
            }
        }
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
const IMPLICIT: &[&str] = &["Sphere", "Cube", "Cylinder", "Cone", "Capsule", "Plane"];
const LIGHTS: &[&str] = &["SphereLight", "RectLight", "DiskLight", "CylinderLight", "DistantLight", "DomeLight", "DomeLight_1"];

/// Reads and translates the stage at `path` at its default frame.
pub fn load(path: &std::path::Path) -> Result<Translation> {
    load_at(path, None)
}

/// Reads and translates the stage at `path`, evaluating time samples (linearly interpolated)
/// at `frame`, by default the stage's `startTimeCode` when it authors a range, else 0.
pub fn load_at(path: &std::path::Path, frame: Option<f64>) -> Result<Translation> {
    let _span = tracing::info_span!("usd_load", path = %path.display()).entered();
    let path_str = path.to_str().context("scene path is not valid UTF-8")?;
    if !path.exists() {
        anyhow::bail!("{}: no such file", path.display());
    }
    // Text layers are checked for the malformed names and paths the crate cannot survive.
    if let Ok(bytes) = std::fs::read(path)
        && bytes.starts_with(b"#usda")
    {
        lint::check(&String::from_utf8_lossy(&bytes)).map_err(|e| anyhow::anyhow!("{}: cannot read USD: {e}", path.display()))?;
    }
    let stage = Stage::open(path_str).map_err(|e| anyhow::anyhow!("{}: cannot read USD: {e:#}", path.display()))?;
    let default_frame = if stage.has_authored_time_code_range() { stage.start_time_code() } else { 0.0 };
    let time = TimeCode::new(frame.unwrap_or(default_frame));
    let mut reader = Reader {
        stage: &stage,
        time,
        world: HashMap::new(),
        out: Translation::default(),
        materials_seen: HashMap::new(),
        all_paths: Vec::new(),
        instancer_roots: Vec::new(),
        native: HashMap::new(),
        bindings: HashMap::new(),
    };
    // Stage metrics first: DomeLight_1's pole follows the up axis.
    reader.out.z_up = stage.stage_metadata("upAxis").ok().flatten().as_ref().and_then(values::token).is_some_and(|t| t == "Z");
    reader.out.meters_per_unit = stage
        .stage_metadata("metersPerUnit")
        .ok()
        .flatten()
        .as_ref()
        .and_then(values::scalar)
        .filter(|m| m.is_finite() && *m > 0.0)
        .unwrap_or(0.01);
    for e in stage.composition_errors() {
        reader.out.warnings.push(format!("composition: {e}"));
    }
    let mut paths = Vec::new();
    stage
        .traverse(PrimPredicate::DEFAULT_PROXIES, |p| paths.push(p.clone()))
        .map_err(|e| anyhow::anyhow!("{}: traversal failed: {e:#}", path.display()))?;
    reader.all_paths = paths.clone();
    for p in paths {
        reader.visit(&p).with_context(|| format!("{}: {}", path.display(), p.as_str()))?;
    }
    Ok(reader.out)
}

struct Reader<'s> {
    stage: &'s Stage,
    /// Time at which time-sampled transforms are read: the stage's start time.
    time: TimeCode,
    world: HashMap<String, DMat4>,
    out: Translation,
    materials_seen: HashMap<String, ()>,
    /// Every prim path the traversal visits, in order.
    all_paths: Vec<sdf::Path>,
    /// PointInstancers seen so far: prims beneath them render only through them.
    instancer_roots: Vec<String>,
    /// Native instancing: (prototype mesh path, material) → index of its instancer.
    native: HashMap<(String, String), usize>,
    /// Each prim's resolved material binding: a mesh asks for its own and its subsets' several
    /// times (material, texture coordinates, primvars), and a broken binding is reported once.
    bindings: HashMap<String, Option<String>>,
}

/// A double-precision world matrix as the renderer's affine transform.
fn to_affine(m: &DMat4) -> Result<Affine3A> {
    let a = Affine3A::from_mat4(Mat4::from_cols_array(&m.to_cols_array().map(|x| x as f32)));
    if !a.is_finite() {
        anyhow::bail!("the transform is not finite");
    }
    Ok(a)
}

/// The rotation matrix USD makes of an orientation quaternion (GfMatrix4d::SetRotate): the
/// unit-quaternion formula applied to the raw components, without normalising. Half-precision
/// orientations are rarely unit length; normalising them (or going through GfRotation's
/// axis-angle) moved instances by 1e-4 relative to what usd-core computes.
fn usd_rotation(q: glam::DQuat) -> glam::DMat3 {
    let (x2, y2, z2) = (q.x + q.x, q.y + q.y, q.z + q.z);
    let (xx, xy, xz) = (q.x * x2, q.x * y2, q.x * z2);
    let (yy, yz, zz) = (q.y * y2, q.y * z2, q.z * z2);
    let (wx, wy, wz) = (q.w * x2, q.w * y2, q.w * z2);
    glam::DMat3::from_cols(
        glam::DVec3::new(1.0 - (yy + zz), xy + wz, xz - wy),
        glam::DVec3::new(xy - wz, 1.0 - (xx + zz), yz + wx),
        glam::DVec3::new(xz + wy, yz - wx, 1.0 - (xx + yy)),
    )
}

/// True when `path` is `root` or beneath it.
fn under(path: &str, root: &str) -> bool {
    path == root || (path.starts_with(root) && path.as_bytes().get(root.len()) == Some(&b'/'))
}

/// An attribute's value at `time`: its time samples interpolated, else its default.
fn get(prim: &Prim, name: &str, time: TimeCode) -> Result<Option<Value>> {
    prim.attribute(name).get_at::<Value>(time).map_err(|e| anyhow::anyhow!("attribute '{name}': {e:#}"))
}

impl Reader<'_> {
    fn visit(&mut self, path: &sdf::Path) -> Result<()> {
        if !well_formed_path(path.as_str()) {
            self.out.warnings.push(format!("'{}' is not a valid prim path; the prim is skipped", path.as_str()));
            return Ok(());
        }
        let prim = self.stage.prim(path.clone());
        let type_name = prim.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
        let p = path.as_str().to_string();
        if STRUCTURAL.contains(&type_name.as_str()) || self.instancer_roots.iter().any(|r| under(&p, r) && *r != p) {
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
            t if IMPLICIT.contains(&t) => self.implicit(&prim, &p, t, visible),
            "PointInstancer" => self.point_instancer(&prim, &p, visible),
            "RenderSettings" => self.render_settings(&prim, &p),
            // Read through the RenderSettings that names them.
            "RenderProduct" | "RenderVar" => Ok(()),
            "Camera" => self.camera(&prim, &p),
            t if LIGHTS.contains(&t) => self.light(&prim, &p, t, visible),
            // UsdSkel: the meshes under a SkelRoot are ordinary meshes in their rest pose.
            "SkelRoot" => {
                self.out
                    .warnings
                    .push(format!("{p}: skinning (UsdSkel) is not supported yet: the meshes under it render in their rest pose"));
                Ok(())
            }
            "Skeleton" | "SkelAnimation" | "BlendShape" => {
                self.out.skipped.push(p);
                Ok(())
            }
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
        let prim = self.stage.prim(path.clone());
        // The schema looks each op up by name: check the names first (a garbled one sent the
        // openusd crate into an endless loop, found by fuzzing).
        if let Some(order) = get(&prim, "xformOpOrder", self.time)? {
            for op in values::token_array(&order).unwrap_or_default() {
                let name = op.trim_start_matches("!invert!");
                if op != "!resetXformStack!" && !well_formed_name(name) {
                    anyhow::bail!("{path}: attribute 'xformOpOrder' names '{op}', which is not a valid attribute name");
                }
            }
        }
        let view = AnyXformable(prim);
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
        to_affine(&m).with_context(|| format!("{p}: xformOps compose to a non-finite transform"))
    }

    fn mesh(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        if let Some(shared) = prim.prim_in_prototype()?
            && self.native_instance(prim, p, visible, shared.path().as_str())?
        {
            return Ok(());
        }
        let (mesh, face_of, face_count) = self.read_mesh(prim, p)?;
        let subsets = self.material_subsets(prim, p, face_count)?;
        if subsets.is_empty() {
            return self.add_mesh(prim, p, mesh, visible);
        }
        // Faces in a bound GeomSubset render as a mesh of their own (named by the subset's
        // path) with the subset's material; the rest keep the mesh's.
        let mut claimed = vec![false; face_count];
        for (subset, faces) in &subsets {
            let set: std::collections::HashSet<u32> = faces.iter().copied().collect();
            for &f in faces {
                claimed[f as usize] = true;
            }
            let part = select_faces(&mesh, &face_of, |f| set.contains(&f));
            let material = self.bound_material(subset)?;
            let material = match material {
                Some(m) => {
                    self.material(&m)?;
                    Some(m)
                }
                None => None,
            };
            self.add_mesh_with(prim, subset.path().as_str(), part, visible, material)?;
        }
        let rest = select_faces(&mesh, &face_of, |f| !claimed[f as usize]);
        if rest.indices.is_empty() {
            return Ok(());
        }
        self.add_mesh(prim, p, rest, visible)
    }

    /// A mesh inside an instanceable prim (an instance proxy standing for `shared`, a mesh
    /// in the stage's prototype): its geometry is read once per prototype and bound material
    /// and every proxy becomes one more instance of it, so a forest of referenced instanceable
    /// trees costs one BLAS. Proxies with GeomSubsets or without a bound material take the
    /// flat path (returns false).
    fn native_instance(&mut self, prim: &Prim, p: &str, visible: bool, shared: &str) -> Result<bool> {
        for child in prim.children()? {
            if child.type_name()?.is_some_and(|t| t.as_str() == "GeomSubset") {
                return Ok(false);
            }
        }
        let Some(material) = self.bound_material(prim)? else { return Ok(false) };
        // A material inside the instance is one material for every instance: name it by its
        // prim in the prototype.
        let in_prototype = self.stage.prim(sdf::path(&material)?).prim_in_prototype()?;
        let shared_material = in_prototype.map_or_else(|| material.clone(), |m| m.path().as_str().to_string());
        self.material(&shared_material)?;
        let key = (shared.to_string(), shared_material.clone());
        let index = match self.native.get(&key) {
            Some(&i) => i,
            None => {
                let (mesh, _, _) = self.read_mesh(prim, p)?;
                let same_prototype = self.native.keys().filter(|(s, _)| s == shared).count();
                let mesh_path = if same_prototype == 0 { shared.to_string() } else { format!("{shared}[{same_prototype}]") };
                let desc = MeshDesc { mesh: Arc::new(mesh), transform: Affine3A::IDENTITY, material: shared_material, visible: false };
                self.out.meshes.push((mesh_path.clone(), desc));
                self.out
                    .instancers
                    .push((format!("{mesh_path}[instances]"), InstancerDesc { prototype: mesh_path, transforms: Vec::new() }));
                self.native.insert(key.clone(), self.out.instancers.len() - 1);
                self.out.instancers.len() - 1
            }
        };
        let world = self.affine(prim, p)?;
        let prototype = &self.out.instancers[index].1.prototype;
        let triangles = self.out.meshes.iter().find(|(path, _)| path == prototype).map_or(0, |(_, m)| m.mesh.indices.len());
        if visible {
            self.out.instancers[index].1.transforms.push(world);
        }
        self.out.native_instances.push(NativeInstance { path: p.to_string(), instancer: index, world, material, triangles, visible });
        Ok(true)
    }

    /// Reads and triangulates a mesh prim: the mesh, the authored face of each triangle, and
    /// the number of authored faces.
    fn read_mesh(&mut self, prim: &Prim, p: &str) -> Result<(render_core::geometry::Mesh, Vec<u32>, usize)> {
        let time = self.time;
        let req = |name: &str| -> Result<Value> { get(prim, name, time)?.with_context(|| format!("{p}: attribute '{name}' is missing")) };
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
        let left_handed = get(prim, "orientation", time)?.as_ref().and_then(values::token).is_some_and(|t| t == "leftHanded");
        // UsdGeomMesh's default subdivisionScheme is catmullClark: smooth normals stand in for the limit surface.
        let smooth = get(prim, "subdivisionScheme", time)?.as_ref().and_then(values::token).is_none_or(|s| s != "none");
        let face_count = counts.len();
        let uvs = self.uvs(prim, p)?;
        let primvars = self.primvars(prim, p)?;
        let src = MeshSource { points, counts, indices, normals, uvs, primvars, left_handed, smooth };
        let mut warnings = Vec::new();
        let (mesh, face_of) =
            triangulate_with_faces(&src, |w| warnings.push(format!("{p}: {w}"))).map_err(|e| anyhow::anyhow!("{p}: {e}"))?;
        self.out.warnings.extend(warnings);
        Ok((mesh, face_of, face_count))
    }

    /// The mesh's `materialBind` GeomSubsets of faces that carry a material binding, with
    /// their face indices (validated against `face_count`).
    fn material_subsets(&self, prim: &Prim, p: &str, face_count: usize) -> Result<Vec<(Prim, Vec<u32>)>> {
        let time = self.time;
        let mut out = Vec::new();
        for child in prim.children()? {
            if child.type_name()?.is_none_or(|t| t.as_str() != "GeomSubset") {
                continue;
            }
            let c = child.path().as_str().to_string();
            let family = get(&child, "familyName", time)?.as_ref().and_then(values::token).unwrap_or_default();
            let element = get(&child, "elementType", time)?.as_ref().and_then(values::token).unwrap_or_else(|| "face".into());
            if family != "materialBind" || element != "face" {
                continue;
            }
            let indices = match get(&child, "indices", time)? {
                Some(v) => values::int_array(&v).with_context(|| format!("{c}: attribute 'indices' is not an int array"))?,
                None => Vec::new(),
            };
            if let Some((i, &f)) = indices.iter().enumerate().find(|(_, f)| **f < 0 || **f as usize >= face_count) {
                anyhow::bail!("{c}: attribute 'indices': entry {i} is face {f}, but {p} has {face_count} faces");
            }
            if MaterialBindingAPI::get(self.stage, child.path().clone())?.is_none() {
                continue; // an unbound subset keeps the mesh's material
            }
            out.push((child, indices.into_iter().map(|f| f as u32).collect()));
        }
        Ok(out)
    }

    /// Places a triangulated gprim: its world transform and its material (the bound one,
    /// else a preview surface of its `displayColor`, else the renderer's fallback).
    fn add_mesh(&mut self, prim: &Prim, p: &str, mesh: render_core::geometry::Mesh, visible: bool) -> Result<()> {
        let material = match self.bound_material(prim)? {
            Some(m) => {
                self.material(&m)?;
                Some(m)
            }
            None => None,
        };
        self.add_mesh_with(prim, p, mesh, visible, material)
    }

    /// As [`Self::add_mesh`], with the material already resolved (`None`: the gprim's
    /// displayColor, else the fallback).
    fn add_mesh_with(
        &mut self,
        prim: &Prim,
        p: &str,
        mesh: render_core::geometry::Mesh,
        visible: bool,
        material: Option<String>,
    ) -> Result<()> {
        let transform = self.affine(prim, p)?;
        let material = match material {
            Some(m) => m,
            None => self.display_color_material(prim, p)?.unwrap_or_default(),
        };
        self.out.meshes.push((p.to_string(), MeshDesc { mesh: Arc::new(mesh), transform, material, visible }));
        Ok(())
    }

    /// UsdGeom: an unbound gprim shows its `primvars:displayColor` (or the older
    /// `displayColor`). Per-vertex colours are averaged into one, with a warning, until
    /// primvars reach the shading system.
    fn display_color_material(&mut self, prim: &Prim, p: &str) -> Result<Option<String>> {
        let time = self.time;
        let Some(v) = get(prim, "primvars:displayColor", time)?.or(get(prim, "displayColor", time)?) else {
            return Ok(None);
        };
        let colors = values::vec3_array(&v).or_else(|| values::vec3(&v).map(|c| vec![c])).unwrap_or_default();
        if colors.is_empty() || colors.iter().any(|c| !c.is_finite()) {
            self.out.warnings.push(format!("{p}: primvars:displayColor is empty or not finite and is ignored"));
            return Ok(None);
        }
        if colors.len() > 1 {
            self.out.warnings.push(format!("{p}: primvars:displayColor varies over the surface; its average colour is used"));
        }
        let c = colors.iter().copied().sum::<Vec3>() / colors.len() as f32;
        let path = format!("/__displayColor/c{:08x}{:08x}{:08x}", c.x.to_bits(), c.y.to_bits(), c.z.to_bits());
        if !self.materials_seen.contains_key(&path) {
            self.materials_seen.insert(path.clone(), ());
            let shader = format!("{path}/PreviewSurface");
            let mut node = MaterialNode { path: shader.clone(), node_type_id: "UsdPreviewSurface".into(), ..Default::default() };
            node.parameters.insert("diffuseColor".into(), ParamValue::Float3(c.clamp(Vec3::ZERO, Vec3::ONE)));
            self.out.materials.push((path.clone(), MaterialNetwork { nodes: vec![node], connections: Vec::new(), surface_node: shader }));
        }
        Ok(Some(path))
    }

    /// An implicit prim, tessellated with the schema's defaults for unauthored sizes.
    fn implicit(&mut self, prim: &Prim, p: &str, type_name: &str, visible: bool) -> Result<()> {
        let time = self.time;
        let size = |name: &str, default: f64| -> Result<f32> {
            let v = get(prim, name, time)?.as_ref().and_then(values::scalar).unwrap_or(default);
            if !(v.is_finite() && v > 0.0) {
                anyhow::bail!("{p}: attribute '{name}' is {v}; it must be finite and positive");
            }
            Ok(v as f32)
        };
        let axis = match get(prim, "axis", time)?.as_ref().and_then(values::token) {
            None => shapes::Axis::Z,
            Some(t) => shapes::Axis::parse(&t).with_context(|| format!("{p}: attribute 'axis' is '{t}', expected X, Y or Z"))?,
        };
        let shape = match type_name {
            "Sphere" => shapes::Shape::Sphere { radius: size("radius", 1.0)? },
            "Cube" => shapes::Shape::Cube { size: size("size", 2.0)? },
            "Cylinder" => shapes::Shape::Cylinder { radius: size("radius", 1.0)?, height: size("height", 2.0)?, axis },
            "Cone" => shapes::Shape::Cone { radius: size("radius", 1.0)?, height: size("height", 2.0)?, axis },
            "Capsule" => shapes::Shape::Capsule { radius: size("radius", 0.5)?, height: size("height", 1.0)?, axis },
            _ => shapes::Shape::Plane { width: size("width", 2.0)?, length: size("length", 2.0)?, axis },
        };
        self.add_mesh(prim, p, shapes::tessellate(shape), visible)
    }

    /// A `UsdRender` `RenderSettings` prim: kept when it is the one the stage designates
    /// (`renderSettingsPrimPath`) or, without one, the first met.
    fn render_settings(&mut self, prim: &Prim, p: &str) -> Result<()> {
        let designated = self.stage.stage_metadata("renderSettingsPrimPath")?.as_ref().and_then(values::token);
        let chosen = match &designated {
            Some(d) => d == p,
            None => self.out.render_settings.is_none(),
        };
        if !chosen {
            return Ok(());
        }
        let camera = camera_target(prim)?;
        let resolution = self.resolution(prim, p)?;
        let pixel_aspect = match get(prim, "pixelAspectRatio", self.time)?.as_ref().and_then(values::scalar) {
            Some(a) if a.is_finite() && a > 0.0 => Some(a as f32),
            Some(a) => anyhow::bail!("{p}: attribute 'pixelAspectRatio' is {a}; expected a positive number"),
            None => None,
        };
        let mut products = Vec::new();
        for target in valid_targets(prim, p, "products")? {
            let tp = target.as_str().to_string();
            let product = self.stage.prim(target);
            if product.type_name()?.is_none_or(|t| t.as_str() != "RenderProduct") {
                self.out.warnings.push(format!("{p}: products target {tp}, which is not a RenderProduct; ignored"));
                continue;
            }
            products.push(self.render_product(&product, &tp)?);
        }
        if products.len() > 1 {
            self.out.warnings.push(format!(
                "{p}: {} render products; only the first ({}) is written (one EXR per render)",
                products.len(),
                products[0].path
            ));
        }
        self.out.render_settings = Some(RenderSettingsDesc { path: p.to_string(), camera, resolution, pixel_aspect, products });
        Ok(())
    }

    /// `resolution` of a RenderSettings or RenderProduct prim.
    fn resolution(&self, prim: &Prim, p: &str) -> Result<Option<(u32, u32)>> {
        Ok(match get(prim, "resolution", self.time)? {
            Some(Value::Vec2i(r)) if r.x > 0 && r.y > 0 => Some((r.x as u32, r.y as u32)),
            Some(v) => anyhow::bail!("{p}: attribute 'resolution' is {v:?}; expected two positive integers"),
            None => None,
        })
    }

    /// A `RenderProduct`: `productName`, its own camera and resolution, and the AOVs of its
    /// `orderedVars` (a `sourceName` we do not produce is a warning naming the RenderVar).
    fn render_product(&mut self, prim: &Prim, p: &str) -> Result<RenderProductDesc> {
        let name = get(prim, "productName", self.time)?.as_ref().and_then(values::token).filter(|n| !n.is_empty());
        let camera = camera_target(prim)?;
        let resolution = self.resolution(prim, p)?;
        let mut aovs = Vec::new();
        for target in valid_targets(prim, p, "orderedVars")? {
            let vp = target.as_str().to_string();
            let var = self.stage.prim(target);
            let source = get(&var, "sourceName", self.time)?.as_ref().and_then(values::token).unwrap_or_default();
            match aov_of_source(&source) {
                Some("beauty") => {}
                Some(aov) if !aovs.iter().any(|a| a == aov) => aovs.push(aov.to_string()),
                Some(_) => {}
                None => self.out.warnings.push(format!("{vp}: RenderVar sourceName '{source}' is not an AOV Tessera renders; skipped")),
            }
        }
        Ok(RenderProductDesc { path: p.to_string(), name, camera, resolution, aovs })
    }

    /// A `PointInstancer`: each mesh (or implicit prim) of each prototype becomes one
    /// instancer of a shared BLAS, placed by the instancer's world transform, the instance's
    /// translate-orient-scale (UsdGeomPointInstancer's order) and the mesh's transform
    /// relative to its prototype root's parent (the prototype's own xform included, as
    /// USD's default `IncludeProtoXform` does).
    fn point_instancer(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let _span = tracing::debug_span!("point_instancer", path = p).entered();
        self.instancer_roots.push(p.to_string());
        let time = self.time;
        let ints = |name: &str| -> Result<Option<Vec<i64>>> {
            match get(prim, name, time)? {
                None => Ok(None),
                Some(v) => Ok(Some(values::int_array(&v).with_context(|| format!("{p}: attribute '{name}' is not an int array"))?)),
            }
        };
        let prototypes = valid_targets(prim, p, "prototypes")?;
        let proto_indices = ints("protoIndices")?.with_context(|| format!("{p}: attribute 'protoIndices' is missing"))?;
        let n = proto_indices.len();
        let positions = match get(prim, "positions", time)? {
            Some(v) => values::vec3_array(&v).with_context(|| format!("{p}: attribute 'positions' is not a point3f[]"))?,
            None => anyhow::bail!("{p}: attribute 'positions' is missing"),
        };
        let orientations = match get(prim, "orientations", time)?.or(get(prim, "orientationsf", time)?) {
            Some(v) => Some(values::quat_array(&v).with_context(|| format!("{p}: attribute 'orientations' is not a quath[]"))?),
            None => None,
        };
        let scales = match get(prim, "scales", time)? {
            Some(v) => Some(values::vec3_array(&v).with_context(|| format!("{p}: attribute 'scales' is not a float3[]"))?),
            None => None,
        };
        let check = |name: &str, len: usize| -> Result<()> {
            if len != n {
                anyhow::bail!("{p}: attribute '{name}' has {len} entries but protoIndices has {n}");
            }
            Ok(())
        };
        check("positions", positions.len())?;
        if let Some(o) = &orientations {
            check("orientations", o.len())?;
        }
        if let Some(s) = &scales {
            check("scales", s.len())?;
        }
        if let Some((i, &k)) = proto_indices.iter().enumerate().find(|(_, k)| **k < 0 || **k as usize >= prototypes.len()) {
            anyhow::bail!("{p}: attribute 'protoIndices': entry {i} is {k}, but there are {} prototypes", prototypes.len());
        }
        // Instances hidden by id (ids default to the instance index).
        let hidden: std::collections::HashSet<i64> = ints("invisibleIds")?.unwrap_or_default().into_iter().collect();
        let ids = ints("ids")?;
        let instancer_world = self.world_transform(prim.path())?;
        let mut per_proto: Vec<Vec<DMat4>> = vec![Vec::new(); prototypes.len()];
        for i in 0..n {
            let id = ids.as_ref().and_then(|ids| ids.get(i).copied()).unwrap_or(i as i64);
            if hidden.contains(&id) {
                continue;
            }
            let t = positions[i].as_dvec3();
            let r = orientations.as_ref().map_or(glam::DMat3::IDENTITY, |o| usd_rotation(o[i]));
            let s = scales.as_ref().map_or(glam::DVec3::ONE, |s| s[i].as_dvec3());
            if !(t.is_finite() && r.is_finite() && s.is_finite()) {
                anyhow::bail!("{p}: instance {i} has a non-finite position, orientation or scale");
            }
            let trs = DMat4::from_translation(t) * DMat4::from_mat3(r) * DMat4::from_scale(s);
            per_proto[proto_indices[i] as usize].push(instancer_world * trs);
        }
        for (k, proto) in prototypes.iter().enumerate() {
            let root = proto.as_str().to_string();
            let root_parent = match proto.parent() {
                Some(pp) if pp.as_str() != "/" && !pp.as_str().is_empty() => self.world_transform(&pp)?.inverse(),
                _ => DMat4::IDENTITY,
            };
            let members: Vec<sdf::Path> = self.all_paths.iter().filter(|q| under(q.as_str(), &root)).cloned().collect();
            if members.is_empty() {
                anyhow::bail!("{p}: relationship 'prototypes' targets {root}, which is not a prim on the stage");
            }
            for member in members {
                let mprim = self.stage.prim(member.clone());
                let type_name = mprim.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
                if type_name != "Mesh" && !IMPLICIT.contains(&type_name.as_str()) {
                    if !STRUCTURAL.contains(&type_name.as_str()) {
                        self.out
                            .warnings
                            .push(format!("{}: prim type '{type_name}' in a PointInstancer prototype is not rendered", member.as_str()));
                        self.out.skipped.push(member.as_str().to_string());
                    }
                    continue;
                }
                let view = AnyXformable(mprim.clone());
                if matches!(view.compute_purpose()?, Purpose::Proxy | Purpose::Guide) || view.compute_visibility()? == Visibility::Invisible
                {
                    continue;
                }
                // The prototype mesh itself (one per bound GeomSubset too), never drawn directly.
                let before = self.out.meshes.len();
                if type_name == "Mesh" {
                    self.mesh(&mprim, member.as_str(), false)?;
                } else {
                    self.implicit(&mprim, member.as_str(), &type_name, false)?;
                }
                let relative = root_parent * self.world_transform(&member)?;
                let transforms = if visible {
                    per_proto[k]
                        .iter()
                        .map(|m| to_affine(&(*m * relative)))
                        .collect::<Result<Vec<_>>>()
                        .with_context(|| format!("{p}: instances of {root}"))?
                } else {
                    Vec::new()
                };
                for (mesh_key, _) in &mut self.out.meshes[before..] {
                    let part = mesh_key.clone();
                    if !under(&part, p) {
                        *mesh_key = format!("{part}@{p}");
                    }
                    self.out
                        .instancers
                        .push((format!("{p}[{part}]"), InstancerDesc { prototype: mesh_key.clone(), transforms: transforms.clone() }));
                }
            }
        }
        Ok(())
    }

    /// The `varname`s that the materials bound to `prim` (and to its GeomSubsets) read
    /// through nodes of the given ids, in order of first use.
    fn reader_varnames(&mut self, prim: &Prim, ids: &[&str]) -> Result<Vec<String>> {
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

    /// The float, float3 and int primvars the mesh's materials read through
    /// `UsdPrimvarReader_float`, `_float3` and `_int`, de-indexed, with their interpolations.
    /// A primvar the mesh lacks is left out (the readers' fallbacks apply, as USD says); one of
    /// a type no reader can read is a warning.
    fn primvars(&mut self, prim: &Prim, p: &str) -> Result<Vec<(String, Vec<Vec3>, String)>> {
        let names = self.reader_varnames(prim, &["UsdPrimvarReader_float", "UsdPrimvarReader_float3", "UsdPrimvarReader_int"])?;
        let mut out = Vec::new();
        for name in names {
            let attr_name = format!("primvars:{name}");
            let Some(v) = get(prim, &attr_name, self.time)? else { continue };
            let values: Option<Vec<Vec3>> = values::vec3_array(&v)
                .or_else(|| values::float_array(&v).map(|a| a.into_iter().map(|x| Vec3::new(x, 0.0, 0.0)).collect()))
                .or_else(|| values::vec3(&v).map(|x| vec![x]))
                .or_else(|| values::scalar(&v).map(|x| vec![Vec3::new(x as f32, 0.0, 0.0)]));
            let Some(values) = values else {
                self.out.warnings.push(format!(
                    "{p}: {attr_name} has type {}, which no primvar reader reads; readers use their fallbacks",
                    values::type_of(&v)
                ));
                continue;
            };
            let (values, interp) = self.flatten_primvar(prim, p, &attr_name, values)?;
            out.push((name, values, interp));
        }
        Ok(out)
    }

    /// `data` of the primvar `attr_name` de-indexed by its `:indices` (an index out of range
    /// is an error naming the entry), with its interpolation (USD's fallback: constant).
    fn flatten_primvar<T: Copy>(&self, prim: &Prim, p: &str, attr_name: &str, data: Vec<T>) -> Result<(Vec<T>, String)> {
        let data = match get(prim, &format!("{attr_name}:indices"), self.time)?.as_ref().and_then(values::int_array) {
            Some(idx) => {
                if let Some((i, k)) = idx.iter().enumerate().find(|(_, k)| **k < 0 || **k as usize >= data.len()) {
                    anyhow::bail!("{p}: attribute '{attr_name}:indices': entry {i} is {k}, but {attr_name} has {} values", data.len());
                }
                idx.iter().map(|&k| data[k as usize]).collect()
            }
            None => data,
        };
        let interp = prim
            .attribute(attr_name)
            .get_metadata::<openusd::tf::Token>("interpolation")
            .ok()
            .flatten()
            .map(|t| t.as_str().to_string())
            .unwrap_or_else(|| "constant".to_string());
        Ok((data, interp))
    }

    /// The float2 primvar the mesh's materials read through `UsdPrimvarReader_float2`
    /// (`st` when none names one), de-indexed, with its interpolation.
    fn uvs(&mut self, prim: &Prim, p: &str) -> Result<Option<(String, Vec<glam::Vec2>, String)>> {
        let time = self.time;
        let names = self.reader_varnames(prim, &["UsdPrimvarReader_float2"])?;
        if names.len() > 1 {
            self.out.warnings.push(format!(
                "{p}: its materials read several texture coordinate sets ({}); only '{}' is sent",
                names.join(", "),
                names[0]
            ));
        }
        let name = names.into_iter().next().unwrap_or_else(|| "st".to_string());
        let attr_name = format!("primvars:{name}");
        let Some(v) = get(prim, &attr_name, time)? else { return Ok(None) };
        let Some(st) = values::vec2_array(&v) else {
            self.out.warnings.push(format!("{p}: {attr_name} has type {}, not texCoord2f[]; no texture coordinates", values::type_of(&v)));
            return Ok(None);
        };
        let (st, interp) = self.flatten_primvar(prim, p, &attr_name, st)?;
        Ok(Some((attr_name, st, interp)))
    }

    fn normals(&self, prim: &Prim, p: &str) -> Result<Option<(Vec<Vec3>, String)>> {
        let time = self.time;
        let interp = |name: &str, default: &str| -> String {
            prim.attribute(name)
                .get_metadata::<openusd::tf::Token>("interpolation")
                .ok()
                .flatten()
                .map(|t| t.as_str().to_string())
                .unwrap_or_else(|| default.to_string())
        };
        if let Some(v) = get(prim, "primvars:normals", time)? {
            let n = values::vec3_array(&v).with_context(|| format!("{p}: primvars:normals is not a normal3f[]"))?;
            let n = match get(prim, "primvars:normals:indices", time)?.as_ref().and_then(values::int_array) {
                Some(idx) => idx.iter().map(|&i| n.get(i as usize).copied().unwrap_or(Vec3::ZERO)).collect(),
                None => n,
            };
            return Ok(Some((n, interp("primvars:normals", "constant"))));
        }
        match get(prim, "normals", time)? {
            Some(v) => Ok(Some((
                values::vec3_array(&v).with_context(|| format!("{p}: normals is not a normal3f[]"))?,
                interp("normals", "vertex"),
            ))),
            None => Ok(None),
        }
    }

    /// The bound material: the prim's own binding, else the nearest ancestor's (purpose
    /// `full`, falling back to all-purpose).
    fn bound_material(&mut self, prim: &Prim) -> Result<Option<String>> {
        let key = prim.path().as_str().to_string();
        if let Some(m) = self.bindings.get(&key) {
            return Ok(m.clone());
        }
        let m = self.resolve_binding(prim)?;
        self.bindings.insert(key, m.clone());
        Ok(m)
    }

    /// [`Self::bound_material`] without the cache.
    fn resolve_binding(&mut self, prim: &Prim) -> Result<Option<String>> {
        if let Some(m) = self.stronger_ancestor_binding(prim)? {
            return Ok(Some(m));
        }
        let mut cur = Some(prim.path().clone());
        while let Some(path) = cur {
            if path.as_str() == "/" || path.as_str().is_empty() {
                break;
            }
            let here = self.stage.prim(path.clone());
            let mut broken = false;
            for rel in here.relationships()? {
                let name = rel.path().name().unwrap_or_default().to_string();
                if !name.starts_with("material:binding") {
                    continue;
                }
                for t in rel.targets()? {
                    if !well_formed_path(t.as_str()) {
                        self.out.warnings.push(format!(
                            "{path}: relationship '{name}' targets '{}', which is not a valid path; the binding is ignored",
                            t.as_str()
                        ));
                        broken = true;
                    }
                }
            }
            if broken {
                return Ok(None);
            }
            if let Some(api) = MaterialBindingAPI::get(self.stage, path.clone())? {
                if let Some(m) = api.compute_bound_material("full")? {
                    if !well_formed_path(m.as_str()) {
                        self.out
                            .warnings
                            .push(format!("{path}: bound material '{}' is not a valid path; the binding is ignored", m.as_str()));
                        return Ok(None);
                    }
                    return Ok(Some(m.as_str().to_string()));
                }
            }
            cur = path.parent();
        }
        Ok(None)
    }

    /// The binding of the topmost ancestor whose `material:binding` is
    /// `bindMaterialAs = "strongerThanDescendants"`: it overrides every binding beneath it.
    /// openusd 0.6 reads that metadata only when it is a token, while usd-core writes it as a
    /// string, so the strength is read here (through the property's metadata) and the crate's
    /// own walk handles the rest.
    fn stronger_ancestor_binding(&mut self, prim: &Prim) -> Result<Option<String>> {
        let mut ancestors = Vec::new();
        let mut cur = prim.path().parent();
        while let Some(path) = cur {
            if path.as_str() == "/" || path.as_str().is_empty() {
                break;
            }
            cur = path.parent();
            ancestors.push(path);
        }
        for path in ancestors.into_iter().rev() {
            let here = self.stage.prim(path.clone());
            for name in ["material:binding:full", "material:binding"] {
                let strength = here.attribute(name).get_metadata::<Value>("bindMaterialAs").ok().flatten();
                let stronger = strength.as_ref().and_then(values::token).is_some_and(|t| t == "strongerThanDescendants");
                if !stronger {
                    continue;
                }
                if let Some(t) = here.relationship(name).targets()?.into_iter().next()
                    && well_formed_path(t.as_str())
                {
                    return Ok(Some(t.as_str().to_string()));
                }
            }
        }
        Ok(None)
    }

    /// Collects the network feeding the material's surface terminal, as Hydra does.
    fn material(&mut self, path: &str) -> Result<()> {
        let time = self.time;
        if self.materials_seen.contains_key(path) {
            return Ok(());
        }
        self.materials_seen.insert(path.to_string(), ());
        let mut network = MaterialNetwork::default();
        let Some(material) = Material::get(self.stage, sdf::path(path)?)? else {
            self.out.warnings.push(format!("{path}: bound material is not a Material prim; the default material is used"));
            return Ok(());
        };
        // The material's outputs are followed by the openusd crate itself: check their
        // connections first (a malformed one sent it into endless recursion, found by fuzzing).
        let material_prim = self.stage.prim(sdf::path(path)?);
        for name in material_prim.property_names()? {
            if !name.as_str().starts_with("outputs:") {
                continue;
            }
            for src in material_prim.attribute(name.as_str()).connections()? {
                if !well_formed_path(src.as_str()) {
                    self.out.warnings.push(format!(
                        "{path}: '{}' connects to '{}', which is not a valid path; the default material is used",
                        name.as_str(),
                        src.as_str()
                    ));
                    return Ok(());
                }
            }
        }
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
            let id = get(&prim, "info:id", time)?.as_ref().and_then(values::token).unwrap_or_default();
            let mut node = MaterialNode { path: node_path.as_str().to_string(), node_type_id: id, ..Default::default() };
            for name in prim.property_names()? {
                let Some(input) = name.strip_prefix("inputs:") else {
                    continue;
                };
                let attr = prim.attribute(name.as_str());
                for src in attr.connections()? {
                    if !well_formed_path(src.as_str()) {
                        self.out.warnings.push(format!(
                            "{}: input '{input}' connects to '{}', which is not a valid path; the connection is ignored",
                            node.path,
                            src.as_str()
                        ));
                        continue;
                    }
                    // The property part of `/Material/Node.outputs:rgb`.
                    let property = src.as_str().rsplit_once('.').map_or("", |(_, p)| p).to_string();
                    let (up_prim, up_output) = (src.prim_path(), property.trim_start_matches("outputs:").to_string());
                    // A connection to the material's own interface (`inputs:` on the
                    // Material or a NodeGraph) passes that input's value down.
                    let up = self.stage.prim(up_prim.clone());
                    if up.type_name()?.is_some_and(|t| t.as_str() == "Material" || t.as_str() == "NodeGraph")
                        && property.starts_with("inputs:")
                    {
                        match up.attribute(property.as_str()).get_at::<Value>(time)?.as_ref().and_then(param) {
                            Some(pv) => {
                                node.parameters.insert(input.to_string(), pv);
                            }
                            None => self.out.warnings.push(format!(
                                "{}: input '{input}' connects to {}, which has no value; its own value is used",
                                node.path,
                                src.as_str()
                            )),
                        }
                        continue;
                    }
                    network.connections.push(MaterialConnection {
                        downstream_node: node.path.clone(),
                        downstream_input: input.to_string(),
                        upstream_node: up_prim.as_str().to_string(),
                        upstream_output: up_output,
                    });
                    stack.push(up_prim);
                }
                if node.parameters.contains_key(input) {
                    continue; // set through the material interface above
                }
                if let Some(v) = attr.get_at::<Value>(time)? {
                    if let Value::AssetPath(a) = &v {
                        let pv = self.texture_param(&node.path, input, a);
                        node.parameters.insert(input.to_string(), pv);
                        continue;
                    }
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

    /// An asset input of a shader: the file's content hash once its bytes are read (and kept
    /// for upload), else the authored path with a warning naming the node and input.
    fn texture_param(&mut self, node: &str, input: &str, a: &openusd::sdf::AssetPath) -> ParamValue {
        if a.is_empty() {
            return ParamValue::Asset(String::new());
        }
        if let Some(resolved) = a.resolved_path() {
            self.out.texture_paths.push((format!("{node}.inputs:{input}"), resolved.to_string()));
        }
        match read_asset(a) {
            Ok(bytes) => {
                let hash = tessera_wire::content_hash(&bytes);
                self.out.textures.entry(hash.clone()).or_insert(TextureFile { source: a.as_str().to_string(), bytes: Arc::new(bytes) });
                ParamValue::Texture { hash, source: a.as_str().to_string() }
            }
            Err(e) => {
                self.out.warnings.push(format!("{node}: input '{input}': cannot read '{}': {e}", a.as_str()));
                ParamValue::Asset(a.as_str().to_string())
            }
        }
    }

    fn light(&mut self, prim: &Prim, p: &str, type_name: &str, visible: bool) -> Result<()> {
        let time = self.time;
        // UsdLux inputs; pre-2021 files spell them without the `inputs:` prefix.
        let input = |name: &str| -> Result<Option<Value>> {
            match get(prim, &format!("inputs:{name}"), time)? {
                Some(v) => Ok(Some(v)),
                None => get(prim, name, time),
            }
        };
        let float =
            |name: &str, default: f32| -> Result<f32> { Ok(input(name)?.as_ref().and_then(values::scalar).map_or(default, |v| v as f32)) };
        let kind = match type_name {
            "SphereLight" => LightKind::Sphere { radius: float("radius", 0.5)? },
            "RectLight" => LightKind::Rect { width: float("width", 1.0)?, height: float("height", 1.0)? },
            "DiskLight" => LightKind::Disk { radius: float("radius", 0.5)? },
            "CylinderLight" => LightKind::Cylinder { radius: float("radius", 0.5)?, length: float("length", 1.0)? },
            "DistantLight" => LightKind::Distant { angle_degrees: float("angle", 0.53)? },
            _ => LightKind::Dome,
        };
        let mut texture = None;
        match (type_name, input("texture:file")?) {
            ("DomeLight" | "DomeLight_1", Some(Value::AssetPath(a))) if !a.is_empty() => {
                let format = input("texture:format")?.as_ref().and_then(values::token).unwrap_or_else(|| "automatic".into());
                if format != "automatic" && format != "latlong" {
                    self.out.warnings.push(format!(
                        "{p}: texture:format '{format}' is not supported (only latlong); the map is read as latitude-longitude"
                    ));
                }
                if let ParamValue::Texture { hash, source } = self.texture_param(p, "texture:file", &a) {
                    texture = Some(render_core::texture::TextureRef { hash, source });
                }
            }
            ("RectLight", Some(_)) => self
                .out
                .warnings
                .push(format!("{p}: inputs:texture:file on a RectLight is not supported yet; the light's constant colour is used")),
            _ => {}
        }
        // UsdLux: the colour temperature multiplies `color` when enabled (default 6500 K).
        let temperature = (input("enableColorTemperature")?.as_ref().and_then(values::scalar).unwrap_or(0.0) != 0.0)
            .then(|| float("colorTemperature", 6500.0))
            .transpose()?;
        let mut transform = self.affine(prim, p)?;
        if type_name == "DomeLight_1" {
            // `poleAxis` (UsdLux DomeLight_1): the dome's top pole starts along the stage's up
            // axis ("scene", the fallback), +Y or +Z; a Z pole is the +Y pole turned 90° about
            // +X, applied to the dome alone.
            let pole = get(prim, "poleAxis", time)?.as_ref().and_then(values::token).unwrap_or_else(|| "scene".into());
            let z_pole = match pole.as_str() {
                "Z" => true,
                "Y" => false,
                "scene" => self.out.z_up,
                other => {
                    self.out.warnings.push(format!("{p}: poleAxis '{other}' is not scene, Y or Z; using scene"));
                    self.out.z_up
                }
            };
            if z_pole {
                transform *= glam::Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2);
            }
        }
        let desc = LightDesc {
            kind,
            transform,
            // UsdLux: DistantLight's intensity defaults to 50000, every other light's to 1.
            intensity: float("intensity", if type_name == "DistantLight" { 50000.0 } else { 1.0 })?,
            exposure: float("exposure", 0.0)?,
            color: input("color")?.as_ref().and_then(values::vec3).unwrap_or(Vec3::ONE)
                * temperature.map_or(Vec3::ONE, render_core::light::blackbody::blackbody_rgb),
            normalize: input("normalize")?.as_ref().and_then(values::scalar).unwrap_or(0.0) != 0.0,
            visible_to_camera: visible,
            shaping: self.shaping(prim, p, type_name)?,
            diffuse: float("diffuse", 1.0)?,
            specular: float("specular", 1.0)?,
            texture,
        };
        if !visible {
            return Ok(());
        }
        self.out.lights.push((p.to_string(), desc));
        Ok(())
    }

    /// `ShapingAPI` inputs when any is authored (on the area lights it applies to); IES
    /// profiles are reported as unsupported.
    fn shaping(&mut self, prim: &Prim, p: &str, type_name: &str) -> Result<Option<render_core::light::Shaping>> {
        let time = self.time;
        let read = |name: &str| get(prim, &format!("inputs:shaping:{name}"), time);
        let (angle, softness, focus, tint) = (read("cone:angle")?, read("cone:softness")?, read("focus")?, read("focusTint")?);
        if read("ies:file")?.is_some() {
            self.out.warnings.push(format!("{p}: IES profiles (inputs:shaping:ies:file) are not supported yet and are ignored"));
        }
        if angle.is_none() && softness.is_none() && focus.is_none() && tint.is_none() {
            return Ok(None);
        }
        if matches!(type_name, "DomeLight" | "DomeLight_1" | "DistantLight") {
            self.out.warnings.push(format!("{p}: ShapingAPI has no meaning for a {type_name} and is ignored"));
            return Ok(None);
        }
        let d = render_core::light::Shaping::default();
        let scalar = |v: &Option<Value>, default: f32| v.as_ref().and_then(values::scalar).map_or(default, |x| x as f32);
        Ok(Some(render_core::light::Shaping {
            cone_angle: scalar(&angle, d.cone_angle),
            cone_softness: scalar(&softness, d.cone_softness),
            focus: scalar(&focus, d.focus),
            focus_tint: tint.as_ref().and_then(values::vec3).unwrap_or(d.focus_tint),
        }))
    }

    fn camera(&mut self, prim: &Prim, p: &str) -> Result<()> {
        let time = self.time;
        let d = CameraDesc::default();
        let float = |name: &str, default: f32| -> Result<f32> {
            Ok(get(prim, name, time)?.as_ref().and_then(values::scalar).map_or(default, |v| v as f32))
        };
        let orthographic = get(prim, "projection", time)?.as_ref().and_then(values::token).is_some_and(|t| t == "orthographic");
        let f_stop = float("fStop", 0.0)?;
        if orthographic && f_stop > 0.0 {
            self.out.warnings.push(format!("{p}: depth of field is not simulated for orthographic cameras; fStop is ignored"));
        }
        let clip = get(prim, "clippingRange", time)?.as_ref().and_then(values::vec2).unwrap_or([d.near as f64, d.far as f64]);
        let desc = CameraDesc {
            transform: self.affine(prim, p)?,
            focal_length: float("focalLength", d.focal_length)?,
            horizontal_aperture: float("horizontalAperture", d.horizontal_aperture)?,
            vertical_aperture: float("verticalAperture", d.vertical_aperture)?,
            horizontal_aperture_offset: float("horizontalApertureOffset", 0.0)?,
            vertical_aperture_offset: float("verticalApertureOffset", 0.0)?,
            near: clip[0] as f32,
            far: clip[1] as f32,
            orthographic,
            f_stop,
            focus_distance: float("focusDistance", 0.0)?,
            shutter_open: float("shutter:open", 0.0)?,
            shutter_close: float("shutter:close", 0.0)?,
        };
        if desc.shutter_close > desc.shutter_open {
            self.out.warnings.push(format!(
                "{p}: the shutter is open from {} to {} frames; motion blur is not simulated yet, so the frame's own time is rendered",
                desc.shutter_open, desc.shutter_close
            ));
        }
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
fn read_asset(a: &openusd::sdf::AssetPath) -> std::io::Result<Vec<u8>> {
    use openusd::ar::Resolver;
    let resolved = a.resolved_path().filter(|r| !r.is_empty()).ok_or_else(|| {
        std::io::Error::new(std::io::ErrorKind::NotFound, "the path does not resolve (no such file next to the layer that authored it)")
    })?;
    let mut asset = openusd::ar::DefaultResolver::new().open_asset(&openusd::ar::ResolvedPath::new(resolved))?;
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut asset, &mut bytes)?;
    Ok(bytes)
}
