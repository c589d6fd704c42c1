//! Walking the composed stage: visiting prims in order, world transforms, attribute reads at the frame.

use anyhow::{Context, Result};
use openusd::usd::Collection;

use super::*;

/// A double-precision world matrix as the renderer's affine transform.
pub(super) fn to_affine(m: &DMat4) -> Result<Affine3A> {
    let a = Affine3A::from_mat4(Mat4::from_cols_array(&m.to_cols_array().map(|x| x as f32)));
    if !a.is_finite() {
        anyhow::bail!("the transform is not finite");
    }
    Ok(a)
}

/// The rotation matrix USD makes of an orientation quaternion (GfMatrix4d::SetRotate): the
/// unit-quaternion formula applied to the raw components, without normalising. Half-precision
/// orientations are rarely unit length; normalising them (or going through GfRotation's
/// axis-angle) moved instances by 1e-4 relative to what usd-core computes.
pub(super) fn usd_rotation(q: glam::DQuat) -> glam::DMat3 {
    let (x2, y2, z2) = (q.x + q.x, q.y + q.y, q.z + q.z);
    let (xx, xy, xz) = (q.x * x2, q.x * y2, q.x * z2);
    let (yy, yz, zz) = (q.y * y2, q.y * z2, q.z * z2);
    let (wx, wy, wz) = (q.w * x2, q.w * y2, q.w * z2);
    glam::DMat3::from_cols(
        glam::DVec3::new(1.0 - (yy + zz), xy + wz, xz - wy),
        glam::DVec3::new(xy - wz, 1.0 - (xx + zz), yz + wx),
        glam::DVec3::new(xz + wy, yz - wx, 1.0 - (xx + yy)),
    )
}

/// True when `path` is `root` or beneath it.
pub fn under(path: &str, root: &str) -> bool {
    path == root || (path.starts_with(root) && path.as_bytes().get(root.len()) == Some(&b'/'))
}

/// An attribute's value at `time`: its time samples interpolated, else its default.
pub(super) fn get(prim: &Prim, name: &str, time: TimeCode) -> Result<Option<Value>> {
    if !authored::may_hold(prim, name) {
        return Ok(None);
    }
    prim.attribute(name).get_at::<Value>(time).map_err(|e| anyhow::anyhow!("attribute '{name}': {e:#}"))
}

/// Which properties the prim being read has opinions for. The translation asks for every input
/// a schema defines, and most are not authored: a 10,000-light file asked the composed stage
/// for a value that no layer held about twenty times a light. One list of the prim's composed
/// property names answers those without composing each property. Under value clips it does not:
/// an attribute only the clips author is no property of the prim, yet has a value.
pub(super) mod authored {
    use std::cell::RefCell;
    use std::collections::{HashMap, HashSet};

    use openusd::usd::Prim;

    /// What is known of the last prim asked about.
    struct Listed {
        prim: String,
        /// Its composed property names; None when value clips may source its attributes or
        /// the names could not be listed.
        names: Option<HashSet<String>>,
    }

    thread_local! {
        static LAST: RefCell<Option<Listed>> = const { RefCell::new(None) };
        /// Whether clips are anchored on each prim asked about or on one of its ancestors.
        static CLIPPED: RefCell<HashMap<String, bool>> = RefCell::new(HashMap::new());
    }

    /// The reading of one stage on this thread. What the thread knew is forgotten when it
    /// starts (a DCC reloading an edited file reads the same paths again) and when it ends (a
    /// million prims' clip marks would otherwise stay with the thread).
    pub(in crate::usd) struct Reading(());

    impl Reading {
        pub(in crate::usd) fn start() -> Self {
            forget();
            Reading(())
        }
    }

    impl Drop for Reading {
        fn drop(&mut self) {
            forget();
        }
    }

    fn forget() {
        LAST.take();
        CLIPPED.take();
    }

    /// False only when the prim's composed property names do not include `name` and no value
    /// clips may source it; true otherwise (the value is then read as usual).
    pub(in crate::usd) fn may_hold(prim: &Prim, name: &str) -> bool {
        LAST.with_borrow_mut(|last| {
            if last.as_ref().is_none_or(|l| l.prim != prim.path().as_str()) {
                let names = match (under_clips(prim), prim.property_names()) {
                    (false, Ok(names)) => Some(names.iter().map(|n| n.as_str().to_string()).collect()),
                    _ => None,
                };
                *last = Some(Listed { prim: prim.path().as_str().to_string(), names });
            }
            last.as_ref().and_then(|l| l.names.as_ref()).is_none_or(|names| names.contains(name))
        })
    }

    /// True when value clips are anchored on `prim` or an ancestor (or that cannot be read):
    /// an attribute only the clips author is then not among the prim's properties, yet has a
    /// value, as USD resolves it through the manifest it generates from the clips.
    fn under_clips(prim: &Prim) -> bool {
        CLIPPED.with_borrow_mut(|known| {
            // The ancestors not yet known, nearest first; then each from its parent down.
            let mut unknown = Vec::new();
            let mut path = prim.path().clone();
            while !known.contains_key(path.as_str()) && !path.is_abs_root() {
                let parent = path.parent();
                unknown.push(path);
                match parent {
                    Some(parent) => path = parent,
                    None => break,
                }
            }
            for path in unknown.into_iter().rev() {
                let above = path.parent().and_then(|p| known.get(p.as_str()).copied()).unwrap_or(false);
                let here = prim.stage().prim(path.clone()).has_clips().unwrap_or(true);
                known.insert(path.as_str().to_string(), above || here);
            }
            known.get(prim.path().as_str()).copied().unwrap_or(true)
        })
    }
}

/// An int array attribute of the prim at `p` (`None` unauthored); another type is an error
/// naming the prim and attribute.
pub(super) fn get_ints(prim: &Prim, p: &str, name: &str, time: TimeCode) -> Result<Option<Vec<i64>>> {
    get(prim, name, time)?
        .map(|v| values::int_array(&v).with_context(|| format!("{p}: attribute '{name}' is not an int array")))
        .transpose()
}

/// As [`get_ints`], for float arrays.
pub(super) fn get_floats(prim: &Prim, p: &str, name: &str, time: TimeCode) -> Result<Option<Vec<f32>>> {
    get(prim, name, time)?
        .map(|v| values::float_array(&v).with_context(|| format!("{p}: attribute '{name}' is not a float array")))
        .transpose()
}

impl Reader<'_> {
    pub(super) fn visit(&mut self, path: &sdf::Path) -> Result<()> {
        if !well_formed_path(path.as_str()) {
            self.out.warnings.push(format!("'{}' is not a valid prim path; the prim is skipped", path.as_str()));
            return Ok(());
        }
        let prim = self.stage.prim(path.clone());
        let type_name = prim.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
        let p = path.as_str().to_string();
        self.report_unsupported_apis(&prim, &p, &type_name)?;
        // Draw modes sit on models (Xforms): checked before structural prims are passed by.
        if let Some(mode) = get(&prim, "model:drawMode", self.time)?.as_ref().and_then(values::token)
            && !matches!(mode.as_str(), "default" | "inherited")
        {
            self.out
                .warnings
                .push(format!("{p}: model:drawMode '{mode}' is a viewport stand-in (cards, bounds, origin); the geometry itself renders"));
        }
        if STRUCTURAL.contains(&type_name.as_str()) || self.instancer_roots.iter().any(|r| under(&p, r) && *r != p) {
            return Ok(());
        }
        if let Some(purpose) = get(&prim, "purpose", self.time)?.as_ref().and_then(values::token)
            && !matches!(purpose.as_str(), "default" | "render" | "proxy" | "guide")
        {
            self.out.warnings.push(format!("{p}: purpose '{purpose}' is not default, render, proxy or guide; read as default"));
        }
        let view = AnyXformable(prim.clone());
        let purpose = view.compute_purpose()?;
        if matches!(purpose, Purpose::Proxy | Purpose::Guide) {
            return Ok(());
        }
        let visible = !self.invisible(path)?;
        match type_name.as_str() {
            "Mesh" => self.mesh(&prim, &p, visible),
            t if IMPLICIT.contains(&t) => self.implicit(&prim, &p, t, visible),
            "PointInstancer" => self.point_instancer(&prim, &p, visible),
            "Points" => self.points(&prim, &p, visible),
            "BasisCurves" => self.basis_curves(&prim, &p, visible),
            "Volume" => self.volume(&prim, &p, visible),
            // Read through the Volume whose fields name them.
            "OpenVDBAsset" | "Field3DAsset" => Ok(()),
            "RenderSettings" => self.render_settings(&prim, &p),
            // Read through the RenderSettings that names them.
            "RenderProduct" | "RenderVar" => Ok(()),
            "Camera" => self.camera(&prim, &p),
            t if LIGHTS.contains(&t) => self.light(&prim, &p, t, visible),
            // UsdSkel: the SkelRoot comes before its meshes, which find their pose ready.
            "SkelRoot" => self.skel_root(&p),
            "Skeleton" | "SkelAnimation" | "BlendShape" => {
                self.out.skipped.push(p);
                Ok(())
            }
            other => {
                self.out.warnings.push(format!("{p}: prim type '{other}' is not supported yet and is not rendered"));
                self.out.skipped.push(p);
                Ok(())
            }
        }
    }

    /// Each opinion on the prim's metadata `field` along its prim stack, strongest first, with
    /// the identifier of the layer that holds it (relative assets resolve beside it).
    pub(super) fn opinions(&self, prim: &Prim, field: &str) -> Vec<(String, Value)> {
        let Ok(stack) = prim.prim_stack() else { return Vec::new() };
        let mut found = Vec::new();
        for (layer_id, spec_path) in stack {
            let Some(layer) = self.stage.layer(&layer_id) else { continue };
            let Some(spec) = layer.prim(spec_path) else { continue };
            if let Ok(Some(value)) = spec.field(field) {
                found.push((layer_id, value));
            }
        }
        found
    }

    /// Applied API schemas that ask for what Tessera does not do yet, said once per prim: a
    /// volume or a prim not rendered as a mesh as a light, and collections whose path
    /// expression cannot be evaluated.
    fn report_unsupported_apis(&mut self, prim: &Prim, p: &str, type_name: &str) -> Result<()> {
        self.reported_names.update(self.stage);
        let applied = if self.reported_names.apis { prim.api_schemas()? } else { Vec::new() };
        for api in applied {
            let api = api.as_str();
            // A gprim tessellated to a mesh is read as a mesh light ([`Reader::gprim_light`]).
            let gprim_light = matches!(api, "MeshLightAPI" | "LightAPI") && lit_as_mesh(type_name);
            if !gprim_light && (matches!(api, "MeshLightAPI" | "VolumeLightAPI") || (api == "LightAPI" && !LIGHTS.contains(&type_name))) {
                self.out.warnings.push(format!(
                    "{p}: {api} (a {type_name} as a light) is not supported yet; it renders with its bound material and emits only what that emits"
                ));
            }
            // A light's own link collections are said by the light links' reader.
            let light_link = |name: &str| LIGHTS.contains(&type_name) && matches!(name, "lightLink" | "shadowLink");
            if let Some(name) = api.strip_prefix("CollectionAPI:").filter(|name| !light_link(name))
                && let Some(error) = Collection::new(prim.path().clone(), name).expression_error(self.stage)?
            {
                self.out.warnings.push(format!(
                    "{p}: collection '{name}': its membershipExpression cannot be evaluated ({error}); where it decides, it holds no prims"
                ));
            }
        }
        Ok(())
    }

    /// True when the prim at `path` or an ancestor is invisible at the frame, as
    /// UsdGeomImageable's ComputeVisibility(time) says: `visibility` may be time-sampled (a prop
    /// that appears mid-shot), where openusd's `compute_visibility` reads defaults only.
    pub(super) fn invisible(&mut self, path: &sdf::Path) -> Result<bool> {
        if let Some(&hidden) = self.hidden.get(path.as_str()) {
            return Ok(hidden);
        }
        let prim = self.stage.prim(path.clone());
        let here = get(&prim, "visibility", self.time)?.as_ref().and_then(values::token).is_some_and(|v| v == "invisible");
        let hidden = here
            || match path.parent() {
                Some(parent) if !parent.is_abs_root() && !parent.as_str().is_empty() => self.invisible(&parent)?,
                _ => false,
            };
        self.hidden.insert(path.as_str().to_string(), hidden);
        Ok(hidden)
    }

    /// Local-to-world, composing parents and honouring `!resetXformStack!`.
    pub(super) fn world_transform(&mut self, path: &sdf::Path) -> Result<DMat4> {
        if let Some(m) = self.world.get(path.as_str()) {
            return Ok(*m);
        }
        let (local, parent) = self.local_at(path, self.time)?;
        let m = match parent {
            Some(parent) => self.world_transform(&parent)? * local,
            None => local,
        };
        self.world.insert(path.as_str().to_string(), m);
        Ok(m)
    }

    /// Local-to-world at `time` (uncached: the cache holds the frame's own time).
    pub(super) fn world_at(&mut self, path: &sdf::Path, time: TimeCode) -> Result<DMat4> {
        let (local, parent) = self.local_at(path, time)?;
        Ok(match parent {
            Some(parent) => self.world_at(&parent, time)? * local,
            None => local,
        })
    }

    /// The prim's local-to-parent transform at `time`, and the parent its world transform
    /// composes with (`None` at the root or past `!resetXformStack!`).
    fn local_at(&mut self, path: &sdf::Path, time: TimeCode) -> Result<(DMat4, Option<sdf::Path>)> {
        let prim = self.stage.prim(path.clone());
        // The schema looks each op up by name: check the names first (a garbled one sent the
        // openusd crate into an endless loop, found by fuzzing).
        if let Some(order) = get(&prim, "xformOpOrder", self.time)? {
            for op in values::token_array(&order).unwrap_or_default() {
                let name = op.trim_start_matches("!invert!");
                if op != "!resetXformStack!" && !well_formed_name(name) {
                    anyhow::bail!("{path}: attribute 'xformOpOrder' names '{op}', which is not a valid attribute name");
                }
            }
        }
        let view = AnyXformable(prim);
        let local = values::matrix(&view.local_to_parent_transform(time)?);
        let parent = match path.parent() {
            Some(parent) if !view.resets_xform_stack()? && parent.as_str() != "/" && !parent.as_str().is_empty() => Some(parent),
            _ => None,
        };
        Ok((local, parent))
    }

    /// The world transform a gprim renders with: a skinned mesh's is its skeleton's.
    pub(super) fn affine(&mut self, prim: &Prim, p: &str) -> Result<Affine3A> {
        let m = match self.skins.get(prim.path().as_str()).and_then(|s| s.world()) {
            Some(skeleton) => skeleton,
            None => self.world_transform(prim.path())?,
        };
        to_affine(&m).with_context(|| format!("{p}: xformOps compose to a non-finite transform"))
    }
}
