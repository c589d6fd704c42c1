//! Uniform sampling of the solid angle a triangle subtends (Arvo, "Stratified Sampling of
//! Spherical Triangles", SIGGRAPH 1995), in the form pbrt-v4 gives it (Pharr, Jakob and
//! Humphreys, "Physically Based Rendering", 4th edition, section 6.5.4, "Sampling Spherical
//! Triangles": the angle at the first vertex from normalized edge-plane normals, here as its
//! sine and cosine, and the sampled arc from the difference- and sum-of-products forms).
//!
//! An emissive triangle sampled by area gives directions a density of distance² / cos at the
//! light, far from what a large or near triangle delivers: a neon sign a hand's width in
//! front of a wall lights the wall behind it through samples whose weight swings by orders
//! of magnitude. Sampling its solid angle uniformly leaves only the receiver's cosine
//! unmatched, as for rect lights ([`super::spherical_rect`]).
//!
//! The solid angle comes from Van Oosterom and Strackee's formula ([`solid_angle`]), which
//! loses precision for a small or distant triangle; below [`MIN_SOLID_ANGLE`] the caller
//! samples by area (as good there), and above [`MAX_SOLID_ANGLE`] (a point almost on the
//! triangle's plane inside it) the arc's construction loses precision, so area sampling takes
//! over there too (pbrt-v4's bounds).

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// Below this solid angle (sr) the spherical excess cancels in f32 and area sampling is as
/// good (pbrt-v4's `MinSphericalSampleArea`).
pub const MIN_SOLID_ANGLE: f32 = 3e-4;

/// Above this solid angle (sr; a hemisphere is 2π ≈ 6.283) the arc's construction loses
/// precision (pbrt-v4's `MaxSphericalSampleArea`).
pub const MAX_SOLID_ANGLE: f32 = 6.22;

/// The spherical triangle a triangle subtends from a point.
#[derive(Clone, Copy, Debug)]
pub struct SphericalTriangle {
    /// Unit directions to the vertices.
    a: Vec3,
    b: Vec3,
    c: Vec3,
    /// Sine and cosine of the angle at `a`.
    sin_alpha: f32,
    cos_alpha: f32,
    /// α + β + γ.
    angle_sum: f32,
    /// The solid angle, α + β + γ − π.
    pub solid_angle: f32,
}

impl SphericalTriangle {
    /// The spherical triangle of `v` (of area `area`) seen from `o`; None when its solid
    /// angle is outside [[`MIN_SOLID_ANGLE`], [`MAX_SOLID_ANGLE`]] ([`solid_angle`]).
    pub fn new(o: Vec3, v: &[Vec3; 3], area: f32) -> Option<SphericalTriangle> {
        let [a, b, c] = directions(o, v, area)?;
        let solid_angle = in_range(a, b, c)?;
        // The angle at `a` between the planes of its edges, as its sine and cosine: the first
        // from the normals' cross product, accurate where the second (their dot) is not.
        let (n_ab, n_ac) = (a.cross(b).normalize_or_zero(), a.cross(c).normalize_or_zero());
        let (sin_alpha, cos_alpha) = (n_ab.cross(n_ac).length(), n_ab.dot(n_ac));
        Some(SphericalTriangle { a, b, c, sin_alpha, cos_alpha, angle_sum: solid_angle + PI, solid_angle })
    }

    /// The unit direction at `u` in [0, 1)²: uniform over the solid angle.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let (a, b, c) = (self.a, self.b, self.c);
        // The sub-triangle of area u.x · Ω: its third vertex c' lies on the arc from a to c.
        let area_pi = PI + u.x * (self.angle_sum - PI);
        let (sin_area, cos_area) = area_pi.sin_cos();
        let (sin_alpha, cos_alpha) = (self.sin_alpha, self.cos_alpha);
        let sin_phi = sin_area * cos_alpha - cos_area * sin_alpha;
        let cos_phi = cos_area * cos_alpha + sin_area * sin_alpha;
        let k1 = cos_phi + cos_alpha;
        let k2 = sin_phi - sin_alpha * a.dot(b);
        let cos_bp = (k2 + k2.mul_add(cos_phi, -k1 * sin_phi) * cos_alpha) / (k2.mul_add(sin_phi, k1 * cos_phi) * sin_alpha);
        let cos_bp = if cos_bp.is_nan() { 1.0 } else { cos_bp.clamp(-1.0, 1.0) };
        let sin_bp = (1.0 - cos_bp * cos_bp).max(0.0).sqrt();
        let cp = cos_bp * a + sin_bp * (c - c.dot(a) * a).normalize_or_zero();
        // Then the direction along the arc from b to c', uniform in the sub-triangle's area.
        let cos_theta = 1.0 - u.y * (1.0 - cp.dot(b));
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        (cos_theta * b + sin_theta * (cp - cp.dot(b) * b).normalize_or_zero()).normalize_or_zero()
    }
}

/// The solid angle of triangle `v` (of area `area`) seen from `o`, when it lies in
/// [[`MIN_SOLID_ANGLE`], [`MAX_SOLID_ANGLE`]]: the range where it is sampled by solid angle,
/// decided alike by sampling and by the density MIS asks for.
pub fn solid_angle(o: Vec3, v: &[Vec3; 3], area: f32) -> Option<f32> {
    let [a, b, c] = directions(o, v, area)?;
    in_range(a, b, c)
}

/// Unit directions from `o` to the vertices; None when the triangle is surely too small to
/// sample by solid angle: its solid angle is at most area / d², d the distance to its nearest
/// point, at least the centroid's distance less the farthest vertex's from it. Most triangles
/// of a dense emissive mesh stop here, before any square root.
fn directions(o: Vec3, v: &[Vec3; 3], area: f32) -> Option<[Vec3; 3]> {
    let centroid = (v[0] + v[1] + v[2]) / 3.0;
    let reach2 = v.iter().map(|x| (*x - centroid).length_squared()).fold(0.0f32, f32::max);
    let d2 = (o - centroid).length_squared();
    // gap = d − reach > 0 and area < MIN · gap², without a square root when d is far.
    if d2 > reach2 && area < MIN_SOLID_ANGLE * (d2.sqrt() - reach2.sqrt()).powi(2) {
        return None;
    }
    Some(v.map(|x| (x - o).normalize_or_zero()))
}

/// The solid angle of the spherical triangle of unit vectors `a`, `b`, `c` by Van Oosterom
/// and Strackee's formula ("The Solid Angle of a Plane Triangle", IEEE Trans. Biomed. Eng.
/// 30(2), 1983: one arctangent where the spherical excess needs three arcsines), when in range.
fn in_range(a: Vec3, b: Vec3, c: Vec3) -> Option<f32> {
    let omega = 2.0 * a.dot(b.cross(c)).abs().atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a));
    (MIN_SOLID_ANGLE..=MAX_SOLID_ANGLE).contains(&omega).then_some(omega)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    fn area(v: &[Vec3; 3]) -> f32 {
        0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length()
    }

    /// The solid angle by Van Oosterom and Strackee's formula, in f64.
    fn solid_angle(o: Vec3, v: &[Vec3; 3]) -> f64 {
        let [a, b, c] = v.map(|x| (x - o).as_dvec3());
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let triple = a.dot(b.cross(c)).abs();
        2.0 * triple.atan2(la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb)
    }

    /// Ω against the closed form, from near and far, and the samples uniform over it: every
    /// direction meets the triangle, and the share landing in each of four sub-triangles (its
    /// midpoint split) is the share of Ω each subtends, within the binomial noise.
    #[test]
    fn samples_cover_the_solid_angle_uniformly() {
        let v = [Vec3::new(-1.0, 0.0, 2.0), Vec3::new(2.0, -0.5, 1.5), Vec3::new(0.3, 1.5, 2.5)];
        let m = [(v[0] + v[1]) / 2.0, (v[1] + v[2]) / 2.0, (v[2] + v[0]) / 2.0];
        let parts = [[v[0], m[0], m[2]], [m[0], v[1], m[1]], [m[2], m[1], v[2]], [m[0], m[1], m[2]]];
        for o in [Vec3::ZERO, Vec3::new(0.5, 0.4, 1.9), Vec3::new(3.0, -4.0, -9.0)] {
            let st = SphericalTriangle::new(o, &v, area(&v)).expect("in range");
            let exact = solid_angle(o, &v);
            assert!((st.solid_angle as f64 / exact - 1.0).abs() < 1e-4, "{o}: {} vs {exact}", st.solid_angle);
            let (mut rng, n) = (Pcg32::new(3, 4), 200_000);
            let mut counts = [0u32; 4];
            for _ in 0..n {
                let w = st.sample(rng.next_2d());
                let inside = |t: &[Vec3; 3]| {
                    let [a, b, c] = t.map(|x| (x - o).normalize());
                    let s = [a.cross(b).dot(w), b.cross(c).dot(w), c.cross(a).dot(w)];
                    s.iter().all(|&x| x >= -1e-5) || s.iter().all(|&x| x <= 1e-5)
                };
                assert!(inside(&v), "{o}: {w} misses the triangle");
                if let Some(k) = parts.iter().position(inside) {
                    counts[k] += 1;
                }
            }
            for (k, part) in parts.iter().enumerate() {
                let share = solid_angle(o, part) / exact;
                let sigma = (share * (1.0 - share) / n as f64).sqrt();
                let got = counts[k] as f64 / n as f64;
                assert!((got - share).abs() < 5.0 * sigma, "{o}: part {k} drew {got}, subtends {share}");
            }
        }
    }

    /// Degenerate and out-of-range triangles are refused, for the caller to sample by area: a
    /// point on an edge's line, a far speck, and a point just above the triangle's middle.
    #[test]
    fn degenerate_and_extreme_triangles_are_left_to_area_sampling() {
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let at = |o: Vec3| SphericalTriangle::new(o, &v, 0.5);
        assert!(at(Vec3::new(2.0, 0.0, 0.0)).is_none(), "on an edge's line");
        assert!(at(Vec3::new(0.0, 0.0, 1e3)).is_none(), "a speck");
        assert!(at(Vec3::new(0.3, 0.3, 1e-5)).is_none(), "almost a hemisphere");
        // Just above the early bound's distance, the full computation decides alike.
        assert!(at(Vec3::new(0.3, 0.3, 38.0)).is_some() && at(Vec3::new(0.3, 0.3, 42.0)).is_none());
        let near = at(Vec3::new(0.3, 0.3, 0.05)).expect("near, in range");
        let mut rng = Pcg32::new(5, 6);
        for _ in 0..10_000 {
            let w = near.sample(rng.next_2d());
            assert!(w.is_finite() && (w.length() - 1.0).abs() < 1e-4 && w.z < 0.0, "{w}");
        }
    }
}
