//! Transform motion (and, by the same clock, deformation: [`crate::geometry::Mesh::triangle_at`])
//! over the shutter: a prim's placement sampled at evenly spaced times from
//! shutter open (normalized time 0) to close (1), interpolated linearly between samples as
//! pbrt-v4's and Cycles' motion transforms are between their keys (the samples are taken
//! densely enough by the USD reader that the chord of a rotation stays close to its arc).
//!
//! Linear interpolation keeps every point of the moving object inside the convex hull of its
//! positions at the two bracketing samples, so the union of the object's bounds at the samples
//! encloses all of its motion: that is the bound the TLAS builds over.

use glam::{Affine3A, Vec3};

use crate::geometry::Transform;

/// Most samples one prim's motion may have: clients send them, so they are bounded.
pub const MAX_MOTION_SAMPLES: usize = 64;

/// Where normalized shutter time `time` (clamped to [0, 1]) falls among `count` evenly spaced
/// samples (at least one): the sample before it and the fraction of the way to the next.
#[inline]
pub fn segment(time: f32, count: usize) -> (usize, f32) {
    let last = count - 1;
    let x = time.clamp(0.0, 1.0) * last as f32;
    let i = (x as usize).min(last.saturating_sub(1));
    (i, x - i as f32)
}

/// Placement at normalized shutter time `time` (clamped to [0, 1]) of `samples`, which are
/// evenly spaced over the shutter (at least two).
pub fn transform_at(samples: &[Affine3A], time: f32) -> Affine3A {
    let (i, f) = segment(time, samples.len());
    let (a, b) = (&samples[i], &samples[(i + 1).min(samples.len() - 1)]);
    Affine3A { matrix3: a.matrix3 * (1.0 - f) + b.matrix3 * f, translation: a.translation * (1.0 - f) + b.translation * f }
}

/// [`transform_at`] ready for intersection. An interpolated placement that collapses (two
/// samples mirror each other) falls back to the nearer sample.
pub fn placement_at(samples: &[Affine3A], time: f32) -> Transform {
    Transform::new(transform_at(samples, time)).unwrap_or_else(|| {
        let nearest = (time.clamp(0.0, 1.0) * (samples.len() - 1) as f32).round() as usize;
        Transform::new(samples[nearest]).unwrap_or_else(Transform::identity)
    })
}

/// World to object at `time`: all traversal needs of [`placement_at`] (no normal matrix).
#[inline]
pub fn to_object_at(samples: &[Affine3A], time: f32) -> Affine3A {
    let m = transform_at(samples, time);
    if Transform::invertible(&m) { m.inverse() } else { placement_at(samples, time).to_object }
}

/// World bounds of object-space box (`lo`, `hi`) over the whole motion.
pub fn bounds_over(samples: &[Affine3A], lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let mut out = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for m in samples {
        for i in 0..8 {
            let c =
                Vec3::new(if i & 1 == 0 { lo.x } else { hi.x }, if i & 2 == 0 { lo.y } else { hi.y }, if i & 4 == 0 { lo.z } else { hi.z });
            let w = m.transform_point3(c);
            out = (out.0.min(w), out.1.max(w));
        }
    }
    out
}

/// Why `samples` cannot be a motion, if they cannot: a count outside 2..=[`MAX_MOTION_SAMPLES`]
/// (0 means no motion and is fine), or a sample that is singular or not finite.
pub fn check_samples(samples: &[Affine3A]) -> Result<(), String> {
    if samples.is_empty() {
        return Ok(());
    }
    if samples.len() < 2 || samples.len() > MAX_MOTION_SAMPLES {
        return Err(format!("{} motion samples; a motion has 2 to {MAX_MOTION_SAMPLES}", samples.len()));
    }
    match samples.iter().position(|m| Transform::new(*m).is_none()) {
        Some(i) => Err(format!("motion sample {i} is singular or not finite")),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placements_interpolate_between_evenly_spaced_samples() {
        let samples: Vec<Affine3A> = (0..5).map(|i| Affine3A::from_translation(Vec3::new(i as f32 * i as f32, 0.0, 0.0))).collect();
        // Samples at 0, 1/4, 1/2, 3/4, 1 hold x = 0, 1, 4, 9, 16.
        assert_eq!(transform_at(&samples, 0.0).translation.x, 0.0);
        assert_eq!(transform_at(&samples, 0.5).translation.x, 4.0);
        assert_eq!(transform_at(&samples, 0.625).translation.x, 6.5);
        assert_eq!(transform_at(&samples, 1.0).translation.x, 16.0);
        assert_eq!(transform_at(&samples, 7.0).translation.x, 16.0, "clamped");
        // Traversal's inverse is the full placement's.
        let turning: Vec<Affine3A> = (0..3).map(|i| Affine3A::from_rotation_z(i as f32) * Affine3A::from_scale(Vec3::splat(2.0))).collect();
        assert_eq!(to_object_at(&turning, 0.3), placement_at(&turning, 0.3).to_object);
    }

    #[test]
    fn the_bounds_enclose_every_interpolated_placement() {
        let samples = [
            Affine3A::from_rotation_z(0.0),
            Affine3A::from_rotation_z(0.7) * Affine3A::from_translation(Vec3::X),
            Affine3A::from_scale(Vec3::splat(2.0)),
        ];
        let (lo, hi) = bounds_over(&samples, -Vec3::ONE, Vec3::ONE);
        for k in 0..=100 {
            let m = transform_at(&samples, k as f32 / 100.0);
            for i in 0..8 {
                let c = Vec3::new(
                    if i & 1 == 0 { -1.0 } else { 1.0 },
                    if i & 2 == 0 { -1.0 } else { 1.0 },
                    if i & 4 == 0 { -1.0 } else { 1.0 },
                );
                let w = m.transform_point3(c);
                assert!(w.cmpge(lo - 1e-5).all() && w.cmple(hi + 1e-5).all(), "{w} outside {lo}..{hi} at {k}");
            }
        }
    }

    #[test]
    fn bad_sample_sets_are_named() {
        assert!(check_samples(&[]).is_ok());
        assert!(check_samples(&[Affine3A::IDENTITY]).unwrap_err().contains("1 motion samples"));
        assert!(check_samples(&vec![Affine3A::IDENTITY; MAX_MOTION_SAMPLES + 1]).is_err());
        let singular = Affine3A::from_scale(Vec3::ZERO);
        assert!(check_samples(&[Affine3A::IDENTITY, singular]).unwrap_err().contains("sample 1"));
    }
}
