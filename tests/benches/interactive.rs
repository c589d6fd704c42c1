//! Interactive latency over loopback against the real server (`cargo bench -p tessera-tests
//! --bench interactive`): the Cornell box rendering progressively at 512² and 1920×1080 and a
//! 1M-triangle scene with 400 instances at 1920×1080, and
//! edits of each kind (camera move, object transform, light intensity, material roughness,
//! texture swap, mesh points)
//! made at pseudo-random moments of the render, with the viewport's coarse first passes on
//! (8×8 blocks first). For each: how long the Sync takes to return, and how long until
//! `Restarted`, the first tile of the new scene version and its first whole coarse frame reach
//! the client. Also the first tile and first whole frame after Render. Prints numbers; asserts nothing. Results:
//! `docs/service.md`.

use std::time::{Duration, Instant};

use glam::{Affine3A, Vec3};
use render_core::camera::CameraDesc;
use render_core::light::LightDesc;
use render_core::material::{MaterialNetwork, ParamValue};
use render_core::scene::MeshDesc;
use tessera::usd::Translation;
use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tessera_server::EmbeddedServer;
use tessera_wire::convert;
use tokio::sync::mpsc;
use tonic::transport::Channel;

type Client = RenderClient<Channel>;

/// Edits per kind and resolution.
const EDITS: usize = 20;

/// Block edge of the first coarse pass, as a viewport asks for it.
const COARSE_START: u32 = 8;

#[derive(Clone, Copy, Debug)]
enum Edit {
    Camera,
    Transform,
    Light,
    Material,
    TextureSwap,
    MeshPoints,
}

impl Edit {
    const ALL: [Edit; 6] = [Edit::Camera, Edit::Transform, Edit::Light, Edit::Material, Edit::TextureSwap, Edit::MeshPoints];

    fn name(self) -> &'static str {
        match self {
            Edit::Camera => "camera move",
            Edit::Transform => "object transform",
            Edit::Light => "light intensity",
            Edit::Material => "material roughness",
            Edit::TextureSwap => "texture swap",
            Edit::MeshPoints => "mesh points",
        }
    }

    /// The prim deltas that make the `k`-th edit of this kind, or `None` where the scene has
    /// nothing to edit that way (a texture swap needs a textured material).
    fn items(self, t: &Translation, k: usize) -> Option<Vec<pb::sync_request::Item>> {
        let wiggle = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
        let nudge = |by: f32| Affine3A::from_translation(Vec3::new(by * wiggle, 0.0, 0.0));
        Some(match self {
            Edit::Camera => {
                let (path, c) = &t.cameras[0];
                let c = CameraDesc { transform: nudge(0.01) * c.transform, ..c.clone() };
                vec![tessera::sync::delta(path, pb::PrimKind::Camera, pb::prim_delta::Payload::Camera(convert::camera_to_wire(&c)))]
            }
            Edit::Transform => {
                let (path, m) = edited_mesh(t, false);
                vec![tessera::sync::mesh_placement(path, &MeshDesc { transform: nudge(0.02) * m.transform, ..m.clone() })]
            }
            Edit::Light => {
                let (path, l) = &t.lights[0];
                let l = LightDesc { intensity: l.intensity * (1.0 + 0.1 * wiggle), ..l.clone() };
                vec![tessera::sync::delta(path, pb::PrimKind::Light, pb::prim_delta::Payload::Light(convert::light_to_wire(&l)))]
            }
            Edit::Material => {
                let (path, mut m) = t.materials[0].clone();
                let surface = m.nodes.iter_mut().find(|n| n.node_type_id == "UsdPreviewSurface")?;
                surface.parameters.insert("roughness".into(), ParamValue::Float(0.5 + 0.2 * wiggle));
                vec![material_item(&path, &m)]
            }
            Edit::TextureSwap => {
                // Both files were uploaded with the scene (as a DCC's first swap would upload
                // the new one); the edit names the other by content.
                let (path, mut m) = t.materials.iter().find(|(_, m)| m.nodes.iter().any(|n| n.node_type_id == "UsdUVTexture"))?.clone();
                let node = m.nodes.iter_mut().find(|n| n.node_type_id == "UsdUVTexture")?;
                let (hash, file) = t.textures.iter().nth(k % 2)?;
                node.parameters.insert("file".into(), ParamValue::Texture { hash: hash.clone(), source: file.source.clone() });
                vec![material_item(&path, &m)]
            }
            Edit::MeshPoints => {
                let (path, m) = edited_mesh(t, true);
                let mut mesh = (*m.mesh).clone();
                mesh.positions.iter_mut().for_each(|p| *p *= 1.0 + 0.01 * wiggle);
                let moved = MeshDesc { mesh: std::sync::Arc::new(mesh), ..m.clone() };
                tessera::sync::full_sync(&Translation { meshes: vec![(path.clone(), moved)], ..Default::default() })
            }
        })
    }
}

/// The mesh an edit moves: the Cornell box's tall box; else, for point edits, the prototype
/// of instances (every instance changes), and for transforms the first visible mesh.
fn edited_mesh(t: &Translation, points: bool) -> &(String, MeshDesc) {
    let prototype = t.instancers.first().map(|(_, i)| i.prototype.as_str()).filter(|_| points);
    let pick = |(p, m): &&(String, MeshDesc)| p.contains("Tall") || Some(p.as_str()) == prototype || (!points && m.visible);
    t.meshes.iter().find(|m| m.0.contains("Tall")).or_else(|| t.meshes.iter().find(pick)).unwrap_or(&t.meshes[0])
}

fn material_item(path: &str, m: &MaterialNetwork) -> pb::sync_request::Item {
    tessera::sync::delta(path, pb::PrimKind::Material, pb::prim_delta::Payload::Material(convert::material_to_wire(m)))
}

/// The checker-plane fixture with a second texture uploaded beside its own, for swaps.
fn textured_plane() -> Translation {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/textures");
    let mut t = tessera::usd::load(&dir.join("checker_plane.usda")).unwrap();
    let bytes = std::fs::read(dir.join("maps/quadrants.png")).unwrap();
    let file = tessera::usd::TextureFile { source: "maps/quadrants.png".into(), bytes: std::sync::Arc::new(bytes) };
    t.textures.insert(tessera_wire::content_hash(&file.bytes), file);
    t
}

async fn client(server: &EmbeddedServer) -> Client {
    let channel = Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
    RenderClient::new(channel).max_decoding_message_size(64 << 20)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// What the stream reader saw, with the time it arrived.
enum Seen {
    Tile(u64, Instant),
    Restarted(u64, Instant),
    /// The first coarse pass of a version covered the whole frame.
    CoarseFrame(u64, Instant),
}

/// Reads a render stream to its end, reporting tiles (with the version they belong to),
/// restarts, and the moment the first coarse pass of each version covered `pixels`.
fn read_events(mut stream: tonic::Streaming<pb::RenderEvent>, pixels: u32, tx: mpsc::UnboundedSender<Seen>) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let (mut version, mut coarse) = (0, 0);
        while let Ok(Some(e)) = stream.message().await {
            let now = Instant::now();
            match e.event {
                Some(pb::render_event::Event::Started(s)) => version = s.scene_version,
                Some(pb::render_event::Event::Restarted(r)) => {
                    (version, coarse) = (r.scene_version, 0);
                    let _ = tx.send(Seen::Restarted(version, now));
                }
                Some(pb::render_event::Event::Tile(t)) if t.aov == "beauty" => {
                    let _ = tx.send(Seen::Tile(version, now));
                    if t.pixel_size == COARSE_START {
                        coarse += t.width * t.height;
                        if coarse == pixels {
                            let _ = tx.send(Seen::CoarseFrame(version, now));
                        }
                    }
                }
                _ => {}
            }
        }
    })
}

/// When `version` (or a newer one) showed: its `Restarted`, first tile and first whole
/// coarse frame.
struct Shown {
    restarted: Option<Instant>,
    tile: Instant,
    frame: Instant,
}

/// Waits for the first whole coarse frame of `version` (or newer).
async fn until_new_frame(rx: &mut mpsc::UnboundedReceiver<Seen>, version: u64) -> Shown {
    let (mut restarted, mut tile) = (None, None);
    loop {
        match rx.recv().await.expect("the render ended before showing the edit") {
            Seen::Restarted(v, t) if v >= version && restarted.is_none() => restarted = Some(t),
            Seen::Tile(v, t) if v >= version && tile.is_none() => tile = Some(t),
            Seen::CoarseFrame(v, t) if v >= version => return Shown { restarted, tile: tile.unwrap_or(t), frame: t },
            _ => {}
        }
    }
}

/// A tiny deterministic generator for the moments of the edits.
fn next_delay(state: &mut u64) -> Duration {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    Duration::from_millis(30 + (*state >> 33) % 600)
}

fn summary(label: &str, v: &mut [f64]) -> String {
    v.sort_by(f64::total_cmp);
    format!("{label} p50 {:.0} ms, p90 {:.0} ms, max {:.0} ms", percentile(v, 0.5), percentile(v, 0.9), v.last().unwrap())
}

async fn edits_during_render(server: &EmbeddedServer, t: &Translation, width: u32, height: u32) {
    let mut c = client(server).await;
    let s = c.create_session(pb::CreateSessionRequest { client_name: "interactive bench".into() }).await.unwrap().into_inner().session_id;
    c.sync(tokio_stream::iter(tessera::sync::requests(&s, tessera::sync::full_sync(t)))).await.unwrap();
    let settings = pb::RenderSettings { width, height, spp: 1 << 16, coarse_start: COARSE_START, ..Default::default() };
    let started = Instant::now();
    let stream = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(settings) }).await.unwrap().into_inner();
    let (tx, mut rx) = mpsc::unbounded_channel();
    let reader = read_events(stream, width * height, tx);
    let first = until_new_frame(&mut rx, 0).await;
    let ms = |t: Instant, from: Instant| (t - from).as_secs_f64() * 1e3;
    println!(
        "{width}x{height}: first tile {:.0} ms, first whole coarse frame {:.0} ms after Render",
        ms(first.tile, started),
        ms(first.frame, started)
    );
    let mut state = 0x7e55e7a;
    for kind in Edit::ALL {
        if kind.items(t, 0).is_none() {
            continue;
        }
        let (mut sync, mut restart, mut tile, mut frame) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for k in 0..EDITS {
            let items = kind.items(t, k).unwrap();
            tokio::time::sleep(next_delay(&mut state)).await;
            while rx.try_recv().is_ok() {}
            let t0 = Instant::now();
            let r = c.sync(tokio_stream::iter(tessera::sync::requests(&s, items))).await.unwrap().into_inner();
            sync.push(t0.elapsed().as_secs_f64() * 1e3);
            let shown = until_new_frame(&mut rx, r.scene_version).await;
            restart.push(shown.restarted.map_or(f64::NAN, |r| ms(r, t0)));
            tile.push(ms(shown.tile, t0));
            frame.push(ms(shown.frame, t0));
        }
        println!(
            "  {:<18} {}; {}; {}; {}",
            kind.name(),
            summary("Sync returns", &mut sync),
            summary("Restarted", &mut restart),
            summary("first new tile", &mut tile),
            summary("whole coarse frame", &mut frame)
        );
    }
    c.cancel(pb::CancelRequest { session_id: s.clone() }).await.unwrap();
    reader.await.unwrap();
    c.close_session(pb::CloseSessionRequest { session_id: s }).await.unwrap();
}

/// A scene built in code, as the client's translation of a stage would hold it.
fn as_translation(desc: render_core::scene::SceneDesc) -> Translation {
    Translation {
        meshes: desc.meshes.into_iter().collect(),
        materials: desc.materials.into_iter().collect(),
        instancers: desc.instancers.into_iter().collect(),
        lights: desc.lights.into_iter().collect(),
        cameras: desc.cameras.into_iter().collect(),
        ..Default::default()
    }
}

fn main() {
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    rt.block_on(async {
        // As `tessera-server` does at start-up (the embedded server builds them on first use).
        render_core::bsdf::energy::warm_up();
        let server = EmbeddedServer::start().await.unwrap();
        println!("interactive bench, {} cores, {EDITS} edits per kind", std::thread::available_parallelism().map_or(1, |n| n.get()));
        let cornell =
            tessera::usd::load(&std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/cornell_box.usda")).unwrap();
        for (w, h) in [(512, 512), (1920, 1080)] {
            println!("Cornell box");
            edits_during_render(&server, &cornell, w, h).await;
        }
        println!("Textured plane (fixtures/textures/checker_plane.usda) with a second texture to swap to");
        edits_during_render(&server, &textured_plane(), 1920, 1080).await;
        println!("1M-triangle mesh + 400 instances of a 5k-triangle rock (tessera_tests::production_scene)");
        edits_during_render(&server, &as_translation(tessera_tests::production_scene()), 1920, 1080).await;
        server.stop().await.unwrap();
    });
}
