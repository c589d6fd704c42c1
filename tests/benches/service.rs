//! The service under load, over loopback against the real server (`cargo bench -p
//! tessera-tests --bench service`): how fast Cancel and a vanished client free an expensive
//! render, and first-tile latency and throughput with 1, 16 and 64 sessions rendering the
//! Cornell box at 128² at once. Prints numbers; asserts nothing. Results: `docs/service.md`.

use std::time::{Duration, Instant};

use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tessera_server::EmbeddedServer;
use tonic::transport::Channel;

type Client = RenderClient<Channel>;

async fn client(server: &EmbeddedServer) -> Client {
    let channel = Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
    RenderClient::new(channel).max_decoding_message_size(64 << 20)
}

async fn cornell_session(c: &mut Client) -> String {
    let s = c.create_session(pb::CreateSessionRequest { client_name: "bench".into() }).await.unwrap().into_inner().session_id;
    let t = tessera::usd::load(&std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/cornell_box.usda")).unwrap();
    c.sync(tokio_stream::iter(tessera::sync::requests(&s, tessera::sync::full_sync(&t)))).await.unwrap();
    s
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// Peak resident memory of this process so far, from `/proc/self/status`.
fn peak_rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kib: f64 =
        status.lines().find_map(|l| l.strip_prefix("VmHWM:")).and_then(|v| v.split_whitespace().next()?.parse().ok()).unwrap_or(0.0);
    kib / 1024.0
}

/// One 64×64 tile, thousands of samples per pass: each pass is one long tile.
fn expensive() -> pb::RenderSettings {
    pb::RenderSettings { width: 64, height: 64, tile_size: 64, spp: 1 << 16, max_depth: 8, ..Default::default() }
}

/// Waits for the pass with at least `spp` samples, then returns.
async fn until_spp(stream: &mut tonic::Streaming<pb::RenderEvent>, spp: u32) {
    while let Some(e) = stream.message().await.unwrap() {
        if let Some(pb::render_event::Event::Progress(p)) = e.event
            && p.spp >= spp
        {
            return;
        }
    }
}

async fn cancel_latency(server: &EmbeddedServer) {
    let mut c = client(server).await;
    let s = cornell_session(&mut c).await;
    let mut to_finished = Vec::new();
    let mut to_idle = Vec::new();
    for round in 0..10 {
        let mut stream = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(expensive()) }).await.unwrap().into_inner();
        until_spp(&mut stream, 16 << (round % 3)).await;
        if round % 2 == 0 {
            let t = Instant::now();
            c.cancel(pb::CancelRequest { session_id: s.clone() }).await.unwrap();
            while let Some(e) = stream.message().await.unwrap() {
                if matches!(e.event, Some(pb::render_event::Event::Finished(_))) {
                    break;
                }
            }
            to_finished.push(t.elapsed().as_secs_f64() * 1e3);
        } else {
            let t = Instant::now();
            drop(stream);
            loop {
                let st = c.get_session_stats(pb::GetSessionStatsRequest { session_id: s.clone() }).await.unwrap().into_inner();
                if !st.rendering {
                    break;
                }
                tokio::time::sleep(Duration::from_millis(1)).await;
            }
            to_idle.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    c.close_session(pb::CloseSessionRequest { session_id: s }).await.unwrap();
    for v in [&mut to_finished, &mut to_idle] {
        v.sort_by(f64::total_cmp);
    }
    println!(
        "cancel -> Finished: median {:.1} ms, max {:.1} ms ({} runs); client gone -> render stopped: median {:.1} ms, max {:.1} ms ({} runs)",
        percentile(&to_finished, 0.5),
        to_finished.last().unwrap(),
        to_finished.len(),
        percentile(&to_idle, 0.5),
        to_idle.last().unwrap(),
        to_idle.len()
    );
}

/// `n` sessions render the Cornell box at 128², 16 spp, at once: first-tile latency per
/// session and total samples per second.
async fn load(server: &EmbeddedServer, n: usize) -> f64 {
    let mut sessions = Vec::new();
    for _ in 0..n {
        let mut c = client(server).await;
        let s = cornell_session(&mut c).await;
        sessions.push((c, s));
    }
    let start = Instant::now();
    let tasks: Vec<_> = sessions
        .into_iter()
        .map(|(mut c, s)| {
            tokio::spawn(async move {
                let t = Instant::now();
                let settings = pb::RenderSettings { width: 128, height: 128, spp: 16, ..Default::default() };
                let mut stream =
                    c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(settings) }).await.unwrap().into_inner();
                let mut first_tile = None;
                let mut paths = 0;
                while let Some(e) = stream.message().await.unwrap() {
                    match e.event {
                        Some(pb::render_event::Event::Tile(_)) if first_tile.is_none() => first_tile = Some(t.elapsed()),
                        Some(pb::render_event::Event::Finished(f)) => paths = f.paths,
                        _ => {}
                    }
                }
                c.close_session(pb::CloseSessionRequest { session_id: s }).await.unwrap();
                (first_tile.unwrap().as_secs_f64() * 1e3, paths)
            })
        })
        .collect();
    let mut firsts = Vec::new();
    let mut paths = 0;
    for t in tasks {
        let (f, p) = t.await.unwrap();
        firsts.push(f);
        paths += p;
    }
    let secs = start.elapsed().as_secs_f64();
    firsts.sort_by(f64::total_cmp);
    let rate = paths as f64 / secs;
    println!(
        "{n:>2} sessions: first tile p50 {:.0} ms, p90 {:.0} ms, max {:.0} ms; {:.2} M samples/s in all; wall {:.2} s; peak RSS {:.0} MiB",
        percentile(&firsts, 0.5),
        percentile(&firsts, 0.9),
        firsts.last().unwrap(),
        rate / 1e6,
        secs,
        peak_rss_mib()
    );
    rate
}

fn main() {
    // `cargo bench` passes --bench; run only when asked for all benches or this one.
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    rt.block_on(async {
        let limits = tessera_server::limits::Limits { max_sessions: 80, ..Default::default() };
        let server = EmbeddedServer::start_with(tessera_server::ServerConfig { limits, ..Default::default() }).await.unwrap();
        println!("service bench, {} cores", std::thread::available_parallelism().map_or(1, |n| n.get()));
        cancel_latency(&server).await;
        let one = load(&server, 1).await;
        for n in [16, 64] {
            let rate = load(&server, n).await;
            println!("   throughput {n} sessions / 1 session: {:.2}x", rate / one);
        }
        server.stop().await.unwrap();
    });
}
