//! `UsdGeomPoints` render as spheres of their widths, through the instancing path.

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
