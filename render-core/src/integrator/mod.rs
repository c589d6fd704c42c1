//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (Veach 1997, power heuristic), and Russian roulette.
//!
//! Depth counts scattering events (pbrt's convention): `max_depth = 1` is direct lighting
//! only. Mitsuba's `max_depth` counts path vertices including the emitter, so its
//! `max_depth = 8` equals our 7.

//! Renders trace camera samples in waves ([`trace_wave`]: every live path's ray intersected,
//! then every path's step), [`trace_path`] one path at a time; both run the same step
//! (`Tracer::step`), which calls parts with one job each, over a [`path::PathState`]:
//! shading-point setup ([`shading`]), emission found by the path ([`emission`]), next-event
//! estimation ([`direct`]), subsurface random walks ([`medium`]) and the next direction
//! ([`scatter`]); the light-path AOVs are recorded as light is added ([`path::LightPaths`]).

mod direct;
mod emission;
mod medium;
mod path;
mod scatter;
mod settings;
mod shading;
mod volume;

pub use settings::{IntegratorSettings, LightStrategy};

use crate::bsdf::Bsdf;
use crate::bvh::Hit;
use crate::caustics::{self, CausticMode};
use crate::film::PixelSample;
use crate::geometry::Ray;
use crate::light::ShadingContext;
use crate::math::is_finite;
use crate::plan::{Feature, Features};
use crate::sampling::PathSampler;
use crate::scene::{CommittedScene, NO_GROUP};

use direct::DirectLighting;
use medium::WalkStep;
use path::PathState;
use shading::{Landing, Vertex};
use volume::VolumeStep;

/// Counters of one path.
#[derive(Clone, Copy, Debug, Default)]
pub struct PathCounters {
    /// Rays traced (camera, bounce and shadow).
    pub rays: u64,
    /// Samples whose radiance was not finite (dropped; a bug indicator).
    pub non_finite: u64,
}

/// The scene and settings a path is traced with. `FULL` selects the general path loop; the
/// specialised one (`FULL = false`) is compiled without the machinery of the features and
/// settings [`needs_full_loop`] names, so a scene of opaque surfaces never tests for media,
/// cut-outs, glitter, transparent shadows or light-path AOVs.
struct Tracer<'a, const FULL: bool> {
    scene: &'a CommittedScene,
    settings: &'a IntegratorSettings,
}

impl<const FULL: bool> Tracer<'_, FULL> {
    /// Caustic avoidance is on.
    #[inline(always)]
    fn avoid(&self) -> bool {
        FULL && self.settings.caustics == CausticMode::Avoid
    }

    /// Every piece of machinery runs ([`IntegratorSettings::force_all_effects`]).
    #[inline(always)]
    fn force(&self) -> bool {
        FULL && self.settings.force_all_effects
    }

    /// The first surface's light is split into the light-path AOVs.
    #[inline(always)]
    fn light_path_aovs(&self) -> bool {
        FULL && self.settings.light_path_aovs
    }

    /// The scene's light links, in the general loop (the plan sends linked scenes there).
    #[inline(always)]
    fn links(&self) -> Option<&crate::scene::LightLinks> {
        if FULL { self.scene.links.as_ref() } else { None }
    }

    /// The link group of a point on instance `instance`.
    #[inline(always)]
    fn group_of_instance(&self, instance: u32) -> u32 {
        self.links().map_or(NO_GROUP, |l| l.instance_group(instance))
    }

    /// True when light `light` illuminates points of link group `group`.
    #[inline(always)]
    fn reaches(&self, light: usize, group: u32) -> bool {
        self.links().is_none_or(|l| l.illuminates(light, group))
    }

    /// True when only some prims cast light `light`'s shadows.
    #[inline(always)]
    fn shadow_linked(&self, light: usize) -> bool {
        self.links().is_some_and(|l| l.shadow_linked(light))
    }
}

/// The BSDF and textured material at a path's current vertex, when they are built there (a
/// material's BSDF that serves every view is shared instead: `Bsdf::settle`): filled anew at
/// every vertex (see `Bsdf::clone_from`), the buffers kept from vertex to vertex to spare
/// their copies.
#[derive(Default)]
struct VertexBuffers {
    bsdf: Bsdf,
    local: shading::LocalMaterial,
}

/// Features whose machinery only the general path loop holds.
pub const FULL_LOOP_FEATURES: [Feature; 8] = [
    Feature::Subsurface,
    Feature::TexturedCutouts,
    Feature::PartialPresence,
    Feature::Glitter,
    Feature::Hair,
    Feature::Volumes,
    Feature::LightLinking,
    Feature::ShadowLinking,
];

/// True when the scene's features or the render's settings need the general path loop.
pub fn needs_full_loop(features: Features, settings: &IntegratorSettings) -> bool {
    general_loop_causes(features, settings).next().is_some()
}

/// What makes a render take the general path loop, by name: the settings, then the scene's
/// features, whose machinery only that loop holds. None for the specialised loop.
pub fn general_loop_causes(features: Features, settings: &IntegratorSettings) -> impl Iterator<Item = &'static str> {
    let asked = [
        (settings.general_loop, "the general loop asked for"),
        (settings.force_all_effects, "every effect forced on"),
        (settings.light_path_aovs, "light-path AOVs"),
        (settings.caustics == CausticMode::Avoid, "caustic avoidance"),
    ];
    let by_settings = asked.into_iter().filter(|&(on, _)| on).map(|(_, cause)| cause);
    by_settings.chain(FULL_LOOP_FEATURES.into_iter().filter(move |&f| features.has(f)).map(Feature::name))
}

/// Radiance and first-hit AOVs along a camera ray.
pub fn trace_path(
    scene: &CommittedScene,
    camera_ray: Ray,
    depth_of: impl Fn(f32) -> f32,
    background_depth: f32,
    rng: &mut PathSampler,
    settings: &IntegratorSettings,
    counters: &mut PathCounters,
) -> PixelSample {
    match needs_full_loop(scene.plan.features, settings) {
        true => Tracer::<true> { scene, settings }.trace(camera_ray, depth_of, background_depth, rng, counters),
        false => Tracer::<false> { scene, settings }.trace(camera_ray, depth_of, background_depth, rng, counters),
    }
}

/// A camera sample of a wave.
pub struct CameraPath {
    /// Its camera ray.
    pub ray: Ray,
    /// The cosine its depth AOV is measured with ([`crate::camera::Camera::depth`]).
    pub cos: f32,
    /// Its random numbers, the camera's set drawn.
    pub rng: PathSampler,
}

/// The buffers waves are traced in, kept from wave to wave: a tile traces hundreds of waves,
/// and allocating and zeroing them for each one cost about 2% of a Cornell box render.
#[derive(Default)]
pub struct WaveBuffers {
    states: Vec<(PathState, PixelSample)>,
    hits: Vec<Option<Hit>>,
    live: Vec<usize>,
    at: VertexBuffers,
    samples: Vec<PixelSample>,
}

/// Radiance and first-hit AOVs of each of `paths`, traced together: every live path's ray is
/// intersected, then every path takes its step, until none is left. Each path does exactly
/// what [`trace_path`] does with it, so the samples are the same to the bit. The samples come
/// in the order of `paths`, held in `buffers` until the next wave.
pub fn trace_wave<'b>(
    scene: &CommittedScene,
    paths: &mut [CameraPath],
    depth_of: impl Fn(f32, f32) -> f32,
    background_depth: f32,
    settings: &IntegratorSettings,
    counters: &mut PathCounters,
    buffers: &'b mut WaveBuffers,
) -> &'b [PixelSample] {
    match needs_full_loop(scene.plan.features, settings) {
        true => Tracer::<true> { scene, settings }.trace_wave(paths, depth_of, background_depth, counters, buffers),
        false => Tracer::<false> { scene, settings }.trace_wave(paths, depth_of, background_depth, counters, buffers),
    }
    &buffers.samples
}

impl<const FULL: bool> Tracer<'_, FULL> {
    /// [`trace_wave`]'s loop.
    fn trace_wave(
        &self,
        paths: &mut [CameraPath],
        depth_of: impl Fn(f32, f32) -> f32,
        background_depth: f32,
        counters: &mut PathCounters,
        buffers: &mut WaveBuffers,
    ) {
        let WaveBuffers { states, hits, live, at, samples } = buffers;
        let new = |p: &CameraPath| (PathState::new(p.ray, self.settings), PixelSample { depth: background_depth, ..Default::default() });
        states.clear();
        states.extend(paths.iter().map(new));
        hits.clear();
        hits.resize(paths.len(), None);
        live.clear();
        live.extend(0..paths.len());
        while !live.is_empty() {
            for &i in live.iter() {
                counters.rays += 1;
                hits[i] = self.scene.intersect(&states[i].0.ray);
            }
            live.retain(|&i| {
                let ((path, out), cos) = (&mut states[i], paths[i].cos);
                self.step(path, out, hits[i], |t| depth_of(t, cos), at, &mut paths[i].rng, counters)
            });
        }
        samples.clear();
        samples.extend(states.drain(..).map(|(path, out)| finish(out, path.light, self.settings.exposure_scale, counters)));
    }

    /// The path loop: each ray traced, then the path's [`Tracer::step`] at what it found.
    fn trace(
        &self,
        camera_ray: Ray,
        depth_of: impl Fn(f32) -> f32,
        background_depth: f32,
        rng: &mut PathSampler,
        counters: &mut PathCounters,
    ) -> PixelSample {
        let mut out = PixelSample { depth: background_depth, ..Default::default() };
        let mut path = PathState::new(camera_ray, self.settings);
        let mut at = VertexBuffers::default();
        loop {
            counters.rays += 1;
            let hit = self.scene.intersect(&path.ray);
            if !self.step(&mut path, &mut out, hit, &depth_of, &mut at, rng, counters) {
                break;
            }
        }
        finish(out, path.light, self.settings.exposure_scale, counters)
    }

    /// What the path does where its ray found `hit` (or nothing): media and volumes crossed,
    /// light found, the surface landed on, and the next ray; false when the path ends.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn step(
        &self,
        path: &mut PathState,
        out: &mut PixelSample,
        hit: Option<Hit>,
        depth_of: impl Fn(f32) -> f32,
        at: &mut VertexBuffers,
        rng: &mut PathSampler,
        counters: &mut PathCounters,
    ) -> bool {
        let (scene, settings, tracer) = (self.scene, self.settings, self);
        if let Some(m) = path.walk.medium.filter(|_| FULL) {
            // Inside a subsurface medium: scatter before the boundary, or reach it.
            match tracer.walk_step(path, m, hit.map_or(f32::INFINITY, |h| h.t), rng, counters) {
                WalkStep::Scattered => return true,
                WalkStep::Ended => return false,
                WalkStep::Boundary => {}
            }
        }
        let t_hit = hit.map_or(path.ray.tmax, |h| h.t);
        if FULL && !scene.volumes.is_empty() {
            let from_camera = path.depth == 0;
            match tracer.volume_step(path, t_hit, rng, counters) {
                VolumeStep::Passed => {}
                step => {
                    // Coverage: the share of camera rays a volume stops is its opacity.
                    if from_camera {
                        out.alpha = 1.0;
                    }
                    return step == VolumeStep::Scattered;
                }
            }
        }
        let share = std::mem::replace(&mut path.exit_share, 1.0);
        tracer.add_crossed_lights(path, t_hit, share);
        let Some(hit) = hit else {
            tracer.add_escaped(path, share);
            return false;
        };
        let v = match tracer.land(path, &hit, &mut at.bsdf, &mut at.local) {
            Landing::Surface(v) => v,
            Landing::PassedThrough => {
                path.exit_share = share;
                return true;
            }
            Landing::Stopped => return false,
        };
        tracer.add_surface_emission(path, &v, &hit, share);
        if path.depth == 0 {
            record_first_hit(out, scene, &v, depth_of(hit.t));
        }
        if path.depth >= settings.max_depth || v.bsdf.is_empty() {
            return false;
        }
        tracer.bounce(path, &v, rng, counters)
    }

    /// Direct light at `v`, then the next direction; false when the path ends there.
    fn bounce(&self, path: &mut PathState, v: &Vertex, rng: &mut PathSampler, counters: &mut PathCounters) -> bool {
        let bsdf = v.bsdf;
        // Light sampling context: the geometric normal on the viewer's side.
        let ctx =
            ShadingContext { p: v.s.p, n: if v.ng.dot(v.wo) < 0.0 { -v.ng } else { v.ng }, both_sides: bsdf.transmits(), time: v.s.time };
        // Each bounce draws two 4D sets, whatever happens along the path: (light position,
        // light choice, roulette) and (BSDF direction, lobe choice), the 2D pairs on a set's
        // best-stratified first two dimensions.
        let [[ul_x, ul_y, u_sel, u_rr], [ub_x, ub_y, u_lobe, _]] = rng.next_2x4d();
        let inside_here = path.walk.medium.is_some();
        let leaving_share = self.leaving_share(path, v);
        // Next-event estimation here finds direct light at the first surface, or at the exit
        // of the walk it started.
        let is_direct = path.depth == 0 || (path.light.in_walk && inside_here);
        let direct = DirectLighting { v, bsdf, ctx, u: [ul_x, ul_y, u_sel], leaving_share, is_direct };
        self.add_direct_light(path, &direct, counters);
        self.scatter(path, v, bsdf, ctx, [ub_x, ub_y, u_lobe], leaving_share) && path.survives_roulette(self.settings.rr_start, u_rr)
    }

    /// Caustic avoidance at a subsurface boundary seen from inside: what light the path
    /// finds by leaving the medium here, transparent shadows from the scattering event
    /// before already found w'(B_t) of ("lighting at the exit point will be weighted down
    /// and replaced by lighting in the interior"). Indirect light beyond stays whole.
    fn leaving_share(&self, path: &PathState, v: &Vertex) -> f32 {
        match (&path.prev, path.walk.medium.is_some()) {
            (Some(p), true) if self.avoid() => {
                self.scene.medium_boundary(v.s.material).map_or(1.0, |b| 1.0 - caustics::roughness_weight(p.roughness, b.roughness))
            }
            _ => 1.0,
        }
    }
}

/// The first-hit AOVs: coverage, prim id, normal, depth, position and albedo.
fn record_first_hit(out: &mut PixelSample, scene: &CommittedScene, v: &Vertex, depth: f32) {
    out.alpha = 1.0;
    out.prim_id = scene.instances[v.s.instance as usize].prim + 1;
    out.normal = v.ns;
    out.depth = depth;
    out.position = v.s.p;
    out.albedo = v.bsdf.albedo(v.wo_local.with_z(v.wo_local.z.abs()));
}

/// The sample the path gathered; a non-finite one is dropped and counted.
fn finish(mut out: PixelSample, mut light: path::LightPaths, exposure: f32, counters: &mut PathCounters) -> PixelSample {
    if !is_finite(light.total) {
        counters.non_finite += 1;
        light.clear();
    }
    if exposure != 1.0 {
        // Only a camera with an exposure pays for it (10 vector products a path).
        light.total *= exposure;
        light.components = light.components.map(|c| c * exposure);
        light.direct = light.direct.map(|c| c * exposure);
    }
    out.radiance = light.total;
    out.components = light.components;
    out.direct = light.direct;
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each feature alone takes the general loop exactly when that loop holds its machinery,
    /// and is named as the cause; so is each setting that needs it.
    #[test]
    fn the_general_loop_names_what_calls_for_it() {
        let plain = IntegratorSettings::default();
        assert_eq!(general_loop_causes(Features::default(), &plain).count(), 0);
        for &f in Feature::ALL {
            let mut alone = Features::default();
            alone.insert(f);
            let causes: Vec<&str> = general_loop_causes(alone, &plain).collect();
            let expected: Vec<&str> = FULL_LOOP_FEATURES.contains(&f).then_some(f.name()).into_iter().collect();
            assert_eq!(causes, expected, "{}", f.name());
            assert_eq!(needs_full_loop(alone, &plain), !expected.is_empty());
        }
        let settings = [
            IntegratorSettings { general_loop: true, ..Default::default() },
            IntegratorSettings { force_all_effects: true, ..Default::default() },
            IntegratorSettings { light_path_aovs: true, ..Default::default() },
            IntegratorSettings { caustics: CausticMode::Avoid, ..Default::default() },
        ];
        for s in &settings {
            assert_eq!(general_loop_causes(Features::default(), s).count(), 1);
        }
        let mut volumes = Features::default();
        volumes.insert(Feature::Volumes);
        let both: Vec<&str> = general_loop_causes(volumes, &settings[3]).collect();
        assert_eq!(both, ["caustic avoidance", Feature::Volumes.name()]);
    }
}
