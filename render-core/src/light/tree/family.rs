//! The importances of an interior node's two children and four grandchildren in one AVX
//! pass.
//!
//! The walk down the light tree computes, at every level, both children's importance
//! ([`LightBounds::importance`]): chains of four or five square roots and a division each,
//! about 50 ns a level, the many-light vertex's largest cost (docs/benchmarks.md,
//! 2026-12-04). Here a node's children sit in lanes 0 and 1 of eight and its grandchildren in
//! lanes 2-3 (the left child's) and 4-5 (the right child's), and the node itself in lane 6 (a
//! walk starting there checks that it matters at all), so one chain of instructions weighs two
//! levels of the walk: it takes a chain's latency per two levels where a pair of lanes took
//! one per level. Only nodes at even depths hold a family; the others are weighed in their
//! parent's (`Lanes` in the tree). Every lane takes exactly the scalar operations in the scalar
//! order (the branches become selects; IEEE operations round alike in either form), so the
//! values are the scalar ones to the bit and the tree picks and weighs lights as it always
//! has (`family_importances_are_the_scalar_ones` compares them).

use glam::Vec3;

use super::LightBounds;

/// Lanes of a family: two children, four grandchildren, the node, one unused.
pub(super) const LANES: usize = 8;

/// The lane of the node itself.
pub(super) const NODE: usize = 6;

/// A node's children (lanes 0 and 1), grandchildren (lanes 2 to 5) and itself (lane 6),
/// component by component; lanes without bounds (a child that is a leaf has no children, and
/// lane 7 is never used) hold no power, so their importance is 0.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(super) struct FamilyBounds {
    center: [[f32; LANES]; 3],
    radius: [f32; LANES],
    phi: [f32; LANES],
    w: [[f32; LANES]; 3],
    cos_o: [f32; LANES],
    sin_o: [f32; LANES],
    cos_e: [f32; LANES],
    /// All bits set where the bounds are two-sided.
    two_sided: [u32; LANES],
}

impl FamilyBounds {
    /// The family of `members`, lane by lane (None: an empty lane).
    pub(super) fn new(members: [Option<&LightBounds>; 7]) -> Self {
        let lanes = |f: &dyn Fn(&LightBounds) -> f32| {
            let mut out = [0.0; LANES];
            for (o, m) in out.iter_mut().zip(members) {
                *o = m.map_or(0.0, f);
            }
            out
        };
        let mut two_sided = [0; LANES];
        for (t, m) in two_sided.iter_mut().zip(members) {
            *t = if m.is_some_and(|m| m.two_sided) { u32::MAX } else { 0 };
        }
        FamilyBounds {
            center: [lanes(&|l| l.center.x), lanes(&|l| l.center.y), lanes(&|l| l.center.z)],
            radius: lanes(&|l| l.radius),
            phi: lanes(&|l| l.phi),
            w: [lanes(&|l| l.w.x), lanes(&|l| l.w.y), lanes(&|l| l.w.z)],
            cos_o: lanes(&|l| l.cos_o),
            sin_o: lanes(&|l| l.sin_o),
            cos_e: lanes(&|l| l.cos_e),
            two_sided,
        }
    }

    /// The importances at `p` with normal `n`, lane by lane: `member.importance(p, n)` to the
    /// bit, 0 for empty lanes.
    #[inline(always)]
    pub(super) fn importances(&self, p: Vec3, n: Vec3) -> [f32; LANES] {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        {
            // SAFETY: the target has AVX2 (checked at compile time).
            unsafe { avx::importances(self, p, n) }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
        {
            std::array::from_fn(|k| LightBounds::new_lane(self, k).importance(p, n))
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
impl LightBounds {
    /// Lane `k`'s bounds (the fields importance reads).
    fn new_lane(family: &FamilyBounds, k: usize) -> LightBounds {
        let v = |c: &[[f32; LANES]; 3]| Vec3::new(c[0][k], c[1][k], c[2][k]);
        let center = v(&family.center);
        LightBounds {
            lo: center,
            hi: center,
            phi: family.phi[k],
            w: v(&family.w),
            cos_o: family.cos_o[k],
            cos_e: family.cos_e[k],
            two_sided: family.two_sided[k] != 0,
            center,
            radius: family.radius[k],
            sin_o: family.sin_o[k],
        }
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod avx {
    use std::arch::x86_64::*;

    use glam::Vec3;

    use super::{FamilyBounds, LANES};

    #[inline(always)]
    unsafe fn load(x: &[f32; LANES]) -> __m256 {
        unsafe { _mm256_load_ps(x.as_ptr()) }
    }

    #[inline(always)]
    unsafe fn splat(x: f32) -> __m256 {
        unsafe { _mm256_set1_ps(x) }
    }

    /// `a ? b : c` lane by lane.
    #[inline(always)]
    unsafe fn select(mask: __m256, b: __m256, c: __m256) -> __m256 {
        unsafe { _mm256_blendv_ps(c, b, mask) }
    }

    /// Lanes where `a > b` (false where either is NaN, as Rust's `>`).
    #[inline(always)]
    unsafe fn gt(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(a, b) }
    }

    /// Lanes where `a <= b` (false where either is NaN).
    #[inline(always)]
    unsafe fn le(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(a, b) }
    }

    /// `(x·x' + y·y') + z·z'`, glam's `Vec3::dot` order.
    #[inline(always)]
    unsafe fn dot(a: [__m256; 3], b: [__m256; 3]) -> __m256 {
        unsafe { _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])), _mm256_mul_ps(a[2], b[2])) }
    }

    /// `x.max(0.0)` as Rust computes it for non-NaN `x`, and 0 for NaN (`maxps` returns its
    /// second operand when either is NaN).
    #[inline(always)]
    unsafe fn max0(x: __m256) -> __m256 {
        unsafe { _mm256_max_ps(x, _mm256_setzero_ps()) }
    }

    /// `|x|`.
    #[inline(always)]
    unsafe fn abs(x: __m256) -> __m256 {
        unsafe { _mm256_andnot_ps(splat(-0.0), x) }
    }

    /// `sin_of`: `sqrt(max(1 − c², 0))`.
    #[inline(always)]
    unsafe fn sin_of(c: __m256) -> __m256 {
        unsafe { _mm256_sqrt_ps(max0(_mm256_sub_ps(splat(1.0), _mm256_mul_ps(c, c)))) }
    }

    /// `cos_sub_clamped` and `sin_sub_clamped`: cos and sin of max(0, a − b).
    #[inline(always)]
    unsafe fn sub_clamped(sin_a: __m256, cos_a: __m256, sin_b: __m256, cos_b: __m256) -> (__m256, __m256) {
        unsafe {
            let past = gt(cos_a, cos_b);
            let cos = _mm256_add_ps(_mm256_mul_ps(cos_a, cos_b), _mm256_mul_ps(sin_a, sin_b));
            let sin = _mm256_sub_ps(_mm256_mul_ps(sin_a, cos_b), _mm256_mul_ps(cos_a, sin_b));
            (select(past, splat(1.0), cos), select(past, _mm256_setzero_ps(), sin))
        }
    }

    /// The shading point as the eight lanes see it: its offset from each bound's centre and
    /// the distances the importance reads, with the bounds' power.
    struct Receiver {
        v: [__m256; 3],
        n: [__m256; 3],
        /// No normal (a point in a medium): every direction receives.
        no_normal: bool,
        phi: __m256,
        r2: __m256,
        dist2: __m256,
        /// `dist2.max(radius).max(MIN_DIST2)`.
        d2: __m256,
    }

    /// [`super::FamilyBounds::importances`]: `LightBounds::importance` lane by lane, its
    /// branches as selects (every branch is computed; the lanes keep the one the scalar code
    /// takes).
    #[inline(always)]
    pub(super) unsafe fn importances(b: &FamilyBounds, p: Vec3, n: Vec3) -> [f32; LANES] {
        unsafe {
            let v = [
                _mm256_sub_ps(splat(p.x), load(&b.center[0])),
                _mm256_sub_ps(splat(p.y), load(&b.center[1])),
                _mm256_sub_ps(splat(p.z), load(&b.center[2])),
            ];
            let (phi, radius) = (load(&b.phi), load(&b.radius));
            let dist2 = dot(v, v);
            // `dist2.max(radius).max(MIN_DIST2)`: maxps returns its second operand when the
            // first is NaN, as Rust's max does.
            let d2 = _mm256_max_ps(_mm256_max_ps(dist2, radius), splat(super::super::MIN_DIST2));
            let at = Receiver {
                v,
                n: [splat(n.x), splat(n.y), splat(n.z)],
                no_normal: n == Vec3::ZERO,
                phi,
                r2: _mm256_mul_ps(radius, radius),
                dist2,
                d2,
            };
            let is_omni = _mm256_and_ps(le(load(&b.cos_o), splat(-1.0)), le(load(&b.cos_e), _mm256_setzero_ps()));
            let value = select(le(phi, _mm256_setzero_ps()), _mm256_setzero_ps(), select(is_omni, omni(&at), within_cone(b, &at)));
            let mut out = [0.0f32; LANES];
            _mm256_storeu_ps(out.as_mut_ptr(), value);
            out
        }
    }

    /// Emitters facing every way: the receiver's bound alone (`sphere_receiver_cos`).
    #[inline(always)]
    unsafe fn omni(at: &Receiver) -> __m256 {
        unsafe {
            let one = splat(1.0);
            let a = abs(dot(at.v, at.n));
            let a2 = _mm256_mul_ps(a, a);
            let t_r2 = _mm256_sub_ps(at.dist2, at.r2);
            let c = max0(_mm256_add_ps(
                _mm256_mul_ps(a, _mm256_sqrt_ps(t_r2)),
                _mm256_sqrt_ps(_mm256_mul_ps(at.r2, max0(_mm256_sub_ps(at.dist2, a2)))),
            ));
            let whole = _mm256_or_ps(le(at.dist2, at.r2), _mm256_cmp_ps::<_CMP_GE_OQ>(a2, t_r2));
            let whole = if at.no_normal { _mm256_castsi256_ps(_mm256_set1_epi32(-1)) } else { whole };
            let (c, t) = (select(whole, one, c), select(whole, one, at.dist2));
            _mm256_div_ps(_mm256_mul_ps(at.phi, c), _mm256_mul_ps(at.d2, t))
        }
    }

    /// Emitters within a cone of normals.
    #[inline(always)]
    unsafe fn within_cone(b: &FamilyBounds, at: &Receiver) -> __m256 {
        unsafe {
            let (zero, one) = (_mm256_setzero_ps(), splat(1.0));
            let inv = _mm256_div_ps(one, _mm256_sqrt_ps(at.dist2));
            let ahead = gt(at.dist2, zero);
            let wi = [0, 1, 2].map(|k| select(ahead, _mm256_mul_ps(at.v[k], inv), zero));
            // `bounding_cone`.
            let s2 = _mm256_div_ps(at.r2, at.dist2);
            let inside = le(at.dist2, at.r2);
            let sin_b = select(inside, zero, _mm256_sqrt_ps(s2));
            let cos_b = select(inside, splat(-1.0), _mm256_sqrt_ps(max0(_mm256_sub_ps(one, s2))));
            let w = [load(&b.w[0]), load(&b.w[1]), load(&b.w[2])];
            let cos_w = dot(w, wi);
            let cos_w = select(_mm256_load_ps(b.two_sided.as_ptr().cast()), abs(cos_w), cos_w);
            let sin_w = sin_of(cos_w);
            let (cos_x, sin_x) = sub_clamped(sin_w, cos_w, load(&b.sin_o), load(&b.cos_o));
            let (cos_p, _) = sub_clamped(sin_x, cos_x, sin_b, cos_b);
            // `receiver_cos`.
            let receiver = if at.no_normal {
                one
            } else {
                let cos_i = abs(dot(wi, at.n));
                max0(sub_clamped(sin_of(cos_i), cos_i, sin_b, cos_b).0)
            };
            let value = max0(_mm256_mul_ps(_mm256_div_ps(_mm256_mul_ps(at.phi, cos_p), at.d2), receiver));
            select(le(cos_p, load(&b.cos_e)), zero, value)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::shapes::Shape;
    use crate::sampling::{Pcg32, uniform_sphere};
    use glam::Vec2;

    fn point(rng: &mut Pcg32, size: f32) -> Vec3 {
        (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * size
    }

    /// Bounds of every kind the tree holds: spheres (emitting every way), one-sided rects,
    /// two-sided triangles, clusters of several (wider cones, unions of sides), a light the
    /// facing-anywhere way, and none at all (no power).
    fn bounds(rng: &mut Pcg32) -> LightBounds {
        let one = |rng: &mut Pcg32| {
            let (c, phi) = (point(rng, 8.0), 0.1 + 10.0 * rng.next_f32());
            let shape = match (rng.next_f32() * 3.0) as u32 {
                0 => Shape::Sphere { center: c, radius: 0.05 + rng.next_f32(), l: Vec3::ONE },
                1 => {
                    let n = uniform_sphere(rng.next_2d());
                    let frame = crate::math::Frame::from_normal(n);
                    Shape::Rect { center: c, u: frame.t * rng.next_f32(), v: frame.b, n, area: 1.0, l: Vec3::ONE }
                }
                _ => Shape::triangle([c, c + point(rng, 2.0), c + point(rng, 2.0)], Vec3::ONE).expect("a triangle with area"),
            };
            LightBounds::of(&shape, phi).expect("a finite light")
        };
        match (rng.next_f32() * 10.0) as u32 {
            0 => LightBounds { phi: 0.0, ..one(rng) },
            1 => LightBounds::facing_anywhere(point(rng, 8.0), point(rng, 8.0) + Vec3::splat(5.0), 3.0),
            2..=4 => (0..2 + (rng.next_f32() * 4.0) as usize).map(|_| one(rng)).reduce(|a, b| a.union(&b)).unwrap(),
            _ => one(rng),
        }
    }

    /// Every lane against the scalar importance, bit for bit, at points near and inside the
    /// bounds, with random normals, normals along an axis, and no normal (a point in a
    /// medium); empty lanes weigh 0.
    #[test]
    fn family_importances_are_the_scalar_ones() {
        let mut rng = Pcg32::new(17, 3);
        let (mut compared, mut nonzero) = (0, 0);
        for i in 0..20_000 {
            // Some lanes empty, as where a child is a leaf.
            let members: [Option<LightBounds>; 7] = std::array::from_fn(|_| (rng.next_f32() < 0.85).then(|| bounds(&mut rng)));
            let family = FamilyBounds::new(members.each_ref().map(Option::as_ref));
            let near = members.iter().flatten().next().map_or(Vec3::ZERO, |a| a.center + point(&mut rng, a.radius));
            let p = if i % 7 == 0 { near } else { point(&mut rng, 12.0) };
            let n = match i % 5 {
                0 => Vec3::ZERO,
                1 => Vec3::Y,
                _ => uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())),
            };
            let lanes = family.importances(p, n);
            for (k, lane) in lanes.iter().enumerate() {
                let scalar = members.get(k).copied().flatten().map_or(0.0, |m| m.importance(p, n));
                assert_eq!(lane.to_bits(), scalar.to_bits(), "lane {k} of {members:?}\np {p} n {n}: {lane} vs {scalar}");
                if members.get(k).is_some_and(Option::is_some) {
                    compared += 1;
                    nonzero += (scalar > 0.0) as usize;
                }
            }
        }
        // Most members weigh something (a test of zeros alone would prove little).
        assert!(nonzero > compared / 2, "{nonzero} of {compared} nonzero");
    }
}
