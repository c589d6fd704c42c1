//! The `tessera-server` binary as an operator runs it: it refuses to expose an unguarded
//! server, drains renders on SIGTERM within its grace period, and serves TLS with tokens.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tonic::transport::Channel;

fn server() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tessera-server"));
    c.env("RUST_LOG", "warn").stdin(Stdio::null());
    c
}

/// A loopback port nothing listens on now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Connects to the child's port, retrying while it starts (bounded).
async fn connect(url: &str) -> RenderClient<Channel> {
    for _ in 0..200 {
        if let Ok(ch) = Channel::from_shared(url.to_string()).unwrap().connect().await {
            return RenderClient::new(ch);
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    panic!("the server never listened on {url}");
}

/// Waits for the child to exit (bounded); its status code.
fn wait_exit(child: &mut Child, within: Duration) -> i32 {
    let deadline = Instant::now() + within;
    while Instant::now() < deadline {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code().unwrap_or(-1);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    panic!("the server did not exit within {within:?}");
}

#[test]
fn a_non_loopback_address_needs_tokens_and_tls() {
    let out = server().args(["--listen", "0.0.0.0:0"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("refusing to serve 0.0.0.0:0 without tokens and TLS") && err.contains("--insecure"), "{err}");
}

/// One triangle in front of a camera, under a dome.
fn scene(session: &str) -> Vec<pb::SyncRequest> {
    use pb::prim_delta::Payload;
    let delta = |path: &str, kind: pb::PrimKind, payload: Payload| pb::SyncRequest {
        session_id: session.into(),
        item: Some(pb::sync_request::Item::Prim(pb::PrimDelta {
            path: path.into(),
            kind: kind as i32,
            dirty: pb::DirtyBits::DirtyAll as u32,
            payload: Some(payload),
        })),
    };
    let chunk = |field: pb::ArrayField, floats: Vec<f32>, uints: Vec<u32>| pb::SyncRequest {
        session_id: session.into(),
        item: Some(pb::sync_request::Item::Chunk(pb::ArrayChunk {
            path: "/Tri".into(),
            field: field as i32,
            floats,
            uints,
            ..Default::default()
        })),
    };
    let camera = pb::CameraPrim {
        transform: Some(pb::Matrix4 { m: vec![1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0.3, 0.3, 3., 1.] }),
        focal_length: 50.0,
        horizontal_aperture: 20.0,
        vertical_aperture: 20.0,
        near_clip: 0.01,
        far_clip: 100.0,
        ..Default::default()
    };
    vec![
        delta(
            "/Tri",
            pb::PrimKind::Mesh,
            Payload::Mesh(pb::MeshPrim { points_len: 9, triangle_indices_len: 3, visible: true, ..Default::default() }),
        ),
        chunk(pb::ArrayField::Points, vec![0., 0., 0., 1., 0., 0., 0., 1., 0.], vec![]),
        chunk(pb::ArrayField::TriangleIndices, vec![], vec![0, 1, 2]),
        delta("/Cam", pb::PrimKind::Camera, Payload::Camera(camera)),
        delta(
            "/Dome",
            pb::PrimKind::Light,
            Payload::Light(pb::LightPrim { light_type: pb::LightType::Dome as i32, intensity: 1.0, ..Default::default() }),
        ),
    ]
}

/// SIGTERM during a long render: the render ends with `Finished { cancelled }`, new work is
/// refused, and the process exits well within its grace period.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_drains_running_renders_then_exits() {
    let port = free_port();
    let mut child = server().args(["--listen", &format!("127.0.0.1:{port}"), "--shutdown-grace", "5"]).spawn().unwrap();
    let mut c = connect(&format!("http://127.0.0.1:{port}")).await;
    let s = c.create_session(pb::CreateSessionRequest::default()).await.unwrap().into_inner().session_id;
    c.sync(tokio_stream::iter(scene(&s))).await.unwrap();
    let settings = pb::RenderSettings { width: 64, height: 64, tile_size: 64, spp: 1 << 20, ..Default::default() };
    let mut stream = c.render(pb::RenderRequest { session_id: s.clone(), settings: Some(settings) }).await.unwrap().into_inner();
    stream.message().await.unwrap().expect("Started");
    let signalled = Instant::now();
    assert!(Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    let mut finished = None;
    while let Ok(Some(e)) = stream.message().await {
        if let Some(pb::render_event::Event::Finished(f)) = e.event {
            finished = Some(f);
            break;
        }
    }
    let f = finished.expect("the running render ends with Finished");
    assert!(f.cancelled, "{f:?}");
    let code = wait_exit(&mut child, Duration::from_secs(5));
    assert_eq!(code, 0);
    assert!(signalled.elapsed() < Duration::from_secs(5), "{:?}", signalled.elapsed());
}

/// TLS with a certificate signed by a throw-away authority (made by `openssl`), and a token:
/// a client trusting the authority and holding the token renders; a plain-text client
/// cannot talk to it at all.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_and_tokens_guard_a_public_address() {
    let dir = std::env::temp_dir().join(format!("tessera-tls-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sh = |args: &[&str]| {
        let out = Command::new("openssl").args(args).current_dir(&dir).output().expect("openssl is installed (.ci/run)");
        assert!(out.status.success(), "openssl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes"];
    sh(&[&["req", "-x509"][..], &ec, &["-keyout", "ca.key", "-out", "ca.pem", "-subj", "/CN=Tessera test CA", "-days", "1"]].concat());
    sh(&[&["req"][..], &ec, &["-keyout", "server.key", "-out", "server.csr", "-subj", "/CN=localhost"]].concat());
    std::fs::write(
        dir.join("ext.cnf"),
        "subjectAltName=IP:127.0.0.1,DNS:localhost\nbasicConstraints=CA:FALSE\nextendedKeyUsage=serverAuth\n",
    )
    .unwrap();
    sh(&[
        "x509",
        "-req",
        "-in",
        "server.csr",
        "-CA",
        "ca.pem",
        "-CAkey",
        "ca.key",
        "-CAcreateserial",
        "-out",
        "server.pem",
        "-days",
        "1",
        "-extfile",
        "ext.cnf",
    ]);
    let token = "farm 00112233445566778899aabbccddeeff";
    std::fs::write(dir.join("tokens"), format!("{token}\n")).unwrap();

    let port = free_port();
    let path = |f: &str| dir.join(f).to_string_lossy().into_owned();
    let mut child = server()
        .args([
            "--listen",
            &format!("127.0.0.1:{port}"),
            "--token-file",
            &path("tokens"),
            "--tls-cert",
            &path("server.pem"),
            "--tls-key",
            &path("server.key"),
        ])
        .spawn()
        .unwrap();
    let ca = tonic::transport::Certificate::from_pem(std::fs::read(dir.join("ca.pem")).unwrap());
    let tls = tonic::transport::ClientTlsConfig::new().ca_certificate(ca).domain_name("localhost");
    let mut channel = None;
    for _ in 0..200 {
        let endpoint = Channel::from_shared(format!("https://127.0.0.1:{port}")).unwrap().tls_config(tls.clone()).unwrap();
        if let Ok(ch) = endpoint.connect().await {
            channel = Some(ch);
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    let bearer: tonic::metadata::MetadataValue<_> = "Bearer 00112233445566778899aabbccddeeff".parse().unwrap();
    let mut c = RenderClient::with_interceptor(channel.expect("TLS connects"), move |mut r: tonic::Request<()>| {
        r.metadata_mut().insert("authorization", bearer.clone());
        Ok(r)
    });
    let s = c.create_session(pb::CreateSessionRequest::default()).await.unwrap().into_inner().session_id;
    c.sync(tokio_stream::iter(scene(&s))).await.unwrap();
    let settings = pb::RenderSettings { width: 8, height: 8, spp: 1, ..Default::default() };
    let mut stream = c.render(pb::RenderRequest { session_id: s, settings: Some(settings) }).await.unwrap().into_inner();
    let mut done = false;
    while let Some(e) = stream.message().await.unwrap() {
        done |= matches!(e.event, Some(pb::render_event::Event::Finished(_)));
    }
    assert!(done);
    // Plain text gets nowhere.
    let plain = Channel::from_shared(format!("http://127.0.0.1:{port}")).unwrap().connect().await;
    if let Ok(ch) = plain {
        assert!(RenderClient::new(ch).get_capabilities(pb::GetCapabilitiesRequest {}).await.is_err());
    }
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
}
