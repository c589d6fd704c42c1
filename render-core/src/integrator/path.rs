//! What a path carries from vertex to vertex.

use glam::Vec3;

use crate::bsdf::PathKind;
use crate::caustics::RoughnessFloor;
use crate::geometry::Ray;
use crate::light::ShadingContext;
use crate::subsurface::Medium;

use super::IntegratorSettings;

/// Index of the emission component in [`crate::film::PixelSample::components`].
pub(super) const EMISSION: usize = 3;

/// Index of the subsurface component in [`crate::film::PixelSample::components`].
pub(super) const SUBSURFACE: usize = 4;

/// A ray's footprint as a cone (Akenine-Möller et al., "Texture Level of Detail Strategies
/// for Real-Time Ray Tracing", Ray Tracing Gems, 2019, chapter 20): width at the last vertex
/// and spread angle. Camera rays start with the pixel's angle.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayCone {
    pub width: f32,
    pub spread: f32,
}

impl RayCone {
    pub fn width_at(self, t: f32) -> f32 {
        self.width + self.spread * t
    }

    /// After scattering at a vertex where the cone was `width` wide, by a lobe of
    /// `roughness`: a glossy lobe widens the cone by about its lobe width (roughness² is the
    /// GGX α, the tangent of the lobe's half-angle), a mirror keeps it (surface curvature
    /// ignored), so textures seen in rough reflections are fetched blurred, as they look.
    pub fn after_bounce(self, width: f32, roughness: f32) -> RayCone {
        RayCone { width, spread: self.spread + roughness * roughness }
    }
}

/// Where the previous vertex sampled its outgoing direction from, for MIS.
#[derive(Clone, Copy)]
pub(super) struct PrevVertex {
    pub ctx: ShadingContext,
    pub bsdf_pdf: f32,
    pub delta: bool,
    /// The kind of lobe that sampled the direction, for lights' diffuse/specular multipliers.
    pub kind: PathKind,
    /// The roughest lobe there, for caustic avoidance's weighting.
    pub roughness: f32,
    /// A scattering event inside a subsurface medium: no next-event estimation there finds a
    /// light this direction can hit (only lights outside, through transparent shadows).
    pub in_medium: bool,
    /// The link group of the point ([`crate::scene::LightLinks`]): a linked light the
    /// direction finds counts only if it illuminates that group.
    pub receiver: u32,
}

/// The radiance a path has gathered, and its split into the light-path AOVs.
#[derive(Clone, Copy, Debug)]
pub(super) struct LightPaths {
    /// The radiance (the beauty).
    pub total: Vec3,
    /// Diffuse, specular, transmission, emission, subsurface: what the first surface did.
    pub components: [Vec3; 5],
    /// The direct parts of diffuse, specular, transmission and subsurface.
    pub direct: [Vec3; 4],
    /// The component the first scattering event chose.
    pub first: usize,
    /// Light the current ray finds comes straight from an emitter to the first surface (or to
    /// the medium behind it).
    pub seg_direct: bool,
    /// The path is still in the random walk the first surface started, before meeting any
    /// other surface.
    pub in_walk: bool,
}

impl LightPaths {
    fn new() -> Self {
        LightPaths {
            total: Vec3::ZERO,
            components: [Vec3::ZERO; 5],
            direct: [Vec3::ZERO; 4],
            first: EMISSION,
            seg_direct: false,
            in_walk: false,
        }
    }

    /// Adds `c` to the beauty and to component `k` (and to its direct part when `is_direct`).
    #[inline]
    pub fn add(&mut self, k: usize, c: Vec3, is_direct: bool) {
        self.total += c;
        self.record(k, c, is_direct);
    }

    /// Adds a contribution to light-path component `k` only, and to its direct part when it
    /// came straight from an emitter (emission has none: the camera sees it directly).
    #[inline]
    pub fn record(&mut self, k: usize, c: Vec3, is_direct: bool) {
        self.components[k] += c;
        if is_direct {
            match k {
                0..=2 => self.direct[k] += c,
                SUBSURFACE => self.direct[3] += c,
                _ => {}
            }
        }
    }

    /// The component light found by the current ray belongs to: emission seen from the
    /// camera, else what the first surface did.
    #[inline]
    pub fn found_at(&self, depth: u32) -> usize {
        if depth == 0 { EMISSION } else { self.first }
    }

    /// Drops everything (a non-finite sample).
    pub fn clear(&mut self) {
        *self = LightPaths { first: self.first, ..LightPaths::new() };
    }
}

/// The subsurface random walk a path is in.
#[derive(Clone, Copy, Default)]
pub(super) struct Walk {
    /// The medium the path is inside.
    pub medium: Option<Medium>,
    /// Transparent shadows from inside cross its boundary (any roughness below 1).
    pub shadows: bool,
    /// Scattering events taken in media.
    pub steps: u32,
}

/// The state of one path between vertices.
pub(super) struct PathState {
    /// The ray to trace next.
    pub ray: Ray,
    /// Throughput.
    pub beta: Vec3,
    /// The product of η'² over the refractions taken: radiance throughput drops by 1/η'² on
    /// entering glass and regains it on leaving, which Russian roulette must not read as
    /// lost energy (pbrt-v4's `etaScale`, Mitsuba 3's `eta`).
    pub eta_scale: f32,
    /// Scattering events so far.
    pub depth: u32,
    pub prev: Option<PrevVertex>,
    pub light: LightPaths,
    pub walk: Walk,
    /// The ray's footprint, for texture filtering.
    pub cone: RayCone,
    /// Caustic avoidance: the roughness every later lobe is clamped to.
    pub floor: RoughnessFloor,
    pub cutouts_crossed: usize,
    /// Caustic avoidance after a path leaves a subsurface medium: the share of the direct
    /// light it finds next that transparent shadows from inside did not already take.
    pub exit_share: f32,
}

impl PathState {
    pub fn new(camera_ray: Ray, settings: &IntegratorSettings) -> Self {
        PathState {
            ray: camera_ray,
            beta: Vec3::ONE,
            eta_scale: 1.0,
            depth: 0,
            prev: None,
            light: LightPaths::new(),
            walk: Walk::default(),
            cone: RayCone { width: settings.pixel_footprint.0, spread: settings.pixel_footprint.1 },
            floor: RoughnessFloor::default(),
            cutouts_crossed: 0,
            exit_share: 1.0,
        }
    }

    /// True when the throughput can no longer carry light.
    #[inline]
    pub fn is_dark(&self) -> bool {
        self.beta == Vec3::ZERO || !crate::math::is_finite(self.beta)
    }

    /// Russian roulette after `rr_start` bounces: the path survives with probability
    /// max(energy throughput, 0.05) and is reweighted by its inverse. The energy throughput is
    /// the radiance throughput times [`Self::eta_scale`], so paths inside glass (whose radiance
    /// throughput is 1/η² lower) are not killed for it. False when it ends.
    #[inline]
    pub fn survives_roulette(&mut self, rr_start: u32, u: f32) -> bool {
        if self.depth < rr_start {
            return true;
        }
        let q = (1.0 - (self.beta * self.eta_scale).max_element()).max(0.05);
        if u < q {
            return false;
        }
        self.beta /= 1.0 - q;
        true
    }
}

/// A contribution, clamped when it is indirect and a clamp is set.
#[inline]
pub(super) fn clamped(c: Vec3, indirect: bool, clamp: Option<f32>) -> Vec3 {
    match clamp {
        Some(max) if indirect && c.max_element() > max => c * (max / c.max_element()),
        _ => c,
    }
}
