//! A live session as a DCC keeps one: the scene the server holds is mirrored here, and every
//! edit (a re-exported USD file, a moved object, a light or material tweak) is sent as the
//! Hydra-style deltas that take the server from what it holds to the edited scene, and
//! nothing else. The Python package and the Blender add-on drive this type.

use anyhow::{Context, Result, bail};
use glam::{Affine3A, DMat4, Vec3};
use render_core::light::{LightDesc, MeshLight};
use render_core::material::ParamValue;
use tessera_proto::v1 as pb;

use crate::remote::Connection;
use crate::usd::Translation;

/// Puts every mesh, instancer and volume of `t` at or under one of `prims` into link
/// collection `id` and takes every other out of it (all out when `prims` is None).
fn relink(t: &mut Translation, id: &str, prims: Option<&[String]>) -> Result<()> {
    let held = |path: &str| {
        // Keys name their prim, then what the reader split it into ("/A[points]", "/P[/P/M]").
        let prim = path.split('[').next().unwrap_or(path);
        prims.is_some_and(|ps| ps.iter().any(|p| p == "/" || crate::usd::under(prim, p)))
    };
    let set = |collections: &mut Vec<String>, on: bool| {
        collections.retain(|c| c != id);
        if on {
            collections.push(id.to_string());
        }
    };
    let native: std::collections::BTreeSet<usize> = t.native_instances.iter().map(|n| n.instancer).collect();
    for (path, m) in &mut t.meshes {
        set(&mut m.link_collections, held(path));
    }
    for (path, v) in &mut t.volumes {
        set(&mut v.link_collections, held(path));
    }
    for (k, (path, inst)) in t.instancers.iter_mut().enumerate() {
        let on = match native.contains(&k) {
            false => held(path),
            true => {
                let sides: std::collections::BTreeSet<bool> =
                    t.native_instances.iter().filter(|n| n.instancer == k).map(|n| held(&n.path)).collect();
                if sides.len() > 1 {
                    bail!("{id}: instances drawn by {path} fall on both sides of the link; author the link in USD and sync it instead");
                }
                sides.contains(&true)
            }
        };
        set(&mut inst.link_collections, on);
    }
    Ok(())
}

/// One prim a sync sent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SentPrim {
    /// Its path (a content hash for a texture).
    pub path: String,
    /// `mesh`, `material`, `light`, `camera`, `instancer`, `texture` or `remove`.
    pub kind: &'static str,
    /// What changed, as Hydra's dirty bits name it (`transform`, `points`, … or `all`).
    pub dirty: Vec<&'static str>,
    /// Array chunks sent with it (points, indices, texture bytes).
    pub chunks: usize,
}

/// A session with the scene it holds.
pub struct LiveSession {
    /// The connection (its session id names the session).
    pub conn: Connection,
    held: Option<Translation>,
}

impl LiveSession {
    /// A live session on an open connection.
    pub fn new(conn: Connection) -> Self {
        LiveSession { conn, held: None }
    }

    /// The scene the server holds, as last synced.
    pub fn held(&self) -> Option<&Translation> {
        self.held.as_ref()
    }

    /// Reads a USD file at `frame` and syncs it: whole the first time, afterwards only the
    /// prims whose content changed.
    pub async fn sync_usd(&mut self, path: &std::path::Path, frame: Option<f64>) -> Result<(Vec<SentPrim>, Vec<String>)> {
        let owned = path.to_path_buf();
        let mut t = tokio::task::spawn_blocking(move || crate::usd::load_at(&owned, frame)).await??;
        t.add_default_camera();
        let warnings = t.warnings.clone();
        Ok((self.sync(t).await?, warnings))
    }

    /// Brings the server from the scene it holds to `after`.
    pub async fn sync(&mut self, after: Translation) -> Result<Vec<SentPrim>> {
        let items = match &self.held {
            None => {
                let missing = self.conn.missing_textures(after.textures.keys().cloned().collect()).await?;
                crate::sync::scene_sync(&after, |h| missing.iter().any(|m| m == h))
            }
            Some(before) => crate::sync::changes(before, &after),
        };
        let sent = summarize(&items);
        if !items.is_empty() {
            self.conn.sync(items).await.context("the server rejected the edit")?;
        }
        self.held = Some(after);
        Ok(sent)
    }

    /// Applies `edit` to a copy of the held scene and syncs the difference.
    async fn edit(&mut self, edit: impl FnOnce(&mut Translation) -> Result<()>) -> Result<Vec<SentPrim>> {
        let mut after = self.held.clone().context("nothing synced yet: call sync_usd first")?;
        edit(&mut after)?;
        self.sync(after).await
    }

    /// Moves a mesh, light or camera to the object-to-world matrix `m`, indexed `m[row][col]`
    /// with the translation in the last column (the transpose of USD's `GfMatrix4d`, which
    /// keeps it in the last row; what Blender's `matrix_world` gives row by row).
    pub async fn set_transform(&mut self, prim: &str, m: [[f64; 4]; 4]) -> Result<Vec<SentPrim>> {
        let affine = affine_of(prim, m)?;
        self.edit(|t| {
            if let Some((_, mesh)) = t.meshes.iter_mut().find(|(p, _)| p == prim) {
                mesh.transform = affine;
            } else if let Some((_, light)) = t.lights.iter_mut().find(|(p, _)| p == prim) {
                light.transform = affine;
            } else if let Some((_, camera)) = t.cameras.iter_mut().find(|(p, _)| p == prim) {
                camera.transform = affine;
            } else {
                bail!("{prim}: no mesh, light or camera with this path in the session");
            }
            Ok(())
        })
        .await
    }

    /// Changes a camera's lens: any of `focal_length`, `f_stop`, `focus_distance` (scene
    /// units), `horizontal_aperture`, `vertical_aperture` (millimetres as USD authors them),
    /// and its `exposure` (stops).
    pub async fn set_camera(&mut self, path: &str, params: &[(String, f64)]) -> Result<Vec<SentPrim>> {
        self.edit(|t| {
            let (_, c) = t.cameras.iter_mut().find(|(p, _)| p == path).with_context(|| format!("{path}: no camera with this path"))?;
            for (name, v) in params {
                let v = finite(path, name, *v)? as f32;
                match name.as_str() {
                    "focal_length" => c.focal_length = v,
                    "f_stop" => c.f_stop = v,
                    "focus_distance" => c.focus_distance = v,
                    "horizontal_aperture" => c.horizontal_aperture = v,
                    "vertical_aperture" => c.vertical_aperture = v,
                    "exposure" => c.exposure = v,
                    _ => bail!(
                        "{path}: unknown camera parameter '{name}' (focal_length, f_stop, focus_distance, horizontal_aperture, vertical_aperture, exposure)"
                    ),
                }
            }
            Ok(())
        })
        .await
    }

    /// Changes a light's (a UsdLux light's or a mesh light's) inputs: `intensity`, `exposure`, `diffuse`, `specular` (numbers) and
    /// `color` (three numbers).
    pub async fn set_light_params(&mut self, path: &str, params: &[(String, Vec<f64>)]) -> Result<Vec<SentPrim>> {
        self.edit(|t| {
            let mut values = Vec::new();
            for (name, v) in params {
                let v: Vec<f32> = v.iter().map(|&x| finite(path, name, x).map(|x| x as f32)).collect::<Result<_>>()?;
                if !matches!((name.as_str(), v.len()), ("intensity" | "exposure" | "diffuse" | "specular", 1) | ("color", 3)) {
                    bail!(
                        "{path}: '{name}' is not a light parameter taking {} value(s) (intensity, exposure, diffuse, specular, color)",
                        v.len()
                    );
                }
                values.push((name.as_str(), v));
            }
            for_each_light(t, path, |l| {
                for (name, v) in &values {
                    match (*name, v.as_slice()) {
                        ("intensity", [x]) => *l.intensity = *x,
                        ("exposure", [x]) => *l.exposure = *x,
                        ("diffuse", [x]) => *l.diffuse = *x,
                        ("specular", [x]) => *l.specular = *x,
                        ("color", [r, g, b]) => *l.color = Vec3::new(*r, *g, *b),
                        _ => unreachable!("each name and count is checked above"),
                    }
                }
            })
        })
        .await
    }

    /// Links light `path` (a UsdLux light or a mesh light; UsdLux light linking, as a DCC's
    /// light-linking editor sets it): with
    /// `illuminates`, the light reaches only the prims at or under those paths; with
    /// `shadowed_by`, only they cast its shadows; None for either: every prim. Prims move in or
    /// out of the light's link collections, so the deltas are categories-only mesh edits. Native
    /// instances of one prototype share an instancer: all of them must fall on the same side.
    pub async fn set_light_links(
        &mut self,
        path: &str,
        illuminates: Option<Vec<String>>,
        shadowed_by: Option<Vec<String>>,
    ) -> Result<Vec<SentPrim>> {
        self.edit(|t| {
            let (light, shadow) = (crate::usd::link_collection_id(path, "lightLink"), crate::usd::link_collection_id(path, "shadowLink"));
            for_each_light(t, path, |l| {
                *l.light_link = illuminates.is_some().then(|| light.clone());
                *l.shadow_link = shadowed_by.is_some().then(|| shadow.clone());
            })?;
            relink(t, &light, illuminates.as_deref())?;
            relink(t, &shadow, shadowed_by.as_deref())
        })
        .await
    }

    /// Sets one input of one shader node of a material (`shader` is the node's path or its
    /// name under the material), as a float, a float3 or a string.
    pub async fn set_material_input(&mut self, material: &str, shader: &str, input: &str, value: ParamValue) -> Result<Vec<SentPrim>> {
        self.edit(|t| {
            let (_, net) =
                t.materials.iter_mut().find(|(p, _)| p == material).with_context(|| format!("{material}: no material with this path"))?;
            let full = format!("{material}/{shader}");
            let node = net
                .nodes
                .iter_mut()
                .find(|n| n.path == shader || n.path == full)
                .with_context(|| format!("{material}: no shader '{shader}' in its network"))?;
            node.parameters.insert(input.trim_start_matches("inputs:").to_string(), value);
            Ok(())
        })
        .await
    }
}

/// What a live edit may change of a light: its inputs and links.
struct LightFields<'t> {
    intensity: &'t mut f32,
    exposure: &'t mut f32,
    diffuse: &'t mut f32,
    specular: &'t mut f32,
    color: &'t mut Vec3,
    light_link: &'t mut Option<String>,
    shadow_link: &'t mut Option<String>,
}

/// Calls `edit` with the fields of the light at `path`: a UsdLux light's, or a mesh light's
/// (each of its parts when its GeomSubsets split it); an error when there is none.
fn for_each_light(t: &mut Translation, path: &str, mut edit: impl FnMut(LightFields)) -> Result<()> {
    if let Some((_, l)) = t.lights.iter_mut().find(|(p, _)| p == path) {
        let LightDesc { intensity, exposure, diffuse, specular, color, light_link, shadow_link, .. } = l;
        edit(LightFields { intensity, exposure, diffuse, specular, color, light_link, shadow_link });
        return Ok(());
    }
    let mut found = false;
    for (p, mesh) in t.meshes.iter_mut() {
        let Some(light) = mesh.light.as_mut().filter(|l| p == path || l.part_of.as_deref() == Some(path)) else { continue };
        let MeshLight { intensity, exposure, diffuse, specular, color, light_link, shadow_link, .. } = light;
        edit(LightFields { intensity, exposure, diffuse, specular, color, light_link, shadow_link });
        found = true;
    }
    anyhow::ensure!(found, "{path}: no light with this path");
    Ok(())
}

fn finite(prim: &str, name: &str, v: f64) -> Result<f64> {
    if !v.is_finite() {
        bail!("{prim}: {name} must be finite, got {v}");
    }
    Ok(v)
}

/// The affine transform of a row-major matrix (translation in the last column), refusing
/// non-finite entries and a projective last row.
fn affine_of(prim: &str, m: [[f64; 4]; 4]) -> Result<Affine3A> {
    if m.iter().flatten().any(|x| !x.is_finite()) {
        bail!("{prim}: the transform has a non-finite entry");
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        bail!("{prim}: the transform's last row must be 0 0 0 1 (row-major, translation in the last column)");
    }
    let cols = DMat4::from_cols_array_2d(&m).transpose();
    Ok(Affine3A::from_mat4(cols.as_mat4()))
}

fn kind_name(kind: i32) -> &'static str {
    match pb::PrimKind::try_from(kind) {
        Ok(pb::PrimKind::Mesh) => "mesh",
        Ok(pb::PrimKind::Instancer) => "instancer",
        Ok(pb::PrimKind::Material) => "material",
        Ok(pb::PrimKind::Light) => "light",
        Ok(pb::PrimKind::Camera) => "camera",
        Ok(pb::PrimKind::Texture) => "texture",
        Ok(pb::PrimKind::Volume) => "volume",
        Ok(pb::PrimKind::Remove) => "remove",
        _ => "unknown",
    }
}

fn dirty_names(bits: u32) -> Vec<&'static str> {
    if bits == pb::DirtyBits::DirtyAll as u32 {
        return vec!["all"];
    }
    let names = [
        (pb::DirtyBits::DirtyTransform, "transform"),
        (pb::DirtyBits::DirtyPoints, "points"),
        (pb::DirtyBits::DirtyTopology, "topology"),
        (pb::DirtyBits::DirtyNormals, "normals"),
        (pb::DirtyBits::DirtyMaterialId, "material_id"),
        (pb::DirtyBits::DirtyParams, "params"),
        (pb::DirtyBits::DirtyVisibility, "visibility"),
        (pb::DirtyBits::DirtyCategories, "categories"),
    ];
    names.into_iter().filter(|(b, _)| bits & (*b as u32) != 0).map(|(_, n)| n).collect()
}

/// What a list of sync items sends, prim by prim, with each prim's array chunks counted.
pub fn summarize(items: &[pb::sync_request::Item]) -> Vec<SentPrim> {
    let mut sent: Vec<SentPrim> = Vec::new();
    for item in items {
        match item {
            pb::sync_request::Item::Prim(d) => {
                sent.push(SentPrim { path: d.path.clone(), kind: kind_name(d.kind), dirty: dirty_names(d.dirty), chunks: 0 })
            }
            pb::sync_request::Item::Chunk(c) => {
                if let Some(p) = sent.iter_mut().rev().find(|p| p.path == c.path) {
                    p.chunks += 1;
                }
            }
        }
    }
    sent
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_major_matrices_put_translation_in_the_last_column() {
        let m = [[1.0, 0.0, 0.0, 2.0], [0.0, 1.0, 0.0, 3.0], [0.0, 0.0, 1.0, 4.0], [0.0, 0.0, 0.0, 1.0]];
        assert_eq!(affine_of("/a", m).unwrap().translation, glam::Vec3A::new(2.0, 3.0, 4.0));
        let mut bad = m;
        bad[3][0] = 1.0;
        assert!(affine_of("/a", bad).unwrap_err().to_string().contains("last row"));
        bad = m;
        bad[0][0] = f64::NAN;
        assert!(affine_of("/a", bad).unwrap_err().to_string().contains("/a: the transform has a non-finite entry"));
    }

    #[test]
    fn dirty_bits_are_named() {
        assert_eq!(dirty_names(pb::DirtyBits::DirtyAll as u32), ["all"]);
        assert_eq!(dirty_names(1 | 16 | 64), ["transform", "material_id", "visibility"]);
    }
}
