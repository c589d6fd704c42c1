//! Lambertian diffuse reflection: f = R/π.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use super::{LobeFlags, LobeSample};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// Ideal diffuse reflection with reflectance `r`, cosine-sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Hemispherical reflectance in [0, 1] per channel.
    pub r: Vec3,
}

impl Lambert {
    /// Reflection only, not delta.
    pub const FLAGS: LobeFlags = LobeFlags { reflection: true, transmission: false, delta: false };

    /// f(wo, wi) = R/π when both directions are above the surface.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z > 0.0 && wi.z > 0.0 { self.r * FRAC_1_PI } else { Vec3::ZERO }
    }

    /// Cosine-weighted sampling: the weight is exactly R.
    #[inline]
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = cosine_hemisphere(u);
        if wi.z <= 0.0 {
            return None;
        }
        Some(LobeSample { wi, weight: self.r, pdf: cosine_hemisphere_pdf(wi.z), flags: Self::FLAGS, eta: 1.0 })
    }

    /// cos θi / π above the surface.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z > 0.0 && wi.z > 0.0 { cosine_hemisphere_pdf(wi.z) } else { 0.0 }
    }

    /// The albedo is R at every angle.
    #[inline]
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        if wo.z > 0.0 { self.r } else { Vec3::ZERO }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lobe, testing};

    fn lobes() -> Vec<Lobe> {
        vec![Lobe::Lambert(Lambert { r: Vec3::ONE }), Lobe::Lambert(Lambert { r: Vec3::new(0.2, 0.5, 0.0) })]
    }

    testing::lobe_battery!(lobes: lobes(), chi_square: lobes(), seed: 0xc0ffee);

    #[test]
    fn white_lambert_reflects_everything() {
        let a = testing::albedo_estimate(&Lobe::Lambert(Lambert { r: Vec3::ONE }), Vec3::new(0.6, 0.0, 0.8), 100_000);
        assert!((a - Vec3::ONE).abs().max_element() < 0.01, "{a:?}");
    }

    #[test]
    fn pdf_integrates_to_one() {
        // Every cosine sample is returned, so the chi-square mass check pins the integral at 1.
        let lobe = Lobe::Lambert(Lambert { r: Vec3::ONE });
        let mut rng = crate::sampling::Pcg32::new(2, 2);
        let (n, mut acc) = (400_000, 0.0f64);
        for _ in 0..n {
            let w = crate::sampling::uniform_sphere(rng.next_2d());
            acc += lobe.pdf(Vec3::new(0.3, 0.1, 0.95).normalize(), w) as f64 * 4.0 * std::f64::consts::PI;
        }
        assert!((acc / n as f64 - 1.0).abs() < 0.01, "{}", acc / n as f64);
    }
}
