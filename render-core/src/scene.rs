//! The scene description a session edits (keyed by USD path), and its commit into the
//! structures the renderer traces against.
//!
//! [`commit`] rebuilds only what changed: a mesh whose geometry `Arc` is unchanged keeps
//! its BLAS through [`BlasCache`], so moving an object or a light costs a TLAS rebuild and
//! nothing more.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3};

use crate::bvh::{Blas, BuildQuality, Hit, Tlas, TlasInstance};
use crate::camera::CameraDesc;
use crate::geometry::{Mesh, Ray, Transform};
use crate::light::{Light, LightDesc, LightSet};
use crate::material::{Material, MaterialNetwork};
use crate::plan::RenderPlan;

/// A mesh prim.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshDesc {
    /// Geometry, shared so unchanged meshes keep their BLAS across commits.
    pub mesh: Arc<Mesh>,
    /// Object to world.
    pub transform: Affine3A,
    /// Bound material path; empty for none.
    pub material: String,
    /// Rendered at all (false for invisible meshes and instancer prototypes).
    pub visible: bool,
}

/// A point instancer: world transforms of instances of one prototype mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct InstancerDesc {
    /// Path of the prototype mesh in [`SceneDesc::meshes`].
    pub prototype: String,
    /// Object-to-world transform of each instance.
    pub transforms: Vec<Affine3A>,
}

/// Everything a session has synced, keyed by USD path.
#[derive(Clone, Debug, Default)]
pub struct SceneDesc {
    /// Meshes.
    pub meshes: BTreeMap<String, MeshDesc>,
    /// Instancers.
    pub instancers: BTreeMap<String, InstancerDesc>,
    /// Material networks.
    pub materials: BTreeMap<String, MaterialNetwork>,
    /// Lights.
    pub lights: BTreeMap<String, LightDesc>,
    /// Cameras.
    pub cameras: BTreeMap<String, CameraDesc>,
    /// Decoded texture files by content hash, as materials name them.
    pub textures: BTreeMap<String, Arc<crate::texture::Image>>,
}

/// A scene that cannot be committed, naming the prim and field at fault.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SceneError {
    /// Invalid data on a prim.
    #[error("{prim}: {field}: {problem}")]
    Invalid {
        /// Prim path.
        prim: String,
        /// Attribute or field.
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// A reference to a prim that does not exist.
    #[error("{prim}: {field} refers to {target}, which is not in the scene")]
    Dangling {
        /// Prim path.
        prim: String,
        /// Field holding the reference.
        field: String,
        /// Missing path.
        target: String,
    },
}

/// Largest coordinate a point may have, in object or world space. Squared distances and
/// cross products of coordinates beyond ~1e19 overflow f32 (the BVH builder indexed out of
/// bounds on a point at 1e38); 1e15 scene units is already 6 700 astronomical units in metres.
pub const MAX_COORDINATE: f32 = 1e15;

/// Checks a mesh for what would break the renderer: non-finite or overflowing positions,
/// indices out of range, normal arrays of the wrong length. Bad normals are not an error; they
/// are repaired at shading time (the geometric normal is used).
pub fn validate_mesh(path: &str, mesh: &Mesh) -> Result<(), SceneError> {
    let invalid = |field: &str, problem: String| SceneError::Invalid { prim: path.to_string(), field: field.to_string(), problem };
    if let Some((i, p)) = mesh.positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        return Err(invalid("points", format!("point {i} is {p} (NaN or Inf)")));
    }
    if let Some((i, p)) = mesh.positions.iter().enumerate().find(|(_, p)| p.abs().max_element() > MAX_COORDINATE) {
        return Err(invalid("points", format!("point {i} is {p}, beyond ±{MAX_COORDINATE:e}: single-precision geometry overflows there")));
    }
    let n = mesh.positions.len() as u64;
    for (t, tri) in mesh.indices.iter().enumerate() {
        for (k, &v) in tri.iter().enumerate() {
            if v as u64 >= n {
                return Err(invalid("faceVertexIndices", format!("triangle {t} corner {k} has index {v}, out of range for {n} points")));
            }
        }
    }
    // Per-corner data must match the layout it claims, or shading would index past its end.
    fn check<T>(a: &crate::geometry::Attribute<T>, mesh: &Mesh) -> Result<(), String> {
        use crate::geometry::Attribute;
        let (got, want, interp) = match a {
            Attribute::None => return Ok(()),
            Attribute::Vertex(v) => (v.len(), mesh.positions.len(), "vertex"),
            Attribute::FaceVarying(v) => (v.len(), 3 * mesh.indices.len(), "faceVarying"),
        };
        if got == want { Ok(()) } else { Err(format!("{got} {interp} values for {want} expected")) }
    }
    check(&mesh.normals, mesh).map_err(|e| invalid("normals", e))?;
    check(&mesh.uvs, mesh).map_err(|e| invalid("uvs", e))?;
    for p in &mesh.primvars {
        check(&p.values, mesh).map_err(|e| invalid(&format!("primvars:{}", p.name), e))?;
    }
    Ok(())
}

/// BLASes kept between commits, keyed by mesh path and geometry identity.
#[derive(Default)]
pub struct BlasCache {
    entries: HashMap<String, (Arc<Mesh>, Arc<Blas>)>,
    /// Mip pyramids by (content hash, colour space), kept while a material reads them.
    textures: HashMap<(String, crate::texture::ColorSpace), Arc<crate::texture::Texture>>,
    /// BLAS builds done by the last commit (for tests and logs).
    pub last_builds: usize,
    /// MikkTSpace tangents of normal-mapped meshes, by mesh geometry.
    tangents: Vec<(Arc<Mesh>, Arc<crate::geometry::Attribute<glam::Vec4>>)>,
}

/// Per-instance data the integrator needs at a hit.
#[derive(Clone, Debug)]
pub struct InstanceData {
    /// Index into [`CommittedScene::meshes`].
    pub mesh: usize,
    /// Placement.
    pub transform: Transform,
    /// Index into [`CommittedScene::materials`].
    pub material: u32,
    /// Index of the first triangle light of this instance, if its material emits.
    pub emitter_base: Option<u32>,
    /// Index into [`CommittedScene::prim_paths`].
    pub prim: u32,
}

/// The renderable scene: acceleration structures, materials, lights and the plan.
pub struct CommittedScene {
    /// Geometry per distinct mesh.
    pub meshes: Vec<Arc<Mesh>>,
    /// Per mesh, its MikkTSpace tangents (per corner) when a normal map is drawn on it.
    tangents: Vec<Option<Arc<crate::geometry::Attribute<glam::Vec4>>>>,
    blases: Vec<Arc<Blas>>,
    /// Instances in the TLAS.
    pub instances: Vec<InstanceData>,
    tlas: Tlas,
    /// Resolved materials; index 0 is the default material. A textured material is here as
    /// seen from afar (each texture at its mean); [`Self::textured`] gives it per point.
    pub materials: Vec<Material>,
    /// Per material, its inputs that vary over the surface, if any.
    pub textured: Vec<Option<Arc<crate::material::TexturedMaterial>>>,
    /// True when rays may pass some surface at some points: a textured material cut out
    /// there (opacity below its threshold) or a partially present material. Rays then test
    /// the material where they hit it.
    pub has_see_through: bool,
    /// Each material's BSDF without and with energy compensation, built on first use of each
    /// setting (for a textured material, its mean).
    bsdfs: [std::sync::OnceLock<Vec<crate::bsdf::Bsdf>>; 2],
    /// The same at each roughness floor of caustic avoidance ([`crate::caustics`]):
    /// `[level][material]`, built only by renders that avoid caustics.
    floored_bsdfs: [std::sync::OnceLock<Vec<Vec<crate::bsdf::Bsdf>>>; 2],
    /// Each material's BSDF with every lobe (`force_all_effects`), built on first use.
    every_lobe_bsdfs: [std::sync::OnceLock<Vec<crate::bsdf::Bsdf>>; 2],
    /// Each material's subsurface medium.
    media: Vec<Option<crate::subsurface::Medium>>,
    /// Each material's smooth glass as transparent shadows see it.
    shadow_glass: Vec<Option<crate::caustics::ShadowGlass>>,
    /// Per material, its subsurface medium's boundary as shadows from inside see it.
    medium_boundary: Vec<Option<crate::caustics::ShadowGlass>>,
    /// Materials some instance uses: only their lobes' energy tables are built.
    used_materials: Vec<u32>,
    /// Lights and their selection distribution.
    pub lights: LightSet,
    /// Indices of the finite lights a ray may cross (area lights; not triangle emitters,
    /// which are found through the BVH).
    pub crossable_lights: crate::light::tree::LightTree,
    /// Indices of the lights at infinity.
    pub infinite_lights: Vec<u32>,
    /// Prim path of each instance's source.
    pub prim_paths: Vec<String>,
    /// Cameras, copied from the description.
    pub cameras: BTreeMap<String, CameraDesc>,
    /// World bounds of the geometry (min, max); empty scenes have min > max.
    pub bounds: (Vec3, Vec3),
    /// What the renderer simulates for this scene.
    pub plan: RenderPlan,
    /// What commit could not honour, by prim.
    pub warnings: Vec<String>,
    /// Materials whose subsurface medium lies behind a smooth boundary (roughness up to
    /// [`crate::caustics::SMOOTH_GLASS`]): full path tracing lights them only by chance.
    pub smooth_subsurface: Vec<String>,
}

/// Surface data at a ray hit, in world space.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal (not face-forwarded).
    pub ng: Vec3,
    /// Unit shading normal (not face-forwarded).
    pub ns: Vec3,
    /// Material index.
    pub material: u32,
    /// Triangle-light index when the surface emits.
    pub light: Option<u32>,
    /// The size that bounds the error of `p`: the larger of its coordinates and the hit
    /// triangle's world-space edges. Ray origins leaving the surface are offset in proportion
    /// ([`crate::geometry::offset_ray_origin`]), so a 1 km ground plane and a 1 mm bead in the
    /// same scene each get an offset fit for them.
    pub offset_scale: f32,
    /// The object's up axis (local +Y) in world space: anisotropic and fabric materials run
    /// their tangent around it ([`crate::math::Frame::from_normal_around`]) until meshes carry
    /// UV tangents.
    pub up: Vec3,
    /// Texture coordinates, when the mesh has them.
    pub st: Option<Vec2>,
    /// Texture-space length per world-space length on the hit triangle (0 without `st`).
    pub uv_density: f32,
    /// World-space ∂p/∂s and ∂p/∂t of the hit triangle (zero without `st`): the tangent frame
    /// of normal maps.
    pub dpds: Vec3,
    /// See [`Self::dpds`].
    pub dpdt: Vec3,
    /// The instance hit.
    pub instance: u32,
    /// The triangle hit, in its mesh.
    pub triangle: u32,
    /// Barycentrics (b1, b2) of the hit.
    pub bary: Vec2,
    /// World-space MikkTSpace tangent (xyz, interpolated) and bitangent sign (w) where the
    /// mesh is normal-mapped; zero elsewhere.
    pub tangent: glam::Vec4,
}

/// A uniform number in [0, 1) for a ray meeting a partially present surface at `p` along
/// `dir`: a hash of the two, so the decision needs no sampler dimension and shadow rays make it
/// as camera rays do. Positions differ from sample to sample, so the coins are independent.
pub fn see_through_coin(p: Vec3, dir: Vec3) -> f32 {
    let bits = |v: Vec3| ((v.x.to_bits() as u64) << 32 | v.y.to_bits() as u64) ^ (v.z.to_bits() as u64).rotate_left(17);
    let h = crate::sampling::mix64(bits(p) ^ crate::sampling::mix64(bits(dir) ^ 0x5ee7_4409));
    (h >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// Cut-out surfaces a ray passes through before the rest counts as opaque.
pub const MAX_CUTOUT_CROSSINGS: usize = 64;

/// Builds the renderable scene from its description, reusing cached BLASes.
pub fn commit(desc: &SceneDesc, cache: &mut BlasCache) -> Result<CommittedScene, SceneError> {
    let _span = tracing::info_span!("commit", meshes = desc.meshes.len(), lights = desc.lights.len()).entered();
    let mut warnings = Vec::new();
    let mut plan = RenderPlan::default();

    // Materials: index 0 is the fallback for unbound meshes.
    let mut materials = vec![Material::preview_surface_default()];
    let mut textured = vec![None];
    let mut material_index: HashMap<&str, u32> = HashMap::new();
    let pyramids = std::cell::RefCell::new(HashMap::new());
    let source = |hash: &str, space: crate::texture::ColorSpace| -> Option<Arc<crate::texture::Texture>> {
        let key = (hash.to_string(), space);
        let known = cache.textures.get(&key).cloned().or_else(|| pyramids.borrow().get(&key).cloned());
        let t = match known {
            Some(t) => t,
            None => {
                let image = desc.textures.get(hash)?;
                let _span = tracing::info_span!("mipmap", hash, bytes = image.bytes()).entered();
                Arc::new(crate::texture::Texture::new(image, space))
            }
        };
        pyramids.borrow_mut().insert(key, Arc::clone(&t));
        Some(t)
    };
    for (path, network) in &desc.materials {
        let mut report = crate::material::ResolveReport::default();
        let varying = crate::material::TexturedMaterial::compile(network, path, &source, &mut report);
        let m = match &varying {
            Some(t) => {
                let (m, r) = t.mean();
                report.warnings.extend(r.warnings);
                m
            }
            None => {
                let (m, r) = network.resolve(path);
                report.warnings.extend(r.warnings);
                m
            }
        };
        warnings.extend(report.warnings);
        material_index.insert(path.as_str(), materials.len() as u32);
        materials.push(m);
        textured.push(varying.map(Arc::new));
    }
    // Dome light maps, read as the materials' textures are (linear for float files).
    let mut environments: HashMap<&str, Arc<crate::texture::Texture>> = HashMap::new();
    for (path, l) in &desc.lights {
        if let Some(t) = &l.texture {
            match source(&t.hash, crate::texture::ColorSpace::Auto) {
                Some(tex) => {
                    environments.insert(path.as_str(), tex);
                }
                None => warnings.push(format!("{path}: texture '{}' is not on the server; the dome is its constant colour", t.source)),
            }
        }
    }
    // Keep exactly the pyramids this scene reads.
    cache.textures = pyramids.into_inner();

    // Geometry: one BLAS per distinct mesh prim that has triangles.
    let mut meshes = Vec::new();
    let mut blases = Vec::new();
    let mut mesh_slot: HashMap<&str, usize> = HashMap::new();
    let mut builds = 0;
    let mut fresh = HashMap::new();
    let used_as_prototype: std::collections::HashSet<&str> = desc.instancers.values().map(|i| i.prototype.as_str()).collect();
    for (path, m) in &desc.meshes {
        validate_mesh(path, &m.mesh)?;
        if m.mesh.indices.is_empty() || !(m.visible || used_as_prototype.contains(path.as_str())) {
            if m.mesh.indices.is_empty() {
                warnings.push(format!("{path}: mesh has no triangles and is skipped"));
            }
            continue;
        }
        let blas = match cache.entries.get(path) {
            Some((geom, blas)) if Arc::ptr_eq(geom, &m.mesh) => blas.clone(),
            _ => {
                builds += 1;
                Arc::new(Blas::build(&m.mesh, BuildQuality::Medium))
            }
        };
        fresh.insert(path.clone(), (m.mesh.clone(), blas.clone()));
        mesh_slot.insert(path.as_str(), meshes.len());
        meshes.push(m.mesh.clone());
        blases.push(blas);
    }
    cache.entries = fresh;
    cache.last_builds = builds;

    let material_of = |prim: &str, path: &str| -> u32 {
        if path.is_empty() {
            return 0;
        }
        match material_index.get(path) {
            Some(&i) => i,
            None => {
                tracing::warn!(prim, material = path, "bound material is not in the scene; using the default");
                0
            }
        }
    };

    // Instances: visible meshes, then instancer instances.
    let mut instances = Vec::new();
    let mut prim_paths = Vec::new();
    let push_instance = |prim_paths: &mut Vec<String>,
                         instances: &mut Vec<InstanceData>,
                         path: &str,
                         mesh: usize,
                         xf: &Affine3A,
                         material: u32|
     -> Result<(), SceneError> {
        let transform = Transform::new(*xf).ok_or_else(|| SceneError::Invalid {
            prim: path.to_string(),
            field: "transform".into(),
            problem: "singular or not finite".into(),
        })?;
        let prim = match prim_paths.last() {
            Some(p) if p == path => prim_paths.len() as u32 - 1,
            _ => {
                prim_paths.push(path.to_string());
                prim_paths.len() as u32 - 1
            }
        };
        instances.push(InstanceData { mesh, transform, material, emitter_base: None, prim });
        Ok(())
    };
    // Materials with no effect on light (cut out, index-matched clear glass) remove their
    // surfaces altogether.
    // A textured material is cut out point by point, never as a whole.
    let cut_out = |m: u32| textured[m as usize].is_none() && materials[m as usize].is_invisible();
    let has_see_through = textured.iter().flatten().any(|t| t.may_see_through()) || materials.iter().any(|m| m.pass_through > 0.0);
    for (path, m) in &desc.meshes {
        if !m.visible {
            continue;
        }
        if let Some(&slot) = mesh_slot.get(path.as_str()) {
            let material = material_of(path, &m.material);
            if !cut_out(material) {
                push_instance(&mut prim_paths, &mut instances, path, slot, &m.transform, material)?;
            }
        }
    }
    for (path, inst) in &desc.instancers {
        let Some(&slot) = mesh_slot.get(inst.prototype.as_str()) else {
            if desc.meshes.contains_key(&inst.prototype) {
                continue; // an empty prototype was already reported
            }
            return Err(SceneError::Dangling { prim: path.clone(), field: "prototype".into(), target: inst.prototype.clone() });
        };
        let proto = &desc.meshes[&inst.prototype];
        let material = material_of(path, &proto.material);
        if cut_out(material) {
            continue;
        }
        for xf in &inst.transforms {
            push_instance(&mut prim_paths, &mut instances, path, slot, xf, material)?;
        }
    }

    // MikkTSpace tangents for the meshes drawn with a normal map, each computed once per
    // geometry and kept between commits.
    let mut tangents: Vec<Option<Arc<crate::geometry::Attribute<glam::Vec4>>>> = vec![None; meshes.len()];
    let mut kept_tangents = Vec::new();
    let mut tried = vec![false; meshes.len()];
    for inst in &instances {
        let mesh = &meshes[inst.mesh];
        let normal_mapped = textured[inst.material as usize].as_deref().is_some_and(|t| t.has_normal_map());
        if tried[inst.mesh] || !normal_mapped || mesh.uvs.is_empty() {
            continue;
        }
        tried[inst.mesh] = true;
        let t = match cache.tangents.iter().find(|(m, _)| Arc::ptr_eq(m, mesh)) {
            Some((_, t)) => Some(t.clone()),
            None => crate::tangents::mikktspace(mesh).map(Arc::new),
        };
        if let Some(t) = &t {
            kept_tangents.push((mesh.clone(), t.clone()));
        }
        tangents[inst.mesh] = t;
    }
    cache.tangents = kept_tangents;

    // Bounds, for sizing infinite lights and the default camera; an instance whose transform
    // carries its geometry beyond what f32 holds is an error naming it.
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for inst in &instances {
        let (a, b) = blases[inst.mesh].bounds();
        for i in 0..8 {
            let c = Vec3::new(if i & 1 == 0 { a.x } else { b.x }, if i & 2 == 0 { a.y } else { b.y }, if i & 4 == 0 { a.z } else { b.z });
            let w = inst.transform.to_world.transform_point3(c);
            if !w.is_finite() || w.abs().max_element() > MAX_COORDINATE {
                return Err(SceneError::Invalid {
                    prim: prim_paths[inst.prim as usize].clone(),
                    field: "transform".into(),
                    problem: format!("places the geometry at {w}, beyond ±{MAX_COORDINATE:e}"),
                });
            }
            lo = lo.min(w);
            hi = hi.max(w);
        }
    }
    let tlas_instances: Vec<TlasInstance> = instances.iter().map(|i| TlasInstance { blas: i.mesh, transform: i.transform }).collect();
    let tlas = Tlas::build(&blases, &tlas_instances);
    let scene_radius = if lo.x <= hi.x { 0.5 * (hi - lo).length().max(1e-3) } else { 1.0 };

    // Lights: UsdLux lights, then one per emissive triangle.
    let mut lights: Vec<Light> = Vec::new();
    let mut light_prims = Vec::new();
    for (path, l) in &desc.lights {
        match l.commit_with(environments.get(path.as_str()).cloned()) {
            Some(light) => {
                lights.push(light);
                light_prims.push(path.clone());
            }
            None => {
                warnings.push(format!("{path}: light emits nothing (zero size, zero intensity or a singular transform) and is skipped"))
            }
        }
    }
    let mut emissive_prims = Vec::new();
    let mut emissive_triangles = 0usize;
    for (index, inst) in instances.iter_mut().enumerate() {
        let m = &materials[inst.material as usize];
        if !m.is_emissive() {
            continue;
        }
        let varies = textured[inst.material as usize].as_ref().is_some_and(|t| t.emission_varies());
        inst.emitter_base = Some(lights.len() as u32);
        let mesh = &meshes[inst.mesh];
        for t in 0..mesh.triangle_count() {
            let p = mesh.triangle(t).map(|v| inst.transform.to_world.transform_point3(v));
            // Degenerate triangles keep their slot (indices must line up) but emit nothing.
            let shape = crate::light::Shape::triangle(p, m.emission).unwrap_or(crate::light::Shape::Triangle {
                p,
                n: Vec3::Z,
                area: 0.0,
                l: Vec3::ZERO,
            });
            let mut light = Light::plain(shape, true);
            light.textured_emitter = varies.then_some((index as u32, t as u32));
            lights.push(light);
        }
        emissive_triangles += mesh.triangle_count();
        emissive_prims.push(prim_paths[inst.prim as usize].clone());
    }
    // UsdLux lights a ray can pass through, in a BVH: with thousands of them a linear scan per
    // ray would dominate the render.
    let crossable_lights = crate::light::tree::LightTree::build(
        (0..light_prims.len()).filter_map(|i| crate::light::tree::LightBounds::of(&lights[i].shape, 1.0).map(|b| (i as u32, b))).collect(),
        light_prims.len(),
    );
    let infinite_lights = (0..light_prims.len() as u32).filter(|&i| lights[i as usize].shape.is_infinite()).collect();

    // The plan: what this scene calls for.
    if !light_prims.is_empty() {
        plan.enable(
            "lights",
            format!("{} UsdLux light(s), chosen through a light tree with adaptive splitting, MIS (power heuristic)", light_prims.len()),
            light_prims.clone(),
        );
    }
    let mapped_domes: Vec<String> = environments.keys().map(|p| p.to_string()).collect();
    if !mapped_domes.is_empty() {
        plan.enable(
            "environment-map",
            "DomeLight texture, importance-sampled by luminance × sin θ (2D piecewise-constant) with MIS".to_string(),
            mapped_domes,
        );
    }
    // Texture machinery, with the materials that call for it: per-point material resolution,
    // normal maps, cut-out tests on every ray, per-texel emission.
    let textured_with = |pred: &dyn Fn(&crate::material::TexturedMaterial) -> bool| -> Vec<String> {
        desc.materials.keys().filter(|m| textured[material_index[m.as_str()] as usize].as_deref().is_some_and(pred)).cloned().collect()
    };
    for (effect, reason, prims) in [
        ("textures", "material inputs from textures, resolved per shading point and mip-mapped by ray cones", textured_with(&|_| true)),
        ("normal-maps", "tangent-space normal maps", textured_with(&|t| t.has_normal_map())),
        ("textured-cutouts", "opacity textures cut surfaces out per point, for every ray", textured_with(&|t| t.may_see_through())),
        ("textured-emission", "emission looked up per texel where light sampling lands", textured_with(&|t| t.emission_varies())),
    ] {
        if !prims.is_empty() {
            plan.enable(effect, reason.to_string(), prims);
        }
    }
    if emissive_triangles > 0 {
        emissive_prims.dedup();
        plan.enable("emissive-meshes", format!("{emissive_triangles} emissive triangle(s) sampled by area with MIS"), emissive_prims);
    }
    if lights.is_empty() {
        warnings.push("the scene has no lights and no emissive surfaces: the image will be black".into());
    }
    // Each effect the materials call for, with the materials that call for it.
    let materials_where = |pred: &dyn Fn(&Material) -> bool| -> Vec<String> {
        desc.materials.keys().filter(|m| pred(&materials[material_index[m.as_str()] as usize])).cloned().collect()
    };
    type Pred = fn(&crate::material::Uber) -> bool;
    let effects: [(&str, &str, Pred); 12] = [
        ("diffuse", "diffuse reflection (Lambertian; Disney's for tessera:Principled)", |u| {
            u.plastic.weight > 0.0 || (u.fabric.weight > 0.0 && u.fabric.params.specular < 1.0)
        }),
        ("metal", "GGX conductor reflection", |u| u.metal.weight > 0.0),
        ("transmission", "rough dielectric refraction (glass)", |u| u.has_refraction()),
        ("thin-transmission", "thin dielectric sheets (Imageworks' double-refraction series)", |u| {
            u.glass.weight > 0.0 && u.glass.params.thin
        }),
        ("diffuse-transmission", "Lambertian transmission", |u| u.plastic.weight > 0.0 && u.plastic.params.diffuse_transmission > 0.0),
        ("clearcoat", "a clearcoat layered over the base", |u| u.clearcoat.weight > 0.0 && u.specular_control > 0.0),
        ("sheen", "sheen (Charlie coat, or Disney's for tessera:Principled)", |u| {
            u.sheen.weight > 0.0 || (u.plastic.weight > 0.0 && u.plastic.params.disney_sheen.max_element() > 0.0)
        }),
        ("fabric", "the DreamWorks fabric cone", |u| u.fabric.weight > 0.0 && u.fabric.params.specular > 0.0),
        ("glitter", "DreamWorks glitter: object-space Worley flakes found per shading point, GGX lobe per flake", |u| u.has_glitter()),
        ("thin-film", "thin-film interference coat (Airy, three wavelengths)", |u| u.thin_film.weight > 0.0 && u.specular_control > 0.0),
        ("double-specular", "two GGX roughnesses blended", |u| {
            (u.metal.weight > 0.0 && u.metal.params.mix2 > 0.0)
                || (u.plastic.weight > 0.0 && u.plastic.params.specular.is_some_and(|s| s.mix2 > 0.0))
        }),
        ("anisotropy", "anisotropic GGX", |u| {
            (u.metal.weight > 0.0 && u.metal.params.anisotropic != 0.0)
                || (u.plastic.weight > 0.0 && u.plastic.params.specular.is_some_and(|s| s.anisotropic != 0.0))
                || (u.glass.weight > 0.0 && u.glass.params.anisotropic != 0.0)
        }),
    ];
    for (effect, reason, pred) in effects {
        let who = materials_where(&|m| pred(&m.surface));
        if !who.is_empty() {
            plan.enable(effect, reason, who);
        }
    }
    if !desc.instancers.is_empty() {
        plan.enable("instancing", "instances share one BLAS per prototype under a TLAS", desc.instancers.keys().cloned());
    }
    let partial = materials_where(&|m| m.pass_through > 0.0);
    if !partial.is_empty() {
        plan.enable(
            "partial-presence",
            "opacityMode presence: rays pass the surface unbent in proportion to 1 - opacity, shadow rays too",
            partial,
        );
    }
    let subsurface = materials_where(&|m| m.medium().is_some());
    let smooth_subsurface = materials_where(&|m| {
        crate::caustics::ShadowGlass::of_medium_boundary(m).is_some_and(|b| b.roughness <= crate::caustics::SMOOTH_GLASS)
    });
    if !subsurface.is_empty() {
        plan.enable("subsurface", "random walk in a homogeneous medium behind a dielectric boundary (van de Hulst albedo)", subsurface);
    }
    let thin_lens: Vec<String> =
        desc.cameras.iter().filter(|(_, c)| !c.orthographic && c.f_stop > 0.0 && c.focus_distance > 0.0).map(|(p, _)| p.clone()).collect();
    if !thin_lens.is_empty() {
        plan.enable("depth-of-field", "thin-lens cameras (fStop, focusDistance): rays from points on the lens", thin_lens);
    }
    // What the renderer can do that this scene does not ask for, and so does not build.
    plan.skipped = [
        "subsurface",
        "partial-presence",
        "glitter",
        "textures",
        "normal-maps",
        "textured-cutouts",
        "textured-emission",
        "environment-map",
        "emissive-meshes",
        "instancing",
        "depth-of-field",
    ]
    .iter()
    .filter(|e| !plan.has(e))
    .map(|e| format!("{e}: not needed by this scene"))
    .collect();

    let used_materials: Vec<u32> = instances.iter().map(|i| i.material).collect::<std::collections::BTreeSet<u32>>().into_iter().collect();
    let light_set = LightSet::new(lights, scene_radius);
    tracing::info!(instances = instances.len(), blas_builds = builds, lights = light_set.lights.len(), "scene committed");
    let shadow_glass = materials.iter().map(crate::caustics::ShadowGlass::of).collect();
    let medium_boundary = materials.iter().map(crate::caustics::ShadowGlass::of_medium_boundary).collect();
    let media = materials.iter().map(|m| m.medium()).collect();
    Ok(CommittedScene {
        meshes,
        tangents,
        blases,
        instances,
        tlas,
        materials,
        textured,
        has_see_through,
        bsdfs: Default::default(),
        floored_bsdfs: Default::default(),
        every_lobe_bsdfs: Default::default(),
        shadow_glass,
        medium_boundary,
        smooth_subsurface,
        media,
        used_materials,
        lights: light_set,
        crossable_lights,
        infinite_lights,
        prim_paths,
        cameras: desc.cameras.clone(),
        bounds: (lo, hi),
        plan,
        warnings,
    })
}

impl CommittedScene {
    /// Builds the BSDFs for one energy-compensation setting, and the energy tables their
    /// lobes read, for the materials some instance uses: a render calls this before its first
    /// tile, so a render with compensation off never builds the compensation tables and the
    /// fallback material counts only when a mesh falls back to it.
    pub fn prepare_bsdfs(&self, energy_compensation: bool) -> &[crate::bsdf::Bsdf] {
        self.bsdfs[energy_compensation as usize].get_or_init(|| {
            let _span = tracing::info_span!("prepare_bsdfs", energy_compensation).entered();
            let set: Vec<crate::bsdf::Bsdf> = self.materials.iter().map(|m| m.bsdf(energy_compensation)).collect();
            self.used_materials.iter().for_each(|&m| set[m as usize].build_tables());
            set
        })
    }

    /// The BSDFs at every roughness floor of caustic avoidance (`[level][material]`, level 0
    /// the materials' own), built on first use.
    pub fn prepare_floored_bsdfs(&self, energy_compensation: bool) -> &[Vec<crate::bsdf::Bsdf>] {
        self.floored_bsdfs[energy_compensation as usize].get_or_init(|| {
            let _span = tracing::info_span!("prepare_floored_bsdfs", energy_compensation).entered();
            (0..crate::caustics::FLOOR_LEVELS)
                .map(|level| {
                    let floor = crate::caustics::RoughnessFloor::of_level(level);
                    self.materials.iter().map(|m| m.surface.with_roughness_floor(floor).bsdf(energy_compensation)).collect()
                })
                .collect()
        })
    }

    /// The BSDF of material `index` with every microfacet lobe at least as rough as floor
    /// `level` (0: the material's own).
    #[inline]
    pub fn bsdf_floored(&self, index: u32, energy_compensation: bool, level: usize) -> &crate::bsdf::Bsdf {
        if level == 0 {
            return self.bsdf(index, energy_compensation);
        }
        &self.prepare_floored_bsdfs(energy_compensation)[level][index as usize]
    }

    /// Material `index`'s BSDF holding every lobe the uber-material can build (unused ones at
    /// weight 0), with all their energy tables built: the cost without a render plan.
    pub fn bsdf_with_every_lobe(&self, index: u32, energy_compensation: bool) -> &crate::bsdf::Bsdf {
        &self.every_lobe_bsdfs[energy_compensation as usize].get_or_init(|| {
            let set: Vec<crate::bsdf::Bsdf> = self.materials.iter().map(|m| m.surface.bsdf_with_every_lobe(energy_compensation)).collect();
            set.iter().for_each(|b| b.build_tables());
            set
        })[index as usize]
    }

    /// The scattering medium behind material `index`'s surface (subsurface scattering).
    #[inline]
    pub fn medium(&self, index: u32) -> Option<crate::subsurface::Medium> {
        self.media.get(index as usize).copied().flatten()
    }

    /// Material `index`'s glass as transparent shadows see it (None: opaque to them).
    #[inline]
    pub fn shadow_glass(&self, index: u32) -> Option<crate::caustics::ShadowGlass> {
        self.shadow_glass.get(index as usize).copied().flatten()
    }

    /// Material `index`'s subsurface boundary as transparent shadows from inside its medium
    /// see it (None: no medium, or too rough to cross).
    #[inline]
    pub fn medium_boundary(&self, index: u32) -> Option<crate::caustics::ShadowGlass> {
        self.medium_boundary.get(index as usize).copied().flatten()
    }

    /// The BSDF of material `index` (unprepared), with or without energy compensation.
    #[inline]
    pub fn bsdf(&self, index: u32, energy_compensation: bool) -> &crate::bsdf::Bsdf {
        &self.prepare_bsdfs(energy_compensation)[index as usize]
    }

    /// Closest surface hit along `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.tlas.intersect(&self.blases, ray)
    }

    /// Material `index`'s inputs that vary over the surface, if any.
    #[inline]
    pub fn textured(&self, index: u32) -> Option<&crate::material::TexturedMaterial> {
        self.textured.get(index as usize).and_then(|t| t.as_deref())
    }

    /// Emitted radiance at world point `p` on triangle `triangle` of instance `instance`, for
    /// materials whose emission is textured (finest texture level: a light sample has no
    /// footprint).
    pub fn emission_at(&self, instance: u32, triangle: u32, p: Vec3) -> Vec3 {
        let inst = &self.instances[instance as usize];
        let Some(t) = self.textured(inst.material) else { return self.materials[inst.material as usize].emission };
        let [a, b, c] = self.meshes[inst.mesh].triangle(triangle as usize).map(|v| inst.transform.to_world.transform_point3(v));
        // Barycentrics of p by areas (p lies on the triangle up to rounding).
        let n = (b - a).cross(c - a);
        let nn = n.length_squared();
        if nn <= 0.0 {
            return Vec3::ZERO;
        }
        let b1 = (p - a).cross(c - a).dot(n) / nn;
        let b2 = (b - a).cross(p - a).dot(n) / nn;
        // Only what the lookup reads: no full surface (normals, tangents) per light sample.
        t.at(&self.point_on(instance, triangle, Vec2::new(b1, b2).clamp(Vec2::ZERO, Vec2::ONE))).0.emission
    }

    /// What a textured material needs to know of the surface at `s`, seen by a ray whose
    /// footprint is `width` wide at |cos| `cos` to the surface.
    pub fn shading_point(&self, s: &SurfaceHit, width: f32, cos: f32) -> crate::material::ShadingPoint<'_> {
        let mut sp = self.point_on(s.instance, s.triangle, s.bary);
        (sp.st, sp.width, sp.cos, sp.uv_density) = (s.st, width, cos, s.uv_density);
        sp
    }

    /// The shading point at barycentrics `bary` of `triangle` of `instance` for a lookup without
    /// footprint (the finest texture level): texture coordinates and primvars only.
    fn point_on(&self, instance: u32, triangle: u32, bary: Vec2) -> crate::material::ShadingPoint<'_> {
        let mesh = &self.meshes[self.instances[instance as usize].mesh];
        let tri = triangle as usize;
        let primvars = (!mesh.primvars.is_empty()).then_some(crate::material::graph::PrimvarSource { mesh, triangle: tri, bary });
        let st = mesh.uvs.interpolate(tri, mesh.indices[tri], bary);
        crate::material::ShadingPoint { st, primvars, width: 0.0, cos: 1.0, uv_density: 0.0 }
    }

    /// True when a ray along `dir` passes the surface `s` untouched: cut out there by a
    /// textured opacity (lookups at the finest level: shadow rays carry no footprint), or
    /// not present for this ray where the surface is partially present
    /// ([`Material::pass_through`]: a coin with that chance, tossed by [`see_through_coin`]).
    pub fn see_through_at(&self, s: &SurfaceHit, dir: Vec3) -> bool {
        let pass = match self.textured(s.material).filter(|t| t.may_see_through()) {
            Some(t) => {
                let m = t.at(&self.shading_point(s, 0.0, 1.0)).0;
                if m.cut_out {
                    return true;
                }
                m.pass_through
            }
            None => self.materials[s.material as usize].pass_through,
        };
        pass > 0.0 && see_through_coin(s.p, dir) < pass
    }

    /// True when a surface blocks the ray before `tmax`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, tmax: f32) -> bool {
        if self.has_see_through {
            return self.occluded_past_cutouts(ray, tmax);
        }
        self.tlas.occluded(&self.blases, ray, tmax)
    }

    /// Occlusion walking through the points of surfaces their opacity cuts out.
    fn occluded_past_cutouts(&self, ray: &Ray, tmax: f32) -> bool {
        let mut r = ray.with_tmax(tmax);
        // Each step passes one cut-out surface; a stack of more than this is treated as opaque.
        for _ in 0..MAX_CUTOUT_CROSSINGS {
            let Some(hit) = self.tlas.intersect(&self.blases, &r) else { return false };
            let s = self.surface(&hit);
            if !self.see_through_at(&s, r.dir) {
                return true;
            }
            let origin = crate::geometry::offset_ray_origin(s.p, if r.dir.dot(s.ng) > 0.0 { s.ng } else { -s.ng }, s.offset_scale);
            let left = r.tmax - (origin - r.origin).dot(r.dir) / r.dir.length_squared();
            if left <= 0.0 {
                return false;
            }
            r = Ray::new(origin, r.dir).with_tmax(left);
        }
        true
    }

    /// World-space surface data at `hit`.
    pub fn surface(&self, hit: &Hit) -> SurfaceHit {
        let inst = &self.instances[hit.instance as usize];
        let mesh = &self.meshes[inst.mesh];
        let tri = hit.triangle as usize;
        let [a, b, c] = mesh.triangle(tri);
        let w = Vec2::new(hit.bary.x, hit.bary.y);
        let p_obj = a * (1.0 - w.x - w.y) + b * w.x + c * w.y;
        let p = inst.transform.to_world.transform_point3(p_obj);
        let ng = (inst.transform.normal_matrix * (b - a).cross(c - a)).normalize_or_zero();
        let ng = if ng == Vec3::ZERO { Vec3::Z } else { ng };
        let ns = mesh
            .shading_normal(tri, w)
            .map(|n| (inst.transform.normal_matrix * n).normalize_or_zero())
            .filter(|n| *n != Vec3::ZERO && n.is_finite())
            .unwrap_or(ng);
        let m = inst.transform.to_world.matrix3;
        let edges = (m * glam::Vec3A::from(b - a)).abs().max((m * glam::Vec3A::from(c - a)).abs()).max_element();
        let offset_scale = p.abs().max_element().max(edges);
        let up = Vec3::from(m * glam::Vec3A::Y);
        let mut s = SurfaceHit {
            p,
            ng,
            ns,
            material: inst.material,
            light: inst.emitter_base.map(|b| b + hit.triangle),
            offset_scale,
            up,
            st: None,
            uv_density: 0.0,
            dpds: Vec3::ZERO,
            dpdt: Vec3::ZERO,
            instance: hit.instance,
            triangle: hit.triangle,
            bary: w,
            tangent: glam::Vec4::ZERO,
        };
        if let Some(v) = self.tangents[inst.mesh].as_ref().and_then(|t| t.interpolate(tri, mesh.indices[tri], w)) {
            s.tangent = Vec3::from(m * glam::Vec3A::from(v.truncate())).extend(if v.w < 0.0 { -1.0 } else { 1.0 });
        }
        if let Some([ta, tb, tc]) = mesh.uvs.corners(tri, mesh.indices[tri]) {
            s.st = Some(ta * (1.0 - w.x - w.y) + tb * w.x + tc * w.y);
            let (d1, d2) = (tb - ta, tc - ta);
            let (e1, e2) = (Vec3::from(m * glam::Vec3A::from(b - a)), Vec3::from(m * glam::Vec3A::from(c - a)));
            let uv_area = d1.perp_dot(d2);
            let world_area = e1.cross(e2).length();
            if uv_area != 0.0 && world_area > 0.0 {
                s.uv_density = (uv_area.abs() / world_area).sqrt();
                let r = 1.0 / uv_area;
                s.dpds = (e1 * d2.y - e2 * d1.y) * r;
                s.dpdt = (e2 * d1.x - e1 * d2.x) * r;
            }
        }
        s
    }

    /// The scene's camera at `path`, the first camera when `path` is empty, or a default
    /// camera framing the scene's bounds when it has none.
    pub fn camera(&self, path: &str) -> Result<CameraDesc, SceneError> {
        if !path.is_empty() {
            return self.cameras.get(path).cloned().ok_or_else(|| SceneError::Dangling {
                prim: "render settings".into(),
                field: "camera".into(),
                target: path.into(),
            });
        }
        if let Some(c) = self.cameras.values().next() {
            return Ok(c.clone());
        }
        let (lo, hi) = self.bounds;
        let (center, radius) = if lo.x <= hi.x { (0.5 * (lo + hi), 0.5 * (hi - lo).length().max(1e-3)) } else { (Vec3::ZERO, 1.0) };
        let d = CameraDesc::default();
        // Back off along +Z until the bounding sphere fits the vertical field of view.
        let half = (0.5 * d.vertical_aperture / d.focal_length).atan();
        let dist = radius / half.sin();
        Ok(CameraDesc { transform: Affine3A::from_translation(center + Vec3::Z * dist), near: (dist - radius).max(1e-3) * 0.5, ..d })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Normals;

    fn tri_mesh() -> Arc<Mesh> {
        Arc::new(Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            normals: Normals::None,
            ..Default::default()
        })
    }

    #[test]
    fn validation_names_prim_and_field() {
        let mut m = (*tri_mesh()).clone();
        m.indices[0][2] = 7;
        let e = validate_mesh("/World/Tri", &m).unwrap_err().to_string();
        assert!(e.contains("/World/Tri") && e.contains("faceVertexIndices") && e.contains("index 7"), "{e}");
        let mut m = (*tri_mesh()).clone();
        m.positions[1].y = f32::NAN;
        let e = validate_mesh("/World/Tri", &m).unwrap_err().to_string();
        assert!(e.contains("points") && e.contains("point 1"), "{e}");
    }

    #[test]
    fn moving_a_mesh_reuses_its_blas() {
        let mut desc = SceneDesc::default();
        desc.meshes
            .insert("/A".into(), MeshDesc { mesh: tri_mesh(), transform: Affine3A::IDENTITY, material: String::new(), visible: true });
        let mut cache = BlasCache::default();
        commit(&desc, &mut cache).unwrap();
        assert_eq!(cache.last_builds, 1);
        desc.meshes.get_mut("/A").unwrap().transform = Affine3A::from_translation(Vec3::X);
        let scene = commit(&desc, &mut cache).unwrap();
        assert_eq!(cache.last_builds, 0);
        let hit = scene.intersect(&Ray::new(Vec3::new(1.2, 0.2, 1.0), -Vec3::Z)).expect("moved triangle is hit");
        assert!((hit.t - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_cut_out_material_removes_its_surfaces() {
        use crate::material::{MaterialNetwork, MaterialNode, ParamValue};
        let network = |opacity: f32| MaterialNetwork {
            nodes: vec![MaterialNode {
                path: "/M/S".into(),
                node_type_id: "UsdPreviewSurface".into(),
                parameters: [("opacity", opacity), ("opacityThreshold", 0.5)]
                    .into_iter()
                    .map(|(k, v)| (k.to_string(), ParamValue::Float(v)))
                    .collect(),
            }],
            connections: vec![],
            surface_node: "/M/S".into(),
        };
        for (opacity, hit) in [(0.2, false), (0.7, true)] {
            let mut desc = SceneDesc::default();
            desc.materials.insert("/M".into(), network(opacity));
            desc.meshes
                .insert("/A".into(), MeshDesc { mesh: tri_mesh(), transform: Affine3A::IDENTITY, material: "/M".into(), visible: true });
            let scene = commit(&desc, &mut BlasCache::default()).unwrap();
            let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
            assert_eq!(scene.intersect(&ray).is_some(), hit, "opacity {opacity} against threshold 0.5");
            assert_eq!(scene.occluded(&ray, 10.0), hit, "a cut-out casts no shadow either");
        }
    }
}
