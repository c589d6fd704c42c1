//! The memory budget holds in fact, not only in its bookkeeping: a server with `--memory-budget
//! 2G` answers the requests that took 8-12 GB before (a 16384² all-AOV render, a 16-bit PNG
//! that decodes to 16384² RGBA, 40M- and 200M-triangle mesh declarations) with RESOURCE_EXHAUSTED, and
//! this process's peak resident memory (`VmHWM` in `/proc/self/status`) stays under the budget.
//! Its own test binary, so no other test's allocations count.

use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tessera_server::{EmbeddedServer, ServerConfig};

use tessera_tests::hostile_inputs as inputs;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_server_stays_under_its_memory_budget() {
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
