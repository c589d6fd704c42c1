//! The scene a session edits and what the renderer traces against.
//!
//! * [`desc`]: the description a session edits, keyed by USD path, and its validation;
//! * [`commit`](commit()): its commit as named steps — materials, features
//!   ([`crate::plan`]), displacement, geometry, instances, tangents, bounds, lights;
//! * [`cache`]: what commits keep for the next — a mesh whose geometry `Arc` is unchanged
//!   keeps its BLAS, so moving an object or a light costs a TLAS rebuild and nothing more;
//! * [`committed`] and the queries on it (hits, occlusion, surfaces, BSDFs, transparent
//!   shadows);
//! * [`links`]: light linking, which lights reach and are shadowed by which prims.

mod cache;
mod commit;
mod committed;
mod desc;
mod displace;
mod features;
mod links;
mod materials;
mod query;
mod shadows;

pub use cache::BlasCache;
pub use commit::commit;
pub use committed::{CommittedScene, InstanceData, MAX_CUTOUT_CROSSINGS, SurfaceHit, ray_hash, see_through_coin};
pub use desc::{InstancerDesc, MAX_COORDINATE, MeshDesc, SceneDesc, SceneError, validate_mesh};
pub use displace::MAX_DICED_TRIANGLES;
pub use links::{LightLinks, NO_GROUP};
pub use shadows::ShadowPass;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Normals;
    use crate::geometry::{Mesh, Ray};
    use glam::{Affine3A, Vec3};
    use std::sync::Arc;

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
        desc.meshes.insert(
            "/A".into(),
            MeshDesc {
                mesh: tri_mesh(),
                transform: Affine3A::IDENTITY,
                motion: Vec::new(),
                material: String::new(),
                visible: true,
                link_collections: Vec::new(),
                light: None,
            },
        );
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
    fn blases_built_together_stay_with_their_meshes() {
        // Forty small meshes, their BLASes built several at once, and a big one built alone;
        // then every other small one and the big one change, so fresh and cached BLASes mix.
        // Mesh k is a triangle scaled by 1 + k/8 (at most 5.9) at x = 8k, apart from the
        // others: a BLAS paired with another mesh's instance reports that instance for the ray
        // aimed at mesh k.
        let mesh = |k: usize| {
            let mut m = (*tri_mesh()).clone();
            for p in &mut m.positions {
                *p = *p * (1.0 + k as f32 / 8.0) + Vec3::X * (8 * k) as f32;
            }
            Arc::new(m)
        };
        let mut desc = SceneDesc::default();
        for k in 0..40 {
            let m = MeshDesc {
                mesh: mesh(k),
                transform: Affine3A::IDENTITY,
                motion: Vec::new(),
                material: String::new(),
                visible: true,
                link_collections: Vec::new(),
                light: None,
            };
            desc.meshes.insert(format!("/M{k:02}"), m);
        }
        // One mesh big enough to be built alone (a 256 × 256 grid of quads at x = -100).
        let big = {
            let n = 256u32;
            Arc::new(Mesh::grid(n, |i, j| Vec3::new(-100.0 + i as f32 / n as f32, j as f32 / n as f32, 0.0)))
        };
        assert!(big.indices.len() >= commit::BUILT_ALONE);
        let m = MeshDesc {
            mesh: big.clone(),
            transform: Affine3A::IDENTITY,
            motion: Vec::new(),
            material: String::new(),
            visible: true,
            link_collections: Vec::new(),
            light: None,
        };
        desc.meshes.insert("/Big".into(), m);
        let mut cache = BlasCache::default();
        commit(&desc, &mut cache).unwrap();
        assert_eq!(cache.last_builds, 41);
        for k in (0..40).step_by(2) {
            desc.meshes.get_mut(&format!("/M{k:02}")).unwrap().mesh = mesh(k);
        }
        desc.meshes.get_mut("/Big").unwrap().mesh = Arc::new((*big).clone());
        let scene = commit(&desc, &mut cache).unwrap();
        assert_eq!(cache.last_builds, 21);
        let hit = scene.intersect(&Ray::new(Vec3::new(-99.5, 0.5, 1.0), -Vec3::Z)).expect("the big mesh is hit");
        assert_eq!(scene.prim_paths[hit.instance as usize], "/Big");
        for k in 0..40 {
            // Just inside the scaled triangle's far corner: only mesh k's own BLAS reaches it.
            let s = 1.0 + k as f32 / 8.0;
            let at = Vec3::new(8.0 * k as f32 + 0.9 * s, 0.05 * s, 1.0);
            let hit = scene.intersect(&Ray::new(at, -Vec3::Z)).unwrap_or_else(|| panic!("mesh {k} is missed"));
            assert_eq!(scene.prim_paths[hit.instance as usize], format!("/M{k:02}"));
        }
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
            desc.meshes.insert(
                "/A".into(),
                MeshDesc {
                    mesh: tri_mesh(),
                    transform: Affine3A::IDENTITY,
                    motion: Vec::new(),
                    material: "/M".into(),
                    visible: true,
                    link_collections: Vec::new(),
                    light: None,
                },
            );
            let scene = commit(&desc, &mut BlasCache::default()).unwrap();
            let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
            assert_eq!(scene.intersect(&ray).is_some(), hit, "opacity {opacity} against threshold 0.5");
            assert_eq!(scene.occluded(&ray, 10.0), hit, "a cut-out casts no shadow either");
        }
    }
}
