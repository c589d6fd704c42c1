//! Bad input gets a clear error naming the prim and field, and the server keeps serving.

use tessera::remote::Connection;
use tessera_proto::v1 as pb;
use tessera_server::EmbeddedServer;
use tessera_tests::*;

#[test]
fn malformed_usd_is_an_error_naming_the_file() {
    let e = tessera::usd::load(&fixture("bad/malformed.usda")).unwrap_err().to_string();
    assert!(e.contains("malformed.usda"), "{e}");
    let e = tessera::usd::load(&fixture("bad/does_not_exist.usda")).unwrap_err().to_string();
    assert!(e.contains("no such file"), "{e}");
}

/// A bad mesh is reported by prim and attribute and skipped; the stage still loads.
#[test]
fn bad_meshes_in_usd_name_the_prim_and_attribute() {
    let skipped_with = |file: &str, needles: &[&str]| {
        let t = tessera::usd::load(&fixture(file)).unwrap_or_else(|e| panic!("{file}: {e:#}"));
        assert!(t.meshes.iter().all(|(p, _)| p != "/World/Broken"), "{file}: the bad mesh is left out");
        assert_eq!(t.skipped, ["/World/Broken"], "{file}");
        let w = t.warnings.join("\n");
        assert!(needles.iter().all(|n| w.contains(n)) && w.contains("the prim is skipped"), "{file}: {w}");
    };
    skipped_with("bad/index_out_of_range.usda", &["/World/Broken", "faceVertexIndices[2] = 7"]);
    skipped_with("bad/nan_points.usda", &["/World/Broken", "points", "point 1"]);
}

/// One malformed prim of each kind (no points, `points` as `int[]`, `normals` as `float[]`,
/// a zero scale) beside a good quad: each is reported once by prim and attribute and
/// skipped, the quad renders, and `--strict` turns the warnings into a failure before
/// rendering.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_prims_are_skipped_and_the_rest_renders() {
    let t = tessera::usd::load(&fixture("bad/malformed_prims.usda")).expect("the stage loads");
    assert_eq!(t.skipped, ["/World/NoPoints", "/World/IntPoints", "/World/BadNormals", "/World/Singular"]);
    for (prim, what) in [
        ("/World/NoPoints", "'points' is missing"),
        ("/World/IntPoints", "'points' has type"),
        ("/World/BadNormals", "normals"),
        ("/World/Singular", "singular transform"),
    ] {
        let said: Vec<&String> = t.warnings.iter().filter(|w| w.starts_with(prim)).collect();
        assert_eq!(said.len(), 1, "{prim} reported once: {:?}", t.warnings);
        assert!(said[0].contains(what) && said[0].contains("the prim is skipped"), "{}", said[0]);
    }
    assert_eq!(t.meshes.iter().map(|(p, _)| p.as_str()).collect::<Vec<_>>(), ["/World/Good"]);
    let report = render_fixture("bad/malformed_prims.usda", &small(32, 32, 4)).await;
    let centre = report.image.pixel("beauty", 16, 16);
    assert!(centre[0] > 0.1 && centre[3] == 1.0, "the good quad renders: {centre:?}");

    let out = std::env::temp_dir().join(format!("tessera-strict-{}.exr", std::process::id()));
    let job = tessera::commands::render::RenderJob {
        strict: true,
        ..tessera::commands::render::RenderJob::new(fixture("bad/malformed_prims.usda"), out.clone(), small(8, 8, 1))
    };
    let e = format!("{:#}", tessera::commands::render::run(&job).await.unwrap_err());
    assert!(e.contains("4 warning(s)") && e.contains("--strict"), "{e}");
    assert!(!out.exists(), "nothing is written");
}

fn raw_mesh(path: &str, points: Vec<f32>, indices: Vec<u32>) -> Vec<pb::sync_request::Item> {
    let prim =
        pb::MeshPrim { points_len: points.len() as u64, triangle_indices_len: indices.len() as u64, visible: true, ..Default::default() };
    vec![
        tessera::sync::delta(path, pb::PrimKind::Mesh, pb::prim_delta::Payload::Mesh(prim)),
        pb::sync_request::Item::Chunk(pb::ArrayChunk {
            path: path.into(),
            field: pb::ArrayField::Points as i32,
            offset: 0,
            floats: points,
            ..Default::default()
        }),
        pb::sync_request::Item::Chunk(pb::ArrayChunk {
            path: path.into(),
            field: pb::ArrayField::TriangleIndices as i32,
            offset: 0,
            uints: indices,
            ..Default::default()
        }),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_server_rejects_bad_deltas_by_name_and_keeps_serving_others() {
    let server = EmbeddedServer::start().await.unwrap();
    let mut good = Connection::connect(&server.url(), "good").await.unwrap();
    good.sync(tessera::sync::full_sync(&load("cornell_box.usda"))).await.unwrap();

    let mut bad = Connection::connect(&server.url(), "bad").await.unwrap();
    let tri = vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let e = bad.sync(raw_mesh("/Evil/OutOfRange", tri.clone(), vec![0, 1, 9])).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/OutOfRange") && e.contains("faceVertexIndices") && e.contains("index 9"), "{e}");
    let mut nan = tri.clone();
    nan[4] = f32::NAN;
    let e = bad.sync(raw_mesh("/Evil/Nan", nan, vec![0, 1, 2])).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/Nan") && e.contains("points") && e.contains("point 1"), "{e}");
    let mut short = raw_mesh("/Evil/Short", tri.clone(), vec![0, 1, 2]);
    short.truncate(2);
    let e = bad.sync(short).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/Short") && e.contains("triangle_indices") && e.contains("received 0 of 3"), "{e}");
    let mut past_end = raw_mesh("/Evil/PastEnd", tri, vec![0, 1, 2]);
    if let pb::sync_request::Item::Chunk(c) = &mut past_end[1] {
        c.offset = 3;
    }
    let e = bad.sync(past_end).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/PastEnd") && e.contains("runs past the declared length"), "{e}");
    // Primvars: a chunk for one that was not declared, a declared one left short, and one whose
    // length does not match its interpolation.
    let with_primvar = |len: u64, chunk_for: u32, values: Vec<f32>| {
        let mut items = raw_mesh("/Evil/Primvar", vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], vec![0, 1, 2]);
        if let pb::sync_request::Item::Prim(pb::PrimDelta { payload: Some(pb::prim_delta::Payload::Mesh(m)), .. }) = &mut items[0] {
            m.primvars = vec![pb::PrimvarInfo { name: "tint".into(), len, interpolation: pb::NormalInterpolation::NormalsVertex as i32 }];
        }
        items.push(pb::sync_request::Item::Chunk(pb::ArrayChunk {
            path: "/Evil/Primvar".into(),
            field: pb::ArrayField::Primvar as i32,
            primvar: chunk_for,
            floats: values,
            ..Default::default()
        }));
        items
    };
    let e = bad.sync(with_primvar(9, 1, vec![0.0; 9])).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/Primvar") && e.contains("chunk.primvar") && e.contains("no primvar 1"), "{e}");
    let e = bad.sync(with_primvar(9, 0, vec![0.0; 6])).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/Primvar") && e.contains("primvars:tint") && e.contains("received 6 of 9"), "{e}");
    let e = bad.sync(with_primvar(6, 0, vec![0.0; 6])).await.unwrap_err().to_string();
    assert!(e.contains("/Evil/Primvar") && e.contains("primvars:tint") && e.contains("2 vertex values for 3 expected"), "{e}");
    let e = bad.render(&small(8, 8, 1), |_| {}).await.unwrap_err().to_string();
    assert!(e.contains("no scene yet"), "a failed sync commits nothing: {e}");
    let e = good
        .render(&tessera::remote::RenderOptions { aovs: vec!["bogus".into()], ..small(8, 8, 1) }, |_| {})
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown AOV 'bogus'"), "{e}");

    // The well-behaved session still renders.
    let report = good.render(&small(16, 16, 2), |_| {}).await.unwrap();
    let (mean, _) = mean_where(&report.image, "beauty", 1, |_, _| true);
    assert!(mean > 0.05, "{mean}");
    server.stop().await.unwrap();
}

/// A warning is said once however many prims run into it: two meshes bound to one material
/// path that is not a Material (the reader looks at each material path once).
#[test]
fn each_warning_is_said_once() {
    let mesh = |name: &str| {
        format!(
            r#"def Mesh "{name}" (prepend apiSchemas = ["MaterialBindingAPI"])
{{
    point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0)]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    rel material:binding = </NotAMaterial>
}}
"#
        )
    };
    let t = load_text("once", &format!("#usda 1.0\ndef Xform \"NotAMaterial\" {{}}\n{}{}", mesh("A"), mesh("B")));
    let about: Vec<&String> = t.warnings.iter().filter(|w| w.contains("/NotAMaterial")).collect();
    assert_eq!(about.len(), 1, "{:?}", t.warnings);
}

/// What would otherwise be lost without a word gets one warning each: a camera whose clipping
/// range hides every mesh, a `model:drawMode` stand-in (the geometry renders), an `upAxis`
/// that is neither Y nor Z, a reference and a payload whose files do not exist, a `purpose`
/// token UsdGeom does not define (the prim renders as `default`), an attribute animated by a
/// spline with inner loops (deprecated in USD, not evaluated: the light keeps its fallback),
/// a volume as a light (VolumeLightAPI; a mesh as a light is read, not reported),
/// and a collection defined by a path expression (the text layer failed to parse before: the
/// crate knew no `pathExpression` type).
#[test]
fn silent_losses_are_said() {
    let t = load_text(
        "silent",
        r#"#usda 1.0
(
    upAxis = "X"
)
def Xform "Asset" (prepend apiSchemas = ["GeomModelAPI"])
{
    uniform token model:drawMode = "cards"
    def Mesh "Quad"
    {
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token purpose = "bogus"
    }
}
def "Missing" (prepend references = @./does_not_exist.usda@)
{
}
def "Unloadable" (prepend payload = @./nope.usda@)
{
}
def Camera "Far"
{
    float2 clippingRange = (100, 1000)
    double3 xformOp:translate = (0, 0, 5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Camera "Fine"
{
    double3 xformOp:translate = (0, 0, 5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Mesh "Glow" (prepend apiSchemas = ["MeshLightAPI"])
{
    point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0)]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
}
def Volume "Haze" (prepend apiSchemas = ["VolumeLightAPI"])
{
}
def Scope "Sets" (prepend apiSchemas = ["CollectionAPI:props"])
{
    uniform pathExpression collection:props:membershipExpression = "/Asset/* //{bogus}"
}
def RectLight "Fill" (prepend apiSchemas = ["CollectionAPI:shadowLink"])
{
    uniform bool collection:shadowLink:includeRoot = 0
}
def DiskLight "Plain"
{
}
def SphereLight "Key" (prepend apiSchemas = ["CollectionAPI:lightLink"])
{
    rel collection:lightLink:includes = </Asset/Quad>
    float inputs:intensity.spline = {
        bezier,
        loop: (0, 10, 1, 1, 0),
        0: 1; pre (0, 0); post linear,
        10: 11; post held,
    }
}
"#,
    );
    let one = |needle: &str| {
        let n = t.warnings.iter().filter(|w| w.contains(needle)).count();
        assert_eq!(n, 1, "'{needle}' said once: {:?}", t.warnings);
    };
    one("/Far: clippingRange (100, 1000) hides the whole scene");
    one("/Asset: model:drawMode 'cards'");
    one("upAxis 'X'");
    one("unresolved Reference layer @");
    one("unresolved Payload layer @");
    one("/Asset/Quad: purpose 'bogus'");
    one("/Key.inputs:intensity: attribute animated by a spline");
    one("/Haze: VolumeLightAPI (a Volume as a light) is not supported yet");
    assert!(!t.warnings.iter().any(|w| w.contains("/Glow")), "{:?}", t.warnings);
    let glow = t.meshes.iter().find(|(path, _)| path == "/Glow").expect("the mesh light");
    let light = glow.1.light.as_ref().expect("read as a light");
    assert_eq!((light.intensity, light.sync), (1.0, render_core::light::MaterialSync::GlowTintsLight), "MeshLightAPI's fallbacks");
    one("/Sets: collection 'props': its membershipExpression cannot be evaluated");
    assert!(!t.warnings.iter().any(|w| w.contains("/Plain")), "{:?}", t.warnings);
    let key = t.lights.iter().find(|(path, _)| path == "/Key").expect("the key light");
    assert_eq!(key.1.intensity, 1.0, "the fallback, not a half-read spline");
    // Light linking is read, not reported: includes alone limit nothing (LightAPI's includeRoot
    // fallback is true, as usd-core's membership query says), and a shadow link that leaves the
    // root out holds no prim.
    assert_eq!((key.1.light_link.as_deref(), key.1.shadow_link.as_deref()), (None, None));
    let fill = t.lights.iter().find(|(path, _)| path == "/Fill").expect("the fill light");
    assert_eq!((fill.1.light_link.as_deref(), fill.1.shadow_link.as_deref()), (None, Some("/Fill.collection:shadowLink")));
    assert!(t.meshes.iter().all(|(_, m)| m.link_collections.is_empty()), "no prim casts the fill's shadows");
    assert!(!t.warnings.iter().any(|w| w.contains("/Fine")), "{:?}", t.warnings);
    assert_eq!(t.meshes.len(), 2, "the geometry under a draw mode renders, and the mesh light as a mesh");
}

/// What a payload's layer asks for is read or reported too, though the layer loads only when
/// composition reaches its prim, after the stage opened: a light link inside a payload links,
/// a mesh light there is read as a light, and a volume light there gets its warning.
#[test]
fn a_payloads_unsupported_requests_are_said() {
    let dir = std::env::temp_dir().join(format!("tessera-payload-reports-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("asset.usda"),
        r#"#usda 1.0
(
    defaultPrim = "A"
)
def Xform "A"
{
    def Mesh "Glow" (prepend apiSchemas = ["MeshLightAPI"])
    {
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0)]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
    }
    def SphereLight "Key"
    {
        uniform bool collection:lightLink:includeRoot = 0
        rel collection:lightLink:includes = </A/Glow>
    }
    def Volume "Haze" (prepend apiSchemas = ["VolumeLightAPI"])
    {
    }
}
"#,
    )
    .unwrap();
    std::fs::write(dir.join("scene.usda"), "#usda 1.0\ndef \"World\" (prepend payload = @./asset.usda@)\n{\n}\n").unwrap();
    let t = tessera::usd::load(&dir.join("scene.usda")).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(t.warnings.iter().filter(|w| w.contains("/World/Haze: VolumeLightAPI")).count(), 1, "{:?}", t.warnings);
    let key = &t.lights.iter().find(|(p, _)| p == "/World/Key").expect("the light").1;
    assert_eq!(key.light_link.as_deref(), Some("/World/Key.collection:lightLink"));
    let glow = &t.meshes.iter().find(|(p, _)| p == "/World/Glow").expect("the mesh").1;
    assert_eq!(glow.link_collections, ["/World/Key.collection:lightLink"]);
    assert!(glow.light.is_some(), "the payload's mesh light is a light");
}

/// The commit says each thing once too: a textured material's mistyped input is said once,
/// though its network is both compiled (texture graph) and resolved (constant part).
#[test]
fn a_commit_says_each_warning_once() {
    let mut t = load("textures/checker_plane.usda");
    let net = &mut t.materials[0].1;
    let surface = net.nodes.iter_mut().find(|n| n.node_type_id == "UsdPreviewSurface").unwrap();
    surface.parameters.insert("roughness".into(), render_core::material::ParamValue::Float3(glam::Vec3::ONE));
    let scene = render_core::scene::commit(&t.to_scene_desc(), &mut render_core::scene::BlasCache::default()).unwrap();
    let said = scene.warnings.iter().filter(|w| w.contains("'roughness' has the wrong type")).count();
    assert_eq!(said, 1, "{:?}", scene.warnings);
}

/// A light link given by a `membershipExpression` limits the light only where usd-core
/// evaluates it: with `includeRoot` authored false. Left to LightAPI's fallback (true), or
/// authored true, the root holds every prim in usd-core too. An expression that cannot be
/// evaluated (a predicate nobody defines) holds nothing, and says so, naming the light.
#[test]
fn a_link_expression_limits_the_light_only_where_usd_core_evaluates_it() {
    let expression = |name: &str, root: &str, text: &str| {
        format!(
            "def SphereLight \"{name}\"\n{{\n{root}    uniform pathExpression collection:lightLink:membershipExpression = \"{text}\"\n}}\n"
        )
    };
    let (on, off) = ("    uniform bool collection:lightLink:includeRoot = 1\n", "    uniform bool collection:lightLink:includeRoot = 0\n");
    let usda = format!(
        "#usda 1.0\ndef Cube \"A\"\n{{\n}}\ndef Cube \"B\"\n{{\n}}\n{}{}{}{}",
        expression("Fallback", "", "/A"),
        expression("RootOn", on, "/A"),
        expression("RootOff", off, "/A"),
        expression("Unknown", off, "//{bogus}"),
    );
    let t = load_text("link_expression", &usda);
    let said: Vec<&String> = t.warnings.iter().filter(|w| w.contains("membershipExpression")).collect();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(said[0].starts_with("/Unknown: collection:lightLink:membershipExpression cannot be evaluated"), "{said:?}");
    let link = |light: &str| t.lights.iter().find(|(path, _)| path == light).and_then(|(_, l)| l.light_link.clone());
    assert_eq!((link("/Fallback"), link("/RootOn")), (None, None), "the root holds every prim");
    let collections = |mesh: &str| t.meshes.iter().find(|(path, _)| path == mesh).map(|(_, m)| m.link_collections.clone()).unwrap();
    assert_eq!(collections("/A"), ["/RootOff.collection:lightLink"], "the expression holds /A alone");
    assert!(collections("/B").is_empty());
    assert_eq!(link("/Unknown").as_deref(), Some("/Unknown.collection:lightLink"), "a link that holds nothing");
}

/// Path expressions are hostile input too: each worst case loads (on a test thread's 2 MiB
/// stack), says why its light's link cannot be evaluated, and leaves the light illuminating
/// nothing. A chain of 50,000 `-` overflowed the stack in the evaluator's recursive walks
/// before the parser bounded operators (512); references that double at each of 40
/// collections would expand to 2^40 terms (bounded at 4,096); and a chain of references
/// recurses once per collection (bounded at 64).
#[test]
fn path_expressions_past_the_limits_are_said_not_crashed_on() {
    let light = |expression: &str| {
        format!(
            "def SphereLight \"L\"\n{{\n    uniform bool collection:lightLink:includeRoot = 0\n    uniform pathExpression collection:lightLink:membershipExpression = \"{expression}\"\n}}\n"
        )
    };
    let collections = |count: usize, refer: &dyn Fn(usize) -> String| -> String {
        (0..count)
            .map(|i| {
                let text = if i + 1 < count { refer(i + 1) } else { "/A".to_string() };
                format!("def Scope \"S{i}\" (\n    prepend apiSchemas = [\"CollectionAPI:c\"]\n)\n{{\n    uniform pathExpression collection:c:membershipExpression = \"{text}\"\n}}\n")
            })
            .collect()
    };
    let cases = [
        ("operators", light(&vec!["/A"; 50_000].join(" - ")), "more than 512 operators"),
        ("predicates", light(&format!("//{{{}}}", vec!["isa:Cube"; 50_000].join(" and "))), "more than 512 operators"),
        ("doubling", light("%/S0:c") + &collections(40, &|n| format!("%/S{n}:c %/S{n}:c")), "more than 4096 terms"),
        ("chain", light("%/S0:c") + &collections(200, &|n| format!("%/S{n}:c")), "more than 64 collections in a chain"),
    ];
    for (name, body, why) in cases {
        let t = load_text(&format!("expression-{name}"), &format!("#usda 1.0\ndef Cube \"A\"\n{{\n}}\n{body}"));
        let said: Vec<&String> = t.warnings.iter().filter(|w| w.starts_with("/L: collection:lightLink:membershipExpression")).collect();
        assert_eq!(said.len(), 1, "{name}: {:?}", t.warnings.iter().take(3).collect::<Vec<_>>());
        assert!(said[0].contains(why) && said[0].len() < 600, "{name}: {}", said[0]);
        let cube = t.meshes.iter().find(|(path, _)| path == "/A").expect("the cube renders");
        assert!(cube.1.link_collections.is_empty(), "{name}: the light holds nothing");
        let l = t.lights.iter().find(|(path, _)| path == "/L").expect("the light");
        assert_eq!(l.1.light_link.as_deref(), Some("/L.collection:lightLink"), "{name}");
    }
}
