//! Paths through volumes ([`crate::volume`]): the free flight along each ray with the
//! emission gathered on the way and, at a real collision, next-event estimation through the
//! phase function and the next direction drawn from it.

use glam::{Vec2, Vec3};

use crate::bsdf::PathKind;
use crate::geometry::Ray;
use crate::light::ShadingContext;
use crate::sampling::{PathSampler, power_heuristic};
use crate::volume::Volume;
use crate::volume::tracking::{self, Stream};

use super::direct::shadow_ray;
use super::medium::MEDIUM_ROUGHNESS;
use super::path::{PathState, PrevVertex, clamped};
use super::{LightStrategy, NO_GROUP, PathCounters, Tracer};

/// What the path did along its ray's segment through the volumes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum VolumeStep {
    /// It crossed them to the surface (or out of the scene).
    Passed,
    /// It scattered; the path's ray leaves the scattering point.
    Scattered,
    /// It collided and ended there (depth, roulette or no throughput left).
    Ended,
}

/// A real collision in a volume.
struct Collision<'s> {
    volume: &'s Volume,
    p: Vec3,
    /// Towards where the path came from.
    wo: Vec3,
    time: f32,
    /// Its link group.
    receiver: u32,
}

impl<const FULL: bool> Tracer<'_, FULL> {
    /// Tracks the path's ray through the volumes up to `t_hit`, adding their emission.
    pub(super) fn volume_step(&self, path: &mut PathState, t_hit: f32, rng: &mut PathSampler, counters: &mut PathCounters) -> VolumeStep {
        let [u_seed_a, u_seed_b, u_sel, u_rr] = rng.next_4d();
        let seed = (u_seed_a.to_bits() as u64) << 32 | u_seed_b.to_bits() as u64;
        let ray = path.ray;
        let flight = tracking::fly(&self.scene.volumes, &ray, t_hit, &mut Stream::new(seed));
        if flight.emitted != Vec3::ZERO {
            let c = clamped(path.beta * flight.emitted, path.depth >= 2, self.settings.clamp_indirect);
            let (k, direct) = (path.light.found_at(path.depth), path.light.seg_direct);
            path.light.add(k, c, direct);
        }
        let Some((t, k)) = flight.collision else { return VolumeStep::Passed };
        let volume = &self.scene.volumes[k];
        let p = ray.origin + ray.dir * t;
        path.beta *= volume.albedo_at(p, ray.time);
        if path.depth >= self.settings.max_depth || path.is_dark() {
            return VolumeStep::Ended;
        }
        if path.depth == 0 {
            path.light.first = PathKind::Diffuse as usize;
        }
        let at = Collision { volume, p, wo: -ray.dir, time: ray.time, receiver: self.links().map_or(NO_GROUP, |l| l.volume_group(k)) };
        let [ul_x, ul_y, up_x, up_y] = rng.next_4d();
        self.add_phase_direct(path, &at, [ul_x, ul_y, u_sel], counters);
        let (wi, pdf) = volume.phase.sample(at.wo, Vec2::new(up_x, up_y));
        (path.light.seg_direct, path.light.in_walk) = (path.depth == 0, false);
        let ctx = ShadingContext { p: at.p, n: Vec3::ZERO, both_sides: true, time: at.time };
        let (kind, receiver) = (PathKind::Diffuse, at.receiver);
        path.prev = Some(PrevVertex { ctx, bsdf_pdf: pdf, delta: false, kind, roughness: MEDIUM_ROUGHNESS, in_medium: false, receiver });
        path.cone = path.cone.after_bounce(path.cone.width_at(t), MEDIUM_ROUGHNESS);
        path.ray = Ray::new(at.p, wi).with_time(at.time);
        path.depth += 1;
        match path.survives_roulette(self.settings.rr_start, u_rr) {
            true => VolumeStep::Scattered,
            false => VolumeStep::Ended,
        }
    }

    /// Next-event estimation at a collision: a light sampled, its shadow ray's visibility and
    /// transmittance, the phase function, MIS against phase sampling.
    fn add_phase_direct(&self, path: &mut PathState, at: &Collision, u: [f32; 3], counters: &mut PathCounters) {
        let ctx = ShadingContext { p: at.p, n: Vec3::ZERO, both_sides: true, time: at.time };
        self.each_light_sample(&ctx, u, at.receiver, |ls, light, i| {
            let phase = at.volume.phase.eval(at.wo, ls.wi);
            let shadow = shadow_ray(at.p, at.p, &ls).with_time(at.time);
            counters.rays += 1;
            if self.occluded(&shadow, i) {
                return;
            }
            let tr = self.volume_transmittance(&shadow, i);
            let w = match ls.delta || self.settings.strategy == LightStrategy::LightOnly || self.shadow_linked(i) {
                true => 1.0,
                false => power_heuristic(ls.pdf, phase),
            };
            let c = path.beta * ls.li * (phase * tr * w * light.multiplier(PathKind::Diffuse) / ls.pdf);
            let first = path.light.first;
            path.light.add(first, clamped(c, path.depth >= 1, self.settings.clamp_indirect), path.depth == 0);
        });
    }

    /// The volumes' transmittance along a shadow ray towards light `light` (1 without
    /// volumes), by ratio tracking with numbers hashed from the ray, so it needs no sampler
    /// dimension. Volumes outside a shadow-linked light's link let its light through.
    pub(super) fn volume_transmittance(&self, shadow: &Ray, light: usize) -> f32 {
        if !FULL || self.scene.volumes.is_empty() {
            return 1.0;
        }
        let seed = crate::scene::ray_hash(shadow.origin, shadow.dir, 0x7a1e_5eed);
        let links = self.links().filter(|l| l.shadow_linked(light));
        let casts = |k: usize| links.is_none_or(|l| l.volume_casts_shadow(light, k));
        tracking::transmittance(&self.scene.volumes, shadow, shadow.tmax, &mut Stream::new(seed), casts)
    }
}
