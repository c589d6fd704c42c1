//! Helpers for the end-to-end tests: fixtures, an embedded server per test, image statistics.

use std::path::{Path, PathBuf};

use tessera::output::Image;
use tessera::remote::{Connection, RenderOptions, RenderReport};
use tessera::usd::Translation;
use tessera_server::EmbeddedServer;

pub mod lit_plane;

/// Path of a file under `fixtures/`.
pub fn fixture(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures").join(rel)
}

/// Every fixture a reader should accept (the `bad/` ones are meant to fail).
pub fn all_fixtures() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("fixtures directory") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                if path.file_name().is_some_and(|n| n != "bad") {
                    walk(&path, out);
                }
            } else if path.extension().is_some_and(|e| e == "usda" || e == "usdc" || e == "usdz") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&fixture(""), &mut out);
    out.sort();
    out
}

/// What usd-core reads, from `fixtures/inspect_usd.py`.
pub fn usd_core_reads(scene: &Path, frame: Option<f64>) -> serde_json::Value {
    usd_core_reads_all(&[(scene.to_path_buf(), frame)]).remove(0)
}

/// What usd-core reads from each of `scenes` at its frame, in one Python process (starting
/// Python with usd-core takes about 0.3 s, so tests that compare many scenes read them together).
pub fn usd_core_reads_all(scenes: &[(PathBuf, Option<f64>)]) -> Vec<serde_json::Value> {
    use std::io::Write;
    let list: Vec<(String, Option<f64>)> = scenes.iter().map(|(p, f)| (p.display().to_string(), *f)).collect();
    let mut child = std::process::Command::new("python3")
        .arg(fixture("inspect_usd.py"))
        .arg("--batch")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs (the tests use Pixar's usd-core as an independent reader)");
    let mut stdin = child.stdin.take().expect("piped stdin");
    stdin.write_all(&serde_json::to_vec(&list).expect("scene list as JSON")).expect("scene list written");
    drop(stdin);
    let out = child.wait_with_output().expect("inspect_usd.py finishes");
    assert!(
        out.status.success(),
        "inspect_usd.py --batch failed (is usd-core installed? pip install -r fixtures/requirements.txt):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let all: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).expect("inspect_usd.py prints JSON");
    assert_eq!(all.len(), scenes.len(), "one result per scene");
    all
}

/// Reads a fixture with the client's USD reader.
pub fn load(rel: &str) -> Translation {
    tessera::usd::load(&fixture(rel)).unwrap_or_else(|e| panic!("{rel}: {e:#}"))
}

/// Reads a `.usda` layer given as text (written to a temporary folder of its own, so
/// relative asset paths in it resolve there and find nothing).
pub fn load_text(name: &str, usda: &str) -> Translation {
    load_text_at(name, usda, None)
}

/// [`load_text`] at time code `frame` (None: the layer's start).
pub fn load_text_at(name: &str, usda: &str, frame: Option<f64>) -> Translation {
    let dir = std::env::temp_dir().join(format!("tessera-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let file = dir.join(format!("{name}.usda"));
    std::fs::write(&file, usda).expect("layer written");
    let t = tessera::usd::load_at(&file, frame).unwrap_or_else(|e| panic!("{name}: {e:#}"));
    std::fs::remove_dir_all(&dir).ok();
    t
}

/// A server on loopback and a session on it with `translation` synced.
pub async fn session_with(translation: &Translation) -> (EmbeddedServer, Connection) {
    let server = EmbeddedServer::start().await.expect("embedded server starts");
    let mut conn = Connection::connect(&server.url(), "e2e").await.expect("connects");
    conn.sync_scene(translation).await.expect("scene syncs");
    (server, conn)
}

/// Renders a fixture over loopback.
pub async fn render_fixture(rel: &str, opts: &RenderOptions) -> RenderReport {
    let (server, mut conn) = session_with(&load(rel)).await;
    let report = conn.render(opts, |_| {}).await.expect("renders");
    server.stop().await.expect("server stops");
    report
}

/// Options for a small, quick render.
pub fn small(width: u32, height: u32, spp: u32) -> RenderOptions {
    RenderOptions { width, height, spp, progressive_f16: false, ..Default::default() }
}

/// Asserts every value of every layer is finite.
pub fn assert_all_finite(image: &Image) {
    for (name, (_, data)) in &image.layers {
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            panic!("AOV {name}: value {i} is {}", data[i]);
        }
    }
}

/// Mean of channel `c` of `aov` over the pixels where `keep` holds.
pub fn mean_where(image: &Image, aov: &str, c: usize, keep: impl Fn(u32, u32) -> bool) -> (f64, usize) {
    let mut sum = 0.0;
    let mut n = 0;
    for y in 0..image.height {
        for x in 0..image.width {
            if keep(x, y) {
                sum += image.pixel(aov, x, y)[c] as f64;
                n += 1;
            }
        }
    }
    (sum / n.max(1) as f64, n)
}

/// Mean of each beauty channel over the pixels where the camera hit geometry (alpha 1), and
/// how many there are.
pub fn covered_rgb(report: &RenderReport) -> ([f64; 3], usize) {
    let img = &report.image;
    let covered = |x, y| img.pixel("beauty", x, y)[3] == 1.0;
    let means = [0, 1, 2].map(|c| mean_where(img, "beauty", c, covered));
    (means.map(|(m, _)| m), means[0].1)
}

/// Renders a furnace fixture (32x32, 64 spp, max depth 64) and returns the mean red value over
/// the pixels where the camera sees geometry, after checking every AOV is finite.
pub async fn furnace_sphere_mean(fixture_name: &str, energy_compensation: bool) -> f64 {
    let opts = RenderOptions { max_depth: 64, energy_compensation, ..small(32, 32, 64) };
    let report = render_fixture(fixture_name, &opts).await;
    assert_all_finite(&report.image);
    let ([mean, ..], n) = covered_rgb(&report);
    assert!(n > 100, "{fixture_name}: the sphere covers {n} pixels");
    mean
}

/// Inputs a hostile client sends, shared by the hostile-client and memory tests.
pub mod hostile_inputs {
    use tessera_proto::v1 as pb;

    type Item = pb::sync_request::Item;

    /// A PNG whose header claims `width`×`height` RGBA16 and whose data is a few bytes: what the
    /// 2 MB "bomb" looks like to a decoder before it allocates.
    pub fn png_claiming(width: u32, height: u32) -> Vec<u8> {
        fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
            out.extend((data.len() as u32).to_be_bytes());
            let start = out.len();
            out.extend(kind);
            out.extend(data);
            let crc = crc32(&out[start..]);
            out.extend(crc.to_be_bytes());
        }
        let mut ihdr = Vec::new();
        ihdr.extend(width.to_be_bytes());
        ihdr.extend(height.to_be_bytes());
        ihdr.extend([16, 6, 0, 0, 0]); // 16 bits, RGBA, deflate, adaptive filter, no interlace
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        chunk(&mut png, b"IHDR", &ihdr);
        chunk(&mut png, b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
        chunk(&mut png, b"IEND", &[]);
        png
    }

    /// CRC-32 (ISO-HDLC), as PNG chunks carry it.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
            }
        }
        !crc
    }

    fn node(path: &str, id: &str, params: Vec<(&str, pb::param_value::Value)>) -> pb::MaterialNode {
        pb::MaterialNode {
            path: path.into(),
            node_type_id: id.into(),
            parameters: params.into_iter().map(|(k, v)| (k.to_string(), pb::ParamValue { value: Some(v) })).collect(),
        }
    }

    /// A material using the texture with `hash`, and the texture's upload.
    pub fn textured(hash: &str, bytes: &[u8]) -> Vec<Item> {
        let tex = pb::TexturePrim { source: "bomb.png".into(), bytes_len: bytes.len() as u64 };
        let texture = pb::param_value::Value::TextureValue(pb::TextureRef { content_hash: hash.into(), source: "bomb.png".into() });
        let net = pb::MaterialNetwork {
            nodes: vec![node("/M/S", "UsdPreviewSurface", vec![]), node("/M/Tex", "UsdUVTexture", vec![("file", texture)])],
            connections: vec![pb::MaterialConnection {
                downstream_node: "/M/S".into(),
                downstream_input: "diffuseColor".into(),
                upstream_node: "/M/Tex".into(),
                upstream_output: "rgb".into(),
            }],
            surface_node: "/M/S".into(),
        };
        vec![
            tessera::sync::delta(hash, pb::PrimKind::Texture, pb::prim_delta::Payload::Texture(tex)),
            Item::Chunk(pb::ArrayChunk {
                path: hash.into(),
                field: pb::ArrayField::TextureBytes as i32,
                data: bytes.to_vec(),
                ..Default::default()
            }),
            tessera::sync::delta("/Evil/Bomb", pb::PrimKind::Material, pb::prim_delta::Payload::Material(net)),
        ]
    }

    /// A material whose texture node reads the UDIM set `tiles` (tile number, content hash).
    pub fn udim_material(tiles: &[(u32, &str)]) -> Vec<Item> {
        let tiles = tiles.iter().map(|&(tile, hash)| pb::UdimTile { tile, content_hash: hash.into() }).collect();
        let udim = pb::param_value::Value::UdimValue(pb::UdimSet { tiles, source: "tiles.<UDIM>.png".into() });
        let net = pb::MaterialNetwork {
            nodes: vec![node("/M/S", "UsdPreviewSurface", vec![]), node("/M/Tex", "UsdUVTexture", vec![("file", udim)])],
            connections: vec![],
            surface_node: "/M/S".into(),
        };
        vec![tessera::sync::delta("/Evil/Tiles", pb::PrimKind::Material, pb::prim_delta::Payload::Material(net))]
    }

    /// A mesh delta declaring `triangles` triangles (and half as many points), with no data.
    pub fn declared_mesh(path: &str, triangles: u64) -> Vec<Item> {
        let m = pb::MeshPrim { points_len: 3 * triangles / 2, triangle_indices_len: 3 * triangles, visible: true, ..Default::default() };
        vec![tessera::sync::delta(path, pb::PrimKind::Mesh, pb::prim_delta::Payload::Mesh(m))]
    }
}

/// Scenes built in code for the benches.
mod production {
    use std::collections::BTreeMap;
    use std::sync::Arc;

    use glam::{Affine3A, Vec3};
    use render_core::camera::CameraDesc;
    use render_core::geometry::Mesh;
    use render_core::light::{LightDesc, LightKind};
    use render_core::material::{MaterialNetwork, MaterialNode, ParamValue};
    use render_core::scene::{InstancerDesc, MeshDesc, SceneDesc};

    fn preview(path: &str, colour: Vec3, roughness: f32) -> MaterialNetwork {
        let node = MaterialNode {
            path: format!("{path}/Surface"),
            node_type_id: "UsdPreviewSurface".into(),
            parameters: BTreeMap::from([
                ("diffuseColor".to_string(), ParamValue::Float3(colour)),
                ("roughness".to_string(), ParamValue::Float(roughness)),
            ]),
        };
        MaterialNetwork { surface_node: node.path.clone(), nodes: vec![node], connections: Vec::new() }
    }

    fn light(kind: LightKind, at: Vec3, intensity: f32) -> LightDesc {
        LightDesc::new(kind, Affine3A::from_translation(at), intensity)
    }

    /// A production-sized scene for the latency benches: a 1M-triangle mesh, 400 instances of a
    /// 5 000-triangle rock, two lights, two materials and a camera.
    pub fn production_scene() -> SceneDesc {
        let mut desc = SceneDesc::default();
        let mesh = |m: Mesh, xf: Affine3A, material: &str, visible: bool| MeshDesc {
            mesh: Arc::new(m),
            transform: xf,
            motion: Vec::new(),
            material: material.into(),
            visible,
            link_collections: Vec::new(),
            light: None,
        };
        desc.meshes.insert("/World/Hero".into(), mesh(Mesh::uv_sphere(500, 1000), Affine3A::from_scale(Vec3::splat(2.0)), "/M/Hero", true));
        desc.meshes.insert("/World/Rock".into(), mesh(Mesh::uv_sphere(50, 50), Affine3A::IDENTITY, "/M/Rock", false));
        let transforms = (0..400)
            .map(|i| {
                let (x, z) = ((i % 20) as f32 - 9.5, (i / 20) as f32 - 9.5);
                Affine3A::from_scale_rotation_translation(Vec3::splat(0.2), glam::Quat::from_rotation_y(i as f32), Vec3::new(x, -2.0, z))
            })
            .collect();
        desc.instancers.insert(
            "/World/Scatter".into(),
            InstancerDesc { prototype: "/World/Rock".into(), transforms, motion: Vec::new(), link_collections: Vec::new() },
        );
        desc.materials.insert("/M/Hero".into(), preview("/M/Hero", Vec3::new(0.8, 0.2, 0.1), 0.3));
        desc.materials.insert("/M/Rock".into(), preview("/M/Rock", Vec3::splat(0.4), 0.8));
        desc.lights.insert("/Lights/Key".into(), light(LightKind::Sphere { radius: 0.5 }, Vec3::new(3.0, 5.0, 3.0), 50.0));
        desc.lights.insert("/Lights/Fill".into(), light(LightKind::Rect { width: 4.0, height: 4.0 }, Vec3::new(-4.0, 4.0, 0.0), 5.0));
        let camera = CameraDesc { transform: Affine3A::from_translation(Vec3::new(0.0, 1.0, 12.0)), ..Default::default() };
        desc.cameras.insert("/Camera".into(), camera);
        desc
    }
}
pub use production::production_scene;

/// This process's peak resident memory (`VmHWM` in `/proc/self/status`), in bytes.
pub fn peak_rss() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("Linux /proc");
    let kib: u64 = status.lines().find_map(|l| l.strip_prefix("VmHWM:")).and_then(|v| v.split_whitespace().next()?.parse().ok()).unwrap();
    kib * 1024
}

/// An orthographic `/Camera` looking down −Z from z = 10 at `aperture / 10` units square
/// around the origin, with `extra` attributes spliced in (a shutter), and `/Sky`, a white dome
/// of radiance 1.
pub fn ortho_camera_and_dome_usda(aperture: f32, extra: &str) -> String {
    format!(
        r#"def Camera "Camera"
{{
    token projection = "orthographic"
    float horizontalAperture = {aperture}
    float verticalAperture = {aperture}
    {extra}
    double3 xformOp:translate = (0, 0, 10)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def DomeLight "Sky"
{{
    float inputs:intensity = 1
}}
"#
    )
}

/// A USD camera 4 units up +Z looking down −Z with a square aperture, as stage text: the
/// framing of the closed-form silhouette tests.
pub fn camera_usda(focal_length: f32, aperture: f32) -> String {
    format!(
        r#"def Camera "Camera" {{
    float focalLength = {focal_length}
    float horizontalAperture = {aperture}
    float verticalAperture = {aperture}
    double3 xformOp:translate = (0, 0, 4)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"#
    )
}
