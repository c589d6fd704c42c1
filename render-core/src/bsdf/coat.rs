//! Coatings over any combination of lobes (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Coatings"): a clearcoat (Disney's GTR1
//! or Imageworks' dielectric layer with absorption) or the Charlie sheen, each taking from the
//! layers beneath what it reflects itself: by the slides' min rule, or, over a diffuse lobe of
//! known shape, by their renormalised product ([`DiffuseProfile`]).

use glam::Vec3;

use super::{CharlieSheen, Clearcoat, Fuzz, GgxReflection, Lobe, SpecularFresnel, ThinFilmCoat, charlie, energy, fuzz};

/// A layer over the lobes added before it, which takes from them what it reflects
/// (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Coatings": f_s' = min(1 − E(μo), 1 − E(μi))·f_s, E the coat's directional
/// albedo, or the renormalised product over a diffuse lobe, [`DiffuseProfile`]; coats can
/// stack).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coat {
    /// Disney's GTR1 clearcoat ([`Clearcoat`]).
    Disney(Clearcoat),
    /// Imageworks' Charlie sheen ([`CharlieSheen`]).
    Sheen(CharlieSheen),
    /// Zeltner et al.'s fuzz ([`Fuzz`]).
    Fuzz(Fuzz),
    /// A dielectric layer with its own IOR, roughness and absorbing thickness.
    Dielectric(DielectricCoat),
    /// A thin film's interference (iridescence).
    ThinFilm(ThinFilmCoat),
}

/// Imageworks' clearcoat (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Clearcoat"; DreamWorks' Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation" section 2.3 exposes
/// the same refractive index, thickness and attenuation colour): a compensated dielectric
/// GGX reflection whose albedo comes from the 3D E(μ) table
/// ([`energy::dielectric_specular`]), tinting the layers beneath by absorption along the
/// refracted path in and out, exp(−σ_a·t·(1/μo' + 1/μi')).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricCoat {
    /// Coverage in [0, 1].
    pub weight: f32,
    /// Refractive index of the coat over the outside.
    pub eta: f32,
    /// Roughness.
    pub roughness: f32,
    /// σ_a·thickness per channel (0: clear).
    pub absorption: Vec3,
}

impl DielectricCoat {
    /// A coat whose normal-incidence round trip (in and out) is tinted `color`:
    /// σ_a·t = −ln(color)/2 per channel, `thickness` scaling it (1: exactly `color` head-on).
    pub fn new(weight: f32, eta: f32, roughness: f32, color: Vec3, thickness: f32) -> Self {
        let color = color.clamp(Vec3::splat(1e-4), Vec3::ONE);
        let absorption = -0.5 * thickness.max(0.0) * Vec3::new(color.x.ln(), color.y.ln(), color.z.ln());
        DielectricCoat { weight: weight.clamp(0.0, 1.0), eta: eta.clamp(1.0, 3.0), roughness: roughness.clamp(0.0, 1.0), absorption }
    }

    /// Transmittance along the refracted direction inside the coat for outside cosine `mu`.
    fn transmittance(&self, mu: f32) -> Vec3 {
        if self.absorption == Vec3::ZERO {
            return Vec3::ONE;
        }
        let cos_t = (1.0 - (1.0 - mu * mu) / (self.eta * self.eta)).max(1e-4).sqrt();
        (-self.absorption / cos_t).exp()
    }
}

impl Coat {
    /// The coat's own lobe and its weight.
    pub fn lobe(&self, compensate: bool) -> (Lobe, f32) {
        match *self {
            Coat::Disney(c) => (Lobe::Clearcoat(c), 1.0),
            Coat::Sheen(s) => (Lobe::CharlieSheen(s), 1.0),
            Coat::Fuzz(f) => (Lobe::Fuzz(f), 1.0),
            Coat::Dielectric(d) => (
                Lobe::GgxReflection(GgxReflection::new(d.roughness, 0.0, SpecularFresnel::Dielectric { eta: d.eta }, compensate)),
                d.weight,
            ),
            Coat::ThinFilm(t) => (Lobe::GgxReflection(t.lobe(compensate)), t.weight),
        }
    }

    /// What the coat lets through to the layers beneath at cosine `mu`: 1 − E(μ).
    pub(super) fn through(&self, mu: f32) -> f32 {
        let mu = mu.abs();
        let e = match self {
            Coat::Disney(c) => c.weight * energy::clearcoat().e(c.alpha, mu),
            Coat::Sheen(s) => s.color.max_element() * charlie::sheen_energy().e(s.r, mu),
            Coat::Fuzz(f) => f.color.max_element() * fuzz::albedo(mu, f.alpha),
            Coat::Dielectric(d) => d.weight * energy::dielectric_specular().e(d.eta, d.roughness, mu),
            Coat::ThinFilm(t) => t.weight * t.e(mu),
        };
        (1.0 - e).max(0.0)
    }

    /// The scales of the lobes beneath for light entering at `wi` and leaving at `wo`, each
    /// times the coat's absorption both ways:
    /// - `any`, for any lobe: min(1 − E(μo), 1 − E(μi)) (the slides' rule);
    /// - `diffuse`, for a lobe whose shape in μi is known ([`DiffuseProfile`]):
    ///   (1 − E(μo))(1 − E(μi)), to be renormalised by [`DiffuseProfile::coat_norm`].
    ///
    /// Both are symmetric in their arguments, so layering keeps the BSDF reciprocal. The fuzz,
    /// whose own lobe is not reciprocal, scales both by 1 − E(μo) alone, OpenPBR's albedo
    /// scaling (and Cycles'): a white fuzz over a white base then reflects all the light,
    /// where the min rule lost 6% of it. `through_wo` is [`Coat::through`] at `wo`, which
    /// `Bsdf::prepare` looks up once per view.
    pub(super) fn over(&self, through_wo: f32, wo: Vec3, wi: Vec3) -> CoatScale {
        let (any, diffuse) = match self {
            Coat::Fuzz(_) => (through_wo, through_wo),
            _ => {
                let through_wi = self.through(wi.z);
                (through_wo.min(through_wi), through_wo * through_wi)
            }
        };
        let tint = self.tint(wo, wi);
        CoatScale { any: any * tint, diffuse: diffuse * tint }
    }

    /// What the coat's absorption leaves of light entering at `wi` and leaving at `wo`.
    fn tint(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Coat::Dielectric(d) if d.absorption != Vec3::ZERO => {
                let tint = d.transmittance(wo.z.abs()) * d.transmittance(wi.z.abs());
                Vec3::ONE + (tint - Vec3::ONE) * d.weight
            }
            _ => Vec3::ONE,
        }
    }

    /// True when the coat's scale of a lobe beneath depends on both directions (all but the
    /// fuzz, which scales by 1 − E(μo) alone).
    fn is_reciprocal(&self) -> bool {
        !matches!(self, Coat::Fuzz(_))
    }
}

/// A coat's scales of the lobes beneath it ([`Coat::over`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct CoatScale {
    /// For any lobe: the min rule.
    pub any: Vec3,
    /// For a diffuse lobe of known shape: the product, before its renormalisation.
    pub diffuse: Vec3,
}

impl CoatScale {
    /// No coat.
    pub const NONE: CoatScale = CoatScale { any: Vec3::ONE, diffuse: Vec3::ONE };
}

/// How a diffuse lobe's f varies with μi, where it is f(μo, μi) = c(μo)·g(μi): a Lambertian
/// lobe (g = 1), or a Lambertian coupled to the dielectric specular over it (g = 1 − E_s(μi):
/// UsdPreviewSurface's diffuse).
///
/// Over such a lobe both the coats' E and the lobe's shape are known, so the slides'
/// renormalised product applies rather than their min rule: Kulla & Conty 2017, "Revisiting Physically
/// Based Shading at Imageworks", "Coatings" takes min(1 − E(μo), 1 − E(μi)) because "since
/// the underlying BSDF can be anything – not just diffuse – we have no way to renormalize it";
/// for a diffuse one the section "Microfacet dielectrics — diffuse term" does renormalise,
/// f·(1 − E(μo))(1 − E(μi))/(1 − E_avg). With several coats and the lobe's own shape the
/// constant is K = ∫g·T·2μ dμ / ∫g·2μ dμ, T = Π(1 − E_j) over the coats: the lobe then
/// reflects exactly T(μo) of what it reflected bare (a white Lambertian under a clear coat is
/// white in the furnace, where the min rule lost up to 5.5%), and the scale stays symmetric.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum DiffuseProfile {
    /// g = 1.
    Flat,
    /// g = 1 − E_s(μ) of a dielectric specular (η, roughness).
    Coupled(f32, f32),
}

impl DiffuseProfile {
    /// g(μ).
    fn at(self, mu: f32) -> f32 {
        match self {
            DiffuseProfile::Flat => 1.0,
            DiffuseProfile::Coupled(eta, r) => 1.0 - energy::dielectric_specular().e(eta, r, mu),
        }
    }

    /// 1/K for the lobe under `coats` (only the reciprocal ones renormalise); 1 when they let
    /// everything through. The quadrature reads the tables two dozen times, and a textured
    /// material builds its BSDF at every shading point, mostly under the same coats: each
    /// thread keeps its last answer for each number of coats, since a stack is renormalised
    /// again as each coat goes on (a coupled diffuse under a Disney clearcoat, built again and
    /// again: 363 ns a build with the coat changing each time, 39 ns with it the same; a
    /// Lambertian under a clearcoat and a sheen, 927 ns while one answer was kept, as the two
    /// stages took turns evicting each other, 82 ns with one for each).
    pub(super) fn coat_norm<'c>(self, coats: impl Iterator<Item = &'c Coat>) -> f32 {
        let mut key = [None; super::MAX_COATS];
        let mut count = 0;
        for (slot, c) in key.iter_mut().zip(coats.filter(|c| c.is_reciprocal())) {
            (*slot, count) = (Some(*c), count + 1);
        }
        if count == 0 {
            return 1.0;
        }
        type Last = Option<(DiffuseProfile, [Option<Coat>; super::MAX_COATS], f32)>;
        thread_local! {
            static LAST: [std::cell::Cell<Last>; super::MAX_COATS] = const { [const { std::cell::Cell::new(None) }; super::MAX_COATS] };
        }
        LAST.with(|last| match last[count - 1].get() {
            Some((profile, coats, norm)) if profile == self && coats == key => norm,
            _ => {
                let norm = self.integrate(key.iter().flatten());
                last[count - 1].set(Some((self, key, norm)));
                norm
            }
        })
    }

    /// 1/K by Gauss-Legendre quadrature over μ.
    fn integrate<'c>(self, coats: impl Iterator<Item = &'c Coat> + Clone) -> f32 {
        let (mut with, mut bare) = (0.0, 0.0);
        for &(x, w) in gauss_legendre_unit() {
            let g = self.at(x) * w * x;
            with += g * coats.clone().map(|c| c.through(x)).product::<f32>();
            bare += g;
        }
        if with > 0.0 { bare / with } else { 0.0 }
    }
}

/// Nodes of [`gauss_legendre_unit`]: enough for the smooth 1 − E(μ) of a coat and a coupled
/// lobe (a test holds the result to a fine midpoint sum).
const GAUSS_NODES: usize = 12;

/// Gauss-Legendre nodes and weights on [0, 1], computed once: the roots of P_n by Newton's
/// method from Chebyshev guesses, weights 2/((1 − x²)P_n'(x)²), both mapped from [−1, 1].
fn gauss_legendre_unit() -> &'static [(f32, f32); GAUSS_NODES] {
    static RULE: std::sync::OnceLock<[(f32, f32); GAUSS_NODES]> = std::sync::OnceLock::new();
    RULE.get_or_init(|| {
        let n = GAUSS_NODES;
        std::array::from_fn(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                // P_n(x) by the three-term recurrence, and its derivative.
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let step = p1 / dp;
                x -= step;
                if step.abs() < 1e-15 {
                    break;
                }
            }
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            (((1.0 + x) * 0.5) as f32, (w * 0.5) as f32)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, DisneyDiffuse, Lambert, testing};

    fn coated(coats: &[Coat]) -> Bsdf {
        let mut b = Bsdf::default();
        b.push(Lobe::Lambert(Lambert { r: Vec3::ONE }));
        for c in coats {
            b.coat_with(*c, true);
        }
        b
    }

    fn coats() -> Vec<Vec<Coat>> {
        vec![
            vec![Coat::Sheen(CharlieSheen::new(Vec3::ONE, 0.3))],
            vec![Coat::Sheen(CharlieSheen::new(Vec3::ONE, 1.0))],
            vec![Coat::Dielectric(DielectricCoat::new(1.0, 1.5, 0.2, Vec3::ONE, 0.0))],
            vec![Coat::Dielectric(DielectricCoat::new(1.0, 1.5, 0.0, Vec3::ONE, 0.0))],
            vec![Coat::Dielectric(DielectricCoat::new(0.7, 2.0, 0.6, Vec3::new(0.9, 0.5, 0.2), 1.0))],
            // Stacked: sheen over a clearcoat over the base.
            vec![Coat::Dielectric(DielectricCoat::new(1.0, 1.5, 0.1, Vec3::ONE, 0.0)), Coat::Sheen(CharlieSheen::new(Vec3::ONE, 0.5))],
            // Fuzz, after the rest so their χ² seeds stay theirs.
            vec![Coat::Fuzz(Fuzz::new(Vec3::ONE, 0.5))],
            vec![Coat::Fuzz(Fuzz::new(Vec3::ONE, 1.0))],
        ]
    }

    /// Over a white Lambertian base a clear coat, or a white sheen, loses nothing: the base is
    /// renormalised under it ([`DiffuseProfile`]) and reflects exactly what the coat lets
    /// through, so coat and base sum to 1 at every view. With the slides' min rule alone the
    /// clear coats lost up to 5.5% and a sheen of roughness 1, seen head-on, 13.5% (light
    /// arriving at grazing angles, where the sheen reflects most, was taken from the base).
    /// Stacked, the clearcoat's own lobe under the sheen keeps the min rule (it is not diffuse)
    /// and loses a little. 40 000 samples hold each estimate to about 0.005; the coats' tables
    /// hold their E to about as much (measured: 0.998-1.005 for the clear coats).
    #[test]
    fn coated_white_base_keeps_its_energy() {
        for c in coats().into_iter().filter(|c| !matches!(c[..], [Coat::Dielectric(d)] if d.absorption != Vec3::ZERO)) {
            let b = coated(&c);
            let stacked = c.len() > 1;
            for wo in testing::probe_directions() {
                let a = testing::albedo_estimate(&b, wo, 40_000).x;
                assert!(a <= 1.0 + 0.01, "{c:?} at {wo:?}: {a}");
                // At μo = 1e-4 the sheen's lobe reflects a little less than its table's last
                // cosine says, and what the table says is what the base gives up: 0.970-0.973
                // alone, 0.917 stacked. Elsewhere the lowest is 0.9947 (stacked).
                let floor = match (wo.z < 1e-3, stacked) {
                    (false, _) => 0.99,
                    (true, false) => 0.965,
                    (true, true) => 0.91,
                };
                assert!(a >= floor, "{c:?} at {wo:?} loses energy: {a}");
            }
        }
    }

    /// The renormalisation's quadrature: exact for polynomials of degree 2n − 1, and 1/K for
    /// real coats within 1e-4 of a 20 000-point midpoint sum.
    #[test]
    fn diffuse_renormalisation_integrates_exactly_enough() {
        for degree in 0..2 * GAUSS_NODES as i32 {
            let sum: f64 = gauss_legendre_unit().iter().map(|&(x, w)| w as f64 * (x as f64).powi(degree)).sum();
            assert!((sum - 1.0 / (degree + 1) as f64).abs() < 1e-6, "x^{degree}: {sum}");
        }
        let profiles = [DiffuseProfile::Flat, DiffuseProfile::Coupled(1.5, 0.0), DiffuseProfile::Coupled(1.3, 0.7)];
        for c in coats() {
            for p in profiles {
                let n = 20_000;
                let (mut with, mut bare) = (0.0f64, 0.0f64);
                for k in 0..n {
                    let mu = (k as f32 + 0.5) / n as f32;
                    let g = (p.at(mu) * mu) as f64;
                    with += g * c.iter().filter(|c| c.is_reciprocal()).map(|c| c.through(mu) as f64).product::<f64>();
                    bare += g;
                }
                let (fine, quick) = (bare / with, p.coat_norm(c.iter()) as f64);
                assert!((fine - quick).abs() < 1e-4 * fine, "{c:?} over {p:?}: {quick} against {fine}");
            }
        }
    }

    /// Extreme coats over extreme diffuse lobes: the renormalisation stays finite, never below 1
    /// (a coat only takes), and the coated BSDF's values stay finite and non-negative at
    /// grazing views and lights. The worst case is a coat reflecting nearly everything: an
    /// index-3 dielectric at roughness 0 over a coupled lobe of index 3.
    #[test]
    fn renormalisation_stays_finite_at_the_extremes() {
        let mut coats = vec![];
        for eta in [1.0f32, 1.001, 1.5, 3.0] {
            for r in [0.0f32, 1e-4, 0.5, 1.0] {
                for w in [0.0f32, 1e-6, 1.0] {
                    coats.push(Coat::Dielectric(DielectricCoat::new(w, eta, r, Vec3::new(1.0, 0.0, 0.5), 2.0)));
                }
            }
        }
        coats.extend([0.0f32, 0.07, 1.0].map(|r| Coat::Sheen(CharlieSheen::new(Vec3::ONE, r))));
        coats.extend([0.0f32, 1.0].map(|g| Coat::Disney(Clearcoat::new(1.0, g))));
        let profiles =
            [DiffuseProfile::Flat, DiffuseProfile::Coupled(1.0, 0.0), DiffuseProfile::Coupled(3.0, 0.0), DiffuseProfile::Coupled(1.5, 1.0)];
        let directions = [Vec3::Z, Vec3::new(1.0, 0.0, 1e-6).normalize(), Vec3::new(0.6, 0.0, 0.8), Vec3::new(-1.0, 0.0, 1e-4).normalize()];
        for c in &coats {
            for p in profiles {
                let norm = p.coat_norm(std::iter::once(c));
                assert!(norm.is_finite() && norm >= 1.0 - 1e-4, "{c:?} over {p:?}: 1/K = {norm}");
                let mut b = Bsdf::default();
                b.push(match p {
                    DiffuseProfile::Flat => Lobe::Lambert(Lambert { r: Vec3::ONE }),
                    DiffuseProfile::Coupled(eta, r) => Lobe::DisneyDiffuse(DisneyDiffuse::new(Vec3::ONE, 0.5, 0.0, Some((eta, r)), true)),
                });
                b.coat_with(*c, true);
                for wo in directions {
                    b.prepare(wo);
                    for wi in directions {
                        let f = b.eval(wo, wi);
                        assert!(crate::math::is_finite(f) && f.min_element() >= 0.0, "{c:?} over {p:?}, {wo:?} -> {wi:?}: {f:?}");
                    }
                }
            }
        }
    }

    /// UsdPreviewSurface's diffuse (coupled to its specular) under a clear dielectric coat: the
    /// base is renormalised too, and reflects exactly what the coat lets through of what it
    /// reflected bare. Measured within 7e-4 at every view; by the min rule alone it fell 0.035
    /// short head-on.
    #[test]
    fn a_coupled_diffuse_under_a_clearcoat_keeps_what_the_coat_lets_through() {
        let diffuse = Lobe::DisneyDiffuse(DisneyDiffuse::new(Vec3::ONE, 0.5, 0.0, Some((1.5, 0.3)), true));
        let coat = Coat::Dielectric(DielectricCoat::new(1.0, 1.6, 0.3, Vec3::ONE, 0.0));
        let mut b = Bsdf::default();
        b.push(diffuse);
        b.coat_with(coat, true);
        let mut base = Bsdf::default();
        base.push(diffuse);
        for wo in testing::probe_directions().into_iter().filter(|w| w.z >= 1e-2) {
            let (a, bare) = (testing::albedo_estimate(&b, wo, 40_000).x, testing::albedo_estimate(&base, wo, 40_000).x);
            let (coat_alone, through) = (testing::albedo_estimate(&coat.lobe(true).0, wo, 40_000).x, coat.through(wo.z));
            let want = coat_alone + through * bare;
            assert!((a - want).abs() < 3e-3, "at {wo:?}: {a} against {want} (bare {bare}, coat {coat_alone}, through {through})");
        }
    }

    /// Reciprocal where the coat is: the fuzz's own lobe is not (an LTC fitted per view), so
    /// its layering keeps the base reciprocal but not the sum.
    #[test]
    fn coated_bsdfs_are_reciprocal_and_sample_their_pdf() {
        for (k, c) in coats().into_iter().enumerate() {
            let b = coated(&c);
            if !c.iter().any(|c| matches!(c, Coat::Fuzz(_))) {
                testing::assert_reciprocal(&b);
            }
            testing::assert_weights_consistent(&b);
            testing::assert_chi2_at(&b, 950 + k as u64, testing::probe_directions().into_iter().filter(|w| w.z >= 1e-2).collect());
        }
    }

    /// A white fuzz over a white Lambertian base reflects all the light at every view: its
    /// lobe reflects R(μo) and the base keeps 1 − R(μo). 100 000 samples hold the estimate to
    /// 5e-3 (the fuzz's weights are R, the base's 1 − R... each below 1).
    #[test]
    fn a_white_fuzz_over_white_reflects_everything() {
        for alpha in [0.2f32, 0.5, 1.0] {
            let b = coated(&[Coat::Fuzz(Fuzz::new(Vec3::ONE, alpha))]);
            for mu in [1.0f32, 0.5, 0.1, 0.02] {
                let a = testing::albedo_estimate(&b, Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu), 100_000).x;
                assert!((a - 1.0).abs() < 5e-3, "α {alpha} μ {mu}: {a}");
            }
        }
    }

    #[test]
    fn absorption_tints_a_head_on_round_trip_by_the_colour() {
        let color = Vec3::new(0.9, 0.5, 0.2);
        let d = DielectricCoat::new(1.0, 1.5, 0.0, color, 1.0);
        let t = d.transmittance(1.0) * d.transmittance(1.0);
        assert!((t - color).abs().max_element() < 1e-5, "{t:?}");
        // Longer paths at grazing angles saturate the colour further.
        let g = d.transmittance(0.1) * d.transmittance(0.1);
        assert!(g.z < color.z && g.x < color.x);
        // Thickness 0 is clear whatever the colour.
        assert_eq!(DielectricCoat::new(1.0, 1.5, 0.0, color, 0.0).transmittance(0.3), Vec3::ONE);
    }
}
