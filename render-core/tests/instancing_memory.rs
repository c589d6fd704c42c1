//! 100 000 instances of a 10 000-triangle prototype share one BLAS: committing them must take
//! a few hundred MB at most (the USD issue's bound), where copying the geometry per instance
//! would take tens of GB. Measured as the growth of this process's resident set, in its own
//! test binary so no other test allocates meanwhile.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::{Affine3A, Vec3};
use render_core::geometry::{Mesh, Normals};
use render_core::scene::{BlasCache, InstancerDesc, MeshDesc, SceneDesc, commit};

/// Resident set size in bytes, from /proc (Linux).
fn rss_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm");
    let pages: u64 = statm.split_whitespace().nth(1).expect("resident field").parse().expect("a number");
    pages * 4096
}

/// A 100×50 grid of quads bent into a dome: 10 000 triangles.
fn prototype() -> Mesh {
    let (nx, nz) = (101u32, 51u32);
    let mut positions = Vec::new();
    for j in 0..nz {
        for i in 0..nx {
            let (u, v) = (i as f32 / (nx - 1) as f32 - 0.5, j as f32 / (nz - 1) as f32 - 0.5);
            positions.push(Vec3::new(u, 0.25 - u * u - v * v, v));
        }
    }
    let mut indices = Vec::new();
    for j in 0..nz - 1 {
        for i in 0..nx - 1 {
            let a = j * nx + i;
            indices.push([a, a + nx, a + 1]);
            indices.push([a + 1, a + nx, a + nx + 1]);
        }
    }
    Mesh { positions, indices, normals: Normals::None, ..Default::default() }
}

#[test]
fn a_hundred_thousand_instances_of_ten_thousand_triangles_fit_in_a_few_hundred_mb() {
    let proto = prototype();
    assert_eq!(proto.indices.len(), 10_000);
    let transforms: Vec<Affine3A> =
        (0..100_000).map(|i| Affine3A::from_translation(Vec3::new((i % 316) as f32 * 1.5, 0.0, (i / 316) as f32 * 1.5))).collect();
    let mut desc = SceneDesc::default();
    desc.meshes.insert(
        "/Proto".into(),
        MeshDesc {
            mesh: Arc::new(proto),
            transform: Affine3A::IDENTITY,
            motion: Vec::new(),
            material: String::new(),
            visible: false,
            link_collections: Vec::new(),
            light: None,
        },
    );
    desc.instancers = BTreeMap::from([(
        "/Forest".into(),
        InstancerDesc { prototype: "/Proto".into(), transforms, motion: Vec::new(), link_collections: Vec::new() },
    )]);

    let before = rss_bytes();
    let scene = commit(&desc, &mut BlasCache::default()).expect("commits");
    let grown = rss_bytes().saturating_sub(before);
    assert_eq!(scene.instances.len(), 100_000);
    println!("commit of 100k instances x 10k triangles: resident set grew by {:.1} MB", grown as f64 / 1e6);
    // A copy per instance would be 1e9 triangles; sharing costs the TLAS and instance data.
    assert!(grown < 300_000_000, "the resident set grew by {:.0} MB", grown as f64 / 1e6);

    // And the instances are really there: a ray down onto the field hits one.
    let ray = render_core::geometry::Ray::new(Vec3::new(150.0 * 1.5 + 0.1, 10.0, 100.0 * 1.5 + 0.05), -Vec3::Y);
    let hit = scene.intersect(&ray).expect("a ray onto the instanced field hits");
    assert!((hit.t - (10.0 - 0.25)).abs() < 0.02, "hit at t = {}", hit.t);
}
