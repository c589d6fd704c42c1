//! The camera of a `UsdGeomCamera`: perspective (with a thin lens when `fStop` > 0) or
//! orthographic.
//!
//! USD camera units: focal length and apertures are in tenths of a scene unit, so an
//! orthographic camera's `horizontalAperture` of 20 frames 2 units, and the thin lens of a
//! perspective one has radius (focalLength/10)/(2·fStop) scene units (`UsdGeomCamera`
//! documentation; pbrt-v4's `PerspectiveCamera` for the thin-lens model).

use glam::{Affine3A, Vec2, Vec3};

use crate::geometry::Ray;
use crate::sampling::concentric_disk;

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
    /// `projection` is `orthographic`.
    pub orthographic: bool,
    /// `fStop`: 0 for a pinhole (no depth of field).
    pub f_stop: f32,
    /// `focusDistance`, in scene units.
    pub focus_distance: f32,
    /// `shutter:open`, in frames relative to the frame rendered (for the record: the reader
    /// samples motion over the shutter into [`Self::motion`] and meshes' motions).
    pub shutter_open: f32,
    /// `shutter:close`; see [`Self::shutter_open`].
    pub shutter_close: f32,
    /// Camera to world at evenly spaced times over the shutter when the camera moves
    /// ([`crate::motion`]); empty when it does not.
    pub motion: Vec<Affine3A>,
    /// The image's exposure in stops: log2 of UsdGeomCamera's linear exposure scale (its
    /// `exposure`, `exposure:iso`, `:time`, `:fStop` and `:responsivity`); 0 leaves the light
    /// as it arrives.
    pub exposure: f32,
}

/// The most stops a camera's exposure may brighten or darken the image: 2^±64, a range of
/// about 10^19 either way, far past any photographic exposure.
pub const MAX_EXPOSURE_STOPS: f32 = 64.0;

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
            orthographic: false,
            f_stop: 0.0,
            focus_distance: 0.0,
            shutter_open: 0.0,
            shutter_close: 0.0,
            motion: Vec::new(),
            exposure: 0.0,
        }
    }
}

/// A camera ready to generate rays for one image size.
#[derive(Clone, Debug)]
pub struct Camera {
    to_world: Affine3A,
    /// Camera to world over the shutter when the camera moves ([`crate::motion`]).
    motion: Vec<Affine3A>,
    forward: Vec3,
    /// Film window on the plane z = −1: (left, top) and size.
    window_min: Vec2,
    window_size: Vec2,
    width: u32,
    height: u32,
    near: f32,
    far: f32,
    /// Orthographic: the window is in scene units on the plane z = 0.
    orthographic: bool,
    /// Thin lens radius and focus distance (scene units); radius 0 is a pinhole.
    lens_radius: f32,
    focus_distance: f32,
    /// 2^exposure: what the image's light is multiplied by.
    exposure_scale: f32,
}

impl Camera {
    /// Builds for a `width`×`height` image. The aperture is conformed to the image aspect
    /// with UsdRender's default policy, `expandAperture`: the aperture grows in one
    /// dimension so the image shows at least what the aperture frames.
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Self {
        Self::with_pixel_aspect(desc, width, height, 1.0)
    }

    /// [`Camera::new`] for pixels `pixel_aspect` times wider than tall (UsdRender
    /// `pixelAspectRatio`): the image's aspect is then width·pixel_aspect/height, and the
    /// aperture is conformed to that.
    pub fn with_pixel_aspect(desc: &CameraDesc, width: u32, height: u32, pixel_aspect: f32) -> Self {
        let pixel_aspect = if pixel_aspect.is_finite() && pixel_aspect > 0.0 { pixel_aspect } else { 1.0 };
        let f = if desc.focal_length > 0.0 { desc.focal_length } else { 50.0 };
        let (mut ha, mut va) = (desc.horizontal_aperture.abs(), desc.vertical_aperture.abs());
        if !(ha > 0.0) {
            ha = 20.955;
        }
        let image_aspect = width as f32 * pixel_aspect / height as f32;
        if !(va > 0.0) {
            va = ha / image_aspect;
        }
        if ha / va < image_aspect {
            ha = va * image_aspect;
        } else {
            va = ha / image_aspect;
        }
        // Perspective: the window on the plane z = −1 (apertures over focal length).
        // Orthographic: the window itself, apertures in tenths of a scene unit.
        let scale = if desc.orthographic { 10.0 } else { f };
        let center = Vec2::new(desc.horizontal_aperture_offset, desc.vertical_aperture_offset) / scale;
        let size = Vec2::new(ha, va) / scale;
        let thin_lens = !desc.orthographic && desc.f_stop > 0.0 && desc.focus_distance > 0.0 && desc.f_stop.is_finite();
        let window_min = Vec2::new(center.x - 0.5 * size.x, center.y + 0.5 * size.y);
        let forward = (-Vec3::from(desc.transform.matrix3.z_axis)).normalize_or(-Vec3::Z);
        Camera {
            to_world: desc.transform,
            motion: if crate::motion::check_samples(&desc.motion).is_ok() { desc.motion.clone() } else { Vec::new() },
            forward,
            window_min,
            window_size: size,
            width,
            height,
            near: desc.near.max(0.0),
            far: if desc.far > desc.near { desc.far } else { f32::INFINITY },
            orthographic: desc.orthographic,
            lens_radius: if thin_lens { (f / 10.0) / (2.0 * desc.f_stop) } else { 0.0 },
            focus_distance: if thin_lens { desc.focus_distance } else { 0.0 },
            exposure_scale: if desc.exposure.abs() <= MAX_EXPOSURE_STOPS { desc.exposure.exp2() } else { 1.0 },
        }
    }

    /// The linear scale of the camera's exposure (1 beyond [`MAX_EXPOSURE_STOPS`], which the
    /// wire and the USD reader refuse).
    pub fn exposure_scale(&self) -> f32 {
        self.exposure_scale
    }

    /// A ray through image position (`x`, `y`) in pixels, y down, with its range clipped
    /// to the clipping planes. Also returns cos of the angle to the view axis, which turns
    /// a hit distance into camera-space depth.
    pub fn ray(&self, x: f32, y: f32) -> (Ray, f32) {
        self.ray_through_lens(x, y, Vec2::splat(0.5))
    }

    /// [`Camera::ray`] through the lens point that `lens` (in [0, 1)²) picks: with a thin
    /// lens, rays from every lens point through a pixel meet on the plane of focus.
    pub fn ray_through_lens(&self, x: f32, y: f32, lens: Vec2) -> (Ray, f32) {
        self.ray_at(x, y, lens, 0.0)
    }

    /// [`Camera::ray_through_lens`] at shutter time `time` (0 open, 1 close): from where a
    /// moving camera is then, and seeing moving geometry where it is then.
    pub fn ray_at(&self, x: f32, y: f32, lens: Vec2, time: f32) -> (Ray, f32) {
        let sx = x / self.width as f32;
        let sy = y / self.height as f32;
        let film = Vec2::new(self.window_min.x + sx * self.window_size.x, self.window_min.y - sy * self.window_size.y);
        let (origin_local, dir_local) = if self.orthographic {
            (film.extend(0.0), -Vec3::Z)
        } else if self.lens_radius > 0.0 {
            let focus = film.extend(-1.0) * self.focus_distance;
            let on_lens = (concentric_disk(lens) * self.lens_radius).extend(0.0);
            (on_lens, (focus - on_lens).normalize())
        } else {
            (Vec3::ZERO, film.extend(-1.0).normalize())
        };
        let to_world = if self.motion.is_empty() { self.to_world } else { crate::motion::transform_at(&self.motion, time) };
        let dir = to_world.transform_vector3(dir_local).normalize();
        let origin = to_world.transform_point3(origin_local);
        // Depth is along the view axis of the moment: a camera turning over the shutter turns it.
        let forward = if self.motion.is_empty() { self.forward } else { (-Vec3::from(to_world.matrix3.z_axis)).normalize_or(self.forward) };
        let cos = dir.dot(forward).max(1e-6);
        let t0 = self.near / cos;
        let mut ray = Ray::new(origin + dir * t0, dir).with_time(time);
        ray.tmax = self.far / cos - t0;
        (ray, cos)
    }

    /// The footprint of one pixel as a ray cone: (width at the origin, spread angle). A
    /// perspective pixel subtends about window height / image height radians; an
    /// orthographic one is that many scene units wide and does not spread.
    pub fn pixel_footprint(&self) -> (f32, f32) {
        let pixel = self.window_size.y / self.height.max(1) as f32;
        if self.orthographic { (pixel, 0.0) } else { (0.0, pixel) }
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

    /// pixelAspectRatio 2 on a 50x100 image of a square aperture: the image is as wide as it
    /// is tall in the scene, so the edges see what a 100x100 image of square pixels sees.
    #[test]
    fn wide_pixels_widen_the_image_not_the_pixels_count() {
        let desc = CameraDesc { focal_length: 10.0, horizontal_aperture: 20.0, vertical_aperture: 20.0, near: 0.0, ..Default::default() };
        let square = Camera::new(&desc, 100, 100);
        let wide = Camera::with_pixel_aspect(&desc, 50, 100, 2.0);
        let slope = |c: &Camera, x: f32, y: f32| {
            let (r, _) = c.ray(x, y);
            Vec2::new(r.dir.x, r.dir.y) / -r.dir.z
        };
        assert!((slope(&square, 0.0, 0.0) - slope(&wide, 0.0, 0.0)).length() < 1e-5);
        assert!((slope(&square, 100.0, 30.0) - slope(&wide, 50.0, 30.0)).length() < 1e-5);
        // Square pixels on the same 50x100 image make a tall image: expandAperture keeps the
        // width and doubles the height the camera sees.
        let narrow = Camera::new(&desc, 50, 100);
        assert!((slope(&narrow, 0.0, 50.0).x - slope(&square, 0.0, 50.0).x).abs() < 1e-5);
        assert!((slope(&narrow, 25.0, 0.0).y - 2.0 * slope(&square, 50.0, 0.0).y).abs() < 1e-5);
    }

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
    fn orthographic_rays_are_parallel_and_frame_the_aperture_in_tenths_of_a_unit() {
        let desc = CameraDesc { orthographic: true, horizontal_aperture: 40.0, vertical_aperture: 40.0, near: 0.0, ..Default::default() };
        let cam = Camera::new(&desc, 100, 100);
        let (a, _) = cam.ray(0.0, 50.0);
        let (b, _) = cam.ray(100.0, 50.0);
        assert_eq!((a.dir, b.dir), (-Vec3::Z, -Vec3::Z));
        assert!((b.origin.x - a.origin.x - 4.0).abs() < 1e-5, "40 tenths frame 4 units: {} to {}", a.origin.x, b.origin.x);
    }

    #[test]
    fn a_thin_lens_focuses_on_the_focus_distance() {
        let desc = CameraDesc {
            focal_length: 50.0,
            horizontal_aperture: 36.0,
            vertical_aperture: 36.0,
            f_stop: 2.0,
            focus_distance: 7.0,
            near: 0.0,
            ..Default::default()
        };
        let cam = Camera::new(&desc, 64, 64);
        // Radius (50/10)/(2·2) = 1.25 units; every lens point's ray through pixel (20, 30)
        // crosses z = −7 at the same point.
        let points: Vec<Vec3> = [(0.1, 0.2), (0.9, 0.5), (0.5, 0.95), (0.3, 0.7)]
            .iter()
            .map(|&(u, v)| {
                let (r, _) = cam.ray_through_lens(20.0, 30.0, Vec2::new(u, v));
                assert!(r.origin.length() <= 1.25 + 1e-5);
                r.at(7.0 / -r.dir.z)
            })
            .collect();
        for p in &points[1..] {
            assert!((*p - points[0]).length() < 1e-4, "{p} vs {}", points[0]);
        }
        // fStop 0 is a pinhole.
        let pinhole = Camera::new(&CameraDesc { f_stop: 0.0, ..desc }, 64, 64);
        assert_eq!(pinhole.ray_through_lens(20.0, 30.0, Vec2::new(0.1, 0.9)).0.origin, Vec3::ZERO);
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
