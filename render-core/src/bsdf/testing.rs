//! The statistical test battery every lobe runs: white furnace, reciprocity, chi-square
//! goodness of fit of `sample` against `pdf` (the method of pbrt-v4's `bsdfs_test.cpp` and
//! Mitsuba 3's `chi2.py`: equal-area bins in (cos θ, φ), cells with expected count below 5
//! pooled, a Šidák-corrected significance level), and sample weights equal to f·cos/pdf.

use std::f64::consts::PI;

use glam::{Vec2, Vec3};

use super::{Bsdf, Lobe, LobeSample};
use crate::sampling::Pcg32;

/// What the battery needs of a scattering function: a lobe, or a whole BSDF.
pub trait Scatter: std::fmt::Debug {
    /// f(wo, wi).
    fn f(&self, wo: Vec3, wi: Vec3) -> Vec3;
    /// Sample.
    fn sample_dir(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample>;
    /// Density of `sample_dir`.
    fn density(&self, wo: Vec3, wi: Vec3) -> f32;
    /// `f` and `density` in one call (`eval_pdf`; a test double need not have one).
    fn f_and_density(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        (self.f(wo, wi), self.density(wo, wi))
    }
    /// Runs `with` on this scatterer made ready for the one view `wo`: a BSDF prepares a copy
    /// once (lobe selection, table lookups), as the renderer does per shading point, instead of
    /// at every call (the whole principled BSDF's χ² test took 25 s that way, 14 s now).
    fn seen_from<R>(&self, _wo: Vec3, with: impl FnOnce(&dyn Scatter) -> R) -> R
    where
        Self: Sized,
    {
        with(self)
    }
}

impl Scatter for Lobe {
    fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval(wo, wi)
    }
    fn sample_dir(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample> {
        self.sample(wo, uc, u)
    }
    fn density(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.pdf(wo, wi)
    }
    fn f_and_density(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.eval_pdf(wo, wi)
    }
}

/// A BSDF, prepared for each `wo` it is asked about.
impl Scatter for Bsdf {
    fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval(wo, wi)
    }
    fn sample_dir(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample> {
        self.seen_from(wo, |b| b.sample_dir(wo, uc, u))
    }
    fn density(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.seen_from(wo, |b| b.density(wo, wi))
    }
    fn f_and_density(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.seen_from(wo, |b| b.f_and_density(wo, wi))
    }
    fn seen_from<R>(&self, wo: Vec3, with: impl FnOnce(&dyn Scatter) -> R) -> R {
        let mut b = self.clone();
        b.prepare(wo);
        with(&Prepared(b))
    }
}

/// A BSDF prepared for the one `wo` it is asked about (`Scatter::seen_from`).
#[derive(Debug)]
struct Prepared(Bsdf);

impl Scatter for Prepared {
    fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.0.eval(wo, wi)
    }
    fn sample_dir(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample> {
        self.0.sample(wo, uc, u)
    }
    fn density(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn f_and_density(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.0.eval_pdf(wo, wi)
    }
}

/// Directions `wo` the battery probes, down to grazing (cos θ = 1e-4).
pub fn probe_directions() -> Vec<Vec3> {
    [1.0f32, 0.8, 0.5, 0.2, 0.05, 1e-2, 1e-4]
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let s = (1.0 - c * c).max(0.0).sqrt();
            let phi = 0.7 + i as f32;
            Vec3::new(s * phi.cos(), s * phi.sin(), c)
        })
        .collect()
}

/// ∫ f(ω) dω over the upper hemisphere by n × n midpoints in (cos θ, φ) (equal solid angles),
/// summed in f64: for closed forms that need a reference with no sampling noise.
pub fn hemisphere_integral(n: usize, f: impl Fn(Vec3) -> f32) -> f64 {
    let mut acc = 0.0f64;
    for i in 0..n {
        let z = (i as f32 + 0.5) / n as f32;
        let s = (1.0 - z * z).sqrt();
        for j in 0..n {
            let phi = 2.0 * std::f32::consts::PI * (j as f32 + 0.5) / n as f32;
            acc += f(Vec3::new(s * phi.cos(), s * phi.sin(), z)) as f64;
        }
    }
    acc * 2.0 * PI / (n * n) as f64
}

/// Monte Carlo estimate of the directional albedo ∫ f·|cos| dωi via the lobe's own sampling,
/// in energy: transmitted samples have their radiance scaling 1/η'² undone.
pub fn albedo_estimate(lobe: &impl Scatter, wo: Vec3, n: u32) -> Vec3 {
    let mut rng = Pcg32::new(17, 23);
    let mut acc = glam::DVec3::ZERO;
    for _ in 0..n {
        if let Some(s) = lobe.sample_dir(wo, rng.next_f32(), rng.next_2d()) {
            assert!(crate::math::is_finite(s.weight) && s.weight.min_element() >= 0.0, "bad weight {:?}", s.weight);
            acc += (s.weight * s.eta * s.eta).as_dvec3();
        }
    }
    (acc / n as f64).as_vec3()
}

/// Which sides of the surface the battery looks from.
#[derive(Clone, Copy, Debug)]
pub enum Sides {
    /// Reflecting lobes: `wo` above the surface only.
    Above,
    /// Transmitting lobes: `wo` above and below (inside the medium of index `eta_below`).
    Both,
}

impl Sides {
    /// The probe directions on these sides.
    pub fn directions(self) -> Vec<Vec3> {
        match self {
            Sides::Above => probe_directions(),
            Sides::Both => probe_directions().into_iter().flat_map(|w| [w, -w]).collect(),
        }
    }
}

/// White furnace: albedo ≤ 1 + 1e-3 (plus Monte Carlo slack) at every probe direction.
pub fn assert_albedo_at_most_one(lobe: &impl Scatter) {
    assert_albedo_at_most_one_from(lobe, Sides::Above);
}

/// The white furnace from the given sides.
pub fn assert_albedo_at_most_one_from(lobe: &impl Scatter, sides: Sides) {
    for wo in sides.directions() {
        let a = albedo_estimate(lobe, wo, 50_000);
        assert!(a.max_element() <= 1.0 + 1e-3 + 0.01, "albedo {a:?} > 1 at wo={wo:?} for {lobe:?}");
    }
}

/// f(wo, wi) = f(wi, wo) to 1e-4 relative for random direction pairs.
pub fn assert_reciprocal(lobe: &impl Scatter) {
    assert_reciprocal_across(lobe, 1.0);
}

/// Veach's generalised reciprocity for radiance BSDFs between media (thesis, eq. 5.14):
/// f(wo, wi)/η_o² = f(wi, wo)/η_i², with index 1 above the surface and `eta_below` below.
/// With `eta_below` = 1 this is plain symmetry.
pub fn assert_reciprocal_across(lobe: &impl Scatter, eta_below: f32) {
    let n2 = |w: Vec3| if w.z > 0.0 { 1.0 } else { eta_below * eta_below };
    let mut rng = Pcg32::new(5, 9);
    for _ in 0..1000 {
        let a = crate::sampling::uniform_sphere(rng.next_2d());
        let b = crate::sampling::uniform_sphere(rng.next_2d());
        let f1 = lobe.f(a, b) / n2(a);
        let f2 = lobe.f(b, a) / n2(b);
        let scale = f1.abs().max(f2.abs()).max_element().max(1e-6);
        assert!((f1 - f2).abs().max_element() <= 1e-4 * scale, "f({a:?},{b:?})={f1:?} but reversed {f2:?}");
    }
}

/// For sampled directions, the returned weight equals eval·|cos θi|/pdf and pdf matches
/// `Lobe::pdf`.
pub fn assert_weights_consistent(lobe: &impl Scatter) {
    assert_weights_consistent_from(lobe, Sides::Above);
}

/// Sample weights against eval and pdf from the given sides.
pub fn assert_weights_consistent_from(lobe: &impl Scatter, sides: Sides) {
    let mut rng = Pcg32::new(77, 1);
    for wo in sides.directions() {
        for _ in 0..2000 {
            let Some(s) = lobe.sample_dir(wo, rng.next_f32(), rng.next_2d()) else {
                continue;
            };
            if s.flags.delta {
                continue;
            }
            let pdf = lobe.density(wo, s.wi);
            assert!((pdf - s.pdf).abs() <= 1e-3 * pdf.max(1e-3), "pdf {pdf} vs sampled {}", s.pdf);
            let w = lobe.f(wo, s.wi) * s.wi.z.abs() / pdf;
            assert!((w - s.weight).abs().max_element() <= 1e-3 * w.max_element().max(1e-3), "weight {:?} vs {:?}", s.weight, w);
        }
    }
}

/// `eval_pdf` against `eval` and `pdf` called apart, bit for bit, at directions from the
/// given sides to every direction of the sphere (uniform, so grazing and opposite sides
/// included) and to the lobe's own samples.
pub fn assert_eval_pdf_is_both(lobe: &impl Scatter, sides: Sides) {
    let mut rng = Pcg32::new(91, 5);
    let bits = |(f, p): (Vec3, f32)| (f.to_array().map(f32::to_bits), p.to_bits());
    for wo in sides.directions() {
        for k in 0..2000 {
            let sampled = (k % 2 == 0).then(|| lobe.sample_dir(wo, rng.next_f32(), rng.next_2d())).flatten();
            let wi = sampled.map_or_else(|| crate::sampling::uniform_sphere(rng.next_2d()), |s| s.wi);
            let apart = (lobe.f(wo, wi), lobe.density(wo, wi));
            assert_eq!(bits(lobe.f_and_density(wo, wi)), bits(apart), "{lobe:?} wo {wo} wi {wi}: {apart:?}");
        }
    }
}

/// The battery every lobe runs, as the same five tests in each lobe's test module:
/// `battery_white_furnace` (albedo ≤ 1 at every probe direction), `battery_reciprocity`,
/// `battery_chi_square` (`sample` against `pdf`, lobe k with seed `seed + k`) and
/// `battery_sample_weights` (weight = f·cos/pdf, pdf as `pdf` says), and
/// `battery_eval_pdf_is_eval_and_pdf` (the one-call pair, bit for bit). `lobes` are the lobes
/// (a `Vec<Lobe>`); `chi_square` those whose pdf the harness's quadrature resolves.
/// Transmitting lobes add `index_below: |lobe| η`: every test then looks from both sides,
/// and reciprocity is the generalised one between media of index 1 and η. A model that is not
/// reciprocal by construction (Chiang's hair) adds `reciprocal: false` and says why.
macro_rules! lobe_battery {
    (lobes: $lobes:expr, chi_square: $chi:expr, seed: $seed:expr $(,)?) => {
        $crate::bsdf::testing::lobe_battery!(@tests $lobes, $chi, $seed, $crate::bsdf::testing::Sides::Above, |_| 1.0);
    };
    (lobes: $lobes:expr, chi_square: $chi:expr, seed: $seed:expr, index_below: $eta:expr $(,)?) => {
        $crate::bsdf::testing::lobe_battery!(@tests $lobes, $chi, $seed, $crate::bsdf::testing::Sides::Both, $eta);
    };
    (lobes: $lobes:expr, chi_square: $chi:expr, seed: $seed:expr, index_below: $eta:expr, reciprocal: false $(,)?) => {
        $crate::bsdf::testing::lobe_battery!(@common $lobes, $chi, $seed, $crate::bsdf::testing::Sides::Both);
    };
    (@tests $lobes:expr, $chi:expr, $seed:expr, $sides:expr, $eta:expr) => {
        $crate::bsdf::testing::lobe_battery!(@common $lobes, $chi, $seed, $sides);

        #[test]
        fn battery_reciprocity() {
            for lobe in $lobes {
                $crate::bsdf::testing::assert_reciprocal_across(&lobe, ($eta)(&lobe));
            }
        }
    };
    (@common $lobes:expr, $chi:expr, $seed:expr, $sides:expr) => {
        #[test]
        fn battery_white_furnace() {
            for lobe in $lobes {
                $crate::bsdf::testing::assert_albedo_at_most_one_from(&lobe, $sides);
            }
        }

        #[test]
        fn battery_chi_square() {
            for (k, lobe) in $chi.into_iter().enumerate() {
                $crate::bsdf::testing::assert_chi2_at(&lobe, $seed + k as u64, $sides.directions());
            }
        }

        #[test]
        fn battery_sample_weights() {
            for lobe in $lobes {
                $crate::bsdf::testing::assert_weights_consistent_from(&lobe, $sides);
            }
        }

        #[test]
        fn battery_eval_pdf_is_eval_and_pdf() {
            for lobe in $lobes {
                $crate::bsdf::testing::assert_eval_pdf_is_both(&lobe, $sides);
            }
        }
    };
}
pub(crate) use lobe_battery;

const THETA_BINS: usize = 20;
const PHI_BINS: usize = 40;
const SAMPLES: u32 = 400_000;
/// Overall significance level; divided among the tests of one lobe by Šidák's correction.
const ALPHA: f64 = 0.01;

fn bin_of(w: Vec3) -> usize {
    let theta = (w.z as f64).clamp(-1.0, 1.0).acos();
    let c = (theta / PI * THETA_BINS as f64).floor().clamp(0.0, THETA_BINS as f64 - 1.0) as usize;
    let phi = (w.y as f64).atan2(w.x as f64).rem_euclid(2.0 * PI);
    let p = (phi / (2.0 * PI) * PHI_BINS as f64).floor().clamp(0.0, PHI_BINS as f64 - 1.0) as usize;
    c * PHI_BINS + p
}

/// Chi-square test of `sample` against `pdf` at every probe direction.
pub fn assert_chi2(lobe: &impl Scatter, seed: u64) {
    chi2_over(lobe, seed, probe_directions());
}

/// The chi-square test at the given `wo` directions.
pub fn assert_chi2_at(lobe: &impl Scatter, seed: u64, dirs: Vec<Vec3>) {
    chi2_over(lobe, seed, dirs);
}

/// The delta directions a sampler returned at one `wo`: each direction, the energy weight
/// (f·cos/p, times η'² to undo radiance scaling) its samples carry, and how often it came.
/// A delta sample's pdf is a convention (1 per lobe, times the lobe's selection), so the test
/// is on weights: the same direction always carries the same weight, and the delta part's
/// energy is what its frequency times its weight says.
#[derive(Default)]
pub struct DeltaTally(Vec<(Vec3, Vec3, u32)>, u32);

impl DeltaTally {
    fn add(&mut self, s: &LobeSample) {
        assert!(crate::math::is_finite(s.weight) && s.weight.min_element() >= 0.0, "delta weight {:?}", s.weight);
        let w = s.weight * s.eta * s.eta;
        match self.0.iter_mut().find(|(d, _, _)| (*d - s.wi).length() < 1e-4) {
            Some((d, seen, n)) => {
                assert!(
                    (*seen - w).abs().max_element() <= 1e-4 * seen.max_element().max(1e-6),
                    "delta direction {d:?} carries weights {seen:?} and {w:?}"
                );
                *n += 1;
            }
            None => self.0.push((s.wi, w, 1)),
        }
        self.1 += 1;
    }

    /// The share of samples that were delta.
    fn share(&self) -> f64 {
        self.1 as f64 / SAMPLES as f64
    }

    /// The delta part's directional albedo: Σ frequency × energy weight.
    pub fn energy(&self) -> Vec3 {
        self.0.iter().fold(Vec3::ZERO, |acc, &(_, w, n)| acc + w * (n as f32 / SAMPLES as f32))
    }
}

/// The delta part of `lobe`'s sampling at `wo`, tallied over the chi-square test's sample
/// count.
pub fn delta_part(lobe: &impl Scatter, wo: Vec3, seed: u64) -> DeltaTally {
    let mut rng = Pcg32::new(seed, 0);
    let mut deltas = DeltaTally::default();
    for _ in 0..SAMPLES {
        if let Some(s) = lobe.sample_dir(wo, rng.next_f32(), rng.next_2d()).filter(|s| s.flags.delta) {
            deltas.add(&s);
        }
    }
    deltas
}

fn chi2_over(lobe: &impl Scatter, seed: u64, dirs: Vec<Vec3>) {
    let alpha = 1.0 - (1.0 - ALPHA).powf(1.0 / dirs.len() as f64);
    for (k, wo) in dirs.into_iter().enumerate() {
        let mut rng = Pcg32::new(seed, k as u64);
        let mut observed = vec![0.0f64; THETA_BINS * PHI_BINS];
        // Delta samples are tested apart: the pdf is the smooth part's density only.
        let mut deltas = DeltaTally::default();
        let expected = lobe.seen_from(wo, |seen| {
            for _ in 0..SAMPLES {
                match seen.sample_dir(wo, rng.next_f32(), rng.next_2d()) {
                    Some(s) if s.flags.delta => deltas.add(&s),
                    Some(s) => observed[bin_of(s.wi.normalize())] += 1.0,
                    None => {}
                }
            }
            expected_counts(|wi| seen.density(wo, wi))
        });
        let what = format!("{lobe:?} at wo={wo:?}");
        // The smooth pdf integrates to at most 1 less the delta part, and to the fraction of
        // samples returned smooth (to the integration's 0.5%, reached on grazing lobes a
        // degree wide).
        let mass = expected.iter().sum::<f64>() / SAMPLES as f64;
        let returned = observed.iter().sum::<f64>() / SAMPLES as f64;
        let delta_share = deltas.share();
        assert!(mass + delta_share <= 1.0 + 5e-3, "pdf of {what} integrates to {mass} besides delta samples {delta_share}");
        assert!((mass - returned).abs() <= 5e-3, "pdf of {what} integrates to {mass} but {returned} of samples were returned smooth");
        let (stat, dof) = chi2_statistic(&observed, &expected);
        if dof == 0 {
            continue;
        }
        let p = chi2_survival(stat, dof as f64);
        assert!(p > alpha, "chi-square rejects sampling of {what}: stat={stat:.1}, dof={dof}, p={p:.3e} < {alpha:.3e}");
    }
}

/// Expected counts per bin: the pdf integrated over each (θ, φ) cell (with the sin θ
/// Jacobian) times the sample count. Two integrators, because neither suffices alone:
/// a quadtree of 4×4 midpoint rules resolves grazing lobes a degree wide, but lattice
/// points miss or hit the integrable singularities of refraction at the critical cone (one
/// bin at cos θo = 0.01, η = 1/1.5 reads 0, 1017, 763 and 779 with 4², 16², 64², 1024²
/// points; brute force gives 777); jittered stratified Monte Carlo is unbiased there.
/// Each bin uses the quadtree unless a 32² stratified estimate disagrees, and then 256²
/// stratified samples.
fn expected_counts(pdf: impl Fn(Vec3) -> f32) -> Vec<f64> {
    let (dt, dp) = (PI / THETA_BINS as f64, 2.0 * PI / PHI_BINS as f64);
    let mut rng = Pcg32::new(0xe4, 0x51);
    let mut expected = vec![0.0f64; THETA_BINS * PHI_BINS];
    for ci in 0..THETA_BINS {
        for pi in 0..PHI_BINS {
            let (t0, p0) = (ci as f64 * dt, pi as f64 * dp);
            let q = integrate_cell(&pdf, t0, t0 + dt, p0, p0 + dp, 0) * SAMPLES as f64;
            let m = stratified(&pdf, &mut rng, t0, t0 + dt, p0, p0 + dp, 32) * SAMPLES as f64;
            expected[ci * PHI_BINS + pi] = if (q - m).abs() <= 0.03 * q.max(m) + 3.0 {
                q
            } else {
                stratified(&pdf, &mut rng, t0, t0 + dt, p0, p0 + dp, 256) * SAMPLES as f64
            };
        }
    }
    expected
}

/// ∫ pdf over a cell by jittered stratified sampling, strata equal in φ and in cos θ, except
/// that cells touching the horizon or a pole place their strata on a cubic warp towards it:
/// transmission from inside at grazing angles leaves through steep microfacets into a sliver
/// z < 3e-4 just above the horizon, a 500th of the cell, and the sharpest clearcoat
/// (α = 0.001) peaks within 1 − z < 1e-5 of the pole; equal strata missed both.
fn stratified(pdf: &impl Fn(Vec3) -> f32, rng: &mut Pcg32, t0: f64, t1: f64, p0: f64, p1: f64, n: usize) -> f64 {
    let (c0, c1) = (t0.cos(), t1.cos());
    // z = edge + (far − edge)·t³, dz = 3t²(far − edge) dt, with `edge` the horizon when touched.
    let (edge, far, warp) = if c1.abs() < 1e-9 || c1 < -1.0 + 1e-9 {
        (c1, c0, true)
    } else if c0.abs() < 1e-9 || c0 > 1.0 - 1e-9 {
        (c0, c1, true)
    } else {
        (c0, c1, false)
    };
    let mut acc = 0.0;
    for a in 0..n {
        for b in 0..n {
            let t = (a as f64 + rng.next_f32() as f64) / n as f64;
            let (z, jacobian) = if warp { (edge + (far - edge) * t.powi(5), 5.0 * t.powi(4)) } else { (edge + (far - edge) * t, 1.0) };
            let phi = p0 + (p1 - p0) * (b as f64 + rng.next_f32() as f64) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            acc += pdf(Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)) as f64 * jacobian;
        }
    }
    acc / (n * n) as f64 * (c0 - c1).abs() * (p1 - p0)
}

fn midpoint(pdf: &impl Fn(Vec3) -> f32, t0: f64, t1: f64, p0: f64, p1: f64) -> f64 {
    const N: usize = 4;
    let (ht, hp) = ((t1 - t0) / N as f64, (p1 - p0) / N as f64);
    let mut acc = 0.0;
    for a in 0..N {
        let theta = t0 + (a as f64 + 0.5) * ht;
        let (st, ct) = theta.sin_cos();
        for b in 0..N {
            let phi = p0 + (b as f64 + 0.5) * hp;
            acc += pdf(Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32)) as f64 * st;
        }
    }
    acc * ht * hp
}

/// Quadtree refinement where a 4×4 midpoint rule and its four children disagree.
fn integrate_cell(pdf: &impl Fn(Vec3) -> f32, t0: f64, t1: f64, p0: f64, p1: f64, depth: u32) -> f64 {
    let (tm, pm) = (0.5 * (t0 + t1), 0.5 * (p0 + p1));
    let coarse = midpoint(pdf, t0, t1, p0, p1);
    let children = [(t0, tm, p0, pm), (t0, tm, pm, p1), (tm, t1, p0, pm), (tm, t1, pm, p1)];
    let fine: f64 = children.iter().map(|&(a, b, c, d)| midpoint(pdf, a, b, c, d)).sum();
    if (fine - coarse).abs() <= (1e-3 * fine).max(0.02 / SAMPLES as f64) || depth >= 7 {
        return fine;
    }
    children.iter().map(|&(a, b, c, d)| integrate_cell(pdf, a, b, c, d, depth + 1)).sum()
}

/// Pearson's statistic with cells of expected count < 5 pooled (pbrt's approach).
fn chi2_statistic(observed: &[f64], expected: &[f64]) -> (f64, usize) {
    // Samples where the integrated pdf is zero mean the sampler and pdf disagree, unless they
    // are a handful landing in a sliver the quadrature cannot resolve (e.g. at the edge of
    // total internal reflection); those are pooled with the other small cells.
    let stray: f64 = observed.iter().zip(expected).filter(|(_, e)| **e == 0.0).map(|(o, _)| *o).sum();
    assert!(stray <= 1e-4 * observed.iter().sum::<f64>(), "{stray} samples landed in bins of zero density");
    let mut idx: Vec<usize> = (0..observed.len()).collect();
    idx.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut pooled_o, mut pooled_e, mut stat, mut dof) = (0.0, 0.0, 0.0, 0usize);
    for &i in &idx {
        if expected[i] < 5.0 {
            pooled_o += observed[i];
            pooled_e += expected[i];
        } else {
            let d = observed[i] - expected[i];
            stat += d * d / expected[i];
            dof += 1;
        }
    }
    if pooled_e > 0.0 {
        let d = pooled_o - pooled_e;
        stat += d * d / pooled_e;
        dof += 1;
    }
    (stat, dof.saturating_sub(1))
}

/// P[X ≥ x] for X ~ χ²(k): the regularised upper incomplete gamma Q(k/2, x/2).
pub fn chi2_survival(x: f64, k: f64) -> f64 {
    gamma_q(k / 2.0, x / 2.0)
}

fn ln_gamma(x: f64) -> f64 {
    // Lanczos approximation (g = 7, n = 9).
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    if x < a + 1.0 {
        // Series for P, then Q = 1 - P.
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - ln_gamma(a)).exp()
    } else {
        // Continued fraction (Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - ln_gamma(a)).exp() * h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_survival_matches_tables() {
        // Critical values from standard χ² tables.
        assert!((chi2_survival(3.841, 1.0) - 0.05).abs() < 1e-3);
        assert!((chi2_survival(18.307, 10.0) - 0.05).abs() < 1e-3);
        assert!((chi2_survival(124.342, 100.0) - 0.05).abs() < 1e-3);
    }

    /// Half smooth glass (two delta directions) and half Lambert: the smooth part is tested
    /// against its pdf, the delta part's directions against their claimed probabilities.
    /// Before, the first delta sample ended the test and a mixed BSDF passed unexamined.
    #[test]
    fn mixed_delta_and_smooth_bsdfs_test_both_parts() {
        use crate::bsdf::{Dielectric, Lambert};
        let mut b = Bsdf::default();
        b.push_weighted(Lobe::Dielectric(Dielectric::new(0.0, 0.0, 1.5, Vec3::ONE)), 0.5);
        b.push_weighted(Lobe::Lambert(Lambert { r: Vec3::splat(0.8) }), 0.5);
        let dirs: Vec<Vec3> = probe_directions().into_iter().filter(|w| w.z >= 1e-2).collect();
        assert_chi2_at(&b, 31, dirs.clone());
        // The delta part is half the BSDF, and clear glass loses nothing: its energy is 1/2 at
        // every angle (binomial noise of the reflect/refract choice over 400k samples: σ ≈ 1e-3).
        for wo in dirs {
            let e = delta_part(&b, wo, 32).energy();
            assert!((e - Vec3::splat(0.5)).abs().max_element() < 5e-3, "delta energy {e:?} at {wo:?}");
        }
        // A delta part whose weights vary for one direction is caught.
        #[derive(Debug)]
        struct Wobbly(Bsdf);
        impl Scatter for Wobbly {
            fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
                self.0.f(wo, wi)
            }
            fn sample_dir(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample> {
                self.0.sample_dir(wo, uc, u).map(|s| if s.flags.delta { LobeSample { weight: s.weight * (1.0 + u.x), ..s } } else { s })
            }
            fn density(&self, wo: Vec3, wi: Vec3) -> f32 {
                self.0.density(wo, wi)
            }
        }
        let wobbly = std::panic::catch_unwind(|| delta_part(&Wobbly(b.clone()), Vec3::Z, 33));
        assert!(wobbly.is_err(), "a delta direction with varying weights must fail");
    }

    #[test]
    fn chi2_catches_a_sampler_that_disagrees_with_its_pdf() {
        // A Lambert lobe sampled uniformly over the hemisphere but claiming a cosine pdf.
        let observed_uniform = {
            let mut rng = Pcg32::new(1, 1);
            let mut o = vec![0.0f64; THETA_BINS * PHI_BINS];
            for _ in 0..SAMPLES {
                let u: Vec2 = rng.next_2d();
                let w = crate::sampling::uniform_sphere(u);
                let w = Vec3::new(w.x, w.y, w.z.abs());
                o[bin_of(w)] += 1.0;
            }
            o
        };
        let lobe = Lobe::Lambert(super::super::Lambert { r: Vec3::ONE });
        let e = expected_counts(|wi| lobe.pdf(Vec3::Z, wi));
        let (stat, dof) = chi2_statistic(&observed_uniform, &e);
        assert!(chi2_survival(stat, dof as f64) < 1e-6);
    }
}
