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
        let points: Vec<f32> = m.mesh.positions.iter().flat_map(|p| p.to_array()).collect();
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
        let transforms: Vec<f64> = inst.transforms.iter().flat_map(|xf| convert::matrix(xf).m).collect();
        let prim = pb::InstancerPrim { prototype_path: inst.prototype.clone(), transforms_len: transforms.len() as u64 };
        items.push(delta(path, pb::PrimKind::Instancer, pb::prim_delta::Payload::Instancer(prim)));
        items.extend(chunks(path, pb::ArrayField::InstanceTransforms, &transforms, |c, v| c.doubles = v));
    }
    items
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
    items
        .into_iter()
        .enumerate()
        .map(|(i, item)| pb::SyncRequest { session_id: if i == 0 { session_id.to_string() } else { String::new() }, item: Some(item) })
        .collect()
}
