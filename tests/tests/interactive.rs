//! Edits during a render reach the client without waiting for the running pass: asserted in
//! samples, not milliseconds (the latency itself is `cargo bench -p tessera-tests --bench
//! interactive`, in docs/service.md).

use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tessera_server::EmbeddedServer;
use tessera_wire::convert;

use tessera_tests::load;

/// The next event that is not a tile.
async fn next_non_tile(stream: &mut tonic::Streaming<pb::RenderEvent>) -> pb::render_event::Event {
    loop {
        let e = stream.message().await.unwrap().expect("the stream goes on").event.unwrap();
        if !matches!(e, pb::render_event::Event::Tile(_)) {
            return e;
        }
    }
}

/// Two 64×64 tiles, one per core, so a pass is two long tiles: the pass after 256 spp adds
/// 256 samples to each of 8192 pixels (2M paths, a second or more on two cores). The old
/// server built the edited scene's BVH on the thread pool both tiles held, so the Sync, and
/// the `Restarted`, waited for that pass to finish and its `Progress` came first.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_restarts_the_render_inside_a_long_pass() {
    let server = EmbeddedServer::start().await.unwrap();
    let channel = tonic::transport::Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
    let mut c = RenderClient::new(channel);
    let s = c.create_session(pb::CreateSessionRequest::default()).await.unwrap().into_inner().session_id;
    let cornell = load("cornell_box.usda");
    c.sync(tokio_stream::iter(tessera::sync::requests(&s, tessera::sync::full_sync(&cornell)))).await.unwrap();
    let settings = pb::RenderSettings { width: 128, height: 64, tile_size: 64, spp: 1 << 16, ..Default::default() };
    let mut stream = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(settings) }).await.unwrap().into_inner();
    let spp_seen = loop {
        if let pb::render_event::Event::Progress(p) = next_non_tile(&mut stream).await
            && p.spp >= 256
        {
            break p.spp;
        }
    };

    let (path, light) = &cornell.lights[0];
    let mut brighter = light.clone();
    brighter.intensity *= 2.0;
    let edit = tessera::sync::delta(path, pb::PrimKind::Light, pb::prim_delta::Payload::Light(convert::light_to_wire(&brighter)));
    let version = c.sync(tokio_stream::iter(tessera::sync::requests(&s, vec![edit]))).await.unwrap().into_inner().scene_version;

    match next_non_tile(&mut stream).await {
        pb::render_event::Event::Restarted(r) => assert_eq!(r.scene_version, version),
        other => panic!("the pass after {spp_seen} spp went on after the edit: {other:?}"),
    }
    // The new version renders from its first pass again, and nothing of the old one follows.
    match next_non_tile(&mut stream).await {
        pb::render_event::Event::Progress(p) => assert_eq!(p.spp, 1, "first pass of the new version"),
        other => panic!("expected the new version's first pass, got {other:?}"),
    }
    c.cancel(pb::CancelRequest { session_id: s.clone() }).await.unwrap();
    while stream.message().await.unwrap().is_some() {}
    server.stop().await.unwrap();
}

/// A render that restarts on an edit ends with the same image as a fresh render of the
/// edited scene: the restart keeps nothing of the old version's samples. (256 spp at 48²
/// takes far longer than the edit needs to arrive after `Started`.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_render_equals_a_fresh_render_of_the_edited_scene() {
    let cornell = load("cornell_box.usda");
    let (path, light) = &cornell.lights[0];
    let mut edited = cornell.clone();
    edited.lights[0].1.intensity = light.intensity * 0.5;

    let (server, mut conn) = tessera_tests::session_with(&edited).await;
    let fresh = conn.render(&tessera_tests::small(48, 48, 256), |_| {}).await.unwrap();
    server.stop().await.unwrap();

    let server = EmbeddedServer::start().await.unwrap();
    let channel = tonic::transport::Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
    let mut c = RenderClient::new(channel);
    let s = c.create_session(pb::CreateSessionRequest::default()).await.unwrap().into_inner().session_id;
    c.sync(tokio_stream::iter(tessera::sync::requests(&s, tessera::sync::full_sync(&cornell)))).await.unwrap();
    let settings = pb::RenderSettings { width: 48, height: 48, spp: 256, ..Default::default() };
    let mut stream = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(settings) }).await.unwrap().into_inner();
    next_non_tile(&mut stream).await; // Started
    let edit = tessera::sync::delta(path, pb::PrimKind::Light, pb::prim_delta::Payload::Light(convert::light_to_wire(&edited.lights[0].1)));
    c.sync(tokio_stream::iter(tessera::sync::requests(&s, vec![edit]))).await.unwrap();
    let mut image = tessera::output::Image { width: 48, height: 48, layers: Default::default() };
    let mut version_now = 0;
    while let Some(e) = stream.message().await.unwrap() {
        match e.event.unwrap() {
            pb::render_event::Event::Restarted(r) => version_now = r.scene_version,
            pb::render_event::Event::Tile(t) if version_now > 0 => {
                let px: Vec<f32> = t.pixels.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
                image.write_tile(&t.aov, t.x, t.y, t.width, t.height, t.channels, &px);
            }
            pb::render_event::Event::Finished(f) => assert!(!f.cancelled),
            _ => {}
        }
    }
    assert!(version_now > 0, "the edit restarted the render");
    assert_eq!(image.layers["beauty"], fresh.image.layers["beauty"], "bit-identical to a fresh render of the edited scene");
    server.stop().await.unwrap();
}
