//! Subdivision surfaces read from USD: refined by OpenSubdiv, rendered as their limit surface.

use tessera::usd::{LoadOptions, load_with};
use tessera_tests::{fixture, load, load_text, render_fixture, small};

/// World-space y range of a mesh's points.
fn y_range(t: &tessera::usd::Translation, path: &str) -> (f32, f32) {
    let (_, m) = t.meshes.iter().find(|(p, _)| p == path).unwrap_or_else(|| panic!("{path} not read"));
    m.mesh
        .positions
        .iter()
        .map(|p| m.transform.transform_point3(*p).y)
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)))
}

#[tokio::test]
async fn a_subdivided_sphere_cage_covers_what_the_sphere_does() {
    // The cage's limit surface is the unit sphere (fixtures/make_fixtures.py moves its points
    // until each vertex's limit is on it); the camera is 4 units away, 35 mm lens, 20 mm
    // aperture. A sphere's silhouette there is a circle of radius f·r/√(d² − r²) on the sensor:
    // 35/√15 mm, i.e. 57.84 pixels at 128 pixels across 20 mm: π·57.84² = 10 510 pixels.
    let t = load("usd/subdivided_sphere.usda");
    let radii: Vec<f32> = t.meshes[0].1.mesh.positions.iter().map(|p| p.length()).collect();
    let (r_lo, r_hi) = radii.iter().fold((f32::INFINITY, 0.0f32), |(a, b), r| (a.min(*r), b.max(*r)));
    assert!(r_lo > 0.995 && r_hi < 1.005, "the limit surface lies within 0.5% of the unit sphere: radii {r_lo}..{r_hi}");
    let report = render_fixture("usd/subdivided_sphere.usda", &small(128, 128, 16)).await;
    let coverage: f64 =
        (0..128).flat_map(|y| (0..128).map(move |x| (x, y))).map(|(x, y)| report.image.pixel("beauty", x, y)[3] as f64).sum();
    let radius = 35.0 / 15f64.sqrt() * 128.0 / 20.0;
    let expected = std::f64::consts::PI * radius * radius;
    // 1%: the limit surface strays from the sphere by well under that between cage vertices;
    // 16 samples on ~520 edge pixels leave ~0.02% of noise.
    println!("coverage {coverage:.1} pixels, the sphere's {expected:.1}: {:+.3}%", 100.0 * (coverage / expected - 1.0));
    assert!((coverage / expected - 1.0).abs() < 0.01, "coverage {coverage:.0} pixels, a sphere {expected:.0}");
    assert_eq!(t.subdivided.len(), 1);
    assert_eq!(t.subdivided[0].level, 3, "primvars:tessera:refinementLevel names the mesh's level");
}

#[test]
fn creases_and_corners_shape_the_limit_surface() {
    let t = load("usd/subdivision.usda");
    // The creased pyramid keeps its apex (a sharp corner) and its flat base (an infinitely
    // sharp crease loop in the plane y = 0); the smooth one rounds both off.
    let (smooth_lo, smooth_hi) = y_range(&t, "/World/PyramidSmooth");
    let (creased_lo, creased_hi) = y_range(&t, "/World/PyramidCreased");
    let (_, semi_hi) = y_range(&t, "/World/PyramidSemiSharp");
    assert!((creased_hi - 1.5).abs() < 1e-5 && creased_lo.abs() < 1e-5, "creased: {creased_lo}..{creased_hi}");
    assert!(smooth_hi < 1.2 && smooth_lo > 0.05, "smooth: {smooth_lo}..{smooth_hi}");
    // Semi-sharp side edges (sharpness 2) pull the apex up, short of the corner.
    assert!(smooth_hi < semi_hi && semi_hi < 1.5, "semi-sharp apex {semi_hi}");
    for s in &t.subdivided {
        let want = match s.path.as_str() {
            "/World/LoopOctahedron" => "loop",
            "/World/BilinearCube" => "bilinear",
            _ => "catmullClark",
        };
        assert_eq!((s.scheme.as_str(), s.level), (want, tessera::usd::DEFAULT_SUBDIVISION_LEVEL), "{}", s.path);
    }
    assert_eq!(t.subdivided.len(), 7, "every mesh of the fixture is a subdivision surface");
    // A bilinear cube is its cage, flat faces and all: 6 faces × 16 quads × 2 triangles.
    let (_, cube) = t.meshes.iter().find(|(p, _)| p == "/World/BilinearCube").unwrap();
    assert_eq!(cube.mesh.indices.len(), 6 * 16 * 2);
    let (lo, hi) = y_range(&t, "/World/BilinearCube");
    assert!((lo - 0.0).abs() < 1e-5 && (hi - 1.0).abs() < 1e-5, "{lo}..{hi}");
}

#[test]
fn the_render_plan_lists_subdivision_with_its_prims() {
    let plan = tessera::commands::render::explain_plan(&fixture("usd/subdivision.usda"), LoadOptions::default()).unwrap();
    let line = plan.lines().position(|l| l.starts_with("  + subdivision")).unwrap_or_else(|| panic!("{plan}"));
    let prims = plan.lines().nth(line + 1).unwrap();
    assert!(
        prims.contains("/World/PyramidCreased (catmullClark level 2)") && prims.contains("/World/LoopOctahedron (loop level 2)"),
        "{prims}"
    );
    let cornell = tessera::commands::render::explain_plan(&fixture("cornell_box.usda"), LoadOptions::default()).unwrap();
    assert!(!cornell.contains("subdivision"), "a scene without subdivision surfaces pays nothing and says nothing");
}

#[test]
fn level_zero_renders_the_cages_and_scheme_none_is_never_refined() {
    let cages = load_with(&fixture("usd/subdivision.usda"), LoadOptions { subdivision_level: 0, ..Default::default() }).unwrap();
    assert!(cages.subdivided.is_empty());
    let (_, pyramid) = cages.meshes.iter().find(|(p, _)| p == "/World/PyramidSmooth").unwrap();
    assert_eq!(pyramid.mesh.indices.len(), 2 + 4, "the cage's own triangles");
    let cornell = load("cornell_box.usda");
    assert!(cornell.subdivided.is_empty(), "subdivisionScheme = none stays polygonal");
}

#[test]
fn a_cage_opensubdiv_cannot_take_renders_unrefined_with_a_warning() {
    let t = load_text(
        "bad_crease",
        r#"#usda 1.0
def Mesh "Quad" {
    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    int[] creaseIndices = [0, 7]
    int[] creaseLengths = [2]
    float[] creaseSharpnesses = [1]
}
def Mesh "Odd" {
    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    uniform token subdivisionScheme = "smoothest"
}
"#,
    );
    assert!(t.meshes.iter().any(|(p, m)| p == "/Quad" && m.mesh.indices.len() == 2), "the cage renders");
    assert!(
        t.warnings.iter().any(|w| w.contains("/Quad") && w.contains("creaseIndices[1] = 7") && w.contains("unrefined")),
        "{:?}",
        t.warnings
    );
    assert!(t.warnings.iter().any(|w| w.contains("/Odd") && w.contains("subdivisionScheme")), "{:?}", t.warnings);
    assert!(t.meshes.iter().all(|(p, _)| p != "/Odd"));
}

/// A unit cube's cage (every corner extraordinary, valence 3), named `name`, with `extra`
/// inside its prim.
fn cube_cage(name: &str, extra: &str) -> String {
    format!(
        r#"def Mesh "{name}" (
    prepend apiSchemas = ["MaterialBindingAPI"]
) {{
    point3f[] points = [(0,0,0), (1,0,0), (1,1,0), (0,1,0), (0,0,1), (1,0,1), (1,1,1), (0,1,1)]
    int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
    int[] faceVertexIndices = [0,3,2,1, 4,5,6,7, 0,1,5,4, 1,2,6,5, 2,3,7,6, 3,0,4,7]
    {extra}
}}
"#
    )
}

#[test]
fn meshes_refined_after_the_traversal_come_out_as_refined_inline() {
    // Plain subdivision meshes are refined after the traversal, several at once (a big one
    // alone on every thread; `client/src/usd/refine_later.rs`); a mesh with a bound
    // GeomSubset is refined inline.
    // The same cage both ways must give the same triangles to the bit, the warnings must stay
    // in traversal order, and a prim skipped after its prototype mesh was deferred must leave
    // nothing behind.
    let subset = r#"def GeomSubset "All" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    ) {
        uniform token elementType = "face"
        uniform token familyName = "materialBind"
        int[] indices = [0, 1, 2, 3, 4, 5]
        rel material:binding = </Looks/Grey>
    }"#;
    let usda = [
        "#usda 1.0\ndef Scope \"Looks\" { def Material \"Grey\" { } }\n".to_string(),
        cube_cage("Deferred", "int primvars:tessera:refinementLevel = 3"),
        // Big enough to spread over every thread (396 000 locations): refined on its own.
        cube_cage("Big", "int primvars:tessera:refinementLevel = 8"),
        cube_cage("BadCrease", "int[] creaseIndices = [0, 9]\n    int[] creaseLengths = [2]\n    float[] creaseSharpnesses = [2]"),
        cube_cage("Flat", "uniform token subdivisionScheme = \"none\"\n    color3f[] primvars:displayColor = []"),
        cube_cage("Inline", &format!("int primvars:tessera:refinementLevel = 3\n    {subset}")),
        r#"def PointInstancer "Broken" {
    rel prototypes = [</Broken/Proto/Cube>, </Nowhere>]
    int[] protoIndices = [0, 1]
    point3f[] positions = [(0, 0, 0), (2, 0, 0)]
    def Scope "Proto" {
"#
        .to_string(),
        cube_cage("Cube", ""),
        "    }\n}\n".to_string(),
    ]
    .concat();
    let t = load_text("refine_later", &usda);
    let mesh = |path: &str| t.meshes.iter().find(|(p, _)| p == path).map(|(_, m)| m.mesh.clone()).unwrap_or_else(|| panic!("{path}"));
    let (deferred, inline) = (mesh("/Deferred"), mesh("/Inline/All"));
    // 6 quads × 8² grid quads × 2 triangles at level 3.
    assert_eq!(deferred.indices.len(), 6 * 64 * 2);
    assert_eq!((&deferred.positions, &deferred.indices, &deferred.normals), (&inline.positions, &inline.indices, &inline.normals));
    assert_eq!(mesh("/BadCrease").indices.len(), 12, "the cage OpenSubdiv refuses renders unrefined");
    let order: Vec<&str> = t.meshes.iter().map(|(p, _)| p.as_str()).collect();
    assert_eq!(mesh("/Big").indices.len(), 6 * 256 * 256 * 2);
    assert_eq!(order, ["/Deferred", "/Big", "/BadCrease", "/Flat", "/Inline/All"], "traversal order; the broken instancer adds nothing");
    let levels: Vec<(&str, u32)> = t.subdivided.iter().map(|s| (s.path.as_str(), s.level)).collect();
    assert_eq!(levels, [("/Deferred", 3), ("/Big", 8), ("/Inline", 3)], "the refused cage and the skipped prototype are not listed");
    let at = |needle: &str| t.warnings.iter().position(|w| w.contains(needle)).unwrap_or_else(|| panic!("{needle}: {:?}", t.warnings));
    assert!(at("creaseIndices[1] = 9") < at("/Flat: primvars:displayColor"), "{:?}", t.warnings);
    assert!(at("/Flat: primvars:displayColor") < at("/Broken"), "{:?}", t.warnings);
}
