//! One glitter flake: a GGX lobe whose microfacet normal is the flake's tilted normal
//! (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 3.3: "each visible flake is instantiated as a GGX microfacet lobe, with a
//! Schlick Fresnel term, using the computed flake color as incident specular color, and flake
//! normal as the microfacet normal").
//!
//! The flake is a small tilted mirror set into the surface. In the flake's own frame its
//! reflection is an ordinary GGX lobe f_flake(o, i); seen from the macro surface, a flake that
//! covers area A of the surface has area A/(n·n_f), and its projected area towards w over A's
//! is g(w) = (w·n_f)/((n·n_f)(w·n)). The macro BRDF of the covered area is therefore
//!
//!   f(wo, wi) = f_flake(o, i) · (o·z)(i·z) / ((n·n_f) μo μi) / max(1, g(wo), g(wi)),
//!
//! symmetric in wo and wi (reciprocal). The max(1, g) is the masking of a tilted flake by the
//! binder around it: towards grazing directions on the side the flake faces, its projected
//! area would exceed the area it covers, which no real flake set into a surface shows. With
//! it the albedo is at most g(wo)/max(1, g(wo)) times the flake-frame GGX albedo, so at most 1.
//! Sampling draws the flake-frame GGX by visible normals; directions that fall below the macro
//! surface are lost (the pdf integrates to less than 1 there).

use glam::{Vec2, Vec3};

use super::fresnel;
use super::microfacet::{Ggx, reflect};
use super::{LobeFlags, LobeSample};
use crate::math::Frame;

/// Smallest flake surface roughness: flakes stay glossy lobes, never deltas, so point and
/// small lights glint from them.
pub const MIN_FLAKE_ROUGHNESS: f32 = 0.1;

/// A tilted GGX flake.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flake {
    /// Unit flake normal in the local shading frame (z > 0).
    pub normal: Vec3,
    /// GGX α of the flake's own surface.
    pub alpha: f32,
    /// Schlick F0: the flake's colour.
    pub f0: Vec3,
}

impl Flake {
    /// Flags: glossy reflection.
    pub const FLAGS: LobeFlags = LobeFlags { reflection: true, transmission: false, delta: false };

    /// A flake tilted to `normal` (normalised; one below the surface tilts up to it), with
    /// surface `roughness` (floored at [`MIN_FLAKE_ROUGHNESS`]) and colour `f0`.
    pub fn new(normal: Vec3, roughness: f32, f0: Vec3) -> Self {
        let r = if roughness.is_finite() { roughness.clamp(MIN_FLAKE_ROUGHNESS, 1.0) } else { 1.0 };
        let n = normal.normalize_or_zero();
        let n = if n.is_finite() && n.z > 1e-3 { n } else { Vec3::new(n.x, n.y, 1e-3).normalize_or(Vec3::Z) };
        Flake { normal: n, alpha: r * r, f0: f0.clamp(Vec3::ZERO, Vec3::ONE) }
    }

    fn ggx(&self) -> Ggx {
        Ggx { ax: self.alpha, ay: self.alpha }
    }

    fn frame(&self) -> Frame {
        Frame::from_normal(self.normal)
    }

    /// g(w): the flake's projected area towards `w` over the area it covers.
    #[inline]
    fn projected(&self, w: Vec3) -> f32 {
        w.dot(self.normal) / (self.normal.z * w.z)
    }

    /// f(wo, wi) without the cosine.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let fr = self.frame();
        let (o, i) = (fr.to_local(wo), fr.to_local(wi));
        if o.z <= 0.0 || i.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (o + i).normalize();
        let g = self.ggx();
        let masking = 1.0f32.max(self.projected(wo)).max(self.projected(wi));
        // f_flake·(o·z)(i·z) with f_flake = F·D·G2/(4 (o·z)(i·z)): the flake-frame cosines cancel.
        let f = fresnel::schlick(self.f0, o.dot(h)) * (g.d(h) * g.g2(o, i) / (4.0 * self.normal.z * wo.z * wi.z * masking));
        if f.is_finite() { f } else { Vec3::ZERO }
    }

    /// Density of [`Flake::sample`] choosing `wi`: the flake-frame VNDF reflection density
    /// (solid angle is the same in both frames).
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let fr = self.frame();
        let (o, i) = (fr.to_local(wo), fr.to_local(wi));
        if o.z <= 0.0 || i.z <= 0.0 {
            return 0.0;
        }
        let h = (o + i).normalize();
        let g = self.ggx();
        let p = g.g1(o) * g.d(h) / (4.0 * o.z);
        if p.is_finite() { p } else { 0.0 }
    }

    /// Samples the flake's GGX lobe by visible normals in its own frame.
    #[inline]
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let fr = self.frame();
        let o = fr.to_local(wo);
        if o.z <= 0.0 {
            return None;
        }
        let i = reflect(o, self.ggx().sample_visible(o, u));
        let wi = fr.to_world(i);
        if i.z <= 0.0 || wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0) {
            return None;
        }
        let weight = self.eval(wo, wi) * wi.z / pdf;
        weight.is_finite().then_some(LobeSample { wi, weight, pdf, flags: Self::FLAGS, eta: 1.0 })
    }

    /// Albedo estimate for lobe selection: Fresnel head-on to the flake, times the share of the
    /// flake's projected area the masking lets through.
    #[inline]
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        let o = wo.dot(self.normal);
        if wo.z <= 0.0 || o <= 0.0 {
            return Vec3::ZERO;
        }
        let g = self.projected(wo);
        fresnel::schlick(self.f0, o) * (g / g.max(1.0)).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lobe, testing};

    fn tilted(theta_deg: f32, phi: f32) -> Vec3 {
        let (s, c) = theta_deg.to_radians().sin_cos();
        Vec3::new(s * phi.cos(), s * phi.sin(), c)
    }

    /// Head-on, moderately and steeply tilted flakes, the sharpest allowed to rough.
    fn flakes() -> Vec<Lobe> {
        flakes_at_least(MIN_FLAKE_ROUGHNESS)
    }

    fn flakes_at_least(roughness: f32) -> Vec<Lobe> {
        [(0.0, 0.1), (20.0, 0.1), (35.0, 0.3), (60.0, 0.1), (80.0, 1.0), (89.9, 0.2)]
            .iter()
            .map(|&(theta, rough): &(f32, f32)| Lobe::Flake(Flake::new(tilted(theta, 0.4), rough.max(roughness), Vec3::ONE)))
            .collect()
    }

    // Chi-square from roughness 0.2 (α = 0.04), as for `GgxReflection`: sharper lobes at
    // grazing views are thinner than the harness's quadrature of the pdf resolves (α = 0.01 at
    // cos θo = 0.01 integrates to 0.93 where 0.97 of samples return, untilted flake and plain
    // GGX alike).
    testing::lobe_battery!(lobes: flakes(), chi_square: flakes_at_least(0.2), seed: 40);

    /// An untilted flake is exactly the GGX reflection with Schlick Fresnel.
    #[test]
    fn an_untilted_flake_is_plain_ggx() {
        let f0 = Vec3::new(0.9, 0.6, 0.2);
        let flake = Flake::new(Vec3::Z, 0.3, f0);
        let ggx = crate::bsdf::GgxReflection::new(0.3, 0.0, crate::bsdf::SpecularFresnel::Schlick { f0 }, false);
        let mut rng = crate::sampling::Pcg32::new(2, 2);
        for _ in 0..500 {
            let wo = crate::sampling::cosine_hemisphere(rng.next_2d());
            let wi = crate::sampling::cosine_hemisphere(rng.next_2d());
            let (a, b) = (flake.eval(wo, wi), ggx.eval(wo, wi));
            assert!((a - b).abs().max_element() <= 1e-4 * b.max_element().max(1e-3), "{a:?} vs {b:?}");
            assert!((flake.pdf(wo, wi) - ggx.pdf(wo, wi)).abs() <= 1e-4 * ggx.pdf(wo, wi).max(1e-3));
        }
    }

    /// A tilted smooth flake reflects the mirror direction about its own normal, not the
    /// surface's: light from straight above leaves at twice the tilt.
    #[test]
    fn a_tilted_flake_glints_at_twice_its_tilt() {
        let flake = Flake::new(tilted(15.0, 0.0), 0.1, Vec3::ONE);
        let wi = Vec3::Z;
        let at = |deg: f32| flake.eval(tilted(deg, 0.0), wi).x;
        assert!(at(30.0) > 50.0 * at(10.0), "peak {} vs off-peak {}", at(30.0), at(10.0));
        assert!(at(30.0) > 50.0 * at(50.0));
    }

    /// Extreme inputs stay finite: a flake lying in the surface plane, NaN normals and
    /// roughness, directions at cos θ = 1e-6.
    #[test]
    fn extreme_inputs_stay_finite() {
        let g = Vec3::new((1.0f32 - 1e-12).sqrt(), 0.0, 1e-6);
        for flake in [
            Flake::new(Vec3::X, 0.0, Vec3::ONE),
            Flake::new(Vec3::NAN, f32::NAN, Vec3::ONE),
            Flake::new(tilted(89.99, 1.0), 1e-9, Vec3::ONE),
        ] {
            for (wo, wi) in [(g, Vec3::Z), (Vec3::Z, g), (g, -g.with_z(-1e-6) * -1.0), (g, g)] {
                assert!(crate::math::is_finite(flake.eval(wo, wi)) && flake.pdf(wo, wi).is_finite());
                if let Some(s) = flake.sample(wo, 0.5, Vec2::new(0.3, 0.7)) {
                    assert!(crate::math::is_finite(s.weight) && s.pdf.is_finite());
                }
            }
        }
    }
}
