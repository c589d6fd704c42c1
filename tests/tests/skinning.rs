//! UsdSkel skinning: posed points and normals against usd-core's UsdSkel, the render plan, and
//! skinning data that cannot be applied.

use serde_json::Value;
use tessera::usd::{LoadOptions, load_at};
use tessera_tests::*;

/// Largest coordinate difference between two lists of world points.
fn worst_difference(ours: &Value, theirs: &Value) -> f64 {
    let (a, b) = (ours.as_array().expect("points"), theirs.as_array().expect("points"));
    assert_eq!(a.len(), b.len(), "point counts");
    a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |k| (p[k].as_f64().unwrap() - q[k].as_f64().unwrap()).abs())).fold(0.0, f64::max)
}

#[test]
fn skinned_points_agree_with_usd_core_at_and_between_frames() {
    // The arm exercises what the characters do not: blend shapes (one with an in-between, one
    // past weight 1), a reordered skel:joints subset, an animation missing a joint, a rigid
    // binding, a geomBindTransform and a non-uniform joint scale.
    let cases = [
        ("usd/skinned_arm.usda", [1.0, 3.25, 10.0]),
        ("usd-wg/UsdSkel/RiggedSimple.usdz", [1.0, 17.5, 50.0]),
        ("usd-wg/UsdSkel/RiggedFigure.usdz", [0.0, 12.6, 30.0]),
        ("usd-wg/UsdSkel/CesiumMan.usdz", [1.0, 30.2, 48.0]),
    ];
    let mut points = 0;
    let at_frames: Vec<(&str, f64)> = cases.iter().flat_map(|(scene, frames)| frames.map(|f| (*scene, f))).collect();
    let all_theirs = usd_core_reads_all(&at_frames.iter().map(|(scene, f)| (fixture(scene), Some(*f))).collect::<Vec<_>>());
    for ((scene, frame), theirs) in at_frames.into_iter().zip(all_theirs) {
        let ours = tessera::commands::inspect::inspect(&fixture(scene), LoadOptions { frame: Some(frame), ..Default::default() })
            .unwrap_or_else(|e| panic!("{scene}: {e:#}"));
        for (path, expected) in theirs["meshes"].as_object().unwrap().iter().filter(|(_, m)| m.get("skinning").is_some()) {
            let actual = &ours["meshes"][path];
            let at = format!("{scene} frame {frame} {path}");
            assert_eq!(actual["skinning"]["skeleton"], expected["skinning"]["skeleton"], "{at}");
            assert_eq!(actual["skinning"]["animation"], expected["skinning"]["animation"], "{at}");
            // The skeleton's world matrix, f32 in ours.
            assert!(worst_difference(&json_rows(&actual["world"]), &json_rows(&expected["world"])) < 1e-6, "{at}: world");
            // Posed points: both readers sum f32 points through f64 matrices; 1e-5 is f32
            // rounding at these assets' scale (about 1-5 units).
            let d = worst_difference(&actual["skinning"]["worldPoints"], &expected["skinning"]["worldPoints"]);
            assert!(d < 1e-5, "{at}: skinned points differ by up to {d}");
            points += expected["skinning"]["worldPoints"].as_array().unwrap().len();
        }
    }
    // 3 frames each of 208 + 8 (arm, hand), 160, 370 and 3273 points.
    assert_eq!(points, 3 * (216 + 160 + 370 + 3273));
}

/// A flattened 4x4 matrix as four rows of four.
fn json_rows(m: &Value) -> Value {
    Value::Array(m.as_array().expect("matrix").chunks(4).map(|r| Value::Array(r.to_vec())).collect())
}

#[test]
fn skinned_normals_turn_with_the_joints_as_usd_core_bakes_them() {
    // Frame 10 is a time sample, where BakeSkinning's baked normals are exact; the elbow's
    // scale (1, 1.2, 0.8) there makes the inverse transpose matter.
    let script = r#"
import json, sys
from pxr import Usd, UsdSkel, UsdGeom
stage = Usd.Stage.Open(sys.argv[1])
UsdSkel.BakeSkinning(stage.Traverse())
mesh = stage.GetPrimAtPath("/World/Rig/Arm")
world = UsdGeom.XformCache(10).GetLocalToWorldTransform(mesh)
print(json.dumps([list(world.TransformDir(n).GetNormalized()) for n in UsdGeom.Mesh(mesh).GetNormalsAttr().Get(10)]))
"#;
    let out =
        std::process::Command::new("python3").args(["-c", script]).arg(fixture("usd/skinned_arm.usda")).output().expect("python3 runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let theirs: Vec<[f32; 3]> = serde_json::from_slice(&out.stdout).expect("normals");
    let t = load_at(&fixture("usd/skinned_arm.usda"), Some(10.0)).expect("loads");
    let arm = &t.meshes.iter().find(|(p, _)| p == "/World/Rig/Arm").expect("the arm").1;
    let render_core::geometry::Attribute::Vertex(normals) = &arm.mesh.normals else { panic!("vertex normals expected") };
    assert_eq!(normals.len(), theirs.len());
    let worst = normals
        .iter()
        .zip(&theirs)
        .map(|(n, e)| (arm.transform.transform_vector3(*n).normalize() - glam::Vec3::from_array(*e)).length())
        .fold(0.0f32, f32::max);
    // f32 rounding of unit vectors through two matrices.
    assert!(worst < 1e-5, "skinned normals differ from usd-core's by up to {worst}");
}

#[test]
fn the_render_plan_names_the_skinned_meshes_and_their_animation() {
    let plan = tessera::commands::render::explain_plan(&fixture("usd/skinned_arm.usda"), LoadOptions::default()).expect("plan");
    let line = plan.lines().position(|l| l.contains("+ skinning")).unwrap_or_else(|| panic!("no skinning entry:\n{plan}"));
    let prims = plan.lines().nth(line + 1).unwrap();
    assert!(prims.contains("/World/Rig/Arm (/World/Rig/Skel/Anim)") && prims.contains("/World/Rig/Hand"), "{prims}");
    // A scene without skeletons pays nothing and says nothing about skinning.
    let plan = tessera::commands::render::explain_plan(&fixture("cornell_box.usda"), LoadOptions::default()).expect("plan");
    assert!(!plan.contains("skinning"), "{plan}");
}

/// A SkelRoot holding a skeleton (`skeleton`: the Skeleton's body) and a quad bound to it
/// (`binding`: spliced into the mesh's body).
fn rig(skeleton: &str, binding: &str) -> String {
    format!(
        r#"#usda 1.0
def SkelRoot "Rig"
{{
    def Skeleton "Skel"
    {{
        {skeleton}
    }}
    def Mesh "Quad" (prepend apiSchemas = ["SkelBindingAPI"])
    {{
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token subdivisionScheme = "none"
        double3 xformOp:translate = (0, 0, 7)
        uniform token[] xformOpOrder = ["xformOp:translate"]
        rel skel:skeleton = </Rig/Skel>
        {binding}
    }}
}}
"#
    )
}

/// Two joints; B rests 2 along x and was bound at 1.
const SKELETON: &str = r#"uniform token[] joints = ["A", "A/B"]
        uniform matrix4d[] bindTransforms = [( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) ), ( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (1, 0, 0, 1) )]
        uniform matrix4d[] restTransforms = [( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) ), ( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (2, 0, 0, 1) )]"#;

/// Joint influences: `indices` and `weights` as USD arrays, `elementSize` `per`.
fn influences(indices: &str, weights: &str, per: u64) -> String {
    format!(
        r#"int[] primvars:skel:jointIndices = {indices} (interpolation = "vertex" elementSize = {per})
        float[] primvars:skel:jointWeights = {weights} (interpolation = "vertex" elementSize = {per})"#
    )
}

#[test]
fn a_valid_rig_poses_the_quad_in_skeleton_space() {
    // The control for the hostile cases below: joint B's rest pose moves the quad 1 in x
    // (rest 2 - bind 1), and the mesh's own z translation is ignored, as UsdSkel says.
    let t = load_text("rig_ok", &rig(SKELETON, &influences("[1, 1, 1, 1]", "[1, 1, 1, 1]", 1)));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    let quad = &t.meshes.iter().find(|(p, _)| p == "/Rig/Quad").expect("the quad").1;
    let world: Vec<glam::Vec3> = quad.mesh.positions.iter().map(|&p| quad.transform.transform_point3(p)).collect();
    assert_eq!(world[0], glam::Vec3::new(1.0, 0.0, 0.0));
    assert_eq!(world[2], glam::Vec3::new(2.0, 1.0, 0.0));
}

#[test]
fn skinning_data_that_cannot_apply_leaves_the_mesh_in_rest_pose_naming_the_attribute() {
    // The largest count a client controls here is the joints: 20000 of them, bound but with
    // no rest transforms and no animation.
    let n = 20_000;
    let identity = "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )";
    let many = format!(
        "uniform token[] joints = [{}]\n        uniform matrix4d[] bindTransforms = [{}]",
        (0..n).map(|i| format!("\"j{i}\"")).collect::<Vec<_>>().join(", "),
        vec![identity; n].join(", ")
    );
    let ok = influences("[1, 1, 1, 1]", "[1, 1, 1, 1]", 1);
    let shape = |indices: &str| {
        format!(
            "{ok}\n        uniform token[] skel:blendShapes = [\"s\"]\n        rel skel:blendShapeTargets = </Rig/Quad/S>\n        def BlendShape \"S\" {{ uniform vector3f[] offsets = [(0, 0, 1)]\n uniform int[] pointIndices = {indices} }}"
        )
    };
    // Closes the Skeleton early to add a SkelAnimation beside it (the template closes that).
    let animated = |body: &str| {
        format!("{SKELETON}\n        rel skel:animationSource = </Rig/Anim>\n    }}\n    def SkelAnimation \"Anim\" {{\n        {body}")
    };
    let cases: Vec<(&str, String, String, &str)> = vec![
        ("an index out of range", SKELETON.into(), influences("[1, 7, 1, 1]", "[1, 1, 1, 1]", 1), "jointIndices holds 7"),
        ("a negative index", SKELETON.into(), influences("[1, -1, 1, 1]", "[1, 1, 1, 1]", 1), "jointIndices holds -1"),
        ("too few influences", SKELETON.into(), influences("[1, 1]", "[1, 1]", 1), "jointIndices has 2 entries for 4 points"),
        ("a huge elementSize", SKELETON.into(), influences("[1, 1, 1, 1]", "[1, 1, 1, 1]", 1 << 40), "elementSize 1099511627776"),
        ("fewer weights", SKELETON.into(), influences("[1, 1, 1, 1]", "[1]", 1), "jointWeights 1"),
        ("a NaN weight", SKELETON.into(), influences("[1, 1, 1, 1]", "[nan, 1, 1, 1]", 1), "jointWeights holds NaN"),
        (
            "a third joint unbound",
            SKELETON.replace("\"A/B\"]", "\"A/B\", \"C\"]"),
            ok.clone(),
            "'bindTransforms' has 2 matrices for 3 joints",
        ),
        ("a child before its parent", SKELETON.replace("[\"A\", \"A/B\"]", "[\"A/B\", \"A\"]"), ok.clone(), "attribute 'joints'"),
        ("20000 joints without rest", many, influences("[1, 1, 1, 1]", "[1, 1, 1, 1]", 1), "neither animated nor given a rest transform"),
        (
            "a long rotations array",
            animated("uniform token[] joints = [\"A/B\"]\n        quatf[] rotations = [(1, 0, 0, 0), (1, 0, 0, 0)]"),
            ok.clone(),
            "'rotations' has 2 entries for 1",
        ),
        (
            "blend shape indices",
            animated("uniform token[] blendShapes = [\"s\"]\n        float[] blendShapeWeights = [1]"),
            shape("[9]"),
            "'pointIndices' holds 9",
        ),
    ];
    for (what, skeleton, binding, expected) in cases {
        let t = load_text("rig_bad", &rig(&skeleton, &binding));
        let quad = &t.meshes.iter().find(|(p, _)| p == "/Rig/Quad").unwrap_or_else(|| panic!("{what}: the quad still renders")).1;
        assert!(
            t.warnings.iter().any(|w| w.contains("/Rig/") && w.contains(expected) && w.contains("rest pose")),
            "{what}: {:?}",
            t.warnings
        );
        // Rest pose: the authored points where the mesh's own transform puts them.
        assert_eq!(quad.transform.transform_point3(quad.mesh.positions[2]), glam::Vec3::new(1.0, 1.0, 7.0), "{what}");
        assert!(t.skinned.is_empty(), "{what}");
    }
}

#[test]
fn a_mesh_bound_without_influences_stays_as_authored_with_a_warning() {
    // usd-core's SkinningQuery has nothing to deform it with either (HasJointInfluences false).
    let t = load_text("rig_bare", &rig(SKELETON, ""));
    assert!(t.skinned.is_empty());
    assert!(t.warnings.iter().any(|w| w.contains("/Rig/Quad") && w.contains("no joint influences")), "{:?}", t.warnings);
    let quad = &t.meshes.iter().find(|(p, _)| p == "/Rig/Quad").expect("the quad").1;
    assert_eq!(quad.transform.transform_point3(quad.mesh.positions[2]), glam::Vec3::new(1.0, 1.0, 7.0));
}

/// Deformation blur of a skinned mesh: with the shutter open over frames 5 to 6, each of its
/// deformation samples is the mesh as the reader poses it at that sample's time (checked
/// against usd-core above), in world space: the skeleton's pose is sampled over the shutter.
#[test]
fn a_skinned_mesh_blurs_through_the_poses_of_its_shutter() {
    let scene = fixture("usd/skinned_arm.usda");
    let open = tessera::usd::load_with(&scene, LoadOptions { frame: Some(5.5), shutter: Some((-0.5, 0.5)), ..Default::default() }).unwrap();
    assert!(open.warnings.is_empty(), "{:?}", open.warnings);
    let world = |m: &render_core::scene::MeshDesc, points: &[glam::Vec3]| -> Vec<glam::Vec3> {
        points.iter().map(|p| m.transform.transform_point3(*p)).collect()
    };
    let (path, arm) = open.meshes.iter().find(|(_, m)| m.mesh.deformation_samples() > 0).expect("a deforming skinned mesh");
    let k = arm.mesh.deformation_samples();
    assert_eq!(k, tessera::usd::DEFAULT_MOTION_SAMPLES);
    let n = arm.mesh.positions.len();
    let mut worst = 0.0f32;
    for s in 0..k {
        let time = 5.0 + s as f64 / (k - 1) as f64;
        let at = load_at(&scene, Some(time)).unwrap();
        let (_, there) = at.meshes.iter().find(|(p, _)| p == path).unwrap();
        let ours = world(arm, &arm.mesh.deformation[s * n..(s + 1) * n]);
        for (a, b) in ours.iter().zip(world(there, &there.mesh.positions)) {
            worst = worst.max(a.distance(b));
        }
    }
    // Single-precision skinning of the same rig twice, by two routes through the matrices.
    assert!(worst < 1e-5, "worst point difference {worst}");
    // The samples differ: the arm bends within the shutter.
    assert_ne!(arm.mesh.deformation[..n], arm.mesh.deformation[(k - 1) * n..]);
}
