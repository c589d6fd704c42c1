//! UsdPreviewSurface `displacement`: meshes moved along their normals at commit, by a texture
//! or a constant, measured where rays hit them. Fixture: `fixtures/textures/displaced.usda`
//! (see `displaced_surfaces()` in make_fixtures.py for what is where).

use glam::Vec3;
use render_core::geometry::Ray;
use render_core::material::ParamValue;
use render_core::scene::{BlasCache, CommittedScene, SceneDesc, commit};
use tessera::commands::render::explain_plan;
use tessera_tests::{fixture, load, load_text, render_fixture, small};

/// Where a ray from `origin` along `dir` first meets the scene.
fn hit_point(scene: &CommittedScene, origin: Vec3, dir: Vec3) -> Option<Vec3> {
    scene.intersect(&Ray::new(origin, dir)).map(|h| origin + dir * h.t)
}

/// Height of the surface under (x, z), seen from above.
fn height(scene: &CommittedScene, x: f32, z: f32) -> f32 {
    hit_point(scene, Vec3::new(x, 5.0, z), -Vec3::Y).expect("a surface below").y
}

#[test]
fn a_textured_displacement_lifts_each_quadrant_by_its_texel() {
    let scene = commit(&load("textures/displaced.usda").to_scene_desc(), &mut BlasCache::default()).expect("commits");
    // Quadrant centres are grid vertices whose neighbours lie in the same quadrant: there the
    // height is 0.25 × the quadrant's red byte / 255 (read raw), to float precision.
    for ((x, z), byte) in [((-0.5, -0.5), 200.0), ((0.5, -0.5), 40.0), ((-0.5, 0.5), 40.0), ((0.5, 0.5), 230.0)] {
        let expected = 0.25 * byte / 255.0;
        let got = height(&scene, x, z);
        assert!((got - expected).abs() < 1e-5, "quadrant at ({x}, {z}): height {got}, expected {expected}");
    }
    assert!(scene.warnings.iter().all(|w| !w.contains("displacement")), "{:?}", scene.warnings);
}

#[test]
fn a_coarse_mesh_is_diced_for_its_displacement_texture() {
    let scene = commit(&load("textures/displaced.usda").to_scene_desc(), &mut BlasCache::default()).expect("commits");
    // The slab is one quad (z in [2, 4]) under the grid's 64-texel texture: diced into
    // ceil(√2 · 64) = 91 segments an edge (its diagonal spans 91 texels), 2 · 91² triangles, it
    // rises as the grid does in each quadrant's middle (st (0.25, 0.75) is x = -0.5, z = 2.5).
    let slab = scene.prim_paths.iter().position(|p| p == "/World/Slab").expect("the slab");
    let mesh = scene.instances.iter().find(|i| i.prim as usize == slab).map(|i| &scene.meshes[i.mesh]).expect("its instance");
    assert_eq!(mesh.indices.len(), 2 * 91 * 91);
    for ((x, z), byte) in [((-0.5, 2.5), 200.0), ((0.5, 2.5), 40.0), ((-0.5, 3.5), 40.0), ((0.5, 3.5), 230.0)] {
        let expected = 0.25 * byte / 255.0;
        let got = height(&scene, x, z);
        assert!((got - expected).abs() < 1e-5, "slab quadrant at ({x}, {z}): height {got}, expected {expected}");
    }
    // The grid (32 × 32 quads over the same texture) is diced 3 an edge: its diagonals span
    // 2.8 texels.
    let grid = scene.prim_paths.iter().position(|p| p == "/World/Grid").expect("the grid");
    let mesh = scene.instances.iter().find(|i| i.prim as usize == grid).map(|i| &scene.meshes[i.mesh]).expect("its instance");
    assert_eq!(mesh.indices.len(), 2 * 32 * 32 * 9);
}

/// Hostile input: dicing is bounded for the whole scene. Two quads whose texture repeats 16
/// times ask for 1024 segments an edge each (the most): 4.2 M triangles. Scaled down together
/// with the fixture's grid and slab to the scene's 2 M, each is reported by name.
#[test]
fn dicing_stays_within_the_scenes_budget_and_says_where_it_was_limited() {
    let mut t = load("textures/displaced.usda");
    let (slab_path, slab) = t.meshes.iter().find(|(p, _)| p == "/World/Slab").cloned().expect("the slab");
    let mut tiled = (*slab.mesh).clone();
    if let render_core::geometry::Attribute::Vertex(st) = &mut tiled.uvs {
        st.iter_mut().for_each(|uv| *uv *= 16.0);
    }
    for k in 0..2 {
        let mut copy = slab.clone();
        copy.mesh = std::sync::Arc::new(tiled.clone());
        t.meshes.push((format!("{slab_path}Tiled{k}"), copy));
    }
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    let diced: usize = scene.meshes.iter().map(|m| m.indices.len()).sum();
    let limit = render_core::scene::MAX_DICED_TRIANGLES as usize;
    // Past the budget only by the ball's 4 096 triangles, which are not diced.
    assert!(diced <= limit + 64 * 32 * 2, "{diced} triangles");
    for path in ["/World/SlabTiled0", "/World/SlabTiled1", "/World/Slab", "/World/Grid"] {
        let said = scene
            .warnings
            .iter()
            .any(|w| w.starts_with(&format!("{path}: displacement diced ")) && w.contains("more than 2097152 triangles"));
        assert!(said, "{path}: {:?}", scene.warnings);
    }
}

#[test]
fn a_materialx_displacement_shader_moves_the_surface_as_the_preview_surface_does() {
    let t = load("textures/displaced.usda");
    assert!(t.warnings.iter().all(|w| !w.contains("displace")), "{:?}", t.warnings);
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    // ND_image_float of an 8-bit PNG decodes as sRGB (UsdUVTexture's `auto`), times the
    // ND_displacement_float's scale 0.25. The slab lies over z in [5, 7].
    let srgb = |b: f32| {
        let c = b / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    };
    for ((x, z), byte) in [((-0.5, 5.5), 200.0), ((0.5, 5.5), 40.0), ((-0.5, 6.5), 40.0), ((0.5, 6.5), 230.0)] {
        let expected = 0.25 * srgb(byte);
        let got = height(&scene, x, z);
        assert!((got - expected).abs() < 1e-4, "MaterialX slab quadrant at ({x}, {z}): height {got}, expected {expected}");
    }
}

#[test]
fn a_constant_displacement_grows_the_ball_by_its_amount() {
    let scene = commit(&load("textures/displaced.usda").to_scene_desc(), &mut BlasCache::default()).expect("commits");
    // The unit ball at (3, 0, 0), displaced by 0.1: its pole and its equator's vertex on +x
    // lie 1.1 from its centre (both are vertices of the 64 × 32 sphere).
    let top = hit_point(&scene, Vec3::new(3.0, 5.0, 0.0), -Vec3::Y).expect("hits the ball");
    assert!((top.y - 1.1).abs() < 1e-4, "top at {top}");
    let side = hit_point(&scene, Vec3::new(10.0, 0.0, 0.0), -Vec3::X).expect("hits the ball");
    assert!((side.x - 4.1).abs() < 1e-4, "side at {side}");
}

#[test]
fn the_plan_switches_displacement_on_for_the_materials_that_displace() {
    let plan = explain_plan(&fixture("textures/displaced.usda"), Default::default()).unwrap();
    assert!(plan.contains("+ displacement") && plan.contains("/World/Looks/Bumps") && plan.contains("/World/Looks/Swell"), "{plan}");
    // A texture that only displaces is read at commit: shading points never look it up.
    assert!(plan.contains("- textures"), "{plan}");
    let cornell = explain_plan(&fixture("cornell_box.usda"), Default::default()).unwrap();
    assert!(cornell.contains("- displacement"), "{cornell}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_displaced_scene_renders_over_the_server() {
    let report = render_fixture("textures/displaced.usda", &small(48, 32, 4)).await;
    tessera_tests::assert_all_finite(&report.image);
    assert!(report.started.warnings.iter().all(|w| !w.contains("displacement")), "{:?}", report.started.warnings);
}

/// A layer of `material` (a Material at /M) bound to a one-triangle mesh at y = 0, under a dome.
fn with_triangle(material: &str) -> String {
    format!(
        r#"#usda 1.0
{material}
def Mesh "Tri" (prepend apiSchemas = ["MaterialBindingAPI"])
{{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 0, -1)]
    rel material:binding = </M>
}}
def DomeLight "Dome" {{}}
"#
    )
}

/// Sets the Swell material's constant displacement in `desc`.
fn set_swell(desc: &mut SceneDesc, amount: f32) {
    let network = desc.materials.get_mut("/World/Looks/Swell").expect("the Swell material");
    let surface = network.nodes.iter_mut().find(|n| n.path == network.surface_node).expect("its surface node");
    surface.parameters.insert("displacement".into(), ParamValue::Float(amount));
}

#[test]
fn edits_elsewhere_keep_the_displaced_meshes_and_a_new_amount_displaces_again() {
    let mut desc = load("textures/displaced.usda").to_scene_desc();
    let mut cache = BlasCache::default();
    commit(&desc, &mut cache).expect("commits");
    // Moving the ball: no mesh is displaced or built again.
    let ball = desc.meshes.get_mut("/World/Ball").expect("the ball");
    ball.transform = glam::Affine3A::from_translation(Vec3::new(0.0, 0.0, 1.0));
    commit(&desc, &mut cache).expect("commits");
    assert_eq!(cache.last_builds, 0, "a transform edit keeps every displaced BLAS");
    // A new amount on the ball's material: only the ball is displaced and built again.
    set_swell(&mut desc, 0.3);
    let scene = commit(&desc, &mut cache).expect("commits");
    assert_eq!(cache.last_builds, 1);
    let top = hit_point(&scene, Vec3::new(3.0, 5.0, 1.0), -Vec3::Y).expect("hits the ball");
    assert!((top.y - 1.3).abs() < 1e-4, "top at {top}");
}

/// Hostile input: displacements that would carry points past what single precision holds, or
/// that are not numbers, are reported naming the mesh and material; the mesh renders where it
/// was, and everything else renders.
#[test]
fn a_displacement_out_of_range_is_reported_and_the_mesh_stays_where_it_was() {
    for amount in [1e30_f32, f32::INFINITY, f32::NAN] {
        let mut desc = load("textures/displaced.usda").to_scene_desc();
        set_swell(&mut desc, amount);
        let scene = commit(&desc, &mut BlasCache::default()).expect("a bad displacement does not fail the commit");
        let said =
            scene.warnings.iter().any(|w| w.contains("/World/Ball") && w.contains("/World/Looks/Swell") && w.contains("undisplaced"));
        assert!(said, "{amount}: {:?}", scene.warnings);
        let top = hit_point(&scene, Vec3::new(3.0, 5.0, 0.0), -Vec3::Y).expect("hits the ball");
        assert!((top.y - 1.0).abs() < 1e-4, "{amount}: top at {top}");
        assert!((height(&scene, 0.5, 0.5) - 0.25 * 230.0 / 255.0).abs() < 1e-5, "the grid is still displaced");
    }
}

#[test]
fn a_displacement_reading_a_colour_is_reported() {
    let t = load_text(
        "displace-rgb",
        &with_triangle(
            r#"def Material "M"
{
    token outputs:surface.connect = </M/S.outputs:surface>
    def Shader "S"
    {
        uniform token info:id = "UsdPreviewSurface"
        float inputs:displacement.connect = </M/T.outputs:rgb>
        token outputs:surface
    }
    def Shader "T"
    {
        uniform token info:id = "UsdUVTexture"
        float4 inputs:fallback = (1, 1, 1, 1)
        float3 outputs:rgb
    }
}
"#,
        ),
    );
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    let said = scene.warnings.iter().any(|w| w.contains("/M/S") && w.contains("'displacement'") && w.contains("not a float"));
    assert!(said, "{:?}", scene.warnings);
    assert!(height(&scene, 0.2, -0.2).abs() < 1e-5, "not displaced");
}

/// Nothing asked for is dropped silently: a displacement terminal that leads to a shader of its
/// own under a surface that is not MaterialX (an `ND_displacement_float` under a
/// UsdPreviewSurface here) is reported naming the material, terminal and shader, and the
/// surface renders undisplaced.
#[test]
fn a_displacement_shader_tessera_does_not_read_is_reported() {
    let t = load_text(
        "displace-mtlx",
        &with_triangle(
            r#"def Material "M"
{
    token outputs:surface.connect = </M/S.outputs:surface>
    token outputs:mtlx:displacement.connect = </M/D.outputs:out>
    def Shader "S"
    {
        uniform token info:id = "UsdPreviewSurface"
        token outputs:surface
    }
    def Shader "D"
    {
        uniform token info:id = "ND_displacement_float"
        float inputs:displacement = 0.5
        token outputs:out
    }
}
"#,
        ),
    );
    let said = t.warnings.iter().filter(|w| w.contains("/M:") && w.contains("outputs:mtlx:displacement") && w.contains("/M/D")).count();
    assert_eq!(said, 1, "{:?}", t.warnings);
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    assert!(height(&scene, 0.2, -0.2).abs() < 1e-5, "not displaced");
}

/// A MaterialX displacement with a constant amount moves the surface by amount × scale; on a
/// surface that maps onto one of Tessera's own shaders (subsurface here), which do not
/// displace, it is reported naming the surface.
#[test]
fn a_constant_materialx_displacement_moves_the_surface_or_is_reported() {
    let usda = |subsurface: f32| {
        with_triangle(&format!(
            r#"def Material "M"
{{
    token outputs:mtlx:surface.connect = </M/S.outputs:out>
    token outputs:mtlx:displacement.connect = </M/D.outputs:out>
    def Shader "S"
    {{
        uniform token info:id = "ND_standard_surface_surfaceshader"
        float inputs:subsurface = {subsurface}
        token outputs:out
    }}
    def Shader "D"
    {{
        uniform token info:id = "ND_displacement_float"
        float inputs:displacement = 0.5
        float inputs:scale = 0.4
        token outputs:out
    }}
}}
"#
        ))
    };
    let plain = load_text("mtlx-displace", &usda(0.0));
    let scene = commit(&plain.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    assert!((height(&scene, 0.2, -0.2) - 0.2).abs() < 1e-5, "0.5 × 0.4 up: {:?}", plain.warnings);
    let skin = load_text("mtlx-displace-sss", &usda(1.0));
    let said = skin.warnings.iter().any(|w| w.starts_with("/M/S: its displacement has no place on the tessera:SolidDielectric"));
    assert!(said, "{:?}", skin.warnings);
    let scene = commit(&skin.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    assert!(height(&scene, 0.2, -0.2).abs() < 1e-5, "not displaced");
}
