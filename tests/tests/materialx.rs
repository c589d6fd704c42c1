//! MaterialX networks in their UsdShade form: Standard Surface, OpenPBR Surface and
//! MaterialX's UsdPreviewSurface mapped onto the renderer's shaders, with their texture nodes.

use render_core::material::{MaterialNetwork, ParamValue};
use tessera_tests::*;

/// A stage: a unit sphere bound to a Material whose `outputs:mtlx:surface` is a shader of
/// `id` with `inputs` (USD text), `extra` shader prims beside it, in a unit white dome, seen
/// from 4 units away.
fn stage(id: &str, inputs: &str, extra: &str) -> String {
    format!(
        r#"#usda 1.0
def Sphere "Ball" (
    prepend apiSchemas = ["MaterialBindingAPI"]
) {{
    color3f[] primvars:displayColor = [(0.1, 0.7, 0.2)]
    rel material:binding = </Looks/M>
}}
def Scope "Looks" {{
    def Material "M" {{
        token outputs:mtlx:surface.connect = </Looks/M/Surface.outputs:out>
        def Shader "Surface" {{
            uniform token info:id = "{id}"
            {inputs}
            token outputs:out
        }}
        {extra}
    }}
}}
def DomeLight "Dome" {{
    float inputs:intensity = 1
}}
{}"#,
        camera_usda(50.0, 36.0)
    )
}

fn network(t: &tessera::usd::Translation) -> &MaterialNetwork {
    &t.materials.iter().find(|(p, _)| p == "/Looks/M").expect("the material is read").1
}

fn surface_param<'a>(net: &'a MaterialNetwork, name: &str) -> Option<&'a ParamValue> {
    net.nodes.iter().find(|n| n.path == net.surface_node).and_then(|n| n.parameters.get(name))
}

#[test]
fn standard_surface_maps_onto_usd_preview_surface_by_meaning() {
    let t = load_text(
        "mtlx_standard",
        &stage(
            "ND_standard_surface_surfaceshader",
            "float inputs:base = 0.5\n color3f inputs:base_color = (0.2, 0.4, 0.6)\n float inputs:metalness = 0.3\n float inputs:specular_roughness = 0.25\n float inputs:coat = 0.5\n float inputs:emission = 2\n color3f inputs:emission_color = (1, 0.5, 0)",
            "",
        ),
    );
    let net = network(&t);
    let surface = net.nodes.iter().find(|n| n.path == net.surface_node).unwrap();
    assert_eq!(surface.node_type_id, "UsdPreviewSurface");
    // diffuse = base · base_color; emission = emission · emission_color; the rest by name.
    assert_eq!(surface_param(net, "diffuseColor"), Some(&ParamValue::Float3(glam::Vec3::new(0.1, 0.2, 0.3))));
    assert_eq!(surface_param(net, "emissiveColor"), Some(&ParamValue::Float3(glam::Vec3::new(2.0, 1.0, 0.0))));
    assert_eq!(surface_param(net, "metallic"), Some(&ParamValue::Float(0.3)));
    assert_eq!(surface_param(net, "roughness"), Some(&ParamValue::Float(0.25)));
    assert_eq!(surface_param(net, "clearcoat"), Some(&ParamValue::Float(0.5)));
    // Standard Surface's own default coat roughness (0.1), not UsdPreviewSurface's.
    assert_eq!(surface_param(net, "clearcoatRoughness"), Some(&ParamValue::Float(0.1)));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
}

/// OpenPBR's `base_diffuse_roughness` (and Standard Surface's `diffuse_roughness`) on an
/// opaque dielectric becomes tessera:SolidDielectric's `diffuseRoughness`, the rest as the
/// UsdPreviewSurface mapping says it; with metal beside it the roughness is reported, not
/// dropped in silence.
#[test]
fn diffuse_roughness_makes_a_rough_solid_dielectric() {
    let t = load_text(
        "mtlx_rough",
        &stage(
            "ND_open_pbr_surface_surfaceshader",
            "float inputs:base_diffuse_roughness = 0.6\n color3f inputs:base_color = (0.2, 0.4, 0.6)\n float inputs:specular_roughness = 0.25\n float inputs:coat_weight = 0.5",
            "",
        ),
    );
    let net = network(&t);
    let surface = net.nodes.iter().find(|n| n.path == net.surface_node).unwrap();
    assert_eq!(surface.node_type_id, "tessera:SolidDielectric");
    assert_eq!(surface_param(net, "diffuseRoughness"), Some(&ParamValue::Float(0.6)));
    assert_eq!(surface_param(net, "albedo"), Some(&ParamValue::Float3(glam::Vec3::new(0.2, 0.4, 0.6))));
    assert_eq!(surface_param(net, "roughness"), Some(&ParamValue::Float(0.25)));
    assert_eq!(surface_param(net, "clearcoat"), Some(&ParamValue::Float(0.5)));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);

    let inputs = "float inputs:diffuse_roughness = 0.6\n float inputs:metalness = 0.5";
    let t = load_text("mtlx_rough_metal", &stage("ND_standard_surface_surfaceshader", inputs, ""));
    let said: Vec<_> = t.warnings.iter().filter(|w| w.contains("/Looks/M/Surface") && w.contains("diffuse roughness")).collect();
    assert_eq!(said.len(), 1, "{:?}", t.warnings);
}

/// OpenPBR's fuzz is Zeltner et al.'s sheen, Standard Surface's sheen the Charlie sheen: on
/// an opaque dielectric each becomes tessera:SolidDielectric's input of that model, colour and
/// roughness with it. An input no mapping reads is reported by name, once.
#[test]
fn fuzz_and_sheen_keep_their_models() {
    let inputs = "float inputs:fuzz_weight = 0.7\n color3f inputs:fuzz_color = (0.9, 0.2, 0.1)\n float inputs:fuzz_roughness = 0.4";
    let t = load_text("mtlx_fuzz", &stage("ND_open_pbr_surface_surfaceshader", inputs, ""));
    let net = network(&t);
    assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, "tessera:SolidDielectric");
    assert_eq!(surface_param(net, "fuzz"), Some(&ParamValue::Float(0.7)));
    assert_eq!(surface_param(net, "fuzzColor"), Some(&ParamValue::Float3(glam::Vec3::new(0.9, 0.2, 0.1))));
    assert_eq!(surface_param(net, "fuzzRoughness"), Some(&ParamValue::Float(0.4)));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);

    let inputs = "float inputs:sheen = 0.5\n color3f inputs:sheen_color = (0.2, 0.3, 0.9)\n float inputs:coat_affect_color = 0.5";
    let t = load_text("mtlx_sheen", &stage("ND_standard_surface_surfaceshader", inputs, ""));
    let net = network(&t);
    assert_eq!(surface_param(net, "sheen"), Some(&ParamValue::Float(0.5)));
    assert_eq!(surface_param(net, "sheenColor"), Some(&ParamValue::Float3(glam::Vec3::new(0.2, 0.3, 0.9))));
    assert_eq!(surface_param(net, "sheenRoughness"), Some(&ParamValue::Float(0.3)), "Standard Surface's default");
    let said: Vec<_> = t.warnings.iter().filter(|w| w.contains("'coat_affect_color' is not carried")).collect();
    assert_eq!(said.len(), 1, "{:?}", t.warnings);
}

/// A thin film on an opaque dielectric or a full metal becomes the surface film of
/// tessera:SolidDielectric or tessera:Metal, whose interference replaces the specular's
/// Fresnel: OpenPBR's at full weight (its thickness in micrometres), Standard Surface's (in
/// nanometres); on glass, tessera:Principled's film on its specular and glass (since
/// 2026-12-08). A film at partial weight, on a half metal or on thin walls is reported once.
#[test]
fn a_thin_film_replaces_the_specular_fresnel() {
    let open_pbr = "float inputs:thin_film_weight = 1\n float inputs:thin_film_thickness = 0.45\n float inputs:thin_film_ior = 1.33";
    let open_pbr_metal = format!("float inputs:base_metalness = 1\n {open_pbr}");
    for (id, inputs, nm, ior, shader) in [
        ("ND_open_pbr_surface_surfaceshader", open_pbr, 450.0, 1.33, "tessera:SolidDielectric"),
        ("ND_standard_surface_surfaceshader", "float inputs:thin_film_thickness = 300", 300.0, 1.5, "tessera:SolidDielectric"),
        // Over a full metal (since 2026-12-07): tessera:Metal's film over its complex index.
        ("ND_open_pbr_surface_surfaceshader", &open_pbr_metal, 450.0, 1.33, "tessera:Metal"),
        (
            "ND_standard_surface_surfaceshader",
            "float inputs:metalness = 1\n float inputs:thin_film_thickness = 300",
            300.0,
            1.5,
            "tessera:Metal",
        ),
        (
            "ND_standard_surface_surfaceshader",
            "float inputs:transmission = 1\n float inputs:thin_film_thickness = 300",
            300.0,
            1.5,
            "tessera:Principled",
        ),
        (
            "ND_open_pbr_surface_surfaceshader",
            "float inputs:transmission_weight = 1\n float inputs:thin_film_weight = 1",
            500.0,
            1.4,
            "tessera:Principled",
        ),
    ] {
        let t = load_text("mtlx_film", &stage(id, inputs, ""));
        let net = network(&t);
        assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, shader, "{id}");
        assert!(matches!(surface_param(net, "filmThickness"), Some(ParamValue::Float(x)) if (x - nm).abs() < 1e-3), "{id}");
        assert_eq!(surface_param(net, "filmRefractiveIndex"), Some(&ParamValue::Float(ior)), "{id}");
        assert!(t.warnings.is_empty(), "{id}: {:?}", t.warnings);
    }
    for (id, inputs) in [
        ("ND_open_pbr_surface_surfaceshader", "float inputs:thin_film_weight = 0.5"),
        ("ND_open_pbr_surface_surfaceshader", "float inputs:base_metalness = 0.5\n float inputs:thin_film_weight = 1"),
        (
            "ND_standard_surface_surfaceshader",
            "float inputs:transmission = 1\n float inputs:thin_walled = 1\n float inputs:thin_film_thickness = 300",
        ),
    ] {
        let t = load_text("mtlx_film_lost", &stage(id, inputs, ""));
        assert!(surface_param(network(&t), "filmThickness").is_none(), "{inputs}");
        assert_eq!(t.warnings.iter().filter(|w| w.contains("a thin film is carried only")).count(), 1, "{inputs}: {:?}", t.warnings);
    }
}

/// `specular_color` tints an opaque dielectric's specular (tessera:SolidDielectric's
/// `specularColor`); on a metal it is reported.
#[test]
fn a_specular_colour_tints_the_dielectric_specular() {
    let t = load_text("mtlx_tint", &stage("ND_open_pbr_surface_surfaceshader", "color3f inputs:specular_color = (1, 0.5, 0.2)", ""));
    let net = network(&t);
    assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, "tessera:SolidDielectric");
    assert_eq!(surface_param(net, "specularColor"), Some(&ParamValue::Float3(glam::Vec3::new(1.0, 0.5, 0.2))));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    let inputs = "float inputs:metalness = 0.5\n color3f inputs:specular_color = (1, 0.5, 0.2)";
    let t = load_text("mtlx_tint_half_metal", &stage("ND_standard_surface_surfaceshader", inputs, ""));
    assert_eq!(t.warnings.iter().filter(|w| w.contains("specular_color is carried only")).count(), 1, "{:?}", t.warnings);
}

/// A coloured coat becomes Tessera's absorbing clearcoat at thickness 1 (a head-on round trip
/// tinted by the colour), on a dielectric or a metal; a clear coat stays UsdPreviewSurface's.
#[test]
fn a_coat_colour_is_the_clearcoats_absorption() {
    for (inputs, id) in [
        ("float inputs:coat_weight = 1\n color3f inputs:coat_color = (0.9, 0.5, 0.2)", "tessera:SolidDielectric"),
        ("float inputs:base_metalness = 1\n float inputs:coat_weight = 1\n color3f inputs:coat_color = (0.9, 0.5, 0.2)", "tessera:Metal"),
        ("float inputs:coat_weight = 1", "UsdPreviewSurface"),
    ] {
        let t = load_text("mtlx_coat", &stage("ND_open_pbr_surface_surfaceshader", inputs, ""));
        let net = network(&t);
        assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, id, "{inputs}");
        if id != "UsdPreviewSurface" {
            assert_eq!(surface_param(net, "clearcoatAttenuationColor"), Some(&ParamValue::Float3(glam::Vec3::new(0.9, 0.5, 0.2))));
            assert_eq!(surface_param(net, "clearcoatThickness"), Some(&ParamValue::Float(1.0)));
        }
        assert!(t.warnings.is_empty(), "{inputs}: {:?}", t.warnings);
    }
}

/// On a full metal `specular_color` is the edge colour: tessera:Metal's `edgeTint`, read as
/// the F82 tint for OpenPBR and as Gulbrandsen's edge tint for Standard Surface.
#[test]
fn a_metals_specular_colour_is_its_edge_tint() {
    for (id, metalness, f82) in
        [("ND_open_pbr_surface_surfaceshader", "base_metalness", true), ("ND_standard_surface_surfaceshader", "metalness", false)]
    {
        let inputs = format!(
            "float inputs:{metalness} = 1\n color3f inputs:base_color = (0.9, 0.6, 0.3)\n color3f inputs:specular_color = (1, 0.5, 0.2)"
        );
        let t = load_text("mtlx_edge", &stage(id, &inputs, ""));
        let net = network(&t);
        assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, "tessera:Metal", "{id}");
        assert_eq!(surface_param(net, "edgeTint"), Some(&ParamValue::Float3(glam::Vec3::new(1.0, 0.5, 0.2))));
        assert_eq!(surface_param(net, "f82"), Some(&ParamValue::Bool(f82)), "{id}");
        assert!(t.warnings.is_empty(), "{id}: {:?}", t.warnings);
    }
}

#[test]
fn open_pbr_textures_fold_constants_into_scale_and_bias() {
    // base_color = mix(image · 0.5, constant 0.2, mix 0.25) = 0.125 · image + 0.15, read
    // through a texcoord node; anisotropy makes it a tessera:Principled.
    let extra = r#"
        def Shader "Image" {
            uniform token info:id = "ND_image_color3"
            asset inputs:file = @missing.png@
            color3f inputs:default = (0.5, 0.5, 0.5)
            string inputs:uaddressmode = "clamp"
            float2 inputs:texcoord.connect = </Looks/M/Uv.outputs:out>
            color3f outputs:out
        }
        def Shader "Uv" {
            uniform token info:id = "ND_texcoord_vector2"
            float2 outputs:out
        }
        def Shader "Half" {
            uniform token info:id = "ND_multiply_color3FA"
            color3f inputs:in1.connect = </Looks/M/Image.outputs:out>
            float inputs:in2 = 0.5
            color3f outputs:out
        }
        def Shader "Grey" {
            uniform token info:id = "ND_constant_color3"
            color3f inputs:value = (0.2, 0.2, 0.2)
            color3f outputs:out
        }
        def Shader "Mix" {
            uniform token info:id = "ND_mix_color3"
            color3f inputs:fg.connect = </Looks/M/Half.outputs:out>
            color3f inputs:bg.connect = </Looks/M/Grey.outputs:out>
            float inputs:mix = 0.25
            color3f outputs:out
        }
        def Shader "Noise" {
            uniform token info:id = "ND_noise3d_float"
            float outputs:out
        }"#;
    let t = load_text(
        "mtlx_open_pbr",
        &stage(
            "ND_open_pbr_surface_surfaceshader",
            "color3f inputs:base_color.connect = </Looks/M/Mix.outputs:out>\n float inputs:specular_roughness_anisotropy = 0.5\n float inputs:specular_roughness.connect = </Looks/M/Noise.outputs:out>",
            extra,
        ),
    );
    let net = network(&t);
    let surface = net.nodes.iter().find(|n| n.path == net.surface_node).unwrap();
    // Anisotropic: Tessera's own dielectric, whose frame follows the texture coordinates.
    assert_eq!(surface.node_type_id, "tessera:SolidDielectric");
    assert_eq!(surface_param(net, "stTangent"), Some(&ParamValue::Float(1.0)));
    let c = net.connections.iter().find(|c| c.downstream_input == "albedo").expect("albedo is textured");
    assert_eq!(c.upstream_output, "rgb");
    let tex = net.nodes.iter().find(|n| n.path == c.upstream_node).unwrap();
    assert_eq!(tex.node_type_id, "UsdUVTexture");
    assert_eq!(tex.parameters.get("scale"), Some(&ParamValue::Float4(glam::Vec4::new(0.125, 0.125, 0.125, 0.125))));
    let bias = match tex.parameters.get("bias") {
        Some(ParamValue::Float4(b)) => *b,
        other => panic!("{other:?}"),
    };
    assert!((bias.truncate() - glam::Vec3::splat(0.15)).length() < 1e-6, "{bias}");
    assert_eq!(tex.parameters.get("wrapS"), Some(&ParamValue::String("clamp".into())));
    assert!(net.connections.iter().any(|k| k.downstream_node == tex.path && k.downstream_input == "st"), "read through st");
    // The noise is not mapped: said once, by node path, and roughness keeps OpenPBR's 0.3
    // (narrowed for the anisotropy 0.5: 0.3 · (2 · 0.5 / 1.25)^¼).
    assert_eq!(t.warnings.iter().filter(|w| w.contains("/Looks/M/Noise") && w.contains("ND_noise3d_float")).count(), 1, "{:?}", t.warnings);
    assert_eq!(surface_param(net, "roughness"), Some(&ParamValue::Float(0.3 * 0.8f32.powf(0.25))));
}

fn float_param(net: &MaterialNetwork, name: &str) -> f32 {
    match surface_param(net, name) {
        Some(ParamValue::Float(v)) => *v,
        other => panic!("{name}: {other:?}"),
    }
}

/// Anisotropy keeps each specification's αx and αy (Tessera's GGX takes Disney's mapping:
/// αy/αx = 1 − 0.9·anisotropic, √(αx·αy) = roughness²), runs along the texture coordinates'
/// s (MaterialX's default tangent) and turns by Standard Surface's `specular_rotation`.
#[test]
fn anisotropy_keeps_each_specifications_stretch_and_runs_along_the_texture_coordinates() {
    use render_core::bsdf::microfacet::Ggx;
    let alphas = |net: &MaterialNetwork| {
        let g = Ggx::from_roughness(float_param(net, "roughness"), float_param(net, "anisotropy"));
        (g.ax, g.ay)
    };
    let (r, a) = (0.5f32, 0.6f32);
    // Standard Surface (MaterialX's roughness_anisotropy): αx = r²/√(1 − a), αy = r²·√(1 − a).
    let inputs = format!(
        "float inputs:metalness = 1\n float inputs:specular_roughness = {r}\n float inputs:specular_anisotropy = {a}\n float inputs:specular_rotation = 0.125"
    );
    let t = load_text("mtlx_aniso_std", &stage("ND_standard_surface_surfaceshader", &inputs, ""));
    let net = network(&t);
    assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, "tessera:Metal");
    let (ax, ay) = alphas(net);
    assert!((ax - r * r / (1.0 - a).sqrt()).abs() < 1e-6 && (ay - r * r * (1.0 - a).sqrt()).abs() < 1e-6, "{ax} {ay}");
    assert_eq!(float_param(net, "anisotropyRotation"), 0.125);
    assert_eq!(float_param(net, "stTangent"), 1.0);
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    // OpenPBR (open_pbr_anisotropy): αx = r²·√(2/(1 + (1 − a)²)), αy = (1 − a)·αx.
    let inputs = format!(
        "float inputs:base_metalness = 1\n float inputs:specular_roughness = {r}\n float inputs:specular_roughness_anisotropy = {a}"
    );
    let t = load_text("mtlx_aniso_openpbr", &stage("ND_open_pbr_surface_surfaceshader", &inputs, ""));
    let net = network(&t);
    let (ax, ay) = alphas(net);
    let expected = r * r * (2.0 / (1.0 + (1.0 - a) * (1.0 - a))).sqrt();
    assert!((ax - expected).abs() < 1e-6 && (ay - (1.0 - a) * expected).abs() < 1e-6, "{ax} {ay}");
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    // Beyond Tessera's 10:1 the stretch stops there, said.
    let t = load_text(
        "mtlx_aniso_max",
        &stage("ND_standard_surface_surfaceshader", "float inputs:metalness = 1\n float inputs:specular_anisotropy = 0.95", ""),
    );
    assert_eq!(float_param(network(&t), "anisotropy"), 1.0);
    assert!(t.warnings.iter().any(|w| w.contains("specular anisotropy 0.95 is rendered at 0.9")), "{:?}", t.warnings);
    // An authored tangent is not read: said.
    let t = load_text(
        "mtlx_aniso_tangent",
        &stage(
            "ND_open_pbr_surface_surfaceshader",
            "float inputs:specular_roughness_anisotropy = 0.5\n vector3f inputs:geometry_tangent = (0, 1, 0)",
            "",
        ),
    );
    assert!(t.warnings.iter().any(|w| w.contains("geometry_tangent")), "{:?}", t.warnings);
    // On glass (tessera:Principled) the frame is the default one: said.
    let t = load_text(
        "mtlx_aniso_glass",
        &stage("ND_standard_surface_surfaceshader", "float inputs:transmission = 1\n float inputs:specular_anisotropy = 0.5", ""),
    );
    assert!(t.warnings.iter().any(|w| w.contains("runs around the object's up axis, unturned")), "{:?}", t.warnings);
}

#[test]
fn an_unmappable_surface_falls_back_to_display_color_said_once() {
    let t = load_text("mtlx_unknown", &stage("ND_gooch_surfaceshader", "", ""));
    let warnings: Vec<_> = t.warnings.iter().filter(|w| w.contains("ND_gooch_surfaceshader")).collect();
    assert_eq!(warnings.len(), 1, "{:?}", t.warnings);
    assert!(warnings[0].contains("displayColor"));
    let (_, ball) = t.meshes.iter().find(|(p, _)| p == "/Ball").unwrap();
    assert_ne!(ball.material, "/Looks/M");
    let (_, shown) = t.materials.iter().find(|(p, _)| *p == ball.material).expect("a displayColor material");
    assert_eq!(surface_param(shown, "diffuseColor"), Some(&ParamValue::Float3(glam::Vec3::new(0.1, 0.7, 0.2))));
}

/// Mean radiance of the sphere in the unit white dome.
async fn furnace(id: &str, inputs: &str) -> f64 {
    let t = load_text("mtlx_furnace", &stage(id, inputs, ""));
    let (server, mut conn) = session_with(&t).await;
    // Deep paths, as tests/tests/energy.rs: light crosses a glass sphere many times.
    let opts = tessera::remote::RenderOptions { max_depth: 64, ..small(48, 48, 64) };
    let report = conn.render(&opts, |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    let img = &report.image;
    assert_all_finite(img);
    mean_where(img, "beauty", 0, |x, y| img.pixel("beauty", x, y)[3] == 1.0).0
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_lobe_family_keeps_its_energy_in_the_furnace() {
    const OPEN_PBR: &str = "ND_open_pbr_surface_surfaceshader";
    const STANDARD: &str = "ND_standard_surface_surfaceshader";
    // White, non-absorbing lobes reflect (or pass) everything. Bounds: compensated metal
    // and rough glass are within 1% and 2% of 1 in docs/materials.md's probes; Disney's
    // diffuse (a specular weight of 0 selects tessera:Principled) measures 0.987 here; a
    // dielectric coat or specular over a white base may lose a few percent to the layering
    // (measured 0.967 and 0.999) but must gain nothing beyond the noise (~0.3% at 64 spp).
    let cases = [
        (
            "open_pbr metal",
            OPEN_PBR,
            "color3f inputs:base_color = (1, 1, 1)\n float inputs:base_metalness = 1\n float inputs:specular_roughness = 0.5",
            0.99,
            1.01,
        ),
        ("open_pbr rough glass", OPEN_PBR, "float inputs:transmission_weight = 1\n float inputs:specular_roughness = 0.3", 0.98, 1.02),
        ("open_pbr smooth glass", OPEN_PBR, "float inputs:transmission_weight = 1\n float inputs:specular_roughness = 0", 0.99, 1.01),
        ("open_pbr diffuse", OPEN_PBR, "color3f inputs:base_color = (1, 1, 1)\n float inputs:specular_weight = 0", 0.97, 1.01),
        (
            "open_pbr coated diffuse",
            OPEN_PBR,
            "color3f inputs:base_color = (1, 1, 1)\n float inputs:coat_weight = 1\n float inputs:coat_roughness = 0.2",
            0.94,
            1.005,
        ),
        (
            "standard metal",
            STANDARD,
            "float inputs:base = 1\n float inputs:metalness = 1\n float inputs:specular_roughness = 0.5",
            0.99,
            1.01,
        ),
        ("standard plastic", STANDARD, "float inputs:base = 1", 0.97, 1.005),
        // EON keeps a white rough diffuse whole (exactly, bsdf::oren_nayar); under a specular
        // it couples as the Lambertian base does.
        (
            "open_pbr rough diffuse",
            OPEN_PBR,
            "color3f inputs:base_color = (1, 1, 1)\n float inputs:base_diffuse_roughness = 1\n float inputs:specular_ior = 1",
            0.99,
            1.01,
        ),
        ("standard rough plastic", STANDARD, "float inputs:base = 1\n float inputs:diffuse_roughness = 1", 0.97, 1.005),
        // Fuzz over a white base takes from it what it reflects at the view (OpenPBR's albedo
        // scaling, bsdf::coat): measured 0.9999 (0.939 under the coats' min rule).
        (
            "open_pbr fuzz",
            OPEN_PBR,
            "color3f inputs:base_color = (1, 1, 1)\n float inputs:fuzz_weight = 1\n float inputs:specular_ior = 1",
            0.99,
            1.01,
        ),
    ];
    for (name, id, inputs, lo, hi) in cases {
        let mean = furnace(id, inputs).await;
        println!("{name}: {mean:.4}");
        assert!(mean > lo && mean < hi, "{name}: furnace mean {mean}, expected {lo}..{hi}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_referenced_mtlx_document_supplies_its_materials() {
    // fixtures/usd/materialx/materialx.usda references materials.mtlx for /World/Looks/Gold
    // (Standard Surface) and /World/Looks/Checker (OpenPBR, an image × 0.9 in a nodegraph).
    let t = load("usd/materialx/materialx.usda");
    assert!(!t.warnings.iter().any(|w| w.contains(".mtlx") || w.contains("not a Material prim")), "{:?}", t.warnings);
    let net = |p: &str| &t.materials.iter().find(|(m, _)| m == p).unwrap_or_else(|| panic!("{p} read")).1;
    let gold = net("/World/Looks/Gold");
    assert_eq!(surface_param(gold, "diffuseColor"), Some(&ParamValue::Float3(glam::Vec3::new(0.944, 0.776, 0.373))));
    assert_eq!(surface_param(gold, "metallic"), Some(&ParamValue::Float(1.0)));
    let checker = net("/World/Looks/Checker");
    let tex = checker.nodes.iter().find(|n| n.node_type_id == "UsdUVTexture").expect("the image");
    assert!(
        matches!(tex.parameters.get("file"), Some(ParamValue::Texture { .. })),
        "the image file is read: {:?}",
        tex.parameters.get("file")
    );
    assert_eq!(tex.parameters.get("scale"), Some(&ParamValue::Float4(glam::Vec4::new(0.9, 0.9, 0.9, 1.0))), "colour × colour leaves alpha");
    assert_eq!(tex.parameters.get("sourceColorSpace"), Some(&ParamValue::String("sRGB".into())), "the file's colorspace");
    let authored: Vec<&str> = t.materialx_surfaces.iter().map(|(_, id)| id.as_str()).collect();
    assert!(authored.contains(&"ND_standard_surface_surfaceshader") && authored.contains(&"ND_open_pbr_surface_surfaceshader"));
    // The gold ball (left) renders gold under the distant light.
    let (server, mut conn) = session_with(&t).await;
    let report = conn.render(&small(96, 48, 16), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    assert_all_finite(&report.image);
    // The gold ball covers about x 30..40, y 20..28 of the 96×48 frame (the camera's 36 mm
    // square aperture, fitted vertically).
    let img = &report.image;
    let on_gold = |x: u32, y: u32| (28..42).contains(&x) && (18..30).contains(&y) && img.pixel("beauty", x, y)[3] == 1.0;
    let ((r, n), (b, _)) = (mean_where(img, "beauty", 0, on_gold), mean_where(img, "beauty", 2, on_gold));
    assert!(n > 20 && r > 1.5 * b, "gold: red {r:.3}, blue {b:.3} over {n} pixels");
}

#[test]
fn a_missing_or_broken_mtlx_document_is_reported_and_display_color_shown() {
    let t = load_text(
        "mtlx_missing",
        r#"#usda 1.0
def Sphere "Ball" (
    prepend apiSchemas = ["MaterialBindingAPI"]
) {
    color3f[] primvars:displayColor = [(0.1, 0.7, 0.2)]
    rel material:binding = </M>
}
def Material "M" (
    prepend references = @./nowhere.mtlx@</MaterialX/Materials/M>
) {
}
"#,
    );
    let said: Vec<_> = t.warnings.iter().filter(|w| w.contains("nowhere.mtlx")).collect();
    assert_eq!(said.len(), 1, "{:?}", t.warnings);
    assert!(said[0].contains("/M") && said[0].contains("displayColor"), "{}", said[0]);
    let (_, ball) = t.meshes.iter().find(|(p, _)| p == "/Ball").unwrap();
    assert_ne!(ball.material, "/M");
}

/// Subsurface scattering maps onto `tessera:SolidDielectric`'s random walk, by meaning: the
/// mean free path per channel is Standard Surface's radius × scale (OpenPBR's radius × its
/// colour scale), written as the longest channel and each channel's share of it; the weight
/// becomes `scatteringWeight`; the medium's colour is `subsurface_color`, mixed with the base
/// colour by the weight where the weight is partial. A metal (no medium under it here) keeps
/// the diffuse reading, said once.
#[test]
fn subsurface_maps_onto_a_scattering_medium() {
    const STANDARD: &str = "ND_standard_surface_surfaceshader";
    let v3 = |x, y, z| Some(ParamValue::Float3(glam::Vec3::new(x, y, z)));
    let t = load_text(
        "mtlx_sss_standard",
        &stage(
            STANDARD,
            "float inputs:subsurface = 1\n color3f inputs:subsurface_color = (0.9, 0.5, 0.3)\n color3f inputs:subsurface_radius = (1, 0.5, 0.25)\n float inputs:subsurface_scale = 0.2\n float inputs:subsurface_anisotropy = 0.3\n float inputs:coat = 0.4",
            "",
        ),
    );
    let net = network(&t);
    assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, "tessera:SolidDielectric");
    let param = |name| surface_param(net, name).cloned();
    assert_eq!(param("albedo"), v3(0.9, 0.5, 0.3));
    assert_eq!(param("scatteringRadius"), Some(ParamValue::Float(0.2)));
    assert_eq!(param("scatteringColor"), v3(1.0, 0.5, 0.25));
    assert_eq!(param("scatteringWeight"), Some(ParamValue::Float(1.0)));
    assert_eq!(param("scatteringAnisotropy"), Some(ParamValue::Float(0.3)));
    // Standard Surface's own defaults: specular IOR 1.5, roughness 0.2, coat IOR 1.5.
    assert_eq!(param("refractiveIndex"), Some(ParamValue::Float(1.5)));
    assert_eq!(param("roughness"), Some(ParamValue::Float(0.2)));
    assert_eq!(param("clearcoat"), Some(ParamValue::Float(0.4)));
    assert_eq!(param("clearcoatRefractiveIndex"), Some(ParamValue::Float(1.5)));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);

    // OpenPBR at half weight with its defaults: base and subsurface colours 0.8 mix to 0.8,
    // radius 1 × (1, 0.5, 0.25), coat IOR 1.6.
    let t = load_text(
        "mtlx_sss_open_pbr",
        &stage(
            "ND_open_pbr_surface_surfaceshader",
            "float inputs:subsurface_weight = 0.5\n color3f inputs:base_color = (0.4, 0.4, 0.4)",
            "",
        ),
    );
    let net = network(&t);
    let param = |name| surface_param(net, name).cloned();
    let albedo = match param("albedo") {
        Some(ParamValue::Float3(c)) => c,
        other => panic!("{other:?}"),
    };
    assert!((albedo - glam::Vec3::splat(0.6)).abs().max_element() < 1e-6, "half of 0.4 and half of 0.8: {albedo}");
    assert_eq!(param("scatteringRadius"), Some(ParamValue::Float(1.0)));
    assert_eq!(param("scatteringColor"), v3(1.0, 0.5, 0.25));
    assert_eq!(param("scatteringWeight"), Some(ParamValue::Float(0.5)));
    assert_eq!(param("clearcoatRefractiveIndex"), Some(ParamValue::Float(1.6)));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);

    // A metal with subsurface: no medium, said once.
    let t = load_text("mtlx_sss_metal", &stage(STANDARD, "float inputs:subsurface = 1\n float inputs:metalness = 0.5", ""));
    let net = network(&t);
    assert_eq!(net.nodes.iter().find(|n| n.path == net.surface_node).unwrap().node_type_id, "UsdPreviewSurface");
    assert_eq!(t.warnings.iter().filter(|w| w.contains("/Looks/M/Surface") && w.contains("subsurface")).count(), 1, "{:?}", t.warnings);
}

/// A MaterialX subsurface sphere whose medium shows 0.5 behind an index-matched boundary
/// renders 0.5 in the white furnace, as `tessera:SolidDielectric` does
/// (`subsurface_with_a_tiny_mean_free_path_looks_like_its_diffuse_colour` in materials.rs:
/// within the van de Hulst formula's 2%, plus the noise).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_materialx_subsurface_sphere_keeps_its_colour_in_the_furnace() {
    let mean = furnace(
        "ND_open_pbr_surface_surfaceshader",
        "float inputs:subsurface_weight = 1\n color3f inputs:subsurface_color = (0.5, 0.5, 0.5)\n float inputs:subsurface_radius = 0.001\n float inputs:specular_ior = 1",
    )
    .await;
    println!("OpenPBR subsurface, colour 0.5, mfp 0.001: furnace mean {mean:.4}");
    assert!((mean - 0.5).abs() < 0.03, "{mean}");
}

/// A `tiledimage` places its image as MaterialX's own graph for it does, (texcoord · uvtiling −
/// uvoffset) / realworldimagesize · realworldtilesize, repeating: a `UsdTransform2d` of that
/// scale and translation between the coordinates and the texture. Before, any tiling other
/// than 1 was reported and left out.
#[test]
fn a_tiled_image_is_placed_by_its_tiling_offset_and_sizes() {
    let extra = r#"
        def Shader "Tiles" {
            uniform token info:id = "ND_tiledimage_color3"
            asset inputs:file = @missing.png@
            float2 inputs:uvtiling = (2, 3)
            float2 inputs:uvoffset = (0.5, 0.25)
            float2 inputs:realworldimagesize = (2, 2)
            float2 inputs:realworldtilesize = (1, 4)
            color3f outputs:out
        }"#;
    let t = load_text(
        "mtlx_tiled",
        &stage("ND_standard_surface_surfaceshader", "color3f inputs:base_color.connect = </Looks/M/Tiles.outputs:out>", extra),
    );
    let net = network(&t);
    let node = |path: &str| net.nodes.iter().find(|n| n.path == path).unwrap_or_else(|| panic!("{path}: {:?}", net.nodes));
    let upstream = |node: &str, input: &str| {
        net.connections.iter().find(|c| c.downstream_node == node && c.downstream_input == input).map(|c| c.upstream_node.clone())
    };
    let texture = upstream(&net.surface_node, "diffuseColor").expect("the base colour is textured");
    assert_eq!(node(&texture).node_type_id, "UsdUVTexture");
    assert_eq!(node(&texture).parameters.get("wrapS"), Some(&ParamValue::String("repeat".into())));
    let placement = upstream(&texture, "st").expect("st is connected");
    let p = node(&placement);
    assert_eq!(p.node_type_id, "UsdTransform2d");
    // k = tile size / image size = (0.5, 2): scale (2, 3)·k, translation −(0.5, 0.25)·k.
    assert_eq!(p.parameters.get("scale"), Some(&ParamValue::Float2(glam::Vec2::new(1.0, 6.0))));
    assert_eq!(p.parameters.get("translation"), Some(&ParamValue::Float2(glam::Vec2::new(-0.25, -0.5))));
    let reader = upstream(&placement, "in").expect("the transform reads the coordinates");
    assert_eq!(node(&reader).node_type_id, "UsdPrimvarReader_float2");
    assert!(!t.warnings.iter().any(|w| w.contains("/Looks/M/Tiles") && w.contains("tiledimage")), "{:?}", t.warnings);
}

/// The texture output the surface's `input` reads, and that texture's scale and bias (their
/// first components).
fn texture_read(net: &MaterialNetwork, input: &str) -> (String, f32, f32) {
    let c = net.connections.iter().find(|c| c.downstream_node == net.surface_node && c.downstream_input == input).expect(input);
    let tex = net.nodes.iter().find(|n| n.path == c.upstream_node).expect("its texture");
    let first = |k: &str| match tex.parameters.get(k) {
        Some(ParamValue::Float4(v)) => v.x,
        other => panic!("{k}: {other:?}"),
    };
    (c.upstream_output.clone(), first("scale"), first("bias"))
}

/// A packed map (occlusion, roughness, metalness in r, g, b, as glTF and Substance write
/// them): `separate3`'s `outg` feeds roughness and `extract` index 2 (after a multiply) feeds
/// metalness, each read from its own channel of the one image with its own scale.
#[test]
fn channels_of_a_packed_map_feed_their_inputs() {
    let extra = r#"
        def Shader "Packed" {
            uniform token info:id = "ND_image_color3"
            asset inputs:file = @missing.png@
            color3f outputs:out
        }
        def Shader "Split" {
            uniform token info:id = "ND_separate3_color3"
            color3f inputs:in.connect = </Looks/M/Packed.outputs:out>
            float outputs:outr
            float outputs:outg
            float outputs:outb
        }
        def Shader "Dim" {
            uniform token info:id = "ND_multiply_color3FA"
            color3f inputs:in1.connect = </Looks/M/Packed.outputs:out>
            float inputs:in2 = 0.5
            color3f outputs:out
        }
        def Shader "Metal" {
            uniform token info:id = "ND_extract_color3"
            color3f inputs:in.connect = </Looks/M/Dim.outputs:out>
            int inputs:index = 2
            float outputs:out
        }
        def Shader "Beyond" {
            uniform token info:id = "ND_extract_color3"
            color3f inputs:in.connect = </Looks/M/Packed.outputs:out>
            int inputs:index = 7
            float outputs:out
        }"#;
    let inputs = "float inputs:specular_roughness.connect = </Looks/M/Split.outputs:outg>\n float inputs:base_metalness.connect = </Looks/M/Metal.outputs:out>\n float inputs:coat_weight.connect = </Looks/M/Beyond.outputs:out>";
    let t = load_text("mtlx_packed", &stage("ND_open_pbr_surface_surfaceshader", inputs, extra));
    let net = network(&t);
    assert_eq!(texture_read(net, "roughness"), ("g".to_string(), 1.0, 0.0));
    assert_eq!(texture_read(net, "metallic"), ("b".to_string(), 0.5, 0.0));
    // Index 7 names no channel: reported by path, and the coat keeps its default.
    assert_eq!(t.warnings.iter().filter(|w| w.contains("/Looks/M/Beyond") && w.contains("index")).count(), 1, "{:?}", t.warnings);
    assert!(net.connections.iter().all(|c| c.downstream_input != "clearcoat"), "{:?}", net.connections);
}

/// MaterialX's NG_place2d_vector2, as its GLSL computes it (SRT for order 0, TRS for 1).
fn place2d(st: glam::Vec2, pivot: glam::Vec2, scale: glam::Vec2, rotate: f32, offset: glam::Vec2, trs: bool) -> glam::Vec2 {
    let turn = |v: glam::Vec2| {
        let (s, c) = rotate.to_radians().sin_cos();
        glam::Vec2::new(c * v.x + s * v.y, -s * v.x + c * v.y)
    };
    let p = st - pivot;
    (if trs { turn(p - offset) / scale } else { turn(p / scale) - offset }) + pivot
}

/// A `place2d` between an image and its texture coordinates becomes the texture's
/// `UsdTransform2d`, which must place every point where MaterialX's own graph does; a TRS
/// shear it cannot say is reported.
#[test]
fn a_place2d_places_the_texture_as_materialx_computes_it() {
    let (pivot, scale, offset) = (glam::Vec2::new(0.5, 0.25), glam::Vec2::new(2.0, 4.0), glam::Vec2::new(0.25, -0.5));
    for (order, scale) in [(0, scale), (1, glam::Vec2::splat(3.0)), (1, scale)] {
        let extra = format!(
            r#"
        def Shader "Image" {{
            uniform token info:id = "ND_image_color3"
            asset inputs:file = @missing.png@
            float2 inputs:texcoord.connect = </Looks/M/Place.outputs:out>
            color3f outputs:out
        }}
        def Shader "Place" {{
            uniform token info:id = "ND_place2d_vector2"
            float2 inputs:texcoord.connect = </Looks/M/Uv.outputs:out>
            float2 inputs:pivot = ({}, {})
            float2 inputs:scale = ({}, {})
            float inputs:rotate = 30
            float2 inputs:offset = ({}, {})
            int inputs:operationorder = {order}
            float2 outputs:out
        }}
        def Shader "Uv" {{
            uniform token info:id = "ND_texcoord_vector2"
            float2 outputs:out
        }}"#,
            pivot.x, pivot.y, scale.x, scale.y, offset.x, offset.y
        );
        let t = load_text(
            "mtlx_place2d",
            &stage("ND_open_pbr_surface_surfaceshader", "color3f inputs:base_color.connect = </Looks/M/Image.outputs:out>", &extra),
        );
        let net = network(&t);
        let transform = net.nodes.iter().find(|n| n.node_type_id == "UsdTransform2d");
        if order == 1 && scale.x != scale.y {
            assert!(transform.is_none(), "a shear cannot be placed");
            assert_eq!(t.warnings.iter().filter(|w| w.contains("/Looks/M/Place") && w.contains("shear")).count(), 1, "{:?}", t.warnings);
            continue;
        }
        assert!(t.warnings.iter().all(|w| !w.contains("/Looks/M/Place")), "{:?}", t.warnings);
        let p = |name: &str| transform.expect("placed").parameters.get(name).cloned();
        let (Some(ParamValue::Float2(s)), Some(ParamValue::Float(r)), Some(ParamValue::Float2(tr))) =
            (p("scale"), p("rotation"), p("translation"))
        else {
            panic!("{transform:?}")
        };
        // UsdTransform2d: st · scale, turned `rotation` degrees counter-clockwise, + translation.
        let usd = |st: glam::Vec2| glam::Mat2::from_angle(r.to_radians()) * (st * s) + tr;
        for st in [glam::Vec2::ZERO, glam::Vec2::new(1.0, 0.0), glam::Vec2::new(0.3, 0.9), glam::Vec2::new(-2.0, 5.0)] {
            let (want, got) = (place2d(st, pivot, scale, 30.0, offset, order == 1), usd(st));
            assert!((want - got).length() < 1e-5, "order {order}, st {st}: MaterialX {want}, UsdTransform2d {got}");
        }
    }
}

/// Linear nodes with constant operands fold into the texture's scale and bias: `remap` of a
/// channel to [0.2, 0.8], `invert` (1 − x), `divide` by 4; a divide by a texture or by 0, and
/// a remap of an empty range, are reported.
#[test]
fn remap_invert_and_divide_fold_into_scale_and_bias() {
    let extra = r#"
        def Shader "Gloss" {
            uniform token info:id = "ND_image_float"
            asset inputs:file = @missing.png@
            float outputs:out
        }
        def Shader "Rough" {
            uniform token info:id = "ND_remap_float"
            float inputs:in.connect = </Looks/M/Gloss.outputs:out>
            float inputs:outlow = 0.2
            float inputs:outhigh = 0.8
            float outputs:out
        }
        def Shader "Flip" {
            uniform token info:id = "ND_invert_float"
            float inputs:in.connect = </Looks/M/Gloss.outputs:out>
            float outputs:out
        }
        def Shader "Quarter" {
            uniform token info:id = "ND_divide_float"
            float inputs:in1.connect = </Looks/M/Gloss.outputs:out>
            float inputs:in2 = 4
            float outputs:out
        }
        def Shader "ByZero" {
            uniform token info:id = "ND_divide_float"
            float inputs:in1.connect = </Looks/M/Gloss.outputs:out>
            float inputs:in2 = 0
            float outputs:out
        }"#;
    let inputs = "float inputs:specular_roughness.connect = </Looks/M/Rough.outputs:out>\n float inputs:base_metalness.connect = </Looks/M/Flip.outputs:out>\n float inputs:coat_weight.connect = </Looks/M/Quarter.outputs:out>\n float inputs:coat_roughness.connect = </Looks/M/ByZero.outputs:out>";
    let t = load_text("mtlx_linear", &stage("ND_open_pbr_surface_surfaceshader", inputs, extra));
    let net = network(&t);
    let folded = |input: &str| {
        let (_, scale, bias) = texture_read(net, input);
        (scale, bias)
    };
    let close = |(s, b): (f32, f32), (ws, wb): (f32, f32)| (s - ws).abs() < 1e-6 && (b - wb).abs() < 1e-6;
    assert!(close(folded("roughness"), (0.6, 0.2)), "{:?}", folded("roughness"));
    assert!(close(folded("metallic"), (-1.0, 1.0)), "{:?}", folded("metallic"));
    assert!(close(folded("clearcoat"), (0.25, 0.0)), "{:?}", folded("clearcoat"));
    assert_eq!(t.warnings.iter().filter(|w| w.contains("/Looks/M/ByZero") && w.contains("divisor")).count(), 1, "{:?}", t.warnings);
}
