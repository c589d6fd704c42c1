//! `UsdGeomPoints` render as spheres of their widths (discs facing their normals when they
//! have them), through the instancing path.

use tessera_tests::*;

fn stage(points: &str, widths: &str) -> String {
    format!(
        r#"#usda 1.0
def Points "Dots" {{
    point3f[] points = {points}
    {widths}
    color3f[] primvars:displayColor = [(0.8, 0.2, 0.1)]
}}
{}"#,
        camera_usda(35.0, 20.0)
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_point_covers_what_a_sphere_of_its_width_does() {
    // One point of width 2 at the origin, 4 units from a 35 mm lens with a 20 mm aperture:
    // a sphere of radius 1, whose silhouette covers π·(f·r/√(d² − r²) · 128/20)² = 10 510
    // of 128² pixels (the same closed form as tests/tests/subdivision.rs).
    let t = load_text("points_one", &stage("[(0, 0, 0)]", "float[] widths = [2]"));
    assert!(t.warnings.is_empty(), "{:?}", t.warnings);
    let (_, instancer) = t.instancers.iter().find(|(k, _)| k == "/Dots[points]").expect("an instancer");
    assert_eq!(instancer.transforms.len(), 1);
    let (server, mut conn) = session_with(&t).await;
    let report = conn.render(&small(128, 128, 16), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    let coverage: f64 =
        (0..128).flat_map(|y| (0..128).map(move |x| (x, y))).map(|(x, y)| report.image.pixel("beauty", x, y)[3] as f64).sum();
    let radius = 35.0 / 15f64.sqrt() * 128.0 / 20.0;
    let expected = std::f64::consts::PI * radius * radius;
    // 1%: the 128 × 64 tessellated sphere's silhouette is 0.1% under the analytic one.
    assert!((coverage / expected - 1.0).abs() < 0.01, "coverage {coverage:.0}, a sphere {expected:.0}");
}

#[test]
fn widths_size_each_point_and_default_to_one() {
    let t = load_text("points_widths", &stage("[(0, 0, 0), (3, 0, 0)]", "float[] widths = [0.5, 4]"));
    let (_, instancer) = t.instancers.iter().find(|(k, _)| k == "/Dots[points]").unwrap();
    let radii: Vec<f32> = instancer.transforms.iter().map(|m| m.matrix3.x_axis.length()).collect();
    assert_eq!(radii, vec![0.25, 2.0]);
    assert_eq!(instancer.transforms[1].translation, glam::Vec3A::new(3.0, 0.0, 0.0));
    let t = load_text("points_default", &stage("[(0, 0, 0)]", ""));
    assert_eq!(t.instancers[0].1.transforms[0].matrix3.x_axis.length(), 0.5, "width 1 when unauthored");
    // The sphere is drawn once per prim, as a prototype: one mesh whatever the point count.
    assert_eq!(t.meshes.len(), 1);
    assert!(!t.meshes[0].1.visible);
}

#[test]
fn hostile_points_are_reported_by_attribute() {
    let t = load_text("points_bad_width", &stage("[(0, 0, 0)]", "float[] widths = [-1]"));
    assert!(t.warnings.iter().any(|w| w.contains("/Dots") && w.contains("'widths'") && w.contains("-1")), "{:?}", t.warnings);
    assert!(t.instancers.is_empty() && t.meshes.is_empty(), "the prim is skipped");
    let t = load_text("points_nan", &stage("[(0, nan, 0)]", ""));
    assert!(t.warnings.iter().any(|w| w.contains("'points'") && w.contains("NaN")), "{:?}", t.warnings);
    let t = load_text("points_count", &stage("[(0, 0, 0), (1, 0, 0)]", "float[] widths = [1, 2, 3]"));
    assert!(t.warnings.iter().any(|w| w.contains("3 values for 2 points")), "{:?}", t.warnings);
    assert_eq!(t.instancers[0].1.transforms.len(), 2, "rendered with width 1");
}

/// Alpha summed over a 128² render of `t`: the pixels its surfaces cover.
async fn coverage(t: &tessera::usd::Translation) -> f64 {
    let (server, mut conn) = session_with(t).await;
    let report = conn.render(&small(128, 128, 16), |_| {}).await.expect("renders");
    server.stop().await.expect("stops");
    (0..128).flat_map(|y| (0..128).map(move |x| (x, y))).map(|(x, y)| report.image.pixel("beauty", x, y)[3] as f64).sum()
}

/// Pixels a unit-radius disc at the origin facing (sin θ, 0, cos θ) covers in a 128² image of
/// `camera_usda(35, 20)` (4 units away): its outline projected through the pinhole, as a
/// polygon (a straight edge projects to a straight edge).
fn projected_disc_area(sin: f64, cos: f64) -> f64 {
    let n = 4096;
    let outline: Vec<(f64, f64)> = (0..n)
        .map(|j| {
            let (y, x) = (std::f64::consts::TAU * j as f64 / n as f64).sin_cos();
            let (x, z) = (x * cos, -x * sin);
            let scale = 35.0 / (4.0 - z) * 128.0 / 20.0;
            (x * scale, y * scale)
        })
        .collect();
    0.5 * (0..n).map(|i| outline[i].0 * outline[(i + 1) % n].1 - outline[(i + 1) % n].0 * outline[i].1).sum::<f64>().abs()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn points_with_normals_render_as_discs_facing_them() {
    // A disc of width 2 at the origin facing the camera, 4 units from a 35 mm lens with a 20 mm
    // aperture: a circle of radius 35/4 · 128/20 = 56 pixels, π·56² = 9852 of 128².
    let facing = load_text("points_disc", &stage("[(0, 0, 0)]", "float[] widths = [2]\n    normal3f[] normals = [(0, 0, 1)]"));
    assert!(facing.warnings.is_empty(), "{:?}", facing.warnings);
    assert!(facing.meshes.iter().any(|(p, _)| p == "/Dots[disc]"), "a disc prototype");
    let expected = std::f64::consts::PI * 56.0 * 56.0;
    let seen = coverage(&facing).await;
    // 1%: the 128-gon's area is 0.04% under the circle's; the rest is pixel-edge sampling.
    assert!((seen / expected - 1.0).abs() < 0.01, "coverage {seen:.0}, a disc {expected:.0}");
    // Turned 60° about y: the pinhole projection of its outline (7.4% more than cos 60° of the
    // facing disc: the near half, 0.87 units closer, grows more than the far half shrinks).
    let (s, c) = 60f64.to_radians().sin_cos();
    let tilted =
        load_text("points_disc_tilted", &stage("[(0, 0, 0)]", &format!("float[] widths = [2]\n    normal3f[] normals = [({s}, 0, {c})]")));
    let seen = coverage(&tilted).await;
    let expected_tilted = projected_disc_area(s, c);
    assert!((seen / expected_tilted - 1.0).abs() < 0.01, "tilted coverage {seen:.0}, expected {expected_tilted:.0}");
    // Edge-on it all but vanishes.
    let edge_on = load_text("points_disc_edge", &stage("[(0, 0, 0)]", "float[] widths = [2]\n    normal3f[] normals = [(1, 0, 0)]"));
    let seen = coverage(&edge_on).await;
    assert!(seen < 0.01 * expected, "edge-on coverage {seen:.0}");
}

#[test]
fn disc_normals_are_checked_like_widths() {
    // One normal per point turns each disc; its x axis keeps the width.
    let t = load_text(
        "points_discs",
        &stage("[(0, 0, 0), (3, 0, 0)]", "float[] widths = [0.5, 4]\n    normal3f[] normals = [(0, 0, 1), (0, 2, 0)]"),
    );
    let (_, instancer) = t.instancers.iter().find(|(k, _)| k == "/Dots[points]").unwrap();
    let facing: Vec<glam::Vec3> = instancer.transforms.iter().map(|m| m.transform_vector3(glam::Vec3::Z)).collect();
    assert!((facing[0] - glam::Vec3::new(0.0, 0.0, 0.25)).length() < 1e-6, "{facing:?}");
    assert!((facing[1] - glam::Vec3::new(0.0, 2.0, 0.0)).length() < 1e-6, "{facing:?}");
    let t = load_text("points_zero_normal", &stage("[(0, 0, 0)]", "normal3f[] normals = [(0, 0, 0)]"));
    assert!(t.warnings.iter().any(|w| w.contains("/Dots") && w.contains("'normals'") && w.contains("normal 0")), "{:?}", t.warnings);
    assert!(t.instancers.is_empty(), "the prim is skipped");
    let t = load_text("points_nan_normal", &stage("[(0, 0, 0)]", "normal3f[] normals = [(0, nan, 1)]"));
    assert!(t.warnings.iter().any(|w| w.contains("'normals'") && w.contains("NaN")), "{:?}", t.warnings);
    let t = load_text("points_normal_count", &stage("[(0, 0, 0), (1, 0, 0), (2, 0, 0)]", "normal3f[] normals = [(0, 0, 1), (0, 1, 0)]"));
    assert!(t.warnings.iter().any(|w| w.contains("2 values for 3 points") && w.contains("spheres")), "{:?}", t.warnings);
    assert!(t.meshes.iter().any(|(p, _)| p == "/Dots[sphere]"));
}
