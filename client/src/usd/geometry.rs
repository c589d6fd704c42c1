//! Meshes and implicit prims: points, faces, normals, texture coordinates, primvars, GeomSubsets, display colours.

use anyhow::{Context, Result};

use super::subdivision::{self, SubdivTags};
use super::*;

/// A mesh prim's cage as read, before refinement and triangulation.
pub(super) struct CageRead {
    /// Its points (posed), faces, normals, texture coordinates and primvars.
    pub src: MeshSource,
    pub tags: SubdivTags,
    /// Positions and faces only, for the deformation's samples, when the points move within
    /// an open shutter.
    shape_only: Option<MeshSource>,
    /// A skinned mesh's authored points, which each deformation sample poses again.
    rest: Option<Vec<Vec3>>,
    /// Where the warnings of its refinement and triangulation go among the stage's.
    pub warnings_at: usize,
}

impl CageRead {
    /// True when the points move over the shutter (the deformation's samples need the
    /// refinement's faces).
    pub fn deforms(&self) -> bool {
        self.shape_only.is_some()
    }
}

/// `src` refined at `level`, with its render-plan entry and the cage face of each refined face;
/// or, when OpenSubdiv cannot take the cage (bad crease data, a Loop mesh with quads), `src`
/// unrefined, with a warning naming the attribute. Either way without its authored normals:
/// they are for polygons, and UsdGeomMesh says a subdivision surface ignores them.
pub(super) fn refine_cage(
    p: &str,
    src: MeshSource,
    tags: &SubdivTags,
    level: u32,
    warnings: &mut Vec<String>,
) -> (MeshSource, Option<(Subdivided, Vec<u32>)>) {
    let src = MeshSource { normals: None, ..src };
    match subdivision::refine(&src, tags, level, |w| warnings.push(format!("{p}: {w}"))) {
        Ok(r) => {
            let entry = Subdivided { path: p.to_string(), scheme: tags.scheme.clone(), level: r.level, cage_faces: src.counts.len() };
            (r.mesh, Some((entry, r.cage_face)))
        }
        Err(e) => {
            warnings.push(format!("{p}: {e}; the {} cage renders unrefined", tags.scheme));
            (src, None)
        }
    }
}

/// Where a deforming mesh's points come from over the shutter (read once per mesh).
enum PointMotion {
    /// A skinned mesh: its authored points and face-vertex indices, posed per sample.
    Posed { rest: Vec<Vec3>, indices: Vec<i64> },
    /// USD's velocity-based motion from the `points` sample at `from` (None when the points do
    /// not match the velocities).
    Velocity { from: TimeCode, base: Option<Vec<Vec3>>, velocities: Vec<Vec3>, accelerations: Option<Vec<Vec3>> },
    /// Time-sampled `points`, read at each sample's time.
    Sampled,
}

impl Reader<'_> {
    pub(super) fn mesh(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        if let Some(shared) = prim.prim_in_prototype()?
            && self.native_instance(prim, p, visible, shared.path().as_str())?
        {
            return Ok(());
        }
        let cage = self.read_cage(prim, p)?;
        let subsets = self.material_subsets(prim, p, cage.src.counts.len())?;
        if subsets.is_empty() {
            if let Some(level) = self.refinement_to_defer(prim, p, &cage)? {
                return self.add_mesh_refined_later(prim, p, cage, level, visible);
            }
            let (mesh, _, _) = self.build_mesh(prim, p, cage)?;
            return self.add_mesh(prim, p, mesh, visible);
        }
        let (mesh, face_of, face_count) = self.build_mesh(prim, p, cage)?;
        // Faces in a bound GeomSubset render as a mesh of their own (named by the subset's
        // path) with the subset's material; the rest keep the mesh's.
        let mut claimed = vec![false; face_count];
        for (subset, faces) in &subsets {
            let set: std::collections::HashSet<u32> = faces.iter().copied().collect();
            for &f in faces {
                claimed[f as usize] = true;
            }
            let part = select_faces(&mesh, &face_of, |f| set.contains(&f));
            let material = self.usable_material(subset)?;
            self.add_mesh_with(prim, subset.path().as_str(), part, visible, material)?;
        }
        let rest = select_faces(&mesh, &face_of, |f| !claimed[f as usize]);
        if rest.indices.is_empty() {
            return Ok(());
        }
        self.add_mesh(prim, p, rest, visible)
    }

    /// Reads and triangulates a mesh prim: the mesh, the authored face of each triangle, and
    /// the number of authored faces.
    pub(super) fn read_mesh(&mut self, prim: &Prim, p: &str) -> Result<(render_core::geometry::Mesh, Vec<u32>, usize)> {
        let cage = self.read_cage(prim, p)?;
        self.build_mesh(prim, p, cage)
    }

    /// Reads a mesh prim's cage as authored (posed by its skeleton, if it has one).
    pub(super) fn read_cage(&mut self, prim: &Prim, p: &str) -> Result<CageRead> {
        let time = self.time;
        let req = |name: &str| -> Result<Value> { get(prim, name, time)?.with_context(|| format!("{p}: attribute '{name}' is missing")) };
        let points = req("points")?;
        let points = values::vec3_array(&points)
            .with_context(|| format!("{p}: attribute 'points' has type {}, expected point3f[]", values::type_of(&points)))?;
        if let Some((i, v)) = points.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            anyhow::bail!("{p}: attribute 'points': point {i} is {v} (NaN or Inf)");
        }
        let counts = req("faceVertexCounts")?;
        let counts = values::int_array(&counts).with_context(|| format!("{p}: attribute 'faceVertexCounts' is not an int array"))?;
        let indices = req("faceVertexIndices")?;
        let indices = values::int_array(&indices).with_context(|| format!("{p}: attribute 'faceVertexIndices' is not an int array"))?;
        let left_handed = get(prim, "orientation", time)?.as_ref().and_then(values::token).is_some_and(|t| t == "leftHanded");
        let tags = self.subdivision_tags(prim, p)?;
        let normals = self.normals(prim, p)?;
        // A skinned mesh's deformation samples pose the authored points again.
        let rest = self.skin_samples.contains_key(p).then(|| points.clone());
        let (points, normals) = self.skinned(p, points, normals, &indices);
        let uvs = self.uvs(prim, p)?;
        let primvars = self.primvars(prim, p)?;
        let src = MeshSource { points, counts, indices, normals, uvs, primvars, left_handed, smooth: tags.scheme != "none" };
        // Positions only (no normals, texture coordinates or primvars) for the deformation's
        // samples, when the points move within an open shutter.
        let shape_only = self.deforms(prim, p)?.then(|| MeshSource {
            points: src.points.clone(),
            counts: src.counts.clone(),
            indices: src.indices.clone(),
            normals: None,
            uvs: None,
            primvars: Vec::new(),
            ..src
        });
        Ok(CageRead { src, tags, shape_only, rest, warnings_at: self.out.warnings.len() })
    }

    /// `cage` refined (when its scheme subdivides) and triangulated: the mesh, the authored
    /// face of each triangle, and the number of authored faces.
    fn build_mesh(&mut self, prim: &Prim, p: &str, cage: CageRead) -> Result<(render_core::geometry::Mesh, Vec<u32>, usize)> {
        let CageRead { src, tags, shape_only, rest, .. } = cage;
        let face_count = src.counts.len();
        let mut warnings = Vec::new();
        let (mut src, cage_face) = self.subdivide(prim, p, src, &tags, &mut warnings)?;
        // A deforming mesh's motion samples are refined again and must keep the frame's vertices.
        if cage_face.is_some() && shape_only.is_none() {
            subdivision::share_normals(&mut src);
        }
        let (mut mesh, face_of) =
            triangulate_with_faces(&src, |w| warnings.push(format!("{p}: {w}"))).map_err(|e| anyhow::anyhow!("{p}: {e}"))?;
        if let Some(template) = shape_only {
            let posed = rest.map(|rest| (rest, template.indices.clone()));
            mesh.deformation = self.deformation(prim, p, template, &tags, posed, mesh.positions.len())?;
        }
        let face_of = match cage_face {
            Some(cage) => face_of.iter().map(|&f| cage[f as usize]).collect(),
            None => face_of,
        };
        self.out.warnings.extend(warnings);
        Ok((mesh, face_of, face_count))
    }

    /// True when the shutter is open and the mesh's `points` are time-sampled, or its skeleton
    /// animated: deformation blur.
    fn deforms(&self, prim: &Prim, p: &str) -> Result<bool> {
        if self.shutter.is_none() {
            return Ok(false);
        }
        if self.skins.contains_key(p) {
            return Ok(self.skin_samples.contains_key(p));
        }
        Ok(prim.attribute("points").num_time_samples()? > 1 || get(prim, "velocities", self.time)?.is_some())
    }

    /// How the mesh's points move, read once for all the motion samples: its skeleton's poses
    /// applied to the authored points (`posed`: them and the face-vertex indices); else, with
    /// `velocities` authored, USD's velocity-based motion from the points sample at the frame
    /// ([`Reader::velocity_base`]); else `points` read at each time.
    fn point_motion(&self, prim: &Prim, posed: Option<(Vec<Vec3>, Vec<i64>)>) -> Result<PointMotion> {
        if let Some((rest, indices)) = posed {
            return Ok(PointMotion::Posed { rest, indices });
        }
        let read = |name: &str, t: TimeCode| -> Result<Option<Vec<Vec3>>> { Ok(get(prim, name, t)?.as_ref().and_then(values::vec3_array)) };
        let from = self.velocity_base(prim, "points")?;
        let Some(velocities) = read("velocities", from)? else { return Ok(PointMotion::Sampled) };
        let base = read("points", from)?.filter(|b| b.len() == velocities.len());
        let accelerations = read("accelerations", from)?.filter(|a| base.as_ref().is_some_and(|b| a.len() == b.len()));
        Ok(PointMotion::Velocity { from, base, velocities, accelerations })
    }

    /// The mesh's points at motion sample `s` (time `t`) as `motion` moves them: posed by the
    /// sample's skin; moved by velocity × elapsed seconds plus half the `accelerations` × its
    /// square; or read at `t`. None where they cannot be.
    fn points_at(&self, prim: &Prim, p: &str, s: usize, t: TimeCode, motion: &PointMotion) -> Result<Option<Vec<Vec3>>> {
        match motion {
            PointMotion::Posed { rest, indices } => {
                let (Some(samples), Some(frame)) = (self.skin_samples.get(p), self.skins.get(p)) else { return Ok(None) };
                Ok(samples[s].points_in(frame, rest, indices))
            }
            PointMotion::Sampled => Ok(get(prim, "points", t)?.as_ref().and_then(values::vec3_array)),
            PointMotion::Velocity { base: None, .. } => Ok(None),
            PointMotion::Velocity { from, base: Some(base), velocities, accelerations } => {
                let dt = self.seconds_between(*from, t) as f32;
                Ok(Some(super::motion::extrapolate(base, velocities, accelerations.as_deref(), dt)))
            }
        }
    }

    /// The mesh's positions at each motion sample over the shutter, refined and triangulated
    /// as the frame's were (`template`: the frame's points and topology; `posed`: a skinned
    /// mesh's authored points and face-vertex indices), one set after another; empty when
    /// they do not change, or (with a warning) when a sample's points cannot take the frame's
    /// topology.
    fn deformation(
        &mut self,
        prim: &Prim,
        p: &str,
        template: MeshSource,
        tags: &SubdivTags,
        posed: Option<(Vec<Vec3>, Vec<i64>)>,
        vertices: usize,
    ) -> Result<Vec<Vec3>> {
        let times = self.shutter_times();
        if vertices == 0 {
            return Ok(Vec::new()); // nothing to move (and no whole sets to compare below)
        }
        let motion = self.point_motion(prim, posed)?;
        let mut out = Vec::with_capacity(times.len() * vertices);
        for (s, t) in times.into_iter().enumerate() {
            let points = self.points_at(prim, p, s, t, &motion)?.filter(|q| q.iter().all(|v| v.is_finite()));
            let Some(points) = points.filter(|q| q.len() == template.points.len()) else {
                return self.no_deformation(p, "changes its number of points, is not finite, or does not match its 'velocities'");
            };
            let sample = MeshSource { points, ..template.clone() };
            // The sample's refinement is the frame's, already recorded.
            let (recorded, mut ignored) = (self.out.subdivided.len(), Vec::new());
            let (sample, _) = self.subdivide(prim, p, sample, tags, &mut ignored)?;
            self.out.subdivided.truncate(recorded);
            let positions = triangulate_with_faces(&sample, |_| {}).map(|(m, _)| m.positions).unwrap_or_default();
            if positions.len() != vertices {
                return self.no_deformation(p, "changes its number of points");
            }
            out.extend(positions);
        }
        let still = out.chunks_exact(vertices).all(|set| set == &out[..vertices]);
        Ok(if still { Vec::new() } else { out })
    }

    /// Said once for a mesh whose points cannot blur: it keeps the frame's shape.
    fn no_deformation(&mut self, p: &str, why: &str) -> Result<Vec<Vec3>> {
        self.out.warnings.push(format!("{p}: attribute 'points' {why} within the shutter; the mesh renders without deformation blur"));
        Ok(Vec::new())
    }

    /// The mesh's points and normals posed by its skeleton, when it has one. Influences that
    /// do not fit its points leave it in its rest pose, with a warning.
    fn skinned(
        &mut self,
        p: &str,
        points: Vec<Vec3>,
        normals: skinning::AuthoredNormals,
        indices: &[i64],
    ) -> (Vec<Vec3>, skinning::AuthoredNormals) {
        let Some(skin) = self.skins.get(p) else { return (points, normals) };
        match skin.deform(&points, normals.as_ref(), indices) {
            Ok(posed) => posed,
            Err(e) => {
                self.skins.remove(p);
                self.out.skinned.retain(|s| s.path != p);
                self.out.warnings.push(format!("{p}: {e}; the mesh renders in its rest pose"));
                (points, normals)
            }
        }
    }

    /// `src` refined at the mesh's level when its scheme subdivides (with the cage face of each
    /// refined face), else `src` as it is. A cage OpenSubdiv cannot take (bad crease data, a
    /// Loop mesh with quads) renders unrefined, with a warning naming the attribute.
    fn subdivide(
        &mut self,
        prim: &Prim,
        p: &str,
        src: MeshSource,
        tags: &SubdivTags,
        warnings: &mut Vec<String>,
    ) -> Result<(MeshSource, Option<Vec<u32>>)> {
        let level = self.refinement_level(prim, p)?;
        if !tags.is_subdivided() || level == 0 {
            return Ok((src, None));
        }
        let (mesh, refined) = refine_cage(p, src, tags, level, warnings);
        Ok((
            mesh,
            refined.map(|(entry, cage_face)| {
                self.out.subdivided.push(entry);
                cage_face
            }),
        ))
    }

    /// The refinement level: the mesh's own (`primvars:tessera:refinementLevel`, else
    /// `primvars:refinementLevel`, else Arnold's `primvars:arnold:subdiv_iterations`), else the
    /// render's.
    pub(super) fn refinement_level(&self, prim: &Prim, p: &str) -> Result<u32> {
        for name in ["primvars:tessera:refinementLevel", "primvars:refinementLevel", "primvars:arnold:subdiv_iterations"] {
            if let Some(v) = get(prim, name, self.time)? {
                let level = values::scalar(&v).with_context(|| format!("{p}: attribute '{name}' is not a number"))?;
                anyhow::ensure!(level.is_finite() && level >= 0.0, "{p}: attribute '{name}' is {level}, not a level 0 or more");
                return Ok((level as u32).min(subdivision::MAX_LEVEL));
            }
        }
        Ok(self.subdivision_level)
    }

    /// `subdivisionScheme` and the tags that go with it, with USD's fallbacks.
    fn subdivision_tags(&self, prim: &Prim, p: &str) -> Result<SubdivTags> {
        let time = self.time;
        let token = |name: &str, fallback: &str| -> Result<String> {
            Ok(get(prim, name, time)?.as_ref().and_then(values::token).unwrap_or_else(|| fallback.to_string()))
        };
        let ints = |name: &str| Ok::<_, anyhow::Error>(get_ints(prim, p, name, time)?.unwrap_or_default());
        let floats = |name: &str| Ok::<_, anyhow::Error>(get_floats(prim, p, name, time)?.unwrap_or_default());
        let tags = SubdivTags {
            scheme: token("subdivisionScheme", "catmullClark")?,
            interpolate_boundary: token("interpolateBoundary", "edgeAndCorner")?,
            triangle_subdivision_rule: token("triangleSubdivisionRule", "catmullClark")?,
            crease_indices: ints("creaseIndices")?,
            crease_lengths: ints("creaseLengths")?,
            crease_sharpnesses: floats("creaseSharpnesses")?,
            corner_indices: ints("cornerIndices")?,
            corner_sharpnesses: floats("cornerSharpnesses")?,
            hole_indices: ints("holeIndices")?,
        };
        if tags.scheme != "none" && !tags.is_subdivided() {
            anyhow::bail!("{p}: attribute 'subdivisionScheme' is '{}', not none, catmullClark, loop or bilinear", tags.scheme);
        }
        Ok(tags)
    }

    /// The mesh's `materialBind` GeomSubsets of faces that carry a material binding, with
    /// their face indices (validated against `face_count`).
    pub(super) fn material_subsets(&self, prim: &Prim, p: &str, face_count: usize) -> Result<Vec<(Prim, Vec<u32>)>> {
        let time = self.time;
        let mut out = Vec::new();
        for child in prim.children()? {
            if child.type_name()?.is_none_or(|t| t.as_str() != "GeomSubset") {
                continue;
            }
            let c = child.path().as_str().to_string();
            let family = get(&child, "familyName", time)?.as_ref().and_then(values::token).unwrap_or_default();
            let element = get(&child, "elementType", time)?.as_ref().and_then(values::token).unwrap_or_else(|| "face".into());
            if family != "materialBind" || element != "face" {
                continue;
            }
            let indices = get_ints(&child, &c, "indices", time)?.unwrap_or_default();
            if let Some((i, &f)) = indices.iter().enumerate().find(|(_, f)| **f < 0 || **f as usize >= face_count) {
                anyhow::bail!("{c}: attribute 'indices': entry {i} is face {f}, but {p} has {face_count} faces");
            }
            if MaterialBindingAPI::get(self.stage, child.path().clone())?.is_none() {
                continue; // an unbound subset keeps the mesh's material
            }
            out.push((child, indices.into_iter().map(|f| f as u32).collect()));
        }
        Ok(out)
    }

    /// Places a triangulated gprim: its world transform and its material (the bound one,
    /// else a preview surface of its `displayColor`, else the renderer's fallback).
    pub(super) fn add_mesh(&mut self, prim: &Prim, p: &str, mesh: render_core::geometry::Mesh, visible: bool) -> Result<()> {
        let material = self.usable_material(prim)?;
        self.add_mesh_with(prim, p, mesh, visible, material)
    }

    /// The material bound to `prim`, read; `None` when there is none or it cannot be mapped
    /// (the gprim then shows its displayColor).
    pub(super) fn usable_material(&mut self, prim: &Prim) -> Result<Option<String>> {
        let Some(m) = self.bound_material(prim)? else { return Ok(None) };
        self.material(&m)?;
        Ok((!self.unmappable.contains(&m)).then_some(m))
    }

    /// As [`Self::add_mesh`], with the material already resolved (`None`: the gprim's
    /// displayColor, else the fallback).
    pub(super) fn add_mesh_with(
        &mut self,
        prim: &Prim,
        p: &str,
        mesh: render_core::geometry::Mesh,
        visible: bool,
        material: Option<String>,
    ) -> Result<()> {
        let transform = self.affine(prim, p)?;
        if visible && render_core::geometry::Transform::new(transform).is_none() {
            anyhow::bail!("{p}: xformOps compose to a singular transform (a zero scale?), which places the mesh nowhere");
        }
        // A skinned mesh is placed by its skeleton at the frame (deformation blur: not yet).
        let motion = if visible && !self.skins.contains_key(prim.path().as_str()) { self.motion(prim, p)? } else { Vec::new() };
        let material = match material {
            Some(m) => m,
            None => self.display_color_material(prim, p)?.unwrap_or_default(),
        };
        let link_collections = self.link_collections(prim.path());
        let light = self.gprim_light(prim, p)?;
        self.out
            .meshes
            .push((p.to_string(), MeshDesc { mesh: Arc::new(mesh), transform, motion, material, visible, link_collections, light }));
        Ok(())
    }

    /// UsdGeom: an unbound gprim shows its `primvars:displayColor` (or the older
    /// `displayColor`). Per-vertex colours are averaged into one, with a warning, until
    /// primvars reach the shading system.
    pub(super) fn display_color_material(&mut self, prim: &Prim, p: &str) -> Result<Option<String>> {
        let time = self.time;
        let Some(v) = get(prim, "primvars:displayColor", time)?.or(get(prim, "displayColor", time)?) else {
            return Ok(None);
        };
        let colors = values::vec3_array(&v).or_else(|| values::vec3(&v).map(|c| vec![c])).unwrap_or_default();
        if colors.is_empty() || colors.iter().any(|c| !c.is_finite()) {
            self.out.warnings.push(format!("{p}: primvars:displayColor is empty or not finite and is ignored"));
            return Ok(None);
        }
        if colors.len() > 1 {
            self.out.warnings.push(format!("{p}: primvars:displayColor varies over the surface; its average colour is used"));
        }
        let c = colors.iter().copied().sum::<Vec3>() / colors.len() as f32;
        let path = format!("/__displayColor/c{:08x}{:08x}{:08x}", c.x.to_bits(), c.y.to_bits(), c.z.to_bits());
        if !self.materials_seen.contains_key(&path) {
            self.materials_seen.insert(path.clone(), ());
            let shader = format!("{path}/PreviewSurface");
            let mut node = MaterialNode { path: shader.clone(), node_type_id: "UsdPreviewSurface".into(), ..Default::default() };
            node.parameters.insert("diffuseColor".into(), ParamValue::Float3(c.clamp(Vec3::ZERO, Vec3::ONE)));
            self.out.materials.push((path.clone(), MaterialNetwork { nodes: vec![node], connections: Vec::new(), surface_node: shader }));
        }
        Ok(Some(path))
    }

    /// An implicit prim, tessellated with the schema's defaults for unauthored sizes.
    pub(super) fn implicit(&mut self, prim: &Prim, p: &str, type_name: &str, visible: bool) -> Result<()> {
        let time = self.time;
        let size = |name: &str, default: f64| -> Result<f32> {
            let v = get(prim, name, time)?.as_ref().and_then(values::scalar).unwrap_or(default);
            if !(v.is_finite() && v > 0.0) {
                anyhow::bail!("{p}: attribute '{name}' is {v}; it must be finite and positive");
            }
            Ok(v as f32)
        };
        let axis = match get(prim, "axis", time)?.as_ref().and_then(values::token) {
            None => shapes::Axis::Z,
            Some(t) => shapes::Axis::parse(&t).with_context(|| format!("{p}: attribute 'axis' is '{t}', expected X, Y or Z"))?,
        };
        // Cylinder_1's radii may be 0 (a cone), not both.
        let ends = |default: f64| -> Result<(f32, f32)> {
            let end = |name: &str| -> Result<f32> {
                let v = get(prim, name, time)?.as_ref().and_then(values::scalar).unwrap_or(default);
                if !(v.is_finite() && v >= 0.0) {
                    anyhow::bail!("{p}: attribute '{name}' is {v}; it must be finite and not negative");
                }
                Ok(v as f32)
            };
            let (bottom, top) = (end("radiusBottom")?, end("radiusTop")?);
            if bottom == 0.0 && top == 0.0 {
                anyhow::bail!("{p}: attributes 'radiusBottom' and 'radiusTop' are both 0");
            }
            Ok((bottom, top))
        };
        // The legacy prims' one `radius`, or the `_1` prims' two ends.
        let radii = |legacy: bool, default: f64| -> Result<(f32, f32)> {
            if legacy {
                let radius = size("radius", default)?;
                Ok((radius, radius))
            } else {
                ends(default)
            }
        };
        let shape = match type_name {
            "Sphere" => shapes::Shape::Sphere { radius: size("radius", 1.0)? },
            "Cube" => shapes::Shape::Cube { size: size("size", 2.0)? },
            "Cylinder" | "Cylinder_1" => {
                let (bottom, top) = radii(type_name == "Cylinder", 1.0)?;
                shapes::Shape::Cylinder { bottom, top, height: size("height", 2.0)?, axis }
            }
            "Cone" => shapes::Shape::Cone { radius: size("radius", 1.0)?, height: size("height", 2.0)?, axis },
            "Capsule" | "Capsule_1" => {
                let (bottom, top) = radii(type_name == "Capsule", 0.5)?;
                shapes::Shape::Capsule { bottom, top, height: size("height", 1.0)?, axis }
            }
            _ => shapes::Shape::Plane { width: size("width", 2.0)?, length: size("length", 2.0)?, axis },
        };
        self.add_mesh(prim, p, shapes::tessellate(shape), visible)
    }

    /// The float, float3 and int primvars the mesh's materials read through
    /// `UsdPrimvarReader_float`, `_float3` and `_int`, de-indexed, with their interpolations.
    /// A primvar the mesh lacks is left out (the readers' fallbacks apply, as USD says); one of
    /// a type no reader can read is a warning.
    pub(super) fn primvars(&mut self, prim: &Prim, p: &str) -> Result<Vec<(String, Vec<Vec3>, String)>> {
        let names = self.reader_varnames(prim, &["UsdPrimvarReader_float", "UsdPrimvarReader_float3", "UsdPrimvarReader_int"])?;
        let mut out = Vec::new();
        for name in names {
            let attr_name = format!("primvars:{name}");
            let Some(v) = get(prim, &attr_name, self.time)? else { continue };
            let values: Option<Vec<Vec3>> = values::vec3_array(&v)
                .or_else(|| values::float_array(&v).map(|a| a.into_iter().map(|x| Vec3::new(x, 0.0, 0.0)).collect()))
                .or_else(|| values::vec3(&v).map(|x| vec![x]))
                .or_else(|| values::scalar(&v).map(|x| vec![Vec3::new(x as f32, 0.0, 0.0)]));
            let Some(values) = values else {
                self.out.warnings.push(format!(
                    "{p}: {attr_name} has type {}, which no primvar reader reads; readers use their fallbacks",
                    values::type_of(&v)
                ));
                continue;
            };
            let (values, interp) = self.flatten_primvar(prim, p, &attr_name, values)?;
            out.push((name, values, interp));
        }
        Ok(out)
    }

    /// `data` of the primvar `attr_name` de-indexed by its `:indices` (an index out of range
    /// is an error naming the entry), with its interpolation (USD's fallback: constant).
    pub(super) fn flatten_primvar<T: Copy>(&self, prim: &Prim, p: &str, attr_name: &str, data: Vec<T>) -> Result<(Vec<T>, String)> {
        let data = match get(prim, &format!("{attr_name}:indices"), self.time)?.as_ref().and_then(values::int_array) {
            Some(idx) => {
                if let Some((i, k)) = idx.iter().enumerate().find(|(_, k)| **k < 0 || **k as usize >= data.len()) {
                    anyhow::bail!("{p}: attribute '{attr_name}:indices': entry {i} is {k}, but {attr_name} has {} values", data.len());
                }
                idx.iter().map(|&k| data[k as usize]).collect()
            }
            None => data,
        };
        let interp = prim
            .attribute(attr_name)
            .get_metadata::<openusd::tf::Token>("interpolation")
            .ok()
            .flatten()
            .map(|t| t.as_str().to_string())
            .unwrap_or_else(|| "constant".to_string());
        Ok((data, interp))
    }

    /// The float2 primvar the mesh's materials read through `UsdPrimvarReader_float2`
    /// (`st` when none names one), de-indexed, with its interpolation.
    pub(super) fn uvs(&mut self, prim: &Prim, p: &str) -> Result<Option<(String, Vec<glam::Vec2>, String)>> {
        let time = self.time;
        let names = self.reader_varnames(prim, &["UsdPrimvarReader_float2"])?;
        if names.len() > 1 {
            self.out.warnings.push(format!(
                "{p}: its materials read several texture coordinate sets ({}); only '{}' is sent",
                names.join(", "),
                names[0]
            ));
        }
        let name = names.into_iter().next().unwrap_or_else(|| "st".to_string());
        let attr_name = format!("primvars:{name}");
        let Some(v) = get(prim, &attr_name, time)? else { return Ok(None) };
        let Some(st) = values::vec2_array(&v) else {
            self.out.warnings.push(format!("{p}: {attr_name} has type {}, not texCoord2f[]; no texture coordinates", values::type_of(&v)));
            return Ok(None);
        };
        let (st, interp) = self.flatten_primvar(prim, p, &attr_name, st)?;
        Ok(Some((attr_name, st, interp)))
    }

    pub(super) fn normals(&self, prim: &Prim, p: &str) -> Result<Option<(Vec<Vec3>, String)>> {
        let time = self.time;
        let interp = |name: &str, default: &str| -> String {
            prim.attribute(name)
                .get_metadata::<openusd::tf::Token>("interpolation")
                .ok()
                .flatten()
                .map(|t| t.as_str().to_string())
                .unwrap_or_else(|| default.to_string())
        };
        if let Some(v) = get(prim, "primvars:normals", time)? {
            let n = values::vec3_array(&v).with_context(|| format!("{p}: primvars:normals is not a normal3f[]"))?;
            let n = match get(prim, "primvars:normals:indices", time)?.as_ref().and_then(values::int_array) {
                Some(idx) => idx.iter().map(|&i| n.get(i as usize).copied().unwrap_or(Vec3::ZERO)).collect(),
                None => n,
            };
            return Ok(Some((n, interp("primvars:normals", "constant"))));
        }
        match get(prim, "normals", time)? {
            Some(v) => Ok(Some((
                values::vec3_array(&v).with_context(|| format!("{p}: normals is not a normal3f[]"))?,
                interp("normals", "vertex"),
            ))),
            None => Ok(None),
        }
    }
}
