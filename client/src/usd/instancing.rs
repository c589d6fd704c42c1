//! Instancing: native instanceable prims (one mesh per prototype and material) and PointInstancers.

use anyhow::{Context, Result};

use super::*;

impl Reader<'_> {
    /// A mesh inside an instanceable prim (an instance proxy standing for `shared`, a mesh
    /// in the stage's prototype): its geometry is read once per prototype and bound material
    /// and every proxy becomes one more instance of it, so a forest of referenced instanceable
    /// trees costs one BLAS. Proxies with GeomSubsets or without a bound material take the
    /// flat path (returns false).
    pub(super) fn native_instance(&mut self, prim: &Prim, p: &str, visible: bool, shared: &str) -> Result<bool> {
        for child in prim.children()? {
            if child.type_name()?.is_some_and(|t| t.as_str() == "GeomSubset") {
                return Ok(false);
            }
        }
        let Some(material) = self.bound_material(prim)? else { return Ok(false) };
        // A material inside the instance is one material for every instance: name it by its
        // prim in the prototype.
        let in_prototype = self.stage.prim(sdf::path(&material)?).prim_in_prototype()?;
        let shared_material = in_prototype.map_or_else(|| material.clone(), |m| m.path().as_str().to_string());
        self.material(&shared_material)?;
        if self.unmappable.contains(&shared_material) {
            return Ok(false);
        }
        // Instances in different light-link collections share the mesh, not the instancer.
        let link_collections = self.link_collections(prim.path());
        let key = (shared.to_string(), shared_material.clone(), link_collections.clone());
        let index = match self.native.get(&key) {
            Some(&i) => i,
            None => {
                let same_mesh = self.native.iter().find(|((s, m, _), _)| s == shared && *m == shared_material);
                let mesh_path = match same_mesh.map(|(_, &i)| self.out.instancers[i].1.prototype.clone()) {
                    Some(mesh_path) => mesh_path,
                    None => self.native_prototype_mesh(prim, p, shared, &shared_material)?,
                };
                let links = if link_collections.is_empty() { String::new() } else { format!("[{}]", link_collections.join(",")) };
                self.out.instancers.push((
                    format!("{mesh_path}[instances]{links}"),
                    InstancerDesc { prototype: mesh_path, transforms: Vec::new(), motion: Vec::new(), link_collections },
                ));
                self.native.insert(key.clone(), self.out.instancers.len() - 1);
                self.out.instancers.len() - 1
            }
        };
        let world = self.affine(prim, p)?;
        let prototype = &self.out.instancers[index].1.prototype;
        let triangles = self.out.meshes.iter().find(|(path, _)| path == prototype).map_or(0, |(_, m)| m.mesh.indices.len());
        let motion = if visible { self.motion(prim, p)? } else { Vec::new() };
        if visible {
            add_instance(&mut self.out.instancers[index].1, world, motion.clone());
        }
        self.out.native_instances.push(NativeInstance {
            path: p.to_string(),
            instancer: index,
            world,
            material,
            triangles,
            visible,
            motion,
        });
        Ok(true)
    }

    /// The hidden mesh the instances of prototype mesh `shared` with material `material` share,
    /// read from the instance proxy `prim` at `p`; returns its path.
    fn native_prototype_mesh(&mut self, prim: &Prim, p: &str, shared: &str, material: &str) -> Result<String> {
        let (mesh, _, _) = self.read_mesh(prim, p)?;
        let same_prototype =
            self.native.keys().filter(|(s, _, _)| s == shared).map(|(_, m, _)| m).collect::<std::collections::HashSet<_>>().len();
        let mesh_path = if same_prototype == 0 { shared.to_string() } else { format!("{shared}[{same_prototype}]") };
        // Refined once, for every instance: named by the prototype mesh it became.
        if let Some(s) = self.out.subdivided.last_mut().filter(|s| s.path == p) {
            s.path = mesh_path.clone();
        }
        let desc = MeshDesc {
            mesh: Arc::new(mesh),
            transform: Affine3A::IDENTITY,
            motion: Vec::new(),
            material: material.to_string(),
            visible: false,
            link_collections: Vec::new(),
            light: None,
        };
        self.out.meshes.push((mesh_path.clone(), desc));
        Ok(mesh_path)
    }

    /// A `PointInstancer`: each mesh (or implicit prim) of each prototype becomes one
    /// instancer of a shared BLAS, placed by the instancer's world transform, the instance's
    /// translate-orient-scale (UsdGeomPointInstancer's order) and the mesh's transform
    /// relative to its prototype root's parent (the prototype's own xform included, as
    /// USD's default `IncludeProtoXform` does).
    pub(super) fn point_instancer(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let _span = tracing::debug_span!("point_instancer", path = p).entered();
        self.instancer_roots.push(p.to_string());
        let prototypes = valid_targets(prim, p, "prototypes")?;
        let world = self.world_transform(prim.path())?;
        let per_proto = self.instance_transforms(prim, p, prototypes.len(), self.time, world)?;
        let motion = if visible { self.instance_motion(prim, p, &per_proto)? } else { Vec::new() };
        for (k, (proto, instances)) in prototypes.iter().zip(&per_proto).enumerate() {
            self.instance_prototype(p, proto, instances, motion.get(k).map(Vec::as_slice), visible, 0)?;
        }
        Ok(())
    }

    /// A PointInstancer inside another's prototype (`nested`, below the prototype root whose
    /// parent's frame `root_parent` inverts): each of the outer `instances` places every
    /// instance of the nested one, as Hydra draws nested instancers. Still only: the nested
    /// instances do not blur with the outer ones' motion (warned).
    fn nested_instancer(
        &mut self,
        nested: &sdf::Path,
        root_parent: DMat4,
        instances: &[DMat4],
        moving: bool,
        visible: bool,
        depth: usize,
    ) -> Result<()> {
        let n = nested.as_str();
        if depth >= MAX_NESTED_INSTANCERS {
            anyhow::bail!("{n}: PointInstancers nest more than {MAX_NESTED_INSTANCERS} deep (a prototype that holds its own instancer?)");
        }
        if moving {
            self.out
                .warnings
                .push(format!("{n}: a PointInstancer inside another's prototype renders without the outer instances' motion blur"));
        }
        let prim = self.stage.prim(nested.clone());
        let prototypes = valid_targets(&prim, n, "prototypes")?;
        let inner = root_parent * self.world_transform(nested)?;
        let per_proto = self.instance_transforms(&prim, n, prototypes.len(), self.time, inner)?;
        for (proto, placements) in prototypes.iter().zip(&per_proto) {
            let total = instances.len().saturating_mul(placements.len());
            if total as u64 > MAX_NESTED_PRODUCT {
                anyhow::bail!(
                    "{n}: {} outer instances times {} nested ones is more than {MAX_NESTED_PRODUCT}",
                    instances.len(),
                    placements.len()
                );
            }
            let combined: Vec<DMat4> = instances.iter().flat_map(|outer| placements.iter().map(move |m| *outer * *m)).collect();
            self.instance_prototype(n, proto, &combined, None, visible, depth + 1)?;
        }
        Ok(())
    }

    /// Each instance's world transforms at the motion samples over an open shutter, by
    /// prototype (as `per_proto`, the frame's); empty when the shutter is closed or nothing
    /// moves. Instances that come and go within the shutter (a changing count) keep still,
    /// with a warning.
    fn instance_motion(&mut self, prim: &Prim, p: &str, per_proto: &[Vec<DMat4>]) -> Result<Vec<Vec<Vec<DMat4>>>> {
        let times = self.shutter_times();
        if times.is_empty() {
            return Ok(Vec::new());
        }
        if let Some(w) = get(prim, "angularVelocities", self.time)? {
            let (turns, count) =
                (values::vec3_array(&w).map_or(0, |w| w.len()), get_ints(prim, p, "protoIndices", self.time)?.map_or(0, |i| i.len()));
            if turns != count {
                self.out.warnings.push(format!(
                    "{p}: attribute 'angularVelocities' has {turns} entries for {count} instances and is ignored; the instances turn only as their orientations are sampled"
                ));
            }
        }
        let mut motion: Vec<Vec<Vec<DMat4>>> = per_proto.iter().map(|v| vec![Vec::with_capacity(times.len()); v.len()]).collect();
        for t in times {
            let world = self.world_at(prim.path(), t)?;
            let at_t = self.instance_transforms(prim, p, per_proto.len(), t, world)?;
            if at_t.iter().zip(per_proto).any(|(a, b)| a.len() != b.len()) {
                self.out
                    .warnings
                    .push(format!("{p}: the instance count changes within the shutter; the instances render without motion blur"));
                return Ok(Vec::new());
            }
            for (k, instances) in at_t.into_iter().enumerate() {
                for (j, m) in instances.into_iter().enumerate() {
                    motion[k][j].push(m);
                }
            }
        }
        let still = motion.iter().flatten().all(|samples| samples.iter().all(|m| *m == samples[0]));
        Ok(if still { Vec::new() } else { motion })
    }

    /// The world transform of each visible instance of a PointInstancer, by prototype index:
    /// positions, orientations and scales composed as UsdGeomPointInstancer defines them,
    /// instances hidden by `invisibleIds` left out.
    fn instance_transforms(
        &mut self,
        prim: &Prim,
        p: &str,
        prototypes: usize,
        time: TimeCode,
        instancer_world: DMat4,
    ) -> Result<Vec<Vec<DMat4>>> {
        let ints = |name: &str| get_ints(prim, p, name, time);
        let proto_indices = ints("protoIndices")?.with_context(|| format!("{p}: attribute 'protoIndices' is missing"))?;
        let n = proto_indices.len();
        let positions = self.instance_positions(prim, p, time)?;
        let orientations = self.instance_orientations(prim, p, time)?;
        let scales = match get(prim, "scales", time)? {
            Some(v) => Some(values::vec3_array(&v).with_context(|| format!("{p}: attribute 'scales' is not a float3[]"))?),
            None => None,
        };
        for (name, len) in [
            ("positions", Some(positions.len())),
            ("orientations", orientations.as_ref().map(Vec::len)),
            ("scales", scales.as_ref().map(Vec::len)),
        ] {
            if let Some(len) = len.filter(|&len| len != n) {
                anyhow::bail!("{p}: attribute '{name}' has {len} entries but protoIndices has {n}");
            }
        }
        if let Some((i, &k)) = proto_indices.iter().enumerate().find(|(_, k)| **k < 0 || **k as usize >= prototypes) {
            anyhow::bail!("{p}: attribute 'protoIndices': entry {i} is {k}, but there are {prototypes} prototypes");
        }
        // Instances hidden or deactivated by id (ids default to the instance index).
        let mut hidden: std::collections::HashSet<i64> = ints("invisibleIds")?.unwrap_or_default().into_iter().collect();
        hidden.extend(self.inactive_ids(prim));
        let ids = ints("ids")?;
        let mut per_proto: Vec<Vec<DMat4>> = vec![Vec::new(); prototypes];
        for i in 0..n {
            let id = ids.as_ref().and_then(|ids| ids.get(i).copied()).unwrap_or(i as i64);
            if hidden.contains(&id) {
                continue;
            }
            let t = positions[i].as_dvec3();
            let r = orientations.as_ref().map_or(glam::DMat3::IDENTITY, |o| o[i]);
            let s = scales.as_ref().map_or(glam::DVec3::ONE, |s| s[i].as_dvec3());
            if !(t.is_finite() && r.is_finite() && s.is_finite()) {
                anyhow::bail!("{p}: instance {i} has a non-finite position, orientation or scale");
            }
            let trs = DMat4::from_translation(t) * DMat4::from_mat3(r) * DMat4::from_scale(s);
            per_proto[proto_indices[i] as usize].push(instancer_world * trs);
        }
        Ok(per_proto)
    }

    /// The instancer's `inactiveIds` (an int64 list-op metadatum, not time-varying), composed
    /// over its prim stack from the weakest opinion up.
    fn inactive_ids(&self, prim: &Prim) -> Vec<i64> {
        let mut ids = Vec::new();
        for (_, value) in self.opinions(prim, "inactiveIds").into_iter().rev() {
            if let Value::Int64ListOp(op) = value {
                ids = op.compose_over(&ids);
            }
        }
        ids
    }

    /// `positions` at `time`. With `velocities` authored (one per position), USD's
    /// velocity-based motion: the positions sample at the frame moved by velocity × elapsed seconds
    /// (`timeCodesPerSecond`, 24 unless authored), rather than positions interpolated
    /// between samples.
    fn instance_positions(&self, prim: &Prim, p: &str, time: TimeCode) -> Result<Vec<Vec3>> {
        let read = |name: &str, t: TimeCode| -> Result<Option<Vec<Vec3>>> {
            get(prim, name, t)?
                .map(|v| values::vec3_array(&v).with_context(|| format!("{p}: attribute '{name}' is not a vector3f[]")))
                .transpose()
        };
        if time == self.time {
            return read("positions", time)?.with_context(|| format!("{p}: attribute 'positions' is missing"));
        }
        let from = self.velocity_base(prim, "positions")?;
        let base = read("positions", from)?.with_context(|| format!("{p}: attribute 'positions' is missing"))?;
        match read("velocities", from)?.filter(|v| v.len() == base.len()) {
            Some(velocities) => Ok(super::motion::extrapolate(&base, &velocities, None, self.seconds_between(from, time) as f32)),
            None => read("positions", time)?.with_context(|| format!("{p}: attribute 'positions' is missing")),
        }
    }

    /// Each instance's rotation at `time`, None without `orientations`. With
    /// `angularVelocities` authored (degrees per second, one per instance), the frame's
    /// orientation followed by a turn about the angular velocity's axis for the elapsed time,
    /// as UsdGeomPointInstancer composes them (rotation, then the turn, in the instancer's
    /// frame); USD ignores angular velocities where there are no orientations, and so do we.
    fn instance_orientations(&self, prim: &Prim, p: &str, time: TimeCode) -> Result<Option<Vec<glam::DMat3>>> {
        let read = |t: TimeCode| -> Result<Option<Vec<glam::DQuat>>> {
            match get(prim, "orientations", t)?.or(get(prim, "orientationsf", t)?) {
                Some(v) => Ok(Some(values::quat_array(&v).with_context(|| format!("{p}: attribute 'orientations' is not a quath[]"))?)),
                None => Ok(None),
            }
        };
        let rotations = |q: Vec<glam::DQuat>| q.into_iter().map(usd_rotation).collect::<Vec<_>>();
        if time == self.time {
            return Ok(read(time)?.map(rotations));
        }
        let from = self.velocity_base(prim, "orientations")?;
        let Some(base) = read(from)? else { return Ok(None) };
        let turns = get(prim, "angularVelocities", from)?.as_ref().and_then(values::vec3_array).filter(|w| w.len() == base.len());
        let Some(turns) = turns else { return Ok(read(time)?.map(rotations)) };
        let dt = self.seconds_between(from, time);
        let turned = base.into_iter().zip(turns).map(|(q, w)| {
            let w = w.as_dvec3();
            let turn = if w.length() > 0.0 {
                glam::DMat3::from_axis_angle(w.normalize(), (w.length() * dt).to_radians())
            } else {
                glam::DMat3::IDENTITY
            };
            turn * usd_rotation(q)
        });
        Ok(Some(turned.collect()))
    }

    /// Where USD's velocity-based motion extrapolates `attr` from at the frame: its time sample
    /// at or before the frame (the first, before any; the frame itself without samples), as
    /// usd-core's ComputePointsAtTime and ComputeInstanceTransformsAtTime take it.
    pub(super) fn velocity_base(&self, prim: &Prim, attr: &str) -> Result<TimeCode> {
        Ok(match prim.attribute(attr).bracketing_time_samples(self.time)? {
            Some((lo, _)) => TimeCode::new(lo),
            None => self.time,
        })
    }

    /// Seconds from `from` to `to` (`timeCodesPerSecond`, 24 unless authored): the clock of
    /// USD's velocity-based motion.
    pub(super) fn seconds_between(&self, from: TimeCode, to: TimeCode) -> f64 {
        let per_second = self
            .stage
            .stage_metadata("timeCodesPerSecond")
            .ok()
            .flatten()
            .as_ref()
            .and_then(values::scalar)
            .filter(|t| *t > 0.0)
            .unwrap_or(24.0);
        (to.value() - from.value()) / per_second
    }

    /// The meshes of one PointInstancer prototype (the subtree at `proto`), each as a hidden
    /// prototype mesh and an instancer placing it at `instances` (none when the instancer is
    /// invisible).
    fn instance_prototype(
        &mut self,
        p: &str,
        proto: &sdf::Path,
        instances: &[DMat4],
        motion: Option<&[Vec<DMat4>]>,
        visible: bool,
        depth: usize,
    ) -> Result<()> {
        let root = proto.as_str().to_string();
        // The instances belong to the instancer's link collections, and to each prototype
        // mesh's own.
        let instancer_links = self.link_collections(&sdf::path(p)?);
        let root_parent = match proto.parent() {
            Some(pp) if pp.as_str() != "/" && !pp.as_str().is_empty() => self.world_transform(&pp)?.inverse(),
            _ => DMat4::IDENTITY,
        };
        let members: Vec<sdf::Path> = self.all_paths.iter().filter(|q| under(q.as_str(), &root)).cloned().collect();
        if members.is_empty() {
            anyhow::bail!("{p}: relationship 'prototypes' targets {root}, which is not a prim on the stage");
        }
        let mut nested: Vec<String> = Vec::new();
        for member in members {
            if nested.iter().any(|n| under(member.as_str(), n)) {
                continue;
            }
            let mprim = self.stage.prim(member.clone());
            let type_name = mprim.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
            if type_name == "PointInstancer" {
                nested.push(member.as_str().to_string());
                if !self.invisible(&member)? {
                    self.nested_instancer(&member, root_parent, instances, motion.is_some_and(|m| !m.is_empty()), visible, depth)?;
                }
                continue;
            }
            if type_name != "Mesh" && !IMPLICIT.contains(&type_name.as_str()) {
                if !STRUCTURAL.contains(&type_name.as_str()) {
                    self.out
                        .warnings
                        .push(format!("{}: prim type '{type_name}' in a PointInstancer prototype is not rendered", member.as_str()));
                    self.out.skipped.push(member.as_str().to_string());
                }
                continue;
            }
            let view = AnyXformable(mprim.clone());
            if matches!(view.compute_purpose()?, Purpose::Proxy | Purpose::Guide) || self.invisible(&member)? {
                continue;
            }
            // The prototype mesh itself (one per bound GeomSubset too), never drawn directly.
            let before = self.out.meshes.len();
            if type_name == "Mesh" {
                self.mesh(&mprim, member.as_str(), false)?;
            } else {
                self.implicit(&mprim, member.as_str(), &type_name, false)?;
            }
            let relative = root_parent * self.world_transform(&member)?;
            let transforms = match visible {
                true => instances
                    .iter()
                    .map(|m| to_affine(&(*m * relative)))
                    .collect::<Result<Vec<_>>>()
                    .with_context(|| format!("{p}: instances of {root}"))?,
                false => Vec::new(),
            };
            let motion = match (visible, motion) {
                (true, Some(m)) => m
                    .iter()
                    .flatten()
                    .map(|w| to_affine(&(*w * relative)))
                    .collect::<Result<Vec<_>>>()
                    .with_context(|| format!("{p}: motion of the instances of {root}"))?,
                _ => Vec::new(),
            };
            for (mesh_key, _) in &mut self.out.meshes[before..] {
                let part = mesh_key.clone();
                if !under(&part, p) {
                    *mesh_key = format!("{part}@{p}");
                }
                self.out.instancers.push((
                    format!("{p}[{part}]"),
                    InstancerDesc {
                        prototype: mesh_key.clone(),
                        transforms: transforms.clone(),
                        motion: motion.clone(),
                        link_collections: instancer_links.clone(),
                    },
                ));
            }
        }
        Ok(())
    }
}

/// How deep PointInstancers may nest in each other's prototypes.
const MAX_NESTED_INSTANCERS: usize = 8;

/// The most placements one nested prototype may expand to (the server's default instance limit).
const MAX_NESTED_PRODUCT: u64 = 10_000_000;

/// One more instance of a native instancer, at `world`, moving through `motion` (its world
/// transforms at the shutter's samples; empty when still). Once any instance moves, every
/// instance carries samples, the still ones their one placement repeated, as an instancer's
/// motion holds the same count per instance.
fn add_instance(instancer: &mut InstancerDesc, world: Affine3A, motion: Vec<Affine3A>) {
    let k = if motion.is_empty() { instancer.motion_samples() } else { motion.len() };
    if k > 0 && instancer.motion.is_empty() {
        instancer.motion = instancer.transforms.iter().flat_map(|&m| std::iter::repeat_n(m, k)).collect();
    }
    instancer.transforms.push(world);
    match (k, motion.is_empty()) {
        (0, _) => {}
        (_, true) => instancer.motion.extend(std::iter::repeat_n(world, k)),
        (_, false) => instancer.motion.extend(motion),
    }
}
