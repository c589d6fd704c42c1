//! UsdLux units against closed forms: radiance = intensity · 2^exposure · color; normalize
//! divides by the world-space area (or π sin²(angle/2) for a DistantLight).
//!
//! The fixtures (`fixtures/make_fixtures.py`) light a diffuse plane of albedo 0.5, so the
//! plane's radiance is 0.5·E/π.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use render_core::camera::Camera;
use tessera_tests::*;

const ALBEDO: f64 = 0.5;

/// Irradiance at `p` (normal +Y) from a Lambertian polygon of radiance `l`: Lambert's
/// formula E = L/2 Σ Θᵢ (n · ĝᵢ), with Θᵢ the angle each edge subtends.
fn polygon_irradiance(p: DVec3, corners: &[DVec3], l: f64) -> f64 {
    let n = DVec3::Y;
    let mut sum = 0.0;
    for i in 0..corners.len() {
        let a = (corners[i] - p).normalize();
        let b = (corners[(i + 1) % corners.len()] - p).normalize();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += theta * n.dot(a.cross(b).normalize());
    }
    0.5 * l * sum.abs()
}

/// Renders a lit-plane fixture and compares every pixel's mean over a block against the
/// closed form evaluated at the point the pixel sees.
async fn check_plane(fixture_name: &str, spp: u32, tolerance: f64, irradiance: impl Fn(DVec3) -> f64) {
    let (w, h) = (32, 32);
    let translation = load(fixture_name);
    let report = render_fixture(fixture_name, &small(w, h, spp)).await;
    let img = &report.image;
    assert_all_finite(img);
    let cam = Camera::new(&translation.cameras[0].1, w, h);
    let (mut got, mut want) = (0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let (ray, _) = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let t = -ray.origin.y / ray.dir.y;
            let p: Vec3 = ray.at(t);
            want += ALBEDO * irradiance(p.as_dvec3()) / PI;
            got += img.pixel("beauty", x, y)[0] as f64;
        }
    }
    let rel = got / want - 1.0;
    assert!(
        rel.abs() < tolerance,
        "{fixture_name}: mean radiance {} vs closed form {} ({:+.3}%)",
        got / (w * h) as f64,
        want / (w * h) as f64,
        100.0 * rel
    );
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
