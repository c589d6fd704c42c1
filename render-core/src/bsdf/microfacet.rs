//! The anisotropic GGX (GTR2) microfacet distribution with Heitz's Smith masking-shadowing
//! and sampling of the distribution of visible normals; GTR1 for the Disney clearcoat.
//!
//! Sources: Burley 2012 ("Physically Based Shading at Disney", section 5.4: GTR, α = roughness²), Schutte 2018
//! ("Rendering the Moana Island Scene Part 1: Implementing the Disney BSDF", "Specular BRDF": the anisotropic mapping and Heitz's anisotropic Λ), Heitz,
//! "Understanding the Masking-Shadowing Function", JCGT 2014 (height-correlated G2), and
//! Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 2018.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Below this α the surface is a perfect mirror: pbrt-v4's `EffectivelySmooth` threshold.
/// D and its pdf overflow f32 long before α reaches 0, so such lobes become deltas.
pub const SMOOTH_ALPHA: f32 = 1e-3;
/// Floor of each α of a rough lobe, so an anisotropic lobe thin in one direction stays
/// finite (α² = 1e-8 keeps m²/α² far from f32 overflow).
pub const MIN_ALPHA: f32 = 1e-4;

/// Anisotropic GGX with roughness along the local x (`ax`) and y (`ay`) axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// α along the tangent.
    pub ax: f32,
    /// α along the bitangent.
    pub ay: f32,
}

impl Ggx {
    /// Disney's mapping (Schutte, "Specular BRDF"): aspect = sqrt(1 − 0.9·anisotropic),
    /// αx = roughness²/aspect, αy = roughness²·aspect. `anisotropic` is clamped to [−1, 1].
    pub fn from_roughness(roughness: f32, anisotropic: f32) -> Self {
        let r = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
        let aniso = if anisotropic.is_finite() { anisotropic.clamp(-1.0, 1.0) } else { 0.0 };
        let aspect = (1.0 - 0.9 * aniso).sqrt();
        Ggx { ax: r * r / aspect, ay: r * r * aspect }
    }

    /// True when the lobe is a mirror (a delta).
    pub fn is_smooth(&self) -> bool {
        self.ax.max(self.ay) < SMOOTH_ALPHA
    }

    /// The same lobe with each α floored at [`MIN_ALPHA`].
    pub fn regularized(&self) -> Self {
        Ggx { ax: self.ax.max(MIN_ALPHA), ay: self.ay.max(MIN_ALPHA) }
    }

    /// D(m): normal distribution, for a microfacet normal in the local frame.
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let t = (m.x / self.ax).powi(2) + (m.y / self.ay).powi(2) + m.z * m.z;
        1.0 / (PI * self.ax * self.ay * t * t)
    }

    /// Smith Λ(w) for anisotropic GGX.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        let a2t2 = ((self.ax * w.x).powi(2) + (self.ay * w.y).powi(2)) / z2;
        0.5 * (-1.0 + (1.0 + a2t2).sqrt())
    }

    /// G1(w) = 1/(1 + Λ(w)).
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing G2 = 1/(1 + Λ(wo) + Λ(wi)).
    #[inline]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals seen from `wo`: G1(wo)·max(0, wo·m)·D(m)/|wo.z|.
    #[inline]
    pub fn d_visible(&self, wo: Vec3, m: Vec3) -> f32 {
        let cos_o = wo.z.abs();
        if cos_o == 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(m).max(0.0) * self.d(m) / cos_o
    }

    /// Samples a visible normal for `wo` in the upper hemisphere (Heitz 2018).
    #[inline]
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        // Stretch to the hemisphere configuration.
        let vh = Vec3::new(self.ax * wo.x, self.ay * wo.y, wo.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Unstretch.
        Vec3::new(self.ax * nh.x, self.ay * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// Burley's GTR1 distribution (Burley 2012, "Physically Based Shading at Disney", section 5.4), used by the Disney clearcoat, for a
/// unit microfacet normal `h` in the local frame. The denominator 1 + (α² − 1)cos²θ is formed
/// as sin²θ + α²cos²θ from h's components: computed from cos θ in f32 it cancels near the peak
/// of a gloss-1 coat (α² = 1e-6) and D came out up to 6% off there.
#[inline]
pub fn gtr1_d(h: Vec3, alpha: f32) -> f32 {
    if alpha >= 1.0 {
        return 1.0 / PI;
    }
    let a2 = alpha * alpha;
    let t = h.x * h.x + h.y * h.y + a2 * h.z * h.z;
    (a2 - 1.0) / (PI * a2.ln() * t)
}

/// Mirror `w` about `m`.
#[inline]
pub fn reflect(w: Vec3, m: Vec3) -> Vec3 {
    2.0 * w.dot(m) * m - w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Pcg32, uniform_sphere};

    #[test]
    fn d_is_normalised_projected_area() {
        // ∫ D(m) m.z dm = 1 over the hemisphere.
        for g in [Ggx { ax: 0.3, ay: 0.3 }, Ggx { ax: 0.1, ay: 0.6 }, Ggx { ax: 1.0, ay: 1.0 }] {
            let mut rng = Pcg32::new(1, 1);
            let n = 400_000;
            let mut acc = 0.0f64;
            for _ in 0..n {
                let m = uniform_sphere(rng.next_2d());
                acc += (g.d(m) * m.z.max(0.0)) as f64 * 4.0 * std::f64::consts::PI;
            }
            assert!((acc / n as f64 - 1.0).abs() < 0.03, "{g:?}: {}", acc / n as f64);
        }
    }

    #[test]
    fn visible_normals_integrate_to_one() {
        // ∫ D_wo(m) dm = 1 for any wo: the VNDF is a density.
        let g = Ggx { ax: 0.5, ay: 0.2 };
        let wo = Vec3::new(0.6, 0.3, 0.74).normalize();
        let mut rng = Pcg32::new(2, 2);
        let n = 400_000;
        let mut acc = 0.0f64;
        for _ in 0..n {
            let m = uniform_sphere(rng.next_2d());
            acc += g.d_visible(wo, m) as f64 * 4.0 * std::f64::consts::PI;
        }
        assert!((acc / n as f64 - 1.0).abs() < 0.02, "{}", acc / n as f64);
    }

    #[test]
    fn disney_anisotropic_mapping() {
        let g = Ggx::from_roughness(0.5, 0.0);
        assert_eq!((g.ax, g.ay), (0.25, 0.25));
        let g = Ggx::from_roughness(0.5, 1.0);
        let aspect = 0.1f32.sqrt();
        assert!((g.ax - 0.25 / aspect).abs() < 1e-6 && (g.ay - 0.25 * aspect).abs() < 1e-6);
        assert!(Ggx::from_roughness(0.0, 0.0).is_smooth());
        assert!(Ggx::from_roughness(1e-4, 0.0).is_smooth());
        assert!(!Ggx::from_roughness(0.1, 0.0).is_smooth());
    }

    #[test]
    fn gtr1_is_normalised() {
        for alpha in [0.001f32, 0.1, 0.5] {
            // ∫ D(θ) cos θ dω = 2π ∫ D(c) c dc over c in [0, 1]; the peak at c = 1 has width
            // ~α², so integrate in u = 1 − c² on a logarithmic grid (c dc = −du/2).
            let n = 200_000;
            let mut acc = 0.0f64;
            let (lo, hi) = (1e-12f64.ln(), 0.0f64);
            for i in 0..n {
                let t = lo + (hi - lo) * (i as f64 + 0.5) / n as f64;
                let u = t.exp();
                let c = (1.0 - u).max(0.0).sqrt();
                let h = Vec3::new(u.sqrt() as f32, 0.0, c as f32);
                acc += gtr1_d(h, alpha) as f64 * 0.5 * u * (hi - lo) / n as f64;
            }
            let integral = acc * 2.0 * std::f64::consts::PI;
            assert!((integral - 1.0).abs() < 0.01, "alpha {alpha}: {integral}");
        }
    }
}
