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
                image.write_tile(&t.aov, tessera::output::TileRect::of(&t), t.channels, &px);
            }
            pb::render_event::Event::Finished(f) => assert!(!f.cancelled),
            _ => {}
        }
    }
    assert!(version_now > 0, "the edit restarted the render");
    assert_eq!(image.layers["beauty"], fresh.image.layers["beauty"], "bit-identical to a fresh render of the edited scene");
    server.stop().await.unwrap();
}

/// Coarse first-look passes (`coarse_start`): before the first full pass, blocks of 8×8,
/// then 4×4, then 2×2 pixels each cover the whole frame once (100×70 in 32² tiles, so blocks
/// are cut at tile and image edges), with finite values; and since their samples never enter
/// the film, the final image is bit-identical to a render without them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coarse_passes_cover_the_frame_first_and_leave_the_image_unchanged() {
    let (server, mut conn) = tessera_tests::session_with(&load("cornell_box.usda")).await;
    let opts = tessera::remote::RenderOptions { tile_size: 32, ..tessera_tests::small(100, 70, 4) };
    let plain = conn.render(&opts, |_| {}).await.unwrap();
    let mut covered = std::collections::BTreeMap::<u32, u32>::new();
    // The pixel size of every beauty tile in arrival order (1 for full passes).
    let mut order = Vec::new();
    let coarse_opts = tessera::remote::RenderOptions { coarse_start: 8, ..opts };
    let coarse = conn
        .render(&coarse_opts, |e| {
            if let pb::render_event::Event::Tile(t) = e
                && t.aov == "beauty"
            {
                let block = t.pixel_size.max(1);
                order.push(block);
                if block > 1 {
                    *covered.entry(block).or_default() += t.width * t.height;
                    let values = convert::tile_pixels(t).unwrap();
                    assert_eq!(values.len() as u32, t.width * t.height * 4);
                    assert!(values.iter().all(|v| v.is_finite()), "finite coarse values");
                }
            }
        })
        .await
        .unwrap();
    assert_eq!(covered, [(2, 7000), (4, 7000), (8, 7000)].into(), "each coarse pass covers the frame once");
    let first_full = order.iter().position(|&b| b == 1).unwrap();
    assert!(order[..first_full].windows(2).all(|w| w[0] >= w[1]), "8×8, then 4×4, then 2×2: {order:?}");
    assert!(order[first_full..].iter().all(|&b| b == 1), "no coarse tile after the first full one");
    assert_eq!(coarse.image.layers["beauty"], plain.image.layers["beauty"], "coarse passes leave the image bit-identical");
    server.stop().await.unwrap();
}

/// `coarse_start` is a client-controlled size: anything but a power of two up to 64 is refused
/// by name, and the largest blocks on an image smaller than one block still cover it once per
/// pass (blocks are cut at the image's edge).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coarse_start_is_bounded_and_blocks_larger_than_the_image_work() {
    let (server, mut conn) = tessera_tests::session_with(&load("cornell_box.usda")).await;
    for bad in [3, 128, u32::MAX] {
        let opts = tessera::remote::RenderOptions { coarse_start: bad, ..tessera_tests::small(8, 8, 1) };
        let e = conn.render(&opts, |_| {}).await.unwrap_err();
        assert!(format!("{e:#}").contains("coarse_start"), "names the field: {e:#}");
    }
    let mut covered = std::collections::BTreeMap::<u32, u32>::new();
    let opts = tessera::remote::RenderOptions { coarse_start: 64, ..tessera_tests::small(5, 3, 1) };
    conn.render(&opts, |e| {
        if let pb::render_event::Event::Tile(t) = e
            && t.aov == "beauty"
            && t.pixel_size > 1
        {
            *covered.entry(t.pixel_size).or_default() += t.width * t.height;
            assert_eq!(convert::tile_pixels(t).unwrap().len(), 15 * 4);
        }
    })
    .await
    .unwrap();
    assert_eq!(covered, [(2, 15), (4, 15), (8, 15), (16, 15), (32, 15), (64, 15)].into());
    server.stop().await.unwrap();
}
