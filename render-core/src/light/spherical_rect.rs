//! Uniform sampling of the solid angle a rectangle subtends (Ureña, Fajardo and King, "An
//! Area-Preserving Parametrization for Spherical Rectangles", EGSR 2013).
//!
//! Sampling a rect light by area gives a direction density proportional to distance² / cos
//! at the light, which strays far from what the light delivers when the light is large or
//! near: the corners of a ceiling panel are drawn as often as the part overhead. Sampling its
//! solid angle uniformly leaves only the receiver's cosine unmatched. The map from the unit
//! square to the spherical rectangle is exact (area-preserving), so the density is 1/Ω.
//!
//! Ω is the sum of four dihedral angles minus 2π, which cancels for a small or distant
//! rectangle (relative error ≈ ε·2π/Ω); that is also where area sampling is as good, so below
//! [`MIN_SOLID_ANGLE`] the caller samples by area instead, and f32 suffices.

use glam::{Vec2, Vec3};

/// Below this solid angle (sr) the f32 cancellation in Ω exceeds 1e-4 relative, and area
/// sampling is as good anyway (the rect is nearly a point).
pub const MIN_SOLID_ANGLE: f32 = 4e-3;

/// The spherical rectangle a rect `corner + s·ex + t·ey`, s, t in [0, 1], subtends from `o`.
#[derive(Clone, Copy, Debug)]
pub struct SphericalRect {
    o: Vec3,
    x: Vec3,
    y: Vec3,
    z: Vec3,
    x0: f32,
    x1: f32,
    y0: f32,
    y1: f32,
    z0: f32,
    b0: f32,
    b1: f32,
    k: f32,
    /// The solid angle.
    pub solid_angle: f32,
}

impl SphericalRect {
    /// The spherical rectangle of the rect seen from `o`; None when its edges are not
    /// perpendicular, `o` lies in its plane or the solid angle is below [`MIN_SOLID_ANGLE`].
    pub fn new(o: Vec3, corner: Vec3, ex: Vec3, ey: Vec3) -> Option<Self> {
        let (exl, eyl) = (ex.length(), ey.length());
        if !(exl > 0.0 && eyl > 0.0) || (ex.dot(ey) / (exl * eyl)).abs() > 1e-4 {
            return None;
        }
        let (x, y) = (ex / exl, ey / eyl);
        let mut z = x.cross(y);
        let d = corner - o;
        let (x0, y0, mut z0) = (d.dot(x), d.dot(y), d.dot(z));
        // The local frame puts the rect at z0 < 0.
        if z0 > 0.0 {
            z = -z;
            z0 = -z0;
        }
        if !(z0 < 0.0) {
            return None;
        }
        let (x1, y1) = (x0 + exl, y0 + eyl);
        // Normals of the four planes through o and each edge.
        let n0 = Vec3::new(0.0, z0, -y0).normalize();
        let n1 = Vec3::new(-z0, 0.0, x1).normalize();
        let n2 = Vec3::new(0.0, -z0, y1).normalize();
        let n3 = Vec3::new(z0, 0.0, -x0).normalize();
        let angle = |a: Vec3, b: Vec3| (-a.dot(b)).clamp(-1.0, 1.0).acos();
        let (g0, g1, g2, g3) = (angle(n0, n1), angle(n1, n2), angle(n2, n3), angle(n3, n0));
        let k = 2.0 * std::f32::consts::PI - g2 - g3;
        let solid_angle = g0 + g1 - k;
        (solid_angle >= MIN_SOLID_ANGLE && solid_angle.is_finite()).then_some(SphericalRect {
            o,
            x,
            y,
            z,
            x0,
            x1,
            y0,
            y1,
            z0,
            b0: n0.z,
            b1: n2.z,
            k,
            solid_angle,
        })
    }

    /// The point on the rect for `u` in the unit square; directions to it are uniform in
    /// solid angle.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let (u, v) = (u.x, u.y);
        // The horizontal coordinate: invert the area of the sub-rectangle left of xu.
        let au = u * self.solid_angle + self.k;
        let fu = (au.cos() * self.b0 - self.b1) / au.sin();
        let cu = ((fu * fu + self.b0 * self.b0).sqrt().recip().copysign(fu)).clamp(-1.0, 1.0);
        let xu = if cu.abs() < 1.0 { (-(cu * self.z0) / (1.0 - cu * cu).sqrt()).clamp(self.x0, self.x1) } else { self.x0 };
        let xu = if xu.is_finite() { xu } else { self.x0 };
        // The vertical coordinate: uniform in the sine of elevation along that column.
        let dist = (xu * xu + self.z0 * self.z0).sqrt();
        let h0 = self.y0 / (dist * dist + self.y0 * self.y0).sqrt();
        let h1 = self.y1 / (dist * dist + self.y1 * self.y1).sqrt();
        let hv = h0 + v * (h1 - h0);
        let hv2 = hv * hv;
        let yv = if hv2 < 1.0 - 1e-6 { (hv * dist / (1.0 - hv2).sqrt()).clamp(self.y0, self.y1) } else { self.y1 };
        self.o + xu * self.x + yv * self.y + self.z0 * self.z
    }

    /// The unit-square point [`Self::sample`] maps to the rect point `p` (its inverse, for the
    /// density of a warp applied before it): u is the solid angle of the sub-rectangle left
    /// of `p` over the whole, v where `p` lies between the column's sines of elevation.
    pub fn invert(&self, p: Vec3) -> Vec2 {
        let d = p - self.o;
        let (xu, yv) = (d.dot(self.x).clamp(self.x0, self.x1), d.dot(self.y).clamp(self.y0, self.y1));
        let n0 = Vec3::new(0.0, self.z0, -self.y0).normalize();
        let n1 = Vec3::new(-self.z0, 0.0, xu).normalize();
        let n2 = Vec3::new(0.0, -self.z0, self.y1).normalize();
        let angle = |a: Vec3, b: Vec3| (-a.dot(b)).clamp(-1.0, 1.0).acos();
        let left = angle(n0, n1) + angle(n1, n2) - self.k;
        let dist2 = xu * xu + self.z0 * self.z0;
        let h = |y: f32| y / (dist2 + y * y).sqrt();
        let (h0, h1) = (h(self.y0), h(self.y1));
        let v = if h1 > h0 { (h(yv) - h0) / (h1 - h0) } else { 0.5 };
        Vec2::new((left / self.solid_angle).clamp(0.0, 1.0), v.clamp(0.0, 1.0))
    }
}

/// A sample of the bilinear density over the unit square whose corner values are `w`
/// ((0, 0), (1, 0), (0, 1), (1, 1)), by inversion: y from the marginal, then x given y. pbrt-v4
/// warps rect-light samples with it to follow the receiver's cosine across the light.
pub fn sample_bilinear(u: Vec2, w: [f32; 4]) -> Vec2 {
    let y = sample_linear(u.y, w[0] + w[1], w[2] + w[3]);
    let x = sample_linear(u.x, w[0] + (w[2] - w[0]) * y, w[1] + (w[3] - w[1]) * y);
    Vec2::new(x, y)
}

/// The density of [`sample_bilinear`] at `p` (1 when every weight is 0: uniform).
pub fn bilinear_pdf(p: Vec2, w: [f32; 4]) -> f32 {
    let sum = w[0] + w[1] + w[2] + w[3];
    if sum <= 0.0 {
        return 1.0;
    }
    let (x, y) = (p.x, p.y);
    4.0 * ((1.0 - x) * (1.0 - y) * w[0] + x * (1.0 - y) * w[1] + (1.0 - x) * y * w[2] + x * y * w[3]) / sum
}

/// A sample of the density on [0, 1] linear from `a` at 0 to `b` at 1.
fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    if u == 0.0 && a == 0.0 {
        return 0.0;
    }
    let x = u * (a + b) / (a + (a * a + u * (b * b - a * a)).max(0.0).sqrt());
    x.min(1.0 - f32::EPSILON)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    /// Closed form: a w × h rectangle centred at distance d above the point subtends
    /// 4·asin(w·h / √((w² + 4d²)(h² + 4d²))).
    fn centred_solid_angle(w: f64, h: f64, d: f64) -> f64 {
        4.0 * (w * h / ((w * w + 4.0 * d * d) * (h * h + 4.0 * d * d)).sqrt()).asin()
    }

    #[test]
    fn solid_angle_matches_the_closed_form() {
        for (w, h, d) in [(1.0, 1.0, 1.0), (10.0, 10.0, 2.0), (0.3, 0.2, 3.0), (100.0, 1.0, 0.01), (0.5, 0.5, 5.0)] {
            let corner = Vec3::new(-0.5 * w as f32, -0.5 * h as f32, d as f32);
            let r = SphericalRect::new(Vec3::ZERO, corner, Vec3::X * w as f32, Vec3::Y * h as f32).unwrap();
            let expected = centred_solid_angle(w, h, d);
            assert!((r.solid_angle as f64 / expected - 1.0).abs() < 1e-4, "{w}x{h} at {d}: {} vs {expected}", r.solid_angle);
        }
    }

    /// Samples land on the rect, and the directions are uniform in solid angle: the share of
    /// samples in each cell of a 4 × 4 grid on the rect equals that cell's solid angle over
    /// the whole (chi-square over 16 cells).
    #[test]
    fn samples_are_uniform_in_solid_angle() {
        let o = Vec3::new(0.3, -0.2, 0.0);
        let (corner, ex, ey) = (Vec3::new(-2.0, -1.0, 0.7), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0));
        let r = SphericalRect::new(o, corner, ex, ey).unwrap();
        let n = 200_000;
        let mut counts = [0u32; 16];
        let mut rng = Pcg32::new(5, 1);
        for _ in 0..n {
            let q = r.sample(rng.next_2d()) - corner;
            let (s, t) = (q.x / 4.0, q.y / 3.0);
            assert!((-1e-5..=1.0 + 1e-5).contains(&s) && (-1e-5..=1.0 + 1e-5).contains(&t) && q.z.abs() < 1e-5, "off the rect: {q}");
            counts[((s * 4.0).clamp(0.0, 3.999) as usize) * 4 + (t * 4.0).clamp(0.0, 3.999) as usize] += 1;
        }
        let mut chi2 = 0.0;
        for (cell, &c) in counts.iter().enumerate() {
            let (i, j) = ((cell / 4) as f32, (cell % 4) as f32);
            let sub = SphericalRect::new(o, corner + ex * (i / 4.0) + ey * (j / 4.0), ex / 4.0, ey / 4.0).unwrap();
            let expected = n as f64 * (sub.solid_angle / r.solid_angle) as f64;
            chi2 += (c as f64 - expected).powi(2) / expected;
        }
        // 15 degrees of freedom: the 99.9th percentile is 37.7.
        assert!(chi2 < 37.7, "chi-square {chi2}: {counts:?}");
    }

    /// `invert` undoes `sample` across the square, including near its edges.
    #[test]
    fn inverting_a_sample_gives_back_its_square_point() {
        let o = Vec3::new(0.3, -0.2, 0.0);
        let r = SphericalRect::new(o, Vec3::new(-2.0, -1.0, 0.7), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0)).unwrap();
        let mut rng = Pcg32::new(8, 3);
        for k in 0..2000 {
            let u = if k < 4 { Vec2::new((k % 2) as f32 * 0.999 + 5e-4, (k / 2) as f32 * 0.999 + 5e-4) } else { rng.next_2d() };
            let back = r.invert(r.sample(u));
            assert!((back - u).abs().max_element() < 2e-3, "{u} -> {back}");
        }
    }

    /// The bilinear warp's samples follow its density: chi-square over a 4 × 4 grid against
    /// the density integrated over each cell.
    #[test]
    fn bilinear_samples_follow_their_density() {
        let w = [0.05f32, 1.0, 0.4, 2.0];
        let n = 200_000;
        let mut counts = [0u32; 16];
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..n {
            let p = sample_bilinear(rng.next_2d(), w);
            counts[((p.x * 4.0) as usize).min(3) * 4 + ((p.y * 4.0) as usize).min(3)] += 1;
        }
        let mut chi2 = 0.0;
        for (cell, &c) in counts.iter().enumerate() {
            let (i, j) = ((cell / 4) as f32, (cell % 4) as f32);
            // The density is bilinear: its mean over a cell is its value at the cell's centre.
            let expected = n as f64 * (bilinear_pdf(Vec2::new((i + 0.5) / 4.0, (j + 0.5) / 4.0), w) / 16.0) as f64;
            chi2 += (c as f64 - expected).powi(2) / expected;
        }
        assert!(chi2 < 37.7, "chi-square {chi2}: {counts:?}");
        assert_eq!(bilinear_pdf(Vec2::splat(0.3), [0.0; 4]), 1.0);
    }

    #[test]
    fn degenerate_views_are_refused_not_nan() {
        let (corner, ex, ey) = (Vec3::new(-1.0, -1.0, 0.0), Vec3::X * 2.0, Vec3::Y * 2.0);
        // In the rect's plane, skewed edges, a vanishing solid angle.
        assert!(SphericalRect::new(Vec3::new(3.0, 0.0, 0.0), corner, ex, ey).is_none());
        assert!(SphericalRect::new(Vec3::Z, corner, ex, Vec3::new(1.0, 2.0, 0.0)).is_none());
        assert!(SphericalRect::new(Vec3::new(0.0, 0.0, 1e5), corner, ex * 1e-3, ey * 1e-3).is_none());
        // Grazing and huge: finite points on the rect.
        for o in [Vec3::new(5.0, 0.0, 1e-6), Vec3::new(0.0, 0.0, 1e-7), Vec3::new(0.0, 0.0, -1e4)] {
            for (c, a, b) in [(corner, ex, ey), (corner * 1e5, ex * 1e5, ey * 1e5)] {
                let Some(r) = SphericalRect::new(o, c, a, b) else { continue };
                let mut rng = Pcg32::new(2, 2);
                for _ in 0..1000 {
                    let q = r.sample(rng.next_2d());
                    assert!(q.is_finite(), "{o} sees {q}");
                }
            }
        }
    }
}
