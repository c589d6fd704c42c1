//! Two-level ray tracing on obvhs: one compressed-wide BVH (CWBVH) per mesh (the BLAS) and
//! one over instance bounds (the TLAS). This is the only module that names obvhs types.
//!
//! obvhs has no built-in instancing, so the TLAS leaf callback transforms the ray into the
//! instance's object space and traverses that mesh's BLAS. The direction is not
//! renormalised, so hit distances stay in world units.

use std::time::Duration;

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{
    Boundable, BvhBuildParams,
    aabb::Aabb,
    cwbvh::{CwBvh, builder::build_cwbvh, builder::build_cwbvh_from_tris},
    ray::{Ray as BvhRay, RayHit},
    triangle::Triangle,
};

use crate::geometry::{Mesh, Ray, Transform};

/// An obvhs ray. Negative zeros in the direction are made positive: obvhs derives the
/// traversal octant from sign bits and the slab test from `1/x`, and a `-0.0` component
/// makes it miss boxes that the ray grazes along that axis.
#[inline(always)]
fn bvh_ray(o: Vec3A, d: Vec3A, tmax: f32) -> BvhRay {
    BvhRay::new(o, d + Vec3A::ZERO, 0.0, tmax)
}

/// A triangle in BVH order, stored as vertex and edges for Möller-Trumbore.
#[derive(Clone, Copy, Debug)]
struct RtTriangle {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

impl RtTriangle {
    /// Möller & Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection" (1997).
    /// Returns (t, b1, b2) for a hit inside (tmin, tmax).
    #[inline(always)]
    fn intersect(&self, o: Vec3A, d: Vec3A, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        let p = d.cross(self.e2);
        let det = self.e1.dot(p);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let s = o - self.v0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.e2.dot(q) * inv;
        (t > tmin && t < tmax).then_some((t, u, v))
    }
}

/// The bottom-level BVH of one mesh.
pub struct Blas {
    bvh: CwBvh,
    tris: Vec<RtTriangle>,
    /// Original triangle index of each triangle in BVH order.
    tri_ids: Vec<u32>,
    bounds: Aabb,
}

/// How much effort a BVH build spends on quality.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildQuality {
    /// Fast PLOC build, little reinsertion: for interactive edits.
    Fast,
    /// obvhs' medium preset: the default.
    #[default]
    Medium,
}

impl BuildQuality {
    fn params(self) -> BvhBuildParams {
        let mut p = match self {
            BuildQuality::Fast => BvhBuildParams::fast_build(),
            BuildQuality::Medium => BvhBuildParams::medium_build(),
        };
        // Pre-splitting duplicates primitive references; we index triangles directly.
        p.pre_split = false;
        p
    }
}

impl Blas {
    /// Builds the BVH of a mesh with at least one triangle.
    pub fn build(mesh: &Mesh, quality: BuildQuality) -> Self {
        let tris: Vec<Triangle> = (0..mesh.triangle_count())
            .map(|i| {
                let [a, b, c] = mesh.triangle(i);
                Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&tris, quality.params(), &mut Duration::default());
        let rt = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                RtTriangle { v0: t.v0, e1: t.v1 - t.v0, e2: t.v2 - t.v0 }
            })
            .collect();
        let tri_ids = bvh.primitive_indices.clone();
        let bounds = bvh.total_aabb;
        Blas { bvh, tris: rt, tri_ids, bounds }
    }

    /// Closest hit in object space: (t, original triangle index, barycentrics).
    #[inline]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(f32, u32, Vec2)> {
        let ray = bvh_ray(o, d, tmax);
        let mut hit = RayHit::none();
        let mut bary = Vec2::ZERO;
        let found = self.bvh.ray_traverse(ray, &mut hit, |r, id| match self.tris[id].intersect(r.origin, r.direction, r.tmin, r.tmax) {
            Some((t, u, v)) => {
                bary = Vec2::new(u, v);
                t
            }
            None => f32::INFINITY,
        });
        found.then(|| (hit.t, self.tri_ids[hit.primitive_id as usize], bary))
    }

    /// True when anything lies on the segment (0, tmax).
    #[inline]
    pub fn occluded(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        let ray = bvh_ray(o, d, tmax);
        !self
            .bvh
            .ray_traverse_miss(ray, |r, id| self.tris[id].intersect(r.origin, r.direction, r.tmin, r.tmax).map_or(f32::INFINITY, |h| h.0))
    }

    /// Object-space bounds.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.bounds.min.into(), self.bounds.max.into())
    }
}

/// An instance of a BLAS placed in the world.
pub struct TlasInstance {
    /// Index of the BLAS (mesh) this instance references.
    pub blas: usize,
    /// Placement.
    pub transform: Transform,
}

struct InstanceBounds(Aabb);

impl Boundable for InstanceBounds {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// A closest hit.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Distance along the world ray (in units of its direction's length).
    pub t: f32,
    /// Index of the instance hit.
    pub instance: u32,
    /// Triangle index within the instance's mesh.
    pub triangle: u32,
    /// Barycentric coordinates (b1, b2) of the hit.
    pub bary: Vec2,
}

/// The top-level acceleration structure over instances of shared BLASes.
pub struct Tlas {
    bvh: Option<CwBvh>,
    /// Instances in BVH order, with their original index.
    ordered: Vec<(u32, usize, Transform)>,
    /// Rays enter traversal with their direction scaled by this power of two (≤ 1):
    /// obvhs's CWBVH node test clamps the entry distance to an absolute 1e-4 (`node.rs`,
    /// `EPSILON`), which culled every box closer than 1e-4 units, i.e. most of a scene
    /// 2e-4 units big (its continuation rays missed the walls). Scaling the direction by the
    /// scene's extent (rounded down to a power of two, so exactly) moves that limit to 1e-4 of
    /// the scene's size; scenes a unit or larger keep 1.
    ray_scale: f32,
}

impl Tlas {
    /// Builds over `instances`, whose `blas` indices refer into `blases`.
    pub fn build(blases: &[std::sync::Arc<Blas>], instances: &[TlasInstance]) -> Self {
        if instances.is_empty() {
            return Tlas { bvh: None, ordered: Vec::new(), ray_scale: 1.0 };
        }
        let bounds: Vec<InstanceBounds> = instances
            .iter()
            .map(|inst| {
                let (lo, hi) = blases[inst.blas].bounds();
                let mut aabb = Aabb::empty();
                for i in 0..8 {
                    let corner = Vec3::new(
                        if i & 1 == 0 { lo.x } else { hi.x },
                        if i & 2 == 0 { lo.y } else { hi.y },
                        if i & 4 == 0 { lo.z } else { hi.z },
                    );
                    aabb.extend(inst.transform.to_world.transform_point3(corner).into());
                }
                InstanceBounds(aabb)
            })
            .collect();
        let bvh = build_cwbvh(&bounds, BuildQuality::Medium.params(), &mut Duration::default());
        let ordered = bvh.primitive_indices.iter().map(|&i| (i, instances[i as usize].blas, instances[i as usize].transform)).collect();
        let extent = (bvh.total_aabb.max - bvh.total_aabb.min).max_element();
        let ray_scale = if extent.is_finite() && extent > 0.0 && extent < 1.0 { 2f32.powi(extent.log2().floor() as i32) } else { 1.0 };
        Tlas { bvh: Some(bvh), ordered, ray_scale }
    }

    /// Closest hit along `ray` before `ray.tmax`.
    pub fn intersect(&self, blases: &[std::sync::Arc<Blas>], ray: &Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let k = self.ray_scale;
        let wray = bvh_ray(ray.origin.into(), Vec3A::from(ray.dir) * k, ray.tmax / k);
        let mut rh = RayHit::none();
        let mut best: Option<Hit> = None;
        bvh.ray_traverse(wray, &mut rh, |r, id| {
            let (inst, blas, xf) = &self.ordered[id];
            let o = xf.to_object.transform_point3a(r.origin);
            let d = xf.to_object.transform_vector3a(r.direction);
            match blases[*blas].intersect(o, d, r.tmax) {
                Some((t, tri, bary)) => {
                    best = Some(Hit { t: t * k, instance: *inst, triangle: tri, bary });
                    t
                }
                None => f32::INFINITY,
            }
        });
        best
    }

    /// True when anything blocks the segment from `ray.origin` to `ray.at(tmax)`.
    pub fn occluded(&self, blases: &[std::sync::Arc<Blas>], ray: &Ray, tmax: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let k = self.ray_scale;
        let wray = bvh_ray(ray.origin.into(), Vec3A::from(ray.dir) * k, tmax / k);
        !bvh.ray_traverse_miss(wray, |r, id| {
            let (_, blas, xf) = &self.ordered[id];
            let o = xf.to_object.transform_point3a(r.origin);
            let d = xf.to_object.transform_vector3a(r.direction);
            // Any distance below tmax reports the hit; not `0.5 * tmax`, which is infinite for
            // shadow rays towards dome and distant lights and let them pass through everything.
            if blases[*blas].occluded(o, d, r.tmax) { 0.0 } else { f32::INFINITY }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Affine3A;
    use std::sync::Arc;

    fn quad() -> Mesh {
        Mesh {
            positions: vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn hits_closer_than_obvhs_node_epsilon_are_found_in_tiny_scenes() {
        // A quad 2e-4 across, instanced at that scale; rays 5e-5 away must hit it, though
        // obvhs clamps node entry distances to 1e-4.
        let blas = vec![Arc::new(Blas::build(&quad(), BuildQuality::Medium))];
        let xf = Transform::new(Affine3A::from_scale(Vec3::splat(1e-4))).unwrap();
        let tlas = Tlas::build(&blas, &[TlasInstance { blas: 0, transform: xf }]);
        let ray = Ray::new(Vec3::new(2e-5, -3e-5, 5e-5), -Vec3::Z);
        let hit = tlas.intersect(&blas, &ray).expect("a hit 5e-5 away");
        assert!((hit.t - 5e-5).abs() < 1e-9, "t = {}", hit.t);
        assert!(tlas.occluded(&blas, &ray, 1e-4));
        assert!(!tlas.occluded(&blas, &ray, 4e-5));
    }

    #[test]
    fn a_lone_triangle_and_a_lone_instance_are_found() {
        let m = Mesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], indices: vec![[0, 1, 2]], ..Default::default() };
        let blas = vec![Arc::new(Blas::build(&m, BuildQuality::Medium))];
        let tlas = Tlas::build(&blas, &[TlasInstance { blas: 0, transform: Transform::identity() }]);
        let hit = tlas.intersect(&blas, &Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).expect("hit");
        assert_eq!((hit.instance, hit.triangle), (0, 0));
    }

    #[test]
    fn instanced_hits_report_world_distance_and_barycentrics() {
        let blas = vec![Arc::new(Blas::build(&quad(), BuildQuality::Medium))];
        let xf =
            Transform::new(Affine3A::from_scale_rotation_translation(Vec3::splat(2.0), glam::Quat::IDENTITY, Vec3::new(0.0, 0.0, -5.0)))
                .unwrap();
        let tlas = Tlas::build(
            &blas,
            &[
                TlasInstance { blas: 0, transform: xf },
                TlasInstance { blas: 0, transform: Transform::new(Affine3A::from_translation(Vec3::new(0.0, 0.0, -10.0))).unwrap() },
            ],
        );
        let ray = Ray::new(Vec3::new(1.0, 0.5, 0.0), Vec3::new(0.0, 0.0, -1.0));
        let hit = tlas.intersect(&blas, &ray).expect("hit");
        assert!((hit.t - 5.0).abs() < 1e-5);
        assert_eq!(hit.instance, 0);
        // object-space point (0.5, 0.25, 0): in triangle 0 (0,1,2)
        assert_eq!(hit.triangle, 0);
        let [a, b, c] = quad().triangle(0);
        let p = a * (1.0 - hit.bary.x - hit.bary.y) + b * hit.bary.x + c * hit.bary.y;
        assert!((p - Vec3::new(0.5, 0.25, 0.0)).length() < 1e-5);
        assert!(tlas.occluded(&blas, &ray, 6.0));
        assert!(!tlas.occluded(&blas, &ray, 4.0));
        assert!(tlas.occluded(&blas, &ray, f32::INFINITY), "an unbounded shadow ray is blocked too");
        let miss = Ray::new(Vec3::new(5.0, 5.0, 0.0), Vec3::new(0.0, 0.0, -1.0));
        assert!(tlas.intersect(&blas, &miss).is_none());
    }
}
