//! Lights in UsdLux units, their sampling for next-event estimation and their evaluation
//! when a ray finds them.
//!
//! Units follow the UsdLux "Quantities and Units" section: emitted radiance is
//! `intensity · 2^exposure · color`; with `normalize` it is divided by the light's
//! world-space area (transform scale included), and for a `DistantLight` by
//! π·sin²(angle/2), which makes `intensity` the illuminance on a surface facing it.
//! `DomeLight` ignores `normalize`. Area lights emit from their local −Z face (sphere
//! lights outward); they are emitters only and do not cast shadows on each other.

pub mod blackbody;
mod shapes;

pub use shapes::{LightHit, LightSample, Shape};

use glam::{Affine3A, Vec3};

use crate::math::luminance;
use crate::sampling::Distribution1D;

/// A light as the scene description holds it (object space plus transform).
#[derive(Clone, Debug, PartialEq)]
pub struct LightDesc {
    /// Which UsdLux light.
    pub kind: LightKind,
    /// Object to world.
    pub transform: Affine3A,
    /// `inputs:intensity`.
    pub intensity: f32,
    /// `inputs:exposure`.
    pub exposure: f32,
    /// `inputs:color`.
    pub color: Vec3,
    /// `inputs:normalize`.
    pub normalize: bool,
    /// Seen by camera rays.
    pub visible_to_camera: bool,
}

/// UsdLux light types and their shape parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// `SphereLight` with `inputs:radius`.
    Sphere {
        /// Radius in object space.
        radius: f32,
    },
    /// `RectLight` with `inputs:width` and `inputs:height`, in the local XY plane.
    Rect {
        /// Extent along local X.
        width: f32,
        /// Extent along local Y.
        height: f32,
    },
    /// `DiskLight` with `inputs:radius`, in the local XY plane.
    Disk {
        /// Radius in object space.
        radius: f32,
    },
    /// `DistantLight` shining along local −Z, `inputs:angle` in degrees.
    Distant {
        /// Angular diameter in degrees.
        angle_degrees: f32,
    },
    /// `DomeLight` of constant colour.
    Dome,
}

/// A committed light in world space.
#[derive(Clone, Debug)]
pub struct Light {
    /// Geometry and emission.
    pub shape: shapes::Shape,
    /// Seen by camera rays.
    pub visible_to_camera: bool,
}

/// Everything a shading point tells a light for sampling.
#[derive(Clone, Copy, Debug)]
pub struct ShadingContext {
    /// World position.
    pub p: Vec3,
    /// Geometric normal facing the incoming ray.
    pub n: Vec3,
}

impl LightDesc {
    /// Emitted radiance before normalisation.
    fn base_radiance(&self) -> Vec3 {
        self.color.max(Vec3::ZERO) * self.intensity * self.exposure.exp2()
    }

    /// Commits to world space. `None` for lights that cannot emit (degenerate transform,
    /// zero size with normalisation off, non-finite values).
    pub fn commit(&self) -> Option<Light> {
        let l = self.base_radiance();
        if !crate::math::is_finite(l) || !self.transform.is_finite() {
            return None;
        }
        let shape = shapes::Shape::new(self.kind, &self.transform, l, self.normalize)?;
        Some(Light { shape, visible_to_camera: self.visible_to_camera })
    }
}

/// The set of lights and the distribution NEE picks them from.
#[derive(Default)]
pub struct LightSet {
    /// Lights, including one per emissive triangle.
    pub lights: Vec<Light>,
    selection: Distribution1D,
}

impl LightSet {
    /// Builds the selection distribution in proportion to emitted power; `scene_radius`
    /// sizes the infinite lights' power.
    pub fn new(lights: Vec<Light>, scene_radius: f32) -> Self {
        let power: Vec<f32> = lights.iter().map(|l| luminance(l.shape.power(scene_radius))).collect();
        let selection = Distribution1D::new(&power);
        LightSet { lights, selection }
    }

    /// True when nothing emits.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Picks a light with `u` and samples a direction on it.
    pub fn sample(&self, ctx: &ShadingContext, u_select: f32, u: glam::Vec2) -> Option<LightSample> {
        if self.lights.is_empty() {
            return None;
        }
        let (i, p) = self.selection.sample(u_select);
        let mut s = self.lights[i].shape.sample(ctx, u)?;
        s.pdf *= p;
        Some(s)
    }

    /// Selection probability of light `i`.
    pub fn pmf(&self, i: usize) -> f32 {
        self.selection.pmf(i)
    }
}
