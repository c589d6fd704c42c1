//! UsdSkel: meshes bound to a Skeleton under a SkelRoot, posed at the frame being rendered.
//!
//! Blend shapes first, then linear blend skinning (or dual-quaternion skinning where
//! `skel:skinningMethod` asks for it, [`super::dqs`]), as UsdSkel defines them: a skinned point is
//! `Σ w_i · (inverse(bindTransform_i) · jointSkelSpace_i) · geomBindTransform · p`, in the
//! skeleton's space, so the mesh renders with the Skeleton prim's world transform and its own
//! is ignored. The openusd crate's UsdSkel toolkit supplies the joint topology, the animation's
//! time samples (rotations slerped) and the LBS sums; everything it would `assert!` on or
//! silently zero (mismatched lengths, out-of-range joint indices) is checked here first and
//! reported naming the attribute, and the mesh then renders in its rest pose.

use std::collections::HashMap;

use glam::{DMat3, DMat4, Vec3};
use openusd::gf;
use openusd::schemas::skel::{AnimMapper, BlendShape, SkelAnimQuery, SkelBindingAPI, SkeletonResolver, SkinningMethod, SkinningResolver};
use openusd::sdf;

use super::dqs::{Blend, DualJoint, Skinning};
use super::*;

/// Authored normals and their interpolation, as `MeshSource` holds them.
pub(super) type AuthoredNormals = Option<(Vec<Vec3>, String)>;

/// A mesh skinned by a skeleton, for the render plan and `inspect`.
#[derive(Clone, Debug)]
pub struct Skinned {
    pub path: String,
    pub skeleton: String,
    /// The SkelAnimation posing it; `None`: the skeleton's rest pose.
    pub animation: Option<String>,
    /// Blend shapes with a weight other than 0 at the frame.
    pub blend_shapes: usize,
}

/// A skeleton posed at the frame.
#[derive(Clone)]
struct Pose {
    joints: Vec<String>,
    /// `inverse(bindTransform) · jointSkelSpace` per joint, USD's row-vector convention.
    skinning: Vec<gf::Matrix4d>,
    /// The Skeleton prim's local-to-world: where skinned points live.
    world: DMat4,
    animation: Option<String>,
    /// Blend shape weights by name, from the animation.
    weights: HashMap<String, f32>,
}

/// What skinning does to one mesh.
pub(super) struct Skin {
    pose: Pose,
    /// `None`: the mesh has blend shapes but no joint influences (it keeps its own transform).
    joints: Option<Joints>,
    shapes: Vec<Shape>,
}

/// A mesh's joint influences: the toolkit's resolver (joint subset, geomBindTransform, the
/// sums) and the raw arrays, checked, for the normals.
struct Joints {
    resolver: SkinningResolver,
    indices: Vec<i32>,
    weights: Vec<f32>,
}

/// One blend shape at its weight: offsets to add, to the points listed (all when empty).
struct Shape {
    offsets: Vec<gf::Vec3f>,
    point_indices: Vec<i32>,
}

fn to_gf(v: Vec3) -> gf::Vec3f {
    gf::vec3f(v.x, v.y, v.z)
}

fn from_gf(v: gf::Vec3f) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// The matrix that carries normals through `m`: the inverse transpose of its linear part.
fn normal_matrix(m: &gf::Matrix4d) -> DMat3 {
    let linear = DMat3::from_mat4(values::matrix(m));
    if linear.determinant().abs() < 1e-300 { linear } else { linear.inverse().transpose() }
}

/// The offsets of a shape at weight `w`: linear between in-betweens (0 and 1 being "none" and
/// the primary offsets), extrapolated past the ends with the nearest segment, as UsdSkel's
/// BlendShapeQuery does.
fn offsets_at(w: f32, primary: &[gf::Vec3f], inbetweens: &[(f32, Vec<gf::Vec3f>)]) -> Vec<gf::Vec3f> {
    let zero = vec![gf::Vec3f::default(); primary.len()];
    let mut stops: Vec<(f32, &[gf::Vec3f])> = vec![(0.0, &zero), (1.0, primary)];
    stops.extend(inbetweens.iter().map(|(w, o)| (*w, o.as_slice())));
    stops.sort_by(|a, b| a.0.total_cmp(&b.0));
    let upper = stops.iter().position(|s| s.0 >= w).unwrap_or(stops.len() - 1).max(1);
    let ((w0, a), (w1, b)) = (stops[upper - 1], stops[upper]);
    let t = if w1 > w0 { (w - w0) / (w1 - w0) } else { 1.0 };
    a.iter().zip(b).map(|(a, b)| *a + (*b - *a) * t).collect()
}

impl Skin {
    /// Where the mesh renders from: the skeleton's world transform when joints deform it.
    pub(super) fn world(&self) -> Option<DMat4> {
        self.joints.as_ref().map(|_| self.pose.world)
    }

    /// `rest` posed by this skin, in the object space of `frame` (the skin at the frame, whose
    /// world the mesh renders from): the points of a deformation sample.
    pub(super) fn points_in(&self, frame: &Skin, rest: &[Vec3], face_vertex_indices: &[i64]) -> Option<Vec<Vec3>> {
        let (points, _) = self.deform(rest, None, face_vertex_indices).ok()?;
        let (Some(here), Some(there)) = (self.world(), frame.world()) else { return Some(points) };
        let to_frame = there.inverse() * here;
        Some(points.into_iter().map(|p| to_frame.transform_point3(p.as_dvec3()).as_vec3()).collect())
    }

    /// `points` posed: blend shapes, then the joints. Normals (with their interpolation;
    /// face-varying ones through `face_vertex_indices`) follow the same joints.
    pub(super) fn deform(
        &self,
        points: &[Vec3],
        normals: Option<&(Vec<Vec3>, String)>,
        face_vertex_indices: &[i64],
    ) -> Result<(Vec<Vec3>, AuthoredNormals), String> {
        let mut points: Vec<gf::Vec3f> = points.iter().copied().map(to_gf).collect();
        for (k, s) in self.shapes.iter().enumerate() {
            shape_fits(s, points.len()).map_err(|e| format!("blend shape {k}: {e}"))?;
        }
        let shapes: Vec<_> = self
            .shapes
            .iter()
            .map(|s| openusd::schemas::skel::skinning::BlendShapeWeighted {
                weight: 1.0,
                offsets: &s.offsets,
                point_indices: &s.point_indices,
            })
            .collect();
        points = openusd::schemas::skel::skinning::apply_blend_shapes(&points, &shapes);
        let Some(joints) = &self.joints else {
            return Ok((points.into_iter().map(from_gf).collect(), normals.cloned()));
        };
        let skinning = &self.pose.skinning;
        if joints.resolver.skinning_method() == SkinningMethod::DualQuaternion {
            return self.deform_dual_quaternion(points, normals, face_vertex_indices);
        }
        if joints.resolver.is_rigidly_deformed() {
            let m = joints.resolver.compute_rigid_transform(skinning);
            let n = normal_matrix(&m);
            let points = points.into_iter().map(|p| from_gf(m.transform_point(p))).collect();
            let normals = normals.map(|(v, i)| (v.iter().map(|v| (n * v.as_dvec3()).normalize_or_zero().as_vec3()).collect(), i.clone()));
            return Ok((points, normals));
        }
        let influences = self.influences(points.len())?;
        let normals = normals.map(|(v, interp)| (self.skin_normals(v, interp, face_vertex_indices, &influences), interp.clone()));
        let points = joints.resolver.compute_skinned_points(&points, skinning);
        Ok((points.into_iter().map(from_gf).collect(), normals))
    }

    /// [`Self::deform`]'s joints by dual-quaternion skinning ([`super::dqs`]), after blend
    /// shapes: points through the geometry's bind transform, then the blend of their joints;
    /// constant (rigid) influences make one blended transform for every point.
    fn deform_dual_quaternion(
        &self,
        points: Vec<gf::Vec3f>,
        normals: Option<&(Vec<Vec3>, String)>,
        face_vertex_indices: &[i64],
    ) -> Result<(Vec<Vec3>, AuthoredNormals), String> {
        let Joints { resolver, indices, weights } = self.joints.as_ref().expect("joint skinning");
        let per = resolver.num_influences_per_component();
        let rigid = resolver.is_rigidly_deformed();
        if !rigid {
            self.check_influence_count(points.len())?;
        }
        let duals: Vec<DualJoint> =
            resolver.remap_skinning_xforms(&self.pose.skinning).iter().map(|m| DualJoint::new(values::matrix(m))).collect();
        let blend = Blend::new(&duals);
        let influences =
            |v: usize| -> Vec<(usize, f64)> { (v * per..(v + 1) * per).map(|s| (indices[s] as usize, weights[s] as f64)).collect() };
        // Each point's blend once, for its position and its normals; one for a rigid binding.
        let skins: Vec<Skinning> = (0..if rigid { 1 } else { points.len() }).map(|v| blend.skinning(&influences(v))).collect();
        let skin_of = |v: usize| &skins[if rigid { 0 } else { v }];
        let geom = values::matrix(&resolver.geom_bind_transform());
        let geom_normals = normal_matrix(&resolver.geom_bind_transform());
        let skinned =
            points.iter().enumerate().map(|(v, p)| skin_of(v).point(geom.transform_point3(from_gf(*p).as_dvec3())).as_vec3()).collect();
        let normals = normals.map(|(v, interp)| {
            let skinned = v
                .iter()
                .enumerate()
                .map(|(i, n)| match normal_point(interp, face_vertex_indices, i).filter(|&p| p < points.len()) {
                    Some(p) => skin_of(p).normal(geom_normals * n.as_dvec3()).as_vec3(),
                    None => Vec3::ZERO,
                })
                .collect();
            (skinned, interp.clone())
        });
        Ok((skinned, normals))
    }

    /// Per-point influences fit `point_count` points.
    fn check_influence_count(&self, point_count: usize) -> Result<(), String> {
        let Joints { resolver, indices, .. } = self.joints.as_ref().expect("joint skinning");
        let per = resolver.num_influences_per_component();
        if indices.len() != point_count * per {
            return Err(format!(
                "primvars:skel:jointIndices has {} entries for {point_count} points of {per} influences each",
                indices.len()
            ));
        }
        Ok(())
    }

    /// Each point's (normal matrix, weight) pairs, checked against the point count.
    fn influences(&self, point_count: usize) -> Result<Vec<Vec<(DMat3, f64)>>, String> {
        self.check_influence_count(point_count)?;
        let Joints { resolver, indices, weights } = self.joints.as_ref().expect("joint skinning");
        let per = resolver.num_influences_per_component();
        let geom = normal_matrix(&resolver.geom_bind_transform());
        let by_joint: Vec<DMat3> = resolver.remap_skinning_xforms(&self.pose.skinning).iter().map(normal_matrix).collect();
        Ok((0..point_count)
            .map(|v| (v * per..(v + 1) * per).map(|s| (by_joint[indices[s] as usize] * geom, weights[s] as f64)).collect())
            .collect())
    }

    /// Normals through the weighted normal matrices of their points (a face-varying normal
    /// takes its corner's point). Uniform and constant normals have no point: they are left
    /// for the renderer to recompute from the posed surface.
    fn skin_normals(&self, normals: &[Vec3], interp: &str, corners: &[i64], influences: &[Vec<(DMat3, f64)>]) -> Vec<Vec3> {
        normals
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let Some(inf) = normal_point(interp, corners, i).and_then(|p| influences.get(p)) else { return Vec3::ZERO };
                let n = n.as_dvec3();
                inf.iter().map(|(m, w)| *m * n * *w).sum::<glam::DVec3>().normalize_or_zero().as_vec3()
            })
            .collect()
    }
}

/// The point normal `i` of `interp` interpolation follows (a face-varying normal takes its
/// corner's point); `None` for uniform and constant normals, which have no point.
fn normal_point(interp: &str, corners: &[i64], i: usize) -> Option<usize> {
    match interp {
        "vertex" | "varying" => Some(i),
        "faceVarying" => corners.get(i).map(|&p| p as usize),
        _ => None,
    }
}

/// A blend shape's offsets and indices agree with each other and with the mesh.
fn shape_fits(s: &Shape, point_count: usize) -> Result<(), String> {
    if s.point_indices.is_empty() {
        if s.offsets.len() != point_count {
            return Err(format!("'offsets' has {} entries for {point_count} points", s.offsets.len()));
        }
    } else if s.offsets.len() != s.point_indices.len() {
        return Err(format!("'offsets' has {} entries for {} 'pointIndices'", s.offsets.len(), s.point_indices.len()));
    } else if let Some(bad) = s.point_indices.iter().find(|&&i| i < 0 || i as usize >= point_count) {
        return Err(format!("'pointIndices' holds {bad}, out of range for {point_count} points"));
    }
    Ok(())
}

impl Reader<'_> {
    /// Poses every mesh under the SkelRoot at `p` bound to a skeleton; the meshes read later
    /// find their skin in `self.skins`. A skeleton or binding that cannot be posed leaves its
    /// meshes in their rest pose, with a warning naming the attribute.
    pub(super) fn skel_root(&mut self, p: &str) -> Result<()> {
        let mut poses: HashMap<String, std::result::Result<Pose, String>> = HashMap::new();
        let mut shutter_poses: HashMap<String, Option<Vec<Pose>>> = HashMap::new();
        let members: Vec<sdf::Path> = self.all_paths.iter().filter(|q| under(q.as_str(), p) && q.as_str() != p).cloned().collect();
        for path in members {
            let mesh = path.as_str().to_string();
            if self.stage.prim(path.clone()).type_name()?.is_none_or(|t| t.as_str() != "Mesh") {
                continue;
            }
            let Some(binding) = SkelBindingAPI::get(self.stage, path.clone())? else { continue };
            let Some(skeleton) = binding.inherited_skeleton()? else { continue };
            let key = skeleton.as_str().to_string();
            if !poses.contains_key(&key) {
                let pose = self.pose(&skeleton, self.time).map_err(|e| format!("{e:#}"));
                if let Err(e) = &pose {
                    self.out.warnings.push(format!("{e}; the meshes it binds render in their rest pose"));
                }
                poses.insert(key.clone(), pose);
            }
            let Ok(pose) = &poses[&key] else { continue };
            match self.skin(&binding, pose.clone()) {
                Ok(Some(skin)) => {
                    self.out.skinned.push(Skinned {
                        path: mesh.clone(),
                        skeleton: key,
                        animation: pose.animation.clone(),
                        blend_shapes: skin.shapes.len(),
                    });
                    if pose.animation.is_some()
                        && let Some(samples) = self.shutter_skins(&binding, &skeleton, &mut shutter_poses)
                    {
                        self.skin_samples.insert(mesh.clone(), samples);
                    }
                    self.skins.insert(mesh, skin);
                }
                Ok(None) => self.out.warnings.push(format!("{mesh}: bound to {key} but has no joint influences or blend shapes")),
                Err(e) => self.out.warnings.push(format!("{mesh}: {e}; the mesh renders in its rest pose")),
            }
        }
        Ok(())
    }

    /// `binding`'s skins at the motion samples over an open shutter (deformation blur), its
    /// skeleton's poses computed once for all the meshes it binds (in `cache`); None when the
    /// shutter is closed or a sample cannot be posed (said once: the mesh keeps the frame's
    /// pose).
    fn shutter_skins(
        &mut self,
        binding: &SkelBindingAPI,
        skeleton: &sdf::Path,
        cache: &mut HashMap<String, Option<Vec<Pose>>>,
    ) -> Option<Vec<Skin>> {
        self.shutter?;
        let key = skeleton.as_str().to_string();
        if !cache.contains_key(&key) {
            let poses = self.shutter_times().into_iter().map(|t| self.pose(skeleton, t)).collect::<Result<Vec<_>>>();
            if let Err(e) = &poses {
                self.out.warnings.push(format!("{e:#}; within the shutter, so its meshes render without deformation blur"));
            }
            cache.insert(key.clone(), poses.ok());
        }
        let poses = cache[&key].clone()?;
        poses.into_iter().map(|pose| self.skin(binding, pose).ok().flatten()).collect()
    }

    /// The skeleton at `path` posed at `time`: its animation's joints where it has them, its
    /// rest transforms elsewhere.
    fn pose(&mut self, path: &sdf::Path, time: TimeCode) -> Result<Pose> {
        let s = path.as_str();
        let skeleton = openusd::schemas::skel::Skeleton::get(self.stage, path.clone())?
            .with_context(|| format!("{s}: the bound skel:skeleton is not a Skeleton prim"))?;
        let resolver = SkeletonResolver::from_skeleton(&skeleton)?;
        let joints = resolver.joint_order().to_vec();
        let n = joints.len();
        anyhow::ensure!(n > 0, "{s}: attribute 'joints' is empty");
        resolver.topology().validate().map_err(|e| anyhow::anyhow!("{s}: attribute 'joints': {e} (parents must come first)"))?;
        let binds = resolver.joint_world_bind_transforms().len();
        anyhow::ensure!(binds == n, "{s}: attribute 'bindTransforms' has {binds} matrices for {n} joints");
        let rest = resolver.rest_pose_local();
        let mut local: Vec<Option<gf::Matrix4d>> = if rest.len() == n { rest.iter().copied().map(Some).collect() } else { vec![None; n] };
        let animation = self.animation_source(path)?;
        let mut weights = HashMap::new();
        if let Some(anim) = &animation {
            let query = SkelAnimQuery::new(self.stage, anim.clone())?;
            if let Some(query) = query {
                self.check_animation(anim, query.joint_order().len(), query.blend_shape_order().len(), time)?;
                let posed = query.compute_joint_local_transforms(self.stage, time)?;
                let mapper = AnimMapper::new(query.joint_order(), &joints);
                for (t, slot) in local.iter_mut().enumerate() {
                    if let Some(i) = mapper.source_index(t) {
                        *slot = Some(posed[i]);
                    }
                }
                let w = query.compute_blend_shape_weights(self.stage, time)?;
                weights = query.blend_shape_order().iter().cloned().zip(w).collect();
            }
        }
        let local: Vec<gf::Matrix4d> = local
            .into_iter()
            .enumerate()
            .map(|(i, m)| {
                m.with_context(|| {
                    format!(
                        "{s}: joint '{}' is neither animated nor given a rest transform ('restTransforms' has {} for {n} joints)",
                        joints[i],
                        rest.len()
                    )
                })
            })
            .collect::<Result<_>>()?;
        let skinning = resolver.compute_skinning_transforms_from_world(&resolver.joint_local_to_skel_space(&local));
        anyhow::ensure!(skinning.iter().all(|m| m.0.iter().all(|x| x.is_finite())), "{s}: the posed joints are not finite");
        let world = if time == self.time { self.world_transform(path)? } else { self.world_at(path, time)? };
        Ok(Pose { joints, skinning, world, animation: animation.map(|a| a.as_str().to_string()), weights })
    }

    /// The skeleton's `skel:animationSource`, on it or inherited from its ancestors (older
    /// files bind it on the SkelRoot).
    fn animation_source(&self, skeleton: &sdf::Path) -> Result<Option<sdf::Path>> {
        let mut at = Some(skeleton.clone());
        while let Some(path) = at.filter(|p| !p.as_str().is_empty() && p.as_str() != "/") {
            let prim = self.stage.prim(path.clone());
            if let Some(t) = valid_targets(&prim, path.as_str(), "skel:animationSource")?.into_iter().next() {
                return Ok(Some(t));
            }
            at = path.parent();
        }
        Ok(None)
    }

    /// The animation's arrays have one entry per joint (or blend shape); the toolkit would read
    /// a short one as the identity.
    fn check_animation(&self, anim: &sdf::Path, joints: usize, shapes: usize, time: TimeCode) -> Result<()> {
        let prim = self.stage.prim(anim.clone());
        let a = anim.as_str();
        for (name, want) in [("translations", joints), ("rotations", joints), ("scales", joints), ("blendShapeWeights", shapes)] {
            let Some(v) = get(&prim, name, time)? else { continue };
            let len = match name {
                "rotations" => values::quat_array(&v).map(|a| a.len()),
                "blendShapeWeights" => values::float_array(&v).map(|a| a.len()),
                _ => values::vec3_array(&v).map(|a| a.len()),
            };
            let len = len.with_context(|| format!("{a}: attribute '{name}' has type {}", values::type_of(&v)))?;
            anyhow::ensure!(len == want, "{a}: attribute '{name}' has {len} entries for {want}");
        }
        Ok(())
    }

    /// How `binding`'s mesh is skinned by `pose`; `None` when it has neither joint influences
    /// nor blend shapes.
    fn skin(&mut self, binding: &SkelBindingAPI, pose: Pose) -> Result<Option<Skin>, String> {
        let e = |e: anyhow::Error| format!("{e:#}");
        let resolver = SkinningResolver::from_binding(binding, &pose.joints).map_err(e)?;
        let joints = if resolver.has_joint_influences() { Some(self.checked(binding, resolver).map_err(e)?) } else { None };
        let shapes = self.shapes(binding, &pose.weights).map_err(e)?;
        if joints.is_none() && shapes.is_empty() {
            return Ok(None);
        }
        Ok(Some(Skin { pose, joints, shapes }))
    }

    /// The binding's joint influences, checked so the toolkit's sums cannot index out of range.
    fn checked(&mut self, binding: &SkelBindingAPI, r: SkinningResolver) -> Result<Joints> {
        let (indices, weights) = (binding.joint_indices()?, binding.joint_weights()?);
        let element_size = |a: openusd::usd::Attribute| -> Result<f64> {
            Ok(a.get_metadata::<Value>("elementSize")?.as_ref().and_then(values::scalar).unwrap_or(1.0))
        };
        let (indices_per, weights_per) = (element_size(binding.joint_indices_attr())?, element_size(binding.joint_weights_attr())?);
        // The toolkit reads elementSize as an i32: one it cannot hold is refused here.
        if indices_per != r.num_influences_per_component() as f64 {
            anyhow::bail!("primvars:skel:jointIndices has elementSize {indices_per}, which is not a count of influences");
        }
        if weights_per != indices_per {
            anyhow::bail!("primvars:skel:jointWeights has elementSize {weights_per}, primvars:skel:jointIndices {indices_per}");
        }
        if indices.len() != weights.len() {
            anyhow::bail!("primvars:skel:jointIndices has {} entries, primvars:skel:jointWeights {}", indices.len(), weights.len());
        }
        let per = r.num_influences_per_component();
        if r.is_rigidly_deformed() && indices.len() != per {
            anyhow::bail!("constant primvars:skel:jointIndices has {} entries for elementSize {per}", indices.len());
        }
        let joints = r.joint_order_len();
        if let Some(bad) = indices.iter().find(|&&i| i < 0 || i as usize >= joints) {
            anyhow::bail!("primvars:skel:jointIndices holds {bad}, out of range for {joints} joints");
        }
        if let Some(bad) = weights.iter().find(|w| !w.is_finite()) {
            anyhow::bail!("primvars:skel:jointWeights holds {bad}");
        }
        if r.geom_bind_transform().0.iter().any(|x| !x.is_finite()) {
            anyhow::bail!("primvars:skel:geomBindTransform is not finite");
        }
        Ok(Joints { resolver: r, indices, weights })
    }

    /// The mesh's blend shapes with a weight other than 0, their offsets at that weight.
    fn shapes(&mut self, binding: &SkelBindingAPI, weights: &HashMap<String, f32>) -> Result<Vec<Shape>> {
        let names = binding.blend_shapes()?;
        let targets = binding.blend_shape_targets()?;
        anyhow::ensure!(
            names.len() == targets.len(),
            "skel:blendShapes names {} shapes, skel:blendShapeTargets {}",
            names.len(),
            targets.len()
        );
        let mut out = Vec::new();
        for (name, target) in names.iter().zip(&targets) {
            let w = weights.get(name).copied().unwrap_or(0.0);
            if w == 0.0 || !w.is_finite() {
                continue;
            }
            let shape = BlendShape::get(self.stage, target.clone())?
                .with_context(|| format!("skel:blendShapeTargets names {}, which is not a BlendShape", target.as_str()))?;
            let inbetweens: Vec<(f32, Vec<gf::Vec3f>)> = shape
                .inbetweens()?
                .into_iter()
                .filter_map(|b| b.weight.filter(|w| w.is_finite() && *w != 0.0 && *w != 1.0).map(|w| (w, b.offsets)))
                .collect();
            let primary = shape.offsets()?;
            if let Some((_, bad)) = inbetweens.iter().find(|(_, o)| o.len() != primary.len()) {
                anyhow::bail!("{}: an in-between has {} offsets for {} primary ones", target.as_str(), bad.len(), primary.len());
            }
            out.push(Shape { offsets: offsets_at(w, &primary, &inbetweens), point_indices: shape.point_indices()? });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_betweens_interpolate_and_the_ends_extrapolate() {
        let primary = [gf::vec3f(1.0, 0.0, 0.0)];
        let half = vec![(0.5, vec![gf::vec3f(0.0, 1.0, 0.0)])];
        let x = |w: f32, ib: &[(f32, Vec<gf::Vec3f>)]| {
            let o = offsets_at(w, &primary, ib)[0];
            [o.x, o.y, o.z]
        };
        assert_eq!(x(0.5, &[]), [0.5, 0.0, 0.0]);
        assert_eq!(x(1.5, &[]), [1.5, 0.0, 0.0], "past 1: the last segment extended");
        assert_eq!(x(-1.0, &[]), [-1.0, 0.0, 0.0]);
        assert_eq!(x(0.25, &half), [0.0, 0.5, 0.0], "halfway to the in-between");
        assert_eq!(x(0.75, &half), [0.5, 0.5, 0.0], "halfway from it to the primary");
        assert_eq!(x(1.5, &half), [2.0, -1.0, 0.0]);
    }

    #[test]
    fn normals_follow_the_inverse_transpose() {
        // A scale of 2 in x: a 45° normal in xy turns towards y.
        let mut m = gf::Matrix4d::IDENTITY;
        m.0[0] = 2.0;
        let n = normal_matrix(&m) * glam::DVec3::new(1.0, 1.0, 0.0);
        assert!((n.normalize() - glam::DVec3::new(1.0, 2.0, 0.0).normalize()).length() < 1e-12);
    }
}
