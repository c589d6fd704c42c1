//! UsdGeom's implicit prims (`Sphere`, `Cube`, `Cylinder`, `Cone`, `Capsule`, `Plane`, and
//! USD 24.11's `Cylinder_1` and `Capsule_1`, whose two ends may differ in radius) tessellated
//! into triangle meshes with exact analytic normals, in the prim's own space and with the
//! schema's defaults (UsdGeom schema: radius 1, size 2, height 2, axis Z, plane width/length 2,
//! capsule radius 0.5 and height 1).
//!
//! Curved surfaces use enough segments that the silhouette is within 0.05% of the radius
//! (128 around, 64 along a half-circle), and shade with the analytic normal, so only
//! silhouettes show the tessellation.

use glam::Vec3;
use render_core::geometry::{Mesh, Normals};

/// Segments around an axis.
const AROUND: u32 = 128;
/// Segments along a half circle (pole to pole).
const ALONG: u32 = 64;

/// The parameters of an implicit prim, in its local space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// `Sphere.radius`.
    Sphere { radius: f32 },
    /// `Cube.size` (edge length).
    Cube { size: f32 },
    /// `Cylinder` with caps; `Cylinder_1` may narrow from `bottom` (at −height/2) to `top`
    /// radius, either of which may be 0.
    Cylinder { bottom: f32, top: f32, height: f32, axis: Axis },
    /// `Cone`: apex at +height/2 along the axis, base cap at −height/2.
    Cone { radius: f32, height: f32, axis: Axis },
    /// `Capsule`: a cylinder of `height` with hemispherical ends of `radius`. `Capsule_1`'s
    /// ends are spheres of radius `bottom` and `top` centred ±height/2 along the axis, joined by
    /// the cone tangent to both.
    Capsule { bottom: f32, top: f32, height: f32, axis: Axis },
    /// A flat round disc in the XY plane facing +Z (not a UsdGeom prim: `Points` with
    /// `normals` draw one per point).
    Disc { radius: f32 },
    /// `Plane`: `width` along the first other axis, `length` along the second, facing +axis.
    Plane { width: f32, length: f32, axis: Axis },
}

/// UsdGeom's `axis` token.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// "X".
    X,
    /// "Y".
    Y,
    /// "Z".
    Z,
}

impl Axis {
    /// Parses "X", "Y" or "Z".
    pub fn parse(token: &str) -> Option<Self> {
        match token {
            "X" => Some(Axis::X),
            "Y" => Some(Axis::Y),
            "Z" => Some(Axis::Z),
            _ => None,
        }
    }

    /// Maps a point built around +Z onto this axis (a cyclic permutation keeps handedness:
    /// Z-up (x, y, z) becomes X-up (z, x, y) and Y-up (y, z, x)).
    fn orient(self, v: Vec3) -> Vec3 {
        match self {
            Axis::Z => v,
            Axis::X => Vec3::new(v.z, v.x, v.y),
            Axis::Y => Vec3::new(v.y, v.z, v.x),
        }
    }
}

/// Accumulates vertices with normals and counter-clockwise (outward-facing) triangles.
#[derive(Default)]
struct Builder {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

impl Builder {
    fn vertex(&mut self, p: Vec3, n: Vec3) -> u32 {
        self.positions.push(p);
        self.normals.push(n.normalize_or_zero());
        self.positions.len() as u32 - 1
    }

    /// A grid of `rows` × `AROUND` quads from a profile: `profile(t)` gives (radius, z,
    /// normal's radial part, normal's z) for t in [0, 1] along the surface, swept about Z.
    fn revolve(&mut self, rows: u32, profile: impl Fn(f32) -> (f32, f32, f32, f32)) {
        let base = self.positions.len() as u32;
        for i in 0..=rows {
            let (r, z, nr, nz) = profile(i as f32 / rows as f32);
            for j in 0..=AROUND {
                let phi = std::f32::consts::TAU * j as f32 / AROUND as f32;
                let (s, c) = phi.sin_cos();
                self.vertex(Vec3::new(r * c, r * s, z), Vec3::new(nr * c, nr * s, nz));
            }
        }
        let stride = AROUND + 1;
        for i in 0..rows {
            for j in 0..AROUND {
                let (a, b) = (base + i * stride + j, base + i * stride + j + 1);
                let (c, d) = (a + stride, b + stride);
                // Rows run from −Z to +Z and φ counter-clockwise seen from +Z: (a, b, d) faces out.
                self.indices.push([a, b, d]);
                self.indices.push([a, d, c]);
            }
        }
    }

    /// A flat disc of `radius` at height `z`, facing +Z (`up`) or −Z.
    fn cap(&mut self, radius: f32, z: f32, up: bool) {
        let n = if up { Vec3::Z } else { -Vec3::Z };
        let centre = self.vertex(Vec3::new(0.0, 0.0, z), n);
        let ring = self.positions.len() as u32;
        for j in 0..AROUND {
            let phi = std::f32::consts::TAU * j as f32 / AROUND as f32;
            self.vertex(Vec3::new(radius * phi.cos(), radius * phi.sin(), z), n);
        }
        for j in 0..AROUND {
            let (a, b) = (ring + j, ring + (j + 1) % AROUND);
            self.indices.push(if up { [centre, a, b] } else { [centre, b, a] });
        }
    }

    fn finish(mut self, axis: Axis) -> Mesh {
        for p in &mut self.positions {
            *p = axis.orient(*p);
        }
        for n in &mut self.normals {
            *n = axis.orient(*n);
        }
        Mesh { positions: self.positions, indices: self.indices, normals: Normals::Vertex(self.normals), ..Default::default() }
    }
}

/// Tessellates `shape`. Sizes must be finite and positive (checked by the caller, which names
/// the attribute).
pub fn tessellate(shape: Shape) -> Mesh {
    let half_pi = std::f32::consts::FRAC_PI_2;
    let mut b = Builder::default();
    match shape {
        Shape::Sphere { radius } => {
            b.revolve(ALONG, |t| {
                let theta = -half_pi + std::f32::consts::PI * t;
                let (s, c) = theta.sin_cos();
                (radius * c, radius * s, c, s)
            });
            b.finish(Axis::Z)
        }
        Shape::Capsule { bottom, top, height, axis } => {
            let h = 0.5 * height;
            // The side's normal leans by α, where the cone touches both spheres:
            // sin α = (bottom − top) / height (0 for equal ends: hemispheres and a cylinder).
            let alpha = ((bottom - top) / height).clamp(-1.0, 1.0).asin();
            let half = ALONG / 2;
            // The lower sphere from its pole up to α, the cone, the upper sphere from α, as
            // one profile.
            b.revolve(ALONG + 1, |t| {
                let k = t * (ALONG + 1) as f32;
                let on_sphere = |r: f32, z: f32, theta: f32| {
                    let (s, c) = theta.sin_cos();
                    (r * c, z + r * s, c, s)
                };
                if k <= half as f32 {
                    on_sphere(bottom, -h, -half_pi + (alpha + half_pi) * k / half as f32)
                } else if k <= half as f32 + 1.0 {
                    let u = k - half as f32;
                    let (s, c) = alpha.sin_cos();
                    let (r, z) = (bottom + (top - bottom) * u, -h + bottom * s + (2.0 * h + (top - bottom) * s) * u);
                    (r * c, z, c, s)
                } else {
                    on_sphere(top, h, alpha + (half_pi - alpha) * (k - half as f32 - 1.0) / half as f32)
                }
            });
            b.finish(axis)
        }
        Shape::Cylinder { bottom, top, height, axis } => {
            let h = 0.5 * height;
            // A narrowing side's normal leans up: (height, bottom − top) normalised.
            let len = (height * height + (bottom - top) * (bottom - top)).sqrt();
            let (nr, nz) = (height / len, (bottom - top) / len);
            b.revolve(1, |t| (bottom + (top - bottom) * t, -h + height * t, nr, nz));
            if bottom > 0.0 {
                b.cap(bottom, -h, false);
            }
            if top > 0.0 {
                b.cap(top, h, true);
            }
            b.finish(axis)
        }
        Shape::Cone { radius, height, axis } => {
            let h = 0.5 * height;
            // The side's normal leans up by the cone's half-angle: (height, radius) normalised.
            let len = (height * height + radius * radius).sqrt();
            let (nr, nz) = (height / len, radius / len);
            b.revolve(1, |t| (radius * (1.0 - t), -h + height * t, nr, nz));
            b.cap(radius, -h, false);
            b.finish(axis)
        }
        Shape::Cube { size } => {
            let s = 0.5 * size;
            for axis in [Axis::X, Axis::Y, Axis::Z] {
                for sign in [1.0f32, -1.0] {
                    // A face at z = ±s, wound to face ±Z, then rotated onto `axis`.
                    let n = axis.orient(Vec3::Z * sign);
                    let corners = [(-s, -s), (s, -s), (s, s), (-s, s)].map(|(x, y)| axis.orient(Vec3::new(x, y * sign, s * sign)));
                    let i: Vec<u32> = corners.iter().map(|&c| b.vertex(c, n)).collect();
                    b.indices.push([i[0], i[1], i[2]]);
                    b.indices.push([i[0], i[2], i[3]]);
                }
            }
            b.finish(Axis::Z)
        }
        Shape::Disc { radius } => {
            b.cap(radius, 0.0, true);
            b.finish(Axis::Z)
        }
        Shape::Plane { width, length, axis } => {
            let (w, l) = (0.5 * width, 0.5 * length);
            let i: Vec<u32> = [(-w, -l), (w, -l), (w, l), (-w, l)].iter().map(|&(x, y)| b.vertex(Vec3::new(x, y, 0.0), Vec3::Z)).collect();
            b.indices.push([i[0], i[1], i[2]]);
            b.indices.push([i[0], i[2], i[3]]);
            b.finish(axis)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Total area and enclosed volume (divergence theorem), and the largest angle between a
    /// vertex normal and its triangle's winding normal.
    fn measure(m: &Mesh) -> (f64, f64, f32) {
        let Normals::Vertex(n) = &m.normals else { panic!("vertex normals") };
        let (mut area, mut volume, mut worst) = (0.0f64, 0.0f64, 0.0f32);
        for t in 0..m.indices.len() {
            let [a, b, c] = m.triangle(t);
            let cross = (b - a).cross(c - a);
            area += 0.5 * cross.length() as f64;
            volume += a.dot(b.cross(c)) as f64 / 6.0;
            if cross.length() > 1e-9 {
                for &v in &m.indices[t] {
                    worst = worst.max(n[v as usize].angle_between(cross.normalize()).to_degrees());
                }
            }
        }
        (area, volume, worst)
    }

    /// A `Capsule_1` with its analytic area and volume: spheres of radius `r1` and `r2` at
    /// ∓height/2 and the cone tangent to both, touching them at the angle α with
    /// sin α = (r1 − r2) / height. Sphere zones (2πr² times the height fraction), the cone's
    /// lateral area π(ρ1 + ρ2)·slant, spherical segments and a frustum.
    fn tapered_capsule(r1: f64, r2: f64, height: f64) -> (Shape, f64, f64) {
        use std::f64::consts::PI;
        let (h, s) = (height / 2.0, (r1 - r2) / height);
        let c = (1.0 - s * s).sqrt();
        let (z1, z2) = (-h + r1 * s, h + r2 * s);
        let (p1, p2) = (r1 * c, r2 * c);
        let slant = ((z2 - z1).powi(2) + (p2 - p1).powi(2)).sqrt();
        let area = 2.0 * PI * r1 * r1 * (1.0 + s) + 2.0 * PI * r2 * r2 * (1.0 - s) + PI * (p1 + p2) * slant;
        let caps = PI * r1.powi(3) * (s - s.powi(3) / 3.0 + 2.0 / 3.0) + PI * r2.powi(3) * (2.0 / 3.0 - s + s.powi(3) / 3.0);
        let volume = caps + PI * (z2 - z1) * (p1 * p1 + p1 * p2 + p2 * p2) / 3.0;
        (Shape::Capsule { bottom: r1 as f32, top: r2 as f32, height: height as f32, axis: Axis::X }, area, volume)
    }

    #[test]
    fn closed_shapes_have_their_analytic_area_and_volume_and_face_outwards() {
        use std::f64::consts::PI;
        let cases = [
            (Shape::Sphere { radius: 2.0 }, 16.0 * PI, 32.0 * PI / 3.0),
            (Shape::Cube { size: 3.0 }, 54.0, 27.0),
            (Shape::Cylinder { bottom: 1.0, top: 1.0, height: 3.0, axis: Axis::X }, 2.0 * PI + 6.0 * PI, 3.0 * PI),
            // Cylinder_1 narrowing from radius 1 to 0.5 over height 2: a frustum.
            (
                Shape::Cylinder { bottom: 1.0, top: 0.5, height: 2.0, axis: Axis::Y },
                PI * 1.5 * 4.25f64.sqrt() + PI * 1.25,
                PI * 2.0 * (1.0 + 0.5 + 0.25) / 3.0,
            ),
            (Shape::Cone { radius: 1.0, height: 2.0, axis: Axis::Y }, PI + PI * 5f64.sqrt(), 2.0 * PI / 3.0),
            (
                Shape::Capsule { bottom: 0.5, top: 0.5, height: 1.0, axis: Axis::Z },
                4.0 * PI * 0.25 + 2.0 * PI * 0.5,
                PI * 0.25 + 4.0 * PI * 0.125 / 3.0,
            ),
            // Capsule_1 with ends of radius 0.6 and 0.3, 1.2 apart.
            tapered_capsule(0.6, 0.3, 1.2),
        ];
        for (shape, area, volume) in cases {
            let (a, v, worst) = measure(&tessellate(shape));
            assert!((a - area).abs() < 2e-3 * area, "{shape:?}: area {a} vs {area}");
            // Positive volume: every triangle is wound outwards.
            assert!((v - volume).abs() < 2e-3 * volume, "{shape:?}: volume {v} vs {volume}");
            // Normals agree with the winding (within the angle between neighbouring facets,
            // or 45° where a smooth side meets a flat cap or cube edge).
            assert!(worst < 50.0, "{shape:?}: a normal is {worst}° from its triangle");
        }
    }

    #[test]
    fn planes_and_axes_face_where_the_schema_says() {
        for (axis, up) in [(Axis::X, Vec3::X), (Axis::Y, Vec3::Y), (Axis::Z, Vec3::Z)] {
            let m = tessellate(Shape::Plane { width: 2.0, length: 4.0, axis });
            let [a, b, c] = m.triangle(0);
            assert!((b - a).cross(c - a).normalize().dot(up) > 0.999, "{axis:?}");
            let (area, _, _) = measure(&m);
            assert!((area - 8.0).abs() < 1e-5);
            // The cylinder's axis runs along `axis`.
            let cyl = tessellate(Shape::Cylinder { bottom: 0.1, top: 0.1, height: 10.0, axis });
            let extent = cyl.positions.iter().fold(Vec3::ZERO, |e, p| e.max(p.abs()));
            assert!((extent.dot(up) - 5.0).abs() < 1e-5, "{axis:?}: {extent}");
        }
    }
}
