//! The random walk inside a subsurface medium, and caustic avoidance's light reaching its
//! scattering events through the boundary.

use glam::{Vec2, Vec3};

use crate::bsdf::PathKind;
use crate::caustics;
use crate::geometry::Ray;
use crate::light::ShadingContext;
use crate::sampling::PathSampler;
use crate::subsurface::{Medium, Step};

use super::direct::shadow_ray;
use super::path::{PathState, PrevVertex, clamped};
use super::{LightStrategy, NO_GROUP, PathCounters, Tracer};

/// Most scattering events one path takes inside subsurface media.
const MAX_MEDIUM_STEPS: u32 = 4096;

/// Roughness of a scattering event in a medium for caustic avoidance's weighting: a phase
/// function scatters like the roughest surface.
pub(super) const MEDIUM_ROUGHNESS: f32 = 1.0;

/// A scattering event in a subsurface medium.
struct MediumPoint {
    medium: Medium,
    p: Vec3,
    /// The direction the path arrived along.
    dir: Vec3,
    /// The path's throughput there.
    beta: Vec3,
    /// The kind of lobe that led into the medium, for lights' multipliers.
    kind: PathKind,
    /// The path's shutter time.
    time: f32,
    /// The link group it is lit as.
    receiver: u32,
}

/// Where a step of the walk took the path.
pub(super) enum WalkStep {
    /// It scattered in the medium; the path's ray leaves the scattering event.
    Scattered,
    /// It reached the surface its ray hit.
    Boundary,
    /// The walk ended (too long, no throughput left, or roulette).
    Ended,
}

impl<const FULL: bool> Tracer<'_, FULL> {
    /// One step of the walk in `medium` along the path's ray, whose surface lies at `t_surface`.
    pub(super) fn walk_step(
        &self,
        path: &mut PathState,
        medium: Medium,
        t_surface: f32,
        rng: &mut PathSampler,
        counters: &mut PathCounters,
    ) -> WalkStep {
        let [u_channel, u_t, u_x, u_y] = rng.next_4d();
        let (t, weight) = match medium.step(t_surface, u_channel, u_t) {
            Step::Surface { weight } => {
                path.beta *= weight;
                return WalkStep::Boundary;
            }
            Step::Scatter { t, weight } => (t, weight),
        };
        path.beta *= weight;
        path.walk.steps += 1;
        if path.walk.steps > MAX_MEDIUM_STEPS || path.is_dark() || !self.walk_survives(path, rng) {
            return WalkStep::Ended;
        }
        let ray = path.ray;
        let p = ray.origin + ray.dir * t;
        let kind = path.prev.map_or(PathKind::Transmission, |p| p.kind);
        // The walk is lit as the surface it entered through.
        let receiver = path.prev.map_or(NO_GROUP, |p| p.receiver);
        if self.avoid() && path.walk.shadows && !self.scene.lights.is_empty() && self.settings.strategy != LightStrategy::BsdfOnly {
            let [ul_x, ul_y, u_sel, _] = rng.next_4d();
            let at = MediumPoint { medium, p, dir: ray.dir, beta: path.beta, kind, time: ray.time, receiver };
            let c = self.light_through_boundary(&at, [ul_x, ul_y, u_sel], counters);
            let (first, in_walk) = (path.light.first, path.light.in_walk);
            path.light.add(first, c, in_walk);
        }
        let wi = medium.sample_phase(ray.dir, Vec2::new(u_x, u_y));
        path.prev = Some(PrevVertex {
            ctx: ShadingContext { p, n: Vec3::ZERO, both_sides: true, time: ray.time },
            bsdf_pdf: medium.phase_pdf(ray.dir, wi),
            delta: false,
            kind,
            roughness: MEDIUM_ROUGHNESS,
            in_medium: true,
            receiver,
        });
        path.ray = Ray::new(p, wi).with_time(path.ray.time);
        WalkStep::Scattered
    }

    /// Russian roulette on the energy throughput (see [`PathState::survives_roulette`]) after
    /// 8 steps: deep walks in bright media are long, and most of their steps carry little.
    fn walk_survives(&self, path: &mut PathState, rng: &mut PathSampler) -> bool {
        if path.walk.steps <= 8 {
            return true;
        }
        let q = (1.0 - (path.beta * path.eta_scale).max_element()).clamp(0.0, 0.95);
        let [u_rr, ..] = rng.next_4d();
        if u_rr < q {
            return false;
        }
        path.beta /= 1.0 - q;
        true
    }

    /// Caustic avoidance's light at a scattering event in a medium (Kulla & Conty's
    /// "Revisiting Physically Based Shading at Imageworks", the section on brute-force
    /// subsurface scattering): lights reached by transparent shadows across the medium's
    /// boundary, weighted against the walks that leave towards them (all of it behind a
    /// smooth boundary). `u`: the light position and the light choice. A light inside the
    /// medium (no crossing) is left to phase sampling.
    fn light_through_boundary(&self, at: &MediumPoint, u: [f32; 3], counters: &mut PathCounters) -> Vec3 {
        let scene = self.scene;
        let ctx = ShadingContext { p: at.p, n: Vec3::ZERO, both_sides: true, time: at.time };
        let mut total = Vec3::ZERO;
        self.each_light_sample(&ctx, u, at.receiver, |ls, light, i| {
            let shadow = shadow_ray(at.p, at.p, &ls).with_time(at.time);
            counters.rays += 1;
            let Some(pass) = scene.shadow_transmittance(&shadow, shadow.tmax, Some(at.medium), Some(i)).filter(|pass| pass.crossings > 0)
            else {
                return;
            };
            let w = caustics::roughness_weight(MEDIUM_ROUGHNESS, pass.roughness);
            let phase = at.medium.phase_pdf(at.dir, ls.wi);
            let c = at.beta * ls.li * pass.transmittance * (phase * w * light.multiplier(at.kind) / ls.pdf);
            total += clamped(c, true, self.settings.clamp_indirect);
        });
        total
    }
}
