//! The perspective camera of a `UsdGeomCamera`.

use glam::{Affine3A, Vec2, Vec3};

use crate::geometry::Ray;

/// Camera parameters as USD authors them (apertures and focal length share a unit, so
/// only their ratios matter here).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    /// Camera to world; the camera looks down its local −Z with +Y up.
    pub transform: Affine3A,
    /// `focalLength`.
    pub focal_length: f32,
    /// `horizontalAperture`.
    pub horizontal_aperture: f32,
    /// `verticalAperture`.
    pub vertical_aperture: f32,
    /// `horizontalApertureOffset`.
    pub horizontal_aperture_offset: f32,
    /// `verticalApertureOffset`.
    pub vertical_aperture_offset: f32,
    /// `clippingRange` near.
    pub near: f32,
    /// `clippingRange` far.
    pub far: f32,
}

impl Default for CameraDesc {
    /// UsdGeomCamera's schema defaults.
    fn default() -> Self {
        CameraDesc {
            transform: Affine3A::IDENTITY,
            focal_length: 50.0,
            horizontal_aperture: 20.955,
            vertical_aperture: 15.2908,
            horizontal_aperture_offset: 0.0,
            vertical_aperture_offset: 0.0,
            near: 1.0,
            far: 1_000_000.0,
        }
    }
}

/// A camera ready to generate rays for one image size.
#[derive(Clone, Debug)]
pub struct Camera {
    to_world: Affine3A,
    origin: Vec3,
    forward: Vec3,
    /// Film window on the plane z = −1: (left, top) and size.
    window_min: Vec2,
    window_size: Vec2,
    width: u32,
    height: u32,
    near: f32,
    far: f32,
}

impl Camera {
    /// Builds for a `width`×`height` image. The aperture is conformed to the image aspect
    /// with UsdRender's default policy, `expandAperture`: the aperture grows in one
    /// dimension so the image shows at least what the aperture frames.
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Self {
        let f = if desc.focal_length > 0.0 { desc.focal_length } else { 50.0 };
        let (mut ha, mut va) = (desc.horizontal_aperture.abs(), desc.vertical_aperture.abs());
        if !(ha > 0.0) {
            ha = 20.955;
        }
        if !(va > 0.0) {
            va = ha * height as f32 / width as f32;
        }
        let image_aspect = width as f32 / height as f32;
        if ha / va < image_aspect {
            ha = va * image_aspect;
        } else {
            va = ha / image_aspect;
        }
        let center = Vec2::new(desc.horizontal_aperture_offset, desc.vertical_aperture_offset) / f;
        let size = Vec2::new(ha, va) / f;
        let window_min = Vec2::new(center.x - 0.5 * size.x, center.y + 0.5 * size.y);
        let forward = (-Vec3::from(desc.transform.matrix3.z_axis)).normalize_or(-Vec3::Z);
        Camera {
            to_world: desc.transform,
            origin: desc.transform.translation.into(),
            forward,
            window_min,
            window_size: size,
            width,
            height,
            near: desc.near.max(0.0),
            far: if desc.far > desc.near { desc.far } else { f32::INFINITY },
        }
    }

    /// A ray through image position (`x`, `y`) in pixels, y down, with its range clipped
    /// to the clipping planes. Also returns cos of the angle to the view axis, which turns
    /// a hit distance into camera-space depth.
    pub fn ray(&self, x: f32, y: f32) -> (Ray, f32) {
        let sx = x / self.width as f32;
        let sy = y / self.height as f32;
        let local = Vec3::new(self.window_min.x + sx * self.window_size.x, self.window_min.y - sy * self.window_size.y, -1.0);
        let dir = self.to_world.transform_vector3(local).normalize();
        let cos = dir.dot(self.forward).max(1e-6);
        let t0 = self.near / cos;
        let mut ray = Ray::new(self.origin + dir * t0, dir);
        ray.tmax = self.far / cos - t0;
        (ray, cos)
    }

    /// Camera-space depth of a hit `t` along a ray made by [`Camera::ray`].
    pub fn depth(&self, t: f32, cos: f32) -> f32 {
        (t + self.near / cos) * cos
    }

    /// Depth written where the camera sees nothing: the far clipping distance, or 0 when
    /// unbounded, so the AOV stays finite.
    pub fn background_depth(&self) -> f32 {
        if self.far.is_finite() { self.far } else { 0.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_down_minus_z_and_fov_follows_aperture() {
        let desc = CameraDesc { focal_length: 10.0, horizontal_aperture: 20.0, vertical_aperture: 20.0, near: 0.0, ..Default::default() };
        let cam = Camera::new(&desc, 100, 100);
        let (r, cos) = cam.ray(50.0, 50.0);
        assert!((r.dir - -Vec3::Z).length() < 1e-6 && (cos - 1.0).abs() < 1e-6);
        // Left edge: x = -aperture/2 / focal = -1 on the z = -1 plane → 45°.
        let (r, _) = cam.ray(0.0, 50.0);
        assert!((r.dir.x / -r.dir.z + 1.0).abs() < 1e-5);
        // Top row is +Y.
        let (r, _) = cam.ray(50.0, 0.0);
        assert!(r.dir.y > 0.0);
    }

    #[test]
    fn expand_aperture_keeps_the_framed_region() {
        let desc = CameraDesc { focal_length: 10.0, horizontal_aperture: 20.0, vertical_aperture: 20.0, near: 0.0, ..Default::default() };
        // A wide image expands horizontally; the vertical extent stays 45°.
        let cam = Camera::new(&desc, 200, 100);
        let (r, _) = cam.ray(100.0, 0.0);
        assert!((r.dir.y / -r.dir.z - 1.0).abs() < 1e-5);
        let (r, _) = cam.ray(0.0, 50.0);
        assert!((r.dir.x / -r.dir.z + 2.0).abs() < 1e-5);
    }
}
