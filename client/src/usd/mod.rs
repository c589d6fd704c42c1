//! Reading a USD stage (`.usda`, `.usdc`, `.usdz`) with the `openusd` crate and translating
//! it into render-core's scene description.
//!
//! openusd's stage is `Rc`-based, so the whole read happens on one thread and only our own
//! `Send` structs leave this module. openusd does not synthesise schema fallbacks: an
//! unauthored attribute reads as `None`, and the UsdLux / UsdGeom defaults below are the
//! schema's documented ones.

mod lint;
use lint::{well_formed_name, well_formed_path};
mod binding;
mod camera;
pub mod curves;
mod dqs;
mod geometry;
mod instancing;
mod lights;
mod links;
mod materialx;
mod materialx_hair;
mod mesh;
mod motion;
mod mtlx_document;
pub mod points;
mod refine_later;
mod render_settings;
mod shading;
pub mod shapes;
mod skinning;
mod stage;
pub mod subdivision;
mod udim;
mod values;
mod volumes;

pub use lights::SYNC_TOKENS;
pub use links::link_collection_id;
use render_settings::valid_targets;
pub use render_settings::{RenderProductDesc, RenderSettingsDesc};
pub use stage::under;
use stage::{get, get_floats, get_ints, to_affine, usd_rotation};

use std::collections::HashMap;
use std::sync::Arc;

use anyhow::{Context, Result};
use glam::{Affine3A, DMat4, Mat4, Vec3};
use openusd::schemas::geom::{Imageable, Purpose, Xformable};
use openusd::schemas::shade::{Material, MaterialBindingAPI};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, PrimPredicate, SchemaBase, SchemaKind, Stage, TimeCode};
use render_core::camera::CameraDesc;
use render_core::light::{LightDesc, LightKind, MaterialSync, MeshLight};
use render_core::material::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};
use render_core::scene::{InstancerDesc, MeshDesc, SceneDesc};

pub use mesh::{MeshSource, select_faces, triangulate, triangulate_with_faces};
pub use motion::DEFAULT_MOTION_SAMPLES;
pub use skinning::Skinned;

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
    /// MaterialX materials: (material path, the surface shader id as authored), for
    /// `inspect` (the network itself holds the shader it was mapped onto).
    pub materialx_surfaces: Vec<(String, String)>,
    /// Meshes rendered as subdivision surfaces, in reading order.
    pub subdivided: Vec<Subdivided>,
    /// Meshes posed by a UsdSkel skeleton, in reading order.
    pub skinned: Vec<Skinned>,
    /// BasisCurves prims rendered as tubes, in reading order.
    pub curves: Vec<String>,
    /// UsdVol volumes by prim path.
    pub volumes: Vec<(String, render_core::volume::VolumeDesc)>,
    /// Where each volume's grids came from, for `inspect`.
    pub volume_sources: Vec<VolumeSource>,
    /// Samples per cubic span their tubes were swept with.
    pub curve_samples: usize,
}

/// One effect of the render plan with the prims calling for it (the first dozen named).
fn plan_entry(effect: &str, reason: &str, prims: impl ExactSizeIterator<Item = String>) -> String {
    const SHOWN: usize = 12;
    let count = prims.len();
    let mut named: Vec<String> = prims.take(SHOWN).collect();
    if count > SHOWN {
        named.push(format!("and {} more", count - SHOWN));
    }
    format!("  + {effect:<18} {reason}\n  {:<20} {}\n", "", named.join(", "))
}

/// A volume's prim transform and fields as read.
#[derive(Clone, Debug)]
pub struct VolumeSource {
    pub path: String,
    /// The prim's local-to-world transform.
    pub world: Affine3A,
    /// Its local-to-world transforms over the shutter when it moves (empty when still).
    pub motion: Vec<Affine3A>,
    /// (field, resolved VDB file, grid name) of each field rendered.
    pub fields: Vec<(String, String, String)>,
    /// Active voxels per field (tiles counted voxel by voxel).
    pub active_voxels: Vec<u64>,
}

/// A mesh refined as a subdivision surface.
#[derive(Clone, Debug)]
pub struct Subdivided {
    pub path: String,
    /// `catmullClark`, `loop` or `bilinear`.
    pub scheme: String,
    /// The level it was refined at (2^level segments per cage edge).
    pub level: u32,
    pub cage_faces: usize,
}

/// How to read a stage.
#[derive(Clone, Copy, Debug)]
pub struct LoadOptions {
    /// The frame at which to evaluate time samples (by default the stage's start).
    pub frame: Option<f64>,
    /// Refinement level of subdivision surfaces whose mesh names none (0 renders cages).
    pub subdivision_level: u32,
    /// The shutter interval (open, close) in frames relative to the frame, overriding the
    /// render camera's `shutter:open`/`shutter:close`; equal ends render no motion blur.
    pub shutter: Option<(f64, f64)>,
    /// Transform samples over the shutter for prims that move (2 or more).
    pub motion_samples: usize,
    /// Samples per cubic span of BasisCurves' tubes.
    pub curve_samples: usize,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            frame: None,
            subdivision_level: DEFAULT_SUBDIVISION_LEVEL,
            shutter: None,
            motion_samples: DEFAULT_MOTION_SAMPLES,
            curve_samples: curves::DEFAULT_CURVE_SAMPLES,
        }
    }
}

/// Level 2 is usdrecord's default ("high" complexity): 16 faces per cage quad.
pub const DEFAULT_SUBDIVISION_LEVEL: u32 = 2;

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
    /// World transforms over the shutter when it moves (empty when still).
    pub motion: Vec<Affine3A>,
}

/// A texture file read by the client, sent to the server once per content.
#[derive(Clone, Debug)]
pub struct TextureFile {
    /// The path as authored, for messages.
    pub source: String,
    /// The encoded file.
    pub bytes: Arc<Vec<u8>>,
}

impl Translation {
    /// Path of the camera a Z-up stage without cameras gets.
    pub const DEFAULT_CAMERA: &'static str = "/TesseraDefaultCamera";

    /// A Z-up stage without cameras: the renderer's default view (from +Z, Y up) would look
    /// straight down on it, so the client frames it as a viewer's free camera does: from the
    /// front (−Y) and [`Self::DEFAULT_ELEVATION_DEGREES`] above the ground plane, Z up, the
    /// bounding sphere filling the default field of view. Returns whether it added one.
    pub fn add_default_camera(&mut self) -> bool {
        if !self.z_up || !self.cameras.is_empty() {
            return false;
        }
        self.add_z_up_camera();
        !self.cameras.is_empty()
    }

    /// How far above the ground plane the default view of a Z-up stage looks down.
    pub const DEFAULT_ELEVATION_DEGREES: f32 = 25.0;

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
        // Camera looks down its local −Z; local +X stays world +X (no turn about Z), local +Y
        // leans back from world +Z by the elevation.
        let elevation = Self::DEFAULT_ELEVATION_DEGREES.to_radians();
        let back = Vec3::new(0.0, -elevation.cos(), elevation.sin());
        let rotation = glam::Mat3::from_cols(Vec3::X, back.cross(Vec3::X), back);
        let transform = Affine3A::from_mat3_translation(rotation, center + back * dist);
        self.cameras.push((Self::DEFAULT_CAMERA.to_string(), CameraDesc { transform, near: (dist - radius).max(1e-3) * 0.5, ..d }));
    }

    /// A warning for each camera whose clipping range lies wholly in front of or behind
    /// every mesh (an image of nothing but the background, which otherwise converges to
    /// "noise 0%" without a word).
    fn cameras_clipping_everything(&self) -> Vec<String> {
        let corners: Vec<Vec3> = self
            .meshes
            .iter()
            .filter(|(_, m)| m.visible && !m.mesh.positions.is_empty())
            .flat_map(|(_, m)| {
                let (lo, hi) = m.mesh.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
                (0..8).map(move |k| {
                    let c = Vec3::new([lo.x, hi.x][k & 1], [lo.y, hi.y][(k >> 1) & 1], [lo.z, hi.z][k >> 2]);
                    m.transform.transform_point3(c)
                })
            })
            .collect();
        if corners.is_empty() {
            return Vec::new();
        }
        self.cameras
            .iter()
            .filter_map(|(path, c)| {
                let to_camera = c.transform.inverse();
                let depths = corners.iter().map(|w| -to_camera.transform_point3(*w).z);
                let (near, far) = depths.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), d| (a.min(d), b.max(d)));
                (far < c.near || near > c.far).then(|| {
                    format!(
                        "{path}: clippingRange ({}, {}) hides the whole scene (its meshes lie {near:.3}..{far:.3} in front of the camera); the image shows only the background",
                        c.near, c.far
                    )
                })
            })
            .collect()
    }

    /// The render plan's entries for what reading did: the subdivision surfaces refined and
    /// the meshes skinned, in the plan's own layout (empty when there are none). Both happen in
    /// the reader, so the server's plan cannot list them.
    pub fn reader_plan(&self) -> String {
        let mut out = String::new();
        if !self.subdivided.is_empty() {
            let mut levels: Vec<u32> = self.subdivided.iter().map(|s| s.level).collect();
            levels.sort_unstable();
            levels.dedup();
            let levels = levels.iter().map(u32::to_string).collect::<Vec<_>>().join(", ");
            let reason = format!(
                "limit surfaces of subdivision meshes (OpenSubdiv), 2^level segments per cage edge, level {levels}; --subdivision-level 0 renders cages"
            );
            out +=
                &plan_entry("subdivision", &reason, self.subdivided.iter().map(|s| format!("{} ({} level {})", s.path, s.scheme, s.level)));
        }
        if !self.curves.is_empty() {
            let reason = format!(
                "BasisCurves as round tubes ({}-sided; ribbons where normals orient them), {} samples per cubic span (--curve-samples), through the bound material",
                curves::SIDES,
                self.curve_samples
            );
            out += &plan_entry("curves", &reason, self.curves.iter().cloned());
        }
        if !self.skinned.is_empty() {
            let posed = |s: &Skinned| match &s.animation {
                Some(a) => format!("{} ({a})", s.path),
                None => format!("{} (rest pose)", s.path),
            };
            let reason = "UsdSkel meshes posed at the frame: blend shapes, then linear blend skinning";
            out += &plan_entry("skinning", reason, self.skinned.iter().map(posed));
        }
        out
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
        let dome = LightDesc::new(LightKind::Dome, Affine3A::IDENTITY, 1.0);
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
        d.volumes.extend(self.volumes.iter().cloned());
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
const IMPLICIT: &[&str] = &["Sphere", "Cube", "Cylinder", "Cylinder_1", "Cone", "Capsule", "Capsule_1", "Plane"];

/// True for the gprims that render as meshes and so may be lights (`MeshLightAPI`, or
/// `LightAPI` applied to a gprim): meshes and the implicit shapes.
fn lit_as_mesh(type_name: &str) -> bool {
    type_name == "Mesh" || IMPLICIT.contains(&type_name)
}
const LIGHTS: &[&str] = &["SphereLight", "RectLight", "DiskLight", "CylinderLight", "DistantLight", "DomeLight", "DomeLight_1"];

/// Reads and translates the stage at `path` at its default frame.
pub fn load(path: &std::path::Path) -> Result<Translation> {
    load_at(path, None)
}

/// Reads and translates the stage at `path`, evaluating time samples (linearly interpolated)
/// at `frame`, by default the stage's `startTimeCode` when it authors a range, else 0.
pub fn load_at(path: &std::path::Path, frame: Option<f64>) -> Result<Translation> {
    load_with(path, LoadOptions { frame, ..LoadOptions::default() })
}

/// Reads and translates the stage at `path` as `options` say. A panic while reading is this
/// file's error, so the CLI, a farm worker and a DCC hosting the Python package keep running:
/// the vendored USD crate checks what its fuzz tests reach, and this is the last defence for
/// what they do not.
pub fn load_with(path: &std::path::Path, options: LoadOptions) -> Result<Translation> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| translate(path, options))).unwrap_or_else(|panic| {
        let why = panic.downcast_ref::<String>().map(String::as_str).or_else(|| panic.downcast_ref::<&str>().copied());
        Err(anyhow::anyhow!("{}: cannot read USD: the reader failed ({})", path.display(), why.unwrap_or("no message")))
    })
}

/// One warning per attribute a layer animates with a spline (USD 25.05's `.spline`) that value
/// resolution passes over: one with inner loops (deprecated in USD), or binary data the
/// vendored crate cannot decode (Maya-form tangents, time-valued splines). Such an attribute
/// reads its time samples, default or fallback instead.
fn spline_warnings(stage: &Stage) -> Vec<String> {
    let mut warnings = Vec::new();
    for id in stage.layer_identifiers() {
        let Some(layer) = stage.layer(&id) else { continue };
        let data = layer.data();
        let mut paths = data.paths_with_field("spline");
        paths.sort_by(|a, b| a.as_str().cmp(b.as_str()));
        for path in paths {
            if let Ok(Some(spline)) = data.try_field(&path, "spline")
                && openusd::usd::evaluates(&spline)
            {
                continue;
            }
            warnings.push(format!(
                "{}: attribute animated by a spline in {id} that is not evaluated (inner loops, or data the reader cannot decode); its time samples, default or fallback are read",
                path.as_str()
            ));
        }
    }
    warnings
}

/// Whether the layers read so far author a light's link collection, or may apply an API
/// schema the reader reports as unsupported (a gprim as a light, a collection). Asking each
/// light and prim instead composed four link properties a light (the schema lists them,
/// authored or not) and every prim's `apiSchemas`: 6.5% of a 10,000-light file's load. A
/// binary layer rules itself out from its token table. Layers load as composition reaches
/// them (a payload's when its prim is composed), so each is scanned when first seen.
#[derive(Default)]
pub(super) struct ReportedNames {
    scanned: std::collections::HashSet<String>,
    pub(super) links: bool,
    pub(super) apis: bool,
}

impl ReportedNames {
    /// Scans the stage's layers not scanned yet.
    pub(super) fn update(&mut self, stage: &Stage) {
        for id in stage.layer_identifiers() {
            if self.scanned.contains(&id) {
                continue;
            }
            if let Some(layer) = stage.layer(&id) {
                let data = layer.data();
                self.links |= authors_link_properties(data);
                self.apis |=
                    data.may_use_token(&|t| matches!(t, "MeshLightAPI" | "VolumeLightAPI" | "LightAPI") || t.starts_with("CollectionAPI:"));
            }
            self.scanned.insert(id);
        }
    }
}

/// Whether a layer authors a property of a light's `lightLink` or `shadowLink` collection.
fn authors_link_properties(data: &dyn openusd::sdf::AbstractData) -> bool {
    let names: Vec<String> =
        ["lightLink", "shadowLink"].iter().flat_map(|link| LINK_PROPERTIES.iter().map(move |p| format!("collection:{link}:{p}"))).collect();
    if !data.may_use_token(&|t| names.iter().any(|n| n == t)) {
        return false;
    }
    ["targetPaths", "default"].iter().flat_map(|field| data.paths_with_field(field)).any(|path| {
        let property = path.as_str().split_once('.').map_or("", |(_, name)| name);
        names.iter().any(|n| n == property)
    })
}

/// The properties of a link collection that make it hold less than the whole stage.
const LINK_PROPERTIES: [&str; 4] = ["includes", "excludes", "includeRoot", "membershipExpression"];

/// [`load_with`]'s work.
fn translate(path: &std::path::Path, options: LoadOptions) -> Result<Translation> {
    let frame = options.frame;
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
    let _reading = stage::authored::Reading::start();
    let stage = Stage::open(path_str).map_err(|e| anyhow::anyhow!("{}: cannot read USD: {e:#}", path.display()))?;
    let default_frame = if stage.has_authored_time_code_range() { stage.start_time_code() } else { 0.0 };
    let time = TimeCode::new(frame.unwrap_or(default_frame));
    let mut reader = Reader {
        stage: &stage,
        time,
        world: HashMap::new(),
        hidden: HashMap::new(),
        out: Translation::default(),
        materials_seen: HashMap::new(),
        all_paths: Vec::new(),
        instancer_roots: Vec::new(),
        native: HashMap::new(),
        bindings: HashMap::new(),
        binding_cache: Default::default(),
        subdivision_level: options.subdivision_level.min(subdivision::MAX_LEVEL),
        unmappable: std::collections::HashSet::new(),
        mtlx_documents: std::collections::HashSet::new(),
        skins: HashMap::new(),
        skin_samples: HashMap::new(),
        shutter: None,
        curve_samples: options.curve_samples.clamp(1, curves::MAX_CURVE_SAMPLES),
        motion_samples: options.motion_samples.clamp(2, render_core::motion::MAX_MOTION_SAMPLES),
        later: Vec::new(),
        reported_names: ReportedNames::default(),
        links: Default::default(),
    };
    // Stage metrics first: DomeLight_1's pole follows the up axis.
    let up_axis = stage.stage_metadata("upAxis").ok().flatten().as_ref().and_then(values::token);
    reader.out.z_up = up_axis.as_deref() == Some("Z");
    if let Some(axis) = up_axis.filter(|a| a != "Y" && a != "Z") {
        reader.out.warnings.push(format!("{}: upAxis '{axis}' is neither Y nor Z; the stage is read as Y-up", path.display()));
    }
    reader.out.meters_per_unit = stage
        .stage_metadata("metersPerUnit")
        .ok()
        .flatten()
        .as_ref()
        .and_then(values::scalar)
        .filter(|m| m.is_finite() && *m > 0.0)
        .unwrap_or(0.01);
    let mut paths = Vec::new();
    stage
        .traverse(PrimPredicate::DEFAULT_PROXIES, |p| paths.push(p.clone()))
        .map_err(|e| anyhow::anyhow!("{}: traversal failed: {e:#}", path.display()))?;
    reader.all_paths = paths.clone();
    reader.resolve_light_links(&paths);
    reader.shutter = motion::shutter_interval(&stage, &paths, time.value(), &options)
        .map_err(|e| anyhow::anyhow!("{}: the shutter cannot be read: {e:#}", path.display()))?;
    for p in paths {
        reader.visit_or_skip(&p);
    }
    reader.refine_deferred();
    // After the traversal: arcs are composed (and found unresolved) as their prims are read.
    for e in stage.composition_errors() {
        // A .mtlx reference is an arc the crate cannot compose, and one the reader follows.
        let e = e.to_string();
        let asset = e.split('@').nth(1).unwrap_or("\0").trim_start_matches("./");
        if !reader.mtlx_documents.iter().any(|d| d.ends_with(asset)) {
            reader.out.warnings.push(format!("composition: {e}"));
        }
    }
    reader.out.warnings.extend(spline_warnings(&stage));
    let hidden = reader.out.cameras_clipping_everything();
    reader.out.warnings.extend(hidden);
    // Each thing is said once, however many prims run into it.
    let mut said = std::collections::HashSet::new();
    reader.out.warnings.retain(|w| said.insert(w.clone()));
    Ok(reader.out)
}

impl Reader<'_> {
    /// Visits one prim. A prim that cannot be read is reported (the error names the prim and
    /// attribute), left out with whatever it had added, and the rest of the stage still
    /// renders, as usdrecord does; `--strict` makes such warnings fatal.
    fn visit_or_skip(&mut self, p: &sdf::Path) {
        let kept = (self.out.meshes.len(), self.out.lights.len(), self.out.cameras.len());
        if let Err(e) = self.visit(p) {
            self.out.meshes.truncate(kept.0);
            self.forget_deferred_from(kept.0);
            self.out.lights.truncate(kept.1);
            self.out.cameras.truncate(kept.2);
            let why = format!("{e:#}");
            let named = if why.contains(p.as_str()) { why } else { format!("{}: {why}", p.as_str()) };
            self.out.warnings.push(format!("{named}; the prim is skipped"));
            self.out.skipped.push(p.as_str().to_string());
        }
    }
}

struct Reader<'s> {
    stage: &'s Stage,
    /// Time at which time-sampled transforms are read: the stage's start time.
    time: TimeCode,
    world: HashMap<String, DMat4>,
    /// Whether each prim asked about, or an ancestor, is invisible at `time`.
    hidden: HashMap<String, bool>,
    out: Translation,
    materials_seen: HashMap<String, ()>,
    /// Every prim path the traversal visits, in order.
    all_paths: Vec<sdf::Path>,
    /// PointInstancers seen so far: prims beneath them render only through them.
    instancer_roots: Vec<String>,
    /// Native instancing: (prototype mesh path, material, light-link collections) → index of
    /// its instancer.
    native: HashMap<(String, String, Vec<String>), usize>,
    /// Each prim's resolved material binding: a mesh asks for its own and its subsets' several
    /// times (material, texture coordinates, primvars), and a broken binding is reported once.
    bindings: HashMap<String, Option<String>>,
    /// The bindings read at each prim, shared by every prim's resolution.
    binding_cache: openusd::schemas::shade::BindingsCache,
    /// Refinement level of subdivision surfaces that name none.
    subdivision_level: u32,
    /// Materials whose surface shader has no mapping: their meshes show displayColor.
    unmappable: std::collections::HashSet<String>,
    /// MaterialX documents read for materials that reference them.
    mtlx_documents: std::collections::HashSet<String>,
    /// Skinned meshes' poses, by mesh path, found when their SkelRoot is visited.
    skins: HashMap<String, skinning::Skin>,
    /// Skinned meshes' poses at the motion samples over an open shutter, when their skeleton
    /// is animated (deformation blur).
    skin_samples: HashMap<String, Vec<skinning::Skin>>,
    /// The shutter's absolute times when it is open: prims that move over it carry motion.
    shutter: Option<(f64, f64)>,
    /// Transform samples over an open shutter.
    motion_samples: usize,
    /// Samples per cubic span of curves' tubes.
    curve_samples: usize,
    /// Subdivision meshes refined after the traversal (see `refine_later`).
    later: Vec<refine_later::LaterRefinement>,
    /// Whether the layers read so far name what the reader reports as unsupported.
    reported_names: ReportedNames,
    /// The lights' link collections.
    links: links::LinkQueries,
}
