//! Transparent shadows: a shadow ray followed through smooth glass and out of subsurface
//! media, for caustic avoidance ([`crate::caustics`]).

use glam::Vec3;

use super::CommittedScene;
use crate::geometry::{Ray, offset_ray_origin};
use crate::subsurface::Medium;

/// Most glass surfaces one shadow ray passes through.
const MAX_CROSSINGS: usize = 16;

/// What a shadow ray found on its way to the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowPass {
    /// Transmittance through the glass crossed (1 when none).
    pub transmittance: Vec3,
    /// The roughest glass crossed (0 when none).
    pub roughness: f32,
    /// How many glass surfaces the ray crossed.
    pub crossings: u32,
}

impl CommittedScene {
    /// Follows a shadow ray to `tmax` through smooth glass: None when something opaque (or
    /// rough glass) blocks it, else the glass's transmittance without refraction, (1 − F) and
    /// the tint per interface, a thin sheet's series weight once.
    ///
    /// A ray that starts inside the subsurface medium `inside` (Kulla & Conty, "Revisiting
    /// Physically Based Shading at Imageworks", the brute-force subsurface scattering slides:
    /// with a smooth interface, lighting inside the medium comes through transparent shadows)
    /// is attenuated by e^(−σ_t d) up to the medium's boundary, which passes as smooth glass
    /// would (1 − F, no bending) unless it is fully rough. Without the refraction's η² there is
    /// nothing to undo: inside, the light's radiance is η² higher over a solid angle η²
    /// smaller, which leaves its in-scattered radiance as it is.
    ///
    /// Towards a shadow-linked `light`, surfaces of prims that do not cast its shadows are
    /// passed as if absent (the boundary of the medium the ray starts in still counts).
    pub fn shadow_transmittance(&self, ray: &Ray, tmax: f32, mut inside: Option<Medium>, light: Option<usize>) -> Option<ShadowPass> {
        let casts = |instance: u32| match (light, &self.links) {
            (Some(light), Some(links)) => links.casts_shadow(light, instance),
            _ => true,
        };
        let mut pass = ShadowPass { transmittance: Vec3::ONE, roughness: 0.0, crossings: 0 };
        let mut r = *ray;
        let mut left = tmax;
        for _ in 0..MAX_CROSSINGS {
            let Some(hit) = self.intersect(&Ray { tmax: left, ..r }) else { return Some(pass) };
            if hit.t >= left {
                return Some(pass);
            }
            let s = self.surface(&hit);
            // A point a textured opacity cuts out is no surface at all.
            if !self.see_through_at(&s, r.dir) && (inside.is_some() || casts(hit.instance)) {
                let glass = match inside.take() {
                    Some(m) => {
                        pass.transmittance *= m.transmittance((s.p - ray.origin).length());
                        self.medium_boundary(s.material)?
                    }
                    None => self.shadow_glass(s.material)?,
                };
                pass.transmittance *= glass.transmission(s.ns.dot(r.dir).abs().min(1.0));
                pass.roughness = pass.roughness.max(glass.roughness);
                pass.crossings += 1;
                if pass.transmittance == Vec3::ZERO {
                    return None;
                }
            }
            let origin = offset_ray_origin(s.p, if r.dir.dot(s.ng) > 0.0 { s.ng } else { -s.ng }, s.offset_scale);
            left -= (origin - r.origin).length();
            if left <= 0.0 {
                return Some(pass);
            }
            r = Ray { origin, ..r };
        }
        None
    }
}
