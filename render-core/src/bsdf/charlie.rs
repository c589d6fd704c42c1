//! Imageworks' "Charlie" sheen (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Sheen", "Sheen shadowing/masking function"): a
//! microfacet reflection whose normals lean towards the horizon like microcylinders standing
//! on the surface, D(m) = (2 + 1/r)·sin^(1/r)θm / 2π, with no Fresnel term and the slides'
//! fitted Λ in a height-correlated G2 = 1/(1 + Λ(μo) + Λ(μi)).
//!
//! It is a coating: its directional albedo E(r, μ), tabulated 16×16 over (r, μ) by
//! integrating the lobe itself ([`sheen_energy`]), scales the layers beneath by
//! min(1 − E(μo), 1 − E(μi)) (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Coatings"). The slides' terminator softening is
//! not used: the reciprocal variant is "too dark" and the pleasing one is not reciprocal.

use std::f32::consts::PI;
use std::sync::OnceLock;

use glam::{Vec2, Vec3};

use super::{LobeFlags, LobeSample};
use super::{energy::split_axis, lazy_rows::LazyRows};
use crate::sampling::Pcg32;

/// Smallest roughness. The Λ fit stops describing the distribution below it: measured by
/// [`sheen_albedo`], a white sheen at grazing incidence (μ = 0.01) reflects 1.92 at r = 0.01,
/// 1.27 at r = 0.03 and 0.97 at r = 0.07, so r is clamped where the lobe still conserves energy.
const R_MIN: f32 = 0.07;

/// The fit's coefficients (a, b, c, d, e) at r = 0 and r = 1 (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Sheen
/// shadowing/masking function", table).
const FIT_R0: [f32; 5] = [25.3245, 3.32435, 0.16801, -1.27393, -4.85967];
const FIT_R1: [f32; 5] = [21.5473, 3.82987, 0.19823, -1.97760, -4.32054];

/// The Charlie sheen lobe, reflection on either side of a two-sided surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CharlieSheen {
    /// Sheen colour (no Fresnel: the colour is the reflectance scale).
    pub color: Vec3,
    /// Roughness r in [0.07, 1].
    pub r: f32,
}

impl CharlieSheen {
    /// Reflection, not delta.
    pub const FLAGS: LobeFlags = LobeFlags { reflection: true, transmission: false, delta: false };

    /// A sheen of `color` and roughness `r` (clamped to [0.07, 1]; NaN reads 1).
    pub fn new(color: Vec3, r: f32) -> Self {
        let r = if r.is_finite() { r.clamp(R_MIN, 1.0) } else { 1.0 };
        CharlieSheen { color: color.max(Vec3::ZERO), r }
    }

    /// D(m) for the microfacet normal's cosine `cos_m`.
    #[inline]
    pub fn d(r: f32, cos_m: f32) -> f32 {
        let sin2 = (1.0 - cos_m * cos_m).max(0.0);
        (2.0 + 1.0 / r) * sin2.powf(0.5 / r) / (2.0 * PI)
    }

    /// The slides' Λ fit: e^L(μ) below μ = 0.5, e^(2L(0.5) − L(1 − μ)) above, L(x) =
    /// a/(1 + b·x^c) + d·x + e with coefficients interpolated by (1 − r)².
    #[inline]
    pub fn lambda(r: f32, mu: f32) -> f32 {
        let t = (1.0 - r) * (1.0 - r);
        let k: [f32; 5] = std::array::from_fn(|i| FIT_R1[i] + (FIT_R0[i] - FIT_R1[i]) * t);
        let l = |x: f32| k[0] / (1.0 + k[1] * x.powf(k[2])) + k[3] * x + k[4];
        let mu = mu.abs().min(1.0);
        if mu < 0.5 { l(mu).exp() } else { (2.0 * l(0.5) - l(1.0 - mu)).exp() }
    }

    /// f without the cosine.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let h = (wo + wi).normalize_or_zero();
        let g = 1.0 / (1.0 + Self::lambda(self.r, wo.z) + Self::lambda(self.r, wi.z));
        let f = Self::d(self.r, h.z) * g / (4.0 * wo.z * wi.z);
        if f.is_finite() { self.color * f } else { Vec3::ZERO }
    }

    /// Uniform over `wo`'s hemisphere, as the sheen's broad, horizon-leaning lobe suits
    /// better than cosine sampling (which starves the grazing directions where it peaks).
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let z = u.x;
        let s = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let wi = Vec3::new(s * phi.cos(), s * phi.sin(), if wo.z < 0.0 { -z } else { z });
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| LobeSample { wi, weight: self.eval(wo, wi) * wi.z.abs() / pdf, pdf, flags: Self::FLAGS, eta: 1.0 })
    }

    /// 1/2π on `wo`'s side.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z > 0.0 { 1.0 / (2.0 * PI) } else { 0.0 }
    }

    /// Directional albedo colour·E(r, μ) from the table.
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        self.color * sheen_energy().e(self.r, wo.z.abs())
    }
}

/// Sheen table size in roughness (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks": "a 16×16 2D table indexed by roughness and
/// incident angle").
pub const SHEEN_N: usize = 16;
/// Sheen table size in √μ: 32 rather than 16, because the sheen's albedo climbs steeply at
/// grazing angles, and with 16 nodes the under-estimate between them let a white sheen over a
/// white base reflect 1.012 at μ = 0.01 (r = 0.3).
pub const SHEEN_MU: usize = 32;

/// Directional albedo E(r, μ) of the white Charlie sheen over r = max(j/15, 0.07) and
/// √μ = i/31 (μ ≥ 1e-4), computed by stratified quadrature of the lobe.
pub struct SheenEnergy {
    /// E[r][μ], a row per roughness node, built when first read.
    e: LazyRows<[f32; SHEEN_MU]>,
}

fn sheen_r(j: usize) -> f32 {
    (j as f32 / (SHEEN_N - 1) as f32).max(R_MIN)
}

fn sheen_mu(i: usize) -> f32 {
    (i as f32 / (SHEEN_MU - 1) as f32).powi(2).max(1e-4)
}

/// E(μ) of a white sheen of roughness `r` by 96×96 jittered strata of its own sampling.
pub fn sheen_albedo(r: f32, mu: f32) -> f32 {
    let lobe = CharlieSheen::new(Vec3::ONE, r);
    let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut rng = Pcg32::new(0x5eed, (r.to_bits() as u64) << 32 | mu.to_bits() as u64);
    const S: u32 = 96;
    let mut acc = 0.0f64;
    for a in 0..S {
        for b in 0..S {
            let u = Vec2::new((a as f32 + rng.next_f32()) / S as f32, (b as f32 + rng.next_f32()) / S as f32);
            if let Some(s) = lobe.sample(wo, 0.5, u) {
                acc += s.weight.x as f64;
            }
        }
    }
    (acc / (S * S) as f64) as f32
}

impl SheenEnergy {
    fn new() -> Self {
        SheenEnergy { e: LazyRows::new(SHEEN_N, Self::row) }
    }

    fn row(j: usize) -> [f32; SHEEN_MU] {
        let _span = tracing::debug_span!("sheen_energy_row", j).entered();
        std::array::from_fn(|i| sheen_albedo(sheen_r(j), sheen_mu(i)))
    }

    /// E(r, μ), bilinear in (r, √μ).
    pub fn e(&self, r: f32, mu: f32) -> f32 {
        let rows = split_axis(r, SHEEN_N);
        let cols = split_axis(mu.clamp(0.0, 1.0).sqrt(), SHEEN_MU);
        rows.iter().flat_map(|&(j, wj)| cols.iter().map(move |&(i, wi)| (j, i, wj * wi))).map(|(j, i, w)| w * self.e.row(j)[i]).sum()
    }
}

/// The sheen table, each row computed on first use by materials with a Charlie sheen.
pub fn sheen_energy() -> &'static SheenEnergy {
    static TABLE: OnceLock<SheenEnergy> = OnceLock::new();
    TABLE.get_or_init(SheenEnergy::new)
}

/// Builds every row of the sheen table.
pub(super) fn build_sheen_energy() {
    sheen_energy().e.build_all();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lobe, testing};

    fn lobes() -> Vec<Lobe> {
        [R_MIN, 0.1, 0.3, 0.6, 1.0].iter().map(|&r| Lobe::CharlieSheen(CharlieSheen::new(Vec3::ONE, r))).collect()
    }

    testing::lobe_battery!(lobes: lobes(), chi_square: lobes(), seed: 900);

    /// Λ by integrating the distribution: 1 + Λ(w) = ∫⟨w, m⟩₊ D(m) dm / μ (Smith's
    /// projected-area identity), on a fine (θm, φm) midpoint grid.
    fn lambda_numeric(r: f32, mu: f32) -> f64 {
        let w = glam::DVec3::new((1.0 - (mu as f64).powi(2)).sqrt(), 0.0, mu as f64);
        let (nt, np) = (2000, 400);
        let mut acc = 0.0;
        for a in 0..nt {
            let t = (a as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
            let d = CharlieSheen::d(r, t.cos() as f32) as f64;
            for b in 0..np {
                let p = (b as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
                let m = glam::DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                acc += w.dot(m).max(0.0) * d * t.sin();
            }
        }
        acc * (std::f64::consts::FRAC_PI_2 / nt as f64) * (2.0 * std::f64::consts::PI / np as f64) / mu as f64 - 1.0
    }

    #[test]
    fn distribution_is_normalised_and_the_lambda_fit_follows_it() {
        for r in [0.1f32, 0.5, 1.0] {
            // ∫ D(m) cos θm dm = 1.
            let n = 20_000;
            let norm: f64 = (0..n)
                .map(|k| {
                    let t = (k as f64 + 0.5) / n as f64 * std::f64::consts::FRAC_PI_2;
                    CharlieSheen::d(r, t.cos() as f32) as f64 * t.cos() * t.sin()
                })
                .sum::<f64>()
                * std::f64::consts::FRAC_PI_2
                / n as f64
                * 2.0
                * std::f64::consts::PI;
            assert!((norm - 1.0).abs() < 1e-3, "r {r}: ∫D cos = {norm}");
            // The fit reproduces the integrated Λ where it matters for G: 1/(1 + Λ) within
            // 0.02 from μ = 0.1 up.
            for mu in [0.1f32, 0.3, 0.5, 0.8, 1.0] {
                let (fit, num) = (CharlieSheen::lambda(r, mu) as f64, lambda_numeric(r, mu));
                assert!((1.0 / (1.0 + fit) - 1.0 / (1.0 + num)).abs() < 0.02, "r {r}, μ {mu}: fit Λ {fit}, integrated {num}");
            }
        }
    }

    #[test]
    fn table_matches_the_lobe_and_lies_in_zero_one() {
        let t = sheen_energy();
        for j in 0..SHEEN_N {
            for i in 0..SHEEN_MU {
                let e = t.e.row(j)[i];
                assert!((0.0..=1.0).contains(&e), "E[{j}][{i}] = {e}");
            }
        }
        // Between the nodes the bilinear table stays within 0.01 of a fresh quadrature.
        for (r, mu) in [(0.23f32, 0.37f32), (0.55, 0.05), (0.9, 0.8)] {
            let (table, direct) = (t.e(r, mu), sheen_albedo(r, mu));
            assert!((table - direct).abs() < 0.01, "r {r}, μ {mu}: table {table}, direct {direct}");
        }
    }

    #[test]
    fn finite_at_extreme_parameters() {
        for r in [0.0, 1e-7, f32::NAN, 1.0, 7.0] {
            let l = CharlieSheen::new(Vec3::ONE, r);
            for wo in testing::probe_directions() {
                for wi in [Vec3::Z, Vec3::new(1.0, 0.0, 1e-6).normalize(), -wo, Vec3::new(-wo.x, -wo.y, wo.z)] {
                    assert!(crate::math::is_finite(l.eval(wo, wi)) && l.pdf(wo, wi).is_finite());
                }
                assert!(crate::math::is_finite(l.albedo(wo)));
            }
        }
    }
}
