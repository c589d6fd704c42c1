//! Random numbers, warps from the unit square, discrete distributions and MIS weights.
//!
//! Sampling is counter-based: [`PixelSampler`] derives its stream from (seed, pixel,
//! sample index) alone, which is what makes renders independent of thread scheduling.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_4, PI};

/// SplitMix64 finaliser: a bijective 64-bit mix (Steele et al., "Fast splittable
/// pseudorandom number generators", OOPSLA 2014).
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// PCG32 (O'Neill 2014): small state, good statistical quality, cheap to seed.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    const MULT: u64 = 6_364_136_223_846_793_005;

    /// A generator on stream `stream` starting from `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Pcg32 { state: 0, inc: (stream << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform float in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        // 24 random mantissa bits: exactly representable, strictly below 1.
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Two uniform floats in [0, 1).
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

/// The random stream of one camera sample: a pure function of (seed, pixel, sample index).
pub struct PixelSampler;

impl PixelSampler {
    /// The generator for sample `sample_index` of pixel (`x`, `y`).
    pub fn for_sample(seed: u64, x: u32, y: u32, sample_index: u32) -> Pcg32 {
        let key = Self::pixel_key(seed, x, y);
        Pcg32::new(mix64(key ^ sample_index as u64), key)
    }

    fn pixel_key(seed: u64, x: u32, y: u32) -> u64 {
        let pixel = ((y as u64) << 32) | x as u64;
        mix64(seed ^ mix64(pixel.wrapping_add(0x9e37_79b9_7f4a_7c15)))
    }
}

/// Which numbers a render's paths draw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SamplerKind {
    /// Owen-scrambled Sobol points, shuffled per pixel and padded in 4D sets (Burley,
    /// "Practical Hash-based Owen Scrambling", JCGT 2020, through the `sobol_burley` crate).
    #[default]
    Sobol,
    /// Independent uniform random numbers (PCG32).
    Independent,
}

/// The numbers of one camera sample, four dimensions at a time: a pure function of (seed,
/// pixel, sample index), so renders do not depend on thread scheduling.
///
/// With Sobol, each 4D set of a path (camera, then two per bounce) is the first four
/// dimensions of an Owen-scrambled Sobol sequence whose index shuffle and scramble are
/// seeded by (pixel, set): sample k of a pixel is point k of that pixel's sequence, so every
/// power-of-two prefix of a pixel's samples is stratified in each set's 2D and 4D projections
/// (progressive), while pixels and sets stay decorrelated (Burley's padding). Past 2^16
/// samples a pixel falls back to independent numbers (the crate's sequence length).
pub enum PathSampler {
    /// Sobol: sample index, per-pixel key, next 4D set.
    Sobol {
        /// Point index in the pixel's sequence.
        index: u32,
        /// Per-pixel key.
        key: u64,
        /// Next 4D set.
        set: u32,
    },
    /// Independent numbers.
    Independent(Pcg32),
}

impl PathSampler {
    /// The sampler of sample `sample_index` of pixel (`x`, `y`).
    pub fn for_sample(kind: SamplerKind, seed: u64, x: u32, y: u32, sample_index: u32) -> Self {
        match kind {
            SamplerKind::Sobol if sample_index < (1 << 16) => {
                PathSampler::Sobol { index: sample_index, key: PixelSampler::pixel_key(seed, x, y), set: 0 }
            }
            _ => PathSampler::Independent(PixelSampler::for_sample(seed, x, y, sample_index)),
        }
    }

    /// The next four dimensions, each in [0, 1).
    #[inline]
    pub fn next_4d(&mut self) -> [f32; 4] {
        match self {
            PathSampler::Sobol { index, key, set } => {
                let seed = set_seed(*key, *set);
                *set += 1;
                sobol_4d(*index, seed)
            }
            PathSampler::Independent(rng) => [rng.next_f32(), rng.next_f32(), rng.next_f32(), rng.next_f32()],
        }
    }

    /// The next two sets of four dimensions: what two calls of [`PathSampler::next_4d`] give,
    /// to the bit, with the two sets' scrambling done together in eight lanes (a bounce draws
    /// two sets at once).
    #[inline]
    pub fn next_2x4d(&mut self) -> [[f32; 4]; 2] {
        match self {
            PathSampler::Sobol { index, key, set } => {
                let seeds = [set_seed(*key, *set), set_seed(*key, *set + 1)];
                *set += 2;
                sobol_2x4d(*index, seeds)
            }
            PathSampler::Independent(_) => [self.next_4d(), self.next_4d()],
        }
    }
}

/// The seed of 4D set `set` of the pixel keyed `key` (Burley's padding: sets decorrelated).
#[inline(always)]
fn set_seed(key: u64, set: u32) -> u32 {
    mix64(key ^ (set as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)) as u32
}

/// Point `index` (below 2^16) of the Owen-scrambled Sobol sequence seeded by `seed`, in its
/// first four dimensions: bit for bit `sobol_burley::sample_4d(index, 0, seed)` (Burley, JCGT
/// 2020: index shuffle, Sobol point, per-dimension Owen scramble), with the Sobol matrix
/// product replaced by two lookups. Sobol points are linear over GF(2) in the index bits, so
/// the point of a 16-bit (shuffled, bit-reversed) index is the XOR of the points of its two
/// bytes; the crate's loop over the index's set bits (eight dependent steps on average) was
/// most of a set's ~20 ns, two sets per bounce.
#[inline]
fn sobol_4d(index: u32, seed: u32) -> [f32; 4] {
    use sobol_burley::parts::{Int4, hash_int4, owen_scramble_int4_rev};
    let scramble = Int4::from([seed.wrapping_mul(SCRAMBLE_MUL); 4]) ^ DIMENSION_SALTS.into();
    owen_scramble_int4_rev(shuffled_point(index.reverse_bits(), seed), hash_int4(scramble)).reverse_bits().to_f32_norm()
}

// The constants are the crate's own (`sample_4d` in sobol_burley 0.5); the test
// `byte_table_sobol_is_the_crates_bit_for_bit` holds the two together.
/// Salt of the index shuffle's seed.
const SHUFFLE_SALT: u32 = 0x79c6_8e4a;
/// Multiplier of the seed for the per-dimension scrambles.
const SCRAMBLE_MUL: u32 = 0x9c8f_2d3b;
/// Salts of the four dimensions' scrambles.
const DIMENSION_SALTS: [u32; 4] = [0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8];

/// The (bit-reversed) Sobol point of the reversed index `index_rev` after the index shuffle
/// seeded by `seed`, before its per-dimension scramble: two byte-table lookups.
#[inline(always)]
fn shuffled_point(index_rev: u32, seed: u32) -> sobol_burley::parts::Int4 {
    use sobol_burley::parts::{hash, owen_scramble_rev};
    let shuffled_rev = owen_scramble_rev(index_rev, hash(seed ^ SHUFFLE_SALT));
    let tables = &*SOBOL_BYTE_TABLES;
    tables[0][(shuffled_rev >> 24) as usize] ^ tables[1][((shuffled_rev >> 16) & 0xff) as usize]
}

/// [`sobol_4d`] at two seeds: the index shuffles and table lookups one seed at a time, the
/// Owen scrambles of the two points (eight 32-bit lanes of integer arithmetic, exact) together.
#[inline]
fn sobol_2x4d(index: u32, seeds: [u32; 2]) -> [[f32; 4]; 2] {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        let rev = index.reverse_bits();
        let points = seeds.map(|seed| <[u32; 4]>::from(shuffled_point(rev, seed)));
        // SAFETY: the target has AVX2 (checked at compile time).
        unsafe { owen_pair::scramble(points, seeds) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        seeds.map(|seed| sobol_4d(index, seed))
    }
}

/// The tail of [`sobol_4d`] (scramble, hash, Owen scramble, bit reversal, to floats) for two
/// points at once: `sobol_burley`'s four-lane steps, the same integer operations, eight lanes.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod owen_pair {
    use std::arch::x86_64::*;

    #[inline(always)]
    unsafe fn splat(x: u32) -> __m256i {
        unsafe { _mm256_set1_epi32(x as i32) }
    }

    /// `n ^= n * k`, lane by lane (wrapping).
    #[inline(always)]
    unsafe fn xor_mul(n: __m256i, k: u32) -> __m256i {
        unsafe { _mm256_xor_si256(n, _mm256_mullo_epi32(n, splat(k))) }
    }

    /// `sobol_burley::parts::hash_int4`.
    #[inline(always)]
    unsafe fn hash(mut n: __m256i) -> __m256i {
        unsafe {
            n = _mm256_xor_si256(n, splat(0xe6fe_3beb));
            n = _mm256_xor_si256(n, _mm256_srli_epi32::<16>(n));
            n = _mm256_mullo_epi32(n, splat(0x7feb_352d));
            n = _mm256_xor_si256(n, _mm256_srli_epi32::<15>(n));
            n = _mm256_mullo_epi32(n, splat(0x846c_a68b));
            _mm256_xor_si256(n, _mm256_srli_epi32::<16>(n))
        }
    }

    /// `sobol_burley::parts::owen_scramble_int4_rev`.
    #[inline(always)]
    unsafe fn owen_scramble_rev(mut n: __m256i, scramble: __m256i) -> __m256i {
        unsafe {
            n = xor_mul(n, 0x3d20_adea);
            n = _mm256_add_epi32(n, scramble);
            n = _mm256_mullo_epi32(n, _mm256_or_si256(_mm256_srli_epi32::<16>(scramble), splat(1)));
            n = xor_mul(n, 0x0552_6c56);
            xor_mul(n, 0x53a2_2864)
        }
    }

    /// Swaps bit fields of width `W` under `mask` with their neighbours.
    #[inline(always)]
    unsafe fn swap<const W: i32>(n: __m256i, mask: u32) -> __m256i {
        unsafe {
            let m = splat(mask);
            _mm256_or_si256(_mm256_and_si256(_mm256_srli_epi32::<W>(n), m), _mm256_slli_epi32::<W>(_mm256_and_si256(n, m)))
        }
    }

    /// `u32::reverse_bits`, lane by lane.
    #[inline(always)]
    unsafe fn reverse_bits(n: __m256i) -> __m256i {
        unsafe {
            let n = swap::<1>(n, 0x5555_5555);
            let n = swap::<2>(n, 0x3333_3333);
            let n = swap::<4>(n, 0x0f0f_0f0f);
            let n = swap::<8>(n, 0x00ff_00ff);
            _mm256_or_si256(_mm256_srli_epi32::<16>(n), _mm256_slli_epi32::<16>(n))
        }
    }

    /// The two points' four dimensions as floats in [0, 1).
    #[inline(always)]
    pub(super) unsafe fn scramble(points: [[u32; 4]; 2], seeds: [u32; 2]) -> [[f32; 4]; 2] {
        unsafe {
            let [a, b] = points;
            let n = _mm256_loadu_si256([a, b].as_ptr().cast());
            let [s0, s1] = seeds.map(|s| s.wrapping_mul(super::SCRAMBLE_MUL));
            let k = _mm256_loadu_si256([super::DIMENSION_SALTS; 2].as_ptr().cast());
            let seed = _mm256_setr_epi32(s0 as i32, s0 as i32, s0 as i32, s0 as i32, s1 as i32, s1 as i32, s1 as i32, s1 as i32);
            let n = reverse_bits(owen_scramble_rev(n, hash(_mm256_xor_si256(seed, k))));
            // `sobol_burley`'s `to_f32_norm`: the top 23 bits as a mantissa in [1, 2), minus 1.
            let one = _mm256_castsi256_ps(splat(0x3f80_0000));
            let f = _mm256_sub_ps(_mm256_or_ps(_mm256_castsi256_ps(_mm256_srli_epi32::<9>(n)), one), _mm256_set1_ps(1.0));
            let mut out = [[0.0f32; 4]; 2];
            _mm256_storeu_ps(out.as_mut_ptr().cast(), f);
            out
        }
    }
}

/// The first four Sobol dimensions (bit-reversed) of every value of the index's top byte
/// (`[0]`) and next byte (`[1]`), the bytes `sobol_burley` reads of a reversed index.
static SOBOL_BYTE_TABLES: std::sync::LazyLock<[[sobol_burley::parts::Int4; 256]; 2]> = std::sync::LazyLock::new(|| {
    let table = |shift: u32| std::array::from_fn(|b| sobol_burley::parts::sobol_int4_rev((b as u32) << shift, 0));
    [table(24), table(16)]
});

/// Cosine-weighted hemisphere direction around +Z (Malley's method over a concentric disk).
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] in solid angle.
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) / PI
}

/// Shirley-Chiu concentric map from the unit square to the unit disk.
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let x_major = o.x.abs() > o.y.abs();
    let (r, ratio) = if x_major { (o.x, o.y / o.x) } else { (o.y, o.x / o.y) };
    let (sin, cos) = sin_cos_quarter(FRAC_PI_4 * ratio);
    // Past the diagonal the angle is π/2 − φ: its sine and cosine are φ's swapped.
    r * if x_major { Vec2::new(cos, sin) } else { Vec2::new(sin, cos) }
}

/// Sine and cosine of `x` for |x| ≤ π/4, by the minimax polynomials of Cephes' `sinf` and
/// `cosf` (S. Moshier, Cephes Math Library) on that range, which need no range reduction:
/// within an ulp of the exact values (a test checks). libm's general `sincosf`, called here by
/// every cosine-weighted sample, was 2% of a Cornell box render.
#[inline(always)]
fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let z = x * x;
    let sin = (-1.951_529_6e-4f32).mul_add(z, 8.332_161e-3).mul_add(z, -1.666_665_5e-1) * z * x + x;
    let cos = 2.443_315_7e-5f32.mul_add(z, -1.388_731_6e-3).mul_add(z, 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    (sin, cos)
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniform direction in the cone of half-angle acos(`cos_max`) around +Z.
#[inline]
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_t = 1.0 - u.x * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Density of [`uniform_cone`] in solid angle.
#[inline]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Uniform barycentrics (b1, b2) on a triangle (Heitz, "A Low-Distortion Map Between
/// Triangle and Square", 2019).
#[inline]
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    if u.y > u.x {
        let b0 = u.x / 2.0;
        let b1 = u.y - b0;
        Vec2::new(b0, b1)
    } else {
        let b1 = u.y / 2.0;
        let b0 = u.x - b1;
        Vec2::new(b0, b1)
    }
}

/// Veach's power heuristic with β = 2 for two strategies with one sample each.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a == 0.0 {
        return 0.0;
    }
    if !b.is_finite() {
        return 0.0;
    }
    if !a.is_finite() {
        return 1.0;
    }
    a / (a + b)
}

/// A discrete distribution over `n` items proportional to non-negative weights, sampled by
/// binary search over the CDF.
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    cdf: Vec<f32>,
    pmf: Vec<f32>,
}

impl Distribution1D {
    /// Builds from weights; non-finite or negative weights count as zero. When every weight
    /// is zero the distribution is uniform.
    pub fn new(weights: &[f32]) -> Self {
        let w: Vec<f64> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w as f64 } else { 0.0 }).collect();
        let total: f64 = w.iter().sum();
        let n = w.len();
        let pmf: Vec<f32> = if total > 0.0 { w.iter().map(|&x| (x / total) as f32).collect() } else { vec![1.0 / n.max(1) as f32; n] };
        let mut cdf = Vec::with_capacity(n);
        let mut acc = 0.0f64;
        for (i, &p) in pmf.iter().enumerate() {
            acc += p as f64;
            cdf.push(if i + 1 == n { 1.0 } else { acc as f32 });
        }
        Distribution1D { cdf, pmf }
    }

    /// Number of items.
    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    /// True when there is nothing to sample.
    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// Probability of item `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf[i]
    }

    /// An item drawn with `u` in [0, 1), where `u` fell within its CDF step (in [0, 1), for
    /// continuous positions inside the item), and its probability.
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (usize, f32, f32) {
        let (i, p) = self.sample(u);
        let start = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let frac = if p > 0.0 { ((u - start) / p).clamp(0.0, 1.0 - f32::EPSILON) } else { 0.5 };
        (i, frac, p)
    }

    /// An item index drawn with `u` in [0, 1), and its probability.
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let i = self.cdf.partition_point(|&c| c <= u).min(self.pmf.len() - 1);
        // Skip zero-probability items that a boundary value could land on.
        let i = (i..self.pmf.len()).find(|&j| self.pmf[j] > 0.0).unwrap_or(i);
        (i, self.pmf[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sine_and_cosine_are_within_an_ulp() {
        // Every 2^-20 step over [-π/4, π/4] against f64's sin and cos. The values reach
        // 0.707 and 1, where an f32's ulp is 6e-8 (2^-24): measured worst 4.5e-8 (sine) and
        // 5.8e-8 (cosine), one rounding of the result.
        let n = 1 << 20;
        let mut worst: (f64, f64) = (0.0, 0.0);
        for i in -n..=n {
            let x = FRAC_PI_4 * i as f32 / n as f32;
            let (s, c) = sin_cos_quarter(x);
            let (es, ec) = (x as f64).sin_cos();
            worst = (worst.0.max((s as f64 - es).abs()), worst.1.max((c as f64 - ec).abs()));
        }
        assert!(worst.0 <= 6e-8 && worst.1 <= 6e-8, "worst sine, cosine error {worst:?}");
    }

    #[test]
    fn concentric_disk_lands_where_the_trigonometric_map_does() {
        // Shirley and Chiu's map written with f64 trigonometry, on a 513² grid that includes
        // the diagonals, the axes and the square's edges.
        let n = 512;
        for i in 0..=n {
            for j in 0..=n {
                let u = Vec2::new(i as f32 / n as f32, j as f32 / n as f32);
                let o = (2.0 * u.as_dvec2()) - glam::DVec2::ONE;
                let want = if o == glam::DVec2::ZERO {
                    glam::DVec2::ZERO
                } else if o.x.abs() > o.y.abs() {
                    let t = std::f64::consts::FRAC_PI_4 * (o.y / o.x);
                    o.x * glam::DVec2::new(t.cos(), t.sin())
                } else {
                    let t = std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (o.x / o.y);
                    o.y * glam::DVec2::new(t.cos(), t.sin())
                };
                let got = concentric_disk(u).as_dvec2();
                assert!((got - want).abs().max_element() < 3e-7, "u {u}: {got} against {want}");
                assert!(got.length() <= 1.0 + 3e-7, "u {u} leaves the disk: {got}");
            }
        }
    }

    #[test]
    fn byte_table_sobol_is_the_crates_bit_for_bit() {
        // Every index of the crate's range, under seeds from one hash stream (the sampler's
        // seeds are hashes too), and the two seeds whose bits are all equal.
        let mut rng = Pcg32::new(7, 11);
        let seeds: Vec<u32> = (0..6).map(|_| rng.next_u32()).chain([0, u32::MAX]).collect();
        for seed in seeds {
            for index in 0..1u32 << 16 {
                let ours = sobol_4d(index, seed).map(f32::to_bits);
                let crate_s = sobol_burley::sample_4d(index, 0, seed).map(f32::to_bits);
                assert_eq!(ours, crate_s, "index {index}, seed {seed:#x}");
            }
        }
    }

    #[test]
    fn two_sets_at_once_are_two_sets_one_after_the_other() {
        // Every index of the crate's range at a few pixels, both samplers, three draws deep:
        // `next_2x4d` gives the bits of two `next_4d` calls and leaves the sampler where they
        // would.
        for kind in [SamplerKind::Sobol, SamplerKind::Independent] {
            for (x, y) in [(0, 0), (17, 3), (1023, 511)] {
                for index in (0..1u32 << 16).step_by(if kind == SamplerKind::Sobol { 1 } else { 997 }) {
                    let (mut one, mut two) = (PathSampler::for_sample(kind, 9, x, y, index), PathSampler::for_sample(kind, 9, x, y, index));
                    two.next_4d();
                    one.next_4d();
                    for _ in 0..2 {
                        let singles = [one.next_4d(), one.next_4d()].map(|s| s.map(f32::to_bits));
                        assert_eq!(two.next_2x4d().map(|s| s.map(f32::to_bits)), singles, "{kind:?} ({x}, {y}) index {index}");
                    }
                }
            }
        }
    }

    #[test]
    fn sobol_prefixes_are_stratified_per_pixel_and_pixels_differ() {
        // Every power-of-two prefix of one pixel's samples puts exactly one point in each
        // elementary 2D interval of each 4D set's first two dimensions (a (0, 2)-sequence
        // property that Owen scrambling and shuffling keep), while other pixels get
        // different points.
        for (x, y) in [(0, 0), (17, 3), (511, 1023)] {
            for n in [4u32, 16, 64] {
                let side = (n as f32).sqrt() as u32;
                for set in 0..3 {
                    let mut cells = vec![0u32; n as usize];
                    for k in 0..n {
                        let mut s = PathSampler::for_sample(SamplerKind::Sobol, 7, x, y, k);
                        let mut v = [0.0; 4];
                        for _ in 0..=set {
                            v = s.next_4d();
                        }
                        let (cx, cy) = ((v[0] * side as f32) as u32, (v[1] * side as f32) as u32);
                        cells[(cy * side + cx) as usize] += 1;
                    }
                    assert!(cells.iter().all(|&c| c == 1), "pixel ({x}, {y}), {n} samples, set {set}: {cells:?}");
                }
            }
        }
        let first = |x| PathSampler::for_sample(SamplerKind::Sobol, 7, x, 0, 0).next_4d();
        assert_ne!(first(0), first(1));
        // Pure function of (seed, pixel, index).
        assert_eq!(first(5), first(5));
    }

    #[test]
    fn pixel_streams_are_deterministic_and_distinct() {
        let a: Vec<u32> = (0..4).map(|_| 0).scan(PixelSampler::for_sample(7, 3, 4, 5), |r, _| Some(r.next_u32())).collect();
        let b: Vec<u32> = (0..4).map(|_| 0).scan(PixelSampler::for_sample(7, 3, 4, 5), |r, _| Some(r.next_u32())).collect();
        let c: Vec<u32> = (0..4).map(|_| 0).scan(PixelSampler::for_sample(7, 3, 4, 6), |r, _| Some(r.next_u32())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn uniform_floats_have_the_right_mean_and_stay_below_one() {
        let mut r = Pcg32::new(1, 2);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.005);
    }

    #[test]
    fn cosine_hemisphere_matches_its_pdf() {
        // E[1/pdf] over the hemisphere equals its solid angle, 2π.
        let mut r = Pcg32::new(3, 4);
        let n = 200_000;
        let mut acc = 0.0f64;
        for _ in 0..n {
            let d = cosine_hemisphere(r.next_2d());
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-4);
            // integrate cos θ: E[cos/pdf] = π
            acc += (d.z / cosine_hemisphere_pdf(d.z).max(1e-12)) as f64;
        }
        assert!((acc / n as f64 - PI as f64).abs() < 1e-3);
    }

    #[test]
    fn distribution_samples_in_proportion() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        let mut r = Pcg32::new(5, 6);
        let mut counts = [0u32; 3];
        for _ in 0..40_000 {
            counts[d.sample(r.next_f32()).0] += 1;
        }
        assert_eq!(counts[1], 0);
        assert!((counts[2] as f32 / counts[0] as f32 - 3.0).abs() < 0.15);
        assert_eq!(d.pmf(2), 0.75);
    }

    #[test]
    fn power_heuristic_handles_delta_and_zero() {
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert_eq!(power_heuristic(1.0, f32::INFINITY), 0.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-6);
    }
}
