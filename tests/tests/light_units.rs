//! UsdLux units against closed forms: radiance = intensity · 2^exposure · color; normalize
//! divides by the world-space area (or π sin²(angle/2) for a DistantLight).
//!
//! The fixtures (`fixtures/make_fixtures.py`) light a diffuse plane of albedo 0.5, so the
//! plane's radiance is 0.5·E/π.

use glam::DVec3;
use tessera_tests::lit_plane::{assert_plane_radiance, polygon_irradiance};
use tessera_tests::*;

/// A fixture's plane against the closed form `irradiance` (see [`assert_plane_radiance`]).
async fn check_plane(fixture_name: &str, spp: u32, tolerance: f64, irradiance: impl Fn(DVec3) -> f64) {
    assert_plane_radiance(fixture_name, &load(fixture_name), spp, tolerance, irradiance).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn normalized_distant_light_intensity_is_illuminance() {
    // Intensity 3, normalized, 30 degrees from the plane's normal.
    check_plane("lights/distant_plane.usda", 16, 0.002, |_| 3.0 * 30f64.to_radians().cos()).await;
}

fn rect_corners() -> Vec<DVec3> {
    // 0.8 x 0.6 scaled by (2, 1, 1), centred 0.5 above the origin, facing down.
    let (hx, hz) = (0.8, 0.3);
    vec![DVec3::new(-hx, 0.5, -hz), DVec3::new(hx, 0.5, -hz), DVec3::new(hx, 0.5, hz), DVec3::new(-hx, 0.5, hz)]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rect_light_radiance_is_its_intensity() {
    check_plane("lights/rect_plane.usda", 1024, 0.005, |p| polygon_irradiance(p, &rect_corners(), 2.0)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn normalized_rect_light_divides_by_world_area() {
    // World-space area 1.6 x 0.6 = 0.96, transform scale included.
    check_plane("lights/rect_plane_normalized.usda", 1024, 0.005, |p| polygon_irradiance(p, &rect_corners(), 2.0 / 0.96)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_unit_light_seen_head_on_is_pixel_value_one() {
    assert_every_pixel_is_one("lights/rect_head_on.usda", 0.0).await;
}

/// Renders `fixture_name` at 16x16 and checks every pixel's RGB is 1 within `tolerance`.
async fn assert_every_pixel_is_one(fixture_name: &str, tolerance: f32) {
    let report = render_fixture(fixture_name, &small(16, 16, 4)).await;
    for y in 0..16 {
        for x in 0..16 {
            let p = report.image.pixel("beauty", x, y);
            assert!(p[..3].iter().all(|v| (v - 1.0).abs() <= tolerance), "{fixture_name}: pixel ({x}, {y}) is {p:?}");
        }
    }
}

/// A normalized CylinderLight seen side-on: intensity equal to its side's area is radiance 1.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_normalized_cylinder_light_seen_side_on_is_its_intensity_over_its_area() {
    assert_every_pixel_is_one("lights/cylinder_side_on.usda", 1e-5).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_emissive_mesh_lights_like_an_area_light_of_its_radiance() {
    // A 0.8 x 0.6 emissive quad of radiance 1.5, 0.5 above the plane, found through the BVH.
    let (hx, hz) = (0.4, 0.3);
    let corners = vec![DVec3::new(-hx, 0.5, -hz), DVec3::new(hx, 0.5, -hz), DVec3::new(hx, 0.5, hz), DVec3::new(-hx, 0.5, hz)];
    check_plane("lights/emissive_plane.usda", 1024, 0.005, |p| polygon_irradiance(p, &corners, 1.5)).await;
}

/// A camera's exposure scales the image by what usd-core's `ComputeLinearExposureScale` gives:
/// `exposure` in stops times the physical exposure time × ISO × responsivity / (100 × f²).
/// A wall under a uniform dome, seen through three cameras: the schema's defaults (scale 1),
/// one stop up with ISO 200 at 1/2 s (scale 2), and ISO 400 at 1/125 s and f/2.8 (scale
/// 0.00408). Every pixel's light scales by exactly that (the same paths, scaled as they reach
/// the film; f32 rounding of each sample only), coverage does not.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cameras_exposure_scales_the_image_as_usd_core_computes_it() {
    let dir = std::env::temp_dir().join(format!("tessera-camera-exposure-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cameras = [("Plain", 0.0, 100.0, 1.0, 1.0), ("Bright", 1.0, 200.0, 0.5, 1.0), ("Photo", 0.0, 400.0, 1.0 / 125.0, 2.8)];
    let mut layer = String::from(
        "#usda 1.0\ndef Mesh \"Wall\"\n{\n    point3f[] points = [(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)]\n    \
         int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n}\ndef DomeLight \"Sky\"\n{\n}\n",
    );
    for (name, stops, iso, seconds, f_stop) in cameras {
        layer += &format!(
            "def Camera \"{name}\"\n{{\n    float exposure = {stops}\n    float exposure:iso = {iso}\n    float exposure:time = {seconds}\n    \
             float exposure:fStop = {f_stop}\n    double3 xformOp:translate = (0, 0, 5)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n"
        );
    }
    let file = dir.join("exposure.usda");
    std::fs::write(&file, layer).unwrap();
    let theirs = usd_core_reads(&file, None);
    let t = tessera::usd::load(&file).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let (server, mut conn) = session_with(&t).await;
    let mut images = Vec::new();
    for (name, ..) in cameras {
        let opts = tessera::remote::RenderOptions { camera: format!("/{name}"), ..small(24, 24, 8) };
        images.push(conn.render(&opts, |_| {}).await.expect("renders").image);
    }
    server.stop().await.unwrap();
    for (k, (name, ..)) in cameras.iter().enumerate().skip(1) {
        let scale = theirs["cameras"][format!("/{name}")]["exposureScale"].as_f64().unwrap();
        for (y, x) in (0..24).flat_map(|y| (0..24).map(move |x| (y, x))) {
            let (plain, exposed) = (images[0].pixel("beauty", x, y), images[k].pixel("beauty", x, y));
            for c in 0..3 {
                let want = plain[c] as f64 * scale;
                assert!(
                    (exposed[c] as f64 - want).abs() <= 1e-5 * want.abs().max(1e-30),
                    "{name} ({x}, {y})[{c}]: {} against {want}",
                    exposed[c]
                );
            }
            assert_eq!(exposed[3], plain[3], "{name}: coverage unchanged");
        }
    }
}
