//! Motion blur: transform motion over the camera's shutter against closed forms, still scenes
//! untouched by an open shutter, and motion data a client cannot send.

use tessera::usd::{LoadOptions, Translation, load_with};
use tessera_tests::lit_plane::{assert_plane_radiance, polygon_irradiance};
use tessera_tests::*;

/// Image size and scale of [`ortho_stage`]'s camera: 128 pixels over 4 units.
const SIZE: u32 = 128;
const PX_PER_UNIT: f64 = 32.0;

/// A layer with an orthographic camera looking down −Z at 4×4 units around the origin, its
/// shutter open from frame 0 to 1, and `body` (prims, time-sampled over frames 0 to 1).
fn ortho_stage(body: &str) -> String {
    format!(
        r#"#usda 1.0
(
    startTimeCode = 0
    endTimeCode = 1
)
{}
{body}
"#,
        ortho_camera_and_dome_usda(40.0, "double shutter:open = 0\n    double shutter:close = 1")
    )
}

/// A sphere of radius `r` translating along x from `x0` at frame 0 to `x1` at frame 1.
fn moving_sphere(r: f64, x0: f64, x1: f64) -> String {
    format!(
        r#"def Sphere "Ball"
{{
    double radius = {r}
    double3 xformOp:translate.timeSamples = {{ 0: ({x0}, 0, 0), 1: ({x1}, 0, 0) }}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}"#
    )
}

/// The coverage (alpha) image of `t`, 128² at `spp`.
async fn coverage(t: &Translation, spp: u32) -> Vec<f64> {
    let (server, mut conn) = session_with(t).await;
    let report = conn.render(&small(SIZE, SIZE, spp), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).map(|(x, y)| report.image.pixel("beauty", x, y)[3] as f64).collect()
}

/// The fraction of the shutter during which a disc of radius `r` sliding from `x0` to `x1`
/// covers pixel (`px`, `py`), averaged over the pixel (8×8 points): the closed form of a
/// streak, a box filter of the silhouette along the path.
fn streak(px: u32, py: u32, r: f64, x0: f64, x1: f64) -> f64 {
    let mut sum = 0.0;
    for (i, j) in (0..8).flat_map(|i| (0..8).map(move |j| (i, j))) {
        let x = (px as f64 + (i as f64 + 0.5) / 8.0 - 64.0) / PX_PER_UNIT;
        let y = (64.0 - py as f64 - (j as f64 + 0.5) / 8.0) / PX_PER_UNIT;
        if y.abs() >= r {
            continue;
        }
        let h = (r * r - y * y).sqrt();
        // Centres s in [x0, x1] with |x − s| < h.
        let overlap = ((x + h).min(x1.max(x0)) - (x - h).max(x1.min(x0))).max(0.0);
        sum += overlap / (x1 - x0).abs();
    }
    sum / 64.0
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sphere_moving_in_a_line_renders_the_streak_of_its_silhouette() {
    let (r, x0, x1) = (0.5, -1.0, 1.0);
    let t = load_text("motion_line", &ortho_stage(&moving_sphere(r, x0, x1)));
    assert!(t.meshes.iter().any(|(p, m)| p == "/Ball" && m.motion.len() == tessera::usd::DEFAULT_MOTION_SAMPLES), "the ball moves");
    let seen = coverage(&t, 64).await;
    let expected: Vec<f64> = (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).map(|(x, y)| streak(x, y, r, x0, x1)).collect();
    let mean_error =
        seen.iter().zip(&expected).map(|(a, b)| (a - b).abs()).sum::<f64>() / expected.iter().filter(|e| **e > 0.0).count() as f64;
    // Per covered pixel, 64 time samples stratified by Sobol: the streak's edges carry the
    // error (about 1/64 each); 0.01 also allows the tessellated silhouette.
    assert!(mean_error < 0.01, "mean |error| over the streak {mean_error:.4}");
    // The plateau in the middle: covered half the shutter (2h / |x1 − x0| = 1/2).
    let centre = seen[(63 * SIZE + 64) as usize];
    assert!((centre - 0.5).abs() < 0.03, "centre coverage {centre}");
    // Area is conserved: the streak holds the disc's π r² (in pixels), as a still one does.
    let total: f64 = seen.iter().sum();
    let disc = std::f64::consts::PI * (r * PX_PER_UNIT).powi(2);
    assert!((total / disc - 1.0).abs() < 0.01, "total coverage {total:.1}, a disc {disc:.1}");
}

/// Two references to one quad asset (0.5 × 0.5 units, facing the camera, with a material so
/// native instancing takes it): /Moving slides from x = −1 to 1 over the shutter, /Still stays
/// at y = 1.5; both `instanceable` or neither.
fn instanced_quads(instanceable: bool) -> String {
    let quad = r#"class "Asset"
{
    def Mesh "Quad" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        point3f[] points = [(-0.25, -0.25, 0), (0.25, -0.25, 0), (0.25, 0.25, 0), (-0.25, 0.25, 0)]
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token subdivisionScheme = "none"
        rel material:binding = </Looks/Grey>
    }
}
def Scope "Looks"
{
    def Material "Grey"
    {
        token outputs:surface.connect = </Looks/Grey/Surface.outputs:surface>
        def Shader "Surface"
        {
            uniform token info:id = "UsdPreviewSurface"
            token outputs:surface
        }
    }
}"#;
    format!(
        r#"{quad}
def Xform "Moving" (instanceable = {instanceable} references = </Asset>)
{{
    double3 xformOp:translate.timeSamples = {{ 0: (-1, 0, 0), 1: (1, 0, 0) }}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def Xform "Still" (instanceable = {instanceable} references = </Asset>)
{{
    double3 xformOp:translate = (0, 1.5, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}"#
    )
}

/// Instanceable prims move as the same prims flattened do: the native instancer carries each
/// instance's placements over the shutter (the still one's repeated), and the blur is the flat
/// meshes' pixel for pixel.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn instanceable_prims_blur_as_their_flattened_meshes_do() {
    let native = load_text("motion_native", &ortho_stage(&instanced_quads(true)));
    let flat = load_text("motion_flat", &ortho_stage(&instanced_quads(false)));
    assert!(native.warnings.is_empty(), "{:?}", native.warnings);
    let k = tessera::usd::DEFAULT_MOTION_SAMPLES;
    let (_, instancer) = native.instancers.iter().find(|(_, i)| i.transforms.len() == 2).expect("one native instancer, two instances");
    assert_eq!(instancer.motion_samples(), k);
    let moving = flat.meshes.iter().find(|(p, _)| p == "/Moving/Quad").expect("the flat moving quad");
    assert_eq!(&instancer.motion[..k], &moving.1.motion[..], "the moving instance's samples are the flat mesh's");
    assert!(instancer.motion[k..].iter().all(|m| *m == instancer.transforms[1]), "the still instance repeats its placement");
    let (a, b) = (coverage(&native, 64).await, coverage(&flat, 64).await);
    // Two quads of 16 × 16 px: the moving one smeared over 80 px, its area conserved.
    let total: f64 = a.iter().sum();
    assert!((total / 512.0 - 1.0).abs() < 0.01, "native coverage {total:.1} of 512");
    // Same samples, same placements per ray, the same local points: the same pixels.
    assert!(a == b, "native and flat coverage differ");
}

/// A PointInstancer placing one ball (radius `r`) at x = `x0` at frame 0; its motion comes
/// from `motion` (time samples of `positions`, or `velocities`).
fn instanced_ball(r: f64, motion: &str) -> String {
    format!(
        r#"def PointInstancer "Balls"
{{
    rel prototypes = </Balls/Protos/Ball>
    int[] protoIndices = [0]
    {motion}
    def Scope "Protos"
    {{
        def Sphere "Ball" {{ double radius = {r} }}
    }}
}}"#
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn point_instances_blur_with_their_positions_and_velocities() {
    // The same streak as the lone sphere's, from time-sampled positions, and from velocities
    // (2 units over the shutter's one frame at 24 frames per second: 48 units per second).
    let expected: Vec<f64> = (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).map(|(x, y)| streak(x, y, 0.5, -1.0, 1.0)).collect();
    for (what, motion) in [
        ("positions", "point3f[] positions.timeSamples = { 0: [(-1, 0, 0)], 1: [(1, 0, 0)] }"),
        ("velocities", "point3f[] positions = [(-1, 0, 0)]\n    vector3f[] velocities = [(48, 0, 0)]"),
    ] {
        let t = load_text("motion_instances", &ortho_stage(&instanced_ball(0.5, motion)));
        let (_, inst) = t.instancers.iter().find(|(k, _)| k.starts_with("/Balls")).expect("an instancer");
        assert_eq!(inst.motion_samples(), tessera::usd::DEFAULT_MOTION_SAMPLES, "{what}");
        let seen = coverage(&t, 64).await;
        let covered = expected.iter().filter(|e| **e > 0.0).count() as f64;
        let mean_error = seen.iter().zip(&expected).map(|(a, b)| (a - b).abs()).sum::<f64>() / covered;
        assert!(mean_error < 0.01, "{what}: mean |error| over the streak {mean_error:.4}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_moving_camera_blurs_still_geometry_as_the_geometry_moving_the_other_way_would() {
    let still_ball = "def Sphere \"Ball\" { double radius = 0.5 }";
    let layer = ortho_stage(still_ball)
        .replace("double3 xformOp:translate = (0, 0, 10)", "double3 xformOp:translate.timeSamples = { 0: (1, 0, 10), 1: (-1, 0, 10) }");
    let t = load_text("motion_camera", &layer);
    assert!(t.cameras[0].1.motion.len() >= 2, "the camera moves");
    let seen = coverage(&t, 64).await;
    let expected: Vec<f64> = (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).map(|(x, y)| streak(x, y, 0.5, -1.0, 1.0)).collect();
    let mean_error =
        seen.iter().zip(&expected).map(|(a, b)| (a - b).abs()).sum::<f64>() / expected.iter().filter(|e| **e > 0.0).count() as f64;
    assert!(mean_error < 0.01, "mean |error| over the streak {mean_error:.4}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rotating_object_blurs_along_its_arc_not_its_chord() {
    // A ball of radius 0.15 one unit from the origin, its parent turning 90° about z over the
    // shutter: the streak follows the quarter circle. At 45° on the arc it is covered for
    // the ball's angular width over the sweep, 2·asin(0.15)/(π/2) = 19% of the shutter; the
    // chord's midpoint, 0.29 units inside the arc, is never covered.
    let body = r#"def Xform "Turn"
{
    float xformOp:rotateZ.timeSamples = { 0: 0, 1: 90 }
    uniform token[] xformOpOrder = ["xformOp:rotateZ"]
    def Sphere "Ball"
    {
        double radius = 0.15
        double3 xformOp:translate = (1, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}"#;
    let t = load_text("motion_arc", &ortho_stage(body));
    assert_quarter_arc(&coverage(&t, 64).await);
}

/// The coverage of a ball of radius 0.15 turned 90° about z over the shutter from (1, 0, 0):
/// 19% at 45° on the arc, nothing at the chord's midpoint, something at both ends.
fn assert_quarter_arc(seen: &[f64]) {
    let at = |x: f64, y: f64| seen[((64.0 - y * PX_PER_UNIT) as u32 * SIZE + (64.0 + x * PX_PER_UNIT) as u32) as usize];
    let d = std::f64::consts::FRAC_1_SQRT_2;
    let on_arc = at(d, d);
    let expected = 2.0 * 0.15f64.asin() / std::f64::consts::FRAC_PI_2;
    assert!((on_arc - expected).abs() < 0.03, "on the arc {on_arc:.3}, expected {expected:.3}");
    assert_eq!(at(0.5, 0.5), 0.0, "the chord's midpoint");
    // The ends of the sweep are where the ball starts and stops.
    assert!(at(1.0, 0.0) > 0.0 && at(0.0, 1.0) > 0.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn point_instances_turn_with_their_angular_velocities() {
    // One instance at the origin of a prototype ball one unit out along x, turning at 2160°/s
    // about z: 90° over the shutter's one frame at 24 frames per second, the arc above.
    let spin = |orientation: &str| {
        format!(
            r#"def PointInstancer "Spin"
{{
    rel prototypes = </Spin/Protos/Ball>
    int[] protoIndices = [0]
    point3f[] positions = [(0, 0, 0)]
    quath[] orientations = [{orientation}]
    vector3f[] angularVelocities = [(0, 0, 2160)]
    def Scope "Protos"
    {{
        def Sphere "Ball"
        {{
            double radius = 0.15
            double3 xformOp:translate = (1, 0, 0)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }}
    }}
}}"#
        )
    };
    let t = load_text("motion_spin", &ortho_stage(&spin("(1, 0, 0, 0)")));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    assert_quarter_arc(&coverage(&t, 64).await);
    // The turn follows the orientation about the instancer's axes, as usd-core's
    // ComputeInstanceTransformsAtTime composes them (checked there): a ball first turned 90°
    // about y to (0, 0, -1) lies on the z axis and stays there, a still disc at the centre.
    let t = load_text("motion_spin_oriented", &ortho_stage(&spin("(0.7071068, 0, 0.7071068, 0)")));
    let seen = coverage(&t, 64).await;
    let disc = std::f64::consts::PI * (0.15 * PX_PER_UNIT).powi(2);
    let total: f64 = seen.iter().sum();
    assert!((total / disc - 1.0).abs() < 0.05, "coverage {total:.1}, a still disc {disc:.1}");
    assert!(seen[(64 * SIZE + 64) as usize] > 0.99, "the disc sits at the centre");
    // One angular velocity too many: said, and the instance keeps its sampled orientation.
    let t = load_text("motion_spin_bad", &ortho_stage(&spin("(1, 0, 0, 0)").replace("[(0, 0, 2160)]", "[(0, 0, 2160), (0, 0, 1)]")));
    assert!(t.warnings.iter().any(|w| w.contains("'angularVelocities' has 2 entries for 1 instances")), "{:?}", t.warnings);
    assert!(t.instancers.iter().all(|(_, i)| i.motion.is_empty()), "nothing turns");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_still_scene_renders_the_same_with_the_shutter_open_or_closed() {
    let scene = fixture("cornell_box.usda");
    let closed = load_with(&scene, LoadOptions { shutter: Some((0.0, 0.0)), ..Default::default() }).expect("loads");
    let open = load_with(&scene, LoadOptions { shutter: Some((-0.5, 0.5)), ..Default::default() }).expect("loads");
    assert!(open.meshes.iter().all(|(_, m)| m.motion.is_empty()), "nothing moves");
    let render = |t: Translation| async move {
        let (server, mut conn) = session_with(&t).await;
        let report = conn.render(&small(32, 32, 4), |_| {}).await.expect("renders");
        server.stop().await.expect("stops");
        report
    };
    let (a, b) = (render(closed).await, render(open).await);
    assert!(!a.started.plan.iter().any(|p| p.effect == "motion-blur"), "{:?}", a.started.plan);
    assert!(!b.started.plan.iter().any(|p| p.effect == "motion-blur"), "an open shutter over a still scene costs nothing");
    assert_eq!(a.image.layers["beauty"].1, b.image.layers["beauty"].1, "bit for bit");
}

#[test]
fn the_plan_names_what_moves_and_the_shutter_can_be_overridden() {
    let layer = ortho_stage(&moving_sphere(0.5, -1.0, 1.0));
    let dir = std::env::temp_dir().join(format!("tessera-motion-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("moving.usda");
    std::fs::write(&file, layer).unwrap();
    let plan = tessera::commands::render::explain_plan(&file, LoadOptions::default()).expect("plan");
    assert!(plan.lines().any(|l| l.contains("+ motion-blur")), "{plan}");
    // A closed shutter given on the command line: the ball stands at its frame-0 place.
    let closed = load_with(&file, LoadOptions { shutter: Some((0.0, 0.0)), ..Default::default() }).unwrap();
    assert!(closed.meshes.iter().all(|(_, m)| m.motion.is_empty()));
    // More samples, as asked.
    let dense = load_with(&file, LoadOptions { motion_samples: 17, ..Default::default() }).unwrap();
    assert_eq!(dense.meshes.iter().find(|(p, _)| p == "/Ball").unwrap().1.motion.len(), 17);
    std::fs::remove_dir_all(&dir).ok();
}
#[test]
fn whole_number_time_samples_interpolate_between_keys() {
    // openusd 0.6 parsed `{0: 0, 1: 90}` (as usdcat writes whole floats) as ints and held them
    // at 0 until frame 1; usd-core interpolates to 45° at frame 0.5, and so must we (the
    // vendored parser reads them as the declared float: third_party/openusd/PATCHES.md, 12).
    let layer = ortho_stage("").replace(
        "def DomeLight",
        "def Xform \"Turn\" {\n    float xformOp:rotateZ.timeSamples = { 0: 0, 1: 90 }\n    uniform token[] xformOpOrder = [\"xformOp:rotateZ\"]\n    def Cube \"Box\" { double3 xformOp:translate = (1, 0, 0)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n}\ndef DomeLight",
    );
    let dir = std::env::temp_dir().join(format!("tessera-motion-int-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("turn.usda");
    std::fs::write(&file, layer).unwrap();
    let t = load_with(&file, LoadOptions { frame: Some(0.5), shutter: Some((0.0, 0.0)), ..Default::default() }).unwrap();
    let placed = t.meshes.iter().find(|(p, _)| p == "/Turn/Box").unwrap().1.transform.translation;
    let d = std::f32::consts::FRAC_1_SQRT_2;
    assert!((placed - glam::Vec3A::new(d, d, 0.0)).length() < 1e-6, "{placed}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A transform animated by a spline (USD 25.05) blurs as a time-sampled one does: the reader
/// samples transforms over the shutter, whatever animates them. x rises linearly from 0 at
/// frame 0 to 10 at frame 10, so the shutter [4.75, 5.25] spans x = 4.75 to 5.25.
#[test]
fn a_transform_animated_by_a_spline_blurs() {
    let layer = "#usda 1.0\ndef Cube \"Box\"\n{\n    double xformOp:translateX.spline = {\n        0: 0; post linear,\n        10: 10; post held,\n    }\n    uniform token[] xformOpOrder = [\"xformOp:translateX\"]\n}\n";
    let dir = std::env::temp_dir().join(format!("tessera-motion-spline-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("spline.usda");
    std::fs::write(&file, layer).unwrap();
    let options = LoadOptions { frame: Some(5.0), shutter: Some((-0.25, 0.25)), motion_samples: 3, ..Default::default() };
    let t = load_with(&file, options).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let xs: Vec<f32> = t.meshes[0].1.motion.iter().map(|m| m.translation.x).collect();
    assert_eq!(xs, [4.75, 5.0, 5.25]);
}

/// A UV sphere mesh of radius 1 (`rings` × `segments` quads) whose points are scaled from
/// `r0` at frame 0 to `r1` at frame 1, as USD interpolates time-sampled points: linearly; or,
/// `by_velocity`, points of radius `r0` with radial velocities that reach `r1` one frame (1/24
/// s) later.
fn pulsing_sphere(r0: f64, r1: f64, rings: usize, segments: usize, by_velocity: bool) -> String {
    let mut unit = Vec::new();
    for i in 0..=rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            unit.push((theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()));
        }
    }
    let points = |r: f64| unit.iter().map(|(x, y, z)| format!("({}, {}, {})", x * r, y * r, z * r)).collect::<Vec<_>>().join(", ");
    let quads: Vec<String> = (0..rings)
        .flat_map(|i| (0..segments).map(move |j| (i, j)))
        .map(|(i, j)| {
            let (a, b) = (i * segments, (i + 1) * segments);
            let j1 = (j + 1) % segments;
            format!("{}, {}, {}, {}", a + j, b + j, b + j1, a + j1)
        })
        .collect();
    let motion = match by_velocity {
        false => format!("point3f[] points.timeSamples = {{ 0: [{}], 1: [{}] }}", points(r0), points(r1)),
        true => format!("point3f[] points = [{}]\n    vector3f[] velocities = [{}]", points(r0), points(24.0 * (r1 - r0))),
    };
    format!(
        r#"def Mesh "Pulse"
{{
    uniform token subdivisionScheme = "none"
    int[] faceVertexCounts = [{}]
    int[] faceVertexIndices = [{}]
    {motion}
}}"#,
        vec!["4"; rings * segments].join(", "),
        quads.join(", "),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pulsing_sphere_blurs_over_the_radii_it_takes() {
    // The radius grows linearly from 0.5 to 1 over the shutter, from time-sampled points and
    // from velocities (USD's velocity-based motion). A pixel at distance d from
    // the centre is covered while r(t) ≥ d: always inside 0.5, a fraction (1 − d)/0.5 of the
    // shutter between; the coverage sums to ∫ π r(t)² dt = π(1³ − 0.5³)/(3·0.5) = 1.833 units².
    let (r0, r1) = (0.5, 1.0);
    for by_velocity in [false, true] {
        let t = load_text("motion_pulse", &ortho_stage(&pulsing_sphere(r0, r1, 32, 96, by_velocity)));
        assert!(t.warnings.is_empty(), "{:?}", t.warnings);
        let (_, pulse) = t.meshes.iter().find(|(p, _)| p == "/Pulse").expect("the sphere");
        assert_eq!(pulse.mesh.deformation_samples(), tessera::usd::DEFAULT_MOTION_SAMPLES);
        assert_pulse(&coverage(&t, 64).await, r0, r1);
    }
    // With the shutter closed it keeps the frame's shape: no deformation, no motion blur.
    let layer = ortho_stage(&pulsing_sphere(r0, r1, 8, 16, false)).replace("shutter:close = 1", "shutter:close = 0");
    let closed = load_text("motion_pulse_closed", &layer);
    assert!(closed.meshes.iter().all(|(_, m)| m.mesh.deformation.is_empty()));
}

/// The coverage of a disc whose radius grows linearly from `r0` to `r1` over the shutter.
fn assert_pulse(seen: &[f64], r0: f64, r1: f64) {
    let fraction = |px: u32, py: u32| -> f64 {
        let mut sum = 0.0;
        for (i, j) in (0..8).flat_map(|i| (0..8).map(move |j| (i, j))) {
            let x = (px as f64 + (i as f64 + 0.5) / 8.0 - 64.0) / PX_PER_UNIT;
            let y = (64.0 - py as f64 - (j as f64 + 0.5) / 8.0) / PX_PER_UNIT;
            let d = x.hypot(y);
            sum += ((r1 - d) / (r1 - r0)).clamp(0.0, 1.0);
        }
        sum / 64.0
    };
    let expected: Vec<f64> = (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).map(|(x, y)| fraction(x, y)).collect();
    let total: f64 = seen.iter().sum();
    let area = std::f64::consts::PI * (r1.powi(3) - r0.powi(3)) / (3.0 * (r1 - r0)) * PX_PER_UNIT * PX_PER_UNIT;
    // 96 segments: the polygon's area is 0.07% short of the circle's; measured 0.04% short.
    assert!((total / area - 1.0).abs() < 0.005, "coverage {total:.1}, the closed form {area:.1}");
    let ring: Vec<usize> = (0..expected.len()).filter(|&i| expected[i] > 0.0 && expected[i] < 1.0).collect();
    let mean_error = ring.iter().map(|&i| (seen[i] - expected[i]).abs()).sum::<f64>() / ring.len() as f64;
    // Measured 0.0096 at 64 samples per pixel (the five shape samples are exact: the radius
    // grows linearly); the bound leaves the noise room.
    assert!(mean_error < 0.02, "mean |error| over the growing ring {mean_error:.4}");
}

/// A mesh with no points, time-sampled over an open shutter, loads as an empty mesh: there is
/// no shape to sample (comparing its samples once divided by its zero points).
#[test]
fn an_empty_mesh_time_sampled_over_the_shutter_loads() {
    let body = r#"def Mesh "Nothing"
{
    uniform token subdivisionScheme = "none"
    int[] faceVertexCounts = []
    int[] faceVertexIndices = []
    point3f[] points.timeSamples = { 0: [], 1: [] }
}"#;
    let t = load_text("motion_empty", &ortho_stage(body));
    assert!(t.meshes.iter().all(|(_, m)| m.mesh.deformation.is_empty()));
}

/// A diffuse floor (y = 0, albedo 0.5) seen from 0.3 above by a camera looking down, its
/// shutter open over frames 0 to 1, under `light`: the stage of the moving-light tests.
fn lit_floor_stage(light: &str) -> String {
    format!(
        r#"#usda 1.0
(
    startTimeCode = 0
    endTimeCode = 1
    upAxis = "Y"
)
def Material "Grey"
{{
    token outputs:surface.connect = </Grey/Surface.outputs:surface>
    def Shader "Surface"
    {{
        uniform token info:id = "UsdPreviewSurface"
        color3f inputs:diffuseColor = (0.5, 0.5, 0.5)
        float inputs:ior = 1
        token outputs:surface
    }}
}}
def Material "Glow"
{{
    token outputs:surface.connect = </Glow/Surface.outputs:surface>
    def Shader "Surface"
    {{
        uniform token info:id = "UsdPreviewSurface"
        color3f inputs:diffuseColor = (0, 0, 0)
        color3f inputs:emissiveColor = (1.5, 1.5, 1.5)
        float inputs:ior = 1
        token outputs:surface
    }}
}}
def Mesh "Floor" (prepend apiSchemas = ["MaterialBindingAPI"])
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-50, 0, 50), (50, 0, 50), (50, 0, -50), (-50, 0, -50)]
    uniform token subdivisionScheme = "none"
    rel material:binding = </Grey>
}}
def Camera "Camera"
{{
    float2 clippingRange = (0.01, 10000)
    float focalLength = 20
    float horizontalAperture = 10
    float verticalAperture = 10
    double shutter:open = 0
    double shutter:close = 1
    matrix4d xformOp:transform = ( (1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0.3, 0, 1) )
    uniform token[] xformOpOrder = ["xformOp:transform"]
}}
{light}
"#
    )
}

/// The 0.8 × 0.6 emitter of the moving-light tests: its corners 0.5 above the floor, centred
/// on x.
fn emitter_corners(x: f64) -> Vec<glam::DVec3> {
    [(-0.4, -0.3), (0.4, -0.3), (0.4, 0.3), (-0.4, 0.3)].iter().map(|&(a, b)| glam::DVec3::new(x + a, 0.5, b)).collect()
}

/// Irradiance at `p` from an emitter of radiance 1.5 sliding from x = −0.6 to 0.6 over the
/// shutter: the time average of Lambert's formula (midpoint rule over 400 times, whose error
/// is far below the render's noise).
fn sliding_emitter_irradiance(p: glam::DVec3) -> f64 {
    let n = 400;
    let sum: f64 = (0..n).map(|i| -0.6 + 1.2 * (i as f64 + 0.5) / n as f64).map(|x| polygon_irradiance(p, &emitter_corners(x), 1.5)).sum();
    sum / n as f64
}

/// The three ways an emitter moves: a RectLight carried by its transform, an emissive mesh
/// carried by its transform, and an emissive mesh whose points move.
fn sliding_emitters() -> [(&'static str, String); 3] {
    let slide = "double3 xformOp:translate.timeSamples = { 0: (-0.6, 0.5, 0), 1: (0.6, 0.5, 0) }";
    let quad = |y: f64, x: f64| {
        let corners: Vec<String> = emitter_corners(x).iter().map(|c| format!("({}, {y}, {})", c.x, c.z)).collect();
        format!("[{}]", corners.join(", "))
    };
    let mesh = |points: String, xform: &str| {
        format!(
            r#"def Mesh "Emitter" (prepend apiSchemas = ["MaterialBindingAPI"])
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    {points}
    uniform token subdivisionScheme = "none"
    rel material:binding = </Glow>
    {xform}
}}"#
        )
    };
    [
        (
            "a RectLight",
            // Rotated −90° about x, the light's −Z (where it emits) points down.
            format!(
                r#"def RectLight "Emitter"
{{
    float inputs:width = 0.8
    float inputs:height = 0.6
    float inputs:intensity = 1.5
    {slide}
    float xformOp:rotateX = -90
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}}"#
            ),
        ),
        (
            "an emissive mesh moved by its transform",
            mesh(
                format!("point3f[] points = {}", quad(0.0, 0.0)),
                &format!("{slide}\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]"),
            ),
        ),
        (
            "an emissive mesh whose points move",
            mesh(format!("point3f[] points.timeSamples = {{ 0: {}, 1: {} }}", quad(0.5, -0.6), quad(0.5, 0.6)), ""),
        ),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_moving_emitter_lights_the_floor_with_its_irradiance_averaged_over_the_shutter() {
    // Light sampling and the paths that hit the emitter must both find it where it is at the
    // path's time: were either to see the frame's placement (x = −0.6), the floor under the
    // camera would get a third less light than the average.
    let still = polygon_irradiance(glam::DVec3::ZERO, &emitter_corners(-0.6), 1.5);
    assert!(still < 0.7 * sliding_emitter_irradiance(glam::DVec3::ZERO), "the test tells a still emitter from a moving one");
    for (what, light) in sliding_emitters() {
        let t = load_text("moving_light", &lit_floor_stage(&light));
        let plan =
            t.lights.iter().map(|(_, l)| l.motion.len()).chain(t.meshes.iter().map(|(_, m)| m.motion.len() + m.mesh.deformation_samples()));
        assert!(plan.sum::<usize>() > 0, "{what} moves");
        // 1024 samples over 32² pixels: the mean's noise is well below 0.1% (measured:
        // +0.02% for the RectLight, +0.07% for the meshes); were light sampling to see the
        // frame's placement, the error would be −44%.
        assert_plane_radiance(what, &t, 1024, 0.003, sliding_emitter_irradiance).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sphere_light_crossing_the_view_renders_the_streak_of_its_silhouette() {
    // A SphereLight of radiance 3 seen by the camera against the unit dome: each pixel is
    // 1 + 3·(the fraction of the shutter the light covers it), as a moving sphere's coverage is.
    let (r, x0, x1) = (0.5, -1.0, 1.0);
    let light = format!(
        r#"def SphereLight "Bulb"
{{
    float inputs:radius = {r}
    float inputs:intensity = 3
    double3 xformOp:translate.timeSamples = {{ 0: ({x0}, 0, 0), 1: ({x1}, 0, 0) }}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}"#
    );
    let t = load_text("moving_bulb", &ortho_stage(&light));
    let (server, mut conn) = session_with(&t).await;
    let report = conn.render(&small(SIZE, SIZE, 64), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    assert!(
        report.started.plan.iter().any(|p| p.effect == "motion-blur" && p.prims.iter().any(|q| q == "/Bulb")),
        "{:?}",
        report.started.plan
    );
    let pixels = (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y)));
    let seen: Vec<f64> = pixels.clone().map(|(x, y)| (report.image.pixel("beauty", x, y)[0] as f64 - 1.0) / 3.0).collect();
    let expected: Vec<f64> = pixels.map(|(x, y)| streak(x, y, r, x0, x1)).collect();
    let covered = expected.iter().filter(|e| **e > 0.0).count() as f64;
    let mean_error = seen.iter().zip(&expected).map(|(a, b)| (a - b).abs()).sum::<f64>() / covered;
    // As for the moving sphere: the streak's edges carry about 1/64 each; the light is a true
    // sphere, with no tessellated silhouette.
    assert!(mean_error < 0.01, "mean |error| over the streak {mean_error:.4}");
}
