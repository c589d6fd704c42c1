//! Memory bounds measured in fact, not only in bookkeeping: each test runs in a process of its
//! own (rusty-fork starts this binary again for that one test), so the peak resident memory it
//! reads (`VmHWM` in `/proc/self/status`) counts its own allocations and no other test's.
//!
//! - A server with `--memory-budget 2G` answers the requests that took 8-12 GB before (a
//!   16384² all-AOV render, a 16-bit PNG that decodes to 16384² RGBA, 40M- and 200M-triangle
//!   mesh declarations) with RESOURCE_EXHAUSTED, and stays under the budget.
//! - A million points render under 1 GiB of peak resident memory for the client's
//!   translation, the sync, the server's commit (one sphere BLAS, a TLAS over a million
//!   instances) and a render, all in one process (measured: 841 MiB, about 880 bytes a point
//!   counting both ends and the wire copies; a triangle mesh of a million 128 × 64 spheres
//!   would be 16 billion triangles). The points take the reader's own path
//!   (`tessera::usd::points::sphere_instances`, one transform per point).

use std::sync::Arc;

use glam::{DMat4, Vec3};
use render_core::camera::CameraDesc;
use render_core::scene::{InstancerDesc, MeshDesc};
use rusty_fork::rusty_fork_test;
use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tessera_server::{EmbeddedServer, ServerConfig};

use tessera_tests::hostile_inputs as inputs;

/// The tests' two runtime threads, as `#[tokio::test(flavor = "multi_thread")]` would give
/// (that attribute cannot sit inside `rusty_fork_test!`).
fn block_on<F: std::future::Future>(f: F) -> F::Output {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap().block_on(f)
}

rusty_fork_test! {
    #[test]
    fn the_server_stays_under_its_memory_budget() {
        block_on(server_under_budget());
    }

    #[test]
    fn a_million_points_render_in_under_a_gibibyte() {
        block_on(million_points());
    }
}

async fn server_under_budget() {
    let budget = 2u64 << 30;
    let server =
        EmbeddedServer::start_with(ServerConfig { memory_budget: budget, session_memory_budget: budget, ..ServerConfig::default() })
            .await
            .unwrap();
    let channel = tonic::transport::Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
    let mut c = RenderClient::new(channel);
    let s = c.create_session(pb::CreateSessionRequest::default()).await.unwrap().into_inner().session_id;
    let sync = |items: Vec<pb::sync_request::Item>| tokio_stream::iter(tessera::sync::requests(&s, items));
    let cornell = tessera::usd::load(&tessera_tests::fixture("cornell_box.usda")).unwrap();
    c.sync(sync(tessera::sync::full_sync(&cornell))).await.unwrap();

    let all: Vec<String> = render_core::film::Aov::ALL.iter().skip(1).map(|a| a.name().to_string()).collect();
    let huge = pb::RenderSettings { width: 16384, height: 16384, aovs: all, ..Default::default() };
    let e = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(huge) }).await.unwrap_err();
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e:?}");

    let png = inputs::png_claiming(16384, 16384);
    let e = c.sync(sync(inputs::textured(&tessera_server::textures::content_hash(&png), &png))).await.unwrap_err();
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e:?}");

    // Within the per-mesh limit (50 M) but 40 M × 256 bytes is 10 GB: refused by the budget.
    let e = c.sync(sync(inputs::declared_mesh("/Evil/Huge", 40_000_000))).await.unwrap_err();
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("/Evil/Huge"), "names the prim: {e:?}");
    // The 200 M-triangle declaration: refused before a byte of it arrives.
    let e = c.sync(sync(inputs::declared_mesh("/Evil/Huger", 200_000_000))).await.unwrap_err();
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("/Evil/Huger"), "names the prim: {e:?}");

    // A render that fits still runs, under the same budget.
    let ok = pb::RenderSettings { width: 256, height: 256, spp: 4, ..Default::default() };
    let mut stream = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(ok) }).await.unwrap().into_inner();
    while stream.message().await.unwrap().is_some() {}
    let peak = tessera_tests::peak_rss();
    eprintln!("peak RSS {:.0} MiB under a {} budget", peak as f64 / (1 << 20) as f64, tessera_server::budget::human(budget));
    assert!(peak < budget, "peak RSS {peak} bytes over the {budget}-byte budget");
}

async fn million_points() {
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
        link_collections: Vec::new(),
        light: None,
    };
    t.meshes.push(("/Dots[sphere]".into(), desc));
    t.instancers.push((
        "/Dots[points]".into(),
        InstancerDesc { prototype: "/Dots[sphere]".into(), transforms, motion: Vec::new(), link_collections: Vec::new() },
    ));
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
