//! The protocol: health and capabilities, chunked sync of a mesh larger than gRPC's 4 MiB
//! message limit, edits during a render, cancellation.

use std::sync::Arc;
use std::time::Duration;

use glam::Vec3;
use render_core::geometry::{Mesh, Normals};
use render_core::light::{LightDesc, LightKind};
use render_core::scene::MeshDesc;
use tessera::remote::Connection;
use tessera_proto::v1 as pb;
use tessera_server::EmbeddedServer;
use tessera_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_and_capabilities_answer() {
    let server = EmbeddedServer::start().await.unwrap();
    let channel = tonic::transport::Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
    let mut health = tonic_health::pb::health_client::HealthClient::new(channel);
    let status = health.check(tonic_health::pb::HealthCheckRequest { service: "tessera.v1.Render".into() }).await.unwrap().into_inner();
    assert_eq!(status.status, tonic_health::pb::health_check_response::ServingStatus::Serving as i32);
    let mut conn = Connection::connect(&server.url(), "caps").await.unwrap();
    let caps = conn.capabilities().await.unwrap();
    assert!(caps.aovs.contains(&"depth".to_string()) && caps.node_types.contains(&"UsdPreviewSurface".to_string()));
    assert!(caps.limits.unwrap().max_array_chunk_elements * 4 < 4 << 20);
}

/// A flat grid of `n`×`n` quads facing +Z (towards the default camera).
fn grid(n: u32) -> Mesh {
    let mesh = Mesh::grid(n, |i, j| Vec3::new(i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5, 0.0));
    Mesh { normals: Normals::Vertex(vec![Vec3::Z; mesh.positions.len()]), ..mesh }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mesh_larger_than_the_message_limit_syncs_in_chunks() {
    // 400x400 quads: 320 000 triangles, 3.8 MB of indices and 1.9 MB each of points and
    // normals: 7.7 MB in all, nearly twice gRPC's default limit.
    let mut t = tessera::usd::Translation::default();
    let mesh = grid(400);
    assert!(mesh.indices.len() * 12 + mesh.positions.len() * 24 > 4 << 20);
    t.meshes.push((
        "/Grid".into(),
        MeshDesc {
            mesh: Arc::new(mesh),
            transform: glam::Affine3A::IDENTITY,
            motion: Vec::new(),
            material: String::new(),
            visible: true,
            link_collections: Vec::new(),
            light: None,
        },
    ));
    t.lights.push((
        "/Dome".into(),
        LightDesc {
            kind: LightKind::Dome,
            transform: glam::Affine3A::IDENTITY,
            intensity: 1.0,
            exposure: 0.0,
            color: Vec3::ONE,
            normalize: false,
            visible_to_camera: true,
            texture: None,
            shaping: None,
            diffuse: 1.0,
            specular: 1.0,
            motion: Vec::new(),
            light_link: None,
            shadow_link: None,
        },
    ));
    let (server, mut conn) = session_with(&t).await;
    let report = conn.render(&small(16, 16, 1), |_| {}).await.unwrap();
    // The default camera frames the grid: its centre sees the unbound mesh's default material
    // (UsdPreviewSurface: diffuse 0.18 under an IOR 1.5 specular) reflecting the unit dome.
    let centre = report.image.pixel("beauty", 8, 8);
    assert_eq!(centre[3], 1.0, "the grid was synced and is hit");
    assert!(centre[0] > 0.18 && centre[0] < 0.3, "{centre:?}");
    server.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_during_a_render_restarts_it_and_the_image_shows_the_edit() {
    let translation = load("cornell_box.usda");
    let (server, mut conn) = session_with(&translation).await;
    let mut editor = Connection::attach(&server.url(), &conn.session).await.unwrap();
    let (light_path, light) = translation.lights[0].clone();
    let (first_tile_tx, first_tile_rx) = tokio::sync::oneshot::channel::<()>();
    let render = tokio::spawn(async move {
        let mut first = Some(first_tile_tx);
        conn.render(&small(64, 64, 256), move |e| {
            if matches!(e, pb::render_event::Event::Tile(_))
                && let Some(tx) = first.take()
            {
                let _ = tx.send(());
            }
        })
        .await
    });
    first_tile_rx.await.expect("a first tile arrives");
    // Make the only light pure blue.
    let blue = LightDesc { color: Vec3::new(0.0, 0.0, 1.0), ..light };
    let item = tessera::sync::delta(
        &light_path,
        pb::PrimKind::Light,
        pb::prim_delta::Payload::Light(tessera_server::convert::light_to_wire(&blue)),
    );
    let resp = editor.sync(vec![item]).await.unwrap();
    assert_eq!(resp.scene_version, 2);
    let report = render.await.unwrap().unwrap();
    assert_eq!(report.restarts, vec![2], "exactly one restart, at version 2");
    let (red, _) = mean_where(&report.image, "beauty", 0, |_, _| true);
    let (b, _) = mean_where(&report.image, "beauty", 2, |_, _| true);
    assert_eq!(red, 0.0, "no red light remains after the edit");
    assert!(b > 0.01, "blue light arrives: {b}");
    assert_eq!(report.finished.spp, 256);
    server.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancel_stops_a_long_render_promptly() {
    let (server, mut conn) = session_with(&load("cornell_box.usda")).await;
    let mut other = Connection::attach(&server.url(), &conn.session).await.unwrap();
    let render = tokio::spawn(async move { conn.render(&small(128, 128, 1 << 16), |_| {}).await });
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(other.cancel().await.unwrap(), "a render was running");
    let report = tokio::time::timeout(Duration::from_secs(20), render).await.expect("stops within a tile's time").unwrap().unwrap();
    assert!(report.finished.cancelled);
    assert!(report.finished.spp < 1 << 16);
    server.stop().await.unwrap();
}
