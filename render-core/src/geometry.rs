//! Rays, triangle meshes, instances and robust ray origins.

use glam::{Affine3A, Mat3, Vec2, Vec3};

/// A ray with a maximum parametric distance.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction; not necessarily unit length in object space.
    pub dir: Vec3,
    /// Maximum t.
    pub tmax: f32,
    /// When in the shutter the ray travels (0 open, 1 close): what moving geometry it sees.
    pub time: f32,
}

impl Ray {
    /// A ray of unbounded length.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray { origin, dir, tmax: f32::INFINITY, time: 0.0 }
    }

    /// The same ray at shutter time `time`.
    #[inline]
    pub fn with_time(self, time: f32) -> Self {
        Ray { time, ..self }
    }

    /// The same ray ending at `tmax`.
    #[inline]
    pub fn with_tmax(self, tmax: f32) -> Self {
        Ray { tmax, ..self }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// Offsets a surface point along its geometric normal so that a ray leaving it does not
/// re-hit the same surface: Wächter & Binder, "A Fast and Robust Method for Avoiding
/// Self-Intersection", Ray Tracing Gems (2019), chapter 6. Away from the origin the offset is
/// a number of ulps of each coordinate; near it (where ulps vanish) their method adds a fixed
/// 1/65536 within 1/32 of the origin. Both of those constants assume a scene about one unit
/// big, so here they scale with `scene_scale` (the largest coordinate magnitude of the
/// scene): unscaled, a Cornell box of 2e-4 units got offsets of 8% of its size (light leaked
/// in, the boxes went black) and one of 2e5 units self-shadowed its floor at y = 0, where
/// 1/65536 is far below the intersection error of rays 1e5 long.
#[inline]
pub fn offset_ray_origin(p: Vec3, ng: Vec3, scene_scale: f32) -> Vec3 {
    let s = if scene_scale.is_finite() && scene_scale > 0.0 { scene_scale } else { 1.0 };
    #[cfg(target_arch = "x86_64")]
    {
        // The three coordinates in one SSE2 pass (x86-64's baseline): the scalar form below
        // spends most of its instructions on Rust's saturating float-to-int conversions.
        offset_lanes(p, ng, s)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        offset_each(p, ng, s)
    }
}

/// The normal's offset in ulps for each coordinate.
const OFFSET_INT_SCALE: f32 = 256.0;

/// Where [`offset_ray_origin`] stops counting ulps and adds a fixed offset instead, and that
/// offset, in a scene `s` big.
fn offset_near_origin(s: f32) -> (f32, f32) {
    (s / 32.0, s / 65536.0)
}

/// [`offset_ray_origin`] coordinate by coordinate: the reference its SSE form is held to.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn offset_each(p: Vec3, ng: Vec3, s: f32) -> Vec3 {
    let (origin, float_scale) = offset_near_origin(s);
    let of_i = [(OFFSET_INT_SCALE * ng.x) as i32, (OFFSET_INT_SCALE * ng.y) as i32, (OFFSET_INT_SCALE * ng.z) as i32];
    let bump = |c: f32, o: i32| -> f32 {
        let bits = c.to_bits() as i32;
        f32::from_bits(bits.wrapping_add(if c < 0.0 { o.wrapping_neg() } else { o }) as u32)
    };
    let p_i = Vec3::new(bump(p.x, of_i[0]), bump(p.y, of_i[1]), bump(p.z, of_i[2]));
    Vec3::new(
        if p.x.abs() < origin { p.x + float_scale * ng.x } else { p_i.x },
        if p.y.abs() < origin { p.y + float_scale * ng.y } else { p_i.y },
        if p.z.abs() < origin { p.z + float_scale * ng.z } else { p_i.z },
    )
}

/// [`offset_each`] with the three coordinates in SSE2 lanes, bit for bit: the conversion keeps
/// `as i32`'s saturation (NaN to 0, overflow to `i32::MAX`), the integer steps wrap as the
/// scalar ones do, and each product and sum is the same single rounding.
#[cfg(target_arch = "x86_64")]
#[inline]
fn offset_lanes(p: Vec3, ng: Vec3, s: f32) -> Vec3 {
    use std::arch::x86_64::*;
    let (origin, float_scale) = offset_near_origin(s);
    let (p4, n4): (__m128, __m128) = (glam::Vec3A::from(p).into(), glam::Vec3A::from(ng).into());
    // SAFETY: SSE2 is part of x86-64's baseline; these intrinsics only read their operands.
    let out = unsafe {
        let scaled = _mm_mul_ps(_mm_set1_ps(OFFSET_INT_SCALE), n4);
        let not_nan = _mm_cmpord_ps(scaled, scaled);
        let scaled = _mm_and_ps(scaled, not_nan);
        let too_big = _mm_castps_si128(_mm_cmpge_ps(scaled, _mm_set1_ps(2_147_483_648.0)));
        // cvtt gives i32::MIN above range; flipping every bit there gives i32::MAX.
        let of_i = _mm_xor_si128(_mm_cvttps_epi32(scaled), too_big);
        // -o where the coordinate is negative: (o ^ m) - m with m all ones there.
        let negative = _mm_castps_si128(_mm_cmplt_ps(p4, _mm_setzero_ps()));
        let signed = _mm_sub_epi32(_mm_xor_si128(of_i, negative), negative);
        let p_i = _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(p4), signed));
        let abs = _mm_andnot_ps(_mm_set1_ps(-0.0), p4);
        let near = _mm_cmplt_ps(abs, _mm_set1_ps(origin));
        let p_f = _mm_add_ps(p4, _mm_mul_ps(_mm_set1_ps(float_scale), n4));
        _mm_or_ps(_mm_and_ps(near, p_f), _mm_andnot_ps(near, p_i))
    };
    Vec3::from(glam::Vec3A::from(out))
}

/// Per-corner data of a mesh (normals, texture coordinates), in the two layouts a
/// triangulated USD primvar takes.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Attribute<T> {
    /// Not authored.
    #[default]
    None,
    /// One value per vertex.
    Vertex(Vec<T>),
    /// One value per triangle corner (3 per triangle).
    FaceVarying(Vec<T>),
}

impl<T> Attribute<T>
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    /// The three corner values of triangle `tri` with vertex indices `idx`.
    #[inline]
    pub fn corners(&self, tri: usize, idx: [u32; 3]) -> Option<[T; 3]> {
        match self {
            Attribute::None => None,
            Attribute::Vertex(v) => Some(idx.map(|i| v[i as usize])),
            Attribute::FaceVarying(v) => Some([v[3 * tri], v[3 * tri + 1], v[3 * tri + 2]]),
        }
    }

    /// The value at barycentrics (`b1`, `b2`) of triangle `tri`.
    #[inline]
    pub fn interpolate(&self, tri: usize, idx: [u32; 3], bary: Vec2) -> Option<T> {
        self.corners(tri, idx).map(|[a, b, c]| a * (1.0 - bary.x - bary.y) + b * bary.x + c * bary.y)
    }

    /// Number of values held.
    pub fn len(&self) -> usize {
        match self {
            Attribute::None => 0,
            Attribute::Vertex(v) | Attribute::FaceVarying(v) => v.len(),
        }
    }

    /// True when nothing is authored.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// How a mesh's shading normals are stored (`None`: flat shading from the geometric normal).
pub type Normals = Attribute<Vec3>;

/// A mesh's texture coordinates (`st`).
pub type Uvs = Attribute<Vec2>;

/// Unit normals of `count` groups of vertices, `group(v)` being vertex v's: each the sum of the
/// area-weighted normals of the triangles its vertices belong to (zero for a group no
/// triangle with area touches). With one group per vertex, the usual smooth vertex normals.
pub fn area_weighted_normals(positions: &[Vec3], indices: &[[u32; 3]], group: impl Fn(u32) -> usize, count: usize) -> Vec<Vec3> {
    let mut sum = vec![Vec3::ZERO; count];
    for tri in indices {
        let [a, b, c] = tri.map(|i| positions[i as usize]);
        let area_normal = (b - a).cross(c - a);
        for &i in tri {
            sum[group(i)] += area_normal;
        }
    }
    sum.into_iter().map(|n| n.normalize_or_zero()).collect()
}

/// A triangle mesh in object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex indices, three per triangle.
    pub indices: Vec<[u32; 3]>,
    /// Shading normals.
    pub normals: Normals,
    /// Texture coordinates: the float2 primvar the mesh's material reads (`st` unless a
    /// primvar reader names another).
    pub uvs: Uvs,
    /// The other primvars the mesh's materials read (`UsdPrimvarReader_float`, `_float3`,
    /// `_int`).
    pub primvars: Vec<Primvar>,
    /// Deformation over the shutter: the positions at evenly spaced times from shutter open
    /// to close, one full set after another (2 to [`crate::motion::MAX_MOTION_SAMPLES`]
    /// sets); empty when the mesh keeps its shape.
    pub deformation: Vec<Vec3>,
}

/// A named primvar a material reads: float and int primvars in `x`, float3 in all three.
#[derive(Clone, Debug, PartialEq)]
pub struct Primvar {
    /// Name without `primvars:`.
    pub name: String,
    /// Values per vertex or per triangle corner.
    pub values: Attribute<Vec3>,
}

impl Mesh {
    /// A unit sphere of `2 × rings × segments` triangles (for benchmarks and tests that need
    /// a mesh of a given size).
    pub fn uv_sphere(rings: u32, segments: u32) -> Mesh {
        let mut positions = Vec::new();
        for r in 0..=rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let phi = 2.0 * std::f32::consts::PI * s as f32 / segments as f32;
                positions.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
            }
        }
        let mut indices = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
                let (c, d) = ((r + 1) * segments + (s + 1) % segments, (r + 1) * segments + s);
                indices.push([a, b, c]);
                indices.push([a, c, d]);
            }
        }
        Mesh { positions, indices, ..Default::default() }
    }

    /// A grid of `n`×`n` quads, two triangles each, whose vertex (`i`, `j`) (each in 0..=n)
    /// is `at(i, j)` (for benchmarks and tests that need a mesh of a given size).
    pub fn grid(n: u32, at: impl Fn(u32, u32) -> Vec3) -> Mesh {
        let positions = (0..=n).flat_map(|j| (0..=n).map(move |i| (i, j))).map(|(i, j)| at(i, j)).collect();
        let v = |i: u32, j: u32| j * (n + 1) + i;
        let indices = (0..n)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .flat_map(|(i, j)| [[v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)]])
            .collect();
        Mesh { positions, indices, ..Default::default() }
    }

    /// Object-space vertices of triangle `tri`.
    #[inline]
    pub fn triangle(&self, tri: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[tri];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Sets of positions over the shutter (0 when the mesh keeps its shape).
    #[inline]
    pub fn deformation_samples(&self) -> usize {
        if self.positions.is_empty() { 0 } else { self.deformation.len() / self.positions.len() }
    }

    /// Triangle `tri` as it is at shutter time `time` in [0, 1]: its corners interpolated
    /// linearly between the two deformation samples around `time` (the frame's triangle when
    /// the mesh keeps its shape).
    #[inline]
    pub fn triangle_at(&self, tri: usize, time: f32) -> [Vec3; 3] {
        // The still mesh's test first: no division on the path every hit takes.
        if self.deformation.is_empty() {
            return self.triangle(tri);
        }
        let k = self.deformation_samples();
        let (seg, f) = crate::motion::segment(time, k);
        let n = self.positions.len();
        let at = |v: u32| self.deformation[seg * n + v as usize].lerp(self.deformation[(seg + 1) * n + v as usize], f);
        self.indices[tri].map(at)
    }

    /// Interpolated, unnormalised shading normal at barycentrics (`b1`, `b2`), or `None`
    /// for flat meshes.
    #[inline]
    pub fn shading_normal(&self, tri: usize, bary: Vec2) -> Option<Vec3> {
        self.normals.interpolate(tri, self.indices[tri], bary)
    }

    /// The primvar `name` interpolated at barycentrics (`b1`, `b2`) of triangle `tri`, if the
    /// mesh has it.
    #[inline]
    pub fn primvar(&self, name: &str, tri: usize, bary: Vec2) -> Option<Vec3> {
        self.primvars.iter().find(|p| p.name == name)?.values.interpolate(tri, self.indices[tri], bary)
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
}

/// An object-to-world transform with the matrices a renderer needs precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Object to world.
    pub to_world: Affine3A,
    /// World to object.
    pub to_object: Affine3A,
    /// Inverse transpose of the linear part: transforms normals to world space.
    pub normal_matrix: Mat3,
}

impl Transform {
    /// Builds from an object-to-world affine map. Returns `None` when it is singular or
    /// not finite.
    pub fn new(to_world: Affine3A) -> Option<Self> {
        if !Self::invertible(&to_world) {
            return None;
        }
        let to_object = to_world.inverse();
        let normal_matrix = Mat3::from(to_world.matrix3).inverse().transpose();
        Some(Transform { to_world, to_object, normal_matrix })
    }

    /// True when `to_world` places geometry somewhere: finite and not singular.
    #[inline]
    pub fn invertible(to_world: &Affine3A) -> bool {
        let det = to_world.matrix3.determinant();
        det.is_finite() && det.abs() >= 1e-30 && to_world.translation.is_finite()
    }

    /// The identity.
    pub fn identity() -> Self {
        Self::new(Affine3A::IDENTITY).expect("identity is invertible")
    }

    /// True when the transform flips handedness.
    pub fn flips_handedness(&self) -> bool {
        self.to_world.matrix3.determinant() < 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_off_the_surface_at_every_scale() {
        for scale in [1e-4f32, 1.0, 1e5] {
            // Points of a scene `scale` big, one of them on a plane through the origin.
            for p in [Vec3::new(0.3, -0.7, 0.2) * scale, Vec3::new(0.4 * scale, 0.0, -0.6 * scale)] {
                for n in [Vec3::Z, Vec3::Y] {
                    let (up, down) = (offset_ray_origin(p, n, scale), offset_ray_origin(p, -n, scale));
                    assert!((up - p).dot(n) > 0.0 && (down - p).dot(n) < 0.0, "scale {scale}, p {p}, n {n}");
                    // Tiny relative to the scene, and above the f32 error of hitting p with a
                    // ray as long as the scene (a few ulps of the scene's size).
                    let moved = (up - p).length();
                    assert!(moved <= 1e-3 * scale, "scale {scale}: moved {moved}");
                    assert!(moved >= 8.0 * f32::EPSILON * scale, "scale {scale}: moved only {moved}");
                }
            }
        }
    }

    proptest::proptest! {
        // The SSE form against the scalar reference, bit for bit, over any bits at all: NaNs,
        // infinities, huge normals (where `as i32` saturates) and points near the origin.
        #[cfg(target_arch = "x86_64")]
        #[test]
        fn the_lanes_offset_each_coordinate_as_the_scalar_form_does(
            p in proptest::array::uniform3(proptest::num::f32::ANY),
            n in proptest::array::uniform3(proptest::num::f32::ANY),
            unit in proptest::array::uniform3(-1.0f32..=1.0),
            s in proptest::num::f32::ANY,
        ) {
            for n in [Vec3::from(n), Vec3::from(unit)] {
                let s = if s.is_finite() && s > 0.0 { s } else { 1.0 };
                let (lanes, each) = (offset_lanes(Vec3::from(p), n, s), offset_each(Vec3::from(p), n, s));
                proptest::prop_assert_eq!(lanes.to_array().map(f32::to_bits), each.to_array().map(f32::to_bits));
            }
        }
    }

    #[test]
    fn singular_transforms_are_rejected() {
        assert!(Transform::new(Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))).is_none());
        assert!(Transform::new(Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0))).is_none());
        let t = Transform::new(Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0))).unwrap();
        assert!(t.flips_handedness());
    }
}
