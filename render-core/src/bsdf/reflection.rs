//! Microfacet reflection: anisotropic GGX with a conductor's or a dielectric's Fresnel, plus
//! Kulla-Conty's multiple-scattering compensation lobe. Metals use it alone; opaque dielectrics
//! put it over a diffuse base coupled through [`super::energy::dielectric_specular`].
//!
//! f = D·G2·F / (4 μo μi) + f_ms, with (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Microfacet energy compensation")
//! f_ms = (1 − E(μo))(1 − E(μi)) / (π(1 − E_avg)) · F_avg² E_avg / (1 − F_avg(1 − E_avg)),
//! the Fresnel factor in the appendix's corrected form. `sample` picks the specular lobe
//! (VNDF) or the compensation lobe (cosine) in proportion to their albedos at `wo`.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use super::energy;
use super::fresnel;
use super::microfacet::{Ggx, reflect};
use super::view_cache::ViewCache;
use super::{LobeFlags, LobeSample};
use crate::math::luminance;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// How a conductor's reflectance varies with angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpecularFresnel {
    /// Gulbrandsen's reflectivity `r` and edge tint `g` (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", conductor Fresnel slide).
    Gulbrandsen {
        /// Normal-incidence colour.
        r: Vec3,
        /// Edge tint.
        g: Vec3,
    },
    /// The artistic r + (g − r)(1 − μ)^(1/p).
    Artistic {
        /// Normal-incidence colour.
        r: Vec3,
        /// Grazing colour.
        g: Vec3,
        /// Falloff.
        p: f32,
    },
    /// Schlick with a normal-incidence colour (UsdPreviewSurface, Disney metallic).
    Schlick {
        /// F0.
        f0: Vec3,
    },
    /// A dielectric's exact Fresnel with relative IOR `eta` (the specular of plastics).
    Dielectric {
        /// IOR below over above.
        eta: f32,
    },
    /// A dielectric whose normal-incidence reflectance is tinted: F = F0·t + (1 − F0·t)·s(μ),
    /// s = (F_d(μ) − F0)/(1 − F0) the exact dielectric curve rescaled to run from 0 to 1, so
    /// grazing stays white (Cycles' Principled Specular Tint: its generalised Schlick with a
    /// negative exponent; OpenPBR's and Standard Surface's `specular_color`). Build with
    /// [`SpecularFresnel::tinted_dielectric`].
    TintedDielectric {
        /// IOR below over above.
        eta: f32,
        /// Tint of F0 in [0, 1].
        tint: Vec3,
        /// The untinted F0, kept from construction: every evaluation needs it.
        f0: f32,
    },
    /// A conductor's F82-tint Fresnel (OpenPBR's metal, Cycles' Principled metal): Schlick's
    /// curve from F0 less b·μ(1 − μ)⁶, b chosen so that F at μ = 1/7 (about 82°) is the tint
    /// times Schlick's there; a white tint is Schlick. Build with [`SpecularFresnel::f82_tint`].
    F82Tint {
        /// F0.
        f0: Vec3,
        /// The dip's coefficient b.
        b: Vec3,
    },
    /// F = 1: an ideal reflector, for furnace tests.
    White,
    /// A thin film's interference over a dielectric substrate ([`super::thin_film::airy`]);
    /// build with [`SpecularFresnel::thin_film`], which integrates its average once.
    ThinFilm {
        /// Film refractive index.
        film: f32,
        /// Thickness in nanometres.
        thickness: f32,
        /// Substrate refractive index.
        substrate: f32,
        /// Cosine-weighted average, per channel.
        avg: Vec3,
    },
    /// A thin film's interference over a conductor ([`super::thin_film::airy_conductor`]);
    /// build with [`SpecularFresnel::thin_film_conductor`].
    ThinFilmConductor {
        /// Film refractive index.
        film: f32,
        /// Thickness in nanometres.
        thickness: f32,
        /// The metal's complex index.
        metal: super::thin_film::Conductor,
        /// Cosine-weighted average, per channel.
        avg: Vec3,
    },
}

impl SpecularFresnel {
    /// F(μ) where μ is the cosine between the direction and the microfacet normal.
    #[inline]
    pub fn eval(&self, mu: f32) -> Vec3 {
        match *self {
            SpecularFresnel::Gulbrandsen { r, g } => fresnel::gulbrandsen(r, g, mu),
            SpecularFresnel::Artistic { r, g, p } => fresnel::artistic(r, g, p, mu),
            SpecularFresnel::Schlick { f0 } => fresnel::schlick(f0, mu),
            SpecularFresnel::Dielectric { eta } => Vec3::splat(fresnel::dielectric(mu, eta)),
            SpecularFresnel::TintedDielectric { eta, tint, f0 } => tinted(f0, tint, fresnel::dielectric(mu, eta)),
            SpecularFresnel::F82Tint { f0, b } => {
                let m = (1.0 - mu).clamp(0.0, 1.0);
                (fresnel::schlick(f0, mu) - b * (mu * m.powi(6))).clamp(Vec3::ZERO, Vec3::ONE)
            }
            SpecularFresnel::White => Vec3::ONE,
            SpecularFresnel::ThinFilm { film, thickness, substrate, .. } => super::thin_film::airy(mu, film, thickness, substrate),
            SpecularFresnel::ThinFilmConductor { film, thickness, ref metal, .. } => {
                super::thin_film::airy_conductor(mu, film, thickness, metal)
            }
        }
    }

    /// A dielectric of relative index `eta` whose F0 is tinted `tint` (clamped to [0, 1]); a
    /// white tint is the plain dielectric.
    pub fn tinted_dielectric(eta: f32, tint: Vec3) -> Self {
        if tint == Vec3::ONE {
            return SpecularFresnel::Dielectric { eta };
        }
        SpecularFresnel::TintedDielectric { eta, tint: tint.clamp(Vec3::ZERO, Vec3::ONE), f0: fresnel::dielectric(1.0, eta) }
    }

    /// The F82-tint Fresnel of normal-incidence colour `f0` and tint `tint` (both in [0, 1]):
    /// b = F_Schlick(1/7)·(1 − tint) / ((1/7)(6/7)⁶).
    pub fn f82_tint(f0: Vec3, tint: Vec3) -> Self {
        let f0 = f0.clamp(Vec3::ZERO, Vec3::ONE);
        let (mu, m) = (1.0 / 7.0f32, 6.0 / 7.0f32);
        let b = fresnel::schlick(f0, mu) * (Vec3::ONE - tint.clamp(Vec3::ZERO, Vec3::ONE)) / (mu * m.powi(6));
        SpecularFresnel::F82Tint { f0, b }
    }

    /// A thin film's Fresnel with its average ([`super::thin_film::average`]).
    pub fn thin_film(film: f32, thickness: f32, substrate: f32) -> Self {
        SpecularFresnel::ThinFilm { film, thickness, substrate, avg: super::thin_film::average(film, thickness, substrate) }
    }

    /// A thin film's Fresnel over the conductor `metal`, with its average.
    pub fn thin_film_conductor(film: f32, thickness: f32, metal: super::thin_film::Conductor) -> Self {
        let avg = super::thin_film::average_conductor(film, thickness, &metal);
        SpecularFresnel::ThinFilmConductor { film, thickness, metal, avg }
    }

    /// The same Fresnel with a film of index `film` and `thickness` nm over it, when it is a
    /// conductor's (Gulbrandsen's, or the F82 tint's with the edge colour its value at about
    /// 82°, as Cycles reads it); None for any other. The film's average comes from `grid`
    /// when it is this film's (a metal whose colours vary: integrating it costs 7 µs).
    pub fn under_film(&self, film: f32, thickness: f32, grid: Option<&super::thin_film::ConductorAverages>) -> Option<Self> {
        let (r, g) = match *self {
            SpecularFresnel::Gulbrandsen { r, g } => (r, g),
            SpecularFresnel::F82Tint { f0, .. } => (f0, self.eval(1.0 / 7.0)),
            _ => return None,
        };
        let metal = super::thin_film::Conductor::gulbrandsen(r, g);
        Some(match grid.filter(|t| (t.film, t.thickness) == (film, thickness)) {
            Some(t) => SpecularFresnel::ThinFilmConductor { film, thickness, metal, avg: t.at(r, g) },
            None => Self::thin_film_conductor(film, thickness, metal),
        })
    }

    /// The cosine-weighted average F_avg: the slides' fits or closed forms.
    #[inline]
    pub fn average(&self) -> Vec3 {
        match *self {
            SpecularFresnel::Gulbrandsen { r, g } => fresnel::gulbrandsen_avg_fit(r, g),
            SpecularFresnel::Artistic { r, g, p } => fresnel::artistic_avg(r, g, p),
            // Schlick integrates exactly: F0 + (1 − F0)·2∫(1−μ)⁵μ dμ = F0 + (1 − F0)/21.
            SpecularFresnel::Schlick { f0 } => f0 + (Vec3::ONE - f0) / 21.0,
            SpecularFresnel::Dielectric { eta } => Vec3::splat(fresnel::dielectric_avg_fit(eta).clamp(0.0, 1.0)),
            // F is affine in F_d, so its average is the same map of F_d's.
            SpecularFresnel::TintedDielectric { eta, tint, f0 } => tinted(f0, tint, fresnel::dielectric_avg_fit(eta).clamp(0.0, 1.0)),
            // Schlick's average less b·2∫μ²(1 − μ)⁶dμ = b·2·B(3, 7) = b/126.
            SpecularFresnel::F82Tint { f0, b } => (f0 + (Vec3::ONE - f0) / 21.0 - b / 126.0).clamp(Vec3::ZERO, Vec3::ONE),
            SpecularFresnel::White => Vec3::ONE,
            SpecularFresnel::ThinFilm { avg, .. } | SpecularFresnel::ThinFilmConductor { avg, .. } => avg,
        }
    }
}

/// The tinted dielectric's F for the untinted dielectric's value `f_d` (at a cosine, or on
/// average), `f0` being its value head-on: F0·t + (1 − F0·t)·(f_d − F0)/(1 − F0).
#[inline]
fn tinted(f0: f32, tint: Vec3, f_d: f32) -> Vec3 {
    let s = if f0 < 1.0 { ((f_d - f0) / (1.0 - f0)).clamp(0.0, 1.0) } else { 1.0 };
    let f0t = f0 * tint;
    f0t + (Vec3::ONE - f0t) * s
}

/// Rough (or, below α = 1e-3, perfectly smooth) microfacet reflection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxReflection {
    /// Distribution.
    pub ggx: Ggx,
    /// Roughness driving the isotropic compensation table.
    pub roughness: f32,
    /// Where an anisotropic lobe reads its compensation: E over the view azimuth too
    /// ([`energy::GgxAnisoEnergy`] says why one roughness is not enough).
    pub anisotropy: Option<energy::AnisoCoords>,
    /// Reflectance.
    pub fresnel: SpecularFresnel,
    /// Add the multiple-scattering compensation lobe.
    pub compensate: bool,
    /// The compensation's terms at the shading point's view ([`GgxReflection::prepare`]).
    at_view: ViewCache<Option<MsTerms>>,
}

/// What the compensation lobe needs at one view: E_avg and F_ms of the lobe, and E(μo).
#[derive(Clone, Copy, Debug)]
struct MsTerms {
    e_avg: f32,
    fms: Vec3,
    e_wo: f32,
}

impl GgxReflection {
    /// A lobe of `roughness` and `anisotropic` (Disney mapping).
    pub fn new(roughness: f32, anisotropic: f32, fresnel: SpecularFresnel, compensate: bool) -> Self {
        let roughness = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
        let ggx = Ggx::from_roughness(roughness, anisotropic);
        let anisotropy = (ggx.ax != ggx.ay).then(|| energy::AnisoCoords::of(ggx));
        GgxReflection { ggx, roughness: ggx.ax.sqrt().min(1.0), anisotropy, fresnel, compensate, at_view: ViewCache::default() }
    }

    /// Looks the compensation's terms up once for the evaluations and samples at this view.
    #[inline]
    pub fn prepare(&mut self, wo: Vec3) {
        if self.compensate && wo.z > 0.0 {
            self.at_view.store(wo, self.find_ms_terms(wo));
        }
    }

    /// Single-scattering albedo E(w) with F = 1, from the table that fits the lobe.
    #[inline]
    fn e(&self, w: Vec3) -> f32 {
        match &self.anisotropy {
            Some(at) => energy::ggx_anisotropic().e(at, w),
            None => energy::ggx().e(w.z, self.roughness),
        }
    }

    fn smooth(&self) -> bool {
        self.ggx.is_smooth()
    }

    /// Flags: reflection, delta when smooth.
    pub fn flags(&self) -> LobeFlags {
        LobeFlags { reflection: true, transmission: false, delta: self.smooth() }
    }

    /// The compensation's terms at `wo` when compensating, from [`GgxReflection::prepare`]
    /// when `wo` is the view it was made for; None otherwise.
    #[inline(always)]
    fn ms_terms(&self, wo: Vec3) -> Option<MsTerms> {
        if !self.compensate {
            return None;
        }
        self.at_view.get(wo, || self.find_ms_terms(wo))
    }

    /// [`GgxReflection::ms_terms`] from the tables.
    fn find_ms_terms(&self, wo: Vec3) -> Option<MsTerms> {
        if !self.compensate || self.smooth() {
            return None;
        }
        let e_avg = match &self.anisotropy {
            Some(at) => energy::ggx_anisotropic().e_avg(at),
            None => energy::ggx().e_avg(self.roughness),
        };
        if e_avg >= 1.0 {
            return None;
        }
        Some(MsTerms { e_avg, fms: energy::multiple_scattering_fresnel(self.fresnel.average(), e_avg), e_wo: self.e(wo) })
    }

    #[inline]
    fn f_ms(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self.ms_terms(wo) {
            Some(MsTerms { e_avg, fms, e_wo }) => fms * ((1.0 - e_wo) * (1.0 - self.e(wi)) * FRAC_1_PI / (1.0 - e_avg)),
            None => Vec3::ZERO,
        }
    }

    /// Probability of sampling the compensation lobe at `wo`.
    #[inline]
    fn p_ms(&self, wo: Vec3) -> f32 {
        match self.ms_terms(wo) {
            Some(MsTerms { fms, e_wo: e, .. }) => {
                let w_ms = (1.0 - e) * luminance(fms);
                let w_spec = e * luminance(self.fresnel.average()).max(1e-4);
                if w_ms + w_spec > 0.0 { w_ms / (w_ms + w_spec) } else { 0.0 }
            }
            None => 0.0,
        }
    }

    /// f(wo, wi) without the cosine.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 || self.smooth() {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize();
        let g = self.ggx.regularized();
        let spec = self.fresnel.eval(wo.dot(h)) * (g.d(h) * g.g2(wo, wi) / (4.0 * wo.z * wi.z));
        let f = spec + self.f_ms(wo, wi);
        if f.is_finite() { f } else { Vec3::ZERO }
    }

    /// Density of [`GgxReflection::sample`] choosing `wi`.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 || self.smooth() {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        let g = self.ggx.regularized();
        // D_wo(h)/(4 wo·h) = G1(wo)·D(h)/(4 μo): written without wo·h, which cancellation
        // can make slightly negative at grazing angles (pbrt uses |wo·h| for the same reason).
        let spec = g.g1(wo) * g.d(h) / (4.0 * wo.z);
        let p = self.p_ms(wo);
        let pdf = (1.0 - p) * spec + p * cosine_hemisphere_pdf(wi.z);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    /// [`GgxReflection::eval`] and [`GgxReflection::pdf`] at once: the half vector, D(h) and
    /// Λ(wo), which both need, computed once (next-event estimation asks for both at every
    /// light sample). The same operations as the two calls, so the same bits.
    #[inline]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 || self.smooth() {
            return (Vec3::ZERO, 0.0);
        }
        let h = (wo + wi).normalize();
        let g = self.ggx.regularized();
        let (d, lambda_o) = (g.d(h), g.lambda(wo));
        let g2 = 1.0 / (1.0 + lambda_o + g.lambda(wi));
        let spec = self.fresnel.eval(wo.dot(h)) * (d * g2 / (4.0 * wo.z * wi.z));
        let f = spec + self.f_ms(wo, wi);
        let p = self.p_ms(wo);
        let g1 = 1.0 / (1.0 + lambda_o);
        let pdf = (1.0 - p) * (g1 * d / (4.0 * wo.z)) + p * cosine_hemisphere_pdf(wi.z);
        (if f.is_finite() { f } else { Vec3::ZERO }, if pdf.is_finite() { pdf } else { 0.0 })
    }

    /// Samples the specular lobe by visible normals or, with probability from `uc`, the
    /// compensation lobe by cosine.
    #[inline]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        if self.smooth() {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some(LobeSample { wi, weight: self.fresnel.eval(wo.z), pdf: 1.0, flags: self.flags(), eta: 1.0 });
        }
        let wi = if uc < self.p_ms(wo) { cosine_hemisphere(u) } else { reflect(wo, self.ggx.regularized().sample_visible(wo, u)) };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0) {
            return None;
        }
        let weight = self.eval(wo, wi) * wi.z / pdf;
        weight.is_finite().then_some(LobeSample { wi, weight, pdf, flags: self.flags(), eta: 1.0 })
    }

    /// Albedo estimate at `wo`: F(μo)·E(μo) plus the compensation lobe's 1 − E(μo) share.
    #[inline]
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        if wo.z <= 0.0 {
            return Vec3::ZERO;
        }
        let f = self.fresnel.eval(wo.z);
        if self.smooth() {
            return f;
        }
        match self.ms_terms(wo) {
            Some(MsTerms { fms, e_wo: e, .. }) => f * e + fms * (1.0 - e),
            None => f * self.e(wo),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lobe, testing};

    const ROUGHNESS: [f32; 6] = [0.0, 1e-4, 0.1, 0.5, 0.8, 1.0];

    fn white(r: f32, aniso: f32, compensate: bool) -> Lobe {
        Lobe::GgxReflection(GgxReflection::new(r, aniso, SpecularFresnel::White, compensate))
    }

    fn gold(r: f32, aniso: f32) -> Lobe {
        let fresnel = SpecularFresnel::Gulbrandsen { r: Vec3::new(0.944, 0.776, 0.373), g: Vec3::new(0.998, 0.981, 0.751) };
        Lobe::GgxReflection(GgxReflection::new(r, aniso, fresnel, true))
    }

    #[test]
    fn white_furnace_energy_conservation() {
        for r in ROUGHNESS {
            for compensate in [false, true] {
                testing::assert_albedo_at_most_one(&white(r, 0.0, compensate));
            }
            for aniso in [-1.0, 1.0] {
                testing::assert_albedo_at_most_one(&white(r, aniso, false));
            }
            testing::assert_albedo_at_most_one(&gold(r, 0.0));
        }
    }

    /// Anisotropic lobes with compensation read E over the view azimuth
    /// ([`energy::GgxAnisoEnergy`]); driven by one roughness they gained 2.5% at cos θ = 1e-4.
    #[test]
    fn white_furnace_anisotropic_compensated() {
        for r in ROUGHNESS {
            for aniso in [-1.0, 1.0] {
                testing::assert_albedo_at_most_one(&white(r, aniso, true));
                testing::assert_albedo_at_most_one(&gold(r, aniso));
            }
        }
    }

    #[test]
    fn compensation_preserves_energy_at_every_roughness_and_angle() {
        // A white conductor with compensation keeps its albedo within 1% of 1.
        for r in ROUGHNESS {
            for wo in testing::probe_directions() {
                let a = testing::albedo_estimate(&white(r, 0.0, true), wo, 100_000).x;
                assert!((a - 1.0).abs() < 0.01, "roughness {r}, cos {}: albedo {a}", wo.z);
            }
        }
        // Without it, roughness 1 loses what E_avg says.
        let mut avg = 0.0;
        let n = 64;
        for k in 0..n {
            let mu = (k as f32 + 0.5) / n as f32;
            let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            avg += 2.0 * mu * testing::albedo_estimate(&white(1.0, 0.0, false), wo, 20_000).x / n as f32;
        }
        assert!((1.0 - avg - energy::fit_one_minus_e_avg(1.0)).abs() < 0.015, "1 - E_avg(1) = {}", 1.0 - avg);
    }

    #[test]
    fn anisotropic_compensation_preserves_energy_at_every_azimuth() {
        // White anisotropic conductors keep their albedo within 1.5% of 1 wherever they are
        // seen from, including along the smooth axis at grazing angles.
        for r in [0.1, 0.5, 1.0] {
            for aniso in [-1.0, 0.5, 1.0] {
                for c in [1.0f32, 0.5, 0.1, 1e-2, 1e-4] {
                    for phi in [0.0f32, 0.4, 0.8, 1.2, 1.5707964] {
                        let s = (1.0 - c * c).sqrt();
                        let wo = Vec3::new(s * phi.cos(), s * phi.sin(), c);
                        let a = testing::albedo_estimate(&white(r, aniso, true), wo, 40_000).x;
                        assert!((a - 1.0).abs() < 0.015, "roughness {r}, anisotropic {aniso}, wo {wo:?}: albedo {a}");
                    }
                }
            }
        }
    }

    fn tinted_dielectric(r: f32, tint: Vec3) -> Lobe {
        Lobe::GgxReflection(GgxReflection::new(r, 0.0, SpecularFresnel::tinted_dielectric(1.5, tint), true))
    }

    /// White and gold conductors, isotropic and anisotropic, rough to nearly smooth, and a
    /// tinted dielectric specular.
    fn battery_lobes() -> Vec<Lobe> {
        let mut v: Vec<Lobe> =
            [0.1, 0.5, 1.0].into_iter().flat_map(|r| [white(r, 0.0, true), gold(r, 0.7), white(r, -1.0, true)]).collect();
        v.extend([white(0.3, 0.0, true), gold(0.05, 0.5), gold(1.0, 0.0)]);
        v.extend([tinted_dielectric(0.3, Vec3::new(1.0, 0.4, 0.1)), tinted_dielectric(0.8, Vec3::ZERO)]);
        v.push(f82(0.5, Vec3::new(0.5, 0.1, 0.0)));
        v
    }

    fn f82(r: f32, tint: Vec3) -> Lobe {
        Lobe::GgxReflection(GgxReflection::new(r, 0.0, SpecularFresnel::f82_tint(Vec3::new(0.95, 0.64, 0.54), tint), true))
    }

    /// F82-tint: white tint is Schlick; at μ = 1/7 it is the tint times Schlick; head-on and
    /// grazing it is F0 and 1 whatever the tint; its average is its curve's (to 1e-4).
    #[test]
    fn f82_tint_scales_schlick_at_82_degrees() {
        let f0 = Vec3::new(0.95, 0.64, 0.54);
        let tint = Vec3::new(1.0, 0.6, 0.2);
        let white = SpecularFresnel::f82_tint(f0, Vec3::ONE);
        let f = SpecularFresnel::f82_tint(f0, tint);
        for k in 0..=20 {
            let mu = k as f32 / 20.0;
            assert_eq!(white.eval(mu), fresnel::schlick(f0, mu), "μ {mu}");
        }
        assert!((f.eval(1.0 / 7.0) - tint * fresnel::schlick(f0, 1.0 / 7.0)).abs().max_element() < 1e-5);
        assert!((f.eval(1.0) - f0).abs().max_element() < 1e-6 && (f.eval(0.0) - Vec3::ONE).abs().max_element() < 1e-6);
        let n = 4000;
        let avg: Vec3 = (0..n).map(|k| (k as f32 + 0.5) / n as f32).map(|mu| f.eval(mu) * (2.0 * mu / n as f32)).sum();
        assert!((avg - f.average()).abs().max_element() < 1e-4, "{avg:?} against {:?}", f.average());
    }

    /// The tinted dielectric: untinted it is the dielectric's exact Fresnel (to rounding); head-on
    /// it is F0·t; at grazing it is white whatever the tint; its average is the average of its
    /// curve (midpoints, within the F_avg fit's 0.65%).
    #[test]
    fn a_tinted_dielectric_tints_f0_and_keeps_grazing_white() {
        let tint = Vec3::new(1.0, 0.5, 0.0);
        for eta in [1.2f32, 1.5, 2.4, 0.7] {
            let plain = SpecularFresnel::Dielectric { eta };
            // The formula itself at a white tint (the constructor would return the plain one).
            let white = SpecularFresnel::TintedDielectric { eta, tint: Vec3::ONE, f0: fresnel::dielectric(1.0, eta) };
            let tinted = SpecularFresnel::tinted_dielectric(eta, tint);
            for k in 0..=20 {
                let mu = k as f32 / 20.0;
                assert!((white.eval(mu) - plain.eval(mu)).abs().max_element() < 1e-6, "η {eta} μ {mu}");
                assert!(tinted.eval(mu).cmple(plain.eval(mu) + 1e-6).all(), "a tint only takes away");
            }
            let f0 = fresnel::dielectric(1.0, eta);
            assert!((tinted.eval(1.0) - f0 * tint).abs().max_element() < 1e-6);
            assert!((tinted.eval(0.0) - Vec3::ONE).abs().max_element() < 1e-6);
            let n = 2000;
            let mean = |f: SpecularFresnel| -> Vec3 {
                (0..n).map(|k| (k as f32 + 0.5) / n as f32).map(|mu| f.eval(mu) * (2.0 * mu / n as f32)).sum()
            };
            // The tinted average inherits the F_avg fit's error, scaled by (1 − F0·t)/(1 − F0).
            let fit_error = (mean(plain) - plain.average()).abs().max_element();
            let err = (mean(tinted) - tinted.average()).abs().max_element();
            assert!(err <= fit_error / (1.0 - f0) + 1e-4, "η {eta}: {err} against the fit's {fit_error}");
        }
    }

    testing::lobe_battery!(
        lobes: battery_lobes(),
        chi_square: vec![
            white(0.2, 0.0, false),
            white(0.6, 0.0, true),
            gold(0.3, 0.8),
            gold(1.0, -1.0),
            tinted_dielectric(0.4, Vec3::new(0.2, 0.9, 0.5)),
            f82(0.3, Vec3::new(0.3, 0.8, 1.0))
        ],
        seed: 100,
    );

    #[test]
    fn smooth_conductor_is_a_mirror_weighted_by_fresnel() {
        let wo = Vec3::new(0.6, 0.0, 0.8);
        for r in [0.0, 1e-4, 1e-7] {
            let s = gold(r, 0.0).sample(wo, 0.5, Vec2::new(0.3, 0.7)).unwrap();
            assert!(s.flags.delta);
            assert!((s.wi - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
            assert!(s.weight.max_element() <= 1.0 && s.weight.min_element() > 0.3);
        }
    }
}
