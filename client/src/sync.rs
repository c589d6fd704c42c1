//! Translation to Hydra-style wire deltas. Large arrays travel as chunks so that no message
//! comes near gRPC's 4 MiB default limit, whatever the mesh size.

use tessera_proto::v1 as pb;
use tessera_wire::convert;

use crate::usd::Translation;

/// Scalar elements per chunk: 1 MiB of floats.
pub const CHUNK_ELEMENTS: usize = 256 * 1024;

fn chunks<T: Copy>(
    path: &str,
    field: pb::ArrayField,
    data: &[T],
    wrap: impl Fn(&mut pb::ArrayChunk, Vec<T>),
) -> Vec<pb::sync_request::Item> {
    data.chunks(CHUNK_ELEMENTS)
        .enumerate()
        .map(|(i, c)| {
            let mut chunk =
                pb::ArrayChunk { path: path.to_string(), field: field as i32, offset: (i * CHUNK_ELEMENTS) as u64, ..Default::default() };
            wrap(&mut chunk, c.to_vec());
            pb::sync_request::Item::Chunk(chunk)
        })
        .collect()
}

/// Bytes of a texture file per chunk.
pub const TEXTURE_CHUNK_BYTES: usize = 1 << 20;

/// Every prim of a translation as a full (all-dirty) delta, arrays chunked, with every
/// texture file it names.
pub fn full_sync(t: &Translation) -> Vec<pb::sync_request::Item> {
    scene_sync(t, |_| true)
}

/// [`full_sync`], sending only the textures `upload` selects (those the server lacks).
pub fn scene_sync(t: &Translation, upload: impl Fn(&str) -> bool) -> Vec<pb::sync_request::Item> {
    let mut items = Vec::new();
    // Textures first: the server decodes them when the transaction commits.
    for (hash, tex) in t.textures.iter().filter(|(h, _)| upload(h)) {
        let prim = pb::TexturePrim { source: tex.source.clone(), bytes_len: tex.bytes.len() as u64 };
        items.push(delta(hash, pb::PrimKind::Texture, pb::prim_delta::Payload::Texture(prim)));
        for (i, c) in tex.bytes.chunks(TEXTURE_CHUNK_BYTES).enumerate() {
            items.push(pb::sync_request::Item::Chunk(pb::ArrayChunk {
                path: hash.clone(),
                field: pb::ArrayField::TextureBytes as i32,
                offset: (i * TEXTURE_CHUNK_BYTES) as u64,
                data: c.to_vec(),
                ..Default::default()
            }));
        }
    }
    for (path, m) in &t.materials {
        items.push(delta(path, pb::PrimKind::Material, pb::prim_delta::Payload::Material(convert::material_to_wire(m))));
    }
    for (path, l) in &t.lights {
        items.push(delta(path, pb::PrimKind::Light, pb::prim_delta::Payload::Light(convert::light_to_wire(l))));
    }
    for (path, c) in &t.cameras {
        items.push(delta(path, pb::PrimKind::Camera, pb::prim_delta::Payload::Camera(convert::camera_to_wire(c))));
    }
    for (path, m) in &t.meshes {
        // The frame's positions, then the deformation's sets.
        let points: Vec<f32> = m.mesh.positions.iter().chain(&m.mesh.deformation).flat_map(|p| p.to_array()).collect();
        let indices: Vec<u32> = m.mesh.indices.iter().flatten().copied().collect();
        let (normals, interp) = convert::attribute_to_wire(&m.mesh.normals, |v| v.to_array());
        let (uvs, uv_interp) = convert::attribute_to_wire(&m.mesh.uvs, |v| v.to_array());
        let prim = pb::MeshPrim {
            transform: Some(convert::matrix(&m.transform)),
            points_len: points.len() as u64,
            triangle_indices_len: indices.len() as u64,
            normals_len: normals.len() as u64,
            normal_interpolation: interp as i32,
            material_path: m.material.clone(),
            double_sided: true,
            visible: m.visible,
            uvs_len: uvs.len() as u64,
            uv_interpolation: uv_interp as i32,
            primvars: Vec::new(),
            motion: convert::motion_to_wire(&m.motion),
            point_samples: m.mesh.deformation_samples() as u32,
            link_collections: m.link_collections.clone(),
            light: m.light.as_ref().map(convert::mesh_light_to_wire),
        };
        let primvars: Vec<(pb::PrimvarInfo, Vec<f32>)> = m
            .mesh
            .primvars
            .iter()
            .map(|p| {
                let (values, interp) = convert::attribute_to_wire(&p.values, |v| v.to_array());
                (pb::PrimvarInfo { name: p.name.clone(), len: values.len() as u64, interpolation: interp as i32 }, values)
            })
            .collect();
        let prim = pb::MeshPrim { primvars: primvars.iter().map(|(info, _)| info.clone()).collect(), ..prim };
        items.push(delta(path, pb::PrimKind::Mesh, pb::prim_delta::Payload::Mesh(prim)));
        items.extend(chunks(path, pb::ArrayField::Points, &points, |c, v| c.floats = v));
        items.extend(chunks(path, pb::ArrayField::TriangleIndices, &indices, |c, v| c.uints = v));
        items.extend(chunks(path, pb::ArrayField::Normals, &normals, |c, v| c.floats = v));
        items.extend(chunks(path, pb::ArrayField::Uvs, &uvs, |c, v| c.floats = v));
        for (k, (_, values)) in primvars.iter().enumerate() {
            items.extend(chunks(path, pb::ArrayField::Primvar, values, |c, v| {
                c.floats = v;
                c.primvar = k as u32;
            }));
        }
    }
    // Instancers after meshes: the server resolves each prototype by path at commit.
    for (path, inst) in &t.instancers {
        // The placements at the frame, then each instance's over the shutter.
        let transforms: Vec<f64> = inst.transforms.iter().chain(&inst.motion).flat_map(|xf| convert::matrix(xf).m).collect();
        let prim = pb::InstancerPrim {
            prototype_path: inst.prototype.clone(),
            transforms_len: transforms.len() as u64,
            motion_samples: inst.motion_samples() as u32,
            link_collections: inst.link_collections.clone(),
        };
        items.push(delta(path, pb::PrimKind::Instancer, pb::prim_delta::Payload::Instancer(prim)));
        items.extend(chunks(path, pb::ArrayField::InstanceTransforms, &transforms, |c, v| c.doubles = v));
    }
    for (path, v) in &t.volumes {
        items.extend(volume_sync(path, v));
    }
    items
}

/// A volume's delta and its voxels.
fn volume_sync(path: &str, v: &render_core::volume::VolumeDesc) -> Vec<pb::sync_request::Item> {
    let (o, d) = (v.density.origin, v.density.dims);
    let temperature = v.temperature.as_ref().map_or(&[][..], |t| &t.values[..]);
    let color: Vec<f32> = v
        .color
        .as_ref()
        .map_or_else(Vec::new, |[r, g, b]| r.values.iter().zip(&g.values).zip(&b.values).flat_map(|((r, g), b)| [*r, *g, *b]).collect());
    let prim = pb::VolumePrim {
        index_to_world: Some(convert::matrix(&v.index_to_world)),
        origin_x: o.x,
        origin_y: o.y,
        origin_z: o.z,
        dims_x: d.x,
        dims_y: d.y,
        dims_z: d.z,
        density_len: v.density.values.len() as u64,
        temperature_len: temperature.len() as u64,
        shading: Some(convert::volume_shading_to_wire(&v.shading)),
        color_len: color.len() as u64,
        motion: convert::motion_to_wire(&v.motion),
        link_collections: v.link_collections.clone(),
    };
    let mut items = vec![delta(path, pb::PrimKind::Volume, pb::prim_delta::Payload::Volume(prim))];
    items.extend(chunks(path, pb::ArrayField::VolumeDensity, &v.density.values, |c, v| c.floats = v));
    items.extend(chunks(path, pb::ArrayField::VolumeTemperature, temperature, |c, v| c.floats = v));
    items.extend(chunks(path, pb::ArrayField::VolumeColor, &color, |c, v| c.floats = v));
    items
}

/// The deltas that take a session holding `before` to `after`, as Hydra sends them: a prim
/// whose content changed goes again in full; a mesh whose points, topology and primvars are
/// unchanged sends only its transform, material and visibility (no arrays); a prim that is
/// gone is removed; a texture is uploaded only if `before` did not name it. An unchanged
/// scene sends nothing.
pub fn changes(before: &Translation, after: &Translation) -> Vec<pb::sync_request::Item> {
    use std::collections::BTreeMap;
    fn index<T>(v: &[(String, T)]) -> BTreeMap<&str, &T> {
        v.iter().map(|(p, t)| (p.as_str(), t)).collect()
    }
    fn changed<T: Clone + PartialEq>(before: &[(String, T)], after: &[(String, T)]) -> Vec<(String, T)> {
        let old = index(before);
        after.iter().filter(|(p, t)| old.get(p.as_str()) != Some(&t)).cloned().collect()
    }
    let old_meshes = index(&before.meshes);
    let (moved, remade): (Vec<_>, Vec<_>) = after
        .meshes
        .iter()
        .filter(|(p, m)| old_meshes.get(p.as_str()) != Some(&m))
        .cloned()
        .partition(|(p, m)| old_meshes.get(p.as_str()).is_some_and(|o| o.mesh == m.mesh));
    let subset = Translation {
        meshes: remade,
        materials: changed(&before.materials, &after.materials),
        lights: changed(&before.lights, &after.lights),
        cameras: changed(&before.cameras, &after.cameras),
        instancers: changed(&before.instancers, &after.instancers),
        volumes: changed(&before.volumes, &after.volumes),
        textures: after.textures.iter().filter(|(h, _)| !before.textures.contains_key(*h)).map(|(h, t)| (h.clone(), t.clone())).collect(),
        ..Default::default()
    };
    let mut items = scene_sync(&subset, |_| true);
    items.extend(moved.iter().map(|(path, m)| mesh_edit(path, old_meshes[path.as_str()], m)));
    let now = prim_paths(after);
    items.extend(prim_paths(before).into_iter().filter(|p| !now.contains(p)).map(|p| {
        pb::sync_request::Item::Prim(pb::PrimDelta { path: p.to_string(), kind: pb::PrimKind::Remove as i32, dirty: 0, payload: None })
    }));
    items
}

/// Every prim path a translation sends (textures aside).
fn prim_paths(t: &Translation) -> std::collections::BTreeSet<&str> {
    let meshes = t.meshes.iter().map(|(p, _)| p);
    let materials = t.materials.iter().map(|(p, _)| p);
    let lights = t.lights.iter().map(|(p, _)| p);
    let cameras = t.cameras.iter().map(|(p, _)| p);
    let instancers = t.instancers.iter().map(|(p, _)| p);
    let volumes = t.volumes.iter().map(|(p, _)| p);
    meshes.chain(materials).chain(lights).chain(cameras).chain(instancers).chain(volumes).map(String::as_str).collect()
}

/// A mesh delta that moves, rebinds or hides a mesh the session holds, without its arrays.
pub fn mesh_placement(path: &str, m: &render_core::scene::MeshDesc) -> pb::sync_request::Item {
    let prim = pb::MeshPrim {
        transform: Some(convert::matrix(&m.transform)),
        motion: convert::motion_to_wire(&m.motion),
        material_path: m.material.clone(),
        visible: m.visible,
        double_sided: true,
        link_collections: m.link_collections.clone(),
        light: m.light.as_ref().map(convert::mesh_light_to_wire),
        ..Default::default()
    };
    let bits = [
        pb::DirtyBits::DirtyTransform,
        pb::DirtyBits::DirtyMaterialId,
        pb::DirtyBits::DirtyVisibility,
        pb::DirtyBits::DirtyCategories,
        pb::DirtyBits::DirtyParams,
    ];
    pb::sync_request::Item::Prim(pb::PrimDelta {
        path: path.to_string(),
        kind: pb::PrimKind::Mesh as i32,
        dirty: bits.into_iter().fold(0, |acc, b| acc | b as u32),
        payload: Some(pb::prim_delta::Payload::Mesh(prim)),
    })
}

/// A mesh delta for a mesh whose geometry is unchanged, with the dirty bits of just what
/// changed from `before` (transform, material binding, visibility, light-link collections,
/// mesh light).
pub fn mesh_edit(path: &str, before: &render_core::scene::MeshDesc, after: &render_core::scene::MeshDesc) -> pb::sync_request::Item {
    let mut item = mesh_placement(path, after);
    if let pb::sync_request::Item::Prim(d) = &mut item {
        let bits = [
            (before.transform != after.transform || before.motion != after.motion, pb::DirtyBits::DirtyTransform),
            (before.material != after.material, pb::DirtyBits::DirtyMaterialId),
            (before.visible != after.visible, pb::DirtyBits::DirtyVisibility),
            (before.link_collections != after.link_collections, pb::DirtyBits::DirtyCategories),
            (before.light != after.light, pb::DirtyBits::DirtyParams),
        ];
        d.dirty = bits.into_iter().filter(|(changed, _)| *changed).fold(0, |acc, (_, b)| acc | b as u32);
    }
    item
}

/// A delta with every dirty bit set.
pub fn delta(path: &str, kind: pb::PrimKind, payload: pb::prim_delta::Payload) -> pb::sync_request::Item {
    pb::sync_request::Item::Prim(pb::PrimDelta {
        path: path.to_string(),
        kind: kind as i32,
        dirty: pb::DirtyBits::DirtyAll as u32,
        payload: Some(payload),
    })
}

/// Wraps items into a stream of requests; the first carries the session id.
pub fn requests(session_id: &str, items: Vec<pb::sync_request::Item>) -> Vec<pb::SyncRequest> {
    if items.is_empty() {
        // A stage with nothing to render (a materials-only layer) still commits: the stream
        // must carry the session.
        return vec![pb::SyncRequest { session_id: session_id.to_string(), item: None }];
    }
    items
        .into_iter()
        .enumerate()
        .map(|(i, item)| pb::SyncRequest { session_id: if i == 0 { session_id.to_string() } else { String::new() }, item: Some(item) })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn animated(frame: f64) -> Translation {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/usd/animated.usda");
        crate::usd::load_at(&path, Some(frame)).unwrap()
    }

    fn prims(items: &[pb::sync_request::Item]) -> Vec<(String, i32, u32)> {
        items
            .iter()
            .filter_map(|i| match i {
                pb::sync_request::Item::Prim(d) => Some((d.path.clone(), d.kind, d.dirty)),
                _ => None,
            })
            .collect()
    }

    /// Between two frames of `fixtures/usd/animated.usda` the cube only moves (one transform
    /// delta, no arrays) and the triangle's points change (the mesh again, with its arrays);
    /// nothing else is sent, an unchanged scene sends nothing, and a prim that is gone is
    /// removed.
    #[test]
    fn changes_send_only_what_changed() {
        let (a, b) = (animated(1.0), animated(5.0));
        assert!(changes(&a, &a).is_empty());
        let items = changes(&a, &b);
        // Only the transform changed, so only its bit is set.
        let placement = pb::DirtyBits::DirtyTransform as u32;
        let mut sent = prims(&items);
        sent.sort();
        assert_eq!(
            sent,
            [
                ("/World/Mover".to_string(), pb::PrimKind::Mesh as i32, placement),
                ("/World/Triangle".to_string(), pb::PrimKind::Mesh as i32, pb::DirtyBits::DirtyAll as u32),
            ]
        );
        let chunks = items.iter().filter(|i| matches!(i, pb::sync_request::Item::Chunk(c) if c.path == "/World/Mover")).count();
        assert_eq!(chunks, 0, "a moved mesh sends no arrays");
        let mut fewer = b.clone();
        let (gone, _) = fewer.lights.remove(0);
        assert_eq!(prims(&changes(&b, &fewer)), [(gone, pb::PrimKind::Remove as i32, 0)]);
    }
}
