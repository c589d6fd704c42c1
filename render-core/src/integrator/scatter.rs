//! Continuing the path: the BSDF samples the next direction; crossing a subsurface
//! boundary enters or leaves its medium; caustic avoidance weighs refraction into smooth glass
//! and raises the roughness floor.

use glam::{Vec2, Vec3};

use crate::bsdf::{Bsdf, PathKind};
use crate::caustics;
use crate::light::ShadingContext;

use super::Tracer;
use super::path::{PathState, PrevVertex, SUBSURFACE};
use super::shading::Vertex;

impl<const FULL: bool> Tracer<'_, FULL> {
    /// Samples the next direction at `v` with `u` (direction, lobe choice) and moves the
    /// path's ray there. False when the path ends (no direction, a direction the normals
    /// disagree on, or no throughput left).
    pub(super) fn scatter(
        &self,
        path: &mut PathState,
        v: &Vertex,
        bsdf: &Bsdf,
        ctx: ShadingContext,
        u: [f32; 3],
        leaving_share: f32,
    ) -> bool {
        let [u_x, u_y, u_lobe] = u;
        let Some((bs, kind, lobe_roughness)) = bsdf.sample_kind(v.wo_local, u_lobe, Vec2::new(u_x, u_y)) else { return false };
        let inside_here = path.walk.medium.is_some();
        if path.depth == 0 {
            path.light.first = kind as usize;
        }
        let wi = v.frame.to_world(bs.wi).normalize();
        if !v.sides_agree(wi, bs.wi.z) {
            return false;
        }
        path.beta *= bs.weight;
        path.eta_scale *= bs.eta * bs.eta;
        if FULL && kind == PathKind::Transmission {
            self.cross_boundary(path, v, wi, leaving_share);
        }
        if self.avoid() {
            // Refracting into smooth glass after a rougher vertex: transparent shadows from
            // that vertex carry w'(B_t) of this light, so the path keeps 1 − w'(B_t), for
            // everything inside (total internal reflection included).
            let glass = v.local.map_or_else(|| self.scene.shadow_glass(v.s.material), |(m, _)| caustics::ShadowGlass::of(m));
            if let (Some(p), PathKind::Transmission, Some(glass)) = (&path.prev, kind, glass) {
                path.beta *= 1.0 - caustics::transparent_weight(p.roughness, glass.roughness);
            }
            path.floor = path.floor.after(lobe_roughness);
        }
        if path.is_dark() {
            return false;
        }
        // What the next ray finds is direct after the first surface, and after the walk's own
        // boundary (internal reflection or the exit); the walk ends when the path leaves.
        let light = &mut path.light;
        (light.seg_direct, light.in_walk) = match path.depth {
            0 => (true, light.first == SUBSURFACE),
            _ if light.in_walk && inside_here => (true, path.walk.medium.is_some()),
            _ => (false, false),
        };
        let receiver = self.group_of_instance(v.s.instance);
        path.prev =
            Some(PrevVertex { ctx, bsdf_pdf: bs.pdf, delta: bs.flags.delta, kind, roughness: v.a_roughness, in_medium: false, receiver });
        path.cone = path.cone.after_bounce(v.cone_here, if bs.flags.delta { 0.0 } else { lobe_roughness });
        path.ray = v.leave(wi);
        path.depth += 1;
        true
    }

    /// Crossing a subsurface material's boundary along `wi`: inwards enters its medium
    /// (against the outward geometric normal), outwards leaves it.
    fn cross_boundary(&self, path: &mut PathState, v: &Vertex, wi: Vec3, leaving_share: f32) {
        let Some(m) = v.local.map_or_else(|| self.scene.medium(v.s.material), |(m, _)| m.medium()) else { return };
        if path.walk.medium.is_some() && wi.dot(v.ng) > 0.0 {
            path.exit_share = leaving_share;
        }
        path.walk.medium = (wi.dot(v.ng) < 0.0).then_some(m);
        path.walk.shadows = self.scene.medium_boundary(v.s.material).is_some();
        if path.depth == 0 && path.walk.medium.is_some() {
            path.light.first = SUBSURFACE;
        }
    }
}
