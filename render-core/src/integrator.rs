//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (Veach 1997, power heuristic), and Russian roulette.
//!
//! Depth counts scattering events (pbrt's convention): `max_depth = 1` is direct lighting
//! only. Mitsuba's `max_depth` counts path vertices including the emitter, so its
//! `max_depth = 8` equals our 7.

use glam::{Vec2, Vec3};

use crate::bsdf::PathKind;
use crate::caustics::{self, CausticMode, RoughnessFloor};
use crate::film::PixelSample;
use crate::geometry::{Ray, offset_ray_origin};
use crate::light::ShadingContext;
use crate::math::{Frame, is_finite};
use crate::sampling::{PathSampler, power_heuristic};
use crate::scene::CommittedScene;
use crate::subsurface::{Medium, Step};

/// Path-tracing settings.
#[derive(Clone, Copy, Debug)]
pub struct IntegratorSettings {
    /// Maximum number of scattering events.
    pub max_depth: u32,
    /// Kulla-Conty energy compensation on all lobes (the `energy_compensation` setting).
    pub energy_compensation: bool,
    /// Bounce after which Russian roulette may end paths (5, as Mitsuba 3 does: earlier
    /// roulette saves little time in bright interiors and adds visible variance).
    pub rr_start: u32,
    /// Firefly clamp: the largest component an indirect contribution may have (light
    /// reaching the first visible surface after at least one more bounce). Off (`None`) by
    /// default: it trades variance for a bias (energy loss) a user must choose knowingly.
    pub clamp_indirect: Option<f32>,
    /// Split the radiance into the light-path AOVs (diffuse, specular, transmission,
    /// emission) and record the position: off unless a client asks for them.
    pub light_path_aovs: bool,
    /// Caustic paths: full path tracing, or Imageworks' avoidance ([`crate::caustics`]).
    pub caustics: CausticMode,
    /// Which strategies find light: both, combined by MIS (the default), or one alone (to
    /// measure what MIS buys; BSDF sampling alone cannot find delta lights).
    pub strategy: LightStrategy,
    /// Run every piece of machinery whether or not the scene calls for it (every lobe at
    /// weight 0, every energy table, tangent frames, closest-hit shadow rays, light-path
    /// AOVs), for the benchmark that measures what the render plan saves. Same image.
    pub force_all_effects: bool,
    /// A camera ray's footprint as a cone, (width, spread angle), for texture filtering;
    /// the renderer sets it from the camera. (0, 0) fetches the finest texture level.
    pub pixel_footprint: (f32, f32),
    /// Filter textures over the ray's footprint (mip-mapping by ray cones); off, every lookup
    /// reads the finest level and only pixel supersampling filters (the reference's way).
    pub texture_filtering: bool,
    /// Adaptive splitting in the light tree: up to this many lights per shading point where
    /// one cannot represent the cluster (less noise, more shadow rays), at most
    /// [`crate::light::tree::SPLIT_BUDGET`]; 1, one light per point.
    pub light_split_budget: usize,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        IntegratorSettings {
            max_depth: 8,
            rr_start: 5,
            energy_compensation: true,
            clamp_indirect: None,
            light_path_aovs: false,
            caustics: CausticMode::Full,
            force_all_effects: false,
            strategy: LightStrategy::Mis,
            pixel_footprint: (0.0, 0.0),
            texture_filtering: true,
            light_split_budget: crate::light::tree::SPLIT_BUDGET,
        }
    }
}

/// How paths find light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightStrategy {
    /// Next-event estimation and BSDF sampling, combined by the power heuristic.
    #[default]
    Mis,
    /// BSDF sampling alone: light counts only where a path hits it.
    BsdfOnly,
    /// Next-event estimation alone: a path hitting a light after a non-delta bounce adds
    /// nothing (the camera and delta lobes still see emitters directly).
    LightOnly,
}

/// Most scattering events one path takes inside subsurface media.
const MAX_MEDIUM_STEPS: u32 = 4096;

/// Index of the emission component in [`PixelSample::components`].
const EMISSION: usize = 3;

/// Index of the subsurface component in [`PixelSample::components`].
const SUBSURFACE: usize = 4;

/// Adds a contribution to light-path component `k`, and to its direct part when it came
/// straight from an emitter (emission has none: the camera sees it directly).
#[inline]
fn record(comp: &mut [Vec3; 5], direct: &mut [Vec3; 4], k: usize, c: Vec3, is_direct: bool) {
    comp[k] += c;
    if is_direct {
        match k {
            0..=2 => direct[k] += c,
            SUBSURFACE => direct[3] += c,
            _ => {}
        }
    }
}

/// A contribution, clamped when it is indirect and a clamp is set.
#[inline]
fn clamped(c: Vec3, indirect: bool, clamp: Option<f32>) -> Vec3 {
    match clamp {
        Some(max) if indirect && c.max_element() > max => c * (max / c.max_element()),
        _ => c,
    }
}

/// Counters of one path.
#[derive(Clone, Copy, Debug, Default)]
pub struct PathCounters {
    /// Rays traced (camera, bounce and shadow).
    pub rays: u64,
    /// Samples whose radiance was not finite (dropped; a bug indicator).
    pub non_finite: u64,
}

/// A ray's footprint as a cone (Akenine-Möller et al., "Texture Level of Detail Strategies
/// for Real-Time Ray Tracing", Ray Tracing Gems, 2019, chapter 20): width at the last vertex
/// and spread angle. Camera rays start with the pixel's angle.
#[derive(Clone, Copy, Debug)]
struct RayCone {
    width: f32,
    spread: f32,
}

impl RayCone {
    fn width_at(self, t: f32) -> f32 {
        self.width + self.spread * t
    }

    /// After scattering at a vertex where the cone was `width` wide, by a lobe of
    /// `roughness`: a glossy lobe widens the cone by about its lobe width (roughness² is the
    /// GGX α, the tangent of the lobe's half-angle), a mirror keeps it (surface curvature
    /// ignored), so textures seen in rough reflections are fetched blurred, as they look.
    fn after_bounce(self, width: f32, roughness: f32) -> RayCone {
        RayCone { width, spread: self.spread + roughness * roughness }
    }
}

/// Where the previous vertex sampled its outgoing direction from, for MIS.
#[derive(Clone, Copy)]
struct PrevVertex {
    ctx: ShadingContext,
    bsdf_pdf: f32,
    delta: bool,
    /// The kind of lobe that sampled the direction, for lights' diffuse/specular multipliers.
    kind: PathKind,
    /// The roughest lobe there, for caustic avoidance's weighting.
    roughness: f32,
    /// A scattering event inside a subsurface medium: no next-event estimation there finds a
    /// light this direction can hit (only lights outside, through transparent shadows).
    in_medium: bool,
}

/// Roughness of a scattering event in a medium for caustic avoidance's weighting: a phase
/// function scatters like the roughest surface.
const MEDIUM_ROUGHNESS: f32 = 1.0;

/// A shadow ray from `origin` towards the light point `ls` sampled from `p`: aimed at the
/// point and stopped just short of it. An offset origin (which scales with the surface) can
/// exceed a fixed margin, and a ray along the original direction then met an emitting
/// mesh's own surface before tmax.
fn shadow_ray(origin: Vec3, p: Vec3, ls: &crate::light::LightSample) -> Ray {
    if ls.dist.is_finite() {
        let to = p + ls.wi * ls.dist - origin;
        let d = to.length();
        Ray::new(origin, to / d).with_tmax(d * (1.0 - 1e-4))
    } else {
        Ray::new(origin, ls.wi)
    }
}

/// A scattering event in a subsurface medium.
struct MediumPoint {
    medium: Medium,
    p: Vec3,
    /// The direction the path arrived along.
    dir: Vec3,
    /// The path's throughput there.
    beta: Vec3,
    /// The kind of lobe that led into the medium, for lights' multipliers.
    kind: PathKind,
}

/// Caustic avoidance's light at a scattering event in a medium ("Brute-force subsurface
/// scattering"): lights reached by transparent shadows across the medium's boundary, weighted
/// against the walks that leave towards them (all of it behind a smooth boundary). `u`: the
/// light position and the light choice. A light inside the medium (no crossing) is left to
/// phase sampling.
fn light_through_boundary(
    scene: &CommittedScene,
    settings: &IntegratorSettings,
    at: &MediumPoint,
    u: [f32; 3],
    counters: &mut PathCounters,
) -> Vec3 {
    let ctx = ShadingContext { p: at.p, n: Vec3::ZERO, both_sides: true };
    let mut total = Vec3::ZERO;
    scene.lights.sample_each(&ctx, u[2], Vec2::new(u[0], u[1]), settings.light_split_budget, |mut ls, light| {
        if let Some((instance, triangle)) = light.textured_emitter {
            ls.li = scene.emission_at(instance, triangle, at.p + ls.wi * ls.dist);
        }
        if ls.li == Vec3::ZERO || ls.pdf <= 0.0 {
            return;
        }
        let shadow = shadow_ray(at.p, at.p, &ls);
        counters.rays += 1;
        let Some(pass) =
            caustics::shadow_transmittance_from(scene, &shadow, shadow.tmax, Some(at.medium)).filter(|pass| pass.crossings > 0)
        else {
            return;
        };
        let w = caustics::roughness_weight(MEDIUM_ROUGHNESS, pass.roughness);
        let phase = at.medium.phase_pdf(at.dir, ls.wi);
        total +=
            clamped(at.beta * ls.li * pass.transmittance * (phase * w * light.multiplier(at.kind) / ls.pdf), true, settings.clamp_indirect);
    });
    total
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
    let mut out = PixelSample { depth: background_depth, ..Default::default() };
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut ray = camera_ray;
    let mut prev: Option<PrevVertex> = None;
    // The BSDF at the current vertex; one buffer for the whole path (see `Bsdf::clone_from`).
    let mut bsdf = crate::bsdf::Bsdf::default();
    // Caustic avoidance: the roughness every later lobe is clamped to.
    let mut floor = RoughnessFloor::default();
    let lights = &scene.lights;

    // MIS weight of a light found by BSDF sampling: 1 from the camera or after a delta lobe.
    let weight = |prev: &Option<PrevVertex>, light: u32, pdf_light: f32| -> f32 {
        match prev {
            None => 1.0,
            Some(p) if p.delta || p.in_medium => 1.0,
            Some(_) if settings.strategy == LightStrategy::BsdfOnly => 1.0,
            Some(_) if settings.strategy == LightStrategy::LightOnly => 0.0,
            Some(p) => power_heuristic(p.bsdf_pdf, lights.pmf(&p.ctx, light as usize, settings.light_split_budget) * pdf_light),
        }
    };

    // The light-path components, and the one the first scattering event chose.
    let mut comp = [Vec3::ZERO; 5];
    let mut direct = [Vec3::ZERO; 4];
    let mut first = EMISSION;
    // Light the current ray finds comes straight from an emitter to the first surface (or to
    // the medium behind it); `in_walk`: the path is still in the random walk the first
    // surface started, before meeting any other surface.
    let mut seg_direct = false;
    let mut in_walk = false;
    let mut depth = 0u32;
    // Subsurface: the medium the path is inside, and the scattering events taken in it.
    let mut medium: Option<Medium> = None;
    // Transparent shadows from inside cross its boundary (any roughness below 1).
    let mut medium_shadows = false;
    let mut medium_steps = 0u32;
    // The ray's footprint, for texture filtering.
    let mut cone = RayCone { width: settings.pixel_footprint.0, spread: settings.pixel_footprint.1 };
    let mut cutouts_crossed = 0usize;
    // Caustic avoidance after a path leaves a subsurface medium: the share of the direct
    // light it finds next that transparent shadows from inside did not already take.
    let mut exit_share = 1.0f32;
    let avoid = settings.caustics == CausticMode::Avoid;
    loop {
        counters.rays += 1;
        let hit = scene.intersect(&ray);
        if let Some(m) = medium {
            // Inside a subsurface medium: scatter before the boundary, or reach it.
            let [u_channel, u_t, u_x, u_y] = rng.next_4d();
            match m.step(hit.map_or(f32::INFINITY, |h| h.t), u_channel, u_t) {
                Step::Scatter { t, weight } => {
                    beta *= weight;
                    medium_steps += 1;
                    if medium_steps > MAX_MEDIUM_STEPS || beta == Vec3::ZERO || !is_finite(beta) {
                        break;
                    }
                    if medium_steps > 8 {
                        // Russian roulette on the throughput: deep walks in bright media are
                        // long, most of their steps carry little.
                        let q = (1.0 - beta.max_element()).clamp(0.0, 0.95);
                        let [u_rr, ..] = rng.next_4d();
                        if u_rr < q {
                            break;
                        }
                        beta /= 1.0 - q;
                    }
                    let p = ray.origin + ray.dir * t;
                    let kind = prev.map_or(PathKind::Transmission, |p| p.kind);
                    if avoid && medium_shadows && !lights.is_empty() && settings.strategy != LightStrategy::BsdfOnly {
                        let [ul_x, ul_y, u_sel, _] = rng.next_4d();
                        let at = MediumPoint { medium: m, p, dir: ray.dir, beta, kind };
                        let c = light_through_boundary(scene, settings, &at, [ul_x, ul_y, u_sel], counters);
                        l += c;
                        record(&mut comp, &mut direct, first, c, in_walk);
                    }
                    let wi = m.sample_phase(ray.dir, Vec2::new(u_x, u_y));
                    prev = Some(PrevVertex {
                        ctx: ShadingContext { p, n: Vec3::ZERO, both_sides: true },
                        bsdf_pdf: m.phase_pdf(ray.dir, wi),
                        delta: false,
                        kind,
                        roughness: MEDIUM_ROUGHNESS,
                        in_medium: true,
                    });
                    ray = Ray::new(p, wi);
                    continue;
                }
                Step::Surface { weight } => beta *= weight,
            }
        }
        let t_hit = hit.map_or(ray.tmax, |h| h.t);
        let share = std::mem::replace(&mut exit_share, 1.0);

        // Area lights crossed before the surface (they do not occlude).
        scene.crossable_lights.visit_crossed(ray.origin, ray.dir, t_hit, |i| {
            let light = &lights.lights[i as usize];
            if prev.is_none() && !light.visible_to_camera {
                return;
            }
            if let Some(lh) = light.shape.intersect(ray.origin, ray.dir, t_hit) {
                let pdf = prev.map_or(0.0, |p| light.shape.pdf(&p.ctx, ray.dir, lh.t));
                let m = prev.map_or(1.0, |p| light.multiplier(p.kind));
                let c = clamped(
                    beta * lh.le * light.shaped(ray.dir) * (m * share * weight(&prev, i, pdf)),
                    depth >= 2,
                    settings.clamp_indirect,
                );
                l += c;
                record(&mut comp, &mut direct, if depth == 0 { EMISSION } else { first }, c, seg_direct);
            }
        });

        let Some(hit) = hit else {
            for &i in &scene.infinite_lights {
                let light = &lights.lights[i as usize];
                if prev.is_none() && !light.visible_to_camera {
                    continue;
                }
                let le = light.shape.escaped(ray.dir);
                if le != Vec3::ZERO {
                    let pdf = prev.map_or(0.0, |p| light.shape.pdf(&p.ctx, ray.dir, f32::INFINITY));
                    let m = prev.map_or(1.0, |p| light.multiplier(p.kind));
                    let c = clamped(beta * le * (m * share * weight(&prev, i, pdf)), depth >= 2, settings.clamp_indirect);
                    l += c;
                    record(&mut comp, &mut direct, if depth == 0 { EMISSION } else { first }, c, seg_direct);
                }
            }
            break;
        };

        let mut s = scene.surface(&hit);
        let wo = -ray.dir;
        let level = if avoid { floor.level() } else { 0 };
        let force = settings.force_all_effects;
        let cone_here = cone.width_at(hit.t);
        // A textured material is resolved here, at this point and footprint.
        let local = scene.textured(s.material).map(|t| {
            let cos = s.ng.dot(ray.dir).abs() / ray.dir.length();
            t.at(&scene.shading_point(&s, cone_here, cos))
        });
        let pass_through = local.as_ref().map_or(scene.materials[s.material as usize].pass_through, |(m, _)| m.pass_through);
        let absent = pass_through > 0.0 && crate::scene::see_through_coin(s.p, ray.dir) < pass_through;
        if absent || local.as_ref().is_some_and(|(m, _)| m.cut_out) {
            // Cut out here, or not present for this ray: it goes on as if the surface were not
            // there.
            cutouts_crossed += 1;
            if cutouts_crossed > crate::scene::MAX_CUTOUT_CROSSINGS {
                break;
            }
            cone.width = cone_here;
            exit_share = share;
            ray = Ray::new(offset_ray_origin(s.p, if ray.dir.dot(s.ng) > 0.0 { s.ng } else { -s.ng }, s.offset_scale), ray.dir);
            continue;
        }
        if let Some((_, Some(n))) = &local {
            // MikkTSpace's welded tangent where the mesh has one, else the triangle's own.
            let mikk = (s.tangent != glam::Vec4::ZERO).then(|| crate::tangents::perturb(s.ns, s.tangent.truncate(), s.tangent.w, *n));
            s.ns = mikk.flatten().unwrap_or_else(|| crate::material::graph::perturb_normal(s.ns, s.dpds, s.dpdt, *n));
        }
        let ec = settings.energy_compensation;
        // Glitter flakes depend on the point and footprint: such materials build their lobes
        // here, the flakes once the shading frame is known.
        let uber_here = local.as_ref().map_or(&scene.materials[s.material as usize].surface, |(m, _)| &m.surface);
        let glitter = uber_here
            .has_glitter()
            .then(|| if force { *uber_here } else { uber_here.with_roughness_floor(RoughnessFloor::of_level(level)) });
        match &local {
            _ if let Some(u) = &glitter => bsdf = u.base_bsdf(ec, force),
            Some((m, _)) if force => bsdf = m.surface.bsdf_with_every_lobe(ec),
            Some((m, _)) => bsdf = m.surface.with_roughness_floor(RoughnessFloor::of_level(level)).bsdf(ec),
            None if force => bsdf.clone_from(scene.bsdf_with_every_lobe(s.material, ec)),
            None => bsdf.clone_from(scene.bsdf_floored(s.material, ec, level)),
        }
        // The surface's own roughness (before clamping) weighs transparent shadows against
        // paths through glass, on both sides of the comparison.
        let a_roughness = match &local {
            Some((m, _)) if avoid => m.surface.bsdf(ec).roughness(),
            None if avoid => scene.bsdf(s.material, ec).roughness(),
            _ => 0.0,
        };
        // Opaque surfaces are two-sided: both normals face the viewer. Transmissive ones keep
        // their authored orientation (the shading normal's side is outside) so a ray inside
        // glass sees its inside. The geometric normal is turned to the shading normal's side;
        // a direction the two normals put on different sides is dropped below.
        let (ns, ng) = if bsdf.transmits() {
            let ng = if s.ng.dot(s.ns) < 0.0 { -s.ng } else { s.ng };
            // Near silhouettes the viewer itself can be on different sides of the two normals:
            // there the facet decides.
            if wo.dot(ng) * wo.dot(s.ns) > 0.0 { (s.ns, ng) } else { (ng, ng) }
        } else {
            // Both normals on the viewer's side of the facet, the shading normal bent back
            // where it would leave the viewer below its horizon.
            let ng = if s.ng.dot(wo) < 0.0 { -s.ng } else { s.ng };
            let ns = if s.ns.dot(ng) < 0.0 { -s.ns } else { s.ns };
            (crate::math::valid_shading_normal(ng, wo, ns), ng)
        };
        // Where an interpolated normal and the facet disagree about which side a direction is
        // on, following it would reflect into the surface or refract out of the wrong side
        // (light leaks through tessellated glass); such directions carry no light instead.
        let sides_agree = |w: Vec3, local_z: f32| w.dot(ng) * local_z > 0.0;

        if let Some(li) = s.light {
            let light = &lights.lights[li as usize];
            let pdf = prev.map_or(0.0, |p| light.shape.pdf(&p.ctx, ray.dir, hit.t));
            // A textured emitter's radiance is the material's here; the shape holds its mean.
            // After a bounce it is read at the finest level, as light sampling reads it: MIS
            // combines the two only if both estimate the same emission (a footprint-blurred
            // lookup made BSDF-sampled light 20% off light-sampled light on a lit floor).
            let le = match (&local, light.textured_emitter) {
                (Some((m, _)), Some(_)) if depth == 0 => m.emission,
                (_, Some((instance, triangle))) => scene.emission_at(instance, triangle, s.p),
                _ => light.shape.radiance(),
            };
            let c = clamped(beta * le * (share * weight(&prev, li, pdf)), depth >= 2, settings.clamp_indirect);
            l += c;
            record(&mut comp, &mut direct, if depth == 0 { EMISSION } else { first }, c, seg_direct);
        }

        let frame = if force || bsdf.is_anisotropic() { Frame::from_normal_around(ns, s.up) } else { Frame::from_normal(ns) };
        if let Some(u) = &glitter {
            let t = &scene.instances[hit.instance as usize].transform;
            let m3 = t.to_world.matrix3;
            // Flakes live in object space (`000_...`, section 3.5); so does the footprint.
            let n_obj = Vec3::from(m3.transpose() * glam::Vec3A::from(ns)).normalize_or_zero();
            let radius = 0.5 * cone_here / m3.determinant().abs().cbrt();
            let g = &u.glitter;
            let flakes = g.params.flakes_at(t.to_object.transform_point3(s.p), n_obj, radius);
            g.params.apply(g.weight, &flakes, &mut bsdf, |n| frame.to_local((t.normal_matrix * n).normalize_or(ns)));
        }
        let wo_local = frame.to_local(wo);
        if depth == 0 {
            out.alpha = 1.0;
            out.prim_id = scene.instances[hit.instance as usize].prim + 1;
            out.normal = ns;
            out.depth = depth_of(hit.t);
            out.position = s.p;
            out.albedo = bsdf.albedo(wo_local.with_z(wo_local.z.abs()));
        }
        if depth >= settings.max_depth || bsdf.is_empty() {
            break;
        }
        bsdf.prepare(wo_local);
        // Light sampling context: the geometric normal on the viewer's side.
        let ctx = ShadingContext { p: s.p, n: if ng.dot(wo) < 0.0 { -ng } else { ng }, both_sides: bsdf.transmits() };
        // Each bounce draws two 4D sets, whatever happens along the path: (light position,
        // light choice, roulette) and (BSDF direction, lobe choice), the 2D pairs on a set's
        // best-stratified first two dimensions.
        let [ul_x, ul_y, u_sel, u_rr] = rng.next_4d();
        let [ub_x, ub_y, u_lobe, _] = rng.next_4d();
        // Next-event estimation here finds direct light at the first surface, or at the exit
        // of the walk it started.
        let inside_here = medium.is_some();
        let vertex_direct = depth == 0 || (in_walk && inside_here);
        // Caustic avoidance at a subsurface boundary seen from inside: what light the path
        // finds by leaving the medium here, transparent shadows from the scattering event
        // before already found w'(B_t) of ("lighting at the exit point will be weighted down
        // and replaced by lighting in the interior"). Indirect light beyond stays whole.
        let leaving_share = match (&prev, inside_here) {
            (Some(p), true) if avoid => {
                scene.medium_boundary(s.material).map_or(1.0, |b| 1.0 - caustics::roughness_weight(p.roughness, b.roughness))
            }
            _ => 1.0,
        };

        // Next-event estimation.
        if !lights.is_empty() && settings.strategy != LightStrategy::BsdfOnly {
            let u_light = Vec2::new(ul_x, ul_y);
            lights.sample_each(&ctx, u_sel, u_light, settings.light_split_budget, |mut ls, light| {
                if let Some((instance, triangle)) = light.textured_emitter {
                    ls.li = scene.emission_at(instance, triangle, ctx.p + ls.wi * ls.dist);
                }
                if ls.li != Vec3::ZERO && ls.pdf > 0.0 {
                    let wi_local = frame.to_local(ls.wi);
                    // A light with diffuse/specular multipliers weighs each kind of lobe apart.
                    let parts = (light.has_multipliers() || (depth == 0 && (settings.light_path_aovs || force))).then(|| {
                        let mut parts = bsdf.eval_by_kind(wo_local, wi_local);
                        for (k, kind) in [PathKind::Diffuse, PathKind::Specular, PathKind::Transmission].into_iter().enumerate() {
                            parts[k] *= light.multiplier(kind);
                        }
                        parts
                    });
                    let f = if !sides_agree(ls.wi, wi_local.z) {
                        Vec3::ZERO
                    } else {
                        match &parts {
                            Some(p) => p[0] + p[1] + p[2],
                            None => bsdf.eval(wo_local, wi_local),
                        }
                    };
                    if f != Vec3::ZERO {
                        let origin = offset_ray_origin(s.p, if ls.wi.dot(ng) > 0.0 { ng } else { -ng }, s.offset_scale);
                        let shadow = shadow_ray(origin, s.p, &ls);
                        counters.rays += 1;
                        // With caustic avoidance, shadows pass through smooth glass, weighted
                        // against the paths that refract through it; nothing else samples that
                        // straight line, so no MIS weight.
                        let through = if avoid {
                            caustics::shadow_transmittance(scene, &shadow, shadow.tmax).map(|pass| match pass.crossings {
                                0 => None,
                                _ => Some(pass.transmittance * caustics::transparent_weight(a_roughness, pass.roughness)),
                            })
                        } else if force {
                            // The transparent-shadow walk, with glass still opaque.
                            caustics::shadow_transmittance(scene, &shadow, shadow.tmax).filter(|p| p.crossings == 0).map(|_| None)
                        } else {
                            (!scene.occluded(&shadow, shadow.tmax)).then_some(None)
                        };
                        if let Some(glass) = through {
                            let w = match glass {
                                Some(_) => 1.0,
                                None if ls.delta || settings.strategy == LightStrategy::LightOnly => 1.0,
                                None => power_heuristic(ls.pdf, bsdf.pdf(wo_local, wi_local)),
                            };
                            // Light out of a medium through its boundary: transparent shadows
                            // from inside took their share of it.
                            let w = if wi_local.z * wo_local.z < 0.0 { w * leaving_share } else { w };
                            let scale = beta * wi_local.z.abs() * ls.li * glass.unwrap_or(Vec3::ONE) * (w / ls.pdf);
                            let c = clamped(f * scale, depth >= 1, settings.clamp_indirect);
                            l += c;
                            if depth == 0 && (settings.light_path_aovs || force) {
                                // Direct light at the first surface, split by the lobes that reflect it.
                                for (k, part) in parts.unwrap_or_default().into_iter().enumerate() {
                                    record(&mut comp, &mut direct, k, part * scale, true);
                                }
                            } else {
                                record(&mut comp, &mut direct, first, c, vertex_direct);
                            }
                        }
                    }
                }
            });
        }

        // Continue the path by sampling the BSDF.
        let Some((bs, kind, lobe_roughness)) = bsdf.sample_kind(wo_local, u_lobe, Vec2::new(ub_x, ub_y)) else {
            break;
        };
        if depth == 0 {
            first = kind as usize;
        }
        let wi = frame.to_world(bs.wi).normalize();
        if !sides_agree(wi, bs.wi.z) {
            break;
        }
        beta *= bs.weight;
        if kind == PathKind::Transmission {
            // Crossing a subsurface material's boundary: inwards enters its medium (against
            // the outward geometric normal), outwards leaves it.
            if let Some(m) = local.as_ref().map_or_else(|| scene.medium(s.material), |(m, _)| m.medium()) {
                if medium.is_some() && wi.dot(ng) > 0.0 {
                    exit_share = leaving_share;
                }
                medium = (wi.dot(ng) < 0.0).then_some(m);
                medium_shadows = scene.medium_boundary(s.material).is_some();
                if depth == 0 && medium.is_some() {
                    first = SUBSURFACE;
                }
            }
        }
        if avoid {
            // Refracting into smooth glass after a rougher vertex: transparent shadows from
            // that vertex carry w'(B_t) of this light, so the path keeps 1 − w'(B_t), for
            // everything inside (total internal reflection included).
            let glass = local.as_ref().map_or_else(|| scene.shadow_glass(s.material), |(m, _)| caustics::ShadowGlass::of(m));
            if let (Some(p), PathKind::Transmission, Some(glass)) = (&prev, kind, glass) {
                beta *= 1.0 - caustics::transparent_weight(p.roughness, glass.roughness);
            }
            floor = floor.after(lobe_roughness);
        }
        if beta == Vec3::ZERO || !is_finite(beta) {
            break;
        }
        // What the next ray finds is direct after the first surface, and after the walk's own
        // boundary (internal reflection or the exit); the walk ends when the path leaves.
        (seg_direct, in_walk) = match depth {
            0 => (true, first == SUBSURFACE),
            _ if in_walk && inside_here => (true, medium.is_some()),
            _ => (false, false),
        };
        prev = Some(PrevVertex { ctx, bsdf_pdf: bs.pdf, delta: bs.flags.delta, kind, roughness: a_roughness, in_medium: false });
        cone = cone.after_bounce(cone_here, if bs.flags.delta { 0.0 } else { lobe_roughness });
        ray = Ray::new(offset_ray_origin(s.p, if wi.dot(ng) > 0.0 { ng } else { -ng }, s.offset_scale), wi);
        depth += 1;

        if depth >= settings.rr_start {
            let q = (1.0 - beta.max_element()).max(0.05);
            if u_rr < q {
                break;
            }
            beta /= 1.0 - q;
        }
    }

    if !is_finite(l) {
        counters.non_finite += 1;
        l = Vec3::ZERO;
        comp = [Vec3::ZERO; 5];
        direct = [Vec3::ZERO; 4];
    }
    out.radiance = l;
    out.components = comp;
    out.direct = direct;
    out
}
