//! Commit: the scene description turned into the structures the renderer traces against, as
//! named steps — materials (and the textures they read), geometry, instances, features,
//! tangents, bounds and the TLAS, lights — each building only what the features call for.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::sync::Arc;

use glam::{Affine3A, Vec3};

use super::displace::displaced_meshes;
use super::features::plan_of;
use super::materials::Materials;
use super::{BlasCache, CommittedScene, InstanceData, LightLinks, MAX_COORDINATE, MeshDesc, SceneDesc, SceneError, validate_mesh};
use crate::bvh::{Blas, BuildQuality, Tlas, TlasInstance};
use crate::caustics::ShadowGlass;
use crate::geometry::{Attribute, Mesh, Transform};
use crate::light::motion::{LightMotion, Placement};
use crate::light::{Light, LightSet, MaterialSync, MeshLight, Shape};
use crate::material::Material;
use crate::plan::{Feature, RenderPlan};

/// Builds the renderable scene from its description, reusing cached BLASes.
pub fn commit(desc: &SceneDesc, cache: &mut BlasCache) -> Result<CommittedScene, SceneError> {
    let _span = tracing::info_span!("commit", meshes = desc.meshes.len(), lights = desc.lights.len()).entered();
    let mut warnings = Vec::new();
    let materials = Materials::resolve(desc, cache, &mut warnings);
    let mut plan = plan_of(desc, &materials);
    let displaced = match plan.has(Feature::Displacement) {
        true => displaced_meshes(desc, &materials, cache, &mut warnings),
        false => {
            cache.displaced.clear();
            HashMap::new()
        }
    };
    let diced_triangles = displaced.iter().map(|(p, m)| m.indices.len().saturating_sub(desc.meshes[*p].mesh.indices.len()) as u64).sum();
    let geometry = Geometry::build(desc, &displaced, cache, &mut warnings)?;
    let (mut instances, prim_paths) = place_instances(desc, &geometry, &materials)?;
    let tangents = match plan.has(Feature::NormalMaps) {
        true => tangents_of(&instances, &geometry.meshes, &materials, cache),
        false => vec![None; geometry.meshes.len()],
    };
    let volumes = volumes_of(desc)?;
    let (lo, hi) =
        volumes.iter().fold(bounds_of(&instances, &geometry.blases, &prim_paths)?, |(lo, hi), v| (lo.min(v.bounds.0), hi.max(v.bounds.1)));
    let tlas_instances: Vec<TlasInstance> =
        instances.iter().map(|i| TlasInstance { blas: i.mesh, transform: i.transform, motion: i.motion.clone() }).collect();
    let tlas = Tlas::build(&geometry.blases, &tlas_instances);
    let scene_radius = if lo.x <= hi.x { 0.5 * (hi - lo).length().max(1e-3) } else { 1.0 };
    let mut lights = Lights::gather(desc, &materials, &geometry.meshes, &mut instances, &prim_paths, &mut warnings);
    lights.plan(&mut plan);
    let links = LightLinks::build(desc, &lights.usd_lights, &lights.emitters.runs, &instances, &prim_paths);
    if lights.all.is_empty() {
        warnings.push("the scene has no lights and no emissive surfaces: the image will be black".into());
    }
    let used_materials: Vec<u32> = instances.iter().map(|i| i.material).collect::<BTreeSet<u32>>().into_iter().collect();
    let per_material = |f: fn(&Material) -> Option<ShadowGlass>, on: bool| -> Vec<Option<ShadowGlass>> {
        materials.list.iter().map(|m| if on { f(m) } else { None }).collect()
    };
    let subsurface = plan.has(Feature::Subsurface);
    let shadow_glass = per_material(ShadowGlass::of, plan.features.has_any(&[Feature::Transmission, Feature::ThinTransmission]));
    let medium_boundary = per_material(ShadowGlass::of_medium_boundary, subsurface);
    let media = materials.list.iter().map(|m| if subsurface { m.medium() } else { None }).collect();
    let smooth_subsurface = plan.prims(Feature::Subsurface).iter().filter(|m| materials.smooth_behind(m)).cloned().collect();
    let mut light_set = LightSet::new(std::mem::take(&mut lights.all), scene_radius);
    if let Some(links) = &links {
        let per_group = light_set.select_per_group(links.group_count(), |light, group| links.illuminates(light, group));
        plan_links(links, &lights, per_group, &mut plan);
    }
    // Each thing is said once, however many instances or lobes run into it.
    let mut said = std::collections::HashSet::new();
    warnings.retain(|w| said.insert(w.clone()));
    tracing::info!(instances = instances.len(), blas_builds = cache.last_builds, lights = light_set.lights.len(), "scene committed");
    Ok(CommittedScene {
        meshes: geometry.meshes,
        diced_triangles,
        tangents,
        blases: geometry.blases,
        instances,
        tlas,
        materials: materials.list,
        textured: materials.textured,
        bsdfs: Default::default(),
        floored_bsdfs: Default::default(),
        every_lobe_bsdfs: Default::default(),
        inside_medium_bsdfs: Default::default(),
        shadow_glass,
        medium_boundary,
        smooth_subsurface,
        media,
        used_materials,
        lights: light_set,
        glow_scales: std::mem::take(&mut lights.emitters.glow_scales),
        crossable_lights: lights.crossable,
        links,
        infinite_lights: lights.infinite,
        prim_paths,
        cameras: desc.cameras.clone(),
        bounds: (lo, hi),
        volumes,
        plan,
        warnings,
    })
}

/// The volumes, validated, with their majorant grids.
fn volumes_of(desc: &SceneDesc) -> Result<Vec<crate::volume::Volume>, SceneError> {
    desc.volumes
        .iter()
        .map(|(path, v)| {
            crate::volume::validate_volume(path, v)?;
            Ok(crate::volume::Volume::new(path, v))
        })
        .collect()
}

/// Triangles from which a mesh's BLAS is built alone, on the committing thread, rather than
/// beside others on the rayon pool. Its build is parallel inside; built on a pool thread beside
/// the others, the production bench's 1M-triangle terrain left the commit 7 bytes per triangle
/// more resident (99 against 92, after `malloc_trim`).
pub(super) const BUILT_ALONE: usize = 1 << 16;

/// A mesh's BLAS from the last commit, when its geometry is unchanged.
type CachedBlas = Option<Arc<Blas>>;

/// One BLAS per distinct mesh prim that has triangles and renders (visible, or a prototype).
pub(super) struct Geometry<'d> {
    pub meshes: Vec<Arc<Mesh>>,
    pub blases: Vec<Arc<Blas>>,
    /// Index in [`Self::meshes`] by mesh path.
    pub slot: HashMap<&'d str, usize>,
}

impl<'d> Geometry<'d> {
    /// Validates the meshes and builds the BLASes whose geometry (or its displaced form in
    /// `displaced`) changed since the last commit,
    /// those of meshes below [`BUILT_ALONE`] triangles several at once: a scene of many
    /// distinct meshes built them one after another (the principled grid's 51 subdivided
    /// spheres took 0.8 s of its 2.7 s load on one core).
    fn build(
        desc: &'d SceneDesc,
        displaced: &HashMap<&str, Arc<Mesh>>,
        cache: &mut BlasCache,
        warnings: &mut Vec<String>,
    ) -> Result<Self, SceneError> {
        use rayon::prelude::*;
        let mut out = Geometry { meshes: Vec::new(), blases: Vec::new(), slot: HashMap::new() };
        let prototypes: HashSet<&str> = desc.instancers.values().map(|i| i.prototype.as_str()).collect();
        // Each mesh that renders: its path, its geometry, and its BLAS when the cache has it.
        let mut kept: Vec<(&String, Arc<Mesh>, CachedBlas)> = Vec::new();
        for (path, m) in &desc.meshes {
            validate_mesh(path, &m.mesh)?;
            let mesh = displaced.get(path.as_str()).unwrap_or(&m.mesh);
            if m.mesh.indices.is_empty() {
                warnings.push(format!("{path}: mesh has no triangles and is skipped"));
                continue;
            }
            if !(m.visible || prototypes.contains(path.as_str())) {
                continue;
            }
            let cached = cache.entries.get(path).filter(|(geom, _)| Arc::ptr_eq(geom, mesh)).map(|(_, blas)| blas.clone());
            kept.push((path, mesh.clone(), cached));
        }
        let builds = kept.iter().filter(|(_, _, cached)| cached.is_none()).count();
        let build = |(_, mesh, cached): &(&String, Arc<Mesh>, CachedBlas)| {
            cached.clone().unwrap_or_else(|| Arc::new(Blas::build(mesh, BuildQuality::Medium)))
        };
        // Big meshes one after another on this thread (each build is parallel inside), the
        // rest several at once.
        let big: Vec<Option<Arc<Blas>>> =
            kept.iter().map(|k| (k.2.is_none() && k.1.indices.len() >= BUILT_ALONE).then(|| build(k))).collect();
        let blases: Vec<Arc<Blas>> = kept.par_iter().zip(big).map(|(k, big)| big.unwrap_or_else(|| build(k))).collect();
        let mut fresh = HashMap::new();
        for ((path, mesh, _), blas) in kept.into_iter().zip(blases) {
            fresh.insert(path.clone(), (mesh.clone(), blas.clone()));
            out.slot.insert(path.as_str(), out.meshes.len());
            out.meshes.push(mesh.clone());
            out.blases.push(blas);
        }
        cache.entries = fresh;
        cache.last_builds = builds;
        Ok(out)
    }
}

/// The instances in the TLAS: visible meshes, then instancer instances; and the prim path
/// each comes from.
fn place_instances(desc: &SceneDesc, geometry: &Geometry, materials: &Materials) -> Result<(Vec<InstanceData>, Vec<String>), SceneError> {
    let mut instances = Vec::new();
    let mut prim_paths: Vec<String> = Vec::new();
    let mut push = |path: &str, mesh: usize, xf: &Affine3A, material: u32, motion: Option<Arc<[Affine3A]>>| -> Result<(), SceneError> {
        let transform = Transform::new(*xf).ok_or_else(|| SceneError::Invalid {
            prim: path.to_string(),
            field: "transform".into(),
            problem: "singular or not finite".into(),
        })?;
        if prim_paths.last().is_none_or(|p| p != path) {
            prim_paths.push(path.to_string());
        }
        instances.push(InstanceData { mesh, transform, motion, material, emitter_base: None, prim: prim_paths.len() as u32 - 1 });
        Ok(())
    };
    for (path, m) in desc.meshes.iter().filter(|(_, m)| m.visible) {
        if let Some(&slot) = geometry.slot.get(path.as_str()) {
            let material = materials.for_mesh(path, m);
            if !materials.removes_its_surfaces(material) {
                push(path, slot, &m.transform, material, motion_of(path, m)?)?;
            }
        }
    }
    for (path, inst) in &desc.instancers {
        let Some(&slot) = geometry.slot.get(inst.prototype.as_str()) else {
            if desc.meshes.contains_key(&inst.prototype) {
                continue; // an empty prototype was already reported
            }
            return Err(SceneError::Dangling { prim: path.clone(), field: "prototype".into(), target: inst.prototype.clone() });
        };
        let material = materials.for_mesh(path, &desc.meshes[&inst.prototype]);
        if materials.removes_its_surfaces(material) {
            continue;
        }
        let k = inst.motion_samples();
        if !inst.motion.is_empty() && (k * inst.transforms.len() != inst.motion.len() || k < 2) {
            let problem = format!("{} placements for {} instances", inst.motion.len(), inst.transforms.len());
            return Err(SceneError::Invalid { prim: path.clone(), field: "motion".into(), problem });
        }
        for (i, xf) in inst.transforms.iter().enumerate() {
            let motion = match k {
                0 => None,
                _ => {
                    let samples = &inst.motion[i * k..(i + 1) * k];
                    crate::motion::check_samples(samples).map_err(|problem| SceneError::Invalid {
                        prim: path.clone(),
                        field: format!("motion of instance {i}"),
                        problem,
                    })?;
                    Some(samples.into())
                }
            };
            push(path, slot, xf, material, motion)?;
        }
    }
    Ok((instances, prim_paths))
}

/// A mesh's motion over the shutter, checked.
fn motion_of(path: &str, m: &MeshDesc) -> Result<Option<Arc<[Affine3A]>>, SceneError> {
    crate::motion::check_samples(&m.motion).map_err(|problem| SceneError::Invalid {
        prim: path.into(),
        field: "motion".into(),
        problem,
    })?;
    Ok((!m.motion.is_empty()).then(|| m.motion.iter().copied().collect()))
}

/// MikkTSpace tangents for the meshes drawn with a normal map, each computed once per
/// geometry and kept between commits.
fn tangents_of(
    instances: &[InstanceData],
    meshes: &[Arc<Mesh>],
    materials: &Materials,
    cache: &mut BlasCache,
) -> Vec<Option<Arc<Attribute<glam::Vec4>>>> {
    let mut tangents = vec![None; meshes.len()];
    let mut kept = Vec::new();
    let mut tried = vec![false; meshes.len()];
    for inst in instances {
        let mesh = &meshes[inst.mesh];
        let normal_mapped = materials.textured[inst.material as usize].as_deref().is_some_and(|t| t.has_normal_map());
        if tried[inst.mesh] || !normal_mapped || mesh.uvs.is_empty() {
            continue;
        }
        tried[inst.mesh] = true;
        let t = match cache.tangents.iter().find(|(m, _)| Arc::ptr_eq(m, mesh)) {
            Some((_, t)) => Some(t.clone()),
            None => crate::tangents::mikktspace(mesh).map(Arc::new),
        };
        if let Some(t) = &t {
            kept.push((mesh.clone(), t.clone()));
        }
        tangents[inst.mesh] = t;
    }
    cache.tangents = kept;
    tangents
}

/// World bounds of the instances, for sizing infinite lights and the default camera; an
/// instance whose transform carries its geometry beyond what f32 holds is an error naming it.
fn bounds_of(instances: &[InstanceData], blases: &[Arc<Blas>], prim_paths: &[String]) -> Result<(Vec3, Vec3), SceneError> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for inst in instances {
        let (a, b) = blases[inst.mesh].bounds();
        // A moving instance: its bounds over the shutter, checked the same way.
        if let Some(m) = &inst.motion {
            let (ml, mh) = crate::motion::bounds_over(m, a, b);
            for w in [ml, mh] {
                if !w.is_finite() || w.abs().max_element() > MAX_COORDINATE {
                    return Err(SceneError::Invalid {
                        prim: prim_paths[inst.prim as usize].clone(),
                        field: "motion".into(),
                        problem: format!("moves the geometry to {w}, beyond ±{MAX_COORDINATE:e}"),
                    });
                }
            }
            (lo, hi) = (lo.min(ml), hi.max(mh));
        }
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
    Ok((lo, hi))
}

/// The lights: UsdLux lights, then one per emissive triangle.
struct Lights {
    all: Vec<Light>,
    /// Paths of the UsdLux lights (the first entries of [`Self::all`]).
    usd_lights: Vec<String>,
    /// The emitting instances' triangle lights (after the UsdLux lights).
    emitters: Emitters,
    /// The UsdLux lights a ray can pass through, in a BVH: with thousands of them a linear
    /// scan per ray would dominate the render.
    crossable: crate::light::tree::LightTree,
    /// Indices of the lights at infinity.
    infinite: Vec<u32>,
}

impl Lights {
    fn gather(
        desc: &SceneDesc,
        materials: &Materials,
        meshes: &[Arc<Mesh>],
        instances: &mut [InstanceData],
        prim_paths: &[String],
        warnings: &mut Vec<String>,
    ) -> Lights {
        let mut all: Vec<Light> = Vec::new();
        let mut usd_lights = Vec::new();
        for (path, l) in &desc.lights {
            match l.commit_with(materials.environments.get(path.as_str()).cloned()) {
                Some(light) => {
                    all.push(light);
                    usd_lights.push(path.clone());
                }
                None => {
                    warnings.push(format!("{path}: light emits nothing (zero size, zero intensity or a singular transform) and is skipped"))
                }
            }
        }
        let emitters = add_emitters(&mut all, desc, materials, meshes, instances, prim_paths);
        let n = usd_lights.len();
        let crossable = crate::light::tree::LightTree::build((0..n).filter_map(|i| all[i].bounds(1.0).map(|b| (i as u32, b))).collect(), n);
        let infinite = (0..n as u32).filter(|&i| all[i as usize].shape.is_infinite()).collect();
        Lights { all, usd_lights, emitters, crossable, infinite }
    }

    /// The light features, with the prims that call for them.
    fn plan(&self, plan: &mut RenderPlan) {
        let n = self.usd_lights.len();
        let reason = format!("{n} UsdLux light(s), chosen through a light tree with adaptive splitting, MIS (power heuristic)");
        plan.call_for_because(Feature::Lights, reason, self.usd_lights.iter().cloned());
        let mut emissive: Vec<String> = self.emitters.runs.iter().map(|r| r.prim.clone()).collect();
        emissive.dedup();
        let e = &self.emitters;
        let reason = match e.mesh_lights {
            0 => format!("{} emissive triangle(s) sampled by solid angle (by area when small or far) with MIS", e.triangles),
            n => format!(
                "{} emissive triangle(s) sampled by solid angle (by area when small or far) with MIS, {n} mesh(es) of them UsdLux mesh lights",
                e.triangles
            ),
        };
        plan.call_for_because(Feature::EmissiveMeshes, reason, emissive);
    }
}

/// What light linking does for this scene, for the plan.
fn links_reason(per_group: Option<usize>) -> String {
    let what = "lights that illuminate only the prims of their collection:lightLink";
    match per_group {
        Some(n) => format!("{what}: {n} light choice(s) of their own for the receiver groups, each among the lights that reach it"),
        None => format!(
            "{what}: too many receiver groups for a light choice each (over {} entries), so they share one and skip the lights that do not reach them",
            crate::light::MAX_GROUP_SELECTION_ENTRIES
        ),
    }
}

/// The linking features, each with the lights (UsdLux lights and mesh lights) that call for
/// it; `per_group`: the light choices of their own the receiver groups got
/// ([`LightSet::select_per_group`]).
fn plan_links(links: &LightLinks, lights: &Lights, per_group: Option<usize>, plan: &mut RenderPlan) {
    // UsdLux lights by their own links; mesh lights by their runs of triangle lights, not
    // triangle by triangle (an instancer's instances, consecutive runs, named once).
    let n = lights.usd_lights.len();
    let usd = links.linked().take_while(|&(i, ..)| i < n).map(|(i, l, s)| (&lights.usd_lights[i], l, s));
    let meshes = lights.emitters.runs.iter().map(|r| (&r.prim, r.links.0.is_some(), r.links.1.is_some()));
    let (mut light, mut shadow): (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
    for (name, l, s) in usd.chain(meshes) {
        for (linked, names) in [(l, &mut light), (s, &mut shadow)] {
            if linked && names.last() != Some(name) {
                names.push(name.clone());
            }
        }
    }
    plan.call_for_because(Feature::LightLinking, links_reason(per_group), light);
    plan.call_for(Feature::ShadowLinking, shadow);
}

/// The mesh light of the prim an instance comes from: its mesh's, or its instancer
/// prototype's.
fn mesh_light_of<'d>(desc: &'d SceneDesc, prim: &str) -> Option<&'d MeshLight> {
    let mesh = desc.meshes.get(prim).or_else(|| desc.instancers.get(prim).and_then(|i| desc.meshes.get(&i.prototype)));
    mesh.and_then(|m| m.light.as_ref())
}

/// A normalized mesh light's key: the mesh it is part of (itself when whole) and where the
/// instance places it, so the parts of one placed mesh share their light's area.
type LightKey<'a> = (&'a str, [u32; 12]);

/// The [`LightKey`] of instance `inst` of `prim`, whose mesh light is `light`.
fn light_key<'a>(light: &'a MeshLight, prim: &'a str, inst: &InstanceData) -> LightKey<'a> {
    (light.part_of.as_deref().unwrap_or(prim), inst.transform.to_world.to_cols_array().map(f32::to_bits))
}

/// The world-space area of each normalized mesh light, summed over its parts (UsdLux's
/// `normalize` divides by the light's whole surface, however its faces are split).
fn mesh_light_areas<'a>(
    desc: &'a SceneDesc,
    meshes: &[Arc<Mesh>],
    instances: &[InstanceData],
    prim_paths: &'a [String],
) -> HashMap<LightKey<'a>, f32> {
    let mut areas = HashMap::new();
    for inst in instances {
        let prim = prim_paths[inst.prim as usize].as_str();
        let Some(light) = mesh_light_of(desc, prim).filter(|l| l.normalize) else { continue };
        let mesh = &meshes[inst.mesh];
        let xf = inst.transform.to_world;
        let area = |[a, b, c]: [Vec3; 3]| {
            let [a, b, c] = [a, b, c].map(|v| xf.transform_point3(v));
            0.5 * (b - a).cross(c - a).length()
        };
        let sum: f32 = (0..mesh.triangle_count()).map(|t| area(mesh.triangle(t))).filter(|a| a.is_finite()).sum();
        *areas.entry(light_key(light, prim, inst)).or_insert(0.0) += sum;
    }
    areas
}

/// The triangle lights of one emitting instance: `count` lights from `first`, from `prim`,
/// with its mesh light's links.
pub(super) struct EmitterRun {
    pub first: u32,
    pub count: u32,
    pub prim: String,
    pub links: (Option<String>, Option<String>),
}

/// What the emitting instances added: their runs of triangle lights, and the scale of each
/// textured glow a mesh light multiplies (by instance).
#[derive(Default)]
struct Emitters {
    runs: Vec<EmitterRun>,
    triangles: usize,
    mesh_lights: usize,
    glow_scales: Vec<(u32, Vec3)>,
}

/// One triangle light per triangle of each instance whose material emits or whose mesh is a
/// light, appended to `lights`.
fn add_emitters(
    lights: &mut Vec<Light>,
    desc: &SceneDesc,
    materials: &Materials,
    meshes: &[Arc<Mesh>],
    instances: &mut [InstanceData],
    prim_paths: &[String],
) -> Emitters {
    let mut out = Emitters::default();
    let areas = mesh_light_areas(desc, meshes, instances, prim_paths);
    for (index, inst) in instances.iter_mut().enumerate() {
        let m = &materials.list[inst.material as usize];
        let prim = &prim_paths[inst.prim as usize];
        let mesh_light = mesh_light_of(desc, prim);
        if mesh_light.is_none() && !m.is_emissive() {
            continue;
        }
        let mesh = &meshes[inst.mesh];
        let world = |t: usize| mesh.triangle(t).map(|v| inst.transform.to_world.transform_point3(v));
        let textured_glow = materials.textured[inst.material as usize].as_ref().is_some_and(|t| t.emission_varies());
        let (emission, varies) = match mesh_light {
            None => (m.emission, textured_glow),
            Some(l) => {
                let area = areas.get(&light_key(l, prim, inst)).copied().unwrap_or(0.0);
                let tints = l.sync == MaterialSync::GlowTintsLight && m.is_emissive();
                if tints && textured_glow {
                    out.glow_scales.push((index as u32, l.radiance(Vec3::ZERO, area)));
                }
                (l.radiance(m.emission, area), tints && textured_glow)
            }
        };
        let first = lights.len() as u32;
        inst.emitter_base = Some(first);
        let placement = match &inst.motion {
            Some(samples) => Placement::Moving(samples.clone()),
            None => Placement::Still(inst.transform.to_world),
        };
        let moves = inst.motion.is_some() || mesh.deformation_samples() > 0;
        for t in 0..mesh.triangle_count() {
            let p = world(t);
            // Degenerate triangles keep their slot (indices must line up) but emit nothing.
            let shape = Shape::triangle(p, emission).unwrap_or(Shape::Triangle { p, n: Vec3::Z, area: 0.0, l: Vec3::ZERO });
            let mut light = Light::plain(shape, true);
            light.multipliers = mesh_light.map_or((1.0, 1.0), MeshLight::multipliers);
            light.textured_emitter = varies.then_some((index as u32, t as u32));
            light.motion = moves.then(|| {
                let (mesh, triangle, placement) = (mesh.clone(), t as u32, placement.clone());
                Arc::new(LightMotion::Triangle { mesh, triangle, placement, l: emission })
            });
            lights.push(light);
        }
        out.triangles += mesh.triangle_count();
        out.mesh_lights += usize::from(mesh_light.is_some());
        let links = mesh_light.map_or((None, None), |l| (l.light_link.clone(), l.shadow_link.clone()));
        out.runs.push(EmitterRun { first, count: mesh.triangle_count() as u32, prim: prim.clone(), links });
    }
    out
}
