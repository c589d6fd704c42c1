//! A million points render under a stated memory bound: 1 GiB of peak resident memory for
//! the client's translation, the sync, the server's commit (one sphere BLAS, a TLAS over a
//! million instances) and a render, all in this process (measured: 841 MiB, about 880 bytes
//! a point counting both ends and the wire copies; a triangle mesh of a million 128 × 64
//! spheres would be 16 billion triangles). The points take the reader's own
//! path (`tessera::usd::points::sphere_instances`, one transform per point). Its own test
//! binary, so no other test's allocations count.

use glam::{DMat4, Vec3};
use render_core::camera::CameraDesc;
use render_core::scene::{InstancerDesc, MeshDesc};
use std::sync::Arc;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_million_points_render_in_under_a_gibibyte() {
    // A 1000 × 1000 grid of points 1 apart, width 0.8, in the plane z = −600.
    let points: Vec<Vec3> = (0..1_000_000).map(|i| Vec3::new((i % 1000) as f32 - 500.0, (i / 1000) as f32 - 500.0, -600.0)).collect();
    let transforms = tessera::usd::points::sphere_instances(DMat4::IDENTITY, &points, &[0.8]);
    drop(points);
    let mut t = tessera::usd::Translation::default();
    let sphere = tessera::usd::shapes::tessellate(tessera::usd::shapes::Shape::Sphere { radius: 1.0 });
    let desc = MeshDesc {
        mesh: Arc::new(sphere),
        transform: glam::Affine3A::IDENTITY,
        motion: Vec::new(),
        material: String::new(),
        visible: false,
    };
    t.meshes.push(("/Dots[sphere]".into(), desc));
    t.instancers.push(("/Dots[points]".into(), InstancerDesc { prototype: "/Dots[sphere]".into(), transforms, motion: Vec::new() }));
    t.cameras.push(("/Camera".into(), CameraDesc::default()));
    t.add_default_light();
    let (server, mut conn) = tessera_tests::session_with(&t).await;
    let report = conn.render(&tessera_tests::small(64, 64, 4), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    let covered = (0..64).flat_map(|y| (0..64).map(move |x| (x, y))).filter(|&(x, y)| report.image.pixel("beauty", x, y)[3] > 0.0).count();
    let peak = tessera_tests::peak_rss();
    eprintln!("a million points: peak RSS {:.0} MiB, {covered} of 4096 pixels covered", peak as f64 / (1 << 20) as f64);
    // Spheres of radius 0.4 on a unit grid cover half of each pixel's footprint: 4 samples
    // miss them all in 1/16 of the pixels.
    assert!(covered > 3500, "the points are seen: {covered} pixels");
    assert!(peak < 1 << 30, "peak RSS {} MiB", peak >> 20);
}
