//! The colour of a black body: UsdLux's `colorTemperature`, as linear Rec. 709 RGB of
//! luminance 1 (what `UsdLuxBlackbodyTemperatureAsRgb` returns), so switching a light's
//! colour temperature on changes its colour and never its brightness.
//!
//! Planck's law integrated against the CIE 1931 2° colour-matching functions (the
//! multi-lobe Gaussian fit of Wyman, Sloan & Shirley, "Simple Analytic Approximations to the
//! CIE XYZ Color Matching Functions", JCGT 2013) from 360 to 830 nm in 1 nm steps, then XYZ
//! to linear sRGB/Rec. 709, negative components clamped to 0. Temperatures are clamped to
//! [1000 K, 10000 K] as usd-core clamps them. Against usd-core's table: within 1.1% from
//! 2700 K up, 3.7% at 1000 K (measured by `tests/tests/usd.rs`).

use glam::{DVec3, Vec3};

/// Linear Rec. 709 RGB of luminance 1 for a black body at `kelvin`.
pub fn blackbody_rgb(kelvin: f32) -> Vec3 {
    let t = if kelvin.is_finite() { kelvin.clamp(1000.0, 10000.0) as f64 } else { 6500.0 };
    let mut xyz = DVec3::ZERO;
    for nm in 360..=830 {
        let l = nm as f64;
        xyz += planck(l, t) * cie_1931(l);
    }
    let rgb = DVec3::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266_0 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556_0 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
    .max(DVec3::ZERO);
    let luminance = 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
    (rgb / luminance).as_vec3()
}

/// Spectral radiance up to a constant factor (it cancels in the normalisation).
fn planck(nm: f64, kelvin: f64) -> f64 {
    let m = nm * 1e-9;
    // c2 = hc/k in m·K.
    1.0 / (m.powi(5) * ((1.438_776_877e-2 / (m * kelvin)).exp() - 1.0))
}

/// Wyman et al.'s piecewise-Gaussian fit of the CIE 1931 x̄, ȳ, z̄.
pub(crate) fn cie_1931(nm: f64) -> DVec3 {
    let g = |mu: f64, s1: f64, s2: f64| {
        let t = (nm - mu) / if nm < mu { s1 } else { s2 };
        (-0.5 * t * t).exp()
    };
    DVec3::new(
        1.056 * g(599.8, 37.9, 31.0) + 0.362 * g(442.0, 16.0, 26.7) - 0.065 * g(501.1, 20.4, 26.2),
        0.821 * g(568.8, 46.9, 40.5) + 0.286 * g(530.9, 16.3, 31.1),
        1.217 * g(437.0, 11.8, 36.0) + 0.681 * g(459.0, 26.0, 13.8),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luminance_is_one_and_colour_runs_from_red_to_blue() {
        let mut last_ratio = f32::INFINITY;
        for k in [1000.0, 2000.0, 2700.0, 4000.0, 6500.0, 10000.0] {
            let c = blackbody_rgb(k);
            let y = 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
            assert!((y - 1.0).abs() < 1e-5, "{k} K: luminance {y}");
            // Cooler is redder: R/B falls monotonically with temperature.
            let ratio = c.x / c.z.max(1e-6);
            assert!(ratio < last_ratio, "{k} K: {c}");
            last_ratio = ratio;
        }
        // 6500 K is close to white (D65 is not exactly a black body).
        let white = blackbody_rgb(6500.0);
        assert!((white - Vec3::ONE).abs().max_element() < 0.05, "{white}");
        // Clamped like usd-core.
        assert_eq!(blackbody_rgb(20000.0), blackbody_rgb(10000.0));
    }
}
