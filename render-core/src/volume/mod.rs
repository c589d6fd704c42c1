//! Heterogeneous participating media: UsdVol volumes whose density (and temperature) come
//! from voxel grids, shaded as Cycles' Principled Volume shades them, traced by delta
//! tracking through a majorant grid ([`tracking`]) with the Henyey-Greenstein phase function.

pub mod grid;
mod majorant;
pub mod phase;
pub mod tracking;

use std::sync::{Arc, OnceLock};

use glam::{Affine3A, Vec3};

pub use grid::VoxelGrid;
pub use phase::HenyeyGreenstein;

use crate::geometry::Ray;
use crate::scene::SceneError;
use majorant::MajorantGrid;

/// How a volume scatters and emits: the inputs of Blender's Principled Volume, with its
/// meaning (the Blender manual's "Principled Volume" page; Cycles' `svm_node_principled_volume`).
/// Extinction is `density` × the density grid, of which `color` scatters (the albedo) and the
/// rest is absorbed. Emission per unit length is `emission` × the density grid, plus black-body
/// emission: `blackbody_tint` × σ_SB·10⁻⁶/π·T⁴ × the colour of a black body at T (luminance 1),
/// with T = `temperature` × the temperature grid, and `blackbody_intensity` mixing from no
/// black body (0) to a physical one (1), as Cycles mixes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeShading {
    /// Scales the density grid into extinction per scene unit.
    pub density: f32,
    /// Single-scattering albedo, in [0, 1].
    pub color: Vec3,
    /// Henyey-Greenstein g: forward (> 0) or backward (< 0) scattering.
    pub anisotropy: f32,
    /// Emission per unit length per unit of the density grid.
    pub emission: Vec3,
    /// 0 (none) to 1 (physical) black-body emission from the temperature grid.
    pub blackbody_intensity: f32,
    /// Tints the black body.
    pub blackbody_tint: Vec3,
    /// Kelvin per unit of the temperature grid.
    pub temperature: f32,
}

impl Default for VolumeShading {
    /// Blender's defaults for the node.
    fn default() -> Self {
        VolumeShading {
            density: 1.0,
            color: Vec3::splat(0.5),
            anisotropy: 0.0,
            emission: Vec3::ZERO,
            blackbody_intensity: 0.0,
            blackbody_tint: Vec3::ONE,
            temperature: 1000.0,
        }
    }
}

/// A volume prim as the scene description holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeDesc {
    /// The density field.
    pub density: Arc<VoxelGrid>,
    /// The temperature field, in the density grid's index space.
    pub temperature: Option<Arc<VoxelGrid>>,
    /// The colour field (red, green and blue grids in the density grid's block): it
    /// multiplies the albedo, clamped to [0, 1] (Blender's Principled Volume "Color Attribute");
    /// its edge values extend past the block, where the density still ramps down.
    pub color: Option<[Arc<VoxelGrid>; 3]>,
    /// The grids' index space to world.
    pub index_to_world: Affine3A,
    /// How it scatters and emits.
    pub shading: VolumeShading,
    /// Index space to world at evenly spaced times over the shutter ([`crate::motion`]) when
    /// the volume moves; empty when it does not.
    pub motion: Vec<Affine3A>,
    /// The light-link collections the volume belongs to ([`crate::scene::LightLinks`]).
    pub link_collections: Vec<String>,
}

impl VolumeDesc {
    /// Bytes its grids hold.
    pub fn bytes(&self) -> u64 {
        let color = self.color.as_ref().map_or(0, |c| 3 * c[0].values.len());
        4 * (self.density.values.len() + self.temperature.as_ref().map_or(0, |t| t.values.len()) + color) as u64
    }
}

/// Checks a volume for what would break the renderer: grids whose values do not match their
/// size or are not finite, negative densities, an albedo above 1, a singular transform.
pub fn validate_volume(path: &str, v: &VolumeDesc) -> Result<(), SceneError> {
    let invalid = |field: &str, problem: String| SceneError::Invalid { prim: path.to_string(), field: field.to_string(), problem };
    let color = v.color.iter().flatten();
    let grids =
        [("density", &v.density)].into_iter().chain(v.temperature.iter().map(|t| ("temperature", t))).chain(color.map(|c| ("color", c)));
    for (field, g) in grids {
        let want = VoxelGrid::voxel_count(g.dims);
        if want != g.values.len() as u64 || want > grid::MAX_VOXELS {
            return Err(invalid(field, format!("{} values for {} voxels (at most {})", g.values.len(), want, grid::MAX_VOXELS)));
        }
        if g.origin.abs().max_element() > 1 << 29 {
            return Err(invalid(field, format!("grid origin {} is out of range", g.origin)));
        }
        if let Some((i, x)) = g.values.iter().enumerate().find(|(_, x)| !x.is_finite() || (field == "density" && **x < 0.0)) {
            return Err(invalid(field, format!("voxel {i} is {x}; values must be finite (and densities not negative)")));
        }
        if field == "color" && (g.origin != v.density.origin || g.dims != v.density.dims) {
            return Err(invalid(field, "the colour grids must cover the density grid's block".into()));
        }
    }
    let det = v.index_to_world.matrix3.determinant();
    if !v.index_to_world.is_finite() || !det.is_finite() || det.abs() < 1e-30 {
        return Err(invalid("transform", "the grid's index-to-world transform is singular or not finite".into()));
    }
    crate::motion::check_samples(&v.motion).map_err(|problem| invalid("motion", problem))?;
    let s = &v.shading;
    let finite = [s.density, s.anisotropy, s.blackbody_intensity, s.temperature].iter().all(|x| x.is_finite())
        && [s.color, s.emission, s.blackbody_tint].iter().all(|c| c.is_finite());
    if !finite || s.density < 0.0 || s.temperature < 0.0 {
        return Err(invalid("shading", "inputs must be finite, density and temperature not negative".into()));
    }
    if s.color.min_element() < 0.0 || s.color.max_element() > 1.0 {
        return Err(invalid("shading.color", format!("albedo {} is outside [0, 1]: it would create energy", s.color)));
    }
    if s.emission.min_element() < 0.0 || s.blackbody_tint.min_element() < 0.0 || !(0.0..=1.0).contains(&s.blackbody_intensity) {
        return Err(invalid("shading", "emission and tint must not be negative, blackbody intensity within [0, 1]".into()));
    }
    if !(-1.0..=1.0).contains(&s.anisotropy) {
        return Err(invalid("shading.anisotropy", format!("{} is outside [-1, 1]", s.anisotropy)));
    }
    Ok(())
}

/// Tentative collisions per emitting majorant cell crossed, at least: cells that emit without
/// attenuating still get their emission sampled.
const EMISSION_STEPS_PER_CELL: f32 = 4.0;

/// A volume ready to trace.
pub struct Volume {
    /// Its prim path.
    pub prim: String,
    desc: VolumeDesc,
    world_to_index: Affine3A,
    majorant: MajorantGrid,
    /// World-space bounds of where it may be nonzero.
    pub bounds: (Vec3, Vec3),
    /// Its phase function.
    pub phase: HenyeyGreenstein,
    /// Majorant of emitting cells that do not attenuate (per scene unit).
    emission_floor: f32,
    /// It emits black-body light from its temperature grid.
    blackbody: bool,
}

impl Volume {
    /// Builds the majorant grid and bounds of a validated volume.
    pub fn new(prim: &str, desc: &VolumeDesc) -> Self {
        Self::with_majorant_cells(prim, desc, majorant::CELL)
    }

    /// [`Self::new`] with majorant cells of `cell`³ voxels (what the volumes bench varies).
    pub fn with_majorant_cells(prim: &str, desc: &VolumeDesc, cell: i32) -> Self {
        let cell = cell.max(1);
        let s = desc.shading;
        let support = match &desc.temperature {
            Some(t) => (desc.density.support().0.min(t.support().0), desc.density.support().1.max(t.support().1)),
            None => desc.density.support(),
        };
        let blackbody = s.blackbody_intensity > 0.0 && s.temperature > 0.0 && desc.temperature.is_some();
        let majorant = MajorantGrid::build(
            support,
            cell,
            |a, b| majorant::grid_max(&desc.density, s.density, a, b),
            |a, b| {
                (s.emission.max_element() > 0.0 && desc.density.max_in(a, b) > 0.0)
                    || (blackbody && desc.temperature.as_ref().is_some_and(|t| t.max_in(a, b) > 0.0))
            },
        );
        let m = desc.index_to_world;
        let voxel = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis].map(|a| a.length()).into_iter().fold(f32::INFINITY, f32::min);
        // A moving volume: the union of its boxes at the samples holds it at every time.
        let bounds =
            desc.motion.iter().map(|m| world_bounds(m, support)).fold(world_bounds(&m, support), |a, b| (a.0.min(b.0), a.1.max(b.1)));
        Volume {
            prim: prim.to_string(),
            desc: desc.clone(),
            world_to_index: m.inverse(),
            majorant,
            bounds,
            phase: HenyeyGreenstein::new(s.anisotropy),
            emission_floor: EMISSION_STEPS_PER_CELL / (cell as f32 * voxel),
            blackbody,
        }
    }

    /// World to index space at normalised shutter time `time`.
    #[inline]
    pub(super) fn world_to_index_at(&self, time: f32) -> Affine3A {
        match self.desc.motion.is_empty() {
            true => self.world_to_index,
            false => crate::motion::to_object_at(&self.desc.motion, time),
        }
    }

    /// The single-scattering albedo at world point `p` at shutter time `time`: the shader's
    /// colour, times the colour field's (clamped to [0, 1]) where there is one.
    pub fn albedo_at(&self, p: Vec3, time: f32) -> Vec3 {
        let base = self.desc.shading.color;
        let Some([r, g, b]) = &self.desc.color else { return base };
        let q = self.world_to_index_at(time).transform_point3(p);
        base * Vec3::new(r.sample_extended(q), g.sample_extended(q), b.sample_extended(q)).clamp(Vec3::ZERO, Vec3::ONE)
    }

    /// Extinction per scene unit at index-space point `p`.
    #[inline]
    pub fn extinction_at(&self, p: Vec3) -> f32 {
        self.desc.shading.density * self.desc.density.sample(p)
    }

    /// Extinction and emission per scene unit at index-space point `p`, the density grid read
    /// once for both.
    pub fn extinction_and_emission_at(&self, p: Vec3) -> (f32, Vec3) {
        let s = &self.desc.shading;
        let density = self.desc.density.sample(p);
        let mut e = s.emission * density;
        if let Some(t) = self.desc.temperature.as_ref().filter(|_| self.blackbody) {
            e += blackbody_emission(s.temperature * t.sample(p).max(0.0), s.blackbody_intensity) * s.blackbody_tint;
        }
        (s.density * density, e)
    }

    /// The ray's segment `[0, t_max]` may cross the volume's bounds.
    fn overlaps(&self, ray: &Ray, t_max: f32) -> bool {
        let inv = Vec3::ONE / ray.dir;
        let (a, b) = ((self.bounds.0 - ray.origin) * inv, (self.bounds.1 - ray.origin) * inv);
        a.min(b).max_element().max(0.0) <= a.max(b).min_element().min(t_max)
    }

    /// Bytes it holds: its grids and majorants.
    pub fn bytes(&self) -> u64 {
        self.desc.bytes() + 5 * self.majorant.cells() as u64
    }

    /// Cells of its majorant grid.
    pub fn majorant_cells(&self) -> usize {
        self.majorant.cells()
    }
}

/// The world box of an index-space box.
fn world_bounds(m: &Affine3A, (lo, hi): (Vec3, Vec3)) -> (Vec3, Vec3) {
    let mut out = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for k in 0..8 {
        let c = Vec3::new(if k & 1 == 0 { lo.x } else { hi.x }, if k & 2 == 0 { lo.y } else { hi.y }, if k & 4 == 0 { lo.z } else { hi.z });
        let w = m.transform_point3(c);
        out = (out.0.min(w), out.1.max(w));
    }
    out
}

/// Black-body emission per unit length at `kelvin`, as Cycles' Principled Volume gives it:
/// σ_SB·10⁻⁶/π · mix(1, T⁴, intensity) times the black body's colour of luminance 1.
pub fn blackbody_emission(kelvin: f32, intensity: f32) -> Vec3 {
    const SIGMA: f32 = 5.670_374e-8 * 1e-6 / std::f32::consts::PI;
    let t2 = kelvin * kelvin;
    SIGMA * (1.0 + (t2 * t2 - 1.0) * intensity) * blackbody_colour(kelvin)
}

/// [`crate::light::blackbody::blackbody_rgb`] tabulated over 1000–10 000 K (it clamps
/// there) in 64 K steps, interpolated: the exact colour integrates 471 wavelengths.
fn blackbody_colour(kelvin: f32) -> Vec3 {
    const STEPS: usize = 140;
    const STEP: f32 = 9000.0 / STEPS as f32;
    static TABLE: OnceLock<Vec<Vec3>> = OnceLock::new();
    let table = TABLE.get_or_init(|| (0..=STEPS).map(|i| crate::light::blackbody::blackbody_rgb(1000.0 + STEP * i as f32)).collect());
    let x = ((kelvin.clamp(1000.0, 10000.0) - 1000.0) / STEP).min(STEPS as f32 - 1e-3);
    let i = x as usize;
    table[i].lerp(table[i + 1], x - i as f32)
}

/// The unit-cube grid a test volume of constant density fills: `n`³ voxels over [0, 1]³ in
/// world space once placed by [`unit_box_transform`].
#[cfg(test)]
pub(crate) fn constant_grid(n: u32, value: f32) -> VoxelGrid {
    VoxelGrid { origin: glam::IVec3::ZERO, dims: glam::UVec3::splat(n), values: vec![value; (n * n * n) as usize] }
}

/// Index space of [`constant_grid`] onto [0, 1]³: voxel i covers [i/n, (i + 1)/n], its value
/// at the centre, so the trilinear field's support reaches half a voxel beyond.
#[cfg(test)]
pub(crate) fn unit_box_transform(n: u32) -> Affine3A {
    Affine3A::from_scale_rotation_translation(Vec3::splat(1.0 / n as f32), glam::Quat::IDENTITY, Vec3::splat(0.5 / n as f32))
}

#[cfg(test)]
mod tests {
    use super::tracking::{Stream, fly, transmittance};
    use super::*;

    fn slab(n: u32, sigma: f32, shading: VolumeShading) -> Volume {
        let desc = VolumeDesc {
            density: Arc::new(constant_grid(n, 1.0)),
            temperature: None,
            color: None,
            index_to_world: unit_box_transform(n),
            shading: VolumeShading { density: sigma, ..shading },
            motion: Vec::new(),
            link_collections: Vec::new(),
        };
        validate_volume("/V", &desc).unwrap();
        Volume::new("/V", &desc)
    }

    /// Along an axis through the middle, the trilinear field of n voxels of value 1 integrates
    /// to exactly n voxels' length: 1 in world units (ramps of half a voxel each end).
    #[test]
    fn ratio_and_delta_tracking_match_beer_lambert() {
        for (sigma, g) in [(0.5f32, 0.0), (2.0, 0.6), (8.0, -0.4)] {
            let v = [slab(16, sigma, VolumeShading { anisotropy: g, ..Default::default() })];
            let ray = Ray::new(Vec3::new(0.37, 0.52, -2.0), Vec3::Z);
            let expected = (-sigma).exp();
            let n = 200_000;
            let mut s = Stream::new(7);
            let ratio: f64 = (0..n).map(|_| transmittance(&v, &ray, f32::INFINITY, &mut s, |_| true) as f64).sum::<f64>() / n as f64;
            let escaped = (0..n).filter(|_| fly(&v, &ray, f32::INFINITY, &mut s).collision.is_none()).count() as f64 / n as f64;
            // Bernoulli escapes: σ = sqrt(T(1 − T)/n) ≤ 0.0011; 4σ bounds. Ratio tracking's
            // variance is smaller.
            let bound = |t: f32| 4.0 * (t * (1.0 - t) / n as f32).sqrt() as f64;
            let (half_expected, bound) = ((-0.5 * sigma).exp(), bound(expected).max(1e-4));
            assert!((escaped - expected as f64).abs() < bound, "σ = {sigma}: escaped {escaped} vs {expected}");
            assert!((ratio - expected as f64).abs() < bound, "σ = {sigma}: ratio tracking {ratio} vs {expected}");
            // A segment ending at mid-depth sees half the optical depth.
            let half: f64 = (0..n).map(|_| transmittance(&v, &ray, 2.5, &mut s, |_| true) as f64).sum::<f64>() / n as f64;
            let half_bound = 4.0 * (half_expected * (1.0 - half_expected) / n as f32).sqrt() as f64;
            assert!((half - half_expected as f64).abs() < half_bound, "σ = {sigma}: half-way {half} vs {half_expected}");
        }
    }

    /// A purely emitting, non-scattering slab of optical depth τ along the ray: L = ε/σ·(1 − e^(−τ)).
    #[test]
    fn emission_of_an_absorbing_slab_matches_the_closed_form() {
        let eps = Vec3::new(0.5, 1.0, 2.0);
        for sigma in [0.0f32, 1.0, 4.0] {
            let v = [slab(16, sigma, VolumeShading { color: Vec3::ZERO, emission: eps, ..Default::default() })];
            let ray = Ray::new(Vec3::new(0.41, 0.47, -1.0), Vec3::Z);
            let n = 100_000;
            let mut s = Stream::new(11);
            let mut sum = Vec3::ZERO;
            for _ in 0..n {
                sum += fly(&v, &ray, f32::INFINITY, &mut s).emitted;
            }
            let mean = sum / n as f32;
            // ∫ ε(x) e^(−τ(x)) dx; emission follows the density grid, ramps included, so the
            // integral over the ramps is that of the constant slab to O(1/n²) in σ·voxel.
            let expected = if sigma == 0.0 { eps } else { eps / sigma * (1.0 - (-sigma).exp()) };
            assert!(((mean - expected) / expected).abs().max_element() < 0.01, "σ = {sigma}: {mean} vs {expected}");
        }
    }

    /// A client's 1e30 density, with an empty voxel in its block: float steps stop advancing
    /// there, and tracking gives up after its cap instead of looping (the volume counts as
    /// opaque).
    #[test]
    fn absurd_densities_end_tracking_by_its_cap() {
        let v = [slab(4, 1e30, VolumeShading::default())];
        let ray = Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z);
        let mut s = Stream::new(3);
        assert!(fly(&v, &ray, f32::INFINITY, &mut s).collision.is_some());
        assert_eq!(transmittance(&v, &ray, f32::INFINITY, &mut s, |_| true), 0.0);
        let mut holed = constant_grid(4, 1e30);
        holed.values[0] = 0.0;
        let desc = VolumeDesc {
            density: Arc::new(holed),
            temperature: None,
            color: None,
            index_to_world: unit_box_transform(4),
            shading: VolumeShading::default(),
            motion: Vec::new(),
            link_collections: Vec::new(),
        };
        let v = [Volume::new("/V", &desc)];
        let corner = Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.01, 0.01, 1.0).normalize());
        let flight = fly(&v, &corner, f32::INFINITY, &mut s);
        assert!(flight.collision.is_some() && flight.emitted.is_finite());
    }

    #[test]
    fn blackbody_emission_follows_stefan_boltzmann() {
        // Luminance σ_SB·10⁻⁶/π·T⁴ at intensity 1; none at intensity 0 but Cycles' floor.
        let l = |c: Vec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
        let t: f32 = 1500.0;
        let want = 5.670_374e-14 / std::f32::consts::PI * t.powi(4);
        assert!((l(blackbody_emission(t, 1.0)) / want - 1.0).abs() < 1e-3);
        assert!(l(blackbody_emission(t, 0.0)) < 1e-13);
        // The table agrees with the exact colour between its steps.
        let exact = crate::light::blackbody::blackbody_rgb(2345.0);
        assert!((blackbody_colour(2345.0) - exact).abs().max_element() < 0.01, "{} vs {exact}", blackbody_colour(2345.0));
    }

    #[test]
    fn hostile_volumes_are_refused_naming_the_field() {
        let ok = VolumeDesc {
            density: Arc::new(constant_grid(2, 1.0)),
            temperature: None,
            color: None,
            index_to_world: Affine3A::IDENTITY,
            shading: VolumeShading::default(),
            motion: Vec::new(),
            link_collections: Vec::new(),
        };
        let err = |d: VolumeDesc| validate_volume("/V", &d).unwrap_err().to_string();
        let mut nan = constant_grid(2, 1.0);
        nan.values[3] = f32::NAN;
        assert!(err(VolumeDesc { density: Arc::new(nan), ..ok.clone() }).contains("density: voxel 3"));
        let short = VoxelGrid { dims: glam::UVec3::splat(u32::MAX), ..constant_grid(2, 1.0) };
        assert!(err(VolumeDesc { density: Arc::new(short), ..ok.clone() }).contains("density"));
        assert!(err(VolumeDesc { index_to_world: Affine3A::from_scale(Vec3::ZERO), ..ok.clone() }).contains("transform"));
        let bright = VolumeShading { color: Vec3::splat(1.5), ..Default::default() };
        assert!(err(VolumeDesc { shading: bright, ..ok.clone() }).contains("shading.color"));
        let g = VolumeShading { anisotropy: f32::NAN, ..Default::default() };
        assert!(err(VolumeDesc { shading: g, ..ok }).contains("shading"));
    }
}
