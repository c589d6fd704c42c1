//! Queries on the committed scene: BSDFs by material, ray hits and occlusion, surface data,
//! textured emission and cut-outs, cameras.

use glam::{Affine3A, Vec2, Vec3};
use rayon::prelude::*;

use super::{CommittedScene, MAX_CUTOUT_CROSSINGS, SceneError, SurfaceHit, see_through_coin};
use crate::bvh::Hit;
use crate::camera::CameraDesc;
use crate::geometry::Ray;
use crate::plan::Feature;

/// A material's BSDF as the scene keeps it: settled for every view when it can be
/// ([`crate::bsdf::Bsdf::settle`]), so shading points share it rather than copy it.
fn settled(mut bsdf: crate::bsdf::Bsdf) -> crate::bsdf::Bsdf {
    bsdf.settle();
    bsdf
}

impl CommittedScene {
    /// Builds the BSDFs for one energy-compensation setting, and the energy tables their
    /// lobes read, for the materials some instance uses: a render calls this before its first
    /// tile, so a render with compensation off never builds the compensation tables and the
    /// fallback material counts only when a mesh falls back to it.
    pub fn prepare_bsdfs(&self, energy_compensation: bool) -> &[crate::bsdf::Bsdf] {
        self.bsdfs[energy_compensation as usize].get_or_init(|| {
            let _span = tracing::info_span!("prepare_bsdfs", energy_compensation).entered();
            // Materials side by side: a glossy scene's first tile waits for the energy-table
            // rows its materials read, and a row holds the same bits whichever thread builds it.
            let set: Vec<crate::bsdf::Bsdf> = self.materials.par_iter().map(|m| settled(m.bsdf(energy_compensation))).collect();
            self.used_materials.par_iter().for_each(|&m| set[m as usize].build_tables());
            set
        })
    }

    /// The BSDFs at every roughness floor of caustic avoidance (`[level][material]`, level 0
    /// the materials' own), built on first use.
    pub fn prepare_floored_bsdfs(&self, energy_compensation: bool) -> &[Vec<crate::bsdf::Bsdf>] {
        self.floored_bsdfs[energy_compensation as usize].get_or_init(|| {
            let _span = tracing::info_span!("prepare_floored_bsdfs", energy_compensation).entered();
            // Levels and materials side by side, as in `prepare_bsdfs`.
            (0..crate::caustics::FLOOR_LEVELS)
                .into_par_iter()
                .map(|level| {
                    let floor = crate::caustics::RoughnessFloor::of_level(level);
                    self.materials.par_iter().map(|m| settled(m.surface.with_roughness_floor(floor).bsdf(energy_compensation))).collect()
                })
                .collect()
        })
    }

    /// The BSDF of material `index` with every microfacet lobe at least as rough as floor
    /// `level` (0: the material's own).
    #[inline]
    pub fn bsdf_floored(&self, index: u32, energy_compensation: bool, level: usize) -> &crate::bsdf::Bsdf {
        if level == 0 {
            return self.bsdf(index, energy_compensation);
        }
        &self.prepare_floored_bsdfs(energy_compensation)[level][index as usize]
    }

    /// Material `index`'s BSDF holding every lobe the uber-material can build (unused ones at
    /// weight 0), with all their energy tables built: the cost without a render plan.
    pub fn bsdf_with_every_lobe(&self, index: u32, energy_compensation: bool) -> &crate::bsdf::Bsdf {
        &self.every_lobe_bsdfs[energy_compensation as usize].get_or_init(|| {
            let set: Vec<crate::bsdf::Bsdf> = self.materials.iter().map(|m| m.surface.bsdf_with_every_lobe(energy_compensation)).collect();
            set.iter().for_each(|b| b.build_tables());
            set
        })[index as usize]
    }

    /// Per material whose base is only partly a subsurface medium, its BSDF as a path inside
    /// the medium meets it: the boundary alone (None for any other material). Building a
    /// compensated boundary costs more than the walk's step, so it is built once; a render
    /// builds the set before its tiles start, as for the other sets.
    pub fn prepare_inside_medium_bsdfs(&self, energy_compensation: bool) -> &[Option<crate::bsdf::Bsdf>] {
        self.inside_medium_bsdfs[energy_compensation as usize].get_or_init(|| {
            let inside = |m: &crate::material::Material| {
                let b = settled(m.surface.inside_medium().bsdf(energy_compensation));
                b.build_tables();
                b
            };
            self.materials.par_iter().map(|m| m.surface.is_partly_medium().then(|| inside(m))).collect()
        })
    }

    /// Material `index`'s BSDF inside its medium ([`Self::prepare_inside_medium_bsdfs`]).
    #[inline]
    pub fn bsdf_inside_medium(&self, index: u32, energy_compensation: bool) -> Option<&crate::bsdf::Bsdf> {
        self.prepare_inside_medium_bsdfs(energy_compensation).get(index as usize)?.as_ref()
    }

    /// The scattering medium behind material `index`'s surface (subsurface scattering).
    #[inline]
    pub fn medium(&self, index: u32) -> Option<crate::subsurface::Medium> {
        self.media.get(index as usize).copied().flatten()
    }

    /// Material `index`'s glass as transparent shadows see it (None: opaque to them).
    #[inline]
    pub fn shadow_glass(&self, index: u32) -> Option<crate::caustics::ShadowGlass> {
        self.shadow_glass.get(index as usize).copied().flatten()
    }

    /// Material `index`'s subsurface boundary as transparent shadows from inside its medium
    /// see it (None: no medium, or too rough to cross).
    #[inline]
    pub fn medium_boundary(&self, index: u32) -> Option<crate::caustics::ShadowGlass> {
        self.medium_boundary.get(index as usize).copied().flatten()
    }

    /// The BSDF of material `index` (unprepared), with or without energy compensation.
    #[inline]
    pub fn bsdf(&self, index: u32, energy_compensation: bool) -> &crate::bsdf::Bsdf {
        &self.prepare_bsdfs(energy_compensation)[index as usize]
    }

    /// Closest surface hit along `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.tlas.intersect(&self.blases, ray)
    }

    /// Material `index`'s inputs that vary over the surface, if any.
    #[inline]
    pub fn textured(&self, index: u32) -> Option<&crate::material::TexturedMaterial> {
        self.textured.get(index as usize).and_then(|t| t.as_deref())
    }

    /// Emitted radiance at world point `p` on triangle `triangle` of instance `instance` at
    /// shutter time `time`, for materials whose emission is textured (finest texture level: a
    /// light sample has no footprint).
    pub fn emission_at(&self, instance: u32, triangle: u32, p: Vec3, time: f32) -> Vec3 {
        self.textured_emission_at(instance, triangle, p, time) * self.glow_scale(instance)
    }

    /// What a mesh light multiplies the textured glow of `instance` by; 1 for an emissive
    /// material that is not a light's.
    #[inline]
    pub fn glow_scale(&self, instance: u32) -> Vec3 {
        match self.glow_scales.binary_search_by_key(&instance, |&(i, _)| i) {
            Ok(k) => self.glow_scales[k].1,
            Err(_) => Vec3::ONE,
        }
    }

    /// The material's emission of `triangle` of `instance` at `p`.
    fn textured_emission_at(&self, instance: u32, triangle: u32, p: Vec3, time: f32) -> Vec3 {
        let inst = &self.instances[instance as usize];
        let Some(t) = self.textured(inst.material) else { return self.materials[inst.material as usize].emission };
        let to_world = self.placement(instance, time).to_world;
        let [a, b, c] = self.meshes[inst.mesh].triangle_at(triangle as usize, time).map(|v| to_world.transform_point3(v));
        // Barycentrics of p by areas (p lies on the triangle up to rounding).
        let n = (b - a).cross(c - a);
        let nn = n.length_squared();
        if nn <= 0.0 {
            return Vec3::ZERO;
        }
        let b1 = (p - a).cross(c - a).dot(n) / nn;
        let b2 = (b - a).cross(p - a).dot(n) / nn;
        // Only what the lookup reads: no full surface (normals, tangents) per light sample.
        t.at(&self.point_on(instance, triangle, Vec2::new(b1, b2).clamp(Vec2::ZERO, Vec2::ONE))).0.emission
    }

    /// What a textured material needs to know of the surface at `s`, seen by a ray whose
    /// footprint is `width` wide at |cos| `cos` to the surface.
    pub fn shading_point(&self, s: &SurfaceHit, width: f32, cos: f32) -> crate::material::ShadingPoint<'_> {
        let mut sp = self.point_on(s.instance, s.triangle, s.bary);
        (sp.st, sp.width, sp.cos, sp.uv_density) = (s.st, width, cos, s.uv_density);
        sp
    }

    /// The shading point at barycentrics `bary` of `triangle` of `instance` for a lookup without
    /// footprint (the finest texture level): texture coordinates and primvars only.
    fn point_on(&self, instance: u32, triangle: u32, bary: Vec2) -> crate::material::ShadingPoint<'_> {
        let mesh = &self.meshes[self.instances[instance as usize].mesh];
        let tri = triangle as usize;
        let primvars = (!mesh.primvars.is_empty()).then_some(crate::material::graph::PrimvarSource { mesh, triangle: tri, bary });
        let st = mesh.uvs.interpolate(tri, mesh.indices[tri], bary);
        crate::material::ShadingPoint { st, primvars, width: 0.0, cos: 1.0, uv_density: 0.0 }
    }

    /// True when a ray along `dir` passes the surface `s` untouched: cut out there by a
    /// textured opacity (lookups at the finest level: shadow rays carry no footprint), or
    /// not present for this ray where the surface is partially present
    /// ([`crate::material::Material::pass_through`]: a coin with that chance, tossed by [`see_through_coin`]).
    pub fn see_through_at(&self, s: &SurfaceHit, dir: Vec3) -> bool {
        if self.inside_fibre(s, dir) {
            return true;
        }
        let pass = match self.textured(s.material).filter(|t| t.may_see_through()) {
            Some(t) => {
                let m = t.at(&self.shading_point(s, 0.0, 1.0)).0;
                if m.cut_out {
                    return true;
                }
                m.pass_through
            }
            None => self.materials[s.material as usize].pass_through,
        };
        pass > 0.0 && see_through_coin(s.p, dir) < pass
    }

    /// True when a ray along `dir` meets the hair tube `s` from inside. The hair BSDF accounts
    /// for every path through the fibre, so a ray it sends into the tube (TT, TRT) leaves
    /// through the far wall untouched; the wall faces the ray when the facet, turned to the
    /// outward shading normal, faces away from it.
    #[inline]
    pub fn inside_fibre(&self, s: &SurfaceHit, dir: Vec3) -> bool {
        if !(self.materials[s.material as usize].surface.hair.weight > 0.0) {
            return false;
        }
        let outward = if s.ng.dot(s.ns) < 0.0 { -s.ng } else { s.ng };
        dir.dot(outward) > 0.0
    }

    /// True when a surface blocks the ray before `tmax`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, tmax: f32) -> bool {
        if self.plan.features.has_any(&[Feature::TexturedCutouts, Feature::PartialPresence, Feature::Hair]) {
            return self.occluded_past_cutouts(ray, tmax);
        }
        self.tlas.occluded(&self.blases, ray, tmax)
    }

    /// Occlusion of a shadow ray towards light `light`, whose shadows only some prims may
    /// cast (UsdLux `collection:shadowLink`): the ray walks past the others.
    pub fn occluded_for(&self, ray: &Ray, tmax: f32, light: usize) -> bool {
        match &self.links {
            Some(links) if links.shadow_linked(light) => self.occluded_past(ray, tmax, |hit| links.casts_shadow(light, hit.instance)),
            _ => self.occluded(ray, tmax),
        }
    }

    /// Occlusion walking through the points of surfaces their opacity cuts out.
    fn occluded_past_cutouts(&self, ray: &Ray, tmax: f32) -> bool {
        self.occluded_past(ray, tmax, |_| true)
    }

    /// Occlusion walking past cut-out points and past the hits `blocks` says do not count.
    fn occluded_past(&self, ray: &Ray, tmax: f32, blocks: impl Fn(&Hit) -> bool) -> bool {
        let mut r = ray.with_tmax(tmax);
        // Each step passes one surface; a stack of more than this is treated as opaque.
        for _ in 0..MAX_CUTOUT_CROSSINGS {
            let Some(hit) = self.tlas.intersect(&self.blases, &r) else { return false };
            let s = self.surface(&hit);
            if blocks(&hit) && !self.see_through_at(&s, r.dir) {
                return true;
            }
            let origin = crate::geometry::offset_ray_origin(s.p, if r.dir.dot(s.ng) > 0.0 { s.ng } else { -s.ng }, s.offset_scale);
            let left = r.tmax - (origin - r.origin).dot(r.dir) / r.dir.length_squared();
            if left <= 0.0 {
                return false;
            }
            r = Ray { origin, tmax: left, ..r };
        }
        true
    }

    /// Where instance `index` is at shutter time `time`.
    #[inline]
    pub fn placement(&self, index: u32, time: f32) -> std::borrow::Cow<'_, crate::geometry::Transform> {
        let inst = &self.instances[index as usize];
        match &inst.motion {
            None => std::borrow::Cow::Borrowed(&inst.transform),
            Some(m) => std::borrow::Cow::Owned(crate::motion::placement_at(m, time)),
        }
    }

    /// World-space surface data at `hit`.
    pub fn surface(&self, hit: &Hit) -> SurfaceHit {
        let inst = &self.instances[hit.instance as usize];
        let placement = self.placement(hit.instance, hit.time);
        let xf = placement.as_ref();
        let mesh = &self.meshes[inst.mesh];
        let tri = hit.triangle as usize;
        let [a, b, c] = mesh.triangle_at(tri, hit.time);
        let w = Vec2::new(hit.bary.x, hit.bary.y);
        let p_obj = a * (1.0 - w.x - w.y) + b * w.x + c * w.y;
        let p = xf.to_world.transform_point3(p_obj);
        let ng = (xf.normal_matrix * (b - a).cross(c - a)).normalize_or_zero();
        let ng = if ng == Vec3::ZERO { Vec3::Z } else { ng };
        let ns = mesh
            .shading_normal(tri, w)
            .map(|n| (xf.normal_matrix * n).normalize_or_zero())
            .filter(|n| *n != Vec3::ZERO && n.is_finite())
            .unwrap_or(ng);
        let m = xf.to_world.matrix3;
        let edges = (m * glam::Vec3A::from(b - a)).abs().max((m * glam::Vec3A::from(c - a)).abs()).max_element();
        let offset_scale = p.abs().max_element().max(edges);
        let up = Vec3::from(m * glam::Vec3A::Y);
        let mut s = SurfaceHit {
            p,
            ng,
            ns,
            material: inst.material,
            light: inst.emitter_base.map(|b| b + hit.triangle),
            offset_scale,
            up,
            st: None,
            uv_density: 0.0,
            dpds: Vec3::ZERO,
            dpdt: Vec3::ZERO,
            instance: hit.instance,
            triangle: hit.triangle,
            bary: w,
            tangent: glam::Vec4::ZERO,
            time: hit.time,
        };
        if let Some(v) = self.tangents[inst.mesh].as_ref().and_then(|t| t.interpolate(tri, mesh.indices[tri], w)) {
            s.tangent = Vec3::from(m * glam::Vec3A::from(v.truncate())).extend(if v.w < 0.0 { -1.0 } else { 1.0 });
        }
        if let Some([ta, tb, tc]) = mesh.uvs.corners(tri, mesh.indices[tri]) {
            s.st = Some(ta * (1.0 - w.x - w.y) + tb * w.x + tc * w.y);
            let (d1, d2) = (tb - ta, tc - ta);
            let (e1, e2) = (Vec3::from(m * glam::Vec3A::from(b - a)), Vec3::from(m * glam::Vec3A::from(c - a)));
            let uv_area = d1.perp_dot(d2);
            let world_area = e1.cross(e2).length();
            if uv_area != 0.0 && world_area > 0.0 {
                s.uv_density = (uv_area.abs() / world_area).sqrt();
                let r = 1.0 / uv_area;
                s.dpds = (e1 * d2.y - e2 * d1.y) * r;
                s.dpdt = (e2 * d1.x - e1 * d2.x) * r;
            }
        }
        s
    }

    /// The scene's camera at `path`, the first camera when `path` is empty, or a default
    /// camera framing the scene's bounds when it has none.
    pub fn camera(&self, path: &str) -> Result<CameraDesc, SceneError> {
        if !path.is_empty() {
            return self.cameras.get(path).cloned().ok_or_else(|| SceneError::Dangling {
                prim: "render settings".into(),
                field: "camera".into(),
                target: path.into(),
            });
        }
        if let Some(c) = self.cameras.values().next() {
            return Ok(c.clone());
        }
        let (lo, hi) = self.bounds;
        let (center, radius) = if lo.x <= hi.x { (0.5 * (lo + hi), 0.5 * (hi - lo).length().max(1e-3)) } else { (Vec3::ZERO, 1.0) };
        let d = CameraDesc::default();
        // Back off along +Z until the bounding sphere fits the vertical field of view.
        let half = (0.5 * d.vertical_aperture / d.focal_length).atan();
        let dist = radius / half.sin();
        Ok(CameraDesc { transform: Affine3A::from_translation(center + Vec3::Z * dist), near: (dist - radius).max(1e-3) * 0.5, ..d })
    }
}
