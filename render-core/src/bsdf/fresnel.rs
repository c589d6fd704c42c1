//! Fresnel reflectance: exact dielectric, Schlick, conductors through Gulbrandsen's
//! reflectivity / edge-tint parameterization, the artistic (r, g, p) form, and the
//! hemispherical averages F_avg that energy compensation needs.
//!
//! Sources: Kulla & Conty 2017 ("Revisiting Physically Based Shading at Imageworks", "Microfacet energy compensation - Fresnel": the
//! exact dielectric formula, the F_avg fits and their stated maximum errors, the artistic
//! form and its closed-form average); Gulbrandsen, "Artist Friendly Metallic Fresnel", JCGT
//! 2014 (r, g → n, k); Burley 2012 ("Physically Based Shading at Disney", section 5.5, Schlick).

use glam::Vec3;

/// Exact unpolarised Fresnel reflectance of a dielectric interface for the cosine `cos_i`
/// of the incident direction and relative IOR `eta` (transmitted over incident side).
/// Total internal reflection returns 1. The form is Kulla & Conty's (slide "Dielectric
/// Fresnel"), with g² = η² + μ² − 1.
#[inline]
pub fn dielectric(cos_i: f32, eta: f32) -> f32 {
    dielectric_f64(cos_i as f64, eta as f64) as f32
}

/// [`dielectric`] in f64: evaluations that must be reciprocal to 1e-4 near the critical angle,
/// where F is steep, call it directly.
#[inline]
pub fn dielectric_f64(cos_i: f64, eta: f64) -> f64 {
    let mu = cos_i.abs().min(1.0);
    let g2 = eta * eta + mu * mu - 1.0;
    if g2 <= 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - mu) / (g + mu);
    let b = (mu * (g + mu) - 1.0) / (mu * (g - mu) + 1.0);
    (0.5 * a * a * (1.0 + b * b)).clamp(0.0, 1.0)
}

/// Schlick's approximation F0 + (1 − F0)(1 − μ)⁵ (Burley 2012, section 5.5).
#[inline]
pub fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos.abs().min(1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

/// Schlick's F0 of a dielectric of relative IOR `eta`.
#[inline]
pub fn f0_from_ior(eta: f32) -> f32 {
    ((eta - 1.0) / (eta + 1.0)).powi(2)
}

/// A complex number, for conductor Fresnel.
#[derive(Clone, Copy, Debug)]
struct C {
    re: f32,
    im: f32,
}

impl C {
    fn add(self, o: C) -> C {
        C { re: self.re + o.re, im: self.im + o.im }
    }
    fn sub(self, o: C) -> C {
        C { re: self.re - o.re, im: self.im - o.im }
    }
    fn mul(self, o: C) -> C {
        C { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
    fn div(self, o: C) -> C {
        let d = o.re * o.re + o.im * o.im;
        C { re: (self.re * o.re + self.im * o.im) / d, im: (self.im * o.re - self.re * o.im) / d }
    }
    fn norm(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    fn sqrt(self) -> C {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return C { re: 0.0, im: 0.0 };
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 { C { re: t1, im: t2 } } else { C { re: t2.abs(), im: t1.copysign(self.im) } }
    }
}

/// Fresnel reflectance of a conductor with complex IOR n + ik (one channel), as pbrt-v4's
/// `FrComplex`.
#[inline]
pub fn conductor(cos_i: f32, n: f32, k: f32) -> f32 {
    let c = cos_i.abs().clamp(0.0, 1.0);
    let eta = C { re: n, im: k };
    let sin2 = 1.0 - c * c;
    let sin2_t = C { re: sin2, im: 0.0 }.div(eta.mul(eta));
    let cos_t = C { re: 1.0, im: 0.0 }.sub(sin2_t).sqrt();
    let ci = C { re: c, im: 0.0 };
    let r_parl = eta.mul(ci).sub(cos_t).div(eta.mul(ci).add(cos_t));
    let r_perp = ci.sub(eta.mul(cos_t)).div(ci.add(eta.mul(cos_t)));
    (0.5 * (r_parl.norm() + r_perp.norm())).clamp(0.0, 1.0)
}

/// Gulbrandsen's mapping from reflectivity `r` (normal incidence colour) and edge tint `g`
/// to the complex IOR (n, k) of one channel. `r` is kept below 1 so n stays finite.
#[inline]
pub fn gulbrandsen_nk(r: f32, g: f32) -> (f32, f32) {
    let r = r.clamp(0.0, 0.9999);
    let g = g.clamp(0.0, 1.0);
    let sr = r.sqrt();
    let n = g * (1.0 - r) / (1.0 + r) + (1.0 - g) * (1.0 + sr) / (1.0 - sr);
    let k2 = (r * (n + 1.0).powi(2) - (n - 1.0).powi(2)) / (1.0 - r);
    (n, k2.max(0.0).sqrt())
}

/// Conductor reflectance from reflectivity `r` and edge tint `g` through the (n, k) above
/// and the conductor Fresnel approximation Gulbrandsen's paper uses. Kulla & Conty's F_avg fit
/// was made against this form: against it the fit's worst error is 2.4% and its mean 0.30%
/// ("~2%", "~0.25%" in the slides); against exact complex Fresnel, 10%.
#[inline]
pub fn gulbrandsen(r: Vec3, g: Vec3, cos: f32) -> Vec3 {
    let f = |r: f32, g: f32| {
        let (n, k) = gulbrandsen_nk(r, g);
        let c = cos.abs().clamp(0.0, 1.0);
        let (nk2, c2) = (n * n + k * k, c * c);
        let rs = (nk2 - 2.0 * n * c + c2) / (nk2 + 2.0 * n * c + c2);
        let rp = (nk2 * c2 - 2.0 * n * c + 1.0) / (nk2 * c2 + 2.0 * n * c + 1.0);
        (0.5 * (rs + rp)).clamp(0.0, 1.0)
    };
    Vec3::new(f(r.x, g.x), f(r.y, g.y), f(r.z, g.z))
}

/// The artistic conductor Fresnel r + (g − r)(1 − μ)^(1/p) (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Artist Friendly").
#[inline]
pub fn artistic(r: Vec3, g: Vec3, p: f32, cos: f32) -> Vec3 {
    let w = (1.0 - cos.abs().min(1.0)).powf(1.0 / p.max(1e-3));
    r + (g - r) * w
}

/// Cosine-weighted hemispherical average 2∫F(μ)μ dμ: the reference the fits are checked
/// against. Composite two-point Gauss-Legendre over 2048 panels: a single high-order rule
/// loses ~0.7% at the kink that total internal reflection puts in F for η < 1.
pub fn average(f: impl Fn(f32) -> f32) -> f32 {
    const PANELS: usize = 2048;
    let h = 1.0 / PANELS as f64;
    let off = 0.5 / 3.0f64.sqrt();
    let mut acc = 0.0f64;
    for i in 0..PANELS {
        let mid = (i as f64 + 0.5) * h;
        for x in [mid - off * h, mid + off * h] {
            acc += f(x as f32) as f64 * x;
        }
    }
    (2.0 * acc * 0.5 * h) as f32
}

/// F_avg of a dielectric: Kulla & Conty's fits (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Dielectric Fresnel"), for
/// 1 < η < 400 and 0 < η < 1, stated maximum errors ~0.65% and ~0.29%.
#[inline]
pub fn dielectric_avg_fit(eta: f32) -> f32 {
    if eta >= 1.0 {
        (eta - 1.0) / (4.08567 + 1.00071 * eta)
    } else {
        0.997118 + 0.1014 * eta - 0.965241 * eta * eta - 0.130607 * eta * eta * eta
    }
}

/// F_avg of a Gulbrandsen conductor: Kulla & Conty's fit (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Conductor Fresnel"),
/// stated maximum error ~2%, average ~0.25%.
#[inline]
pub fn gulbrandsen_avg_fit(r: Vec3, g: Vec3) -> Vec3 {
    let f = |r: f32, g: f32| {
        0.087237 + 0.0230685 * g - 0.0864902 * g * g + 0.0774594 * g * g * g + 0.782654 * r - 0.136432 * r * r
            + 0.278708 * r * r * r
            + 0.19744 * g * r
            + 0.0360605 * g * g * r
            - 0.2586 * g * r * r
    };
    Vec3::new(f(r.x, g.x), f(r.y, g.y), f(r.z, g.z)).clamp(Vec3::ZERO, Vec3::ONE)
}

/// F_avg of the artistic form, exact: (2gp² + r + 3pr)/(1 + 3p + 2p²).
#[inline]
pub fn artistic_avg(r: Vec3, g: Vec3, p: f32) -> Vec3 {
    (2.0 * g * p * p + r + 3.0 * p * r) / (1.0 + 3.0 * p + 2.0 * p * p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_matches_known_values_and_tir() {
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert_eq!(dielectric(1.0, 1.0), 0.0);
        assert!((dielectric(1e-6, 1.5) - 1.0).abs() < 1e-3, "grazing reflects everything");
        // Leaving glass: beyond the critical angle (sin θc = 1/1.5) everything reflects.
        let cos_c = (1.0f32 - (1.0 / 1.5f32).powi(2)).sqrt();
        assert_eq!(dielectric(cos_c * 0.99, 1.0 / 1.5), 1.0);
        assert!(dielectric(cos_c * 1.01, 1.0 / 1.5) < 1.0);
        // Agrees with the s/p textbook form at 45°.
        let (ci, eta) = (0.5f32.sqrt(), 1.5f32);
        let ct = (1.0 - (1.0 - ci * ci) / (eta * eta)).sqrt();
        let rs = ((ci - eta * ct) / (ci + eta * ct)).powi(2);
        let rp = ((eta * ci - ct) / (eta * ci + ct)).powi(2);
        assert!((dielectric(ci, eta) - 0.5 * (rs + rp)).abs() < 1e-6);
    }

    #[test]
    fn conductor_with_zero_k_is_the_dielectric() {
        for c in [0.1f32, 0.5, 0.9, 1.0] {
            assert!((conductor(c, 1.5, 0.0) - dielectric(c, 1.5)).abs() < 1e-5);
        }
    }

    #[test]
    fn gulbrandsen_reproduces_its_reflectivity_at_normal_incidence() {
        for r in [0.05f32, 0.5, 0.9, 0.98] {
            for g in [0.0f32, 0.5, 1.0] {
                let (n, k) = gulbrandsen_nk(r, g);
                assert!((conductor(1.0, n, k) - r).abs() < 1e-3, "exact, r={r} g={g}: {}", conductor(1.0, n, k));
                let approx = gulbrandsen(Vec3::splat(r), Vec3::splat(g), 1.0).x;
                assert!((approx - r).abs() < 1e-3, "approximate, r={r} g={g}: {approx}");
                assert!(gulbrandsen(Vec3::splat(r), Vec3::splat(g), 0.0).x > 0.999, "grazing goes to 1");
            }
        }
    }

    #[test]
    fn dielectric_avg_fits_stay_within_their_stated_errors() {
        // Stated maximum errors: ~0.65% (η > 1) and ~0.29% (η < 1), absolute in F_avg.
        let mut worst = (0.0f32, 0.0f32);
        for i in 0..400 {
            let eta = 1.0 + 0.01 * i as f32 * (1.0 + i as f32 * 0.05);
            let err = (dielectric_avg_fit(eta) - average(|mu| dielectric(mu, eta))).abs();
            worst.0 = worst.0.max(err);
        }
        for i in 1..100 {
            let eta = i as f32 / 100.0;
            let err = (dielectric_avg_fit(eta) - average(|mu| dielectric(mu, eta))).abs();
            worst.1 = worst.1.max(err);
        }
        // Stated "~0.65%" and "~0.29%". Measured: 0.652% near η = 1.2, and 0.11% near η = 0.1.
        assert!(worst.0 < 0.0066, "η > 1 fit error {}", worst.0);
        assert!(worst.1 < 0.0029, "η < 1 fit error {}", worst.1);
    }

    #[test]
    fn gulbrandsen_avg_fit_stays_within_its_stated_errors() {
        let (mut worst, mut sum, mut n) = (0.0f32, 0.0f32, 0);
        for i in 0..=20 {
            for j in 0..=20 {
                let (r, g) = (i as f32 / 20.0 * 0.99, j as f32 / 20.0);
                let exact = average(|mu| gulbrandsen(Vec3::splat(r), Vec3::splat(g), mu).x);
                let err = (gulbrandsen_avg_fit(Vec3::splat(r), Vec3::splat(g)).x - exact).abs();
                worst = worst.max(err);
                sum += err;
                n += 1;
            }
        }
        // Stated: max ~2%, average ~0.25%. Measured on this grid: 2.4% and 0.30%.
        assert!(worst < 0.025, "max error {worst}");
        assert!(sum / (n as f32) < 0.0035, "average error {}", sum / n as f32);
    }

    #[test]
    fn artistic_avg_is_exact() {
        for (r, g, p) in [(0.9f32, 0.2f32, 0.3f32), (0.1, 0.8, 1.0), (0.5, 0.5, 4.0), (0.95, 1.0, 0.05)] {
            let exact = average(|mu| artistic(Vec3::splat(r), Vec3::splat(g), p, mu).x);
            let closed = artistic_avg(Vec3::splat(r), Vec3::splat(g), p).x;
            assert!((exact - closed).abs() < 1e-4, "r={r} g={g} p={p}: {exact} vs {closed}");
        }
    }
}
