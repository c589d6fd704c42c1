//! Light linking (UsdLux `collection:lightLink` and `collection:shadowLink`) in rendered
//! images: a light reaches only the prims its light link holds, by light sampling and by the
//! rays that find it; only the prims its shadow link holds cast its shadows.
//!
//! Which lights reach which prims, as read from USD, is checked against usd-core's membership
//! queries on `fixtures/usd/light_linking.usda` by `usd::an_independent_reader_agrees_on_every_fixture`.

use tessera::remote::Connection;
use tessera_server::EmbeddedServer;
use tessera_tests::*;

/// Two coplanar quads side by side, seen head-on through an orthographic camera (the left one
/// fills the image's left half), lit by a sphere light out of frame whose light link holds
/// `linked` alone (with the root left out).
fn two_quads(linked: &str) -> String {
    let quad = |name: &str, x0: f32| {
        format!(
            "def Mesh \"{name}\"\n{{\n    point3f[] points = [({x0}, -1, 0), ({}, -1, 0), ({}, 1, 0), ({x0}, 1, 0)]\n    \
             int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n}}\n",
            x0 + 2.0,
            x0 + 2.0
        )
    };
    format!(
        "#usda 1.0\n{}{}def SphereLight \"Key\"\n{{\n    float inputs:intensity = 20\n    double3 xformOp:translate = (0, 3, 2)\n    \
         uniform token[] xformOpOrder = [\"xformOp:translate\"]\n    uniform bool collection:lightLink:includeRoot = 0\n    \
         rel collection:lightLink:includes = <{linked}>\n}}\n\
         def Camera \"Camera\"\n{{\n    token projection = \"orthographic\"\n    float horizontalAperture = 40\n    \
         float verticalAperture = 20\n    double3 xformOp:translate = (0, 0, 5)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n",
        quad("Left", -2.0),
        quad("Right", 0.0)
    )
}

/// The light reaches the quad its link holds and nothing of the other: every pixel of the
/// unlinked quad is exactly black (the quads do not see each other, so no light reaches it
/// any other way), both through light sampling and through BSDF-sampled rays that find the
/// sphere; the linked quad is lit. Swapping the link swaps the halves.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_light_reaches_only_the_prims_its_light_link_holds() {
    for (linked, lit_left) in [("/Left", true), ("/Right", false)] {
        let t = load_text("light_link", &two_quads(linked));
        let (server, mut conn) = session_with(&t).await;
        let report = conn.render(&small(32, 16, 16), |_| {}).await.expect("renders");
        server.stop().await.unwrap();
        let plan: Vec<&str> = report.started.plan.iter().map(|e| e.effect.as_str()).collect();
        assert!(plan.contains(&"light-linking"), "the plan says it links: {plan:?}");
        let (dark, lit): (std::ops::Range<u32>, std::ops::Range<u32>) = if lit_left { (16..32, 0..16) } else { (0..16, 16..32) };
        let lit = mean_where(&report.image, "beauty", 1, |x, _| lit.contains(&x)).0;
        for y in 0..16 {
            for x in dark.clone() {
                let p = report.image.pixel("beauty", x, y);
                assert_eq!(&p[..3], &[0.0, 0.0, 0.0], "{linked} linked: pixel ({x}, {y}) of the unlinked quad is lit");
            }
        }
        // Albedo 0.18 (UsdPreviewSurface's default) under a radius-0.5 sphere of radiance 20
        // about 3.7 units away, at 58° off the normal: about 0.18 × 20 × π0.5²/3.7² × 0.53 / π
        // ≈ 0.035 at the quad's middle.
        assert!(lit > 0.02, "{linked} linked: the linked quad's mean is {lit}");
    }
}

/// A Lambertian floor (UsdPreviewSurface with IOR 1 has no specular reflection) of albedo
/// 0.5, 4 units wide, a black 1×1 blocker 2 units above its middle (if `blocker`), `light`
/// (its USD text, with `link` inside it) above them, and an orthographic camera under the
/// blocker looking down, so it sees only the floor.
fn floor_scene(light: &str, link: &str, blocker: bool) -> String {
    let matte = |name: &str, albedo: f32| {
        format!(
            "def Material \"{name}\"\n{{\n    token outputs:surface.connect = </{name}/S.outputs:surface>\n    def Shader \"S\"\n    {{\n        \
             uniform token info:id = \"UsdPreviewSurface\"\n        color3f inputs:diffuseColor = ({albedo}, {albedo}, {albedo})\n        \
             float inputs:ior = 1\n        token outputs:surface\n    }}\n}}\n"
        )
    };
    let quad = |name: &str, points: &str, material: &str| {
        format!(
            "def Mesh \"{name}\" (prepend apiSchemas = [\"MaterialBindingAPI\"])\n{{\n    point3f[] points = [{points}]\n    \
             int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n    rel material:binding = </{material}>\n}}\n"
        )
    };
    let mut usda = String::from("#usda 1.0\n");
    usda += &quad("Floor", "(-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)", "Matte");
    usda += &matte("Matte", 0.5);
    if blocker {
        usda += &quad("Blocker", "(-0.5, 2, 0.5), (-0.5, 2, -0.5), (0.5, 2, -0.5), (0.5, 2, 0.5)", "Black");
        usda += &matte("Black", 0.0);
    }
    usda += &light.replace("{link}", link);
    usda += "def Camera \"Camera\"\n{\n    token projection = \"orthographic\"\n    float horizontalAperture = 40\n    \
              float verticalAperture = 40\n    float2 clippingRange = (0.01, 100)\n    float3 xformOp:rotateXYZ = (-90, 0, 0)\n    \
              double3 xformOp:translate = (0, 1, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\"]\n}\n";
    usda
}

/// The blocker left out of a light's shadow link.
const UNLINKED: &str = "    rel collection:shadowLink:excludes = </Blocker>\n";

/// Renders a floor scene at 16×16 and returns its image.
async fn render_floor(usda: &str, spp: u32) -> tessera::output::Image {
    let t = load_text("shadow_link", usda);
    let (server, mut conn) = session_with(&t).await;
    let report = conn.render(&small(16, 16, spp), |_| {}).await.expect("renders");
    server.stop().await.unwrap();
    report.image
}

/// Under a normalised distant light of intensity 3 straight above, the floor's radiance is
/// albedo × E / π = 0.5 × 3 / π where lit. With no link the blocker's shadow darkens the
/// floor's middle; with the blocker left out of the light's shadow link the floor is lit
/// everywhere as if the blocker were not there.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn prims_outside_a_lights_shadow_link_cast_none_of_its_shadows() {
    let sun = "def DistantLight \"Sun\"\n{\n    float inputs:intensity = 3\n    bool inputs:normalize = 1\n    \
               float3 xformOp:rotateXYZ = (-90, 0, 0)\n    uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]\n{link}}\n";
    let mut means = Vec::new();
    for link in ["", UNLINKED] {
        let image = render_floor(&floor_scene(sun, link, true), 16).await;
        // The middle 2×2 pixels: well inside the shadow, beyond the pixel filter's reach.
        let middle = |x: u32, y: u32| (7..9).contains(&x) && (7..9).contains(&y);
        let edge = |x: u32, y: u32| x < 2 || y < 2;
        means.push((mean_where(&image, "beauty", 1, middle).0, mean_where(&image, "beauty", 1, edge).0));
    }
    let lit = 0.5 * 3.0 / std::f64::consts::PI;
    let [(shadowed, edge), (middle, edge_linked)] = [means[0], means[1]];
    // The blocker's 1×1 shadow covers the middle 4×4 pixels (of a 4×4 unit floor); the sun's
    // half-degree disk blurs its border by 0.02 units, under a tenth of a pixel.
    assert!(shadowed < 1e-3, "the blocker's shadow, without a link: {shadowed}");
    // The floor's edge, which the blocker never shadows, and the linked floor's middle, match
    // the closed form; the sun's disk is sampled by direction, so only its cosine spread
    // (under 2e-5) and f32 sums stand between them.
    for (what, v) in [("edge", edge), ("edge with the link", edge_linked), ("middle with the link", middle)] {
        assert!((v - lit).abs() < 1e-3 * lit, "{what}: {v} against {lit}");
    }
}

/// A shadow-linked area light is counted once, by light sampling alone: rays a BSDF samples
/// towards it still stop at prims outside its shadow link, so MIS against them would lose
/// the light they miss. Under a large sphere light, the floor with the blocker left out of the
/// shadow link matches the floor with no blocker at all, pixel mean against pixel mean.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_shadow_linked_light_is_found_by_light_sampling_alone() {
    let bulb = "def SphereLight \"Bulb\"\n{\n    float inputs:intensity = 2\n    float inputs:radius = 1.5\n    \
                double3 xformOp:translate = (0, 4, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n{link}}\n";
    let linked = render_floor(&floor_scene(bulb, UNLINKED, true), 256).await;
    let bare = render_floor(&floor_scene(bulb, "", false), 256).await;
    let middle = |x: u32, y: u32| (4..12).contains(&x) && (4..12).contains(&y);
    let (a, b) = (mean_where(&linked, "beauty", 1, middle).0, mean_where(&bare, "beauty", 1, middle).0);
    // Measured: 3e-6 apart (light sampling is nearly noiseless here); with MIS kept against the
    // blocked BSDF rays the unlinked floor came out 0.7% dark.
    assert!((a - b).abs() < 2e-3 * b, "the floor's middle with the blocker unlinked {a}, without the blocker {b}");
}

/// A live edit that moves a prim into a light's link collection and another out of it goes
/// as two mesh deltas with only `categories` dirty (no arrays), and the next render swaps
/// which quad is lit, exactly black where the light no longer reaches.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn moving_prims_between_link_collections_sends_only_their_categories() {
    let before = load_text("link_edit_before", &two_quads("/Left"));
    let mut after = before.clone();
    for (path, mesh) in &mut after.meshes {
        mesh.link_collections = if path == "/Right" { vec!["/Key.collection:lightLink".into()] } else { Vec::new() };
    }
    let items = tessera::sync::changes(&before, &after);
    let sent = tessera::live::summarize(&items);
    let described: Vec<(String, Vec<&str>, usize)> = sent.iter().map(|s| (s.path.clone(), s.dirty.clone(), s.chunks)).collect();
    assert_eq!(described, [("/Left".to_string(), vec!["categories"], 0), ("/Right".to_string(), vec!["categories"], 0)]);
    let (server, mut conn) = session_with(&before).await;
    conn.sync(items).await.expect("the edit syncs");
    let report = conn.render(&small(32, 16, 16), |_| {}).await.expect("renders");
    server.stop().await.unwrap();
    for y in 0..16 {
        for x in 0..16 {
            assert_eq!(&report.image.pixel("beauty", x, y)[..3], &[0.0, 0.0, 0.0], "pixel ({x}, {y}) of the left quad is lit");
        }
    }
    let lit = mean_where(&report.image, "beauty", 1, |x, _| x >= 16).0;
    assert!(lit > 0.02, "the right quad, now linked: {lit}");
}

/// A DCC links a light through the live session: every instance of a native prototype in
/// the forest at once links (their shared instancer moves into the collection), while a link
/// that would split the instances one instancer draws is refused, naming it, and changes
/// nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_live_light_link_moves_whole_instancers_and_refuses_to_split_one() {
    let server = EmbeddedServer::start().await.unwrap();
    let conn = Connection::connect(&server.url(), "links").await.unwrap();
    let mut live = tessera::live::LiveSession::new(conn);
    live.sync_usd(&fixture("usd/instancing/forest.usda"), None).await.unwrap();
    let sent = live.set_light_links("/World/Sky", Some(vec!["/World/Trees".into()]), None).await.unwrap();
    assert!(sent.iter().any(|s| s.kind == "instancer"), "{sent:?}");
    let split = live.set_light_links("/World/Sky", Some(vec!["/World/Trees/Tree_00".into()]), None).await;
    let e = format!("{:#}", split.expect_err("one instancer's trees on both sides"));
    assert!(e.contains("fall on both sides of the link") && e.contains("[instances]"), "{e}");
    // The refused edit left the session as it was: asking for the first link again sends nothing.
    let again = live.set_light_links("/World/Sky", Some(vec!["/World/Trees".into()]), None).await.unwrap();
    assert!(again.is_empty(), "{again:?}");
    server.stop().await.unwrap();
}

/// A volume left out of a light's shadow link lets that light through, as a surface does. A
/// sun at 45° shines past the fixture's ink box onto a wall behind it; the wall is seen beside
/// the box, not through it, so the camera's rays cross no volume there. With no link the
/// box's shadow darkens the wall; with the shadow link leaving every prim out, the shadowed
/// spot is lit as the open wall is.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_volume_outside_a_lights_shadow_link_casts_none_of_its_shadows() {
    let scene = |link: &str| {
        format!(
            "#usda 1.0\n(\n    subLayers = [@{}@]\n)\nover \"World\"\n{{\n    over \"Camera\"\n    {{\n        float horizontalAperture = 60\n        float verticalAperture = 60\n    }}\n    over \"Sky\"\n    {{\n        float inputs:intensity = 0\n    }}\n}}\n\
             def Material \"Matte\"\n{{\n    token outputs:surface.connect = </Matte/S.outputs:surface>\n    def Shader \"S\"\n    {{\n        \
             uniform token info:id = \"UsdPreviewSurface\"\n        color3f inputs:diffuseColor = (0.5, 0.5, 0.5)\n        float inputs:ior = 1\n        \
             token outputs:surface\n    }}\n}}\n\
             def Mesh \"Wall\" (prepend apiSchemas = [\"MaterialBindingAPI\"])\n{{\n    \
             point3f[] points = [(-3, -3, -1), (4, -3, -1), (4, 4, -1), (-3, 4, -1)]\n    int[] faceVertexCounts = [4]\n    \
             int[] faceVertexIndices = [0, 1, 2, 3]\n    uniform token subdivisionScheme = \"none\"\n    rel material:binding = </Matte>\n}}\n\
             def DistantLight \"Sun\"\n{{\n    float inputs:intensity = 2\n    bool inputs:normalize = 1\n    float3 xformOp:rotateXYZ = (0, 45, 0)\n    \
             uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]\n{link}}}\n",
            fixture("usd/volume_box.usda").display()
        )
    };
    let mut means = Vec::new();
    for link in ["", "    uniform bool collection:shadowLink:includeRoot = 0\n"] {
        let t = load_text("volume_shadow_link", &scene(link));
        assert_eq!(t.volumes.len(), 1, "the box is a volume");
        let (server, mut conn) = session_with(&t).await;
        let report = conn.render(&small(24, 24, 64), |_| {}).await.expect("renders");
        server.stop().await.unwrap();
        // The camera widened to 6 units (apertures are in tenths of a unit): 4 pixels a unit
        // over x, y in [-2.5, 3.5]. The unit box's shadow falls on x in [-2, 0], y in [0, 1];
        // x in [2, 3] at the same height is open wall.
        let shadow = |x: u32, y: u32| (4..8).contains(&x) && (11..14).contains(&y);
        let open = |x: u32, y: u32| (18..22).contains(&x) && (11..14).contains(&y);
        means.push((mean_where(&report.image, "beauty", 1, shadow).0, mean_where(&report.image, "beauty", 1, open).0));
    }
    let [(shadowed, open), (linked, open_linked)] = [means[0], means[1]];
    // Albedo 0.5 under an illuminance of 2 at 45°: 0.5 · 2 cos 45° / π. Light sampling of a
    // distant light is noiseless but for its half-degree disk.
    let lit = 0.5 * 2.0 * std::f64::consts::FRAC_1_SQRT_2 / std::f64::consts::PI;
    // Measured: 0.16 of it over these pixels (the whole path of √2 through density 2 leaves
    // e^(-2√2) = 0.06; the pixels nearer the shadow's edge cross less of the box).
    assert!(shadowed < 0.5 * lit, "the box's shadow without a link: {shadowed} against {lit}");
    for (what, v) in [("the open wall", open), ("the open wall with the link", open_linked), ("the shadow's spot with the link", linked)] {
        assert!((v - lit).abs() < 1e-3 * lit, "{what}: {v} against {lit}");
    }
}
