//! Caustic path avoidance (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Caustic path avoidance"): the `caustics = avoid` render
//! setting. Unidirectional path tracing finds light focused by smooth glass and mirrors only
//! by chance, as fireflies. Imageworks trade that noise for a bias in three steps, and light
//! subsurface media the same way:
//!
//! 1. **Roughness clamping**: roughness never decreases along a path, so after a rough bounce
//!    every later lobe is at least that rough ([`RoughnessFloor`], BSDFs pre-built per level).
//! 2. **Transparent shadows**: shadow rays pass through smooth glass as if light did not bend,
//!    attenuated by the glass's colour and Fresnel transmission ([`shadow_transmittance`]).
//! 3. **Weighting** so the two estimates of light through glass do not add up: for a surface
//!    A and glass B, w(B_t) = max(rough(A) − rough(B), 0), w(B_p) = 1 − w(B_t), both
//!    recalculated by the power heuristic ([`transparent_weight`]). Shadows through glass carry
//!    w'(B_t); a path refracting into glass carries w'(B_p) from then on (total internal
//!    reflection inside included, as the slides do).
//! 4. **Subsurface** ("Brute-force subsurface scattering"): every scattering event of a random
//!    walk connects to the lights through a transparent shadow across its medium's boundary
//!    ([`shadow_transmittance`] from inside the medium), weighted by [`roughness_weight`] of a phase function
//!    (roughness 1) against the boundary's; the direct light a walk finds by leaving keeps
//!    w'(B_p), the indirect light beyond the exit all of it.
//!
//! The bias: light through glass arrives unfocused and unbent, and the indirect light that a
//! rough surface sees through glass is scaled by w'(B_p). `caustics = full` renders without
//! any of it; `tessera bench accuracy` measures the difference.

use glam::Vec3;

/// How the integrator treats caustic paths.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CausticMode {
    /// Unbiased path tracing.
    #[default]
    Full,
    /// Roughness clamping, transparent shadows and their weighting.
    Avoid,
}

/// Glass at least this rough blocks shadow rays: light through it is affordable to find by
/// path tracing ("unless the glass is rough, in which case we could afford the real thing").
pub const SMOOTH_GLASS: f32 = 0.3;

/// Roughness floors the BSDFs are pre-built at: level k clamps every microfacet lobe to
/// roughness ≥ k/8. A path's floor rounds down, so clamping never exceeds the path's own
/// roughness.
pub const FLOOR_LEVELS: usize = 9;

/// The roughness floor of a path.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RoughnessFloor(pub f32);

impl RoughnessFloor {
    /// The floor after scattering by a lobe of `roughness`.
    pub fn after(self, roughness: f32) -> Self {
        RoughnessFloor(self.0.max(roughness.clamp(0.0, 1.0)))
    }

    /// The pre-built level that does not exceed the floor.
    pub fn level(self) -> usize {
        ((self.0 * (FLOOR_LEVELS - 1) as f32).floor() as usize).min(FLOOR_LEVELS - 1)
    }

    /// The roughness of `level`.
    pub fn of_level(level: usize) -> f32 {
        level as f32 / (FLOOR_LEVELS - 1) as f32
    }
}

/// w'(B_t): the share of light through glass B (roughness `r_b`) that transparent shadows
/// from a surface A of roughness `r_a` carry; 1 − w'(B_t) is the path's share.
pub fn transparent_weight(r_a: f32, r_b: f32) -> f32 {
    if r_b > SMOOTH_GLASS {
        return 0.0;
    }
    roughness_weight(r_a, r_b)
}

/// The slides' roughness heuristic itself, for any roughness of B: [`transparent_weight`]
/// without the cut-off for rough glass. A subsurface boundary uses it whole ("for rough
/// interfaces ... this is what our transparency/indirect weighting produces"): a random walk
/// arrives at its exit from a random direction, so connecting to a small light through even a
/// moderately glossy boundary is noisy (docs/accuracy-vs-time.md measures it at roughness 0.4).
pub fn roughness_weight(r_a: f32, r_b: f32) -> f32 {
    // w(B_t) + w(B_p) = 1, so the power heuristic's denominator is at least 1/2.
    let wt = (r_a - r_b).clamp(0.0, 1.0);
    let wp = 1.0 - wt;
    wt * wt / (wt * wt + wp * wp)
}

/// The glass of a material as transparent shadows see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowGlass {
    /// Share of the glass family (the rest of the material is opaque).
    pub weight: f32,
    /// Tint per crossing (a thick interface) or one crossing's colour (a sheet).
    pub color: Vec3,
    /// Refractive index.
    pub eta: f32,
    /// A thin sheet.
    pub thin: bool,
    /// Its roughness.
    pub roughness: f32,
    /// A thin film on a thick interface, whose reflectance replaces the Fresnel term.
    pub film: Option<crate::bsdf::GlassFilm>,
}

impl ShadowGlass {
    /// The glass of `m`, when it is smooth enough for transparent shadows.
    pub fn of(m: &crate::material::Material) -> Option<Self> {
        let g = &m.surface.glass;
        let w = if g.weight.is_finite() { g.weight.clamp(0.0, 1.0) } else { 0.0 };
        let r = if g.params.roughness.is_finite() { g.params.roughness.clamp(0.0, 1.0) } else { 1.0 };
        (w > 0.0 && r <= SMOOTH_GLASS && !m.cut_out).then(|| ShadowGlass {
            weight: w,
            color: g.params.color.clamp(Vec3::ZERO, Vec3::ONE),
            eta: if g.params.ior.is_finite() && g.params.ior > 0.0 { g.params.ior } else { 1.5 },
            thin: g.params.thin,
            roughness: r,
            film: (g.params.film_thickness > 0.0)
                .then_some(crate::bsdf::GlassFilm { ior: g.params.film_ior, thickness: g.params.film_thickness }),
        })
    }

    /// The boundary of `m`'s subsurface medium as transparent shadows from inside see it: a
    /// clear interface of the plastic's index and roughness, weighted by [`roughness_weight`]
    /// (None at roughness 1, where that weight is 0).
    pub fn of_medium_boundary(m: &crate::material::Material) -> Option<Self> {
        m.medium()?;
        let p = &m.surface.plastic;
        let r = p.params.specular.map_or(0.0, |s| s.roughness);
        let r = if r.is_finite() { r.clamp(0.0, 1.0) } else { 1.0 };
        let w = if p.weight.is_finite() { p.weight.clamp(0.0, 1.0) } else { 0.0 };
        (r < 1.0 && w > 0.0 && !m.cut_out).then(|| ShadowGlass {
            weight: w,
            color: Vec3::ONE,
            eta: p.params.coupling_eta.max(1.0),
            thin: false,
            roughness: r,
            film: None,
        })
    }

    /// Transmission of one crossing at incidence cosine `cos`.
    pub fn transmission(&self, cos: f32) -> Vec3 {
        let eta = if self.eta < 1.0 { 1.0 / self.eta } else { self.eta };
        if self.thin {
            return self.weight * crate::bsdf::sheet_series(eta, self.color, cos)[1];
        }
        // Light is pretended not to bend, so `cos` is the outside cosine at both the entry and
        // the exit: the refracted pair has the same (1 − F) either way (a film's too, by
        // Stokes' relations).
        if let Some(f) = self.film {
            return self.weight * (Vec3::ONE - f.reflectance(self.eta, cos.abs())) * self.color;
        }
        self.weight * (1.0 - crate::bsdf::fresnel::dielectric(cos, eta)) * self.color
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_follow_the_slides() {
        // Rough A behind smooth B: transparent shadows take everything.
        assert_eq!(transparent_weight(1.0, 0.0), 1.0);
        // Smooth A: the path takes everything.
        assert_eq!(transparent_weight(0.0, 0.0), 0.0);
        assert_eq!(transparent_weight(0.2, 0.25), 0.0);
        // In between, the power heuristic of (0.6, 0.4).
        assert!((transparent_weight(0.7, 0.1) - 0.36 / 0.52).abs() < 1e-6);
        // Rough glass is never crossed by shadows.
        assert_eq!(transparent_weight(1.0, 0.5), 0.0);
        // A subsurface boundary takes the heuristic whole: a walk's scattering event (rough 1)
        // behind a boundary of roughness 0.4 gives shadows (0.6², 0.4²) normalised.
        assert!((roughness_weight(1.0, 0.4) - 0.36 / 0.52).abs() < 1e-6);
        assert_eq!(roughness_weight(1.0, 1.0), 0.0);
    }

    #[test]
    fn floors_round_down_and_only_grow() {
        let f = RoughnessFloor::default().after(0.3).after(0.1);
        assert_eq!(f.0, 0.3);
        assert_eq!(f.level(), 2);
        assert!(RoughnessFloor::of_level(f.level()) <= f.0);
        assert_eq!(RoughnessFloor(1.0).level(), FLOOR_LEVELS - 1);
    }

    #[test]
    fn clear_glass_transmits_what_fresnel_leaves() {
        let g = ShadowGlass { weight: 1.0, color: Vec3::ONE, eta: 1.5, thin: false, roughness: 0.0, film: None };
        assert!((g.transmission(1.0).x - 0.96).abs() < 1e-4);
        let sheet = ShadowGlass { thin: true, ..g };
        assert!((sheet.transmission(1.0).x - 0.96 / 1.04).abs() < 1e-4);
        // At grazing incidence almost nothing passes.
        assert!(g.transmission(1e-3).x < 0.01);
        // Under a film, what the film does not reflect, channel by channel.
        let filmed = ShadowGlass { film: Some(crate::bsdf::GlassFilm { ior: 1.33, thickness: 400.0 }), ..g };
        let film = crate::bsdf::thin_film::airy(0.8, 1.33, 400.0, 1.5);
        assert!((filmed.transmission(0.8) - (Vec3::ONE - film)).abs().max_element() < 1e-6, "{}", filmed.transmission(0.8));
    }
}
