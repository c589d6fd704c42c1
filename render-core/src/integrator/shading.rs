//! Shading-point setup: the material where the ray landed (textures resolved at the ray's
//! footprint), cut-outs and partial presence, normal maps, the BSDF and its frame.

use glam::Vec3;

use crate::bsdf::Bsdf;
use crate::bvh::Hit;
use crate::caustics::RoughnessFloor;
use crate::geometry::{Ray, offset_ray_origin};
use crate::material::{Material, Tilt, Uber};
use crate::math::Frame;
use crate::scene::SurfaceHit;

use super::Tracer;
use super::path::PathState;

/// A textured material resolved at a shading point, and what tilts its normal there.
pub(super) type LocalMaterial = Option<(Material, Option<Tilt>)>;

/// A surface a path scatters at, set up for shading.
pub(super) struct Vertex<'l> {
    /// The surface, its shading normal normal-mapped.
    pub s: SurfaceHit,
    /// Towards the previous vertex.
    pub wo: Vec3,
    /// The material resolved here and what tilts its normal, for textured materials: in the
    /// path's own buffer, as a BSDF built here is (a material is 464 bytes; every vertex
    /// moved it).
    pub local: Option<&'l (Material, Option<Tilt>)>,
    /// The BSDF, prepared for this view: the material's own or the path's buffer.
    pub bsdf: &'l Bsdf,
    /// Shading and geometric normals, oriented for the BSDF (see [`Tracer::orient`]).
    pub ns: Vec3,
    pub ng: Vec3,
    pub frame: Frame,
    pub wo_local: Vec3,
    /// The surface's own roughness (before caustic avoidance clamps it).
    pub a_roughness: f32,
    /// The ray cone's width here.
    pub cone_here: f32,
    /// The BSDF is a hair fibre's, which stands for the whole fibre rather than the facet.
    pub fibre: bool,
}

impl Vertex<'_> {
    /// Where an interpolated normal and the facet disagree about which side a direction is
    /// on, following it would reflect into the surface or refract out of the wrong side
    /// (light leaks through tessellated glass); such directions carry no light instead.
    /// A fibre's directions all leave the fibre, whichever side of the facet they take: the
    /// ray is spawned on that side and crosses the tube if it points in (at a lone fibre's
    /// silhouette, dropping them lost 12% of a white fibre's light).
    #[inline]
    pub fn sides_agree(&self, w: Vec3, local_z: f32) -> bool {
        self.fibre || w.dot(self.ng) * local_z > 0.0
    }

    /// A ray leaving the surface along `dir`, its origin offset to the side `dir` is on.
    #[inline]
    pub fn leave(&self, dir: Vec3) -> Ray {
        Ray::new(offset_ray_origin(self.s.p, if dir.dot(self.ng) > 0.0 { self.ng } else { -self.ng }, self.s.offset_scale), dir)
            .with_time(self.s.time)
    }
}

/// What the ray met. The vertex is returned inline: boxing it cost an allocation per bounce.
#[allow(clippy::large_enum_variant)]
pub(super) enum Landing<'l> {
    /// A surface to scatter at.
    Surface(Vertex<'l>),
    /// A surface cut out or absent here: the ray goes on (the path's ray is already updated).
    PassedThrough,
    /// More cut-outs than a ray crosses: the rest counts as opaque.
    Stopped,
}

impl<'a, const FULL: bool> Tracer<'a, FULL> {
    /// Sets up shading at `hit`: the vertex's BSDF, prepared for its view, is the material's
    /// own where that serves every view, or else written into `bsdf`; a textured material
    /// resolved here goes into `local` (buffers for the whole path).
    pub(super) fn land<'l>(&self, path: &mut PathState, hit: &Hit, bsdf: &'l mut Bsdf, local: &'l mut LocalMaterial) -> Landing<'l>
    where
        'a: 'l,
    {
        let scene = self.scene;
        let mut s = scene.surface(hit);
        let ray = path.ray;
        let cone_here = path.cone.width_at(hit.t);
        // A textured material is resolved here, at this point and footprint.
        *local = scene.textured(s.material).map(|t| {
            let cos = s.ng.dot(ray.dir).abs() / ray.dir.length();
            t.at(&scene.shading_point(&s, cone_here, cos))
        });
        let local: &'l LocalMaterial = local;
        if FULL && self.passes_through(&s, ray.dir, local) {
            // It goes on as if the surface were not there.
            path.cutouts_crossed += 1;
            if path.cutouts_crossed > crate::scene::MAX_CUTOUT_CROSSINGS {
                return Landing::Stopped;
            }
            path.cone.width = cone_here;
            path.ray = Ray { origin: offset_ray_origin(s.p, if ray.dir.dot(s.ng) > 0.0 { s.ng } else { -s.ng }, s.offset_scale), ..ray };
            path.ray.tmax = f32::INFINITY;
            return Landing::PassedThrough;
        }
        match local {
            Some((_, Some(Tilt::NormalMap(n)))) => s.ns = crate::tangents::normal_mapped(s.ns, s.tangent, s.dpds, s.dpdt, *n),
            Some((_, Some(Tilt::Bump(slope)))) => s.ns = crate::tangents::bumped(s.ns, s.dpds, s.dpdt, *slope),
            _ => {}
        }
        let wo = -ray.dir;
        let (shared, glitter) = self.choose_bsdf(path, &s, local, bsdf);
        let a_roughness = self.own_roughness(&s, local);
        let chosen = shared.unwrap_or(bsdf);
        let (ns, ng) = orient(&s, wo, chosen.transmits());
        let fibre = FULL && chosen.is_fibre();
        let frame = if fibre {
            // A fibre's frame runs along the curve (the tube's texture t), root to tip.
            Frame::from_normal_along(ns, s.dpdt, s.up)
        } else if self.force() || chosen.is_anisotropic() {
            self.anisotropic_frame(&s, ns, local)
        } else {
            Frame::from_normal(ns)
        };
        if let Some(u) = &glitter {
            self.apply_glitter(u, &s, ns, &frame, cone_here, bsdf);
        }
        let wo_local = frame.to_local(wo);
        let bsdf: &'l Bsdf = match shared {
            Some(b) => b,
            None => {
                bsdf.prepare(wo_local);
                bsdf
            }
        };
        Landing::Surface(Vertex { s, wo, local: local.as_ref(), bsdf, ns, ng, frame, wo_local, a_roughness, cone_here, fibre })
    }

    /// The frame anisotropic lobes turn with: along the material's `tangent` where it gives
    /// one (a direction in object space), else along dP/ds where it asks for that and the mesh
    /// has texture coordinates, else around the object's up axis; then turned by its rotation.
    fn anisotropic_frame(&self, s: &SurfaceHit, ns: Vec3, local: &LocalMaterial) -> Frame {
        let tangent = match local {
            Some((m, _)) => m.tangent,
            None => self.scene.materials[s.material as usize].tangent,
        };
        let frame = if tangent.direction != Vec3::ZERO {
            let along = self.scene.placement(s.instance, s.time).to_world.transform_vector3(tangent.direction);
            Frame::from_normal_along(ns, along, s.up)
        } else if tangent.along_st {
            // dP/ds is already in world space; a mesh without texture coordinates has none.
            Frame::from_normal_along(ns, s.dpds, s.up)
        } else {
            Frame::from_normal_around(ns, s.up)
        };
        frame.turned(tangent.rotation)
    }

    /// True when the ray passes `s` untouched: cut out here, not present for this ray where
    /// the surface is partially present, or the inside of a hair tube.
    fn passes_through(&self, s: &SurfaceHit, dir: Vec3, local: &LocalMaterial) -> bool {
        let pass_through = local.as_ref().map_or(self.scene.materials[s.material as usize].pass_through, |(m, _)| m.pass_through);
        let absent = pass_through > 0.0 && crate::scene::see_through_coin(s.p, dir) < pass_through;
        absent || local.as_ref().is_some_and(|(m, _)| m.cut_out) || self.scene.inside_fibre(s, dir)
    }

    /// The BSDF at `s`: the material's (at caustic avoidance's roughness floor), with every
    /// lobe when forced, or a glitter material's base lobes, whose flakes are added once the
    /// frame is known (returned). A material's own BSDF that serves every view is returned to
    /// be shared; any other is written into `bsdf`.
    fn choose_bsdf(&self, path: &PathState, s: &SurfaceHit, local: &LocalMaterial, bsdf: &mut Bsdf) -> (Option<&'a Bsdf>, Option<Uber>) {
        let (ec, force) = (self.settings.energy_compensation, self.force());
        let level = if self.avoid() { path.floor.level() } else { 0 };
        // Glitter flakes depend on the point and footprint: such materials build their lobes
        // here, the flakes once the shading frame is known.
        let uber_here = local.as_ref().map_or(&self.scene.materials[s.material as usize].surface, |(m, _)| &m.surface);
        let glitter = (FULL && uber_here.has_glitter())
            .then(|| if force { *uber_here } else { uber_here.with_roughness_floor(RoughnessFloor::of_level(level)) });
        match local {
            _ if let Some(u) = &glitter => *bsdf = u.base_bsdf(ec, force),
            // From inside its medium a partly scattering surface is the boundary alone.
            _ if FULL && path.walk.medium.is_some() && uber_here.is_partly_medium() => {
                match self.scene.bsdf_inside_medium(s.material, ec) {
                    Some(own) if local.is_none() && !force && level == 0 => bsdf.clone_from(own),
                    _ => {
                        let inside = uber_here.inside_medium();
                        let floor = RoughnessFloor::of_level(level);
                        *bsdf = if force { inside.bsdf_with_every_lobe(ec) } else { inside.with_roughness_floor(floor).bsdf(ec) }
                    }
                }
            }
            Some((m, _)) if force => *bsdf = m.surface.bsdf_with_every_lobe(ec),
            Some((m, _)) => *bsdf = m.surface.with_roughness_floor(RoughnessFloor::of_level(level)).bsdf(ec),
            None if force => bsdf.clone_from(self.scene.bsdf_with_every_lobe(s.material, ec)),
            None => {
                let own = self.scene.bsdf_floored(s.material, ec, level);
                if own.is_view_independent() {
                    // Settled when the scene built it: copying and preparing it gave the same
                    // lobe again, for 81 instructions a Cornell box vertex.
                    return (Some(own), None);
                }
                bsdf.clone_from(own);
            }
        }
        (None, glitter)
    }

    /// The surface's own roughness (before clamping), which weighs transparent shadows
    /// against paths through glass on both sides of the comparison; 0 without caustic
    /// avoidance, which alone reads it.
    fn own_roughness(&self, s: &SurfaceHit, local: &LocalMaterial) -> f32 {
        let ec = self.settings.energy_compensation;
        match local {
            Some((m, _)) if self.avoid() => m.surface.bsdf(ec).roughness(),
            None if self.avoid() => self.scene.bsdf(s.material, ec).roughness(),
            _ => 0.0,
        }
    }

    /// Adds a glitter material's flakes at `s` to `bsdf`.
    fn apply_glitter(&self, u: &Uber, s: &SurfaceHit, ns: Vec3, frame: &Frame, cone_here: f32, bsdf: &mut Bsdf) {
        let placement = self.scene.placement(s.instance, s.time);
        let t = placement.as_ref();
        let m3 = t.to_world.matrix3;
        // Flakes live in object space (Xie & Lanz 2017, "Physically Based Shading at DreamWorks
        // Animation", section 3.5); so does the footprint.
        let n_obj = Vec3::from(m3.transpose() * glam::Vec3A::from(ns)).normalize_or_zero();
        let radius = 0.5 * cone_here / m3.determinant().abs().cbrt();
        let g = &u.glitter;
        let flakes = g.params.flakes_at(t.to_object.transform_point3(s.p), n_obj, radius);
        g.params.apply(g.weight, &flakes, bsdf, |n| frame.to_local((t.normal_matrix * n).normalize_or(ns)));
    }
}

/// The shading and geometric normals the BSDF sees. Opaque surfaces are two-sided: both
/// normals face the viewer. Transmissive ones keep their authored orientation (the shading
/// normal's side is outside) so a ray inside glass sees its inside. The geometric normal is
/// turned to the shading normal's side; a direction the two normals put on different sides
/// is dropped ([`Vertex::sides_agree`]).
fn orient(s: &SurfaceHit, wo: Vec3, transmits: bool) -> (Vec3, Vec3) {
    if transmits {
        let ng = if s.ng.dot(s.ns) < 0.0 { -s.ng } else { s.ng };
        // Near silhouettes the viewer itself can be on different sides of the two normals:
        // there the facet decides.
        if wo.dot(ng) * wo.dot(s.ns) > 0.0 { (s.ns, ng) } else { (ng, ng) }
    } else {
        // Both normals on the viewer's side of the facet, the shading normal bent back where
        // it would leave the viewer below its horizon.
        let ng = if s.ng.dot(wo) < 0.0 { -s.ng } else { s.ng };
        if s.ns == s.ng {
            // A flat facet (no shading normals): nothing to bend.
            return (ng, ng);
        }
        let ns = if s.ns.dot(ng) < 0.0 { -s.ns } else { s.ns };
        (crate::math::valid_shading_normal(ng, wo, ns), ng)
    }
}
