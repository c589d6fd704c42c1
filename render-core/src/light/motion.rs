//! Lights that move over the shutter: a UsdLux light carried by its transform's motion (a
//! textured dome turns its map), and each triangle of an emissive mesh that moves or deforms.
//!
//! The committed [`Light`] keeps its frame-time shape, which only weighs its selection by
//! power. Sampling and ray hits pose the light at the ray's time, with the same interpolation
//! the geometry uses ([`crate::motion`], [`Mesh::triangle_at`]), so that a path hitting a
//! moving emitter and a light sample drawn on it describe the same surface; the light tree
//! bounds the light over its whole motion, so its selection does not depend on time.

use std::borrow::Cow;
use std::sync::Arc;

use glam::{Affine3A, Mat3, Vec3};

use super::environment::{EnvironmentMap, dome_rotation};
use super::tree::LightBounds;
use super::{Light, LightKind, Shape, Shaping, ShapingProfile};
use crate::geometry::Mesh;

/// How a light moves over the shutter.
#[derive(Debug)]
pub enum LightMotion {
    /// A UsdLux light: its object-to-world placements at evenly spaced times over the shutter.
    Placed {
        /// Which light, with its object-space size.
        kind: LightKind,
        /// Radiance before normalisation.
        l: Vec3,
        /// `inputs:normalize`: divide by the area the light has at each time.
        normalize: bool,
        /// `ShapingAPI`, turned with the light.
        shaping: Option<Shaping>,
        /// Placements over the shutter (2 to [`crate::motion::MAX_MOTION_SAMPLES`]).
        samples: Arc<[Affine3A]>,
    },
    /// A DomeLight's map turning with its transform.
    Turned {
        /// The map, built at the frame's placement.
        map: Arc<EnvironmentMap>,
        /// Radiance scale.
        l: Vec3,
        /// Placements over the shutter.
        samples: Arc<[Affine3A]>,
    },
    /// A triangle of an emissive mesh that deforms, moves, or both.
    Triangle {
        /// The mesh, with its deformation samples.
        mesh: Arc<Mesh>,
        /// Which triangle.
        triangle: u32,
        /// The instance's placement: its motion samples, or its one frame placement.
        placement: Placement,
        /// Emitted radiance.
        l: Vec3,
    },
}

/// Where an instance is over the shutter.
#[derive(Clone, Debug)]
pub enum Placement {
    /// The same placement all through the shutter.
    Still(Affine3A),
    /// Placements at evenly spaced times ([`crate::motion`]).
    Moving(Arc<[Affine3A]>),
}

impl LightMotion {
    /// The shape and shaping at normalised shutter time `time`; `None` when the light cannot
    /// emit then (its placement collapses).
    fn pose(&self, time: f32) -> Option<(Shape, Option<ShapingProfile>)> {
        match self {
            LightMotion::Placed { kind, l, normalize, shaping, samples } => {
                let xf = crate::motion::transform_at(samples, time);
                Some((Shape::new(*kind, &xf, *l, *normalize)?, super::shaping_profile(*shaping, &xf)))
            }
            LightMotion::Turned { map, l, samples } => {
                let placed = dome_rotation(Mat3::from(crate::motion::transform_at(samples, time).matrix3));
                let turn = placed * map.to_world().transpose();
                Some((Shape::Environment { l: *l, map: map.clone(), turn }, None))
            }
            LightMotion::Triangle { mesh, triangle, placement, l } => {
                let to_world = match placement {
                    Placement::Still(m) => *m,
                    Placement::Moving(samples) => crate::motion::placement_at(samples, time).to_world,
                };
                let p = mesh.triangle_at(*triangle as usize, time).map(|v| to_world.transform_point3(v));
                Some((Shape::triangle(p, *l)?, None))
            }
        }
    }

    /// Bounds of everything the light covers over the shutter, with power `phi`.
    fn bounds(&self, phi: f32) -> Option<LightBounds> {
        match self {
            LightMotion::Placed { kind, l, normalize, samples, .. } => {
                // Linear interpolation keeps the light inside the hull of its shapes at the
                // samples, so their union holds it at every time between.
                let mut keys = samples.iter().filter_map(|xf| LightBounds::of(&Shape::new(*kind, xf, *l, *normalize)?, phi));
                let first = keys.next()?;
                Some(keys.fold(first, |a, b| a.enclosing(&b)))
            }
            LightMotion::Turned { .. } => None,
            LightMotion::Triangle { mesh, triangle, placement, .. } => {
                // The corners' object-space box over the deformation, carried by the
                // placements: the same bound the TLAS uses. A deforming or turning triangle's
                // normal sweeps a cone the samples do not bound, so it may face anywhere.
                let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                let k = mesh.deformation_samples().max(1);
                for s in 0..k {
                    for v in mesh.triangle_at(*triangle as usize, s as f32 / (k - 1).max(1) as f32) {
                        (lo, hi) = (lo.min(v), hi.max(v));
                    }
                }
                let samples = match placement {
                    Placement::Still(m) => std::slice::from_ref(m),
                    Placement::Moving(samples) => &samples[..],
                };
                let (lo, hi) = crate::motion::bounds_over(samples, lo, hi);
                (lo.is_finite() && hi.is_finite()).then(|| LightBounds::facing_anywhere(lo, hi, phi))
            }
        }
    }
}

impl Light {
    /// The light as it is at normalised shutter time `time`: itself when it does not move;
    /// `None` when it cannot emit at that time.
    #[inline]
    pub fn at(&self, time: f32) -> Option<Cow<'_, Light>> {
        let Some(motion) = &self.motion else { return Some(Cow::Borrowed(self)) };
        let (shape, shaping) = motion.pose(time)?;
        Some(Cow::Owned(Light {
            shape,
            visible_to_camera: self.visible_to_camera,
            shaping,
            multipliers: self.multipliers,
            textured_emitter: self.textured_emitter,
            motion: None,
        }))
    }

    /// The light tree's bounds of the light with power `phi`: over its whole motion when it
    /// moves; `None` for lights at infinity.
    pub fn bounds(&self, phi: f32) -> Option<LightBounds> {
        match &self.motion {
            Some(m) => m.bounds(phi),
            None => LightBounds::of(&self.shape, phi),
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;

    /// The bounds over the motion hold the light's bounds at every time between its samples,
    /// and the pose at a sample's time is the light committed there.
    fn assert_bounds_hold_every_pose(light: &Light) {
        let all = light.bounds(1.0).expect("finite light");
        for i in 0..=200 {
            let t = i as f32 / 200.0;
            let posed = light.at(t).expect("emits");
            let at = LightBounds::of(&posed.shape, 1.0).expect("finite light");
            assert!(all.holds(&at), "time {t}: {at:?} outside {all:?}");
        }
    }

    #[test]
    fn a_moving_rect_light_is_bounded_over_its_motion_and_posed_at_each_time() {
        // Turning a quarter turn, sliding and growing twice as large over three samples.
        let samples: Vec<Affine3A> = (0..3)
            .map(|k| {
                let f = k as f32 / 2.0;
                let turn = Quat::from_rotation_y(f * std::f32::consts::FRAC_PI_2);
                Affine3A::from_scale_rotation_translation(Vec3::splat(1.0 + f), turn, Vec3::new(4.0 * f, 1.0, 0.0))
            })
            .collect();
        let mut desc = super::super::LightDesc::new(LightKind::Rect { width: 1.0, height: 0.5 }, samples[0], 2.0);
        (desc.motion, desc.normalize) = (samples.clone(), true);
        let light = desc.commit().expect("emits");
        assert_bounds_hold_every_pose(&light);
        // At the last sample: the light committed there, its normalised radiance divided by
        // the area it has then (four times the first).
        let last = super::super::LightDesc { transform: samples[2], motion: Vec::new(), ..desc.clone() }.commit().unwrap();
        let posed = light.at(1.0).unwrap();
        let Shape::Rect { center, l, area, .. } = posed.shape else { panic!("a rect") };
        let Shape::Rect { center: c2, l: l2, area: a2, .. } = last.shape else { panic!("a rect") };
        assert!((center - c2).length() < 1e-5 && (l - l2).length() < 1e-5 && (area - a2).abs() < 1e-5);
        assert!((area - 2.0).abs() < 1e-5, "1 × 0.5 scaled twice: area {area}");
    }

    #[test]
    fn a_deforming_triangle_on_a_moving_instance_is_bounded_and_posed_as_the_geometry_is() {
        let mut mesh = Mesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], indices: vec![[0, 1, 2]], ..Default::default() };
        // Three shapes: the triangle flips over (its normal sweeps half a turn).
        mesh.deformation = [[Vec3::ZERO, Vec3::X, Vec3::Y], [Vec3::ZERO, Vec3::X, Vec3::Z], [Vec3::ZERO, Vec3::X, -Vec3::Y]].concat();
        let placement: Arc<[Affine3A]> = [Affine3A::IDENTITY, Affine3A::from_translation(Vec3::new(0.0, 0.0, 3.0))].into();
        let mesh = Arc::new(mesh);
        let motion =
            LightMotion::Triangle { mesh: mesh.clone(), triangle: 0, placement: Placement::Moving(placement.clone()), l: Vec3::ONE };
        let frame = Shape::triangle(mesh.triangle(0), Vec3::ONE).unwrap();
        let light = Light { motion: Some(Arc::new(motion)), ..Light::plain(frame, true) };
        assert_bounds_hold_every_pose(&light);
        // Half way: the middle shape, half way along the slide, as the BLAS would place it.
        let posed = light.at(0.5).unwrap();
        let Shape::Triangle { p, .. } = posed.shape else { panic!("a triangle") };
        let expected = mesh.triangle_at(0, 0.5).map(|v| crate::motion::placement_at(&placement, 0.5).to_world.transform_point3(v));
        assert_eq!(p, expected);
        assert!((p[2] - Vec3::new(0.0, 0.0, 2.5)).length() < 1e-6, "{p:?}");
    }
}
