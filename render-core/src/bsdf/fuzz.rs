//! Fuzz: the multiple-scattering sheen of Zeltner, Burley and Chiang, "Practical
//! Multiple-Scattering Sheen Using Linearly Transformed Cosines" (SIGGRAPH 2022 Talks), the
//! sheen OpenPBR Surface specifies for `fuzz` and Cycles renders for the Principled BSDF's
//! Sheen since Blender 4.0.
//!
//! The paper simulates light in a thin volumetric layer of fibres over a surface and fits,
//! for each view cosine μo and roughness α, the reflected lobe with a linearly transformed
//! cosine (LTC): a clamped cosine D_o mapped by M⁻¹ = [[a, 0, b], [0, a, 0], [0, 0, 1]] in the
//! frame whose x axis points along the view's projection on the surface. The lobe is then
//!
//!   f(wo, wi)·cos θi = R(μo, α) · D_o(M⁻¹wi / |M⁻¹wi|) · a² / |M⁻¹wi|³
//!
//! with R the layer's directional albedo. a, b and R are the authors' published closed-form
//! fits (rational for a and b, a Gaussian in μo for R), the functions MaterialX's reference
//! shaders evaluate; Cycles reads a 32 × 32 table of the same quantities. Sampling maps a
//! cosine sample through M, so `pdf` is the LTC density exactly and a sample's weight is R.
//!
//! The lobe depends on the view alone through (a, b, R): it is not reciprocal, as the paper
//! says of any LTC fit.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::{LobeFlags, LobeSample};

/// Smallest roughness the fits describe (MaterialX clamps its sampling there too); the layer
/// reflects less than 1e-4 of the light below it.
const ALPHA_MIN: f32 = 0.01;

/// A fuzz layer's lobe: colour and roughness α in [0.01, 1], on either side of the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fuzz {
    /// Colour (the layer's weight times its tint).
    pub color: Vec3,
    /// Roughness α.
    pub alpha: f32,
}

impl Fuzz {
    /// Reflection, not delta.
    pub const FLAGS: LobeFlags = LobeFlags { reflection: true, transmission: false, delta: false };

    /// A fuzz of `color` and roughness `alpha` (clamped to [0.01, 1]; NaN reads 1).
    pub fn new(color: Vec3, alpha: f32) -> Self {
        let alpha = if alpha.is_finite() { alpha.clamp(ALPHA_MIN, 1.0) } else { 1.0 };
        Fuzz { color: color.max(Vec3::ZERO), alpha }
    }

    /// f without the cosine.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// `(eval, pdf)` from one fit of the LTC at the view.
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z * wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let d = Ltc::at(wo, self.alpha).density(wi);
        let f = albedo(wo.z, self.alpha) * d / wi.z;
        (if f.is_finite() { self.color * f } else { Vec3::ZERO }, d)
    }

    /// A clamped-cosine sample mapped by M. The density is the LTC's, so the weight
    /// f·cos/pdf is colour · R(μo, α) exactly.
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let flip = if wo.z < 0.0 { -1.0 } else { 1.0 };
        let ltc = Ltc::at(wo * flip, self.alpha);
        let wi = ltc.sample(u)?;
        let pdf = ltc.density(wi);
        (pdf > 0.0).then(|| LobeSample { wi: wi * flip, weight: self.albedo(wo), pdf, flags: Self::FLAGS, eta: 1.0 })
    }

    /// The LTC density on `wo`'s side.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        Ltc::at(wo, self.alpha).density(wi)
    }

    /// colour · R(μo, α): the LTC density integrates to one.
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        self.color * albedo(wo.z.abs(), self.alpha)
    }
}

/// The fitted LTC at one view: its frame's x axis (the view's direction along the surface)
/// and the inverse matrix's entries a and b.
struct Ltc {
    x: Vec2,
    a: f32,
    b: f32,
}

impl Ltc {
    fn at(wo: Vec3, alpha: f32) -> Self {
        let mu = wo.z.clamp(0.0, 1.0);
        let along = Vec2::new(wo.x, wo.y);
        // Head-on the lobe is symmetric about the normal (b = 0): any frame does.
        let x = if along.length_squared() > 0.0 { along.normalize() } else { Vec2::X };
        Ltc { x, a: fit_a(mu, alpha), b: fit_b(mu, alpha) }
    }

    /// `w` (local shading frame) in the LTC's frame.
    fn to_frame(&self, w: Vec3) -> Vec3 {
        Vec3::new(self.x.x * w.x + self.x.y * w.y, -self.x.y * w.x + self.x.x * w.y, w.z)
    }

    /// D(w) = D_o(M⁻¹w/|M⁻¹w|)·|det M⁻¹|/|M⁻¹w|³ = cos·a²/(π·|M⁻¹w|⁴) for unit `w`.
    fn density(&self, w: Vec3) -> f32 {
        let v = self.to_frame(w);
        if v.z <= 0.0 {
            return 0.0;
        }
        let len2 = (self.a * v.x + self.b * v.z).powi(2) + (self.a * v.y).powi(2) + v.z * v.z;
        v.z * (self.a / len2).powi(2) / PI
    }

    /// A cosine-distributed direction mapped by M = (M⁻¹)⁻¹, back in the shading frame.
    fn sample(&self, u: Vec2) -> Option<Vec3> {
        let c = crate::sampling::cosine_hemisphere(u);
        let v = Vec3::new((c.x - c.z * self.b) / self.a, c.y / self.a, c.z).normalize_or_zero();
        let w = Vec3::new(self.x.x * v.x - self.x.y * v.y, self.x.y * v.x + self.x.x * v.y, v.z);
        (w.z > 0.0).then_some(w)
    }
}

/// a(μ, α), the LTC inverse's diagonal (the authors' rational fit).
fn fit_a(mu: f32, alpha: f32) -> f32 {
    (2.58126 * mu + 0.813703 * alpha) * alpha / (1.0 + 0.310327 * mu * mu + 2.60994 * mu * alpha)
}

/// b(μ, α), the LTC inverse's skew towards the view (the authors' rational fit).
fn fit_b(mu: f32, alpha: f32) -> f32 {
    let num = (1.0 - mu).max(0.0).sqrt() * (alpha - 1.0) * alpha.powi(3);
    num / (0.0000254053 + 1.71228 * mu - 1.71506 * mu * alpha + 1.34174 * alpha * alpha)
}

/// R(μ, α), the layer's directional albedo for a white fuzz (the authors' fit: a Gaussian in
/// μ whose width, centre and offset are rational in α), held within [0, 1].
pub fn albedo(mu: f32, alpha: f32) -> f32 {
    let y = alpha.clamp(ALPHA_MIN, 1.0);
    let s = y * (0.0206607 + 1.58491 * y) / (0.0379424 + y * (1.32227 + y));
    let m = y * (-0.193854 + y * (-1.14885 + y * (1.7932 - 0.95943 * y * y))) / (0.046391 + y);
    let o = y * (0.000654023 + (-0.0207818 + 0.119681 * y) * y) / (1.26264 + y * (-1.92021 + y));
    let r = (-0.5 * ((mu.clamp(0.0, 1.0) - m) / s).powi(2)).exp() / (s * (2.0 * PI).sqrt()) + o;
    r.clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lobe, testing};

    fn lobes() -> Vec<Lobe> {
        [0.05f32, 0.3, 0.5, 1.0]
            .into_iter()
            .flat_map(|a| [Lobe::Fuzz(Fuzz::new(Vec3::ONE, a)), Lobe::Fuzz(Fuzz::new(Vec3::new(0.9, 0.3, 0.1), a))])
            .collect()
    }

    testing::lobe_battery!(lobes: lobes(), chi_square: lobes(), seed: 0xf022, index_below: |_| 1.0, reciprocal: false);

    /// The LTC density integrates to one over the hemisphere, so the lobe's albedo is R: by
    /// 1 000 × 1 000 midpoints in (cos θ, φ), at views from head-on to grazing. Narrower lobes
    /// (α = 0.05 seen at grazing: 1.004 on this grid, 1.000003 on 2 000 × 2 000 in numpy)
    /// need finer cells than a test can afford; 1e-3 is the quadrature's bound here.
    #[test]
    fn the_ltc_density_is_normalised() {
        for alpha in [0.2f32, 0.5, 1.0] {
            for mu in [1.0f32, 0.6, 0.2, 0.02] {
                let ltc = Ltc::at(Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu), alpha);
                let total = testing::hemisphere_integral(1000, |w| ltc.density(w));
                assert!((total - 1.0).abs() < 1e-3, "α {alpha} μ {mu}: ∫D = {total}");
            }
        }
    }

    /// A sample's weight is R(μo, α) (pdf is the LTC density), and so is f·cos/pdf at the
    /// sampled direction: eval and pdf agree with the sampling.
    #[test]
    fn samples_weigh_the_fitted_albedo() {
        let lobe = Fuzz::new(Vec3::ONE, 0.5);
        let wo = Vec3::new(0.8, 0.0, 0.6);
        let mut rng = crate::sampling::Pcg32::new(7, 7);
        for _ in 0..1000 {
            let s = lobe.sample(wo, 0.5, rng.next_2d()).expect("a sample above the surface");
            assert!((s.weight.x - albedo(0.6, 0.5)).abs() < 1e-4 * albedo(0.6, 0.5).max(1.0), "{:?}", s.weight);
            let estimate = lobe.eval(wo, s.wi).x * s.wi.z / lobe.pdf(wo, s.wi);
            assert!((estimate - albedo(0.6, 0.5)).abs() < 1e-4, "f·cos/pdf {estimate}");
        }
    }

    /// The fit's shape, as the paper's figures show it: fuzz reflects most at grazing views
    /// (R falls as μ rises), more the rougher it is head-on, and never more than the light.
    #[test]
    fn fuzz_reflects_most_at_grazing_views() {
        for alpha in [0.3f32, 0.5, 1.0] {
            let r: Vec<f32> = (0..=20).map(|k| albedo(k as f32 / 20.0, alpha)).collect();
            assert!(r.windows(2).all(|w| w[1] <= w[0] + 1e-6), "α {alpha}: {r:?}");
            assert!(r[0] > 0.6 && r[0] < 0.8, "grazing, α {alpha}: {}", r[0]);
        }
        assert!(albedo(1.0, 1.0) > albedo(1.0, 0.5) && albedo(1.0, 0.5) > albedo(1.0, 0.3));
        for k in 0..=100 {
            for j in 0..=100 {
                let a = albedo(k as f32 / 100.0, j as f32 / 100.0);
                assert!((0.0..=1.0).contains(&a));
            }
        }
    }

    /// Extremes: grazing and head-on views, α at and beyond its range, NaN: finite.
    #[test]
    fn extremes_stay_finite() {
        for alpha in [0.0f32, 1e-6, 0.01, 1.0, 3.0, f32::NAN] {
            let lobe = Fuzz::new(Vec3::ONE, alpha);
            for wo in [Vec3::Z, Vec3::new(1.0, 0.0, 1e-7).normalize(), Vec3::new(0.0, -0.6, -0.8)] {
                for wi in testing::probe_directions() {
                    assert!(lobe.eval(wo, wi).is_finite() && lobe.pdf(wo, wi).is_finite());
                }
                let mut rng = crate::sampling::Pcg32::new(3, 1);
                for _ in 0..100 {
                    if let Some(s) = lobe.sample(wo, 0.5, rng.next_2d()) {
                        assert!(s.weight.is_finite() && s.pdf.is_finite() && s.weight.max_element() <= 1.0 + 1e-4, "{s:?}");
                    }
                }
            }
        }
    }
}
