//! The USD Working Group's test assets (a subset kept in `fixtures/usd-wg/`, Apache-2.0): each
//! renders, and a test checks the pixels that decide its feature against what the asset's
//! README and usdview screenshot show. Renders run in-process at the client's default camera
//! and light; regions are found through the primId AOV, so no test depends on framing.
//! `docs/conformance/` holds our renders beside the assets' screenshots.

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::render::{Framebuffer, RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, CommittedScene, commit};
use tessera::usd::Translation;
use tessera_tests::load;

struct Render {
    fb: Framebuffer,
    scene: CommittedScene,
}

impl Render {
    /// Mean beauty RGB over the pixels whose first hit is the prim at `path`, and their count.
    fn mean_of(&self, path: &str) -> ([f64; 3], usize) {
        let id = self.scene.prim_paths.iter().position(|p| p == path).unwrap_or_else(|| panic!("no prim {path}")) as f32 + 1.0;
        let (ids, beauty) = (&self.fb.layers[&Aov::PrimId], &self.fb.layers[&Aov::Beauty]);
        let mut sum = [0.0; 3];
        let mut n = 0;
        for (i, _) in ids.iter().enumerate().filter(|(_, v)| **v == id) {
            (0..3).for_each(|c| sum[c] += beauty[4 * i + c] as f64);
            n += 1;
        }
        (sum.map(|s| s / n.max(1) as f64), n)
    }

    /// Mean beauty RGB over the prim's pixels whose horizontal position within the prim's
    /// on-screen bounds (0 left, 1 right) `keep` accepts.
    fn mean_of_part(&self, path: &str, keep: impl Fn(f64) -> bool) -> [f64; 3] {
        let id = self.scene.prim_paths.iter().position(|p| p == path).expect("prim") as f32 + 1.0;
        let (ids, beauty, w) = (&self.fb.layers[&Aov::PrimId], &self.fb.layers[&Aov::Beauty], self.fb.width as usize);
        let xs: Vec<usize> = ids.iter().enumerate().filter(|(_, v)| **v == id).map(|(i, _)| i % w).collect();
        let (lo, hi) = (*xs.iter().min().expect("visible") as f64, *xs.iter().max().expect("visible") as f64);
        let mut sum = [0.0; 3];
        let mut n = 0;
        for (i, _) in ids.iter().enumerate().filter(|(i, v)| **v == id && keep(((i % w) as f64 - lo) / (hi - lo).max(1.0))) {
            (0..3).for_each(|c| sum[c] += beauty[4 * i + c] as f64);
            n += 1;
        }
        sum.map(|s| s / n.max(1) as f64)
    }

    /// Standard deviation of the luminance over the prim's pixels: how much pattern it shows.
    fn spread_of(&self, path: &str) -> f64 {
        let id = self.scene.prim_paths.iter().position(|p| p == path).expect("prim") as f32 + 1.0;
        let (ids, beauty) = (&self.fb.layers[&Aov::PrimId], &self.fb.layers[&Aov::Beauty]);
        let lum: Vec<f64> = ids
            .iter()
            .enumerate()
            .filter(|(_, v)| **v == id)
            .map(|(i, _)| 0.2126 * beauty[4 * i] as f64 + 0.7152 * beauty[4 * i + 1] as f64 + 0.0722 * beauty[4 * i + 2] as f64)
            .collect();
        let mean = lum.iter().sum::<f64>() / lum.len() as f64;
        (lum.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / lum.len() as f64).sqrt()
    }
}

impl Render {
    /// Mean |luminance difference| to `other` (the same view) over the prim's pixels,
    /// relative to their mean luminance.
    fn difference(&self, other: &Render, path: &str) -> f64 {
        let id = self.scene.prim_paths.iter().position(|p| p == path).expect("prim") as f32 + 1.0;
        let lum = |b: &[f32], i: usize| 0.2126 * b[4 * i] as f64 + 0.7152 * b[4 * i + 1] as f64 + 0.0722 * b[4 * i + 2] as f64;
        let (a, b) = (&self.fb.layers[&Aov::Beauty], &other.fb.layers[&Aov::Beauty]);
        let (mut diff, mut sum) = (0.0, 0.0);
        for (i, _) in self.fb.layers[&Aov::PrimId].iter().enumerate().filter(|(_, v)| **v == id) {
            diff += (lum(a, i) - lum(b, i)).abs();
            sum += lum(a, i);
        }
        diff / sum.max(1e-12)
    }
}

/// Renders a translation as the CLI would by default (white dome when unlit, the stage's
/// first camera or a framing one).
fn render(mut t: Translation, size: (u32, u32), spp: u32) -> Render {
    t.add_default_light();
    t.add_default_camera();
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    let camera = Camera::new(&scene.camera("").expect("camera"), size.0, size.1);
    let settings = RenderSettings { width: size.0, height: size.1, spp, ..Default::default() };
    let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
    assert!(fb.layers.values().flatten().all(|v| v.is_finite()), "every AOV finite");
    Render { fb, scene }
}

fn asset(rel: &str) -> Translation {
    load(&format!("usd-wg/{rel}"))
}

#[test]
fn texture_coordinates_put_each_corner_of_the_template_on_its_quad() {
    // README: four quads map the four corners of one image; usdview shows Top Left yellow,
    // Top Right orange, Bottom Left blue, Bottom Right green.
    let r = render(asset("TextureCoordinateTest/TextureCoordinateTest.usda"), (160, 160), 8);
    let quad = |name: &str| r.mean_of(&format!("/Asset/Scenes/Scene/{name}Obj/{name}Mesh/submesh"));
    let ([tr, tg, tb], n) = quad("TopLeft");
    assert!(n > 500 && tr > 2.0 * tb && tg > 2.0 * tb && (tr - tg).abs() < 0.3 * tr, "top left is yellow: {tr:.3} {tg:.3} {tb:.3}");
    let ([r_, g, b], _) = quad("TopRight");
    assert!(r_ > 2.0 * g && r_ > 3.0 * b, "top right is orange-red: {r_:.3} {g:.3} {b:.3}");
    let ([r_, g, b], _) = quad("BottomLeft");
    assert!(b > 2.0 * r_ && b > g, "bottom left is blue: {r_:.3} {g:.3} {b:.3}");
    let ([r_, g, b], _) = quad("BottomRight");
    assert!(g > 2.0 * r_ && g > 2.0 * b, "bottom right is green: {r_:.3} {g:.3} {b:.3}");
}

#[test]
fn three_normal_maps_with_their_scale_and_bias_shade_the_cubes_alike() {
    // README: "Whatever light you use, the three cubes should appear nearly the same": each
    // uses a different normal map (one with x reversed and z biased, one with y reversed)
    // undone by UsdUVTexture scale and bias.
    let cubes = ["RNormals", "RNormalsReversedX0BiasZ", "RNormalsReversedY"].map(|c| format!("/NormalsTextureBiasAndScale/Geom/{c}"));
    let t = asset("NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda");
    let r = render(t.clone(), (240, 120), 32);
    let stats: Vec<([f64; 3], f64)> = cubes.iter().map(|c| (r.mean_of(c).0, r.spread_of(c))).collect();
    for (c, (m, s)) in cubes.iter().zip(&stats) {
        assert!((m[0] - stats[0].0[0]).abs() < 0.03 * stats[0].0[0] + 0.005, "{c}: mean {:.4} vs {:.4}", m[0], stats[0].0[0]);
        assert!((s - stats[0].1).abs() < 0.1 * stats[0].1, "{c}: pattern {s:.4} vs {:.4}", stats[0].1);
    }
    // And the maps do something: without them each face shades flat, and the letters vanish.
    let mut flat = t;
    for (_, net) in &mut flat.materials {
        net.connections.retain(|c| c.downstream_input != "normal");
    }
    let f = render(flat, (240, 120), 32);
    for c in &cubes {
        let changed = r.difference(&f, c);
        assert!(changed > 0.05, "{c}: the normal map changes its pixels by only {:.1}%", 100.0 * changed);
    }
}

#[test]
fn texture_file_formats_read_alike() {
    // README: the same picture as PNG 8/16/32-bit RGB, PNG 8/16-bit grey and JPEG RGB / grey /
    // CMYK, side by side: the same content must render the same.
    let r = render(asset("TextureFileFormatTests/all_files.usda"), (320, 320), 8);
    let plane = |kind: &str, name: &str| r.mean_of(&format!("/Scene/{kind}/{name}/Geom/Plane"));
    let (png8, n) = plane("png", "png_rgb_8bit");
    assert!(n > 100, "the PNG plane is visible ({n} px)");
    let (png16, _) = plane("png", "png_rgb_16bit");
    for c in 0..3 {
        assert!((png16[c] - png8[c]).abs() < 0.02 * png8[c] + 0.003, "16-bit channel {c}: {:.4} vs 8-bit {:.4}", png16[c], png8[c]);
    }
    // The "32-bit" file is 16-bit RGBA holding linear values with no colour profile; `auto`
    // reads it as sRGB like the others, so it renders darker, as the usdrecord screenshot
    // shows it.
    let (png32, _) = plane("png", "png_rgb_32bit");
    assert!(png32[1] < 0.8 * png8[1] && png32[1] > 0.2 * png8[1], "32-bit {:.4} vs 8-bit {:.4}", png32[1], png8[1]);
    for (kind, name) in [("png", "png_grayscale_8bit"), ("png", "png_grayscale_16bit"), ("jpeg", "jpeg_grayscale_8bit")] {
        let (m, _) = plane(kind, name);
        // Within the tint of light bounced off the magenta frame around each card.
        assert!(
            (m[0] - m[1]).abs() < 0.03 * m[1] && (m[2] - m[1]).abs() < 0.03 * m[1] && (m[0] - m[2]).abs() < 0.005 * m[1],
            "{name} is grey: {m:?}"
        );
    }
    let (g8, _) = plane("png", "png_grayscale_8bit");
    let (g16, _) = plane("png", "png_grayscale_16bit");
    assert!((g8[1] - g16[1]).abs() < 0.02 * g8[1], "grey 8-bit {:.4} vs 16-bit {:.4}", g8[1], g16[1]);
    let (jpeg, _) = plane("jpeg", "jpeg_rgb_8bit");
    for c in 0..3 {
        assert!((jpeg[c] - png8[c]).abs() < 0.05 * png8[c] + 0.005, "JPEG channel {c}: {:.4} vs PNG {:.4}", jpeg[c], png8[c]);
    }
    // The pictures run red (left) to blue (right); a CMYK file read with inverted inks (the
    // classic Adobe-CMYK mistake) would run cyan to yellow. (Its colours differ from the RGB
    // file's in usdrecord too, so only the direction is checked.)
    for (kind, name) in [("png", "png_rgb_8bit"), ("jpeg", "jpeg_rgb_8bit"), ("jpeg", "jpeg_cmyk_8bit")] {
        let path = format!("/Scene/{kind}/{name}/Geom/Plane");
        let left = r.mean_of_part(&path, |fx| fx < 0.25);
        let right = r.mean_of_part(&path, |fx| fx > 0.75);
        assert!(left[0] > 1.5 * left[2] && right[2] > 1.5 * right[0], "{name}: left {left:?}, right {right:?}");
    }
}

#[test]
fn alpha_cutoffs_cut_where_the_threshold_says() {
    // README: the same alpha gradient texture with opacityThreshold 0.25 and 0.75 (and the
    // default 0.5): a higher threshold cuts more away; opaque and blended cards keep it all.
    let r = render(asset("AlphaBlendModeTest/AlphaBlendModeTest.usd"), (480, 240), 4);
    let covered = |name: &str| r.mean_of(&format!("/AlphaBlendModeTest/{name}")).1;
    let (c25, c50, c75, opaque) = (covered("TestCutoff25"), covered("TestCutoffDefault"), covered("TestCutoff75"), covered("TestOpaque"));
    assert!(opaque > 1000, "the opaque card covers {opaque} px");
    assert!(c25 > c50 && c50 > c75, "coverage falls with the threshold: 0.25 → {c25}, 0.5 → {c50}, 0.75 → {c75}");
    assert!((c25 as f64) < 0.98 * opaque as f64 && c75 > 0, "cut-outs cut part, not all: {c75}..{c25} of {opaque}");
}

#[test]
fn texture_offsets_pick_the_coloured_tiles() {
    // usdview and the glTF reference: the top row, offset in u, v and both, shows the green,
    // blue and cyan tiles of the atlas.
    let r = render(load("usd-wg/TextureTransformTest/TextureTransformTest.usd"), (240, 240), 8);
    let tile = |name: &str| r.mean_of(&format!("/TextureTransformTest/{name}")).0;
    let [r_, g, b] = tile("Offset_U");
    assert!(g > 2.0 * r_ && g > 2.0 * b, "Offset_U is green: {r_:.3} {g:.3} {b:.3}");
    let [r_, g, b] = tile("Offset_V");
    assert!(b > 2.0 * r_ && b > 2.0 * g, "Offset_V is blue: {r_:.3} {g:.3} {b:.3}");
    let [r_, g, b] = tile("Offset_UV");
    assert!(g > 2.0 * r_ && b > 2.0 * r_, "Offset_UV is cyan: {r_:.3} {g:.3} {b:.3}");
}

#[test]
fn textured_roughness_matches_constant_roughness() {
    // RoughnessTest: each row pairs a half whose roughness comes from a texture with a half of
    // the same constant roughness; lit by one distant light (a white dome would hide
    // roughness), the two halves of a row must look alike.
    let mut t = asset("RoughnessTest/RoughnessTest.usdz");
    let sun = render_core::light::LightDesc {
        kind: render_core::light::LightKind::Distant { angle_degrees: 2.0 },
        transform: glam::Affine3A::from_rotation_x(1.2),
        intensity: 3.0,
        exposure: 0.0,
        color: glam::Vec3::ONE,
        normalize: false,
        visible_to_camera: false,
        shaping: None,
        diffuse: 1.0,
        specular: 1.0,
        texture: None,
        motion: Vec::new(),
        light_link: None,
        shadow_link: None,
    };
    t.lights.push(("/Sun".into(), sun));
    let r = render(t, (240, 160), 32);
    for (tex, konst) in [
        ("Tex/Tex000/Mesh", "Const/Const000/Mesh_001"),
        ("Tex/Tex033/Mesh_002", "Const/Const033/Mesh_003"),
        ("Tex/Tex066/Mesh_004", "Const/Const066/Mesh_005"),
    ] {
        let (a, na) = r.mean_of(&format!("/Roughness/{tex}"));
        let (b, nb) = r.mean_of(&format!("/Roughness/{konst}"));
        assert!(na > 50 && nb > 50, "{tex}: {na} and {nb} px");
        assert!((a[1] - b[1]).abs() < 0.1 * b[1] + 0.01, "{tex} {:.4} vs {konst} {:.4}", a[1], b[1]);
    }
}

#[test]
fn spinning_pyramids_keep_the_creases_and_corners_they_author() {
    // README: Pyramid_EdgeCreases sharpens the outer edges (infinitely: sharpness 100),
    // Pyramid_CornerCreases two points (sharpness 25), Pyramid_NoCreases is the smooth
    // subdivision surface for comparison; the Storm screenshot shows a sharp-based, a
    // two-pointed and a rounded pyramid.
    let scene = "SubdivisionSurfaces/Creases_SpinningPyramids.usda";
    let t = asset(scene);
    let cage = tessera::usd::load_with(
        &tessera_tests::fixture(&format!("usd-wg/{scene}")),
        tessera::usd::LoadOptions { subdivision_level: 0, ..Default::default() },
    )
    .expect("reads");
    // The pyramids are instanceable: each is drawn through the prototype mesh it shares.
    let points = |t: &Translation, name: &str| -> Vec<glam::Vec3> {
        let proxy = t.native_instances.iter().find(|n| n.path == format!("/World/{name}/geo/shape")).expect("the pyramid");
        let prototype = &t.instancers[proxy.instancer].1.prototype;
        t.meshes.iter().find(|(p, _)| p == prototype).expect("its prototype").1.mesh.positions.clone()
    };
    let width =
        |p: &[glam::Vec3]| p.iter().map(|v| v.x).fold(f32::NEG_INFINITY, f32::max) - p.iter().map(|v| v.x).fold(f32::INFINITY, f32::min);
    let cage_width = width(&points(&cage, "Pyramid_NoCreases"));
    let (edges, none) = (width(&points(&t, "Pyramid_EdgeCreases")), width(&points(&t, "Pyramid_NoCreases")));
    assert!((edges - cage_width).abs() < 1e-4 * cage_width, "sharp outer edges keep the cage's width: {edges} vs {cage_width}");
    assert!(none < 0.9 * cage_width, "the smooth pyramid shrinks inside its cage: {none} vs {cage_width}");
    // The two sharp corners (cage points 0 and 2) stay where the cage puts them.
    let corner_cage = points(&cage, "Pyramid_CornerCreases");
    let cornered = points(&t, "Pyramid_CornerCreases");
    for k in [0, 2] {
        let nearest = cornered.iter().map(|p| p.distance(corner_cage[k])).fold(f32::INFINITY, f32::min);
        assert!(nearest < 1e-4, "corner {k} moved by {nearest}");
    }
    // On screen (primId names each pyramid by the instancer of its prototype), the
    // sharp-based pyramid covers more than the rounded one.
    let instancer = |t: &Translation, name: &str| {
        let proxy = t.native_instances.iter().find(|n| n.path == format!("/World/{name}/geo/shape")).expect("the pyramid");
        t.instancers[proxy.instancer].0.clone()
    };
    let (edge_key, none_key) = (instancer(&t, "Pyramid_EdgeCreases"), instancer(&t, "Pyramid_NoCreases"));
    let r = render(t, (240, 100), 2);
    let ((_, edge_px), (_, none_px)) = (r.mean_of(&edge_key), r.mean_of(&none_key));
    assert!(edge_px as f64 > 1.1 * none_px as f64, "edge-creased {edge_px} pixels, smooth {none_px}");
}

#[test]
fn the_materialx_plastic_sphere_is_blue() {
    // README: basic.usda binds USD_Plastic from usd_preview_surface_plastic.mtlx (MaterialX's
    // UsdPreviewSurface node, diffuse (0.105, 0.242, 0.818)); the screenshot shows a blue
    // plastic sphere.
    let t = asset("MaterialXTest/basic.usda");
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    let r = render(t, (96, 96), 16);
    let ([red, green, blue], n) = r.mean_of("/sphere");
    assert!(n > 1000 && blue > 2.0 * red && blue > 1.5 * green, "sphere mean {red:.3} {green:.3} {blue:.3} over {n}");
}
