//! Gprims that are lights (UsdLux `MeshLightAPI`, and `LightAPI` applied to a gprim) in
//! rendered images: their radiance in UsdLux units against a closed form and against the
//! `RectLight` of the same shape, each `light:materialSyncMode`, their light links, and a live
//! edit of their inputs.
//!
//! How they are read from USD is checked against usd-core on `fixtures/usd/mesh_lights.usda`
//! by `usd::an_independent_reader_agrees_on_every_fixture`.

use tessera_tests::*;

/// A UsdPreviewSurface material `name` with `diffuse` albedo, IOR 1 (no specular reflection)
/// and `emissive` colour.
fn material(name: &str, diffuse: f32, emissive: [f32; 3]) -> String {
    format!(
        "def Material \"{name}\"\n{{\n    token outputs:surface.connect = </{name}/S.outputs:surface>\n    def Shader \"S\"\n    {{\n        \
         uniform token info:id = \"UsdPreviewSurface\"\n        color3f inputs:diffuseColor = ({diffuse}, {diffuse}, {diffuse})\n        \
         color3f inputs:emissiveColor = ({}, {}, {})\n        float inputs:ior = 1\n        token outputs:surface\n    }}\n}}\n",
        emissive[0], emissive[1], emissive[2]
    )
}

/// A flat quad `name` of half-width `half` at height `y`, facing up, bound to `material`,
/// with `extra` (applied schemas' attributes) in its body and `apis` applied.
fn quad(name: &str, half: f32, y: f32, material: &str, apis: &str, extra: &str) -> String {
    let h = half;
    format!(
        "def Mesh \"{name}\" (prepend apiSchemas = [\"MaterialBindingAPI\"{apis}])\n{{\n    uniform token subdivisionScheme = \"none\"\n    \
         point3f[] points = [(-{h}, {y}, {h}), ({h}, {y}, {h}), ({h}, {y}, -{h}), (-{h}, {y}, -{h})]\n    int[] faceVertexCounts = [4]\n    \
         int[] faceVertexIndices = [0, 1, 2, 3]\n    rel material:binding = </{material}>\n{extra}}}\n"
    )
}

/// An orthographic camera at height `y` looking straight down, `aperture` tenths of a unit
/// wide.
fn camera_down(y: f32, aperture: f32) -> String {
    format!(
        "def Camera \"Camera\"\n{{\n    token projection = \"orthographic\"\n    float horizontalAperture = {aperture}\n    \
         float verticalAperture = {aperture}\n    float2 clippingRange = (0.01, 100)\n    float3 xformOp:rotateXYZ = (-90, 0, 0)\n    \
         double3 xformOp:translate = (0, {y}, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\"]\n}}\n"
    )
}

/// Renders `usda` at `size`² and `spp`; the image and the plan's effects.
async fn render(usda: &str, size: u32, spp: u32) -> (tessera::output::Image, Vec<String>) {
    let t = load_text("mesh_light", usda);
    let (server, mut conn) = session_with(&t).await;
    let report = conn.render(&small(size, size, spp), |_| {}).await.expect("renders");
    server.stop().await.unwrap();
    let plan = report.started.plan.iter().map(|e| e.effect.clone()).collect();
    (report.image, plan)
}

/// The mean of each channel over the whole image.
fn mean_rgb(image: &tessera::output::Image) -> [f64; 3] {
    [0, 1, 2].map(|c| mean_where(image, "beauty", c, |_, _| true).0)
}

/// A Lambertian floor of albedo 0.5 under a 2×2 emitter one unit above its middle, seen at
/// its middle (a tenth of a unit across) from below the emitter: the emitter is `light`.
fn floor_under(light: &str) -> String {
    format!("#usda 1.0\n{}{}{light}{}", quad("Floor", 2.0, 0.0, "Matte", "", ""), material("Matte", 0.5, [0.0; 3]), camera_down(0.5, 1.0))
}

/// A 2×2 square at height 1, as a mesh light with no material response (plain `LightAPI`),
/// `extra` in its body.
fn panel(extra: &str) -> String {
    quad("Panel", 1.0, 1.0, "Matte", ", \"LightAPI\"", &format!("    float inputs:intensity = 8\n    bool inputs:normalize = 1\n{extra}"))
}

/// A normalized 2×2 emitter of intensity 8 has radiance 8 / 4 = 2 (UsdLux units). The
/// irradiance under the middle of a square of side 2 at height 1 is π·L·F with the view
/// factor F = 4 · (1/2π) · 2 · atan(1/√2)/√2 (four corner rectangles of sides 1, 1 at
/// distance 1), so a floor of albedo 0.5 there has radiance 0.5 · L · F = 0.554. The mesh
/// light (two triangles, each sampled by its solid angle) and the `RectLight` of its shape (sampled by solid
/// angle) both give it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mesh_light_emits_in_usdlux_units_as_the_rect_light_of_its_shape_does() {
    let view_factor = 4.0 / std::f64::consts::PI * (1.0f64 / 2f64.sqrt()).atan() / 2f64.sqrt();
    let expected = 0.5 * 2.0 * view_factor;
    let rect = "def RectLight \"Panel\"\n{\n    float inputs:width = 2\n    float inputs:height = 2\n    float inputs:intensity = 8\n    \
                bool inputs:normalize = 1\n    float3 xformOp:rotateXYZ = (-90, 0, 0)\n    double3 xformOp:translate = (0, 1, 0)\n    \
                uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\"]\n}\n";
    for (what, light) in [("mesh light", panel("")), ("rect light", rect.to_string())] {
        let (image, plan) = render(&floor_under(&light), 8, 256).await;
        let v = mean_rgb(&image);
        // 16 384 samples of the floor's direct light: area sampling of the two triangles has
        // a relative spread of about 0.4 per sample here, so the mean holds to 0.3% (1σ).
        for c in v {
            assert!((c - expected).abs() < 0.012 * expected, "{what}: {v:?} against the closed form {expected}");
        }
        let emissive = plan.iter().any(|e| e == "emissive-meshes");
        assert_eq!(emissive, what == "mesh light", "{what}: {plan:?}");
    }
}

/// The three `light:materialSyncMode`s on a quad of diffuse albedo 0.5 and emissive colour
/// (0.5, 0.25, 1), intensity 1, under a normalized sun of 3 straight above, seen from above:
/// the sun's reflection is 0.5 · 3 / π = 0.477. With the glow tinting the light the quad
/// shows glow + reflection; independent, white + reflection; with no material response,
/// white alone (it reflects nothing: exactly 1).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_material_sync_mode_tints_and_reflects_as_usdlux_says() {
    let sun = "def DistantLight \"Sun\"\n{\n    float inputs:intensity = 3\n    bool inputs:normalize = 1\n    \
               float3 xformOp:rotateXYZ = (-90, 0, 0)\n    uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]\n}\n";
    let reflected = 0.5 * 3.0 / std::f64::consts::PI;
    let glow = [0.5, 0.25, 1.0];
    for (mode, expected) in
        [("materialGlowTintsLight", glow.map(|g| g + reflected)), ("independent", [1.0 + reflected; 3]), ("noMaterialResponse", [1.0; 3])]
    {
        let sync = format!("    uniform token light:materialSyncMode = \"{mode}\"\n");
        let usda = format!(
            "#usda 1.0\n{}{}{sun}{}",
            quad("Glow", 1.0, 0.0, "Look", ", \"MeshLightAPI\"", &sync),
            material("Look", 0.5, glow.map(|g| g as f32)),
            camera_down(2.0, 10.0)
        );
        let (image, _) = render(&usda, 8, 256).await;
        let v = mean_rgb(&image);
        // The emission is exact. The sun's share is sampled: the light choice also weighs the
        // quad's own two triangles, which cannot light it, so at 16 spp it came out 0.3% off
        // either way; at 256 spp within 1.3e-4 (the sun's half-degree disk adds only 2e-5).
        for (c, e) in v.iter().zip(expected) {
            assert!((c - e).abs() < 1e-3 * e, "{mode}: {v:?} against {expected:?}");
        }
    }
}

/// A mesh light's light link: with the floor outside it, the floor is exactly black (nothing
/// else lights it); with the floor inside, it is lit as without a link. The plan names the
/// mesh light under light linking.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mesh_light_reaches_only_the_prims_its_light_link_holds() {
    let unlinked = render(&floor_under(&panel("")), 4, 64).await.0;
    for (linked, lit) in [("/Elsewhere", false), ("/Floor", true)] {
        let link = format!("    uniform bool collection:lightLink:includeRoot = 0\n    rel collection:lightLink:includes = <{linked}>\n");
        let (image, plan) = render(&floor_under(&panel(&link)), 4, 64).await;
        assert!(plan.iter().any(|e| e == "light-linking"), "{plan:?}");
        let v = mean_rgb(&image);
        match lit {
            false => assert_eq!(v, [0.0; 3], "the floor outside the link"),
            // The same samples as the unlinked render: the link changes no light choice here.
            true => assert_eq!(v, mean_rgb(&unlinked), "the floor inside the link"),
        }
    }
}

/// A live edit of a mesh light's intensity goes as one mesh delta with only `params` dirty (no
/// arrays), and the floor under it doubles with the intensity.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn editing_a_mesh_lights_inputs_sends_only_its_params() {
    let before = load_text("mesh_light_edit", &floor_under(&panel("")));
    let mut after = before.clone();
    let (_, mesh) = after.meshes.iter_mut().find(|(p, _)| p == "/Panel").expect("the panel");
    mesh.light.as_mut().expect("a mesh light").intensity *= 2.0;
    let items = tessera::sync::changes(&before, &after);
    let sent = tessera::live::summarize(&items);
    let described: Vec<(String, Vec<&str>, usize)> = sent.iter().map(|s| (s.path.clone(), s.dirty.clone(), s.chunks)).collect();
    assert_eq!(described, [("/Panel".to_string(), vec!["params"], 0)]);
    let (server, mut conn) = session_with(&before).await;
    let first = conn.render(&small(4, 4, 64), |_| {}).await.expect("renders");
    conn.sync(items).await.expect("the edit syncs");
    let second = conn.render(&small(4, 4, 64), |_| {}).await.expect("renders");
    server.stop().await.unwrap();
    let (a, b) = (mean_rgb(&first.image), mean_rgb(&second.image));
    // The same samples at twice the radiance: equal to float rounding.
    for (x, y) in a.iter().zip(b) {
        assert!((y - 2.0 * x).abs() < 1e-5 * y, "{a:?} then {b:?}");
    }
}

/// A DCC links a mesh light through the live session as it links a UsdLux light: linking the
/// fixture's sign to the floor alone sends the sign's params and the floor's categories, and
/// the edited session renders what a fresh session holding the linked scene renders, to the
/// bit, and not what it rendered before.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_live_session_links_a_mesh_light() {
    let server = tessera_server::EmbeddedServer::start().await.unwrap();
    let conn = tessera::remote::Connection::connect(&server.url(), "mesh-light-links").await.unwrap();
    let mut live = tessera::live::LiveSession::new(conn);
    live.sync_usd(&fixture("usd/mesh_lights.usda"), None).await.unwrap();
    let opts = small(32, 24, 4);
    let before = live.conn.render(&opts, |_| {}).await.unwrap();
    let sent = live.set_light_links("/World/Sign", Some(vec!["/World/Floor".into()]), None).await.unwrap();
    let described: Vec<(&str, Vec<&str>)> = sent.iter().map(|s| (s.path.as_str(), s.dirty.clone())).collect();
    assert!(described.contains(&("/World/Sign", vec!["params"])), "{described:?}");
    assert!(described.contains(&("/World/Floor", vec!["categories"])), "{described:?}");
    let edited = live.conn.render(&opts, |_| {}).await.unwrap();
    let linked = live.held().expect("the held scene").clone();
    let sign = linked.meshes.iter().find(|(p, _)| p == "/World/Sign").and_then(|(_, m)| m.light.as_ref()).expect("the sign's light");
    assert_eq!(sign.light_link.as_deref(), Some("/World/Sign.collection:lightLink"));
    server.stop().await.unwrap();
    let (fresh_server, mut fresh) = session_with(&linked).await;
    let fresh_image = fresh.render(&opts, |_| {}).await.unwrap().image;
    fresh_server.stop().await.unwrap();
    let pixels = |image: &tessera::output::Image| -> Vec<f32> {
        (0..24).flat_map(|y| (0..32).flat_map(move |x| image.pixel("beauty", x, y)[..3].to_vec())).collect()
    };
    assert_eq!(pixels(&edited.image), pixels(&fresh_image), "the live edit renders as the linked scene does");
    assert_ne!(pixels(&edited.image), pixels(&before.image), "the link changed the image");
}

/// A mesh light split by a material `GeomSubset` is a light in each part, and each part keeps
/// the mesh's light link (the parts are named by their subsets; the link by the mesh).
#[test]
fn a_mesh_lights_subsets_keep_its_links() {
    let t = load_text(
        "mesh_light_subsets",
        r#"#usda 1.0
def Mesh "Sign" (prepend apiSchemas = ["MeshLightAPI"])
{
    uniform token subdivisionScheme = "none"
    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)]
    int[] faceVertexCounts = [4, 4]
    int[] faceVertexIndices = [0, 1, 2, 3, 1, 4, 5, 2]
    uniform bool collection:lightLink:includeRoot = 0
    rel collection:lightLink:includes = </Floor>
    def GeomSubset "Left" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        uniform token elementType = "face"
        uniform token familyName = "materialBind"
        int[] indices = [0]
        rel material:binding = </Red>
    }
}
def Material "Red"
{
}
def Mesh "Floor"
{
    point3f[] points = [(-1, -1, -1), (1, -1, -1), (1, 1, -1)]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
}
"#,
    );
    let parts: Vec<(&str, Option<&str>)> = t
        .meshes
        .iter()
        .filter(|(p, _)| p.starts_with("/Sign"))
        .map(|(p, m)| (p.as_str(), m.light.as_ref().and_then(|l| l.light_link.as_deref())))
        .collect();
    assert_eq!(parts.len(), 2, "{parts:?}");
    assert!(parts.iter().all(|(_, link)| *link == Some("/Sign.collection:lightLink")), "{parts:?}");
}

/// The panel of [`panel`] as two 1×2 halves, each half claimed by a material `GeomSubset`, so
/// that no face is left to the mesh itself: three prims' worth of parts, one light.
fn split_panel() -> String {
    let subset = |name: &str, face: u32| {
        format!(
            "    def GeomSubset \"{name}\" (prepend apiSchemas = [\"MaterialBindingAPI\"])\n    {{\n        uniform token elementType = \
             \"face\"\n        uniform token familyName = \"materialBind\"\n        int[] indices = [{face}]\n        rel material:binding = \
             </Matte>\n    }}\n"
        )
    };
    format!(
        "def Mesh \"Panel\" (prepend apiSchemas = [\"LightAPI\"])\n{{\n    uniform token subdivisionScheme = \"none\"\n    \
         point3f[] points = [(-1, 1, 1), (0, 1, 1), (1, 1, 1), (1, 1, -1), (0, 1, -1), (-1, 1, -1)]\n    \
         int[] faceVertexCounts = [4, 4]\n    int[] faceVertexIndices = [0, 1, 4, 5, 1, 2, 3, 4]\n    \
         float inputs:intensity = 8\n    bool inputs:normalize = 1\n{}{}}}\n",
        subset("Left", 0),
        subset("Right", 1)
    )
}

/// UsdLux's `normalize` divides by the light's whole surface: the panel split by its subsets
/// into two halves lights the floor as the whole panel does (the closed form of
/// [`a_mesh_light_emits_in_usdlux_units_as_the_rect_light_of_its_shape_does`]), not twice as
/// brightly, as it did when each half divided by its own area.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_normalized_mesh_light_split_by_subsets_divides_by_its_whole_area() {
    let t = load_text("split_panel", &floor_under(&split_panel()));
    let parts: Vec<(&str, Option<&str>)> = t
        .meshes
        .iter()
        .filter(|(_, m)| m.light.is_some())
        .map(|(p, m)| (p.as_str(), m.light.as_ref().unwrap().part_of.as_deref()))
        .collect();
    assert_eq!(parts, [("/Panel/Left", Some("/Panel")), ("/Panel/Right", Some("/Panel"))]);
    let view_factor = 4.0 / std::f64::consts::PI * (1.0f64 / 2f64.sqrt()).atan() / 2f64.sqrt();
    let expected = 0.5 * 2.0 * view_factor;
    let (image, _) = render(&floor_under(&split_panel()), 8, 256).await;
    let v = mean_rgb(&image);
    // As in the whole panel's test: 16 384 samples hold the mean to about 0.3% (1σ).
    for c in v {
        assert!((c - expected).abs() < 0.012 * expected, "{v:?} against the closed form {expected}");
    }
}

/// A live edit of a split mesh light, named by its mesh's path (which no part carries once
/// every face is claimed), reaches each part: both go as params-only deltas, and the floor
/// doubles with the intensity.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_live_edit_of_a_split_mesh_light_reaches_every_part() {
    let dir = std::env::temp_dir().join(format!("tessera-split-panel-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("split_panel.usda");
    std::fs::write(&file, floor_under(&split_panel())).unwrap();
    let server = tessera_server::EmbeddedServer::start().await.unwrap();
    let conn = tessera::remote::Connection::connect(&server.url(), "split-mesh-light").await.unwrap();
    let mut live = tessera::live::LiveSession::new(conn);
    live.sync_usd(&file, None).await.unwrap();
    let opts = small(4, 4, 64);
    let before = live.conn.render(&opts, |_| {}).await.unwrap();
    let sent = live.set_light_params("/Panel", &[("intensity".into(), vec![16.0])]).await.unwrap();
    let described: Vec<(&str, Vec<&str>)> = sent.iter().map(|s| (s.path.as_str(), s.dirty.clone())).collect();
    assert_eq!(described, [("/Panel/Left", vec!["params"]), ("/Panel/Right", vec!["params"])]);
    let after = live.conn.render(&opts, |_| {}).await.unwrap();
    server.stop().await.unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let (a, b) = (mean_rgb(&before.image), mean_rgb(&after.image));
    // The same samples at twice the radiance: equal to float rounding.
    for (x, y) in a.iter().zip(b) {
        assert!((y - 2.0 * x).abs() < 1e-5 * y, "{a:?} then {b:?}");
    }
}
