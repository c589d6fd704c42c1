//! The importances of an interior node's two children in one SSE pass.
//!
//! The walk down the light tree computes, at every level, both children's importance
//! ([`LightBounds::importance`]): chains of four or five square roots and a division each,
//! about 50 ns a level, the many-light vertex's largest cost (docs/benchmarks.md,
//! 2026-12-04). Here the two children sit in two lanes of the same vectors, so one chain of
//! instructions computes both. Every lane takes exactly the scalar operations in the scalar
//! order (the branches become selects; IEEE operations round alike in either form), so the
//! values are the scalar ones to the bit and the tree picks and weighs lights as before
//! (`pair_importances_are_the_scalar_ones` compares them).

use glam::Vec3;

use super::LightBounds;

/// Two light bounds, component by component in the first two lanes of four (the other two
/// hold no power, so their importance is 0).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(super) struct PairBounds {
    center: [[f32; 4]; 3],
    radius: [f32; 4],
    phi: [f32; 4],
    w: [[f32; 4]; 3],
    cos_o: [f32; 4],
    sin_o: [f32; 4],
    cos_e: [f32; 4],
    /// All bits set where the bounds are two-sided.
    two_sided: [u32; 4],
}

impl PairBounds {
    pub(super) fn new(a: &LightBounds, b: &LightBounds) -> Self {
        let lanes = |f: &dyn Fn(&LightBounds) -> f32| [f(a), f(b), 0.0, 0.0];
        PairBounds {
            center: [lanes(&|l| l.center.x), lanes(&|l| l.center.y), lanes(&|l| l.center.z)],
            radius: lanes(&|l| l.radius),
            phi: lanes(&|l| l.phi),
            w: [lanes(&|l| l.w.x), lanes(&|l| l.w.y), lanes(&|l| l.w.z)],
            cos_o: lanes(&|l| l.cos_o),
            sin_o: lanes(&|l| l.sin_o),
            cos_e: lanes(&|l| l.cos_e),
            two_sided: [a.two_sided, b.two_sided, false, false].map(|t| if t { u32::MAX } else { 0 }),
        }
    }

    /// The two importances at `p` with normal `n`: `a.importance(p, n)` and
    /// `b.importance(p, n)`, to the bit.
    #[inline(always)]
    pub(super) fn importances(&self, p: Vec3, n: Vec3) -> (f32, f32) {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
        {
            // SAFETY: the target has SSE4.1 (checked at compile time).
            unsafe { sse::importances(self, p, n) }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
        {
            let bounds = |k: usize| LightBounds::new_lane(self, k);
            (bounds(0).importance(p, n), bounds(1).importance(p, n))
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
impl LightBounds {
    /// Lane `k`'s bounds (the fields importance reads).
    fn new_lane(pair: &PairBounds, k: usize) -> LightBounds {
        let v = |c: &[[f32; 4]; 3]| Vec3::new(c[0][k], c[1][k], c[2][k]);
        let center = v(&pair.center);
        LightBounds {
            lo: center,
            hi: center,
            phi: pair.phi[k],
            w: v(&pair.w),
            cos_o: pair.cos_o[k],
            cos_e: pair.cos_e[k],
            two_sided: pair.two_sided[k] != 0,
            center,
            radius: pair.radius[k],
            sin_o: pair.sin_o[k],
        }
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
mod sse {
    use std::arch::x86_64::*;

    use glam::Vec3;

    use super::PairBounds;

    #[inline(always)]
    unsafe fn load(x: &[f32; 4]) -> __m128 {
        unsafe { _mm_load_ps(x.as_ptr()) }
    }

    /// `a ? b : c` lane by lane.
    #[inline(always)]
    unsafe fn select(mask: __m128, b: __m128, c: __m128) -> __m128 {
        unsafe { _mm_blendv_ps(c, b, mask) }
    }

    /// `(x·x' + y·y') + z·z'`, glam's `Vec3::dot` order.
    #[inline(always)]
    unsafe fn dot(a: [__m128; 3], b: [__m128; 3]) -> __m128 {
        unsafe { _mm_add_ps(_mm_add_ps(_mm_mul_ps(a[0], b[0]), _mm_mul_ps(a[1], b[1])), _mm_mul_ps(a[2], b[2])) }
    }

    /// `x.max(0.0)` as Rust computes it for non-NaN `x`, and 0 for NaN (`maxps` returns its
    /// second operand when either is NaN).
    #[inline(always)]
    unsafe fn max0(x: __m128) -> __m128 {
        unsafe { _mm_max_ps(x, _mm_setzero_ps()) }
    }

    /// `|x|`.
    #[inline(always)]
    unsafe fn abs(x: __m128) -> __m128 {
        unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), x) }
    }

    /// `sin_of`: `sqrt(max(1 − c², 0))`.
    #[inline(always)]
    unsafe fn sin_of(c: __m128) -> __m128 {
        unsafe { _mm_sqrt_ps(max0(_mm_sub_ps(_mm_set1_ps(1.0), _mm_mul_ps(c, c)))) }
    }

    /// `cos_sub_clamped` and `sin_sub_clamped`: cos and sin of max(0, a − b).
    #[inline(always)]
    unsafe fn sub_clamped(sin_a: __m128, cos_a: __m128, sin_b: __m128, cos_b: __m128) -> (__m128, __m128) {
        unsafe {
            let past = _mm_cmpgt_ps(cos_a, cos_b);
            let cos = _mm_add_ps(_mm_mul_ps(cos_a, cos_b), _mm_mul_ps(sin_a, sin_b));
            let sin = _mm_sub_ps(_mm_mul_ps(sin_a, cos_b), _mm_mul_ps(cos_a, sin_b));
            (select(past, _mm_set1_ps(1.0), cos), select(past, _mm_setzero_ps(), sin))
        }
    }

    /// [`super::PairBounds::importances`]: `LightBounds::importance` lane by lane, its
    /// branches as selects (every branch is computed; the lanes keep the one the scalar code
    /// takes).
    #[inline(always)]
    pub(super) unsafe fn importances(b: &PairBounds, p: Vec3, n: Vec3) -> (f32, f32) {
        unsafe {
            let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
            let v = [
                _mm_sub_ps(_mm_set1_ps(p.x), load(&b.center[0])),
                _mm_sub_ps(_mm_set1_ps(p.y), load(&b.center[1])),
                _mm_sub_ps(_mm_set1_ps(p.z), load(&b.center[2])),
            ];
            let nv = [_mm_set1_ps(n.x), _mm_set1_ps(n.y), _mm_set1_ps(n.z)];
            let no_normal = n == Vec3::ZERO;
            let (phi, radius) = (load(&b.phi), load(&b.radius));
            let r2 = _mm_mul_ps(radius, radius);
            let dist2 = dot(v, v);
            // `dist2.max(radius)`: maxps returns `radius` when `dist2` is NaN, as Rust does.
            let d2 = _mm_max_ps(dist2, radius);

            // Emitters facing every way: the receiver's bound alone (`sphere_receiver_cos`).
            let omni = {
                let a = abs(dot(v, nv));
                let a2 = _mm_mul_ps(a, a);
                let t_r2 = _mm_sub_ps(dist2, r2);
                let c = max0(_mm_add_ps(_mm_mul_ps(a, _mm_sqrt_ps(t_r2)), _mm_sqrt_ps(_mm_mul_ps(r2, max0(_mm_sub_ps(dist2, a2))))));
                let whole = _mm_or_ps(_mm_cmple_ps(dist2, r2), _mm_cmpge_ps(a2, t_r2));
                let whole = if no_normal { _mm_castsi128_ps(_mm_set1_epi32(-1)) } else { whole };
                let (c, t) = (select(whole, one, c), select(whole, one, dist2));
                _mm_div_ps(_mm_mul_ps(phi, c), _mm_mul_ps(d2, t))
            };

            // Emitters within a cone of normals.
            let general = {
                let inv = _mm_div_ps(one, _mm_sqrt_ps(dist2));
                let ahead = _mm_cmpgt_ps(dist2, zero);
                let wi = [0, 1, 2].map(|k| select(ahead, _mm_mul_ps(v[k], inv), zero));
                // `bounding_cone`.
                let s2 = _mm_div_ps(r2, dist2);
                let inside = _mm_cmple_ps(dist2, r2);
                let sin_b = select(inside, zero, _mm_sqrt_ps(s2));
                let cos_b = select(inside, _mm_set1_ps(-1.0), _mm_sqrt_ps(max0(_mm_sub_ps(one, s2))));
                let w = [load(&b.w[0]), load(&b.w[1]), load(&b.w[2])];
                let cos_w = dot(w, wi);
                let cos_w = select(_mm_load_ps(b.two_sided.as_ptr().cast()), abs(cos_w), cos_w);
                let sin_w = sin_of(cos_w);
                let (cos_x, sin_x) = sub_clamped(sin_w, cos_w, load(&b.sin_o), load(&b.cos_o));
                let (cos_p, _) = sub_clamped(sin_x, cos_x, sin_b, cos_b);
                // `receiver_cos`.
                let receiver = if no_normal {
                    one
                } else {
                    let cos_i = abs(dot(wi, nv));
                    max0(sub_clamped(sin_of(cos_i), cos_i, sin_b, cos_b).0)
                };
                let value = max0(_mm_mul_ps(_mm_div_ps(_mm_mul_ps(phi, cos_p), d2), receiver));
                select(_mm_cmple_ps(cos_p, load(&b.cos_e)), zero, value)
            };

            let is_omni = _mm_and_ps(_mm_cmple_ps(load(&b.cos_o), _mm_set1_ps(-1.0)), _mm_cmple_ps(load(&b.cos_e), zero));
            let value = select(_mm_cmple_ps(phi, zero), zero, select(is_omni, omni, general));
            let mut out = [0.0f32; 4];
            _mm_storeu_ps(out.as_mut_ptr(), value);
            (out[0], out[1])
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

    /// Both lanes against the scalar importance, bit for bit, at points near and inside the
    /// bounds, with random normals, normals along an axis, and no normal (a point in a
    /// medium).
    #[test]
    fn pair_importances_are_the_scalar_ones() {
        let mut rng = Pcg32::new(17, 3);
        let (mut compared, mut nonzero) = (0, 0);
        for i in 0..20_000 {
            let (a, b) = (bounds(&mut rng), bounds(&mut rng));
            let pair = PairBounds::new(&a, &b);
            let p = if i % 7 == 0 { a.center + point(&mut rng, a.radius) } else { point(&mut rng, 12.0) };
            let n = match i % 5 {
                0 => Vec3::ZERO,
                1 => Vec3::Y,
                _ => uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())),
            };
            let (ia, ib) = pair.importances(p, n);
            let (sa, sb) = (a.importance(p, n), b.importance(p, n));
            assert_eq!((ia.to_bits(), ib.to_bits()), (sa.to_bits(), sb.to_bits()), "{a:?}\n{b:?}\np {p} n {n}: {ia} {ib} vs {sa} {sb}");
            compared += 2;
            nonzero += (sa > 0.0) as usize + (sb > 0.0) as usize;
        }
        // Most pairs weigh something (a test of zeros alone would prove little).
        assert!(nonzero > compared / 2, "{nonzero} of {compared} nonzero");
    }
}
