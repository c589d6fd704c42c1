//! Rough diffuse reflection that keeps its energy: the "energy-preserving Oren-Nayar" (EON) of
//! Portsmouth, Kutz and Hill, "EON: A practical energy-preserving rough diffuse BRDF" (JCGT
//! 14(1), 2025), the diffuse model of OpenPBR Surface (`base_diffuse_roughness`) and of
//! Cycles' Oren-Nayar since Blender 4.3.
//!
//! Its single-scattering part is Fujii's "qualitative" Oren-Nayar (FON, "A tiny improvement of
//! Oren-Nayar reflectance model"): f_ss = ρ/π·A·(1 + σ·s/t), with s = cos(wo, wi) − μo·μi,
//! t = max(μo, μi) where s > 0 and 1 elsewhere, A = 1/(1 + (1/2 − 2/(3π))·σ). Its directional
//! albedo has the closed form E(μ) = A + σA·G(μ)/π (EON section 3), and its mean over the
//! cosine-weighted hemisphere Ē = A·(1 + (2/3 − 28/(15π))·σ). What rough facets lose to
//! interreflection comes back through the multiple-scattering part (EON section 4, the same
//! form as Kulla & Conty's 2017 "Revisiting Physically Based Shading at Imageworks",
//! "Energy compensation"):
//!
//!   f_ms = ρ_ms/π · (1 − E(μo))(1 − E(μi)) / (1 − Ē),   ρ_ms = ρ²·Ē / (1 − ρ(1 − Ē)),
//!
//! so a white surface reflects exactly everything at every angle and roughness. Both parts are
//! symmetric in the two directions. Sampling is by the cosine, as Cycles does: the lobe is
//! never far from it (f·cos/pdf stays within [A, 1 + σ]·ρ for the single-scattering part).

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

use super::view_cache::ViewCache;
use super::{LobeFlags, LobeSample};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// 1/2 − 2/(3π): FON's normalisation, A = 1/(1 + this·σ).
const FON_A: f32 = 0.5 - 2.0 / (3.0 * PI);
/// 2/3 − 28/(15π): Ē = A·(1 + this·σ).
const FON_AVG: f32 = 2.0 / 3.0 - 28.0 / (15.0 * PI);

/// EON: Fujii's Oren-Nayar with its lost energy given back, on either side of a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrenNayar {
    /// Reflectance ρ in [0, 1] per channel.
    pub color: Vec3,
    /// Roughness σ in [0, 1] (0 is Lambertian).
    pub sigma: f32,
    /// Under a dielectric specular of (η, roughness): the diffuse reflects only what the
    /// specular leaves, as the Disney diffuse does ([`super::DisneyDiffuse::coupling`]).
    pub coupling: Option<(f32, f32)>,
    /// What the shading point's view reads once: E(μo), and the coupled specular's (Ē_s, E_s(μo)).
    at_view: ViewCache<ViewTerms>,
}

#[derive(Clone, Copy, Debug, Default)]
struct ViewTerms {
    e_o: f32,
    coupling: (f32, f32),
}

impl OrenNayar {
    /// Reflection, not delta.
    pub const FLAGS: LobeFlags = LobeFlags { reflection: true, transmission: false, delta: false };

    /// A lobe of reflectance `color` and roughness `sigma` (clamped to [0, 1]).
    pub fn new(color: Vec3, sigma: f32, coupling: Option<(f32, f32)>) -> Self {
        let sigma = if sigma.is_finite() { sigma.clamp(0.0, 1.0) } else { 0.0 };
        OrenNayar { color: color.clamp(Vec3::ZERO, Vec3::ONE), sigma, coupling, at_view: ViewCache::default() }
    }

    /// Looks up once what every evaluation at view `wo` shares.
    #[inline]
    pub fn prepare(&mut self, wo: Vec3) {
        self.at_view.store(wo, self.view_terms(wo));
    }

    fn view_terms(&self, wo: Vec3) -> ViewTerms {
        let mu = wo.z.abs().min(1.0);
        ViewTerms { e_o: fon_albedo(self.sigma, mu), coupling: super::energy::coupling_at_view(self.coupling, mu) }
    }

    /// f without the cosine.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let terms = self.at_view.get(wo, || self.view_terms(wo));
        let mi = wi.z.abs().min(1.0);
        let single = self.color * self.single_scattering(wo, wi);
        let e_avg = fon_average_albedo(self.sigma);
        let multi = if e_avg < 1.0 {
            multiple_scattering_albedo(self.color, e_avg)
                * ((1.0 - terms.e_o) * (1.0 - fon_albedo(self.sigma, mi)) / (1.0 - e_avg) * FRAC_1_PI)
        } else {
            Vec3::ZERO
        };
        (single + multi).max(Vec3::ZERO) * super::energy::coupled_share(self.coupling, terms.coupling, mi)
    }

    /// FON's single scattering for a white surface, A/π·(1 + σ·s/t).
    fn single_scattering(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (mo, mi) = (wo.z.abs().min(1.0), wi.z.abs().min(1.0));
        // s = cos of the angle between the directions' projections, times both sines.
        let s = wo.dot(wi) - mo * mi;
        let s_over_t = if s > 0.0 { s / mo.max(mi) } else { s };
        fon_a(self.sigma) * (1.0 + self.sigma * s_over_t) * FRAC_1_PI
    }

    /// Cosine-weighted on `wo`'s side.
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let w = cosine_hemisphere(u);
        let wi = if wo.z < 0.0 { -w } else { w };
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| LobeSample { wi, weight: self.eval(wo, wi) * wi.z.abs() / pdf, pdf, flags: Self::FLAGS, eta: 1.0 })
    }

    /// |cos θi|/π on `wo`'s side.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z > 0.0 { cosine_hemisphere_pdf(wi.z.abs()) } else { 0.0 }
    }

    /// The directional albedo, exactly: ρ·E(μo) + ρ_ms·(1 − E(μo)) (the multiple-scattering
    /// part's (1 − E(μi)) averages to 1 − Ē over the cosine-weighted hemisphere), less what a
    /// coupled specular takes.
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        let terms = self.at_view.get(wo, || self.view_terms(wo));
        let e_avg = fon_average_albedo(self.sigma);
        let own = self.color * terms.e_o + multiple_scattering_albedo(self.color, e_avg) * (1.0 - terms.e_o);
        match self.coupling {
            Some(_) => own * (1.0 - terms.coupling.1),
            None => own,
        }
    }
}

/// FON's A = 1/(1 + (1/2 − 2/(3π))·σ).
#[inline]
fn fon_a(sigma: f32) -> f32 {
    1.0 / (1.0 + FON_A * sigma)
}

/// E(μ) of FON for a white surface: A + σA·G(μ)/π (EON, section 3, after Fujii).
pub fn fon_albedo(sigma: f32, mu: f32) -> f32 {
    let a = fon_a(sigma);
    a + sigma * a * fon_g(mu.clamp(0.0, 1.0)) * FRAC_1_PI
}

/// Ē of FON for a white surface: A·(1 + (2/3 − 28/(15π))·σ).
pub fn fon_average_albedo(sigma: f32) -> f32 {
    fon_a(sigma) * (1.0 + FON_AVG * sigma)
}

/// G(μ) = sinθ·(θ − sinθ·cosθ) + (2/3)·(sinθ/cosθ·(1 − sin³θ) − sinθ). The quotient
/// (1 − sin³θ)/cosθ is written μ·(1 + s + s²)/(1 + s) (1 − s = μ²/(1 + s)), which is exact and
/// has no 0/0 at grazing angles: G(0) = π/2 − 2/3.
fn fon_g(mu: f32) -> f32 {
    let s = (1.0 - mu * mu).max(0.0).sqrt();
    let theta = mu.acos();
    let cubic_over_cos = mu * (1.0 + s + s * s) / (1.0 + s);
    s * (theta - s * mu) + (2.0 / 3.0) * (s * cubic_over_cos - s)
}

/// ρ_ms = ρ²·Ē/(1 − ρ(1 − Ē)): what light that reflects more than once between facets
/// returns, summed as a geometric series over bounces of albedo ρ.
#[inline]
fn multiple_scattering_albedo(rho: Vec3, e_avg: f32) -> Vec3 {
    rho * rho * e_avg / (Vec3::ONE - rho * (1.0 - e_avg))
}

/// A bound on f·|cos θi|·π for tests. f itself is not bounded: like Oren-Nayar's tan β, s/t
/// grows without bound as both directions turn grazing. With the cosine it is: the single
/// scattering reaches A·(1 + σ) ≤ 1.56 (μi/t ≤ 1), the multiple scattering
/// Ē·(1 − A)²/(1 − Ē) ≤ 0.25 (E(μ) ≥ A), both at σ = 1.
#[cfg(test)]
const F_PI_BOUND: f32 = 1.81;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lobe, testing};

    fn lobes() -> Vec<Lobe> {
        let mut v = Vec::new();
        for sigma in [0.0, 0.3, 1.0] {
            v.push(Lobe::OrenNayar(OrenNayar::new(Vec3::ONE, sigma, None)));
            v.push(Lobe::OrenNayar(OrenNayar::new(Vec3::new(0.8, 0.4, 0.05), sigma, None)));
        }
        v.push(Lobe::OrenNayar(OrenNayar::new(Vec3::ONE, 0.7, Some((1.5, 0.3)))));
        v
    }

    testing::lobe_battery!(lobes: lobes(), chi_square: lobes(), seed: 0x0e0a);

    /// The closed form against the FON albedo integrated numerically, ∫∫ f_ss·π·μi dμi dφ/π
    /// by 800 × 800 midpoints in (μi, φ), at cosines down to grazing, for σ = 0.25, 0.5, 1.
    /// The bound is the quadrature's: against 8 000 × 8 000 midpoints (numpy, f64) the closed
    /// form agrees to 2e-9 at μ = 0.05.
    #[test]
    fn the_closed_form_albedo_is_the_integral_of_the_single_scattering() {
        for sigma in [0.25f32, 0.5, 1.0] {
            let lobe = OrenNayar::new(Vec3::ONE, sigma, None);
            for mu in [1.0f32, 0.7, 0.3, 0.05, 1e-3] {
                let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let numeric = testing::hemisphere_integral(800, |wi| lobe.single_scattering(wo, wi) * wi.z);
                let closed = fon_albedo(sigma, mu) as f64;
                assert!((numeric - closed).abs() < 2e-5, "σ {sigma} μ {mu}: quadrature {numeric} closed form {closed}");
            }
        }
    }

    /// Ē is the cosine-weighted mean of E(μ): 2∫E(μ)μ dμ, by 20 000 midpoints.
    #[test]
    fn the_average_albedo_is_the_mean_of_the_directional_one() {
        for sigma in [0.1f32, 0.5, 1.0] {
            let n = 20_000;
            let mean: f64 = (0..n)
                .map(|k| {
                    let mu = (k as f64 + 0.5) / n as f64;
                    2.0 * fon_albedo(sigma, mu as f32) as f64 * mu / n as f64
                })
                .sum();
            assert!((mean - fon_average_albedo(sigma) as f64).abs() < 2e-5, "σ {sigma}: {mean} against {}", fon_average_albedo(sigma));
        }
    }

    /// The point of EON: white reflects everything at every view and roughness. The bound is
    /// the estimator's: 200 000 cosine samples, whose weights vary by less than ±σ around 1.
    #[test]
    fn white_reflects_everything_at_every_roughness() {
        for sigma in [0.2f32, 0.6, 1.0] {
            let lobe = Lobe::OrenNayar(OrenNayar::new(Vec3::ONE, sigma, None));
            for mu in [0.95f32, 0.5, 0.1] {
                let a = testing::albedo_estimate(&lobe, Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu), 200_000);
                assert!((a - Vec3::ONE).abs().max_element() < 3e-3, "σ {sigma} μ {mu}: {a:?}");
                assert!((lobe.albedo(Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu)) - Vec3::ONE).abs().max_element() < 1e-5);
            }
        }
    }

    /// Without the multiple scattering a rough white surface loses what FON says it does
    /// (1 − Ē = 0.167 at σ = 1), and `albedo` reports the coloured sum exactly.
    #[test]
    fn albedo_matches_the_sampled_estimate_for_colours() {
        let lobe = OrenNayar::new(Vec3::new(0.8, 0.4, 0.05), 1.0, None);
        assert!((1.0 - fon_average_albedo(1.0) - 0.1673).abs() < 1e-3);
        for mu in [0.9f32, 0.3] {
            let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let est = testing::albedo_estimate(&Lobe::OrenNayar(lobe), wo, 200_000);
            assert!((est - lobe.albedo(wo)).abs().max_element() < 3e-3, "μ {mu}: {est:?} against {:?}", lobe.albedo(wo));
        }
    }

    /// σ = 0 is Lambert's R/π to the bit.
    #[test]
    fn zero_roughness_is_lambertian() {
        let lobe = OrenNayar::new(Vec3::new(0.3, 0.6, 0.9), 0.0, None);
        let (wo, wi) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.28, 0.96, 0.0).lerp(Vec3::Z, 0.5).normalize());
        assert_eq!(lobe.eval(wo, wi), Vec3::new(0.3, 0.6, 0.9) * FRAC_1_PI);
    }

    /// Backscatter: rough facets look back towards the viewer, flattening a lit sphere. At
    /// σ = 1, μo = μi = 0.5 in the plane of incidence, FON's single scattering towards the
    /// viewer is 1 + s/t = 1 + 0.75/0.5 against 1 + s = 1 − 0.75 in the mirror direction: 10x.
    /// The multiple scattering depends on μi alone, so it adds the same to both.
    #[test]
    fn rough_surfaces_scatter_back_towards_the_light() {
        let lobe = OrenNayar::new(Vec3::ONE, 1.0, None);
        let wo = Vec3::new(0.75f32.sqrt(), 0.0, 0.5);
        let (back, mirror) = (wo, Vec3::new(-wo.x, 0.0, wo.z));
        let (fb, fm) = (lobe.eval(wo, back).x, lobe.eval(wo, mirror).x);
        let ms = fb - lobe.single_scattering(wo, back);
        assert!((lobe.single_scattering(wo, back) / lobe.single_scattering(wo, mirror) - 10.0).abs() < 1e-4);
        assert!((fm - lobe.single_scattering(wo, mirror) - ms).abs() < 1e-6 && fb > fm);
    }

    /// Extremes: grazing views and lights, σ outside [0, 1] and NaN, colours outside [0, 1]:
    /// finite, not negative, and f·cos bounded.
    #[test]
    fn extremes_stay_finite_and_bounded() {
        for sigma in [-1.0f32, 0.0, 1e-7, 1.0, 5.0, f32::NAN] {
            let lobe = OrenNayar::new(Vec3::new(1.0, 0.0, 2.0), sigma, None);
            for mu in [0.0f32, 1e-8, 1e-4, 1.0] {
                let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                for wi in testing::probe_directions() {
                    let f = lobe.eval(wo, wi);
                    assert!(f.is_finite() && f.min_element() >= 0.0 && f.max_element() * wi.z.abs() * PI <= F_PI_BOUND, "{f:?}");
                }
                assert!(lobe.albedo(wo).is_finite());
            }
        }
    }
}
