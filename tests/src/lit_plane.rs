//! Closed forms for a diffuse plane lit by area lights: the radiance a camera looking down at
//! the plane y = 0 sees, pixel by pixel, against Lambert's formula for the irradiance.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use render_core::camera::Camera;
use tessera::usd::Translation;

use super::{assert_all_finite, session_with, small};

/// Albedo of the lit planes (a UsdPreviewSurface of diffuse 0.5 and IOR 1: Lambertian), so
/// the plane's radiance is 0.5·E/π.
pub const PLANE_ALBEDO: f64 = 0.5;

/// Irradiance at `p` (normal +Y) from a Lambertian polygon of radiance `l`: Lambert's
/// formula E = L/2 Σ Θᵢ (n · ĝᵢ), with Θᵢ the angle each edge subtends.
pub fn polygon_irradiance(p: DVec3, corners: &[DVec3], l: f64) -> f64 {
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

/// Renders `t` (a plane y = 0 of [`PLANE_ALBEDO`] seen by its first camera) at 32² and `spp`,
/// and compares the mean radiance over the image with the closed form evaluated at the point
/// each pixel sees, within relative `tolerance`.
pub async fn assert_plane_radiance(label: &str, t: &Translation, spp: u32, tolerance: f64, irradiance: impl Fn(DVec3) -> f64) {
    let (w, h) = (32, 32);
    let (server, mut conn) = session_with(t).await;
    let report = conn.render(&small(w, h, spp), |_| {}).await.expect("renders");
    server.stop().await.expect("server stops");
    let img = &report.image;
    assert_all_finite(img);
    let cam = Camera::new(&t.cameras[0].1, w, h);
    let (mut got, mut want) = (0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let (ray, _) = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let p: Vec3 = ray.at(-ray.origin.y / ray.dir.y);
            want += PLANE_ALBEDO * irradiance(p.as_dvec3()) / PI;
            got += img.pixel("beauty", x, y)[0] as f64;
        }
    }
    let rel = got / want - 1.0;
    let n = (w * h) as f64;
    assert!(rel.abs() < tolerance, "{label}: mean radiance {} vs closed form {} ({:+.3}%)", got / n, want / n, 100.0 * rel);
}
