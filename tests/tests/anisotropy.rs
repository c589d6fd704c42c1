//! Which way an anisotropic highlight runs: the shared `tangent` (object space, constant or
//! read per vertex through a primvar reader) and `anisotropyRotation` inputs of Tessera's own
//! shaders. A sun over a strongly anisotropic metal quad facing the camera, direct light only
//! (a delta light and one bounce: no noise), so two settings that mean the same frame give the
//! same pixels and two that do not give visibly different highlights.

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::IntegratorSettings;
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, commit};
use tessera_tests::load_text;

const SIZE: u32 = 64;

/// The quad (normal +Z, 8 units wide) under `xform`, its tessera:Metal given `inputs`, lit by
/// a sun tilted towards +x and +y and seen from 5 units above.
fn scene_usda(xform: &str, inputs: &str, mesh_extra: &str) -> String {
    format!(
        r#"#usda 1.0
(
    upAxis = "Y"
)
def Xform "World"
{{
    def Camera "Camera"
    {{
        double3 xformOp:translate = (0, 0, 5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
        float focalLength = 18
        float horizontalAperture = 36
        float verticalAperture = 36
    }}
    def DistantLight "Sun"
    {{
        float inputs:intensity = 40000
        float inputs:angle = 0.53
        float3 xformOp:rotateXYZ = (-20, 12, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}
    def Xform "Place"
    {{
        {xform}
        def Mesh "Quad" (prepend apiSchemas = ["MaterialBindingAPI"])
        {{
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)]
            {mesh_extra}
            rel material:binding = </World/Looks/M>
        }}
    }}
    def Scope "Looks"
    {{
        def Material "M"
        {{
            token outputs:surface.connect = </World/Looks/M/S.outputs:surface>
            def Shader "S"
            {{
                uniform token info:id = "tessera:Metal"
                color3f inputs:reflectivity = (0.9, 0.9, 0.9)
                float inputs:roughness = 0.35
                float inputs:anisotropy = -0.9
                {inputs}
                token outputs:surface
            }}
            def Shader "Tangents"
            {{
                uniform token info:id = "UsdPrimvarReader_float3"
                string inputs:varname = "brushed"
                float3 outputs:result
            }}
        }}
    }}
}}
"#
    )
}

/// The beauty's red channel, after checking that the file read without a warning.
fn render(xform: &str, inputs: &str, mesh_extra: &str) -> Vec<f32> {
    // A layer file of its own per render: the tests run in parallel in one process.
    static RENDERS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let name = format!("anisotropy-{}", RENDERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
    let t = load_text(&name, &scene_usda(xform, inputs, mesh_extra));
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    assert!(t.warnings.is_empty() && scene.warnings.is_empty(), "{:?} {:?}", t.warnings, scene.warnings);
    let camera = Camera::new(&scene.camera("/World/Camera").expect("camera"), SIZE, SIZE);
    let integrator = IntegratorSettings { max_depth: 1, ..Default::default() };
    let settings = RenderSettings { width: SIZE, height: SIZE, spp: 4, integrator, ..Default::default() };
    let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
    let red: Vec<f32> = fb.layers[&Aov::Beauty].chunks(4).map(|p| p[0]).collect();
    assert!(red.iter().all(|v| v.is_finite()), "finite");
    red
}

/// Largest pixel difference relative to the brightest pixel of `a`.
fn difference(a: &[f32], b: &[f32]) -> f32 {
    let peak = a.iter().cloned().fold(0.0, f32::max);
    assert!(peak > 0.1, "the highlight is on the quad: peak {peak}");
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max) / peak
}

const ALONG_X: &str = "vector3f inputs:tangent = (1, 0, 0)";
const ALONG_Y: &str = "vector3f inputs:tangent = (0, 1, 0)";

#[test]
fn the_highlight_follows_the_tangent_its_rotation_and_the_objects_placement() {
    let along_x = render("", ALONG_X, "");
    let along_y = render("", ALONG_Y, "");
    // The two directions differ: the highlight stretches across the quad one way or the other
    // (measured 0.37 of the peak; a tangent ignored would read 0).
    assert!(difference(&along_x, &along_y) > 0.2, "x and y give different highlights");
    // Without a tangent the frame runs around the object's up axis (+Y): on a +Z normal
    // that is +X. Rounding differs (a cross product against a given vector).
    assert!(difference(&along_x, &render("", "", "")) < 1e-4, "default is around +Y: +X here");
    // A quarter turn counter-clockwise about +Z takes +X to +Y (sin and cos of π/2 in f32).
    assert!(difference(&along_y, &render("", &format!("{ALONG_X}\n float inputs:anisotropyRotation = 0.25"), "")) < 1e-4);
    assert!(difference(&along_x, &render("", &format!("{ALONG_Y}\n float inputs:anisotropyRotation = -0.25"), "")) < 1e-4);
    // The tangent is in object space: turned 90° about Z with the object (the square maps
    // onto itself), +X runs along world +Y.
    let turned = r#"float3 xformOp:rotateXYZ = (0, 0, 90)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]"#;
    assert!(difference(&along_y, &render(turned, ALONG_X, "")) < 1e-4, "object space");
    // Per vertex through a primvar reader, as an exporter writes a mesh's tangents.
    let per_vertex = r#"vector3f[] primvars:brushed = [(0, 3, 0), (0, 3, 0), (0, 3, 0), (0, 3, 0)] (interpolation = "vertex")"#;
    let connected = "vector3f inputs:tangent.connect = </World/Looks/M/Tangents.outputs:result>";
    assert!(difference(&along_y, &render("", connected, per_vertex)) < 1e-4, "read per vertex");
    // Per face corner, as a DCC writes a UV map's tangents (MikkTSpace's, one per corner).
    let per_corner = r#"vector3f[] primvars:brushed = [(0, 2, 0), (0, 2, 0), (0, 2, 0), (0, 2, 0)] (interpolation = "faceVarying")"#;
    assert!(difference(&along_y, &render("", connected, per_corner)) < 1e-4, "read per corner");
}

/// `stTangent`: without a `tangent`, the first axis runs where the quad's texture coordinate s
/// grows (MaterialX's default tangent), placed with the object; a `tangent` still wins, and
/// a mesh without texture coordinates keeps the default frame.
#[test]
fn the_highlight_follows_the_texture_coordinates_where_asked() {
    let (along_x, along_y) = (render("", ALONG_X, ""), render("", ALONG_Y, ""));
    // s = (x + 4)/8 runs along +X, s = (y + 4)/8 along +Y.
    let s_along_x = r#"texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (interpolation = "vertex")"#;
    let s_along_y = r#"texCoord2f[] primvars:st = [(0, 0), (0, 1), (1, 1), (1, 0)] (interpolation = "vertex")"#;
    let asked = "float inputs:stTangent = 1";
    assert!(difference(&along_x, &render("", asked, s_along_x)) < 1e-4, "s along +X");
    assert!(difference(&along_y, &render("", asked, s_along_y)) < 1e-4, "s along +Y");
    // Not asked, the coordinates change nothing (the default frame runs along +X here).
    assert!(difference(&along_x, &render("", "", s_along_y)) < 1e-4, "not asked");
    assert!(difference(&along_x, &render("", &format!("{asked}\n {ALONG_X}"), s_along_y)) < 1e-4, "a tangent wins");
    assert!(difference(&along_x, &render("", asked, "")) < 1e-4, "no coordinates: the default");
    // Turned with the object (90° about Z): s along the quad's +Y runs along world −X.
    let turned = r#"float3 xformOp:rotateXYZ = (0, 0, 90)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]"#;
    assert!(difference(&along_x, &render(turned, asked, s_along_y)) < 1e-4, "placed with the object");
    // And turned by the rotation: a quarter turn of s along +X is +Y.
    assert!(difference(&along_y, &render("", &format!("{asked}\n float inputs:anisotropyRotation = 0.25"), s_along_x)) < 1e-4);
}

/// A tangent along the normal, one too small or too large to normalise, or one that is not
/// finite falls back to the default frame (around the up axis) and renders finite; a
/// non-finite one is reported by the shader's path.
#[test]
fn a_tangent_along_the_normal_falls_back_to_the_up_axis() {
    let default = render("", "", "");
    for tangent in ["(0, 0, 7)", "(1e-30, 0, 0)", "(3e38, 3e38, 0)"] {
        assert!(difference(&default, &render("", &format!("vector3f inputs:tangent = {tangent}"), "")) < 1e-4, "{tangent}");
    }
    let t = load_text("anisotropy-nan", &scene_usda("", "vector3f inputs:tangent = (nan, 0, inf)", ""));
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    assert!(
        scene.warnings.iter().any(|w| w == "/World/Looks/M/S: input 'tangent' is not finite; using its default"),
        "{:?}",
        scene.warnings
    );
}
