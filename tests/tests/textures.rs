//! Textures end to end: the client reads the files (beside the layer, or inside a `.usdz`),
//! uploads each content once per server, and the renderer reads them with USD's st
//! orientation, wrap modes and colour spaces. The fixtures are `fixtures/textures/`; the sRGB
//! codes of the quadrant texture are `QUADRANTS` in make_fixtures.py.

use render_core::texture::srgb_to_linear;
use tessera::output::Image;
use tessera::remote::Connection;
use tessera_server::EmbeddedServer;
use tessera_tests::{assert_all_finite, load, render_fixture, small};

/// sRGB codes of the quadrant texture: top-left, top-right, bottom-left, bottom-right.
const TL: [u8; 3] = [200, 40, 40];
const TR: [u8; 3] = [40, 200, 40];
const BL: [u8; 3] = [40, 40, 200];
const BR: [u8; 3] = [230, 230, 230];
const BLACK: [u8; 3] = [0, 0, 0];

/// The linear albedo a code stands for: under a white dome of radiance 1, a Lambertian
/// surface without specular shows exactly its albedo.
fn linear(code: [u8; 3]) -> [f64; 3] {
    code.map(|c| srgb_to_linear(c as f32 / 255.0) as f64)
}

/// Mean beauty over the pixels whose centres fall in the world rectangle [x0, x1] × [y0, y1]
/// of an orthographic view whose window starts at (`left`, `top`) with `pixel` units per pixel.
fn mean_in(img: &Image, (left, top, pixel): (f64, f64, f64), (x0, x1, y0, y1): (f64, f64, f64, f64)) -> [f64; 3] {
    let mut sum = [0.0; 3];
    let mut n = 0;
    for py in 0..img.height {
        for px in 0..img.width {
            let (x, y) = (left + (px as f64 + 0.5) * pixel, top - (py as f64 + 0.5) * pixel);
            if (x0..=x1).contains(&x) && (y0..=y1).contains(&y) {
                let p = img.pixel("beauty", px, py);
                (0..3).for_each(|c| sum[c] += p[c] as f64);
                n += 1;
            }
        }
    }
    assert!(n >= 16, "region {x0}..{x1} x {y0}..{y1} covers only {n} pixels");
    sum.map(|s| s / n as f64)
}

fn assert_color(got: [f64; 3], code: [u8; 3], what: &str) {
    let want = linear(code);
    for c in 0..3 {
        assert!(
            (got[c] - want[c]).abs() <= 0.01 + 0.03 * want[c],
            "{what}: channel {c} is {:.4}, expected {:.4} (sRGB {code:?})",
            got[c],
            want[c]
        );
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn st_orientation_wrap_modes_and_srgb_decoding_match_the_specification() {
    // 280 x 100 pixels over 7 x 2.5 units: the window's top-left is (-3.5, 1.25).
    let report = render_fixture("textures/wrap_and_orientation.usda", &small(280, 100, 32)).await;
    assert_all_finite(&report.image);
    let view = (-3.5, 1.25, 0.025);
    let at = |rect| mean_in(&report.image, view, rect);
    // /World/Orientation: st (0, 0) is the image's bottom-left.
    assert_color(at((-3.1, -2.3, 0.1, 0.9)), TL, "orientation, top-left");
    assert_color(at((-2.1, -1.3, 0.1, 0.9)), TR, "orientation, top-right");
    assert_color(at((-3.1, -2.3, -0.9, -0.1)), BL, "orientation, bottom-left");
    assert_color(at((-2.1, -1.3, -0.9, -0.1)), BR, "orientation, bottom-right");
    // /World/BlackClamp: st from -0.5 to 1.5; black outside s in [0, 1], edge rows beyond t.
    assert_color(at((-0.95, -0.55, -0.9, 0.9)), BLACK, "wrapS black, left of the image");
    assert_color(at((0.55, 0.95, -0.9, 0.9)), BLACK, "wrapS black, right of the image");
    assert_color(at((-0.4, -0.1, 0.6, 0.95)), TL, "wrapT clamp above the image: its top row");
    assert_color(at((-0.4, -0.1, -0.95, -0.6)), BL, "wrapT clamp below the image: its bottom row");
    // /World/RepeatMirror: s repeats (right of the image is its left column again), t mirrors
    // (above the image is its top row again, below it its bottom row).
    assert_color(at((2.8, 3.1, 0.6, 0.95)), TL, "repeat right, mirror above");
    assert_color(at((1.3, 1.6, -0.95, -0.6)), BR, "repeat left, mirror below");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_usdz_package_supplies_its_own_texture() {
    // 64 x 64 pixels over 2.5 x 2.5 units, the quad spans [-1, 1]².
    let report = render_fixture("textures/packed.usdz", &small(64, 64, 16)).await;
    let view = (-1.25, 1.25, 2.5 / 64.0);
    let at = |rect| mean_in(&report.image, view, rect);
    assert_color(at((-0.9, -0.1, 0.1, 0.9)), TL, "packed, top-left");
    assert_color(at((0.1, 0.9, -0.9, -0.1)), BR, "packed, bottom-right");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_texture_crosses_the_wire_once_per_server() {
    let t = load("textures/wrap_and_orientation.usda");
    assert_eq!(t.textures.len(), 1, "three materials read one file");
    let hashes: Vec<String> = t.textures.keys().cloned().collect();
    let server = EmbeddedServer::start().await.unwrap();
    let mut first = Connection::connect(&server.url(), "first").await.unwrap();
    assert_eq!(first.missing_textures(hashes.clone()).await.unwrap(), hashes, "a new server holds nothing");
    first.sync_scene(&t).await.unwrap();
    // Another session on the same server finds it there and uploads nothing.
    let mut second = Connection::connect(&server.url(), "second").await.unwrap();
    assert!(second.missing_textures(hashes).await.unwrap().is_empty());
    let without_textures = tessera::sync::scene_sync(&t, |_| false);
    second.sync(without_textures).await.expect("the texture comes from the server's cache");
    let report = second.render(&small(28, 10, 4), |_| {}).await.unwrap();
    assert!(report.image.pixel("beauty", 3, 2)[0] > 0.3, "the top-left quadrant is red");
    server.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread")]
async fn missing_or_corrupt_texture_uploads_are_errors_naming_the_file() {
    let t = load("textures/wrap_and_orientation.usda");
    let server = EmbeddedServer::start().await.unwrap();
    let mut conn = Connection::connect(&server.url(), "e2e").await.unwrap();
    // Never uploaded: the error names the material, the node and the file.
    let e = conn.sync(tessera::sync::scene_sync(&t, |_| false)).await.unwrap_err().to_string();
    assert!(e.contains("/World/Looks/") && e.contains("/Texture") && e.contains("maps/quadrants.png"), "{e}");
    // Bytes that do not match their hash.
    let mut tampered = t.clone();
    let file = tampered.textures.values_mut().next().unwrap();
    let mut bytes = (*file.bytes).clone();
    bytes[40] ^= 0xff;
    file.bytes = std::sync::Arc::new(bytes);
    let e = conn.sync(tessera::sync::full_sync(&tampered)).await.unwrap_err().to_string();
    assert!(e.contains("maps/quadrants.png") && e.contains("do not hash"), "{e}");
    // Bytes that hash right but are no image.
    let mut garbage = t.clone();
    let (hash, mut file) = garbage.textures.pop_first().unwrap();
    file.bytes = std::sync::Arc::new(b"not a png".to_vec());
    let new_hash = tessera_server::textures::content_hash(&file.bytes);
    garbage.textures.insert(new_hash.clone(), file);
    for (_, net) in &mut garbage.materials {
        for n in &mut net.nodes {
            for v in n.parameters.values_mut() {
                if let render_core::material::ParamValue::Texture { hash: h, .. } = v
                    && *h == hash
                {
                    *h = new_hash.clone();
                }
            }
        }
    }
    let e = conn.sync(tessera::sync::full_sync(&garbage)).await.unwrap_err().to_string();
    assert!(e.contains("cannot decode 'maps/quadrants.png'"), "{e}");
    // The session still works.
    conn.sync_scene(&t).await.expect("a good upload after bad ones");
    server.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread")]
async fn texture_filtering_is_a_setting_the_render_reports() {
    // The checker plane at 1 spp: filtering reads coarse mips towards the horizon, so the far
    // half of the image is smoother (lower pixel-to-pixel contrast) than point sampling.
    let contrast = |report: &tessera::remote::RenderReport| {
        let img = &report.image;
        let mut sum = 0.0f64;
        for y in 0..img.height / 2 {
            for x in 1..img.width {
                sum += (img.pixel("beauty", x, y)[0] - img.pixel("beauty", x - 1, y)[0]).abs() as f64;
            }
        }
        sum
    };
    let on = render_fixture("textures/checker_plane.usda", &small(64, 48, 1)).await;
    let off_opts = tessera::remote::RenderOptions { texture_filtering: false, ..small(64, 48, 1) };
    let off = render_fixture("textures/checker_plane.usda", &off_opts).await;
    assert!(contrast(&on) < 0.5 * contrast(&off), "filtered {:.2} vs point-sampled {:.2}", contrast(&on), contrast(&off));
    assert!(off.started.warnings.iter().any(|w| w.contains("texture filtering off")), "{:?}", off.started.warnings);
    assert!(!on.started.warnings.iter().any(|w| w.contains("texture filtering")));
}

#[tokio::test(flavor = "multi_thread")]
async fn textured_emission_is_seen_per_texel() {
    // A black quad emitting the quadrant texture, alone: the camera sees the texels.
    let report = render_fixture("textures/emissive.usda", &small(64, 64, 16)).await;
    let view = (-1.25, 1.25, 2.5 / 64.0);
    let at = |rect| mean_in(&report.image, view, rect);
    assert_color(at((-0.9, -0.1, 0.1, 0.9)), TL, "emission, top-left");
    assert_color(at((0.1, 0.9, 0.1, 0.9)), TR, "emission, top-right");
    assert_color(at((-0.9, -0.1, -0.9, -0.1)), BL, "emission, bottom-left");
}

/// A UDIM set (`maps/udim_tile.<UDIM>.png`, tiles 1001, 1002 and 1011 of `UDIM_TILES` in
/// make_fixtures.py) over st 0..2: each unit square of texture space shows its own tile, with
/// no repeat of tile 1001 beyond it, and the square whose tile is absent (1012) the node's
/// fallback of 0.5.
#[tokio::test(flavor = "multi_thread")]
async fn a_udim_set_shows_each_tile_and_the_fallback_where_none_is() {
    let report = render_fixture("textures/udim.usda", &small(100, 100, 16)).await;
    assert!(report.started.warnings.is_empty(), "{:?}", report.started.warnings);
    let view = (-1.25, 1.25, 0.025);
    let at = |rect| mean_in(&report.image, view, rect);
    assert_color(at((-0.9, -0.1, -0.9, -0.1)), [200, 40, 40], "tile 1001, bottom-left");
    assert_color(at((0.1, 0.9, -0.9, -0.1)), [40, 200, 40], "tile 1002, bottom-right");
    assert_color(at((-0.9, -0.1, 0.1, 0.9)), [40, 40, 200], "tile 1011, top-left");
    let fallback = at((0.1, 0.9, 0.1, 0.9));
    // The fallback is linear: 0.5 exactly under the white dome.
    assert!(fallback.iter().all(|c| (c - 0.5).abs() < 1e-3), "tile 1012 is absent: {fallback:?}");
}

/// A MaterialX `image` whose `filename` names a UDIM set (`&lt;UDIM&gt;` in the XML) reads
/// the same three tiles, in order, each uploaded once; so does one naming the tiles Mudbox's
/// way (`&lt;UVTILE&gt;`: `u1_v1`, `u2_v1`, `u1_v2` are tiles 1001, 1002, 1011).
#[test]
fn a_materialx_image_reads_a_udim_set() {
    let udim: fn(u16) -> String = |tile| tile.to_string();
    let uvtile: fn(u16) -> String = |tile| format!("u{}_v{}", (tile - 1001) % 10 + 1, (tile - 1001) / 10 + 1);
    for (token, name) in [("&lt;UDIM&gt;", udim), ("&lt;UVTILE&gt;", uvtile)] {
        let dir = std::env::temp_dir().join(format!("tessera-mtlx-udim-{}-{}", name(1002), std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for tile in [1001, 1002, 1011] {
            let from = tessera_tests::fixture(&format!("textures/maps/udim_tile.{tile}.png"));
            std::fs::copy(from, dir.join(format!("tile.{}.png", name(tile)))).unwrap();
        }
        let doc = std::fs::read_to_string(tessera_tests::fixture("usd/materialx/materials.mtlx")).unwrap();
        let doc = doc.replace("../../textures/maps/checker.png", &format!("tile.{token}.png"));
        std::fs::write(dir.join("materials.mtlx"), doc).unwrap();
        std::fs::copy(tessera_tests::fixture("usd/materialx/materialx.usda"), dir.join("materialx.usda")).unwrap();
        let t = tessera::usd::load(&dir.join("materialx.usda")).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        let (_, checker) = t.materials.iter().find(|(p, _)| p == "/World/Looks/Checker").expect("the checker material");
        let udim = checker.nodes.iter().find_map(|n| match n.parameters.get("file") {
            Some(render_core::material::ParamValue::Udim { tiles, .. }) => Some(tiles.iter().map(|(tile, _)| *tile).collect::<Vec<_>>()),
            _ => None,
        });
        assert_eq!(udim, Some(vec![1001, 1002, 1011]), "{token}: {:?} {:?}", checker.nodes, t.warnings);
        assert_eq!(t.textures.len(), 3, "{token}: one upload per tile");
    }
}

/// Tiles past 1100 are not read (USD's range), and said by number.
#[test]
fn udim_tiles_past_1100_are_reported() {
    let dir = std::env::temp_dir().join(format!("tessera-udim-past-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for tile in [1001, 1105] {
        std::fs::copy(tessera_tests::fixture("textures/maps/udim_tile.1001.png"), dir.join(format!("t.{tile}.png"))).unwrap();
    }
    let usda = "#usda 1.0\ndef Material \"M\"\n{\n    token outputs:surface.connect = </M/S.outputs:surface>\n    def Shader \"S\"\n    {\n        \
                uniform token info:id = \"UsdPreviewSurface\"\n        color3f inputs:diffuseColor.connect = </M/T.outputs:rgb>\n        \
                token outputs:surface\n    }\n    def Shader \"T\"\n    {\n        uniform token info:id = \"UsdUVTexture\"\n        \
                asset inputs:file = @t.<UDIM>.png@\n        color3f outputs:rgb\n    }\n}\ndef Mesh \"Quad\" (prepend apiSchemas = \
                [\"MaterialBindingAPI\"])\n{\n    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]\n    int[] faceVertexCounts = [3]\n    \
                int[] faceVertexIndices = [0, 1, 2]\n    rel material:binding = </M>\n}\n";
    std::fs::write(dir.join("scene.usda"), usda).unwrap();
    let t = tessera::usd::load(&dir.join("scene.usda")).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(t.textures.len(), 1, "tile 1001 alone is read");
    assert!(t.warnings.iter().any(|w| w.contains("/M/T") && w.contains("past 1100 (1105)")), "{:?}", t.warnings);
}

/// A dome light cannot be a UDIM set: said, and its constant colour used.
#[test]
fn a_udim_set_on_a_dome_light_is_reported() {
    let tiles = tessera_tests::fixture("textures/maps/udim_tile.<UDIM>.png");
    let usda = format!("#usda 1.0\ndef DomeLight \"Sky\"\n{{\n    asset inputs:texture:file = @{}@\n}}\n", tiles.display());
    let t = tessera_tests::load_text("udim_dome", &usda);
    assert!(t.lights[0].1.texture.is_none());
    assert!(t.warnings.iter().any(|w| w.contains("/Sky") && w.contains("UDIM set")), "{:?}", t.warnings);
}

/// A file's `colorSpace` metadata decides its decoding where `sourceColorSpace` is `auto`
/// (or unauthored), as Hydra reads it; an authored `sourceColorSpace` wins; what the decoding
/// leaves out (another gamut) and names USD does not define are said.
#[test]
fn a_files_color_space_metadata_decides_its_decoding() {
    let cases = [
        ("raw", "", "raw", None),
        ("lin_rec709_scene", "", "raw", None),
        ("srgb_rec709_scene", "    token inputs:sourceColorSpace = \"auto\"\n", "sRGB", None),
        ("lin_ap1_scene", "", "raw", Some("primaries other than Rec.709's")),
        ("g22_rec709_scene", "", "sRGB", Some("a pure gamma curve")),
        ("g22_ap1_scene", "", "sRGB", Some("a pure gamma curve, decoded with sRGB's, and primaries")),
        ("raw", "    token inputs:sourceColorSpace = \"sRGB\"\n", "sRGB", None),
        ("acescg_typo", "", "auto", Some("not one USD names")),
    ];
    for (declared, authored, expected, said) in cases {
        let usda = format!(
            "#usda 1.0\ndef Shader \"T\"\n{{\n    uniform token info:id = \"UsdUVTexture\"\n    asset inputs:file = @q.png@ (\n        \
             colorSpace = \"{declared}\"\n    )\n{authored}}}\ndef Material \"M\"\n{{\n    token outputs:surface.connect = </S.outputs:surface>\n}}\n\
             def Shader \"S\"\n{{\n    uniform token info:id = \"UsdPreviewSurface\"\n    color3f inputs:diffuseColor.connect = </T.outputs:rgb>\n    \
             token outputs:surface\n}}\ndef Mesh \"Quad\" (prepend apiSchemas = [\"MaterialBindingAPI\"])\n{{\n    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]\n    \
             int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    rel material:binding = </M>\n}}\n"
        );
        let t = tessera_tests::load_text("color_space_metadata", &usda);
        let (_, net) = t.materials.iter().find(|(p, _)| p == "/M").expect("the material");
        let tex = net.nodes.iter().find(|n| n.path == "/T").expect("the texture node");
        let space = tex.parameters.get("sourceColorSpace");
        let want = (expected != "auto").then(|| render_core::material::ParamValue::String(expected.into()));
        assert_eq!(space.cloned().filter(|s| *s != render_core::material::ParamValue::String("auto".into())), want, "{declared}");
        let warned = t.warnings.iter().any(|w| w.contains("/T") && w.contains(&format!("colorSpace '{declared}'")));
        assert_eq!(warned, said.is_some(), "{declared}: {:?}", t.warnings);
        if let Some(said) = said {
            assert!(t.warnings.iter().any(|w| w.contains(said)), "{declared}: {:?}", t.warnings);
        }
    }
}

/// A texture whose file comes through the material's interface (a NodeGraph's input, itself
/// connected to the Material's) decodes by the `colorSpace` declared where the asset is: the
/// nearest interface input that carries one. The texture's own metadata, where it has any,
/// wins.
#[test]
fn an_interface_inputs_color_space_decides_the_files_decoding() {
    let stage = |material_meta: &str, graph_meta: &str, own: &str| {
        format!(
            "#usda 1.0\ndef Material \"M\"\n{{\n    asset inputs:tex = @q.png@ {material_meta}\n    \
             token outputs:surface.connect = </M/S.outputs:surface>\n    def NodeGraph \"G\"\n    {{\n        \
             asset inputs:tex = @q.png@ {graph_meta}\n        asset inputs:tex.connect = </M.inputs:tex>\n        \
             float3 outputs:rgb.connect = </M/G/T.outputs:rgb>\n        def Shader \"T\"\n        {{\n            \
             uniform token info:id = \"UsdUVTexture\"\n            asset inputs:file {own}\n            \
             asset inputs:file.connect = </M/G.inputs:tex>\n            float3 outputs:rgb\n        }}\n    }}\n    \
             def Shader \"S\"\n    {{\n        uniform token info:id = \"UsdPreviewSurface\"\n        \
             color3f inputs:diffuseColor.connect = </M/G.outputs:rgb>\n        token outputs:surface\n    }}\n}}\n\
             def Mesh \"Quad\" (prepend apiSchemas = [\"MaterialBindingAPI\"])\n{{\n    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]\n    \
             int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    rel material:binding = </M>\n}}\n"
        )
    };
    let raw = "(colorSpace = \"raw\")";
    let srgb = "(colorSpace = \"sRGB\")";
    let cases = [
        ("on the Material's input", stage(raw, "", ""), Some("raw")),
        ("on the NodeGraph's input, nearer", stage(srgb, raw, ""), Some("raw")),
        ("on the texture's own input", stage(raw, "", srgb), Some("sRGB")),
        ("nowhere", stage("", "", ""), None),
    ];
    for (where_, usda, expected) in cases {
        let t = tessera_tests::load_text("interface_color_space", &usda);
        let (_, net) = t.materials.iter().find(|(p, _)| p == "/M").expect("the material");
        let tex = net.nodes.iter().find(|n| n.path == "/M/G/T").expect("the texture node");
        let space =
            tex.parameters.get("sourceColorSpace").cloned().filter(|s| *s != render_core::material::ParamValue::String("auto".into()));
        assert_eq!(space, expected.map(|e| render_core::material::ParamValue::String(e.into())), "{where_}: {:?}", t.warnings);
    }
}

#[test]
fn light_sampling_reads_textured_emission_where_it_samples() {
    // A ceiling glowing 20x the quadrant texture (red and blue texels on -X, green and white on
    // +X) over a white floor: next-event estimation looks the emission up at each sampled
    // point, so it agrees with BSDF sampling (which sees the texels it hits) on each half of
    // the floor. With the texture's mean in light sampling the two would differ by side.
    use render_core::camera::Camera;
    use render_core::film::Aov;
    use render_core::integrator::{IntegratorSettings, LightStrategy};
    use render_core::render::{RenderSettings, render_to_framebuffer};
    use render_core::scene::{BlasCache, commit};
    let scene = commit(&load("textures/emissive_ceiling.usda").to_scene_desc(), &mut BlasCache::default()).unwrap();
    let camera = Camera::new(&scene.camera("").unwrap(), 48, 36);
    let halves = |strategy: LightStrategy, spp: u32| {
        let settings = RenderSettings {
            width: 48,
            height: 36,
            spp,
            integrator: IntegratorSettings { strategy, max_depth: 1, light_path_aovs: true, ..Default::default() },
            ..Default::default()
        };
        let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
        let floor = scene.prim_paths.iter().position(|p| p == "/World/Floor").unwrap() as f32 + 1.0;
        let (pos, beauty, ids) = (&fb.layers[&Aov::Position], &fb.layers[&Aov::Beauty], &fb.layers[&Aov::PrimId]);
        let mut sums = [[0.0f64; 2]; 2];
        for i in 0..ids.len() {
            if ids[i] == floor && pos[3 * i].abs() > 0.3 {
                let side = (pos[3 * i] > 0.0) as usize;
                sums[side][0] += beauty[4 * i + 1] as f64;
                sums[side][1] += 1.0;
            }
        }
        [sums[0][0] / sums[0][1], sums[1][0] / sums[1][1]]
    };
    let light = halves(LightStrategy::LightOnly, 256);
    let bsdf = halves(LightStrategy::BsdfOnly, 1024);
    for side in 0..2 {
        assert!((light[side] - bsdf[side]).abs() < 0.04 * bsdf[side], "side {side}: light sampling {light:?}, BSDF sampling {bsdf:?}");
    }
    assert!(light[1] > 1.5 * light[0], "the +X half of the floor, under the green and white texels, is greener: {light:?}");
}

#[test]
fn the_render_plan_names_the_texture_machinery_a_scene_needs() {
    use tessera::commands::render::explain_plan;
    use tessera_tests::fixture;
    let wrap = explain_plan(&fixture("textures/wrap_and_orientation.usda"), Default::default()).unwrap();
    assert!(wrap.contains("+ textures") && wrap.contains("/World/Looks/Plain"), "{wrap}");
    assert!(wrap.contains("- normal-maps") && wrap.contains("- environment-map"), "{wrap}");
    let bumpy = explain_plan(&fixture("hard/normal_map_furnace.usda"), Default::default()).unwrap();
    assert!(bumpy.contains("+ normal-maps"), "{bumpy}");
    let sky = explain_plan(&fixture("textures/dome.usda"), Default::default()).unwrap();
    assert!(sky.contains("+ environment-map") && sky.contains("/World/Sky"), "{sky}");
    let cornell = explain_plan(&fixture("cornell_box.usda"), Default::default()).unwrap();
    assert!(cornell.contains("- textures") && !cornell.contains("+ textures"), "{cornell}");
}

/// Hard case (issue 7), end to end: a 16 384 x 16 384 texture, the largest side accepted, goes
/// from the client through the server (uploaded, hash-checked, decoded, mip-mapped) onto a
/// quad seen head-on: its bright top-left 1/16 corner and grey rest land where st puts them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_16k_texture_renders_through_the_server() {
    let side = render_core::texture::MAX_TEXTURE_SIDE;
    let dir = std::env::temp_dir().join(format!("tessera-16k-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut img = image::GrayImage::from_pixel(side, side, image::Luma([64u8]));
    for y in 0..side / 4 {
        for x in 0..side / 4 {
            img.put_pixel(x, y, image::Luma([255]));
        }
    }
    img.save(dir.join("huge.png")).expect("writes the PNG");
    drop(img);
    // A unit quad facing +Z with st from its corners, under a white dome, seen by an
    // orthographic camera framing it exactly; raw colour space, no specular: pixel = texel.
    let usda = r#"#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "World"
{
    def DomeLight "Dome"
    {
        float inputs:intensity = 1
    }
    def Material "Huge"
    {
        token outputs:surface.connect = </World/Huge/Surface.outputs:surface>
        def Shader "Surface"
        {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor.connect = </World/Huge/Texture.outputs:rgb>
            float inputs:ior = 1
            token outputs:surface
        }
        def Shader "St"
        {
            uniform token info:id = "UsdPrimvarReader_float2"
            token inputs:varname = "st"
            float2 outputs:result
        }
        def Shader "Texture"
        {
            uniform token info:id = "UsdUVTexture"
            asset inputs:file = @huge.png@
            token inputs:sourceColorSpace = "raw"
            float2 inputs:st.connect = </World/Huge/St.outputs:result>
            color3f outputs:rgb
        }
    }
    def Mesh "Quad" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        rel material:binding = </World/Huge>
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (
            interpolation = "vertex"
        )
        uniform token subdivisionScheme = "none"
    }
    def Camera "Camera"
    {
        token projection = "orthographic"
        float horizontalAperture = 20
        float verticalAperture = 20
        double3 xformOp:translate = (0, 0, 5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
"#;
    std::fs::write(dir.join("huge.usda"), usda).unwrap();
    let translation = tessera::usd::load(&dir.join("huge.usda")).expect("reads");
    assert_eq!(translation.textures.len(), 1, "{:?}", translation.warnings);
    let server = EmbeddedServer::start().await.expect("server");
    let mut conn = Connection::connect(&server.url(), "16k").await.expect("connects");
    conn.sync_scene(&translation).await.expect("a 16k texture is within the server's limits");
    let report = conn.render(&small(32, 32, 4), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    std::fs::remove_dir_all(&dir).ok();
    let img = &report.image;
    assert_all_finite(img);
    // The quad fills the frame: pixel (x, y) covers st ((x + 0.5)/32, 1 − (y + 0.5)/32).
    let bright = img.pixel("beauty", 2, 2)[0];
    let grey = img.pixel("beauty", 20, 20)[0];
    assert!((bright - 1.0).abs() < 0.02, "top-left corner {bright}");
    assert!((grey - 64.0 / 255.0).abs() < 0.01, "grey rest {grey}");
}
