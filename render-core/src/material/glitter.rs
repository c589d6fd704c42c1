//! DreamWorks glitter (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 3): flakes as Worley feature spheres in the object's
//! own (reference) space, each flake's coverage of the shading footprint, up to four GGX flake
//! lobes weighted by coverage, and one lobe standing in for the flakes beyond those four.
//!
//! - **Flake cloud** (section 3.1): one feature point per cell of a grid of side
//!   h = density^(-1/3), jittered uniformly in its cell ([Wor96]'s cellular texture with one
//!   point per cell). Each point is the centre of a feature sphere of radius `size`·h/2 (section
//!   3.4: "the default size of each feature sphere in noise space is 1"; at size 1 the spheres
//!   of a regular lattice would touch). Positions are object-space points, so the flakes stick to
//!   a moving object (section 3.5); the footprint is measured in the same space.
//! - **Coverage** (section 3.2): the shading plane through the hit, normal to the shading
//!   normal, cuts a sphere at distance `dist` in the disk of radius r_f = sqrt(r_fs² − dist²)
//!   (eq. 1) centred at C_fs + dist·N_s (eq. 2). The slides then take the overlap *length* of
//!   that disk and the shading disk over the footprint's diameter (eq. 3); we take the overlap
//!   *area* over the footprint's area instead. For flakes about a pixel wide, as the slides use,
//!   the two agree in ranking and roughly in size, but the length ratio of a flake wholly inside
//!   a large footprint is r_f/r_s where its share of the footprint is (r_f/r_s)²: with many
//!   flakes per footprint, length ratios sum to far more than 1. Area shares of non-overlapping
//!   flakes sum to the covered fraction, so the fallback lobe below gets a weight that means
//!   something. Where flakes overlap, the nearer one covers first and the rest get what is left.
//! - **Lobes** (sections 3.3, 3.6): the four nearest visible flakes become [`Flake`] lobes with
//!   their coverage as weight; the flakes beyond them add their coverage to one fallback lobe.
//!   The slides use the stochastic mirror-flake BRDF of [AK16] there and fade it to "a GGX
//!   microfacet lobe of the same roughness" at high flake counts; we use that GGX limit
//!   throughout (roughness from the flake-normal spread and the flakes' own roughness added in
//!   quadrature; Fresnel from the mean flake colour). Footprints wider than a few cells
//!   (distant objects, rays after rough bounces) skip the per-flake search and use the
//!   fallback alone at the cloud's mean coverage, faded in between so nothing pops.
//! - **Controls** (section 3.4): density, size, flake colour with a random hue per flake,
//!   flake roughness (the GGX spread of flake normals around the shading normal, section 3.4
//!   "Flake roughness"), and each flake's own surface roughness.
//!
//! What the flakes do not cover shows the material beneath (the slides' artists layered the
//! glitter "on top of the baseline surface"): `tessera:Glitter` puts its flakes over the
//! material connected to its `base` input, or over a Lambertian `baseColor`.

use std::sync::OnceLock;

use glam::Vec3;

use super::mix::Mix;
use crate::bsdf::{Bsdf, Flake, GgxReflection, Lobe, SpecularFresnel};
use crate::math::Frame;
use crate::sampling::{Pcg32, mix64};

/// Most flakes that get a lobe of their own at one shading point (section 3.3).
pub const MAX_FLAKE_LOBES: usize = 4;
/// Footprints up to this radius, in cells, resolve individual flakes; wider ones fade to the
/// fallback lobe alone, which they reach at twice this radius.
const RESOLVE_CELLS: f32 = 0.75;
/// Flake density range (feature points per unit of object volume).
pub const DENSITY_RANGE: (f32, f32) = (1e-3, 1e9);

/// Glitter parameters: one coat of flakes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlitterParams {
    /// Flake tint (the Fresnel F0 of a flake).
    pub color: Vec3,
    /// How much of a random hue each flake takes, in [0, 1].
    pub random_color: f32,
    /// GGX roughness of the distribution of flake normals around the shading normal.
    pub spread: f32,
    /// Each flake's own surface roughness.
    pub roughness: f32,
    /// Feature points per unit of object-space volume.
    pub density: f32,
    /// Feature-sphere radius in half cells.
    pub size: f32,
}

impl Default for GlitterParams {
    fn default() -> Self {
        GlitterParams { color: Vec3::splat(0.9), random_color: 0.0, spread: 0.3, roughness: 0.1, density: 4000.0, size: 1.0 }
    }
}

impl Mix for GlitterParams {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        GlitterParams {
            color: self.color.mix(wa, &o.color, wb),
            random_color: self.random_color.mix(wa, &o.random_color, wb),
            spread: self.spread.mix(wa, &o.spread, wb),
            roughness: self.roughness.mix(wa, &o.roughness, wb),
            density: self.density.mix(wa, &o.density, wb),
            size: self.size.mix(wa, &o.size, wb),
        }
    }
}

/// One flake seen at a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlakeHit {
    /// Unit flake normal in object space.
    pub normal: Vec3,
    /// Flake colour.
    pub color: Vec3,
    /// Share of the footprint it covers.
    pub coverage: f32,
}

/// The flakes over one footprint.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Flakes {
    /// The nearest visible flakes, with lobes of their own.
    pub near: [Option<FlakeHit>; MAX_FLAKE_LOBES],
    /// Coverage of the remaining flakes, carried by the fallback lobe.
    pub fallback: f32,
}

impl Flakes {
    /// Share of the footprint covered by flakes, in [0, 1].
    pub fn coverage(&self) -> f32 {
        (self.near.iter().flatten().map(|f| f.coverage).sum::<f32>() + self.fallback).min(1.0)
    }
}

/// Overlap of a disk of radius `rf` at distance `d` with the shading disk of radius `rs`, as a
/// share of the shading disk (a point's inside test when the footprint is a point).
pub fn disk_coverage(rs: f32, rf: f32, d: f32) -> f32 {
    if !(d < rs + rf) {
        return 0.0;
    }
    if rs <= 1e-4 * rf || d + rs <= rf {
        return if d < rf { 1.0 } else { 0.0 };
    }
    if d + rf <= rs {
        return (rf / rs).powi(2);
    }
    // Lens area of two circles, in f64: the acos terms cancel badly in f32 for thin lenses.
    let (r1, r2, d) = (rs as f64, rf as f64, d as f64);
    let a1 = ((d * d + r1 * r1 - r2 * r2) / (2.0 * d * r1)).clamp(-1.0, 1.0).acos();
    let a2 = ((d * d + r2 * r2 - r1 * r1) / (2.0 * d * r2)).clamp(-1.0, 1.0).acos();
    let k = ((-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2) * (d + r1 + r2)).max(0.0).sqrt();
    let lens = r1 * r1 * a1 + r2 * r2 * a2 - 0.5 * k;
    (lens / (std::f64::consts::PI * r1 * r1)).clamp(0.0, 1.0) as f32
}

/// A fully saturated colour of hue `h` in [0, 1).
fn hue(h: f32) -> Vec3 {
    let k = |n: f32| {
        let x = (n + h * 6.0) % 6.0;
        1.0 - (x.min(4.0 - x)).clamp(0.0, 1.0)
    };
    Vec3::new(k(5.0), k(3.0), k(1.0))
}

/// The feature point of cell `c` in cell units, and its random numbers (flake normal, hue).
#[inline]
fn feature(c: [i32; 3]) -> (Vec3, [f32; 3]) {
    let key = mix64((c[0] as u32 as u64) ^ mix64((c[1] as u32 as u64) ^ mix64((c[2] as u32 as u64) ^ 0x91a5_17e2)));
    let mut rng = Pcg32::new(key, 0x6c17);
    let p = Vec3::new(c[0] as f32 + rng.next_f32(), c[1] as f32 + rng.next_f32(), c[2] as f32 + rng.next_f32());
    (p, [rng.next_f32(), rng.next_f32(), rng.next_f32()])
}

/// Mean covered share of a plane at sphere `size` (in half cells): the chance that a point
/// lies inside some feature sphere, which is where its plane meets a flake. It is the CDF of
/// the distance from a point to its nearest feature point (Worley's F1) at size/2 cells,
/// estimated once from 2^16 points (an empirical CDF in 256 bins); without overlaps it would be
/// the packing fraction (4/3)π(size/2)³.
pub fn mean_coverage(size: f32) -> f32 {
    static F1_CDF: OnceLock<Vec<f32>> = OnceLock::new();
    const BINS: usize = 256;
    let cdf = F1_CDF.get_or_init(|| {
        let mut counts = vec![0u32; BINS];
        let mut rng = Pcg32::new(0xf1, 0xcdf);
        let n = 1u32 << 16;
        for _ in 0..n {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 64.0 - 32.0;
            let base = p.floor();
            let mut f1 = f32::INFINITY;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let c = [base.x as i32 + dx, base.y as i32 + dy, base.z as i32 + dz];
                        f1 = f1.min(feature(c).0.distance(p));
                    }
                }
            }
            // F1 < 1 is always found among the 27 neighbours; beyond, it only counts as "far".
            let bin = (f1 * BINS as f32) as usize;
            if bin < BINS {
                counts[bin] += 1;
            }
        }
        let mut acc = 0u32;
        counts
            .iter()
            .map(|c| {
                acc += c;
                acc as f32 / n as f32
            })
            .collect()
    });
    // CDF(x) at x = size/2, linear between bin edges (cdf[i] is the CDF at (i + 1)/BINS).
    let x = (size.max(0.0) * 0.5 * BINS as f32).min(BINS as f32);
    let i = x.floor() as usize;
    let lo = if i == 0 { 0.0 } else { cdf[i - 1] };
    let hi = cdf[i.min(BINS - 1)];
    lo + (hi - lo) * (x - i as f32)
}

impl GlitterParams {
    /// Grid cell side in object units.
    pub fn cell(&self) -> f32 {
        let d = if self.density.is_finite() { self.density.clamp(DENSITY_RANGE.0, DENSITY_RANGE.1) } else { DENSITY_RANGE.0 };
        d.powf(-1.0 / 3.0)
    }

    fn size(&self) -> f32 {
        if self.size.is_finite() { self.size.clamp(0.0, 2.0) } else { 1.0 }
    }

    /// Mean flake colour: a random hue averages 1/2 in each channel.
    pub fn mean_color(&self) -> Vec3 {
        self.color.clamp(Vec3::ZERO, Vec3::ONE) * (1.0 - 0.5 * self.random_color.clamp(0.0, 1.0))
    }

    /// The lobe standing for flakes without a lobe of their own: GGX around the shading normal
    /// whose α² is the flake-normal spread's plus a flake's own (section 3.6's high-count limit).
    pub fn fallback_lobe(&self) -> Lobe {
        let r4 = self.spread.clamp(0.0, 1.0).powi(4) + self.roughness.clamp(crate::bsdf::flake::MIN_FLAKE_ROUGHNESS, 1.0).powi(4);
        Lobe::GgxReflection(GgxReflection::new(r4.sqrt().sqrt(), 0.0, SpecularFresnel::Schlick { f0: self.mean_color() }, false))
    }

    /// The flakes seen far away: no flake of its own, the cloud's mean coverage.
    pub fn far_field(&self) -> Flakes {
        Flakes { near: [None; MAX_FLAKE_LOBES], fallback: mean_coverage(self.size()) }
    }

    /// The flakes over the footprint of radius `radius` around `p` on the plane through `p`
    /// normal to `n` (object space, `n` a unit vector).
    pub fn flakes_at(&self, p: Vec3, n: Vec3, radius: f32) -> Flakes {
        let h = self.cell();
        let (pc, rs) = (p / h, if radius.is_finite() { radius.max(0.0) / h } else { f32::INFINITY });
        // Fade from individual flakes (t = 1) to the far field (t = 0).
        let t = (2.0 - rs / RESOLVE_CELLS).clamp(0.0, 1.0);
        if t == 0.0 || !pc.is_finite() || !n.is_finite() {
            return self.far_field();
        }
        let rfs = 0.5 * self.size();
        let reach = rs + rfs;
        let (lo, hi) = ((pc - reach).floor(), (pc + reach).floor());
        // (distance on the plane, coverage, random numbers) of each visible flake; a footprint
        // of 1.5 cells meets about 20, so more than 64 never show beside the 4 nearest.
        let mut seen = [(0.0f32, 0.0f32, [0.0f32; 3]); 64];
        let mut found = 0;
        for z in lo.z as i32..=hi.z as i32 {
            for y in lo.y as i32..=hi.y as i32 {
                for x in lo.x as i32..=hi.x as i32 {
                    let (c, random) = feature([x, y, z]);
                    let dist = (pc - c).dot(n);
                    if dist.abs() >= rfs {
                        continue;
                    }
                    let rf = (rfs * rfs - dist * dist).sqrt();
                    let d = (c + dist * n).distance(pc);
                    let cov = disk_coverage(rs, rf, d);
                    if cov > 0.0 && found < seen.len() {
                        seen[found] = (d, cov, random);
                        found += 1;
                    }
                }
            }
        }
        let seen = &mut seen[..found];
        seen.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let (mut left, mut near, mut rest, mut count) = (1.0f32, [None; MAX_FLAKE_LOBES], 0.0f32, 0);
        let frame = Frame::from_normal(n);
        let alpha = self.spread.clamp(0.0, 1.0).powi(2);
        for &(_, cov, [u1, u2, u3]) in seen.iter() {
            let share = cov.min(left);
            left -= share;
            if count < MAX_FLAKE_LOBES {
                // GGX-distributed normal around the shading normal (tan²θ = α²u/(1 − u)).
                let tan = alpha * (u1 / (1.0 - u1)).sqrt();
                let cos = 1.0 / (1.0 + tan * tan).sqrt();
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = std::f32::consts::TAU * u2;
                let normal = frame.to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos));
                let color = self.color.clamp(Vec3::ZERO, Vec3::ONE) * Vec3::ONE.lerp(hue(u3), self.random_color.clamp(0.0, 1.0));
                near[count] = Some(FlakeHit { normal, color, coverage: share * t });
                count += 1;
            } else {
                rest += share;
            }
            if left <= 0.0 {
                break;
            }
        }
        // In the fade, the far field's mean coverage takes over what the flakes give up.
        Flakes { near, fallback: t * rest + (1.0 - t) * self.far_field().fallback }
    }

    /// Puts the flakes, at `weight`, over `bsdf`: the material beneath keeps the uncovered
    /// share. `to_local` takes an object-space normal to the BSDF's local frame.
    pub fn apply(&self, weight: f32, flakes: &Flakes, bsdf: &mut Bsdf, to_local: impl Fn(Vec3) -> Vec3) {
        let w = if weight.is_finite() { weight.clamp(0.0, 1.0) } else { 0.0 };
        bsdf.cover(w * flakes.coverage());
        for f in flakes.near.iter().flatten() {
            bsdf.push_weighted(Lobe::Flake(Flake::new(to_local(f.normal), self.roughness, f.color)), w * f.coverage);
        }
        bsdf.push_weighted(self.fallback_lobe(), w * flakes.fallback);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing;
    use crate::sampling::uniform_sphere;

    fn params(size: f32) -> GlitterParams {
        GlitterParams { color: Vec3::ONE, size, density: 1.0, ..GlitterParams::default() }
    }

    /// The shading disk's overlap against brute-force counting on a fine grid.
    #[test]
    fn disk_coverage_is_the_overlap_area_share() {
        for &(rs, rf, d) in &[(1.0f32, 0.5f32, 0.9f32), (1.0, 1.0, 1.0), (0.3, 1.0, 0.9), (1.0, 0.2, 0.5), (1.0, 2.0, 2.5)] {
            let n = 800;
            let mut inside = 0;
            let mut total = 0;
            for i in 0..n {
                for j in 0..n {
                    let (x, y) = (rs * (2.0 * (i as f32 + 0.5) / n as f32 - 1.0), rs * (2.0 * (j as f32 + 0.5) / n as f32 - 1.0));
                    if x * x + y * y < rs * rs {
                        total += 1;
                        inside += ((x - d).powi(2) + y * y < rf * rf) as u32;
                    }
                }
            }
            let brute = inside as f32 / total as f32;
            let c = disk_coverage(rs, rf, d);
            assert!((c - brute).abs() < 3e-3, "rs={rs} rf={rf} d={d}: {c} vs {brute}");
        }
        assert_eq!(disk_coverage(0.0, 0.5, 0.49), 1.0);
        assert_eq!(disk_coverage(0.0, 0.5, 0.51), 0.0);
        assert_eq!(disk_coverage(1.0, 0.5, 1.5), 0.0);
    }

    /// Campbell's theorem: whatever the jitter, the mean number of feature spheres holding a
    /// point is the spheres' volume per cell, (4/3)π(size/2)³; the covered share is at most
    /// that, and equal to it where spheres are too small to overlap often.
    #[test]
    fn flake_cloud_has_the_density_and_coverage_the_sizes_imply() {
        let mut rng = Pcg32::new(9, 9);
        for size in [0.5f32, 1.0, 1.5] {
            let r = 0.5 * size;
            let (n, mut hits) = (40_000, 0u32);
            for _ in 0..n {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
                let b = p.floor();
                for dz in -2..=2 {
                    for dy in -2..=2 {
                        for dx in -2..=2 {
                            let c = [b.x as i32 + dx, b.y as i32 + dy, b.z as i32 + dz];
                            hits += (feature(c).0.distance(p) < r) as u32;
                        }
                    }
                }
            }
            let expected = 4.0 / 3.0 * std::f32::consts::PI * r.powi(3);
            let mean = hits as f32 / n as f32;
            let tol = 4.0 * (expected / n as f32).sqrt();
            assert!((mean - expected).abs() < tol, "size {size}: {mean} spheres per point, expected {expected}");
            let cov = mean_coverage(size);
            assert!(cov <= expected + 0.01, "size {size}: covered {cov} > {expected}");
            if size <= 0.5 {
                assert!((cov - expected).abs() < 0.1 * expected, "size {size}: covered {cov}, packing {expected}");
            }
        }
        let table: Vec<f32> = (0..=20).map(|i| mean_coverage(i as f32 * 0.1)).collect();
        assert!(table.windows(2).all(|w| w[1] >= w[0]) && table[0] == 0.0 && table[20] > 0.99, "{table:?}");
    }

    /// Point footprints (texture filtering off) see flakes in the share the table says, and
    /// every footprint's coverage stays within [0, 1].
    #[test]
    fn queries_cover_the_mean_share_and_never_more_than_all() {
        let g = params(1.0);
        let mut rng = Pcg32::new(4, 1);
        let (n, mut acc) = (20_000, 0.0f64);
        for i in 0..n {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 50.0;
            let normal = uniform_sphere(rng.next_2d());
            let radius = if i % 2 == 0 { 0.0 } else { rng.next_f32() * 2.0 };
            let f = g.flakes_at(p, normal, radius);
            let c = f.coverage();
            assert!((0.0..=1.0 + 1e-6).contains(&c), "{f:?}");
            if radius == 0.0 {
                acc += c as f64;
            }
        }
        let mean = (acc / (n / 2) as f64) as f32;
        let expected = mean_coverage(1.0);
        assert!((mean - expected).abs() < 0.02, "points covered {mean}, table {expected}");
    }

    /// Moving the footprint's radius across the fade changes the covered share continuously,
    /// and beyond it the far field is exactly what is left.
    #[test]
    fn the_fade_to_the_far_field_is_continuous() {
        let g = params(1.0);
        let (p, n) = (Vec3::new(3.3, 7.1, 2.2), Vec3::new(0.3, 0.5, 0.8).normalize());
        let far = g.far_field();
        assert_eq!(g.flakes_at(p, n, 2.0 * RESOLVE_CELLS + 1e-3), far);
        let mut last = g.flakes_at(p, n, 1.0).coverage();
        for k in 1..=200 {
            let r = 1.0 + k as f32 * (2.0 * RESOLVE_CELLS - 1.0) / 200.0;
            let c = g.flakes_at(p, n, r).coverage();
            assert!((c - last).abs() < 0.05, "coverage jumps from {last} to {c} at radius {r}");
            last = c;
        }
        assert!((last - far.coverage()).abs() < 0.02);
    }

    fn glitter_bsdf(g: &GlitterParams, p: Vec3, radius: f32) -> Bsdf {
        let mut base = Bsdf::default();
        base.push(Lobe::Lambert(crate::bsdf::Lambert { r: Vec3::ONE }));
        g.apply(1.0, &g.flakes_at(p, Vec3::Z, radius), &mut base, |n| n);
        base
    }

    /// White flakes over a white base: the whole BSDF conserves energy, is reciprocal and
    /// samples as its pdf says, wherever the shading point falls among the flakes. (Flakes of
    /// roughness 0.2: at 0.1, a flake tilted towards a view 87° off the normal folds its lobe
    /// against the horizon so sharply that the chi-square harness's quadrature of the pdf is
    /// 1% off, beyond its 0.5% tolerance; `bsdf::flake`'s own battery covers sharper flakes at
    /// other tilts.)
    #[test]
    fn glitter_over_a_white_base_passes_the_battery() {
        let g = GlitterParams { spread: 0.5, roughness: 0.2, ..params(1.2) };
        let mut rng = Pcg32::new(5, 6);
        let mut with_flakes = 0;
        for k in 0..12 {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 20.0;
            let radius = [0.0, 0.2, 0.6, 1.2][k % 4];
            let b = glitter_bsdf(&g, p, radius);
            with_flakes += (b.len() > 2) as u32;
            testing::assert_albedo_at_most_one(&b);
            testing::assert_reciprocal(&b);
            if k < 4 {
                testing::assert_chi2(&b, 90 + k as u64);
            }
        }
        assert!(with_flakes >= 6, "only {with_flakes} of 12 points saw a flake");
    }

    /// The fallback lobe stands for the flakes it replaces: averaged over many points, the
    /// flakes reflect as much as the far field does, to 15% within 45° of the normal. Further
    /// down, flakes tilted towards the viewer lose the projected area the binder masks (see
    /// `bsdf::flake`) where a GGX microsurface's facets keep theirs, so near flakes reflect
    /// less than the far field: at 66°, between 75% and 100% of it.
    #[test]
    fn near_flakes_average_to_the_far_field() {
        let g = GlitterParams { color: Vec3::ONE, spread: 0.3, roughness: 0.1, density: 1.0, size: 1.0, random_color: 0.0 };
        let black = |flakes: &Flakes| {
            let mut b = Bsdf::default();
            g.apply(1.0, flakes, &mut b, |n| n);
            b
        };
        let far = black(&g.far_field());
        let mut rng = Pcg32::new(8, 8);
        for cos in [1.0f32, 0.7, 0.4] {
            let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let (n, mut near) = (3000, Vec3::ZERO);
            for _ in 0..n {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
                near += testing::albedo_estimate(&black(&g.flakes_at(p, Vec3::Z, 0.0)), wo, 64);
            }
            let near = near / n as f32;
            let far = testing::albedo_estimate(&far, wo, 20_000);
            let ratio = near.x / far.x;
            let ok = if cos >= 0.7 { (ratio - 1.0).abs() < 0.15 } else { (0.75..=1.0).contains(&ratio) };
            assert!(ok, "cos {cos}: near {near:?}, far {far:?}");
        }
    }
}
