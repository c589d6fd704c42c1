//! Hostile clients: every size, depth and count a client controls, sent at its worst over
//! loopback to the real server. Each case expects a clear status naming the prim or field (or
//! a bounded, correct result), and a second session that keeps rendering meanwhile.

use std::time::{Duration, Instant};

use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tessera_server::auth::Auth;
use tessera_server::{EmbeddedServer, ServerConfig};
use tessera_tests::*;
use tonic::transport::Channel;
use tonic::{Code, Status};

type Item = pb::sync_request::Item;

/// A raw protocol client (no USD, no helpers), as a hostile grpcio script would be.
struct Raw {
    client: RenderClient<Channel>,
    token: Option<String>,
}

impl Raw {
    async fn connect(server: &EmbeddedServer) -> Raw {
        let channel = Channel::from_shared(server.url()).unwrap().connect().await.unwrap();
        Raw { client: RenderClient::new(channel).max_decoding_message_size(64 << 20), token: None }
    }

    async fn as_tenant(server: &EmbeddedServer, token: &str) -> Raw {
        Raw { token: Some(token.into()), ..Raw::connect(server).await }
    }

    fn req<T>(&self, msg: T) -> tonic::Request<T> {
        let mut r = tonic::Request::new(msg);
        if let Some(t) = &self.token {
            r.metadata_mut().insert("authorization", format!("Bearer {t}").parse().unwrap());
        }
        r
    }

    async fn session(&mut self) -> Result<String, Status> {
        let r = self.req(pb::CreateSessionRequest { client_name: "hostile".into() });
        Ok(self.client.create_session(r).await?.into_inner().session_id)
    }

    async fn sync(&mut self, session: &str, items: Vec<Item>) -> Result<pb::SyncResponse, Status> {
        let reqs = tessera::sync::requests(session, items);
        let r = self.req(tokio_stream::iter(reqs));
        Ok(self.client.sync(r).await?.into_inner())
    }

    async fn render_stream(&mut self, session: &str, settings: pb::RenderSettings) -> Result<tonic::Streaming<pb::RenderEvent>, Status> {
        let r = self.req(pb::RenderRequest { session_id: session.into(), settings: Some(settings) });
        Ok(self.client.render(r).await?.into_inner())
    }

    /// Renders to the end; the `Finished` event.
    async fn render(&mut self, session: &str, settings: pb::RenderSettings) -> Result<pb::Finished, Status> {
        let mut stream = self.render_stream(session, settings).await?;
        while let Some(e) = stream.message().await? {
            if let Some(pb::render_event::Event::Finished(f)) = e.event {
                return Ok(f);
            }
        }
        Err(Status::internal("stream ended without Finished"))
    }

    async fn cancel(&mut self, session: &str) -> Result<bool, Status> {
        let r = self.req(pb::CancelRequest { session_id: session.into() });
        Ok(self.client.cancel(r).await?.into_inner().was_rendering)
    }

    async fn close(&mut self, session: &str) -> Result<(), Status> {
        let r = self.req(pb::CloseSessionRequest { session_id: session.into() });
        self.client.close_session(r).await.map(|_| ())
    }

    async fn stats(&mut self, session: &str) -> Result<pb::SessionStats, Status> {
        let r = self.req(pb::GetSessionStatsRequest { session_id: session.into() });
        Ok(self.client.get_session_stats(r).await?.into_inner())
    }
}

fn tiny(width: u32, spp: u32) -> pb::RenderSettings {
    pb::RenderSettings { width, height: width, spp, max_depth: 2, ..Default::default() }
}

/// A bystander: its own session with the Cornell box, which must keep rendering whatever the
/// hostile client did.
async fn bystander_renders(server: &EmbeddedServer) {
    let mut raw = Raw::connect(server).await;
    let s = raw.session().await.expect("a bystander gets a session");
    raw.sync(&s, tessera::sync::full_sync(&load("cornell_box.usda"))).await.expect("the bystander's scene syncs");
    let f = raw.render(&s, tiny(16, 2)).await.expect("the bystander renders");
    assert!(!f.cancelled && f.spp == 2, "{f:?}");
    raw.close(&s).await.unwrap();
}

fn assert_status(r: Result<impl std::fmt::Debug, Status>, code: Code, needles: &[&str]) {
    let e = r.expect_err("the server must refuse this");
    assert_eq!(e.code(), code, "{e:?}");
    for n in needles {
        assert!(e.message().contains(n), "'{n}' missing from: {}", e.message());
    }
}

/// A mesh delta with its arrays in single chunks.
fn mesh(path: &str, points: Vec<f32>, indices: Vec<u32>) -> Vec<Item> {
    let prim =
        pb::MeshPrim { points_len: points.len() as u64, triangle_indices_len: indices.len() as u64, visible: true, ..Default::default() };
    let mut items = vec![tessera::sync::delta(path, pb::PrimKind::Mesh, pb::prim_delta::Payload::Mesh(prim))];
    for (field, floats, uints) in [(pb::ArrayField::Points, points, vec![]), (pb::ArrayField::TriangleIndices, vec![], indices)] {
        for (k, (f, u)) in chunked(&floats, &uints).into_iter().enumerate() {
            let offset = (k * tessera::sync::CHUNK_ELEMENTS) as u64;
            items.push(Item::Chunk(pb::ArrayChunk {
                path: path.into(),
                field: field as i32,
                offset,
                floats: f,
                uints: u,
                ..Default::default()
            }));
        }
    }
    items
}

fn chunked(floats: &[f32], uints: &[u32]) -> Vec<(Vec<f32>, Vec<u32>)> {
    let n = tessera::sync::CHUNK_ELEMENTS;
    if !floats.is_empty() {
        floats.chunks(n).map(|c| (c.to_vec(), vec![])).collect()
    } else {
        uints.chunks(n).map(|c| (vec![], c.to_vec())).collect()
    }
}

/// A camera looking down -Z at the unit triangle from z = 3, and a dome.
fn camera_and_light() -> Vec<Item> {
    let mut m = vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.3, 0.3, 3.0, 1.0];
    m.truncate(16);
    let camera = pb::CameraPrim {
        transform: Some(pb::Matrix4 { m }),
        focal_length: 50.0,
        horizontal_aperture: 20.0,
        vertical_aperture: 20.0,
        near_clip: 0.01,
        far_clip: 100.0,
        ..Default::default()
    };
    let dome = pb::LightPrim { light_type: pb::LightType::Dome as i32, intensity: 1.0, visible: true, ..Default::default() };
    vec![
        tessera::sync::delta("/Cam", pb::PrimKind::Camera, pb::prim_delta::Payload::Camera(camera)),
        tessera::sync::delta("/Dome", pb::PrimKind::Light, pb::prim_delta::Payload::Light(dome)),
    ]
}

const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

// ------------------------------------------------------------------ bounded work

/// obvhs built a chain 30 000 deep from coincident triangles and overflowed the stack (the
/// server aborted after 19 s). Now it commits and renders.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thirty_thousand_copies_of_one_triangle_render() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let n = 30_000u32;
    let indices: Vec<u32> = (0..n).flat_map(|_| [0, 1, 2]).collect();
    let mut items = mesh("/Evil/Coincident", TRIANGLE.to_vec(), indices);
    items.extend(camera_and_light());
    raw.sync(&s, items).await.expect("coincident triangles commit");
    let f = raw.render(&s, tiny(8, 1)).await.expect("and render");
    assert_eq!(f.spp, 1);
    bystander_renders(&server).await;
}

/// The same through the top level: 100 000 instances with one transform.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hundred_thousand_identical_instances_render() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let mut items = mesh("/Proto", TRIANGLE.to_vec(), vec![0, 1, 2]);
    let n = 100_000usize;
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let transforms: Vec<f64> = (0..n).flat_map(|_| identity).collect();
    let inst = pb::InstancerPrim {
        prototype_path: "/Proto".into(),
        transforms_len: transforms.len() as u64,
        motion_samples: 0,
        link_collections: Vec::new(),
    };
    items.push(tessera::sync::delta("/Evil/Instancer", pb::PrimKind::Instancer, pb::prim_delta::Payload::Instancer(inst)));
    for (k, c) in transforms.chunks(tessera::sync::CHUNK_ELEMENTS).enumerate() {
        items.push(Item::Chunk(pb::ArrayChunk {
            path: "/Evil/Instancer".into(),
            field: pb::ArrayField::InstanceTransforms as i32,
            offset: (k * tessera::sync::CHUNK_ELEMENTS) as u64,
            doubles: c.to_vec(),
            ..Default::default()
        }));
    }
    items.extend(camera_and_light());
    raw.sync(&s, items).await.expect("identical instances commit");
    raw.render(&s, tiny(8, 1)).await.expect("and render");
    bystander_renders(&server).await;
}

fn node(path: &str, id: &str, params: &[(&str, pb::param_value::Value)]) -> pb::MaterialNode {
    pb::MaterialNode {
        path: path.into(),
        node_type_id: id.into(),
        parameters: params.iter().map(|(k, v)| (k.to_string(), pb::ParamValue { value: Some(v.clone()) })).collect(),
    }
}

fn link(down: &str, input: &str, up: &str, output: &str) -> pb::MaterialConnection {
    pb::MaterialConnection {
        downstream_node: down.into(),
        downstream_input: input.into(),
        upstream_node: up.into(),
        upstream_output: output.into(),
    }
}

fn material(path: &str, net: pb::MaterialNetwork) -> Item {
    tessera::sync::delta(path, pb::PrimKind::Material, pb::prim_delta::Payload::Material(net))
}

/// The 126-byte material that grew memory by 180 MB/s until the process aborted: a Layer
/// whose two inputs connect to itself. Refused, naming the cycle.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_layer_connected_to_itself_is_refused_naming_the_cycle() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let net = pb::MaterialNetwork {
        nodes: vec![node("/M/L", "tessera:Layer", &[])],
        connections: vec![link("/M/L", "a", "/M/L", "surface"), link("/M/L", "b", "/M/L", "surface")],
        surface_node: "/M/L".into(),
    };
    assert_status(
        raw.sync(&s, vec![material("/Evil/SelfLayer", net)]).await,
        Code::InvalidArgument,
        &["/Evil/SelfLayer", "cycle", "/M/L -> /M/L"],
    );
    // A longer cycle through a texture chain is found too.
    let net = pb::MaterialNetwork {
        nodes: vec![
            node("/M/S", "UsdPreviewSurface", &[]),
            node("/M/T1", "UsdTransform2d", &[]),
            node("/M/T2", "UsdTransform2d", &[]),
            node("/M/Tex", "UsdUVTexture", &[]),
        ],
        connections: vec![
            link("/M/S", "diffuseColor", "/M/Tex", "rgb"),
            link("/M/Tex", "st", "/M/T1", "result"),
            link("/M/T1", "in", "/M/T2", "result"),
            link("/M/T2", "in", "/M/T1", "result"),
        ],
        surface_node: "/M/S".into(),
    };
    assert_status(raw.sync(&s, vec![material("/Evil/Loop", net)]).await, Code::InvalidArgument, &["/Evil/Loop", "cycle", "/M/T1", "/M/T2"]);
    bystander_renders(&server).await;
}

/// A Layer "diamond" of depth 24 (each level's a and b both the next level) doubled its
/// commit time per level (7 s); resolved once per node it commits and renders at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_layer_diamond_resolves_each_node_once() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let depth = 24;
    let mut nodes = Vec::new();
    let mut connections = Vec::new();
    for k in 0..depth {
        nodes.push(node(&format!("/M/L{k}"), "tessera:Layer", &[("mask", pb::param_value::Value::FloatValue(0.5))]));
        let next = if k + 1 == depth { "/M/Metal".to_string() } else { format!("/M/L{}", k + 1) };
        connections.push(link(&format!("/M/L{k}"), "a", &next, "surface"));
        connections.push(link(&format!("/M/L{k}"), "b", &next, "surface"));
    }
    nodes.push(node("/M/Metal", "tessera:Metal", &[]));
    let net = pb::MaterialNetwork { nodes, connections, surface_node: "/M/L0".into() };
    let mut items = vec![material("/Evil/Diamond", net)];
    let mut m = mesh("/Tri", TRIANGLE.to_vec(), vec![0, 1, 2]);
    if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Mesh(mp)), .. }) = &mut m[0] {
        mp.material_path = "/Evil/Diamond".into();
    }
    items.extend(m);
    items.extend(camera_and_light());
    let started = Instant::now();
    raw.sync(&s, items).await.expect("a diamond is no cycle");
    raw.render(&s, tiny(8, 1)).await.unwrap();
    // 2^24 resolutions took minutes; 25 take microseconds. Generous for a loaded CI machine.
    assert!(started.elapsed() < Duration::from_secs(20), "{:?}", started.elapsed());
    bystander_renders(&server).await;
}

/// A 40 000-node UsdTransform2d chain (2.8 MB) took 64 s to commit; networks are now
/// limited in nodes and depth, and refused naming the limit.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn huge_and_deep_material_networks_are_refused_by_their_limits() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let chain = |n: usize| {
        let mut nodes = vec![node("/M/S", "UsdPreviewSurface", &[]), node("/M/Tex", "UsdUVTexture", &[])];
        let mut connections = vec![link("/M/S", "diffuseColor", "/M/Tex", "rgb"), link("/M/Tex", "st", "/M/T0", "result")];
        for k in 0..n {
            nodes.push(node(&format!("/M/T{k}"), "UsdTransform2d", &[]));
            if k + 1 < n {
                connections.push(link(&format!("/M/T{k}"), "in", &format!("/M/T{}", k + 1), "result"));
            }
        }
        pb::MaterialNetwork { nodes, connections, surface_node: "/M/S".into() }
    };
    assert_status(
        raw.sync(&s, vec![material("/Evil/Chain", chain(40_000))]).await,
        Code::InvalidArgument,
        &["/Evil/Chain", "nodes", "limit of 1024"],
    );
    assert_status(raw.sync(&s, vec![material("/Evil/Deep", chain(100))]).await, Code::InvalidArgument, &["/Evil/Deep", "more than 64"]);
    bystander_renders(&server).await;
}

/// Motion samples are a count the client controls: 100 000 of them (13 MB) pass no message
/// limit, and 20 000 (2.7 MB, within it), a single one, a singular one and a NaN one are
/// refused naming the field, for meshes, cameras, lights and volumes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn motion_samples_beyond_the_limit_or_broken_are_refused() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let identity = || pb::Matrix4 { m: vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0] };
    let with_motion = |motion: Vec<pb::Matrix4>| {
        let mut items = mesh("/Evil/Mover", TRIANGLE.to_vec(), vec![0, 1, 2]);
        if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Mesh(m)), .. }) = &mut items[0] {
            m.motion = motion;
        }
        items
    };
    let singular = pb::Matrix4 { m: vec![0.0; 16] };
    let nan = pb::Matrix4 { m: vec![f64::NAN; 16] };
    for (what, motion, needle) in [
        ("20 000 samples", vec![identity(); 20_000], "20000 motion samples"),
        ("one sample", vec![identity()], "1 motion samples"),
        ("a singular sample", vec![identity(), singular], "singular"),
        ("a NaN sample", vec![identity(), nan], "NaN"),
    ] {
        let r = raw.sync(&s, with_motion(motion.clone())).await;
        assert!(r.is_err(), "{what}");
        assert_status(r, Code::InvalidArgument, &["/Evil/Mover", "motion", needle]);
        let camera = pb::CameraPrim {
            focal_length: 50.0,
            horizontal_aperture: 20.0,
            vertical_aperture: 20.0,
            motion: motion.clone(),
            ..Default::default()
        };
        let light = pb::LightPrim {
            light_type: pb::LightType::Sphere as i32,
            radius: 1.0,
            intensity: 1.0,
            motion: motion.clone(),
            ..Default::default()
        };
        use pb::prim_delta::Payload;
        for (path, kind, payload) in
            [("/Evil/Cam", pb::PrimKind::Camera, Payload::Camera(camera)), ("/Evil/Bulb", pb::PrimKind::Light, Payload::Light(light))]
        {
            let r = raw.sync(&s, vec![tessera::sync::delta(path, kind, payload)]).await;
            assert_status(r, Code::InvalidArgument, &[path, "motion", needle]);
        }
        let mut smoke = volume([1, 1, 1], (1, 0), &[1.0], None);
        if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Volume(v)), .. }) = &mut smoke[0] {
            v.index_to_world = Some(identity());
            v.motion = motion.clone();
        }
        assert_status(raw.sync(&s, smoke).await, Code::InvalidArgument, &["/Evil/Smoke", "motion", needle]);
    }
    assert_status(raw.sync(&s, with_motion(vec![identity(); 100_000])).await, Code::OutOfRange, &["message length too large"]);
    // A valid motion syncs and renders.
    let mut items = with_motion(vec![identity(), identity()]);
    items.extend(camera_and_light());
    raw.sync(&s, items).await.expect("two samples sync");
    let f = raw.render(&s, tiny(8, 2)).await.expect("renders");
    assert_eq!(f.spp, 2);
    bystander_renders(&server).await;
}

/// A camera's exposure is a number the client controls: NaN, infinities and anything past
/// ±64 stops (2^±64) are refused naming the field; 64 stops down syncs and renders.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_camera_exposure_past_the_limit_is_refused() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let camera = |exposure: f32| {
        let lens =
            pb::CameraPrim { focal_length: 50.0, horizontal_aperture: 20.0, vertical_aperture: 20.0, exposure, ..Default::default() };
        tessera::sync::delta("/Evil/Cam", pb::PrimKind::Camera, pb::prim_delta::Payload::Camera(lens))
    };
    for exposure in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 64.5, -1e30] {
        assert_status(raw.sync(&s, vec![camera(exposure)]).await, Code::InvalidArgument, &["/Evil/Cam", "exposure", "stops"]);
    }
    let mut items = camera_and_light();
    if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Camera(c)), .. }) = &mut items[0] {
        c.exposure = -64.0;
    }
    items.extend(mesh("/Tri", TRIANGLE.to_vec(), vec![0, 1, 2]));
    raw.sync(&s, items).await.expect("64 stops down syncs");
    let f = raw.render(&s, tiny(8, 2)).await.expect("renders");
    assert_eq!(f.spp, 2);
    bystander_renders(&server).await;
}

/// Deformation samples are a count and an array the client controls: a count outside 2..=64
/// (u32::MAX included), points that are no whole number of sets, and a NaN in a later set are
/// refused naming the field; a valid deformation syncs and renders.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deformation_samples_that_fit_no_mesh_are_refused() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let deforming = |samples: u32, points: Vec<f32>| {
        let mut items = mesh("/Evil/Blob", points, vec![0, 1, 2]);
        if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Mesh(m)), .. }) = &mut items[0] {
            m.point_samples = samples;
        }
        items
    };
    let sets = |n: usize| TRIANGLE.repeat(n);
    for (samples, points, needle) in [
        (1, sets(2), "point_samples"),
        (65, sets(66), "point_samples"),
        (u32::MAX, sets(2), "point_samples"),
        (2, [TRIANGLE.as_slice(), &[0.0, 0.0, 1.0]].concat(), "whole sets"),
    ] {
        let r = raw.sync(&s, deforming(samples, points)).await;
        assert_status(r, Code::InvalidArgument, &["/Evil/Blob", needle]);
    }
    let mut nan = sets(3);
    nan[9 + 4] = f32::NAN;
    assert_status(raw.sync(&s, deforming(2, nan)).await, Code::InvalidArgument, &["/Evil/Blob", "deformation", "sample 0"]);
    let mut items = deforming(2, sets(3));
    items.extend(camera_and_light());
    raw.sync(&s, items).await.expect("a deformation of two samples syncs");
    assert_eq!(raw.render(&s, tiny(8, 2)).await.expect("renders").spp, 2);
    bystander_renders(&server).await;
}

/// Instancer motion is counts too: motion samples outside 2..=64 and a transforms array
/// that fits no number of instances are refused naming the field.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn instancer_motion_that_fits_no_instances_is_refused() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let instancer = |motion_samples: u32, transforms_len: u64| {
        let prim = pb::InstancerPrim { prototype_path: "/Evil/Proto".into(), transforms_len, motion_samples, link_collections: Vec::new() };
        vec![tessera::sync::delta("/Evil/Crowd", pb::PrimKind::Instancer, pb::prim_delta::Payload::Instancer(prim))]
    };
    assert_status(raw.sync(&s, instancer(1, 32)).await, Code::InvalidArgument, &["/Evil/Crowd", "motion_samples", "2 to 64"]);
    assert_status(raw.sync(&s, instancer(65, 16 * 66)).await, Code::InvalidArgument, &["/Evil/Crowd", "motion_samples"]);
    assert_status(raw.sync(&s, instancer(3, 16 * 3)).await, Code::InvalidArgument, &["/Evil/Crowd", "multiple of 64"]);
    assert_status(raw.sync(&s, instancer(64, u64::MAX - 7)).await, Code::InvalidArgument, &["/Evil/Crowd", "transforms"]);
    bystander_renders(&server).await;
}

/// A volume delta of `dims` voxels declaring `density_len` and `temperature_len` values,
/// with `voxels` sent as its density (chunked) and `shading`.
fn volume(dims: [u32; 3], lens: (u64, u64), voxels: &[f32], shading: Option<pb::VolumeShading>) -> Vec<Item> {
    let prim = pb::VolumePrim {
        dims_x: dims[0],
        dims_y: dims[1],
        dims_z: dims[2],
        density_len: lens.0,
        temperature_len: lens.1,
        shading,
        ..Default::default()
    };
    let mut items = vec![tessera::sync::delta("/Evil/Smoke", pb::PrimKind::Volume, pb::prim_delta::Payload::Volume(prim))];
    for (k, c) in voxels.chunks(tessera::sync::CHUNK_ELEMENTS).enumerate() {
        let offset = (k * tessera::sync::CHUNK_ELEMENTS) as u64;
        let field = pb::ArrayField::VolumeDensity as i32;
        items.push(Item::Chunk(pb::ArrayChunk { path: "/Evil/Smoke".into(), field, offset, floats: c.to_vec(), ..Default::default() }));
    }
    items
}

/// Every count a volume's client controls, at its worst: dims whose product overflows, dims
/// that disagree with the values, a grid over the voxel limit, a temperature grid of another
/// size, missing, non-finite or negative voxels, an albedo above 1 and chunks with no volume:
/// each refused naming the field, and the server serves a valid volume and a bystander after.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn volumes_that_fit_no_grid_are_refused() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let ones = vec![1.0f32; 8];
    let bright = pb::VolumeShading { density: 1.0, color: Some(pb::Float3 { x: 2.0, y: 0.5, z: 0.5 }), ..Default::default() };
    let mut nan = ones.clone();
    nan[5] = f32::NAN;
    let mut negative = ones.clone();
    negative[2] = -1.0;
    for (items, code, needles) in [
        (volume([u32::MAX; 3], (8, 0), &ones, None), Code::InvalidArgument, vec!["/Evil/Smoke", "density", "declared"]),
        (volume([u32::MAX; 3], (u64::MAX, 0), &[], None), Code::ResourceExhausted, vec!["/Evil/Smoke", "voxels exceed"]),
        (volume([2, 2, 2], (7, 0), &ones[..7], None), Code::InvalidArgument, vec!["density", "7 values declared for 8 voxels"]),
        (volume([1024, 1024, 1024], (1 << 30, 0), &[], None), Code::ResourceExhausted, vec!["/Evil/Smoke", "voxels exceed"]),
        (volume([2, 2, 2], (8, 3), &ones, None), Code::InvalidArgument, vec!["temperature", "0 or one per voxel"]),
        (
            {
                let mut items = volume([2, 2, 2], (8, 0), &ones, None);
                if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Volume(v)), .. }) = &mut items[0] {
                    v.color_len = 8;
                }
                items
            },
            Code::InvalidArgument,
            vec!["color", "three per voxel"],
        ),
        (volume([2, 2, 2], (8, 0), &ones[..4], None), Code::InvalidArgument, vec!["density", "received 4 of 8"]),
        (volume([2, 2, 2], (8, 0), &nan, None), Code::InvalidArgument, vec!["density", "voxel 5"]),
        (volume([2, 2, 2], (8, 0), &negative, None), Code::InvalidArgument, vec!["density", "voxel 2"]),
        (volume([2, 2, 2], (8, 0), &ones, Some(bright)), Code::InvalidArgument, vec!["shading.color", "energy"]),
        (volume([2, 2, 2], (8, 0), &ones, None)[1..].to_vec(), Code::InvalidArgument, vec!["no volume delta"]),
    ] {
        assert_status(raw.sync(&s, items).await, code, &needles);
    }
    let mut items = volume([2, 2, 2], (8, 0), &ones, None);
    items.extend(camera_and_light());
    raw.sync(&s, items).await.expect("a 2³ volume syncs");
    assert_eq!(raw.render(&s, tiny(8, 2)).await.expect("renders").spp, 2);
    bystander_renders(&server).await;
}

// ------------------------------------------------------------------ memory

/// Lights are a count the client controls, and each may carry 64 motion samples: thousands of
/// moving lights are held against the memory budget as geometry is, refused with
/// RESOURCE_EXHAUSTED naming it; a hundred fit, and another session still renders.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thousands_of_moving_lights_are_held_against_the_memory_budget() {
    let server = EmbeddedServer::start_with(budgeted(16 << 20)).await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let identity = || pb::Matrix4 { m: vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0] };
    let lights = |n: usize| -> Vec<Item> {
        let bulb = |i| {
            let light = pb::LightPrim {
                light_type: pb::LightType::Sphere as i32,
                radius: 0.1,
                intensity: 1.0,
                motion: vec![identity(); 64],
                ..Default::default()
            };
            tessera::sync::delta(&format!("/Evil/Bulb{i}"), pb::PrimKind::Light, pb::prim_delta::Payload::Light(light))
        };
        (0..n).map(bulb).collect()
    };
    // 3 000 × (1 KiB + 64 samples × 96 B) = 21.5 MB as estimated, over the 16 MiB budget.
    assert_status(raw.sync(&s, lights(3000)).await, Code::ResourceExhausted, &["memory budget"]);
    raw.sync(&s, lights(100)).await.expect("a hundred moving lights fit");
    bystander_renders(&server).await;
}

/// Displacement dicing makes triangles the description does not hold, so the commit cannot
/// reserve them beforehand: they are held against the budget once made, and a scene whose
/// dicing does not fit is refused naming it. The fixture's 6 k triangles dice into 56 k (14 MB as
/// estimated, at 256 bytes a triangle): over a 4 MiB budget, within a 32 MiB one, where the
/// stats count them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn displacement_dicing_is_held_against_the_memory_budget() {
    for (budget, fits) in [(4u64 << 20, false), (32 << 20, true)] {
        let server = EmbeddedServer::start_with(budgeted(budget)).await.unwrap();
        let mut raw = Raw::connect(&server).await;
        let s = raw.session().await.unwrap();
        let synced = raw.sync(&s, tessera::sync::full_sync(&load("textures/displaced.usda"))).await;
        let st = raw.stats(&s).await.unwrap();
        if fits {
            synced.expect("the diced scene fits 32 MiB");
            assert!(st.triangles > 55_000, "diced triangles counted: {st:?}");
            assert!(st.session_memory_used >= st.triangles * 256, "{st:?}");
        } else {
            assert_status(synced, Code::ResourceExhausted, &["displacement dicing", "memory budget"]);
            assert_eq!(st.session_memory_used, 0, "nothing stays reserved: {st:?}");
        }
        bystander_renders(&server).await;
    }
}

/// A server with a 2 GiB budget, as the memory test and an operator's small box would run it.
fn budgeted(bytes: u64) -> ServerConfig {
    ServerConfig { memory_budget: bytes, session_memory_budget: bytes, ..ServerConfig::default() }
}

/// Under a 2 GiB budget: the 16384² all-AOV render (92 GiB of film), the 16-bit PNG bomb (4
/// GiB to decode), a 200M-triangle declaration and a deformation whose BLAS would not fit are
/// each refused with RESOURCE_EXHAUSTED naming what and how much, before anything is allocated.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_beyond_the_memory_budget_are_resource_exhausted() {
    let server = EmbeddedServer::start_with(budgeted(2 << 30)).await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    raw.sync(&s, tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();

    let all: Vec<String> = render_core::film::Aov::ALL.iter().skip(1).map(|a| a.name().to_string()).collect();
    let huge = pb::RenderSettings { width: 16384, height: 16384, aovs: all, ..Default::default() };
    assert_status(raw.render(&s, huge).await, Code::ResourceExhausted, &["16384x16384 film", "memory budget", "GiB"]);

    // 2^28 voxels (the per-grid limit) of density and temperature: 2 GiB as declared.
    let voxels = volume([1024, 1024, 256], (1 << 28, 1 << 28), &[], None);
    assert_status(raw.sync(&s, voxels).await, Code::ResourceExhausted, &["/Evil/Smoke", "268435456 voxels", "budget"]);

    let png = hostile_inputs::png_claiming(16384, 16384);
    let hash = tessera_server::textures::content_hash(&png);
    assert_status(
        raw.sync(&s, hostile_inputs::textured(&hash, &png)).await,
        Code::ResourceExhausted,
        &["bomb.png", "16384×16384", "memory budget"],
    );

    // 200 M triangles in one mesh are over the per-mesh limit; 40 M, within it, are over the
    // budget (10 GB of BVH and arrays as declared).
    let declare = |tris| hostile_inputs::declared_mesh("/Evil/Huge", tris);
    assert_status(raw.sync(&s, declare(200_000_000)).await, Code::ResourceExhausted, &["/Evil/Huge", "200000000 triangles", "limit"]);
    assert_status(raw.sync(&s, declare(40_000_000)).await, Code::ResourceExhausted, &["/Evil/Huge", "40000000 triangles", "memory budget"]);
    // 4 M triangles fit as declared (the sync then fails for want of their arrays); deforming
    // over 64 samples, their BLAS would hold each triangle 64 times more (13 GB): over it.
    let deforming = |samples: u32| {
        let m = pb::MeshPrim {
            points_len: 9 * (1 + samples as u64),
            triangle_indices_len: 12_000_000,
            point_samples: samples,
            visible: true,
            ..Default::default()
        };
        vec![tessera::sync::delta("/Evil/Blob", pb::PrimKind::Mesh, pb::prim_delta::Payload::Mesh(m))]
    };
    assert_status(raw.sync(&s, deforming(0)).await, Code::InvalidArgument, &["/Evil/Blob", "received 0 of"]);
    assert_status(raw.sync(&s, deforming(64)).await, Code::ResourceExhausted, &["/Evil/Blob", "4000000 triangles", "memory budget"]);

    // Nothing stayed reserved: the session still holds just its Cornell box.
    let st = raw.stats(&s).await.unwrap();
    assert_eq!(st.session_memory_used, st.scene_bytes, "{st:?}");
    assert!(st.scene_bytes > 0 && st.scene_bytes < 1 << 20, "{st:?}");
    raw.render(&s, tiny(16, 1)).await.expect("the session itself still renders");
    bystander_renders(&server).await;
}

/// Within the budget, a decodable-sized claim still fails as a decode error (the data is not
/// there), and a failed Sync leaves nothing in the shared texture cache.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn failed_syncs_leave_the_texture_cache_as_it_was() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    // A valid 2x2 PNG in a sync that then fails on a bad mesh.
    let mut png = Vec::new();
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 10, 10]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let hash = tessera_server::textures::content_hash(&png);
    let mut items = hostile_inputs::textured(&hash, &png);
    items.extend(mesh("/Evil/OutOfRange", TRIANGLE.to_vec(), vec![0, 1, 7]));
    assert_status(raw.sync(&s, items).await, Code::InvalidArgument, &["/Evil/OutOfRange"]);
    let missing =
        raw.client.missing_textures(pb::MissingTexturesRequest { content_hashes: vec![hash.clone()] }).await.unwrap().into_inner();
    assert_eq!(missing.content_hashes, vec![hash], "the failed sync's texture must not be cached");
    let png = hostile_inputs::png_claiming(64, 64);
    let hash = tessera_server::textures::content_hash(&png);
    assert_status(raw.sync(&s, hostile_inputs::textured(&hash, &png)).await, Code::InvalidArgument, &["bomb.png"]);
    bystander_renders(&server).await;
}

// ------------------------------------------------------------------ sessions and tenants

const ALICE: &str = "alice-0123456789abcdef0123456789";
const BOB: &str = "bob-fedcba9876543210fedcba987654";

fn two_tenants() -> ServerConfig {
    let auth = Auth::from_file_contents(&format!("alice {ALICE}\nbob {BOB}\n")).unwrap();
    ServerConfig { auth, ..ServerConfig::default() }
}

/// Ids were s1, s2, ...: any client could drive any other's session. Now they are 128 random
/// bits, a token names a tenant, and another tenant's session does not exist for it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sessions_belong_to_their_tenant() {
    let server = EmbeddedServer::start_with(two_tenants()).await.unwrap();
    let mut alice = Raw::as_tenant(&server, ALICE).await;
    let mut bob = Raw::as_tenant(&server, BOB).await;
    let a = alice.session().await.unwrap();
    let a2 = alice.session().await.unwrap();
    assert!(a.len() == 34 && a.starts_with("s-") && a != a2, "{a} {a2}");
    alice.sync(&a, tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();

    // Everything Bob tries on Alice's session reads as absent.
    let absent = |r: Result<_, Status>| assert_status(r.map(|_: ()| ()), Code::NotFound, &["does not exist"]);
    absent(bob.sync(&a, camera_and_light()).await.map(|_| ()));
    absent(bob.render(&a, tiny(8, 1)).await.map(|_| ()));
    absent(bob.cancel(&a).await.map(|_| ()));
    absent(bob.stats(&a).await.map(|_| ()));
    absent(bob.close(&a).await);
    // Without a token, or with a wrong one, nothing at all.
    let mut anonymous = Raw::connect(&server).await;
    assert_status(anonymous.session().await, Code::Unauthenticated, &["token"]);
    let mut forger = Raw::as_tenant(&server, "alice-0123456789abcdef0123456780").await;
    assert_status(forger.render(&a, tiny(8, 1)).await, Code::Unauthenticated, &["not known"]);

    // Alice's own session is untouched and renders.
    let f = alice.render(&a, tiny(16, 2)).await.unwrap();
    assert_eq!(f.spp, 2);
    alice.close(&a).await.unwrap();
}

/// 64 sessions left open locked every new client out until a restart. Idle sessions are now
/// reaped, and one tenant cannot take every slot.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_sessions_are_reaped_and_tenants_have_their_own_limit() {
    let config = ServerConfig {
        session_idle_timeout: Duration::from_millis(300),
        limits: tessera_server::limits::Limits { max_sessions: 6, max_sessions_per_tenant: 3, ..Default::default() },
        ..two_tenants()
    };
    let server = EmbeddedServer::start_with(config).await.unwrap();
    let mut alice = Raw::as_tenant(&server, ALICE).await;
    let mut bob = Raw::as_tenant(&server, BOB).await;
    let mut held = Vec::new();
    for _ in 0..3 {
        held.push(alice.session().await.unwrap());
    }
    assert_status(alice.session().await, Code::ResourceExhausted, &["tenant 'alice'", "3 sessions"]);
    let b = bob.session().await.expect("Bob still gets a session");
    // Alice's clients leave without closing; Bob keeps using his.
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut reaped = false;
    while Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(100)).await;
        bob.stats(&b).await.expect("a used session is not idle");
        // Asking about Alice's sessions would use them; a new one is refused until they go.
        if alice.session().await.is_ok() {
            reaped = true;
            break;
        }
    }
    assert!(reaped, "idle sessions were never reaped");
    // They go one reaper pass after each reaches the timeout: give the last one three passes.
    for _ in 0..6 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        bob.stats(&b).await.expect("a used session is not idle");
    }
    for s in &held {
        assert_status(alice.stats(s).await, Code::NotFound, &["does not exist"]);
    }
    bob.stats(&b).await.expect("Bob's session survived");
}

/// Two concurrent Syncs on one session both returned OK and one update was lost. The second
/// now gets ABORTED while the first is open, and succeeds after it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_concurrent_sync_is_aborted_not_lost() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    // The first Sync: one message sent, the stream held open.
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    tx.send(pb::SyncRequest { session_id: s.clone(), item: Some(camera_and_light().remove(0)) }).await.unwrap();
    let mut first_client = raw.client.clone();
    let first = tokio::spawn(async move { first_client.sync(tokio_stream::wrappers::ReceiverStream::new(rx)).await });
    // Wait until the server holds the first one (bounded): probing with Syncs before then
    // could let a probe take the slot and abort the first instead.
    let mut held = false;
    for _ in 0..1000 {
        if raw.stats(&s).await.unwrap().syncing {
            held = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(held, "the first Sync reached the server within 10 s");
    let aborted = raw.sync(&s, vec![camera_and_light().remove(1)]).await.err();
    let e = aborted.expect("a concurrent Sync is refused while the first is open");
    assert_eq!(e.code(), Code::Aborted, "{e:?}");
    assert!(e.message().contains("one Sync at a time"), "{e:?}");
    drop(tx);
    let v1 = first.await.unwrap().expect("the first Sync commits").into_inner().scene_version;
    let v2 = raw.sync(&s, vec![camera_and_light().remove(1)]).await.expect("then the second commits").scene_version;
    assert!(v2 > v1);
}

// ------------------------------------------------------------------ cancellation and streams

/// One tile holding the whole 64×64 image and a pass of thousands of samples per pixel: the
/// expensive tile that kept the CPU busy for 240 s after the client left. Cancel must stop it
/// inside the tile: the render's path count stays far below the tile's pass.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancel_reaches_into_an_expensive_tile() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    raw.sync(&s, tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();
    let settings = pb::RenderSettings { width: 64, height: 64, tile_size: 64, spp: 1 << 16, max_depth: 8, ..Default::default() };
    let mut stream = raw.render_stream(&s, settings).await.unwrap();
    // After the pass of 64 spp ends, the next (128 spp, 0.5 M paths) is under way.
    let mut done_spp = 0;
    while let Some(e) = stream.message().await.unwrap() {
        if let Some(pb::render_event::Event::Progress(p)) = e.event {
            done_spp = p.spp;
            if p.spp >= 64 {
                break;
            }
        }
    }
    assert!(raw.cancel(&s).await.unwrap(), "the render was running");
    let finished = loop {
        match stream.message().await.unwrap().and_then(|e| e.event) {
            Some(pb::render_event::Event::Finished(f)) => break f,
            Some(_) => continue,
            None => panic!("no Finished"),
        }
    };
    assert!(finished.cancelled);
    // Paths of the completed passes plus at most part of the next; the passes after it (256,
    // 512, ... spp) never start. Polling every 64 samples leaves the tile within ~a pixel's work.
    let pixels = 64 * 64;
    let next_pass = u64::from(done_spp) * pixels;
    assert!(finished.paths < u64::from(done_spp) * pixels + next_pass, "{} paths after {done_spp} spp", finished.paths);
    bystander_renders(&server).await;
}

/// A client that disconnects mid-render frees the render thread (the session stops
/// rendering) within a bounded wait, whatever the tile costs.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_leaves_frees_its_render() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    raw.sync(&s, tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();
    let settings = pb::RenderSettings { width: 64, height: 64, tile_size: 64, spp: 1 << 16, ..Default::default() };
    let mut stream = raw.render_stream(&s, settings).await.unwrap();
    stream.message().await.unwrap();
    drop(stream);
    wait_until_idle(&mut raw, &s).await;
    bystander_renders(&server).await;
}

async fn wait_until_idle(raw: &mut Raw, s: &str) {
    for _ in 0..200 {
        if !raw.stats(s).await.unwrap().rendering {
            return;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    panic!("the render is still running 5 s later");
}

/// A client that opens a Render and never reads it pinned the render thread and the scene,
/// even after Cancel. With a stall timeout it is dropped; Cancel frees it at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_render_nobody_reads_is_dropped() {
    let config = ServerConfig { stall_timeout: Duration::from_millis(500), ..ServerConfig::default() };
    let server = EmbeddedServer::start_with(config).await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    raw.sync(&s, tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();
    // 1024 tiles of f32 per pass: more than the event buffer and the HTTP/2 windows hold.
    let settings = pb::RenderSettings { width: 1024, height: 1024, tile_size: 32, spp: 64, max_depth: 1, ..Default::default() };
    let _unread = raw.render_stream(&s, settings.clone()).await.unwrap();
    wait_until_idle(&mut raw, &s).await;
    // And with Cancel, without waiting for the stall.
    let _unread_too = raw.render_stream(&s, settings).await.unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    raw.cancel(&s).await.unwrap();
    wait_until_idle(&mut raw, &s).await;
    raw.close(&s).await.unwrap();
    bystander_renders(&server).await;
}

/// `threads = 1024` built a 1024-thread pool per render. Thread counts are capped at the
/// machine's cores and pools are shared; renders still complete and agree.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn absurd_thread_counts_share_a_pool_of_the_machine_size() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    raw.sync(&s, tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();
    let threads_now = || {
        let status = std::fs::read_to_string("/proc/self/status").unwrap();
        status.lines().find_map(|l| l.strip_prefix("Threads:")).unwrap().trim().parse::<usize>().unwrap()
    };
    for _ in 0..4 {
        let f = raw.render(&s, pb::RenderSettings { threads: 1024, ..tiny(16, 2) }).await.unwrap();
        assert_eq!(f.spp, 2);
    }
    // Other tests run in this process too, so only a bound: far from 4 x 1024.
    assert!(threads_now() < 512, "{} threads", threads_now());
}

// ------------------------------------------------------------------ input hygiene

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_paths_parameters_and_chunks_are_refused_by_name() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    // A NUL in a prim path, and a 1 MB path.
    assert_status(
        raw.sync(&s, mesh("/Evil/Nul\0Byte", TRIANGLE.to_vec(), vec![0, 1, 2])).await,
        Code::InvalidArgument,
        &["/Evil/Nul\\0Byte", "control character"],
    );
    let long = format!("/{}", "a".repeat(1 << 20));
    assert_status(
        raw.sync(&s, mesh(&long, TRIANGLE.to_vec(), vec![0, 1, 2])).await,
        Code::InvalidArgument,
        &["1048577 bytes", "limit of 4096"],
    );
    // NaN and 1e38 material parameters, naming the material, node and input.
    for (value, shown) in [(f32::NAN, "NaN"), (1e38, "1e38")] {
        let net = pb::MaterialNetwork {
            nodes: vec![node("/M/S", "UsdPreviewSurface", &[("roughness", pb::param_value::Value::FloatValue(value))])],
            connections: vec![],
            surface_node: "/M/S".into(),
        };
        assert_status(
            raw.sync(&s, vec![material("/Evil/Param", net)]).await,
            Code::InvalidArgument,
            &["/Evil/Param", "/M/S", "'roughness'", shown],
        );
    }
    // A negative light radius and a NaN colour, each by its own name.
    let light = |radius: f32, color: pb::Float3| {
        let l =
            pb::LightPrim { light_type: pb::LightType::Sphere as i32, intensity: 1.0, radius, color: Some(color), ..Default::default() };
        vec![tessera::sync::delta("/Evil/Light", pb::PrimKind::Light, pb::prim_delta::Payload::Light(l))]
    };
    let white = pb::Float3 { x: 1.0, y: 1.0, z: 1.0 };
    assert_status(raw.sync(&s, light(-1.0, white)).await, Code::InvalidArgument, &["/Evil/Light", "radius", "negative"]);
    let nan = pb::Float3 { x: f32::NAN, y: 1.0, z: 1.0 };
    assert_status(raw.sync(&s, light(1.0, nan)).await, Code::InvalidArgument, &["/Evil/Light", "color", "finite"]);
    // A mesh light's inputs: a NaN intensity, a negative colour, a sync mode no one defined, an
    // oversized link name, and a mesh it is part of named by an oversized or a relative path,
    // each by its own name.
    let lit_mesh = |light: pb::MeshLight| {
        let mut items = mesh("/Evil/Glow", TRIANGLE.to_vec(), vec![0, 1, 2]);
        if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Mesh(m)), .. }) = &mut items[0] {
            m.light = Some(light);
        }
        items
    };
    let glow = pb::MeshLight { intensity: 1.0, ..Default::default() };
    let long = "c".repeat(tessera_wire::convert::MAX_LINK_COLLECTION_BYTES + 1);
    for (bad, field) in [
        (pb::MeshLight { intensity: f32::NAN, ..glow.clone() }, "light.intensity"),
        (pb::MeshLight { color: Some(pb::Float3 { x: -1.0, y: 1.0, z: 1.0 }), ..glow.clone() }, "light.color"),
        (pb::MeshLight { material_sync: 99, ..glow.clone() }, "light.material_sync"),
        (pb::MeshLight { light_link: long.clone(), ..glow.clone() }, "light.light_link"),
        (pb::MeshLight { part_of: format!("/{long}"), ..glow.clone() }, "light.part_of"),
        (pb::MeshLight { part_of: "Sign".into(), ..glow.clone() }, "light.part_of"),
    ] {
        assert_status(raw.sync(&s, lit_mesh(bad)).await, Code::InvalidArgument, &["/Evil/Glow", field]);
    }
    // UDIM sets: a tile outside 1001-1100, a tile twice (a set of more than 100 tiles must
    // repeat one), and a tile whose file was never uploaded.
    let h = "sha256:".to_string() + &"a".repeat(64);
    let past: Vec<(u32, &str)> = (1001..=1101).map(|t| (t, h.as_str())).collect();
    let twice: Vec<(u32, &str)> = (0..10_000).map(|_| (1001, h.as_str())).collect();
    for (tiles, words) in [
        (vec![(1001, h.as_str()), (5000, h.as_str())], &["/Evil/Tiles", "'file'", "UDIM tile 5000"][..]),
        (past, &["/Evil/Tiles", "UDIM tile 1101"]),
        (twice, &["/Evil/Tiles", "UDIM tile 1001 follows tile 1001"]),
    ] {
        assert_status(raw.sync(&s, hostile_inputs::udim_material(&tiles)).await, Code::InvalidArgument, words);
    }
    assert_status(
        raw.sync(&s, hostile_inputs::udim_material(&[(1001, h.as_str())])).await,
        Code::FailedPrecondition,
        &["/Evil/Tiles", "tiles.<UDIM>.png", "not uploaded"],
    );
    // A chunk over the advertised element limit.
    let limit = tessera_server::limits::Limits::default().max_array_chunk_elements as usize;
    let prim = pb::MeshPrim { points_len: 3 * (limit as u64 + 3), triangle_indices_len: 3, visible: true, ..Default::default() };
    let items = vec![
        tessera::sync::delta("/Evil/BigChunk", pb::PrimKind::Mesh, pb::prim_delta::Payload::Mesh(prim)),
        Item::Chunk(pb::ArrayChunk {
            path: "/Evil/BigChunk".into(),
            field: pb::ArrayField::Points as i32,
            floats: vec![0.0; 3 * limit + 9],
            ..Default::default()
        }),
    ];
    assert_status(raw.sync(&s, items).await, Code::InvalidArgument, &["/Evil/BigChunk", "chunk", "over the limit"]);
    bystander_renders(&server).await;
}

/// 100 000 small meshes in one Sync stream: every message small, many of them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hundred_thousand_small_prims_sync_in_one_stream() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let n = 100_000;
    let mut items = Vec::with_capacity(3 * n);
    for k in 0..n {
        let dx = (k % 1000) as f32 * 1.5;
        let dy = (k / 1000) as f32 * 1.5;
        let pts = TRIANGLE.chunks(3).flat_map(|p| [p[0] + dx, p[1] + dy, p[2]]).collect();
        items.extend(mesh(&format!("/Many/M{k}"), pts, vec![0, 1, 2]));
    }
    let r = raw.sync(&s, items).await.expect("a large sync from a conforming client goes through");
    assert_eq!(r.prims_applied, n as u32);
    assert_eq!(raw.stats(&s).await.unwrap().triangles, n as u64);
}

/// `first_sample` is a client-controlled count: past the end, between passes, or with
/// adaptive sampling it is refused by name before anything renders; a valid slice that asks
/// for exact film sums gets FilmTile events only, covering the image once per pass.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slices_are_bounded_and_stream_exact_sums() {
    let (server, mut conn) = session_with(&load("cornell_box.usda")).await;
    let slice = |first, noise| tessera::remote::RenderOptions {
        first_sample: first,
        noise_threshold: noise,
        stream_film: true,
        ..small(8, 8, 128)
    };
    for (first, noise) in [(u32::MAX, None), (128, None), (3, None), (100, None), (64, Some(0.01))] {
        let e = conn.render(&slice(first, noise), |_| {}).await.unwrap_err();
        assert!(format!("{e:#}").contains("first_sample"), "names the field: {e:#}");
    }
    let mut film = tessera::film::ExactFilm::new(8, 8, 64);
    let mut tiles = 0;
    conn.render_into(&slice(64, None), Some(&mut film), |e| tiles += matches!(e, pb::render_event::Event::Tile(_)) as u32, |_| Ok(()))
        .await
        .unwrap();
    assert_eq!(tiles, 0, "no resolved tiles when sums are streamed");
    assert_eq!(film.range, 64..128);
    server.stop().await.unwrap();
}

/// Light-link collection names and counts are sizes the client controls: a light's link name
/// past 8 KiB or holding a control character, and a mesh or instancer in more than 1024
/// collections, are refused naming the prim and field; a mesh in 1024 collections, one of
/// them linked, syncs and renders.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn light_link_names_and_counts_past_the_limits_are_refused() {
    use tessera_wire::convert::{MAX_LINK_COLLECTION_BYTES, MAX_LINK_COLLECTIONS};
    let server = EmbeddedServer::start().await.unwrap();
    let mut raw = Raw::connect(&server).await;
    let s = raw.session().await.unwrap();
    let lamp = |light_link: String, shadow_link: String| {
        let l = pb::LightPrim { light_type: pb::LightType::Dome as i32, intensity: 1.0, light_link, shadow_link, ..Default::default() };
        tessera::sync::delta("/Evil/Lamp", pb::PrimKind::Light, pb::prim_delta::Payload::Light(l))
    };
    let long = "c".repeat(MAX_LINK_COLLECTION_BYTES + 1);
    assert_status(raw.sync(&s, vec![lamp(long.clone(), String::new())]).await, Code::InvalidArgument, &["/Evil/Lamp", "light_link"]);
    assert_status(raw.sync(&s, vec![lamp(String::new(), "a\0b".into())]).await, Code::InvalidArgument, &["/Evil/Lamp", "shadow_link"]);
    let in_collections = |n: usize| {
        let mut items = mesh("/Evil/Tri", TRIANGLE.to_vec(), vec![0, 1, 2]);
        if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Mesh(m)), .. }) = &mut items[0] {
            m.link_collections = (0..n).map(|i| format!("/L{i}.collection:lightLink")).collect();
        }
        items
    };
    assert_status(raw.sync(&s, in_collections(MAX_LINK_COLLECTIONS + 1)).await, Code::InvalidArgument, &["/Evil/Tri", "link_collections"]);
    let scatter = pb::InstancerPrim {
        prototype_path: "/Evil/Tri".into(),
        link_collections: vec![String::new(); MAX_LINK_COLLECTIONS + 1],
        ..Default::default()
    };
    let items = vec![tessera::sync::delta("/Evil/Scatter", pb::PrimKind::Instancer, pb::prim_delta::Payload::Instancer(scatter))];
    assert_status(raw.sync(&s, items).await, Code::InvalidArgument, &["/Evil/Scatter", "link_collections"]);
    let mut items = camera_and_light();
    if let Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Light(l)), .. }) = &mut items[1] {
        l.light_link = "/L1023.collection:lightLink".into();
    }
    items.extend(in_collections(MAX_LINK_COLLECTIONS));
    raw.sync(&s, items).await.expect("1024 collections sync");
    let f = raw.render(&s, tiny(8, 2)).await.expect("renders");
    assert_eq!(f.spp, 2);
    bystander_renders(&server).await;
}
