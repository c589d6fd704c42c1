//! Lights in UsdLux units, their sampling for next-event estimation and their evaluation
//! when a ray finds them.
//!
//! Units follow the UsdLux "Quantities and Units" section: emitted radiance is
//! `intensity · 2^exposure · color`; with `normalize` it is divided by the light's
//! world-space area (transform scale included), and for a `DistantLight` by
//! π·sin²(angle/2), which makes `intensity` the illuminance on a surface facing it.
//! `DomeLight` ignores `normalize`. Area lights emit from their local −Z face (sphere
//! lights outward); they are emitters only and do not cast shadows on each other.

mod bilinear;
pub mod blackbody;
pub mod environment;
mod mesh_light;
pub mod motion;
mod shapes;
pub mod spherical_rect;
pub mod spherical_triangle;
pub mod tree;

pub use mesh_light::{MaterialSync, MeshLight};
pub use shapes::{LightHit, LightSample, Shape};

use glam::{Affine3A, Vec3};

use crate::math::luminance;
use crate::sampling::Distribution1D;

/// A light as the scene description holds it (object space plus transform).
#[derive(Clone, Debug, PartialEq)]
pub struct LightDesc {
    /// Which UsdLux light.
    pub kind: LightKind,
    /// Object to world.
    pub transform: Affine3A,
    /// `inputs:intensity`.
    pub intensity: f32,
    /// `inputs:exposure`.
    pub exposure: f32,
    /// `inputs:color`.
    pub color: Vec3,
    /// `inputs:normalize`.
    pub normalize: bool,
    /// Seen by camera rays.
    pub visible_to_camera: bool,
    /// `ShapingAPI`: a cone and focus around the light's local −Z.
    pub shaping: Option<Shaping>,
    /// `inputs:diffuse`: scales what diffuse lobes receive from this light.
    pub diffuse: f32,
    /// `inputs:specular`: scales what specular and transmission lobes receive.
    pub specular: f32,
    /// `DomeLight` `inputs:texture:file` (latitude-longitude), by content.
    pub texture: Option<crate::texture::TextureRef>,
    /// Object to world at evenly spaced times over the shutter ([`crate::motion`]) when the
    /// light moves; empty when it does not.
    pub motion: Vec<Affine3A>,
    /// The link collection whose prims alone the light illuminates (UsdLux
    /// `collection:lightLink`); None: every prim ([`crate::scene::LightLinks`]).
    pub light_link: Option<String>,
    /// The link collection whose prims alone cast the light's shadows
    /// (`collection:shadowLink`); None: every prim.
    pub shadow_link: Option<String>,
}

/// UsdLux `ShapingAPI` controls. The schema leaves the exact falloff to renderers ("TODO:
/// clarify semantics"); Tessera's: emission towards a direction θ off the axis is scaled by
/// focus: lerp(focusTint, 1, cos^focus θ) (1 when focus is 0), and by the cone:
/// 0 beyond `cone_angle`, 1 within `cone_angle·(1 − softness)`, smoothstep between.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shaping {
    /// `inputs:shaping:cone:angle`, degrees (90 = no cut).
    pub cone_angle: f32,
    /// `inputs:shaping:cone:softness` in [0, 1].
    pub cone_softness: f32,
    /// `inputs:shaping:focus` (≥ 0).
    pub focus: f32,
    /// `inputs:shaping:focusTint`.
    pub focus_tint: Vec3,
}

impl Default for Shaping {
    /// The schema's defaults: no shaping.
    fn default() -> Self {
        Shaping { cone_angle: 90.0, cone_softness: 0.0, focus: 0.0, focus_tint: Vec3::ZERO }
    }
}

impl Shaping {
    /// The factor for emission at cos θ off the axis.
    pub fn factor(&self, cos_theta: f32) -> Vec3 {
        self.around(Vec3::Z).at(cos_theta)
    }

    /// The shaping around a world-space `axis`, with its cone's cosines worked out once.
    pub fn around(&self, axis: Vec3) -> ShapingProfile {
        let outer = self.cone_angle.clamp(0.0, 180.0).to_radians();
        let inner = outer * (1.0 - self.cone_softness.clamp(0.0, 1.0));
        ShapingProfile {
            axis,
            cos_outer: outer.cos(),
            cos_inner: inner.cos(),
            focus: self.focus,
            focus_tint: self.focus_tint.max(Vec3::ZERO),
        }
    }
}

/// A committed light's [`Shaping`], ready to evaluate per light sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapingProfile {
    /// Unit world-space axis (the light's local −Z).
    pub axis: Vec3,
    cos_outer: f32,
    cos_inner: f32,
    focus: f32,
    focus_tint: Vec3,
}

impl ShapingProfile {
    /// The factor for emission at cos θ off the axis.
    pub fn at(&self, cos_theta: f32) -> Vec3 {
        let cos_theta = cos_theta.clamp(-1.0, 1.0);
        let (cos_outer, cos_inner) = (self.cos_outer, self.cos_inner);
        let cone = if cos_theta < cos_outer {
            0.0
        } else if cos_theta >= cos_inner || cos_inner <= cos_outer {
            1.0
        } else {
            let t = (cos_theta - cos_outer) / (cos_inner - cos_outer);
            t * t * (3.0 - 2.0 * t)
        };
        let focus = if self.focus > 0.0 { self.focus_tint.lerp(Vec3::ONE, cos_theta.max(0.0).powf(self.focus)) } else { Vec3::ONE };
        focus * cone
    }
}

/// UsdLux light types and their shape parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// `SphereLight` with `inputs:radius`.
    Sphere {
        /// Radius in object space.
        radius: f32,
    },
    /// `RectLight` with `inputs:width` and `inputs:height`, in the local XY plane.
    Rect {
        /// Extent along local X.
        width: f32,
        /// Extent along local Y.
        height: f32,
    },
    /// `DiskLight` with `inputs:radius`, in the local XY plane.
    Disk {
        /// Radius in object space.
        radius: f32,
    },
    /// `CylinderLight` along local X with `inputs:radius` and `inputs:length`, emitting from
    /// its side, not its caps.
    Cylinder {
        /// Radius in object space.
        radius: f32,
        /// Length in object space.
        length: f32,
    },
    /// `DistantLight` shining along local −Z, `inputs:angle` in degrees.
    Distant {
        /// Angular diameter in degrees.
        angle_degrees: f32,
    },
    /// `DomeLight` of constant colour.
    Dome,
}

/// A committed light in world space.
#[derive(Clone, Debug)]
pub struct Light {
    /// Geometry and emission.
    pub shape: shapes::Shape,
    /// Seen by camera rays.
    pub visible_to_camera: bool,
    /// Shaping around the light's world-space axis, ready to evaluate.
    pub shaping: Option<ShapingProfile>,
    /// Multipliers of what diffuse and of what specular/transmission lobes receive
    /// (UsdLux `inputs:diffuse`, `inputs:specular`); (1, 1) for ordinary lights.
    pub multipliers: (f32, f32),
    /// For a triangle of a mesh whose emission is textured: (instance, triangle), so that the
    /// radiance at a point is looked up there (the shape holds the texture's mean, which only
    /// weighs the light's selection).
    pub textured_emitter: Option<(u32, u32)>,
    /// How the light moves over the shutter, if it does ([`Light::at`] poses it).
    pub motion: Option<std::sync::Arc<motion::LightMotion>>,
}

impl Light {
    /// An unshaped, still light that lights every lobe alike.
    pub fn plain(shape: shapes::Shape, visible_to_camera: bool) -> Self {
        Light { shape, visible_to_camera, shaping: None, multipliers: (1.0, 1.0), textured_emitter: None, motion: None }
    }

    /// True when the light treats diffuse and specular lobes differently.
    #[inline]
    pub fn has_multipliers(&self) -> bool {
        self.multipliers != (1.0, 1.0)
    }

    /// The multiplier for light arriving through a lobe of `kind`.
    #[inline]
    pub fn multiplier(&self, kind: crate::bsdf::PathKind) -> f32 {
        match kind {
            crate::bsdf::PathKind::Diffuse => self.multipliers.0,
            crate::bsdf::PathKind::Specular | crate::bsdf::PathKind::Transmission => self.multipliers.1,
        }
    }

    /// The shaping factor for light leaving the light along `dir` (1 without shaping).
    #[inline]
    pub fn shaped(&self, dir: Vec3) -> Vec3 {
        match &self.shaping {
            Some(p) => p.at(dir.dot(p.axis)),
            None => Vec3::ONE,
        }
    }
}

/// Everything a shading point tells a light for sampling.
#[derive(Clone, Copy, Debug)]
pub struct ShadingContext {
    /// World position.
    pub p: Vec3,
    /// Geometric normal facing the incoming ray.
    pub n: Vec3,
    /// The surface also receives light from behind (it transmits), so environment sampling
    /// covers both hemispheres.
    pub both_sides: bool,
    /// Normalised shutter time of the path: where moving lights are.
    pub time: f32,
}

impl LightDesc {
    /// A light of `kind` at `transform` with `intensity`, every other input at its UsdLux
    /// schema default (white, exposure 0, not normalised, seen by the camera, no shaping).
    pub fn new(kind: LightKind, transform: Affine3A, intensity: f32) -> Self {
        LightDesc {
            kind,
            transform,
            intensity,
            exposure: 0.0,
            color: Vec3::ONE,
            normalize: false,
            visible_to_camera: true,
            shaping: None,
            diffuse: 1.0,
            specular: 1.0,
            texture: None,
            motion: Vec::new(),
            light_link: None,
            shadow_link: None,
        }
    }

    /// Emitted radiance before normalisation.
    fn base_radiance(&self) -> Vec3 {
        self.color.max(Vec3::ZERO) * self.intensity * self.exposure.exp2()
    }

    /// Commits to world space. `None` for lights that cannot emit (degenerate transform,
    /// zero size with normalisation off, non-finite values).
    pub fn commit(&self) -> Option<Light> {
        self.commit_with(None)
    }

    /// [`Self::commit`], a `DomeLight` reading `environment` (its `texture:file` and that
    /// map's distribution) if given.
    pub fn commit_with(&self, environment: Option<std::sync::Arc<environment::DomeMap>>) -> Option<Light> {
        let l = self.base_radiance();
        if !crate::math::is_finite(l) || !self.transform.is_finite() {
            return None;
        }
        let shape = match (self.kind, environment) {
            (LightKind::Dome, Some(dome)) => {
                let rotation = glam::Mat3::from(self.transform.matrix3);
                let map = std::sync::Arc::new(environment::EnvironmentMap::placed(dome, rotation));
                shapes::Shape::Environment { l, map, turn: glam::Mat3::IDENTITY }
            }
            _ => shapes::Shape::new(self.kind, &self.transform, l, self.normalize)?,
        };
        let m = |x: f32| if x.is_finite() { x.max(0.0) } else { 1.0 };
        // A constant dome looks the same whichever way it turns; a textured one turns its map.
        let motion = match &shape {
            _ if self.motion.is_empty() => None,
            shapes::Shape::Dome { .. } => None,
            shapes::Shape::Environment { map, .. } => {
                Some(motion::LightMotion::Turned { map: map.clone(), l, samples: self.motion.iter().copied().collect() })
            }
            _ => Some(motion::LightMotion::Placed {
                kind: self.kind,
                l,
                normalize: self.normalize,
                shaping: self.shaping,
                samples: self.motion.iter().copied().collect(),
            }),
        }
        .map(std::sync::Arc::new);
        Some(Light {
            shaping: shaping_profile(self.shaping, &self.transform),
            shape,
            visible_to_camera: self.visible_to_camera,
            multipliers: (m(self.diffuse), m(self.specular)),
            textured_emitter: None,
            motion,
        })
    }
}

/// The shaping of a light placed by `xf`, around its local −Z; `None` without shaping.
fn shaping_profile(shaping: Option<Shaping>, xf: &Affine3A) -> Option<ShapingProfile> {
    let axis = (-Vec3::from(xf.matrix3.z_axis)).normalize_or_zero();
    shaping.filter(|s| *s != Shaping::default() && axis != Vec3::ZERO).map(|s| s.around(axis))
}

/// The set of lights and how next-event estimation picks one: lights at infinity by power
/// among themselves, finite lights (UsdLux prims and emissive triangles) through a
/// [`tree::LightTree`] by their likely contribution at the shading point, the two groups in
/// proportion to their power. With light linking, each receiver group whose lights differ has
/// a choice of its own over the lights that reach it ([`LightSet::select_per_group`]), as
/// Cycles builds a light tree per light set: no sample is spent on a light the point cannot see.
#[derive(Default)]
pub struct LightSet {
    /// Lights, including one per emissive triangle.
    pub lights: Vec<Light>,
    /// Each light's power, as the choices weigh it.
    power: Vec<f32>,
    /// The choices: 0 among every light, then one per distinct set of lights that reach a
    /// receiver group.
    selections: Vec<Selection>,
    /// Per receiver group, its choice (empty: choice 0 for every group).
    by_group: Vec<u32>,
}

/// The choice among some of the lights.
#[derive(Default)]
struct Selection {
    /// Indices of the lights at infinity, and the choice among them by power.
    infinite: Vec<u32>,
    infinite_selection: Distribution1D,
    /// Per light: its slot in `infinite`, if it is one.
    infinite_slot: Vec<Option<u32>>,
    /// Chance of choosing a light at infinity.
    p_infinite: f32,
    tree: tree::LightTree,
}

impl Selection {
    /// The choice among the lights `member` admits.
    fn new(lights: &[Light], power: &[f32], member: impl Fn(usize) -> bool) -> Self {
        let infinite: Vec<u32> =
            (0..lights.len() as u32).filter(|&i| lights[i as usize].shape.is_infinite() && member(i as usize)).collect();
        let mut infinite_slot = vec![None; lights.len()];
        for (k, &i) in infinite.iter().enumerate() {
            infinite_slot[i as usize] = Some(k as u32);
        }
        let infinite_power: Vec<f32> = infinite.iter().map(|&i| power[i as usize]).collect();
        let finite: Vec<(u32, tree::LightBounds)> =
            (0..lights.len()).filter(|&i| member(i)).filter_map(|i| lights[i].bounds(power[i]).map(|b| (i as u32, b))).collect();
        let (p_inf, p_fin): (f32, f32) = (infinite_power.iter().sum(), finite.iter().map(|(i, _)| power[*i as usize]).sum());
        let tree = tree::LightTree::build(finite, lights.len());
        let p_infinite = match (infinite.is_empty(), tree.is_empty()) {
            (true, _) => 0.0,
            (false, true) => 1.0,
            (false, false) if p_inf + p_fin > 0.0 => p_inf / (p_inf + p_fin),
            _ => 0.5,
        };
        Selection { infinite_selection: Distribution1D::new(&infinite_power), infinite, infinite_slot, p_infinite, tree }
    }
}

/// Most light indices the per-group choices may hold together (each holds a table over every
/// light), and a quarter of the (group, light) pairs asked to build them: past either, groups
/// share the choice among every light and lights that do not reach a point are skipped there.
pub const MAX_GROUP_SELECTION_ENTRIES: usize = 1 << 24;

impl LightSet {
    /// Builds the light tree and the choice among lights at infinity; `scene_radius` sizes
    /// the infinite lights' power.
    pub fn new(lights: Vec<Light>, scene_radius: f32) -> Self {
        let power: Vec<f32> = lights.iter().map(|l| luminance(l.shape.power(scene_radius)).max(0.0)).collect();
        let all = Selection::new(&lights, &power, |_| true);
        LightSet { lights, power, selections: vec![all], by_group: Vec::new() }
    }

    /// Gives each of `groups` receiver groups a choice among the lights `reaches` says reach
    /// it; groups reached by the same lights share one. Returns how many choices there are
    /// beyond the one among every light, or None when they would hold more than
    /// [`MAX_GROUP_SELECTION_ENTRIES`] (then every group keeps the shared choice).
    pub fn select_per_group(&mut self, groups: usize, reaches: impl Fn(usize, u32) -> bool) -> Option<usize> {
        let n = self.lights.len();
        // Asking every group about every light is the work: a client's millions of distinct
        // groups must not hold a commit for minutes.
        if groups.saturating_mul(n) > 4 * MAX_GROUP_SELECTION_ENTRIES {
            return None;
        }
        let mut distinct: std::collections::HashMap<Vec<bool>, u32> = std::collections::HashMap::new();
        let mut by_group = Vec::with_capacity(groups);
        for g in 0..groups as u32 {
            let set: Vec<bool> = (0..n).map(|i| reaches(i, g)).collect();
            if set.iter().all(|&r| r) {
                by_group.push(0);
                continue;
            }
            let next = distinct.len() as u32 + 1;
            by_group.push(*distinct.entry(set).or_insert(next));
            if distinct.len().saturating_mul(n) > MAX_GROUP_SELECTION_ENTRIES {
                return None;
            }
        }
        let mut sets: Vec<(Vec<bool>, u32)> = distinct.into_iter().collect();
        sets.sort_by_key(|(_, k)| *k);
        for (set, _) in &sets {
            let selection = Selection::new(&self.lights, &self.power, |i| set[i]);
            self.selections.push(selection);
        }
        self.by_group = by_group;
        Some(sets.len())
    }

    /// The choice receiver group `group` uses.
    #[inline]
    fn selection(&self, group: u32) -> &Selection {
        let k = self.by_group.get(group as usize).copied().unwrap_or(0);
        &self.selections[k as usize]
    }

    /// True when nothing emits.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Picks lights with `u_select` for a shading point of receiver group `group` and samples
    /// a direction on each: one light at infinity, or the finite lights the tree's walks reach
    /// (one per cluster of its adaptive split, `budget` at most, up to [`tree::SPLIT_BUDGET`];
    /// 1: no split). Each sample's pdf includes the chance of its light being picked, so their
    /// contributions add. A picked light that `reaches` says does not reach the point
    /// (light linking, when the groups share the choice among every light) gives no sample:
    /// its share is zero, and the choice stays unbiased.
    #[allow(clippy::too_many_arguments)]
    pub fn sample_each(
        &self,
        ctx: &ShadingContext,
        u_select: f32,
        u: glam::Vec2,
        budget: usize,
        group: u32,
        reaches: impl Fn(usize) -> bool,
        mut visit: impl FnMut(LightSample, &Light, usize),
    ) {
        let mut emit = |i: usize, p: f32| {
            if !reaches(i) {
                return;
            }
            let Some(light) = self.lights[i].at(ctx.time) else { return };
            if let Some(mut s) = light.shape.sample(ctx, u) {
                s.pdf *= p;
                s.li *= light.shaped(-s.wi);
                visit(s, &light, i);
            }
        };
        let sel = self.selection(group);
        if u_select < sel.p_infinite {
            let (k, p) = sel.infinite_selection.sample((u_select / sel.p_infinite).min(1.0 - f32::EPSILON));
            emit(sel.infinite[k] as usize, p * sel.p_infinite);
        } else {
            let u = ((u_select - sel.p_infinite) / (1.0 - sel.p_infinite)).clamp(0.0, 1.0 - f32::EPSILON);
            sel.tree.sample_split(ctx.p, ctx.n, u, budget, |i, p| emit(i as usize, p * (1.0 - sel.p_infinite)));
        }
    }

    /// The probability that [`LightSet::sample_each`] picks light `i` at the shading point
    /// `ctx` of receiver group `group`.
    pub fn pmf(&self, ctx: &ShadingContext, i: usize, budget: usize, group: u32) -> f32 {
        let sel = self.selection(group);
        match sel.infinite_slot.get(i) {
            Some(Some(k)) => sel.p_infinite * sel.infinite_selection.pmf(*k as usize),
            Some(None) => (1.0 - sel.p_infinite) * sel.tree.pmf(ctx.p, ctx.n, i, budget),
            None => 0.0,
        }
    }
}

#[cfg(test)]
mod group_tests {
    use super::*;

    /// With light linking, a receiver group picks among the lights that reach it alone: no
    /// sample lands on another, their chances sum to one, and groups reached by the same lights
    /// share a choice (the one among every light when all reach them).
    #[test]
    fn each_receiver_group_chooses_among_the_lights_that_reach_it() {
        let lights: Vec<Light> = (0..4)
            .map(|i| LightDesc::new(LightKind::Sphere { radius: 0.2 }, Affine3A::from_translation(Vec3::new(i as f32, 2.0, 0.0)), 1.0))
            .map(|d| d.commit().unwrap())
            .collect();
        let mut set = LightSet::new(lights, 10.0);
        let reach: [&[usize]; 4] = [&[0, 1, 2, 3], &[0, 2], &[1, 2, 3], &[0, 2]];
        assert_eq!(set.select_per_group(4, |light, group| reach[group as usize].contains(&light)), Some(2));
        let ctx = ShadingContext { p: Vec3::ZERO, n: Vec3::Y, both_sides: false, time: 0.0 };
        for (group, lights) in reach.iter().enumerate() {
            let group = group as u32;
            let mut seen = std::collections::BTreeSet::new();
            for k in 0..256 {
                let u_select = (k as f32 + 0.5) / 256.0;
                set.sample_each(
                    &ctx,
                    u_select,
                    glam::Vec2::splat(0.5),
                    1,
                    group,
                    |_| true,
                    |_, _, i| {
                        seen.insert(i);
                    },
                );
            }
            assert!(seen.iter().all(|i| lights.contains(i)), "group {group} sampled {seen:?}");
            let total: f32 = lights.iter().map(|&i| set.pmf(&ctx, i, 1, group)).sum();
            assert!((total - 1.0).abs() < 1e-5, "group {group}: chances sum to {total}");
            assert!((0..4).filter(|i| !lights.contains(i)).all(|i| set.pmf(&ctx, i, 1, group) == 0.0));
        }
        // Past the budget (2^25 groups × 4 lights), the groups share the choice among every
        // light without asking a single pair.
        let asked = std::cell::Cell::new(0u64);
        let reaches = |_: usize, _: u32| {
            asked.set(asked.get() + 1);
            true
        };
        let mut shared = LightSet::new(set.lights.clone(), 10.0);
        assert_eq!((shared.select_per_group(1 << 25, reaches), asked.get()), (None, 0));
        assert!((0..4).all(|i| (shared.pmf(&ctx, i, 1, 7) - shared.pmf(&ctx, i, 1, 0)).abs() == 0.0));
    }
}

#[cfg(test)]
mod shaping_tests {
    use super::*;

    #[test]
    fn cone_softness_focus_and_tint_shape_the_emission() {
        // The schema's defaults do nothing.
        assert_eq!(Shaping::default().factor(0.0), Vec3::ONE);
        // A hard 30° cone: 1 inside, 0 outside.
        let hard = Shaping { cone_angle: 30.0, ..Default::default() };
        assert_eq!((hard.factor(29f32.to_radians().cos()), hard.factor(31f32.to_radians().cos())), (Vec3::ONE, Vec3::ZERO));
        // Softness 0.5: full within 15°, a smooth ramp to 0 at 30°, monotonic.
        let soft = Shaping { cone_angle: 30.0, cone_softness: 0.5, ..Default::default() };
        assert_eq!(soft.factor(14f32.to_radians().cos()), Vec3::ONE);
        let ramp: Vec<f32> = (15..=30).map(|d| soft.factor((d as f32).to_radians().cos()).x).collect();
        assert!(ramp.windows(2).all(|w| w[1] <= w[0]) && ramp[ramp.len() - 1] < 1e-6, "{ramp:?}");
        // Focus 2: cos²θ off axis, towards the tint.
        let focus = Shaping { focus: 2.0, focus_tint: Vec3::new(1.0, 0.0, 0.0), ..Default::default() };
        let f = focus.factor(0.5);
        assert!((f - Vec3::new(1.0, 0.25, 0.25)).length() < 1e-6, "{f}");
    }
}
