//! What a render asks of the path tracer.

use crate::caustics::CausticMode;

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
    /// Run the general path loop whatever the scene's features (the benchmark of what the
    /// specialised loop buys; same image).
    pub general_loop: bool,
    /// A camera ray's footprint as a cone, (width, spread angle), for texture filtering;
    /// the renderer sets it from the camera. (0, 0) fetches the finest texture level.
    pub pixel_footprint: (f32, f32),
    /// What every path's light is multiplied by as it reaches the film: the camera's
    /// exposure as a linear scale; the renderer sets it from the camera.
    pub exposure_scale: f32,
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
            general_loop: false,
            strategy: LightStrategy::Mis,
            pixel_footprint: (0.0, 0.0),
            exposure_scale: 1.0,
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
