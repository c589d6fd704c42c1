//! Light a path finds by hitting an emitter: area lights it crosses, lights at infinity it
//! escapes to, and emissive surfaces it lands on, each weighted by MIS against next-event
//! estimation from the vertex before.

use glam::Vec3;

use crate::bvh::Hit;
use crate::sampling::power_heuristic;

use super::path::{PathState, PrevVertex, clamped};
use super::shading::Vertex;
use super::{LightStrategy, Tracer};

impl<const FULL: bool> Tracer<'_, FULL> {
    /// MIS weight of light `light` found by BSDF sampling from `prev`, whose light-sampling
    /// density for this direction is `pdf_light`: 1 from the camera or after a delta lobe.
    fn found_light_weight(&self, prev: &Option<PrevVertex>, light: u32, pdf_light: f32) -> f32 {
        match prev {
            None => 1.0,
            Some(p) if p.delta || p.in_medium => 1.0,
            Some(_) if self.settings.strategy == LightStrategy::BsdfOnly => 1.0,
            Some(_) if self.settings.strategy == LightStrategy::LightOnly => 0.0,
            // Prims that do not cast a shadow-linked light's shadows still stop the rays that
            // BSDF sampling traces, so those rays cannot find it everywhere light sampling
            // does: light sampling alone counts it.
            Some(_) if self.shadow_linked(light as usize) => 0.0,
            Some(p) => {
                let pmf = self.scene.lights.pmf(&p.ctx, light as usize, self.settings.light_split_budget, p.receiver);
                power_heuristic(p.bsdf_pdf, pmf * pdf_light)
            }
        }
    }

    /// Adds the radiance `le · tint` of light `light` reached along the path's ray, at
    /// light-sampling density `pdf_light` from the previous vertex.
    fn add_emission(&self, path: &mut PathState, le: Vec3, tint: Vec3, light: u32, pdf_light: f32, share: f32) {
        if path.prev.is_some_and(|p| !self.reaches(light as usize, p.receiver)) {
            return;
        }
        let multiplier = path.prev.map_or(1.0, |p| self.scene.lights.lights[light as usize].multiplier(p.kind));
        let weight = self.found_light_weight(&path.prev, light, pdf_light);
        let c = clamped(path.beta * le * tint * (multiplier * share * weight), path.depth >= 2, self.settings.clamp_indirect);
        let k = path.light.found_at(path.depth);
        let seg_direct = path.light.seg_direct;
        path.light.add(k, c, seg_direct);
    }

    /// Area lights the ray crosses before `t_hit` (they do not occlude).
    pub(super) fn add_crossed_lights(&self, path: &mut PathState, t_hit: f32, share: f32) {
        let ray = path.ray;
        self.scene.crossable_lights.visit_crossed(ray.origin, ray.dir, t_hit, |i| {
            let Some(light) = self.scene.lights.lights[i as usize].at(ray.time) else { return };
            if path.prev.is_none() && !light.visible_to_camera {
                return;
            }
            if let Some(lh) = light.shape.intersect(ray.origin, ray.dir, t_hit) {
                let pdf = path.prev.map_or(0.0, |p| light.shape.pdf(&p.ctx, ray.dir, lh.t));
                self.add_emission(path, lh.le, light.shaped(ray.dir), i, pdf, share);
            }
        });
    }

    /// Lights at infinity seen by a ray that left the scene.
    pub(super) fn add_escaped(&self, path: &mut PathState, share: f32) {
        let dir = path.ray.dir;
        for &i in &self.scene.infinite_lights {
            let Some(light) = self.scene.lights.lights[i as usize].at(path.ray.time) else { continue };
            if path.prev.is_none() && !light.visible_to_camera {
                continue;
            }
            let (le, pdf) = light.shape.escaped_with_pdf(dir, path.prev.as_ref().map(|p| &p.ctx));
            if le != Vec3::ZERO {
                self.add_emission(path, le, Vec3::ONE, i, pdf, share);
            }
        }
    }

    /// The emission of the surface the path landed on, when it emits.
    pub(super) fn add_surface_emission(&self, path: &mut PathState, v: &Vertex, hit: &Hit, share: f32) {
        let Some(li) = v.s.light else { return };
        let Some(light) = self.scene.lights.lights[li as usize].at(hit.time) else { return };
        let pdf = path.prev.map_or(0.0, |p| light.shape.pdf(&p.ctx, path.ray.dir, hit.t));
        // A textured emitter's radiance is the material's here; the shape holds its mean.
        // After a bounce it is read at the finest level, as light sampling reads it: MIS
        // combines the two only if both estimate the same emission (a footprint-blurred
        // lookup made BSDF-sampled light 20% off light-sampled light on a lit floor).
        let le = match (&v.local, light.textured_emitter) {
            (Some((m, _)), Some(_)) if path.depth == 0 => m.emission * self.scene.glow_scale(hit.instance),
            (_, Some((instance, triangle))) => self.scene.emission_at(instance, triangle, v.s.p, hit.time),
            _ => light.shape.radiance(),
        };
        self.add_emission(path, le, Vec3::ONE, li, pdf, share);
    }
}
