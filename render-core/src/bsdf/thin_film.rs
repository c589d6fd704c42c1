//! Thin-film interference (iridescence), the third of Imageworks' coatings (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks",
//! "Coatings": clearcoat, sheen, thin film; the slides leave the film model to the reader).
//! The model here is the classical Airy summation for one film between air and a dielectric
//! substrate (Born & Wolf, *Principles of Optics*, section 7.6; the form Belcour & Barla 2017
//! start from): with amplitude Fresnel coefficients r01 (air to film) and r12 (film to
//! substrate) per polarisation and the phase δ = (2π/λ)·2·n_f·d·cos θ_f,
//! R = (r01² + r12² + 2 r01 r12 cos δ) / (1 + r01² r12² + 2 r01 r12 cos δ), averaged over the two
//! polarisations and evaluated at 650, 550 and 450 nm for red, green and blue. Three
//! wavelengths alias for films thicker than about a micrometre, so thickness is clamped to
//! [0, 1000] nm.
//!
//! As a coat, its directional albedo E(μ) is tabulated per material when it is built (16 √μ
//! nodes of the coat lobe's own quadrature), and the layers beneath keep
//! min(1 − E(μo), 1 − E(μi)) as for the other coats.

use glam::Vec3;

/// Wavelengths (nm) standing for red, green and blue.
pub const WAVELENGTHS: [f32; 3] = [650.0, 550.0, 450.0];

/// Thickest film the three-wavelength model resolves.
pub const MAX_THICKNESS_NM: f32 = 1000.0;

/// Amplitude reflection coefficients (s, p) from medium of index `n1` into `n2` for incidence
/// cosine `c1`; None past the critical angle.
fn amplitudes(n1: f32, n2: f32, c1: f32) -> Option<(f32, f32, f32)> {
    let s1 = (1.0 - c1 * c1).max(0.0).sqrt();
    let s2 = n1 / n2 * s1;
    if s2 >= 1.0 {
        return None;
    }
    let c2 = (1.0 - s2 * s2).sqrt();
    let rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2);
    let rp = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    Some((rs, rp, c2))
}

/// Reflectance of a film of index `film` and thickness `nm` on a substrate of index
/// `substrate`, seen from air at cosine `cos`, per RGB wavelength.
pub fn airy(cos: f32, film: f32, nm: f32, substrate: f32) -> Vec3 {
    let fix = |x: f32, lo: f32, hi: f32, d: f32| if x.is_finite() { x.clamp(lo, hi) } else { d };
    let (cos, nm) = (fix(cos, 0.0, 1.0, 0.0), fix(nm, 0.0, MAX_THICKNESS_NM, 0.0));
    let (film, substrate) = (fix(film, 1.0, 3.0, 1.33), fix(substrate, 1.0, 3.0, 1.5));
    let Some((r01s, r01p, cf)) = amplitudes(1.0, film, cos) else { return Vec3::ONE };
    let (r12s, r12p) = match amplitudes(film, substrate, cf) {
        Some((s, p, _)) => (s, p),
        // Total reflection at the substrate: the film's bottom reflects everything.
        None => (1.0, 1.0),
    };
    let one = |lambda: f32| {
        let delta = 2.0 * std::f32::consts::PI / lambda * 2.0 * film * nm * cf;
        let r = |a: f32, b: f32| {
            let c = 2.0 * a * b * delta.cos();
            ((a * a + b * b + c) / (1.0 + a * a * b * b + c)).clamp(0.0, 1.0)
        };
        0.5 * (r(r01s, r12s) + r(r01p, r12p))
    };
    Vec3::new(one(WAVELENGTHS[0]), one(WAVELENGTHS[1]), one(WAVELENGTHS[2]))
}

/// A thin-film coat: a GGX reflection whose Fresnel is the film's interference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinFilmCoat {
    /// Coverage.
    pub weight: f32,
    /// Roughness of the film's surface.
    pub roughness: f32,
    /// Film refractive index.
    pub film: f32,
    /// Thickness in nanometres.
    pub thickness: f32,
    /// Refractive index under the film.
    pub substrate: f32,
    /// The coat lobe's directional albedo at √μ = k/15 (largest channel).
    pub e: [f32; 16],
}

impl ThinFilmCoat {
    /// A coat, its albedo table computed by stratified quadrature of its own lobe.
    pub fn new(weight: f32, roughness: f32, film: f32, thickness: f32, substrate: f32, compensate: bool) -> Self {
        let fix = |x: f32, lo: f32, hi: f32, d: f32| if x.is_finite() { x.clamp(lo, hi) } else { d };
        let mut c = ThinFilmCoat {
            weight: fix(weight, 0.0, 1.0, 0.0),
            roughness: fix(roughness, 0.0, 1.0, 0.0),
            film: fix(film, 1.0, 3.0, 1.33),
            thickness: fix(thickness, 0.0, MAX_THICKNESS_NM, 0.0),
            substrate: fix(substrate, 1.0, 3.0, 1.5),
            e: [0.0; 16],
        };
        let lobe = c.lobe(compensate);
        c.e = std::array::from_fn(|k| {
            let mu = ((k as f32 / 15.0).powi(2)).max(1e-4);
            super::energy::grid_albedo(|wo, uc, u| lobe.sample(wo, uc, u), mu, 24).min(1.0)
        });
        c
    }

    /// The coat's own lobe.
    pub fn lobe(&self, compensate: bool) -> super::GgxReflection {
        let fresnel = super::SpecularFresnel::thin_film(self.film, self.thickness, self.substrate);
        super::GgxReflection::new(self.roughness, 0.0, fresnel, compensate)
    }

    /// E(μ) from the table.
    pub fn e(&self, mu: f32) -> f32 {
        super::energy::split_axis(mu.abs().min(1.0).sqrt(), 16).iter().map(|&(k, w)| w * self.e[k]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, Coat, Lambert, Lobe, fresnel, testing};

    #[test]
    fn a_film_of_no_thickness_is_the_bare_substrate() {
        for cos in [1.0f32, 0.7, 0.3, 0.05] {
            let r = airy(cos, 1.33, 0.0, 1.5);
            let bare = fresnel::dielectric(cos, 1.5);
            assert!((r - Vec3::splat(bare)).abs().max_element() < 1e-4, "cos {cos}: {r:?} vs {bare}");
        }
    }

    /// A quarter-wave film of index √n_s cancels reflection at its design wavelength, head-on:
    /// the anti-reflection coating.
    #[test]
    fn quarter_wave_film_is_anti_reflective() {
        let film = 1.5f32.sqrt();
        let r = airy(1.0, film, 550.0 / (4.0 * film), 1.5);
        assert!(r.y < 1e-5, "green reflectance {}", r.y);
        assert!(r.x > 1e-3 && r.z > 1e-3, "the other wavelengths reflect: {r:?}");
        // Colour varies with thickness: iridescence.
        let a = airy(1.0, 1.33, 300.0, 1.5);
        let b = airy(1.0, 1.33, 400.0, 1.5);
        assert!((a - b).abs().max_element() > 0.01);
    }

    #[test]
    fn coated_white_base_conserves_energy_and_samples_its_pdf() {
        let mut b = Bsdf::default();
        b.push(Lobe::Lambert(Lambert { r: Vec3::ONE }));
        b.coat_with(Coat::ThinFilm(ThinFilmCoat::new(1.0, 0.2, 1.33, 380.0, 1.5, true)), true);
        for wo in testing::probe_directions() {
            let a = testing::albedo_estimate(&b, wo, 40_000);
            assert!(a.max_element() <= 1.0 + 1e-3 + 0.01, "{wo:?}: {a:?}");
        }
        testing::assert_reciprocal(&b);
        testing::assert_chi2_at(&b, 1200, testing::probe_directions().into_iter().filter(|w| w.z >= 1e-2).collect());
    }

    #[test]
    fn finite_at_extreme_parameters() {
        for (film, nm, sub) in [(1.0, 0.0, 1.0), (3.0, 1e9, 3.0), (f32::NAN, f32::NAN, f32::NAN), (1.2, 500.0, 3.0)] {
            for cos in [0.0f32, 1e-6, 0.5, 1.0] {
                assert!(crate::math::is_finite(airy(cos, film.clamp(1.0, 3.0), nm, sub.clamp(1.0, 3.0))));
            }
            let c = ThinFilmCoat::new(1.0, 0.0, film, nm, sub, true);
            assert!(c.e.iter().all(|e| e.is_finite()));
        }
    }
}
