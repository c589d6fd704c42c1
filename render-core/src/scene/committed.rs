//! The renderable scene a commit produces, and the surface data at a hit.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::bvh::{Blas, Tlas};
use crate::camera::CameraDesc;
use crate::geometry::{Mesh, Transform};
use crate::light::LightSet;
use crate::material::Material;
use crate::plan::RenderPlan;

/// Per-instance data the integrator needs at a hit.
#[derive(Clone, Debug)]
pub struct InstanceData {
    /// Index into [`CommittedScene::meshes`].
    pub mesh: usize,
    /// Placement at the frame (traversal and shading use [`Self::motion`] when it moves).
    pub transform: Transform,
    /// Placements over the shutter when the instance moves ([`crate::motion`]).
    pub motion: Option<Arc<[glam::Affine3A]>>,
    /// Index into [`CommittedScene::materials`].
    pub material: u32,
    /// Index of the first triangle light of this instance, if its material emits.
    pub emitter_base: Option<u32>,
    /// Index into [`CommittedScene::prim_paths`].
    pub prim: u32,
}

/// The renderable scene: acceleration structures, materials, lights and the plan.
pub struct CommittedScene {
    /// Geometry per distinct mesh.
    pub meshes: Vec<Arc<Mesh>>,
    /// Triangles displacement dicing added to the description's (the server reserves memory
    /// for them after the commit, as it cannot know them before).
    pub diced_triangles: u64,
    /// Per mesh, its MikkTSpace tangents (per corner) when a normal map is drawn on it.
    pub(super) tangents: Vec<Option<Arc<crate::geometry::Attribute<glam::Vec4>>>>,
    pub(super) blases: Vec<Arc<Blas>>,
    /// Instances in the TLAS.
    pub instances: Vec<InstanceData>,
    pub(super) tlas: Tlas,
    /// Resolved materials; index 0 is the default material. A textured material is here as
    /// seen from afar (each texture at its mean); [`Self::textured`] gives it per point.
    pub materials: Vec<Material>,
    /// Per material, its inputs that vary over the surface, if any.
    pub textured: Vec<Option<Arc<crate::material::TexturedMaterial>>>,
    /// Each material's BSDF without and with energy compensation, built on first use of each
    /// setting (for a textured material, its mean).
    pub(super) bsdfs: [std::sync::OnceLock<Vec<crate::bsdf::Bsdf>>; 2],
    /// The same at each roughness floor of caustic avoidance ([`crate::caustics`]):
    /// `[level][material]`, built only by renders that avoid caustics.
    pub(super) floored_bsdfs: [std::sync::OnceLock<Vec<Vec<crate::bsdf::Bsdf>>>; 2],
    /// Each material's BSDF with every lobe (`force_all_effects`), built on first use.
    pub(super) every_lobe_bsdfs: [std::sync::OnceLock<Vec<crate::bsdf::Bsdf>>; 2],
    /// Per material whose base is partly a subsurface medium, its BSDF as a path inside the
    /// medium meets it (the boundary alone), built on first use.
    pub(super) inside_medium_bsdfs: [std::sync::OnceLock<Vec<Option<crate::bsdf::Bsdf>>>; 2],
    /// Each material's subsurface medium.
    pub(super) media: Vec<Option<crate::subsurface::Medium>>,
    /// Each material's smooth glass as transparent shadows see it.
    pub(super) shadow_glass: Vec<Option<crate::caustics::ShadowGlass>>,
    /// Per material, its subsurface medium's boundary as shadows from inside see it.
    pub(super) medium_boundary: Vec<Option<crate::caustics::ShadowGlass>>,
    /// Materials some instance uses: only their lobes' energy tables are built.
    pub(super) used_materials: Vec<u32>,
    /// Lights and their selection distribution.
    pub lights: LightSet,
    /// Per instance whose textured glow tints a mesh light (sorted by instance): what the
    /// light multiplies the glow by ([`crate::light::MeshLight::radiance`] without the tint).
    pub glow_scales: Vec<(u32, glam::Vec3)>,
    /// Indices of the finite lights a ray may cross (area lights; not triangle emitters,
    /// which are found through the BVH).
    pub crossable_lights: crate::light::tree::LightTree,
    /// Indices of the lights at infinity.
    pub infinite_lights: Vec<u32>,
    /// Which lights reach and are shadowed by which prims; None when no light links.
    pub links: Option<super::LightLinks>,
    /// Prim path of each instance's source.
    pub prim_paths: Vec<String>,
    /// Cameras, copied from the description.
    pub cameras: BTreeMap<String, CameraDesc>,
    /// World bounds of the geometry (min, max); empty scenes have min > max.
    pub bounds: (Vec3, Vec3),
    /// Volumes, in path order.
    pub volumes: Vec<crate::volume::Volume>,
    /// What the renderer simulates for this scene.
    pub plan: RenderPlan,
    /// What commit could not honour, by prim.
    pub warnings: Vec<String>,
    /// Materials whose subsurface medium lies behind a smooth boundary (roughness up to
    /// [`crate::caustics::SMOOTH_GLASS`]): full path tracing lights them only by chance.
    pub smooth_subsurface: Vec<String>,
}

/// Surface data at a ray hit, in world space.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal (not face-forwarded).
    pub ng: Vec3,
    /// Unit shading normal (not face-forwarded).
    pub ns: Vec3,
    /// Material index.
    pub material: u32,
    /// Triangle-light index when the surface emits.
    pub light: Option<u32>,
    /// The size that bounds the error of `p`: the larger of its coordinates and the hit
    /// triangle's world-space edges. Ray origins leaving the surface are offset in proportion
    /// ([`crate::geometry::offset_ray_origin`]), so a 1 km ground plane and a 1 mm bead in the
    /// same scene each get an offset fit for them.
    pub offset_scale: f32,
    /// The object's up axis (local +Y) in world space: anisotropic and fabric materials run
    /// their tangent around it ([`crate::math::Frame::from_normal_around`]) until meshes carry
    /// UV tangents.
    pub up: Vec3,
    /// Texture coordinates, when the mesh has them.
    pub st: Option<Vec2>,
    /// Texture-space length per world-space length on the hit triangle (0 without `st`).
    pub uv_density: f32,
    /// World-space ∂p/∂s and ∂p/∂t of the hit triangle (zero without `st`): the tangent frame
    /// of normal maps.
    pub dpds: Vec3,
    /// See [`Self::dpds`].
    pub dpdt: Vec3,
    /// The instance hit.
    pub instance: u32,
    /// The triangle hit, in its mesh.
    pub triangle: u32,
    /// Barycentrics (b1, b2) of the hit.
    pub bary: Vec2,
    /// World-space MikkTSpace tangent (xyz, interpolated) and bitangent sign (w) where the
    /// mesh is normal-mapped; zero elsewhere.
    pub tangent: glam::Vec4,
    /// The shutter time of the ray that found it: rays leaving it travel then too.
    pub time: f32,
}

/// A uniform number in [0, 1) for a ray meeting a partially present surface at `p` along
/// `dir`: a hash of the two, so the decision needs no sampler dimension and shadow rays make it
/// as camera rays do. Positions differ from sample to sample, so the coins are independent.
pub fn see_through_coin(p: Vec3, dir: Vec3) -> f32 {
    (ray_hash(p, dir, 0x5ee7_4409) >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// A hash of a ray's origin and direction (and a `salt` per use), for decisions and random
/// streams a ray makes without a sampler dimension.
pub fn ray_hash(p: Vec3, dir: Vec3, salt: u64) -> u64 {
    let bits = |v: Vec3| ((v.x.to_bits() as u64) << 32 | v.y.to_bits() as u64) ^ (v.z.to_bits() as u64).rotate_left(17);
    crate::sampling::mix64(bits(p) ^ crate::sampling::mix64(bits(dir) ^ salt))
}

/// Cut-out surfaces a ray passes through before the rest counts as opaque.
pub const MAX_CUTOUT_CROSSINGS: usize = 64;
