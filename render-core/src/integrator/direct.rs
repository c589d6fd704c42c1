//! Next-event estimation: a light sampled from the vertex, its shadow ray (through smooth
//! glass when caustic avoidance asks for transparent shadows), weighted by MIS against BSDF
//! sampling.

use glam::{Vec2, Vec3};

use crate::bsdf::{Bsdf, PathKind};
use crate::caustics;
use crate::geometry::Ray;
use crate::light::{Light, LightSample, ShadingContext};
use crate::sampling::power_heuristic;

use super::path::{PathState, clamped};
use super::shading::Vertex;
use super::{LightStrategy, PathCounters, Tracer};

/// A shadow ray from `origin` towards the light point `ls` sampled from `p`: aimed at the
/// point and stopped just short of it. An offset origin (which scales with the surface) can
/// exceed a fixed margin, and a ray along the original direction then met an emitting
/// mesh's own surface before tmax.
pub(super) fn shadow_ray(origin: Vec3, p: Vec3, ls: &LightSample) -> Ray {
    if ls.dist.is_finite() {
        let to = p + ls.wi * ls.dist - origin;
        let d = to.length();
        Ray::new(origin, to / d).with_tmax(d * (1.0 - 1e-4))
    } else {
        Ray::new(origin, ls.wi)
    }
}

/// What next-event estimation at one vertex needs besides the path.
pub(super) struct DirectLighting<'v> {
    pub v: &'v Vertex<'v>,
    pub bsdf: &'v Bsdf,
    pub ctx: ShadingContext,
    /// Light position (2D) and light choice.
    pub u: [f32; 3],
    /// The share of light leaving a subsurface medium that transparent shadows from inside
    /// did not already take (caustic avoidance; 1 otherwise).
    pub leaving_share: f32,
    /// Light found here is direct (the first surface, or the exit of the walk it started).
    pub is_direct: bool,
}

impl<const FULL: bool> Tracer<'_, FULL> {
    /// The light samples `u` (light position, light choice) draws from `ctx`, a textured
    /// emitter's radiance read where each landed; samples that carry no light are dropped, and
    /// so are lights that do not reach link group `group` (light linking). None when the scene
    /// has no lights or only BSDF sampling may find them.
    pub(super) fn each_light_sample(
        &self,
        ctx: &ShadingContext,
        u: [f32; 3],
        group: u32,
        mut visit: impl FnMut(LightSample, &Light, usize),
    ) {
        if self.scene.lights.is_empty() || self.settings.strategy == LightStrategy::BsdfOnly {
            return;
        }
        let [ul_x, ul_y, u_sel] = u;
        let reaches = |i: usize| self.reaches(i, group);
        let budget = self.settings.light_split_budget;
        self.scene.lights.sample_each(ctx, u_sel, Vec2::new(ul_x, ul_y), budget, group, reaches, |mut ls, light, i| {
            if let Some((instance, triangle)) = light.textured_emitter {
                ls.li = self.scene.emission_at(instance, triangle, ctx.p + ls.wi * ls.dist, ctx.time);
            }
            if ls.li != Vec3::ZERO && ls.pdf > 0.0 {
                visit(ls, light, i);
            }
        });
    }

    /// Adds the direct light at vertex `d.v` to the path.
    pub(super) fn add_direct_light(&self, path: &mut PathState, d: &DirectLighting, counters: &mut PathCounters) {
        let group = self.group_of_instance(d.v.s.instance);
        self.each_light_sample(&d.ctx, d.u, group, |ls, light, i| self.add_light_sample(path, d, &ls, (light, i), counters));
    }

    /// Whether the first surface's light is split by lobe into the light-path AOVs.
    #[inline]
    fn splits_by_lobe(&self, depth: u32) -> bool {
        depth == 0 && (self.light_path_aovs() || self.force())
    }

    /// One light sample's contribution through the BSDF, if its shadow ray gets through.
    fn add_light_sample(
        &self,
        path: &mut PathState,
        d: &DirectLighting,
        ls: &LightSample,
        light: (&Light, usize),
        counters: &mut PathCounters,
    ) {
        let ((v, bsdf), (light, index)) = ((d.v, d.bsdf), light);
        let wi_local = v.frame.to_local(ls.wi);
        // A light with diffuse/specular multipliers weighs each kind of lobe apart.
        let parts = (light.has_multipliers() || self.splits_by_lobe(path.depth)).then(|| {
            let mut parts = bsdf.eval_by_kind(v.wo_local, wi_local);
            for (k, kind) in [PathKind::Diffuse, PathKind::Specular, PathKind::Transmission].into_iter().enumerate() {
                parts[k] *= light.multiplier(kind);
            }
            parts
        });
        // MIS weighs the sample by the BSDF's density there unless only the light can find it
        // (a shadow-linked light is found by light sampling alone: see `found_light_weight`).
        let needs_pdf = !ls.delta && self.settings.strategy != LightStrategy::LightOnly && !self.shadow_linked(index);
        let (f, bsdf_pdf) = match &parts {
            _ if !v.sides_agree(ls.wi, wi_local.z) => (Vec3::ZERO, None),
            Some(p) => (p[0] + p[1] + p[2], None),
            None if needs_pdf => {
                let (f, pdf) = bsdf.eval_pdf(v.wo_local, wi_local);
                (f, Some(pdf))
            }
            None => (bsdf.eval(v.wo_local, wi_local), None),
        };
        if f == Vec3::ZERO {
            return;
        }
        let shadow = shadow_ray(v.leave(ls.wi).origin, v.s.p, ls).with_time(v.s.time);
        counters.rays += 1;
        let Some(glass) = self.shadow_pass(&shadow, v.a_roughness, index) else { return };
        let tr = self.volume_transmittance(&shadow, index);
        if tr == 0.0 {
            return;
        }
        let w = match glass {
            Some(_) => 1.0,
            None if !needs_pdf => 1.0,
            None => power_heuristic(ls.pdf, bsdf_pdf.unwrap_or_else(|| bsdf.pdf(v.wo_local, wi_local))),
        };
        // Light out of a medium through its boundary: transparent shadows from inside took
        // their share of it.
        let w = if wi_local.z * v.wo_local.z < 0.0 { w * d.leaving_share } else { w };
        let scale = path.beta * wi_local.z.abs() * ls.li * glass.unwrap_or(Vec3::ONE) * (tr * w / ls.pdf);
        let c = clamped(f * scale, path.depth >= 1, self.settings.clamp_indirect);
        if self.splits_by_lobe(path.depth) {
            // Direct light at the first surface, split by the lobes that reflect it.
            path.light.total += c;
            for (k, part) in parts.unwrap_or_default().into_iter().enumerate() {
                path.light.record(k, part * scale, true);
            }
        } else {
            let first = path.light.first;
            path.light.add(first, c, d.is_direct);
        }
    }

    /// Whether the shadow ray gets through: None when blocked; Some(None) unoccluded;
    /// Some(Some(t)) through smooth glass with transmittance `t` weighted against the paths
    /// that refract through it (caustic avoidance; nothing else samples that straight line,
    /// so no MIS weight). `a_roughness`: the roughness of the surface the shadow leaves;
    /// `light`: the light it aims at, whose shadow links say what blocks it.
    fn shadow_pass(&self, shadow: &Ray, a_roughness: f32, light: usize) -> Option<Option<Vec3>> {
        if self.avoid() {
            self.scene.shadow_transmittance(shadow, shadow.tmax, None, Some(light)).map(|pass| match pass.crossings {
                0 => None,
                _ => Some(pass.transmittance * caustics::transparent_weight(a_roughness, pass.roughness)),
            })
        } else if self.force() {
            // The transparent-shadow walk, with glass still opaque.
            self.scene.shadow_transmittance(shadow, shadow.tmax, None, Some(light)).filter(|p| p.crossings == 0).map(|_| None)
        } else {
            (!self.occluded(shadow, light)).then_some(None)
        }
    }

    /// Whether anything blocks `shadow` towards `light` before its end: for a shadow-linked
    /// light, only the prims that cast its shadows (linked scenes take the general loop).
    #[inline]
    pub(super) fn occluded(&self, shadow: &Ray, light: usize) -> bool {
        match FULL {
            true => self.scene.occluded_for(shadow, shadow.tmax, light),
            false => self.scene.occluded(shadow, shadow.tmax),
        }
    }
}
