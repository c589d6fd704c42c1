//! `tessera inspect SCENE --json`: what the client's USD reader makes of a stage, in a shape
//! that `fixtures/inspect_usd.py` also produces from Pixar's usd-core, so the two readers
//! can be compared field by field.
//!
//! Matrices are USD's: row-major, row vectors, translation in the last row, flattened.

use std::path::Path;

use anyhow::Result;
use glam::{Affine3A, Mat4};
use render_core::material::ParamValue;
use serde_json::{Map, Value, json};

use crate::usd::Translation;

fn usd_matrix(a: &Affine3A) -> Value {
    // glam's columns are USD's rows (see `usd::values::matrix`).
    json!(Mat4::from(*a).to_cols_array().iter().map(|&x| x as f64).collect::<Vec<_>>())
}

fn param(v: &ParamValue) -> Value {
    match v {
        ParamValue::Float(x) => json!(x),
        ParamValue::Float3(c) => json!([c.x, c.y, c.z]),
        ParamValue::Int(i) => json!(i),
        ParamValue::Bool(b) => json!(b),
        ParamValue::String(s) | ParamValue::Asset(s) => json!(s),
        ParamValue::Float2(c) => json!([c.x, c.y]),
        ParamValue::Float4(c) => json!([c.x, c.y, c.z, c.w]),
        // The authored path, as usd-core reports the asset; the hash says it was read.
        ParamValue::Texture { source, .. } | ParamValue::Udim { source, .. } => json!(source),
    }
}

/// The translation as JSON: meshes (world matrix, triangles, material, visibility),
/// instancers (one per prototype mesh: the instances' world matrices), lights, cameras and
/// the material networks' surface shaders.
pub fn to_json(t: &Translation) -> Value {
    // Native instancing is how we render instanceable prims, not what the stage says: list
    // each instance proxy as the mesh a flattened stage has, and hide the shared prototypes.
    let native: std::collections::HashSet<usize> = t.native_instances.iter().map(|n| n.instancer).collect();
    let prototypes: std::collections::HashSet<&str> = native.iter().map(|&i| t.instancers[i].1.prototype.as_str()).collect();
    let mut meshes = Map::new();
    // A mesh's subdivision, by its path; a GeomSubset's mesh is named by the subset, one level below.
    let subdivided: std::collections::HashMap<&str, &crate::usd::Subdivided> = t.subdivided.iter().map(|s| (s.path.as_str(), s)).collect();
    let skinned: std::collections::HashMap<&str, &crate::usd::Skinned> = t.skinned.iter().map(|s| (s.path.as_str(), s)).collect();
    let subdivision_of = |path: &str| {
        subdivided.get(path).or_else(|| path.rsplit_once('/').and_then(|(mesh, _)| subdivided.get(mesh))).map(|s| subdivision_json(s))
    };
    let links = LinkLists::of(t);
    for n in &t.native_instances {
        let mut mesh = json!({ "world": usd_matrix(&n.world), "triangles": n.triangles, "material": n.material, "visible": n.visible });
        links.add_to(&mut mesh, &t.instancers[n.instancer].1.link_collections);
        if !n.motion.is_empty() {
            mesh["motion"] = Value::Array(n.motion.iter().map(usd_matrix).collect());
        }
        if let Some(s) = subdivided.get(t.instancers[n.instancer].1.prototype.as_str()) {
            mesh["subdivision"] = subdivision_json(s);
        }
        meshes.insert(n.path.clone(), mesh);
    }
    for (path, m) in t.meshes.iter().filter(|(p, _)| !prototypes.contains(p.as_str())) {
        // GeomSubsets render as meshes of their own, named by the subset under the mesh.
        let skin = skinned.get(path.as_str()).or_else(|| path.rsplit_once('/').and_then(|(mesh, _)| skinned.get(mesh)));
        let mut mesh = mesh_json(m, subdivision_of(path), skin.copied());
        links.add_to(&mut mesh, &m.link_collections);
        meshes.insert(path.clone(), mesh);
    }
    let mut instancers = Map::new();
    for (path, i) in t.instancers.iter().enumerate().filter(|(k, _)| !native.contains(k)).map(|(_, x)| x) {
        instancers.insert(
            path.clone(),
            json!({ "prototype": i.prototype, "instances": i.transforms.iter().map(usd_matrix).collect::<Vec<_>>() }),
        );
    }
    let mut lights = Map::new();
    for (path, l) in &t.lights {
        let mut light = json!({
            "world": usd_matrix(&l.transform),
            "intensity": l.intensity,
            "exposure": l.exposure,
            "color": [l.color.x, l.color.y, l.color.z],
            "normalize": l.normalize,
        });
        if !l.motion.is_empty() {
            light["motion"] = Value::Array(l.motion.iter().map(usd_matrix).collect());
        }
        lights.insert(path.clone(), light);
    }
    let mut cameras = Map::new();
    for (path, c) in &t.cameras {
        cameras.insert(
            path.clone(),
            json!({
                "world": usd_matrix(&c.transform),
                "focalLength": c.focal_length,
                "horizontalAperture": c.horizontal_aperture,
                "verticalAperture": c.vertical_aperture,
                "projection": if c.orthographic { "orthographic" } else { "perspective" },
                "fStop": c.f_stop,
                "focusDistance": c.focus_distance,
                "shutterOpen": c.shutter_open,
                "shutterClose": c.shutter_close,
                "exposureScale": c.exposure.exp2(),
            }),
        );
    }
    let mut materials = Map::new();
    for (path, n) in &t.materials {
        let surface = n.nodes.iter().find(|node| node.path == n.surface_node);
        let inputs: Map<String, Value> =
            surface.map(|s| s.parameters.iter().map(|(k, v)| (k.clone(), param(v))).collect()).unwrap_or_default();
        // A MaterialX surface is listed as authored (what usd-core finds), with what it became.
        let mut entry = json!({ "surface": surface.map_or("", |s| s.node_type_id.as_str()), "inputs": inputs });
        if let Some((_, authored)) = t.materialx_surfaces.iter().find(|(p, _)| p == path) {
            entry["mappedTo"] = entry["surface"].clone();
            entry["surface"] = json!(authored);
        }
        materials.insert(path.clone(), entry);
    }
    json!({
        "stage": { "metersPerUnit": t.meters_per_unit, "upAxis": if t.z_up { "Z" } else { "Y" } },
        "meshes": meshes,
        "instancers": instancers,
        "lights": lights,
        "cameras": cameras,
        "materials": materials,
        "textures": t.texture_paths.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<Map<String, Value>>(),
        "volumes": volumes_json(t),
        "skipped": t.skipped,
    })
}

/// Each volume's prim transform (and its motion) and the VDB grid each field reads.
fn volumes_json(t: &Translation) -> Value {
    let entry = |v: &crate::usd::VolumeSource| {
        let fields: Map<String, Value> = v
            .fields
            .iter()
            .zip(&v.active_voxels)
            .map(|((field, file, name), voxels)| (field.clone(), json!({ "file": file, "fieldName": name, "activeVoxels": voxels })))
            .collect();
        let mut volume = json!({ "world": usd_matrix(&v.world), "fields": fields });
        if !v.motion.is_empty() {
            volume["motion"] = Value::Array(v.motion.iter().map(usd_matrix).collect());
        }
        (v.path.clone(), volume)
    };
    Value::Object(t.volume_sources.iter().map(entry).collect())
}

/// A skinned mesh's skeleton and animation, and (unless refined, when the points are no longer
/// the authored ones) its posed points in world space.
fn skinning_json(s: &crate::usd::Skinned, m: &render_core::scene::MeshDesc, with_points: bool) -> Value {
    let mut out = json!({ "skeleton": s.skeleton, "animation": s.animation });
    if with_points {
        let points: Vec<Value> = m.mesh.positions.iter().map(|&p| json!(m.transform.transform_point3(p).to_array())).collect();
        out["worldPoints"] = Value::Array(points);
    }
    out
}

/// Light linking as a mesh sees it: the lights that illuminate it (`litBy`, when some light
/// has a light link) and those whose shadows it casts (`shadowedBy`, when some light has a
/// shadow link).
struct LinkLists<'t> {
    /// Each light's path and its light-link and shadow-link collections.
    lights: Vec<(&'t str, [Option<&'t str>; 2])>,
}

impl<'t> LinkLists<'t> {
    /// UsdLux lights and mesh lights.
    fn of(t: &'t Translation) -> Self {
        let usd = t.lights.iter().map(|(p, l)| (p.as_str(), [l.light_link.as_deref(), l.shadow_link.as_deref()]));
        // An invisible mesh lights nothing.
        let meshes = t.meshes.iter().filter(|(_, m)| m.visible);
        let meshes =
            meshes.filter_map(|(p, m)| m.light.as_ref().map(|l| (p.as_str(), [l.light_link.as_deref(), l.shadow_link.as_deref()])));
        LinkLists { lights: usd.chain(meshes).collect() }
    }

    /// Each list only when some light links that way (a list of every light per mesh would
    /// say nothing, at length).
    fn add_to(&self, mesh: &mut Value, collections: &[String]) {
        for (k, name) in ["litBy", "shadowedBy"].into_iter().enumerate() {
            if self.lights.iter().all(|(_, links)| links[k].is_none()) {
                continue;
            }
            let holds = |link: Option<&str>| link.is_none_or(|c| collections.iter().any(|m| m == c));
            let mut paths: Vec<&str> = self.lights.iter().filter(|(_, links)| holds(links[k])).map(|(p, _)| *p).collect();
            paths.sort_unstable();
            mesh[name] = json!(paths);
        }
    }
}

/// A mesh light's inputs, named as UsdLux names them.
fn mesh_light_json(l: &render_core::light::MeshLight) -> Value {
    let sync = crate::usd::SYNC_TOKENS.iter().find(|(_, sync)| *sync == l.sync).map(|(token, _)| *token);
    json!({
        "intensity": l.intensity,
        "exposure": l.exposure,
        "color": [l.color.x, l.color.y, l.color.z],
        "normalize": l.normalize,
        "materialSyncMode": sync,
    })
}

/// One mesh: placement, triangles, material, visibility, and its subdivision, motion,
/// skinning and deformation where it has them.
fn mesh_json(m: &render_core::scene::MeshDesc, subdivision: Option<Value>, skin: Option<&crate::usd::Skinned>) -> Value {
    let mut mesh = json!({
        "world": usd_matrix(&m.transform),
        "triangles": m.mesh.indices.len(),
        "material": m.material,
        "visible": m.visible,
    });
    let refined = subdivision.is_some();
    if let Some(s) = subdivision {
        mesh["subdivision"] = s;
    }
    if !m.motion.is_empty() {
        mesh["motion"] = Value::Array(m.motion.iter().map(usd_matrix).collect());
    }
    if let Some(l) = &m.light {
        mesh["light"] = mesh_light_json(l);
    }
    if let Some(s) = skin {
        mesh["skinning"] = skinning_json(s, m, !refined);
    }
    // Deforming polygon meshes: their points are the authored ones, comparable as they are.
    if m.mesh.deformation_samples() > 0 && skin.is_none() && !refined {
        mesh["deformation"] = deformation_json(m);
    }
    mesh
}

/// A deforming mesh's points in world space at each motion sample: its placement at that
/// sample (the frame's when it does not move) applied to the sample's shape.
fn deformation_json(m: &render_core::scene::MeshDesc) -> Value {
    let n = m.mesh.positions.len();
    let sets = m.mesh.deformation.chunks_exact(n).enumerate().map(|(s, points)| {
        let world = m.motion.get(s).unwrap_or(&m.transform);
        Value::Array(points.iter().map(|&p| json!(world.transform_point3(p).to_array())).collect())
    });
    Value::Array(sets.collect())
}

fn subdivision_json(s: &crate::usd::Subdivided) -> Value {
    json!({ "scheme": s.scheme, "level": s.level, "cageFaces": s.cage_faces })
}

/// Reads `scene` and returns its JSON description.
pub fn inspect(scene: &Path, options: crate::usd::LoadOptions) -> Result<Value> {
    Ok(to_json(&crate::usd::load_with(scene, options)?))
}
