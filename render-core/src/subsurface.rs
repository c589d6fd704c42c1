//! Subsurface scattering as a brute-force random walk (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Subsurface scattering"): a
//! homogeneous medium of constant density behind the dielectric boundary of a
//! `SolidDielectric` with `scatteringRadius` > 0, σ_t = 1/mfp and σ_s = α/mfp.
//!
//! Artists give the colour C they want to see, not the single-scattering albedo α: the slides'
//! van de Hulst inversion, s = 4.09712 + 4.20863C − √(9.59217 + 41.6808C + 17.7126C²),
//! α = (1 − s²)/(1 − g·s²), maps one to the other for a phase function of eccentricity g
//! (clamped to |g| ≤ 0.9, where the mapping stays stable, as the slides advise).
//!
//! The mean free path may differ per channel (`scatteringRadius` × `scatteringColor`), so
//! distances are sampled by one channel chosen uniformly and weighted by the average density
//! of the three (one-sample MIS over channels), which keeps every channel unbiased.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Largest |g| the albedo inversion and the phase function use.
pub const MAX_ECCENTRICITY: f32 = 0.9;

/// The slides' van de Hulst inversion: single-scattering albedo α for a visible colour `c`
/// (per channel, c clamped to [0, 0.999]) and eccentricity `g`.
pub fn albedo_from_color(c: Vec3, g: f32) -> Vec3 {
    let g = g.clamp(-MAX_ECCENTRICITY, MAX_ECCENTRICITY);
    let one = |c: f32| {
        let c = if c.is_finite() { c.clamp(0.0, 0.999) } else { 0.0 };
        let s = 4.09712 + 4.20863 * c - (9.59217 + 41.6808 * c + 17.7126 * c * c).sqrt();
        ((1.0 - s * s) / (1.0 - g * s * s)).clamp(0.0, 1.0)
    };
    Vec3::new(one(c.x), one(c.y), one(c.z))
}

/// The colour the medium itself must reflect (index-matched, as van de Hulst's formula
/// assumes) for the surface to show `color` behind a boundary of relative index `eta`.
///
/// Light that reaches the boundary from inside mostly reflects back (a share
/// 1 − F_avg(1/η) escapes: 47% at η = 1.4) and meets the medium again, so the surface shows
/// Saunderson's series t·R/(1 − (1 − t)·R) of the medium's own reflectance R, darker channels
/// losing most: without this, a medium of colour 0.5 behind IOR 1.4 rendered 0.33 in the white
/// furnace where its Lambertian counterpart renders 0.53. Solving for R keeps the colour the
/// artist set, as the slides' inversion does for an index-matched medium (Kulla & Conty 2017,
/// "Revisiting Physically Based Shading at Imageworks", "Subsurface scattering - color
/// control", which assumes a half space without a boundary).
pub fn color_under_boundary(color: Vec3, eta: f32) -> Vec3 {
    let eta = if eta.is_finite() { eta.max(1.0) } else { 1.0 };
    let t = 1.0 - crate::bsdf::fresnel::dielectric_avg_fit(1.0 / eta);
    let c = color.clamp(Vec3::ZERO, Vec3::splat(0.999));
    c / (Vec3::splat(t) + c * (1.0 - t))
}

/// Van de Hulst's forward formula: the colour C a semi-infinite medium of albedo α and
/// eccentricity g shows under uniform light, C = (1 − s)(1 − 0.139s)/(1 + 1.17s),
/// s = √((1 − α)/(1 − αg)).
pub fn color_from_albedo(alpha: f32, g: f32) -> f32 {
    let s = ((1.0 - alpha) / (1.0 - alpha * g)).max(0.0).sqrt();
    (1.0 - s) * (1.0 - 0.139 * s) / (1.0 + 1.17 * s)
}

/// A homogeneous scattering medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Medium {
    /// Extinction per channel (1/mfp).
    pub sigma_t: Vec3,
    /// Single-scattering albedo per channel.
    pub albedo: Vec3,
    /// Henyey-Greenstein eccentricity.
    pub g: f32,
}

/// What a step through the medium found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Scattered at distance `t`; multiply the throughput by `weight`.
    Scatter {
        /// Distance.
        t: f32,
        /// σ_s·T(t) / p(t), p averaged over channels.
        weight: Vec3,
    },
    /// Reached the surface at the distance given; multiply by `weight`.
    Surface {
        /// T(d) / P(no scattering before d), averaged over channels.
        weight: Vec3,
    },
}

impl Medium {
    /// The medium of a mean free path per channel, visible colour and eccentricity, behind a
    /// boundary of relative index `eta` (1: index-matched).
    pub fn new(mfp: Vec3, color: Vec3, g: f32, eta: f32) -> Option<Self> {
        let mfp = mfp.max(Vec3::splat(1e-9));
        (mfp.is_finite() && mfp.min_element() > 0.0).then(|| {
            let g = if g.is_finite() { g.clamp(-MAX_ECCENTRICITY, MAX_ECCENTRICITY) } else { 0.0 };
            Medium { sigma_t: mfp.recip(), albedo: albedo_from_color(color_under_boundary(color, eta), g), g }
        })
    }

    /// Steps along a ray whose surface lies at distance `d` (∞ if none): `u_channel` picks the
    /// channel whose extinction samples the distance, `u` the distance.
    pub fn step(&self, d: f32, u_channel: f32, u: f32) -> Step {
        let c = ((u_channel * 3.0) as usize).min(2);
        let t = -(1.0 - u).max(1e-12).ln() / self.sigma_t[c];
        if t < d {
            let tr = (-self.sigma_t * t).exp();
            let pdf = (self.sigma_t * tr).element_sum() / 3.0;
            Step::Scatter { t, weight: self.albedo * self.sigma_t * tr / pdf.max(1e-30) }
        } else {
            let tr = (-self.sigma_t * d).exp();
            let p = tr.element_sum() / 3.0;
            Step::Surface { weight: if p > 0.0 { tr / p } else { Vec3::ZERO } }
        }
    }

    /// Transmittance along a straight segment of length `d`, e^(−σ_t d) per channel.
    pub fn transmittance(&self, d: f32) -> Vec3 {
        (-self.sigma_t * d.max(0.0)).exp()
    }

    /// Samples a new direction after scattering of a ray travelling along `dir`
    /// (Henyey-Greenstein by inversion; g > 0 scatters forward, along `dir`).
    pub fn sample_phase(&self, dir: Vec3, u: Vec2) -> Vec3 {
        let g = self.g;
        let cos = if g.abs() < 1e-3 {
            1.0 - 2.0 * u.x
        } else {
            let sq = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
            (1.0 + g * g - sq * sq) / (2.0 * g)
        }
        .clamp(-1.0, 1.0);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let frame = crate::math::Frame::from_normal(dir);
        frame.to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos)).normalize()
    }

    /// The phase function's density for scattering from `dir` into `wi`.
    pub fn phase_pdf(&self, dir: Vec3, wi: Vec3) -> f32 {
        let cos = dir.dot(wi);
        let denom = 1.0 + self.g * self.g - 2.0 * self.g * cos;
        (1.0 - self.g * self.g) / (4.0 * PI * denom * denom.max(1e-12).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    /// Saunderson's series of the medium's reflectance behind the boundary gives back the
    /// colour asked for, for several indices; non-finite input stays finite.
    #[test]
    fn the_boundary_term_returns_the_colour_asked_for() {
        // Index-matched: nothing to undo.
        let c = Vec3::new(0.8, 0.45, 0.3);
        assert_eq!(color_under_boundary(c, 1.0), c);
        for eta in [1.1, 1.4, 2.0, 3.0] {
            let t = 1.0 - crate::bsdf::fresnel::dielectric_avg_fit(1.0 / eta);
            let r = color_under_boundary(c, eta);
            // Saunderson's series of the medium's reflectance gives back the colour, and the
            // medium must reflect more than the surface shows, most for the darkest channel.
            let shown = t * r / (Vec3::ONE - (1.0 - t) * r);
            assert!((shown - c).abs().max_element() < 1e-5, "η {eta}: {shown} against {c}");
            assert!(r.cmpgt(c).all() && (r / c).z > (r / c).x, "η {eta}: {r}");
            assert!(r.cmplt(Vec3::ONE).all());
        }
        for bad in [f32::NAN, f32::INFINITY, 0.5, -2.0] {
            assert!(color_under_boundary(c, bad).is_finite(), "η {bad}");
        }
        assert!(color_under_boundary(Vec3::new(f32::NAN, 2.0, -1.0), 1.4).is_finite());
    }

    /// The slides' closed form is the root of the forward formula: C → α → C round-trips,
    /// for several eccentricities.
    #[test]
    fn van_de_hulst_inversion_round_trips() {
        for g in [-0.9f32, -0.3, 0.0, 0.5, 0.9] {
            for c in [0.0f32, 0.05, 0.2, 0.5, 0.8, 0.95, 0.999] {
                let a = albedo_from_color(Vec3::splat(c), g).x;
                let back = color_from_albedo(a, g);
                assert!((back - c).abs() < 2e-3, "g {g}, C {c}: α {a}, back to {back}");
            }
        }
        // Brighter colours need a brighter albedo, and forward scattering needs more still.
        let a = |g| albedo_from_color(Vec3::splat(0.5), g).x;
        assert!(a(0.5) > a(0.0) && a(0.0) > a(-0.5));
    }

    /// Distance sampling with three different mean free paths stays unbiased per channel: the
    /// probability of crossing a slab of depth d without scattering is e^(−σ_t d) in each.
    #[test]
    fn chromatic_extinction_is_unbiased_per_channel() {
        let m = Medium { sigma_t: Vec3::new(1.0, 3.0, 10.0), albedo: Vec3::ONE, g: 0.0 };
        let d = 0.4;
        let mut rng = Pcg32::new(9, 9);
        let n = 400_000;
        let mut through = glam::DVec3::ZERO;
        for _ in 0..n {
            if let Step::Surface { weight } = m.step(d, rng.next_f32(), rng.next_f32()) {
                through += weight.as_dvec3();
            }
        }
        let got = through / n as f64;
        for c in 0..3 {
            let want = (-(m.sigma_t[c] * d) as f64).exp();
            assert!((got[c] - want).abs() < 0.01 * want + 1e-3, "channel {c}: {} vs {want}", got[c]);
        }
    }

    /// Henyey-Greenstein sampling has mean cosine g and matches its pdf in a histogram.
    #[test]
    fn phase_sampling_matches_its_density() {
        for g in [-0.6f32, 0.0, 0.8] {
            let m = Medium { sigma_t: Vec3::ONE, albedo: Vec3::ONE, g };
            let dir = Vec3::new(0.3, -0.5, 0.81).normalize();
            let mut rng = Pcg32::new(1, 2);
            let n = 200_000;
            let mut mean = 0.0f64;
            let mut bins = [0u32; 10];
            for _ in 0..n {
                let w = m.sample_phase(dir, rng.next_2d());
                let cos = dir.dot(w);
                mean += cos as f64;
                bins[(((cos + 1.0) * 5.0) as usize).min(9)] += 1;
            }
            assert!((mean / n as f64 - g as f64).abs() < 0.01, "g {g}: mean cosine {}", mean / n as f64);
            for (k, &count) in bins.iter().enumerate() {
                // Expected share of the bin: ∫ p dω over its cosine band, by the midpoint rule.
                let (lo, hi) = (k as f32 / 5.0 - 1.0, (k + 1) as f32 / 5.0 - 1.0);
                let expected: f32 = (0..100)
                    .map(|j| lo + (hi - lo) * (j as f32 + 0.5) / 100.0)
                    .map(|c| {
                        let w = crate::math::Frame::from_normal(dir).to_world(Vec3::new((1.0 - c * c).sqrt(), 0.0, c));
                        m.phase_pdf(dir, w) * 2.0 * PI * (hi - lo) / 100.0
                    })
                    .sum();
                let got = count as f32 / n as f32;
                assert!((got - expected).abs() < 0.01 + 0.03 * expected, "g {g}, bin {k}: {got} vs {expected}");
            }
        }
    }
}
