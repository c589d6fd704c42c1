//! A `DomeLight` with a latitude-longitude texture, importance-sampled in proportion to the
//! bilinear interpolation of luminance × sin θ at the texel centres ([`super::bilinear`]): the
//! radiance its lookups return, times the solid angle a unit of image area covers. The map's
//! coordinates and the sin θ change of density are pbrt's infinite area light's (Pharr, Jakob &
//! Humphreys, *Physically Based Rendering*, 3rd ed., section 14.2.4).
//!
//! Orientation is UsdLux's, which follows OpenEXR's latitude-longitude convention: the image's
//! top row is latitude +π/2 (the dome's +Y), its left column longitude +π; latitude 0 and
//! longitude 0 look along +Z, longitude π/2 along +X.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{Mat3, Vec2, Vec3};

use super::bilinear::Bilinear2D;
use crate::texture::{Texture, Wrap};

/// Largest distribution grid side along longitude: a coarser mip is used for bigger maps.
const MAX_GRID_WIDTH: usize = 1024;

/// The finer grid a map wider than [`MAX_GRID_WIDTH`] may take.
const FINE_GRID_WIDTH: usize = 2048;

/// The relative variance per sample the coarse grid must leave against the fine one's values
/// before the fine grid is taken. The fine grid costs about 16% more time on every map, so it
/// must cut a pixel's variance per sample by more than a sixth. On a 4 096 × 2 048 sky over a
/// white floor (`docs/benchmarks.md`, 2026-12-07 13:40 UTC), a 36-texel sun left 0.33 here and
/// the pixels' own relative variance per sample fell from 0.63 to 0.35 on the fine grid; the
/// same sky without its sun left 0.0002.
const FINE_GRID_EXCESS: f64 = 0.1;

/// Every node keeps this share of the mean node weight, so that no direction has zero density.
const FLOOR: f32 = 1e-2;

/// A dome's map and its sampling distribution, which depend on the texture alone: commits that
/// read the same texture share one (`BlasCache` keeps it), since building the distribution of
/// a 1 024 × 512 grid took 28 ms, which every edit of an interactive session paid again.
#[derive(Debug)]
pub struct DomeMap {
    texture: Arc<Texture>,
    distribution: Bilinear2D,
    mean: Vec3,
}

/// A [`DomeMap`] placed by a dome's rotation.
#[derive(Debug)]
pub struct EnvironmentMap {
    map: Arc<DomeMap>,
    to_world: Mat3,
    to_local: Mat3,
}

/// A dome's rotation from its transform's 3×3 part: the axes normalised (the scale removed);
/// the identity when an axis collapses. Between motion samples, the interpolated axes so
/// normalised follow the turn's arc.
pub fn dome_rotation(m: Mat3) -> Mat3 {
    let axes = [m.x_axis, m.y_axis, m.z_axis].map(|a| a.normalize_or_zero());
    if axes.contains(&Vec3::ZERO) { Mat3::IDENTITY } else { Mat3::from_cols(axes[0], axes[1], axes[2]) }
}

/// Luminance × sin θ at the texel centres of one mip level of a map: the density a dome's
/// samples should follow, before the floor.
struct Grid {
    width: usize,
    height: usize,
    values: Vec<f32>,
}

impl Grid {
    /// The grid of `texture`'s mip `level`, and the map's mean radiance read from it.
    fn at(texture: &Texture, level: usize) -> (Grid, Vec3) {
        let (tw, th) = texture.size();
        let (width, height) = ((tw >> level).max(1), (th >> level).max(1));
        let mut values = vec![0.0f32; width * height];
        let (mut sum, mut solid) = (Vec3::ZERO, 0.0);
        for y in 0..height {
            let v = (y as f32 + 0.5) / height as f32;
            let sin_theta = (PI * v).sin();
            for x in 0..width {
                let st = Vec2::new((x as f32 + 0.5) / width as f32, 1.0 - v);
                let c = texture.lookup(st, level as f32, [Wrap::Repeat, Wrap::Clamp]).truncate().max(Vec3::ZERO);
                let c = if c.is_finite() { c } else { Vec3::ZERO };
                values[y * width + x] = crate::math::luminance(c) * sin_theta;
                sum += c * sin_theta;
                solid += sin_theta;
            }
        }
        let mean = if solid > 0.0 { sum / solid } else { Vec3::ZERO };
        (Grid { width, height, values }, mean)
    }

    /// The distribution of these values, each raised by the floor.
    fn distribution(&self) -> Bilinear2D {
        let mean = self.values.iter().sum::<f32>() / self.values.len() as f32;
        let floor = FLOOR * mean.max(1e-20);
        Bilinear2D::new(self.width, self.height, self.values.iter().map(|w| w + floor).collect())
    }

    /// The relative variance per sample that `density` leaves in estimating these values'
    /// integral, E[f²/q]/E[f]² − 1 over the texel centres: what a coarser grid's interpolant
    /// costs where it spreads a small bright feature.
    fn excess_under(&self, density: &Bilinear2D) -> f64 {
        let (mut f, mut f2_over_q) = (0.0f64, 0.0f64);
        for (i, &value) in self.values.iter().enumerate() {
            let st = Vec2::new(((i % self.width) as f32 + 0.5) / self.width as f32, ((i / self.width) as f32 + 0.5) / self.height as f32);
            let q = density.density(st) as f64;
            f += value as f64;
            if q > 0.0 {
                f2_over_q += (value as f64).powi(2) / q;
            }
        }
        let n = self.values.len() as f64;
        if f > 0.0 { (f2_over_q / n) / (f / n).powi(2) - 1.0 } else { 0.0 }
    }
}

impl DomeMap {
    /// The sampling distribution of `texture`: on the mip level at most [`MAX_GRID_WIDTH`]
    /// wide, or [`FINE_GRID_WIDTH`] wide where the coarser grid would leave much more noise
    /// ([`FINE_GRID_EXCESS`]).
    pub fn new(texture: Arc<Texture>) -> Self {
        let level_within = |width: usize| {
            let tw = texture.size().0;
            (0..texture.level_count()).find(|&l| (tw >> l).max(1) <= width).unwrap_or(texture.level_count() - 1)
        };
        let coarse = level_within(MAX_GRID_WIDTH);
        let (grid, mean) = Grid::at(&texture, coarse);
        let mut distribution = grid.distribution();
        let fine = level_within(FINE_GRID_WIDTH);
        if fine < coarse {
            let (fine_grid, _) = Grid::at(&texture, fine);
            if fine_grid.excess_under(&distribution) > FINE_GRID_EXCESS {
                distribution = fine_grid.distribution();
            }
        }
        DomeMap { texture, distribution, mean }
    }

    /// The texture the map reads.
    pub fn texture(&self) -> &Arc<Texture> {
        &self.texture
    }
}

impl EnvironmentMap {
    /// The distribution of `texture` rotated by `rotation` (dome to world; its scale is
    /// removed).
    pub fn new(texture: Arc<Texture>, rotation: Mat3) -> Self {
        Self::placed(Arc::new(DomeMap::new(texture)), rotation)
    }

    /// `map` rotated by `rotation` (dome to world; its scale is removed).
    pub fn placed(map: Arc<DomeMap>, rotation: Mat3) -> Self {
        let to_world = dome_rotation(rotation);
        EnvironmentMap { map, to_world, to_local: to_world.transpose() }
    }

    /// The map's value seen along world direction `d` (unit).
    pub fn lookup(&self, d: Vec3) -> Vec3 {
        self.radiance_at(Self::st_of(self.to_local * d))
    }

    /// [`EnvironmentMap::lookup`] and [`EnvironmentMap::pdf`] along `d` (unit), which find
    /// the direction's texture coordinates once (an arctangent and an arcsine).
    pub fn lookup_with_pdf(&self, d: Vec3) -> (Vec3, f32) {
        let local = self.to_local * d;
        let st = Self::st_of(local);
        (self.radiance_at(st), self.pdf_at(st, local))
    }

    /// The map's value at texture coordinates `st`.
    fn radiance_at(&self, st: Vec2) -> Vec3 {
        self.map.texture.lookup(st, 0.0, [Wrap::Repeat, Wrap::Clamp]).truncate().max(Vec3::ZERO)
    }

    /// The rotation the map was placed by (map to world), as [`dome_rotation`] makes it.
    pub fn to_world(&self) -> Mat3 {
        self.to_world
    }

    /// Mean value over the sphere (solid-angle weighted).
    pub fn mean(&self) -> Vec3 {
        self.map.mean
    }

    /// A direction drawn with `u`, and its solid-angle density.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        self.sample_st(u).map(|(_, d, pdf)| (d, pdf))
    }

    /// [`EnvironmentMap::sample`] and the map's value along the direction, read where the
    /// sample fell in the image (not found again from the direction).
    pub fn sample_with_radiance(&self, u: Vec2) -> Option<(Vec3, f32, Vec3)> {
        self.sample_st(u).map(|(st, d, pdf)| (d, pdf, self.radiance_at(st)))
    }

    /// A direction drawn with `u`: its texture coordinates, the direction and its density.
    fn sample_st(&self, u: Vec2) -> Option<(Vec2, Vec3, f32)> {
        let (sv, pdf_uv) = self.map.distribution.sample(u);
        let (s, v) = (sv.x, sv.y);
        let local = Self::direction(s, v);
        let sin_theta = (PI * v).sin();
        if sin_theta <= 0.0 || !(pdf_uv > 0.0) {
            return None;
        }
        Some((Vec2::new(s, 1.0 - v), (self.to_world * local).normalize(), pdf_uv / (2.0 * PI * PI * sin_theta)))
    }

    /// Density of sampling world direction `d` (unit).
    pub fn pdf(&self, d: Vec3) -> f32 {
        let local = self.to_local * d;
        self.pdf_at(Self::st_of(local), local)
    }

    /// [`EnvironmentMap::pdf`] of the dome-space direction `local`, whose texture coordinates
    /// are `st`.
    fn pdf_at(&self, st: Vec2, local: Vec3) -> f32 {
        let sin_theta = (1.0 - local.y * local.y).max(0.0).sqrt();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let pdf_uv = self.map.distribution.density(Vec2::new(st.x, 1.0 - st.y));
        pdf_uv / (2.0 * PI * PI * sin_theta)
    }

    /// Texture coordinates (s right, t up) of a dome-space direction.
    fn st_of(d: Vec3) -> Vec2 {
        let longitude = d.x.atan2(d.z);
        let latitude = d.y.clamp(-1.0, 1.0).asin();
        let s = (PI - longitude) / (2.0 * PI);
        let v = (0.5 * PI - latitude) / PI;
        Vec2::new(s.rem_euclid(1.0), 1.0 - v)
    }

    /// The dome-space direction at image position (`s` from the left, `v` from the top).
    fn direction(s: f32, v: f32) -> Vec3 {
        let longitude = PI - 2.0 * PI * s;
        let latitude = 0.5 * PI - PI * v;
        let (sl, cl) = latitude.sin_cos();
        let (so, co) = longitude.sin_cos();
        Vec3::new(cl * so, sl, cl * co)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{ColorSpace, Image};

    /// A 64 × 32 map, black but for one bright texel block.
    fn spot_map() -> Arc<Texture> {
        let (w, h) = (64, 32);
        let mut t = vec![0.05f32; w * h * 3];
        for y in 10..13 {
            for x in 40..44 {
                t[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&[50.0, 40.0, 30.0]);
            }
        }
        Arc::new(Texture::new(&Image::from_f32(w as u32, h as u32, 3, &t), ColorSpace::Raw))
    }

    #[test]
    fn orientation_follows_openexr_latlong() {
        // Image centre column (s = 0.5) is longitude 0: +Z; s = 0.25 is longitude π/2: +X;
        // the top row is +Y.
        assert!((EnvironmentMap::direction(0.5, 0.5) - Vec3::Z).length() < 1e-6);
        assert!((EnvironmentMap::direction(0.25, 0.5) - Vec3::X).length() < 1e-6);
        assert!((EnvironmentMap::direction(0.5, 0.0) - Vec3::Y).length() < 1e-6);
        for (s, v) in [(0.1, 0.3), (0.7, 0.8), (0.45, 0.55)] {
            let st = EnvironmentMap::st_of(EnvironmentMap::direction(s, v));
            assert!((st.x - s).abs() < 1e-5 && (1.0 - st.y - v).abs() < 1e-5, "({s}, {v}) → {st}");
        }
    }

    #[test]
    fn sampling_density_integrates_to_one_and_matches_pdf() {
        let map = EnvironmentMap::new(spot_map(), Mat3::from_rotation_y(0.7));
        // ∫ pdf dω over the sphere by a fine uniform quadrature.
        let n = 400;
        let mut total = 0.0f64;
        for i in 0..n {
            for j in 0..2 * n {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let phi = 2.0 * PI * (j as f32 + 0.5) / (2 * n) as f32;
                let r = (1.0 - z * z).sqrt();
                total += map.pdf(Vec3::new(r * phi.cos(), z, r * phi.sin())) as f64;
            }
        }
        let integral = total * 4.0 * PI as f64 / (2 * n * n) as f64;
        assert!((integral - 1.0).abs() < 0.01, "∫pdf = {integral}");
        // Sampled directions report the density pdf() gives them, and land on the bright spot
        // far more often than its area share.
        let mut rng = crate::sampling::Pcg32::new(3, 0);
        let mut bright = 0;
        for _ in 0..10_000 {
            let (d, pdf) = map.sample(rng.next_2d()).unwrap();
            assert!((pdf - map.pdf(d)).abs() <= 1e-3 * pdf.max(1.0), "{pdf} vs {}", map.pdf(d));
            bright += (map.lookup(d).x > 1.0) as u32;
        }
        assert!(bright > 5_000, "{bright} of 10 000 samples on a spot covering 0.6% of the map");
    }

    /// The radiance read where a sample fell in the image is the map's value along the sampled
    /// direction, and one lookup with its density is the two apart, to the bit.
    #[test]
    fn sampled_radiance_and_lookups_with_densities_agree_with_their_parts() {
        let map = EnvironmentMap::new(spot_map(), Mat3::from_rotation_y(0.7));
        let mut rng = crate::sampling::Pcg32::new(8, 2);
        for _ in 0..10_000 {
            let (d, pdf, radiance) = map.sample_with_radiance(rng.next_2d()).unwrap();
            // The same bilinear lookup at coordinates found again from the direction: equal but
            // for the rounding of the round trip, which moves the filter by a few ulps.
            let found = map.lookup(d);
            assert!((radiance - found).abs().max_element() <= 1e-3 * found.max_element().max(1.0), "{radiance} vs {found}");
            assert_eq!(map.lookup_with_pdf(d), (found, map.pdf(d)));
            assert!((pdf - map.pdf(d)).abs() <= 1e-3 * pdf.max(1.0));
        }
    }

    /// A 2 048 × 1 024 sky, blue above and brown below, with a sun of `sun` texels across
    /// (none for 0) carrying most of the power.
    fn big_sky(sun: usize) -> Arc<Texture> {
        let (w, h) = (2048usize, 1024usize);
        let mut t = vec![0.0f32; w * h * 3];
        for y in 0..h {
            let colour = if y < h / 2 { [0.3, 0.5, 1.0] } else { [0.15, 0.12, 0.1] };
            for x in 0..w {
                t[(y * w + x) * 3..][..3].copy_from_slice(&colour);
            }
        }
        for y in 300..300 + sun {
            for x in 700..700 + sun {
                t[(y * w + x) * 3..][..3].copy_from_slice(&[4.0e4, 3.6e4, 3.2e4]);
            }
        }
        Arc::new(Texture::new(&Image::from_f32(w as u32, h as u32, 3, &t), ColorSpace::Raw))
    }

    /// A map wider than the default grid takes the finer one only where the default would leave
    /// much more noise: under a small sun, not under a smooth sky.
    #[test]
    fn a_small_sun_gets_the_finer_grid_and_a_smooth_sky_does_not() {
        assert_eq!(DomeMap::new(big_sky(3)).distribution.width(), FINE_GRID_WIDTH);
        assert_eq!(DomeMap::new(big_sky(0)).distribution.width(), MAX_GRID_WIDTH);
    }

    #[test]
    fn importance_sampling_estimates_the_mean_radiance() {
        // E[L(ω)/pdf(ω)] / 4π is the mean radiance, whatever the map.
        let map = EnvironmentMap::new(spot_map(), Mat3::IDENTITY);
        let mut rng = crate::sampling::Pcg32::new(5, 1);
        let n = 200_000;
        let mut sum = Vec3::ZERO;
        for _ in 0..n {
            let (d, pdf) = map.sample(rng.next_2d()).unwrap();
            sum += map.lookup(d) / pdf;
        }
        let estimate = sum / (n as f32 * 4.0 * PI);
        assert!((estimate - map.mean()).abs().max_element() < 0.03 * map.mean().max_element(), "{estimate} vs {}", map.mean());
    }
}
