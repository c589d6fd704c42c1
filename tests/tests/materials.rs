//! The layered-material front-ends (`tessera:Metal`, `Refractive`, `SolidDielectric`,
//! `Fabric`, `Layer`) in whole renders: read from USD, planned, and energy-safe.

use tessera_tests::*;

/// Mean red value over the furnace sphere.
async fn furnace_mean(rel: &str) -> f64 {
    furnace_sphere_mean(rel, true).await
}

/// White metal over a white plastic with a clearcoat and a sheen (mask 0.5), and a closed
/// thin sheet, in the unit white furnace: no energy gain (the background is 1); the losses
/// are the coats' min rule over the specular lobes and the thin sheet's grazing angles
/// (docs/materials.md). Measured 2026-12-08: layered 0.976 (0.955 before the diffuse was
/// renormalised under the coats, which this bound fails), thin 0.983 (fixed seed); the lower
/// bounds sit 1.6% and 2% below, the sphere mean's sampling noise at this spp being well under
/// 1%.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn layered_coated_and_thin_materials_never_gain_energy_in_the_furnace() {
    let layered = furnace_mean("materials/furnace_layered.usda").await;
    println!("layered in the furnace: {layered}");
    assert!(layered <= 1.01 && layered > 0.96, "layered: {layered}");
    let thin = furnace_mean("materials/furnace_thin.usda").await;
    println!("thin sheet in the furnace: {thin}");
    assert!(thin <= 1.01 && thin > 0.963, "thin sheet: {thin}");
}

/// The showcase reads every native shader without a warning, and the plan names each effect
/// with the material that calls for it.
#[test]
fn showcase_plan_lists_every_effect_by_material() {
    let plan = tessera::commands::render::explain_plan(&fixture("materials/showcase.usda"), Default::default()).unwrap();
    assert!(!plan.contains("  ! "), "warnings: {plan}");
    for (effect, material) in [
        ("metal", "/World/Looks/Gold"),
        ("transmission", "/World/Looks/Glass"),
        ("thin-transmission", "/World/Looks/Pane"),
        ("clearcoat", "/World/Looks/Varnish"),
        ("sheen", "/World/Looks/Velvet"),
        ("fabric", "/World/Looks/Silk"),
        ("diffuse", "/World/Looks/DirtyGlass"),
    ] {
        let line = plan.lines().position(|l| l.contains(&format!("+ {effect} "))).unwrap_or_else(|| panic!("no {effect}: {plan}"));
        let prims = plan.lines().nth(line + 1).unwrap_or_default();
        assert!(prims.contains(material), "{effect} should name {material}: {plan}");
    }
    // The dirt's IOR stays with the dirt: the glass under it is still listed as refracting.
    let transmission = plan.lines().skip_while(|l| !l.contains("+ transmission ")).nth(1).unwrap();
    assert!(transmission.contains("/World/Looks/DirtyGlass"), "{plan}");
}

/// Subsurface scattering with a tiny mean free path behaves like its diffuse counterpart: a
/// sphere whose medium shows colour C = 0.5 (by the van de Hulst inversion) renders 0.5 in the
/// white furnace, as a Lambertian sphere of albedo 0.5 does, within the formula's accuracy.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn subsurface_with_a_tiny_mean_free_path_looks_like_its_diffuse_colour() {
    let mean = furnace_mean("materials/furnace_subsurface.usda").await;
    println!("subsurface sphere, C = 0.5, mfp = radius/1000: furnace mean {mean}");
    assert!((mean - 0.5).abs() < 0.03, "subsurface sphere renders {mean}, its diffuse counterpart 0.5");
    let plan = tessera::commands::render::explain_plan(&fixture("materials/furnace_subsurface.usda"), Default::default()).unwrap();
    assert!(plan.contains("+ subsurface") && plan.contains("/World/Looks/Skin"), "{plan}");
}

/// Relative RMS difference of the beauty of two renders of the same size.
fn relative_rms(a: &tessera::output::Image, b: &tessera::output::Image) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for y in 0..a.height {
        for x in 0..a.width {
            let (p, q) = (a.pixel("beauty", x, y), b.pixel("beauty", x, y));
            for c in 0..3 {
                diff += ((p[c] - q[c]) as f64).powi(2);
                norm += (p[c] as f64).powi(2);
            }
        }
    }
    (diff / norm.max(1e-30)).sqrt()
}

/// Glitter flakes stick to their object (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 3.5): the sphere, its light and
/// the camera moved together by a fraction of a flake cell render the same image, pixel for
/// pixel up to rounding, far closer than two renders of one scene with different seeds.
/// Flakes placed in world space would all have moved across the sphere.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn glitter_flakes_stay_on_a_moving_object() {
    let opts = small(128, 128, 16);
    let here = render_fixture("materials/glitter.usda", &opts).await.image;
    let moved = render_fixture("materials/glitter_moved.usda", &opts).await.image;
    let reseeded = render_fixture("materials/glitter.usda", &tessera::remote::RenderOptions { seed: 7, ..opts.clone() }).await.image;
    assert_all_finite(&here);
    let (motion, noise) = (relative_rms(&here, &moved), relative_rms(&here, &reseeded));
    println!("glitter moved with its rig: relative RMS {motion:.4}; another seed: {noise:.4}");
    assert!(motion < 0.25 * noise, "moving the rig changed the image by {motion}, more than a quarter of the noise {noise}");
}

/// White flakes over a white base in the unit furnace: no energy gain, and the plan names the
/// glitter with its material; the fixture reads without a warning. The flakes lose what they
/// reflect below the surface and what the binder masks (single scattering, as in the slides'
/// model: nothing bounces between flakes): with a spread of 0.5 over 80% coverage the sphere
/// renders 0.72 (0.723 measured 2026-12-02); the bound sits 0.02 below it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn glitter_never_gains_energy_and_is_planned() {
    let mean = furnace_mean("materials/furnace_glitter.usda").await;
    println!("white glitter over white in the furnace: mean {mean}");
    assert!(mean <= 1.01 && mean > 0.70, "glitter furnace: {mean}");
    let plan = tessera::commands::render::explain_plan(&fixture("materials/glitter.usda"), Default::default()).unwrap();
    assert!(!plan.contains("  ! "), "warnings: {plan}");
    let line = plan.lines().position(|l| l.contains("+ glitter ")).unwrap_or_else(|| panic!("no glitter: {plan}"));
    assert!(plan.lines().nth(line + 1).unwrap_or_default().contains("/World/Looks/Glitter"), "{plan}");
}

/// A sphere of `tessera:SolidDielectric` lit from the side by a sphere light and dimly by a
/// dome, seen by a pinhole camera on +Z: `scattering` is spliced into the shader. (A small
/// sun lights a medium through its rough boundary as fireflies, docs/materials.md.)
fn side_lit_sphere(scattering: &str) -> String {
    format!(
        r#"#usda 1.0
(
    upAxis = "Y"
)
def Material "Skin"
{{
    token outputs:surface.connect = </Skin/Shader.outputs:surface>
    def Shader "Shader"
    {{
        uniform token info:id = "tessera:SolidDielectric"
        color3f inputs:albedo = (0.8, 0.6, 0.4)
        float inputs:refractiveIndex = 1.4
        float inputs:roughness = 0.4
        {scattering}
        token outputs:surface
    }}
}}
def Sphere "Ball" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    double radius = 1
    rel material:binding = </Skin>
}}
def DomeLight "Sky"
{{
    float inputs:intensity = 0.3
}}
def SphereLight "Lamp"
{{
    bool inputs:normalize = 1
    float inputs:intensity = 20
    float inputs:radius = 0.7
    double3 xformOp:translate = (2.5, 0, 0.5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
{camera}"#,
        camera = camera_usda(50.0, 24.0)
    )
}

/// Renders `usda` and returns its beauty's mean per 8×8 block of pixels (red, green, blue).
async fn block_means(name: &str, usda: &str, opts: &tessera::remote::RenderOptions) -> Vec<f64> {
    let (server, mut conn) = session_with(&load_text(name, usda)).await;
    let img = conn.render(opts, |_| {}).await.expect("renders").image;
    server.stop().await.expect("server stops");
    assert_all_finite(&img);
    let mut blocks = Vec::new();
    for (by, bx, c) in block_channels(img.width / 8, img.height / 8) {
        let keep = |x: u32, y: u32| x / 8 == bx && y / 8 == by;
        blocks.push(mean_where(&img, "beauty", c, keep).0);
    }
    blocks
}

/// Every (block row, block column, channel).
fn block_channels(w: u32, h: u32) -> Vec<(u32, u32, usize)> {
    (0..h).flat_map(|y| (0..w).flat_map(move |x| (0..3).map(move |c| (y, x, c)))).collect()
}

/// `scatteringWeight` mixes the medium with a plain diffuse reflection as a mix of closures
/// does: on a lone convex sphere (so no path meets its outside twice) the image at weight
/// 0.4 is 0.4 × the image with all of the base a medium plus 0.6 × the image with none of it.
/// Weight 0 is the plain material to the bit. Tolerance: per 8×8 block, two seeds differ by
/// 2.4% RMS (all medium) and 1.7% (weight 0.4), and the mix came within 0.7% to 1.4% of its
/// ends' mix (measured 2026-12-06, three runs), so 3%. Reading the mix from inside the medium
/// too (the diffuse share reflecting back into it) measured 21% and fails; the ends differ by
/// 39%.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scattering_weight_mixes_the_medium_with_a_diffuse_reflection() {
    let opts = tessera::remote::RenderOptions { max_depth: 64, ..small(32, 32, 128) };
    let medium = |w: f32| format!("float inputs:scatteringRadius = 0.3\n        float inputs:scatteringWeight = {w}");
    let plain = block_means("sss_plain", &side_lit_sphere(""), &opts).await;
    let none = block_means("sss_none", &side_lit_sphere(&medium(0.0)), &opts).await;
    assert_eq!(plain, none, "weight 0 is the plain material");
    let all = block_means("sss_all", &side_lit_sphere(&medium(1.0)), &opts).await;
    let mixed = block_means("sss_mixed", &side_lit_sphere(&medium(0.4)), &opts).await;
    let expected: Vec<f64> = all.iter().zip(&plain).map(|(a, p)| 0.4 * a + 0.6 * p).collect();
    let rms = |a: &[f64], b: &[f64]| {
        let (d, n) = a.iter().zip(b).fold((0.0, 0.0), |(d, n), (x, y)| (d + (x - y).powi(2), n + y * y));
        (d / n).sqrt()
    };
    let (err, contrast) = (rms(&mixed, &expected), rms(&all, &plain));
    println!("weight 0.4 against the mix of its ends: relative RMS {err:.4}; the ends differ by {contrast:.4}");
    assert!(contrast > 0.05, "the medium should change the image: {contrast}");
    assert!(err < 0.03, "weight 0.4 is not the mix of its ends: {err}");
}

/// The layered shaders take a normal map as UsdPreviewSurface does: the tilted-normals
/// furnace sphere of `hard/normal_map_furnace.usda` shaded by a white `tessera:SolidDielectric`
/// without a specular renders what its UsdPreviewSurface form renders (the same Lambertian
/// lobe, so the same pixels). Before the map was read, the sphere rendered a flat 1.0 where
/// the map's 80° stripes give 0.85 (docs: tests/tests/hard.rs).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn layered_shaders_read_a_normal_map_as_the_preview_surface_does() {
    let text = std::fs::read_to_string(fixture("hard/normal_map_furnace.usda")).expect("fixture");
    let maps = fixture("hard/maps");
    let preview = text.replace("@maps/", &format!("@{}/", maps.display()));
    let native = preview
        .replace("\"UsdPreviewSurface\"", "\"tessera:SolidDielectric\"")
        .replace("inputs:diffuseColor", "inputs:albedo")
        .replace("float inputs:ior = 1", "float inputs:refractiveIndex = 1");
    let opts = small(32, 32, 16);
    let mut means = Vec::new();
    for (name, usda) in [("bumpy_preview", &preview), ("bumpy_native", &native)] {
        let t = load_text(name, usda);
        assert!(t.warnings.is_empty(), "{name}: {:?}", t.warnings);
        let (server, mut conn) = session_with(&t).await;
        let report = conn.render(&opts, |_| {}).await.expect("renders");
        server.stop().await.expect("stops");
        let ([mean, ..], n) = covered_rgb(&report);
        println!("{name}: mean {mean:.4} over {n} pixels");
        means.push(mean);
    }
    assert!(means[1] < 0.9, "the native shader ignored its normal map: {}", means[1]);
    assert!((means[0] - means[1]).abs() < 1e-6, "preview {} against native {}", means[0], means[1]);
}

/// A medium behind a refractive boundary still shows its colour: with a tiny mean free path,
/// colour 0.5 behind IOR 1.4 (roughness 0.4) renders in the white furnace what the same
/// plastic without a medium renders (Lambertian 0.5 under the specular). Measured
/// 2026-12-06: 0.512 against 0.523 (the 2% of van de Hulst's formula, as at IOR 1); without
/// Saunderson's boundary term (docs/materials.md) the medium rendered 0.331.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_medium_behind_a_refractive_boundary_keeps_its_colour() {
    let text = std::fs::read_to_string(fixture("materials/furnace_subsurface.usda")).expect("fixture");
    let behind = text.replace("float inputs:refractiveIndex = 1\n", "float inputs:refractiveIndex = 1.4\n float inputs:roughness = 0.4\n");
    assert_ne!(behind, text);
    let plain = behind.replace("float inputs:scatteringRadius = 0.001", "float inputs:scatteringRadius = 0");
    let opts = tessera::remote::RenderOptions { max_depth: 256, ..small(32, 32, 128) };
    let mut means = Vec::new();
    for (name, usda) in [("furnace_medium", &behind), ("furnace_plain", &plain)] {
        let (server, mut conn) = session_with(&load_text(name, usda)).await;
        let report = conn.render(&opts, |_| {}).await.expect("renders");
        server.stop().await.expect("stops");
        assert_all_finite(&report.image);
        means.push(covered_rgb(&report).0[0]);
    }
    println!("behind IOR 1.4 in the furnace: medium {:.4}, plain plastic {:.4}", means[0], means[1]);
    assert!((means[0] - means[1]).abs() < 0.03, "medium {} against plain {}", means[0], means[1]);
}
