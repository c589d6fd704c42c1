//! The materials step of commit: every network resolved (textured ones compiled for
//! per-point evaluation), the mip pyramids they and the dome lights read.

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use glam::Vec3;

use super::{BlasCache, MeshDesc, SceneDesc};
use crate::caustics::ShadowGlass;
use crate::light::MaterialSync;
use crate::light::environment::DomeMap;
use crate::material::{Material, Principled, ResolveReport, TexturedMaterial, VaryingInput};
use crate::texture::{ColorSpace, Texture};

/// The materials resolved: index 0 is the fallback for unbound meshes.
pub(super) struct Materials<'d> {
    /// Each material as seen from afar (a textured one with each texture at its mean).
    pub list: Vec<Material>,
    /// Per material, its inputs that vary over the surface, if any.
    pub textured: Vec<Option<Arc<TexturedMaterial>>>,
    /// Per material, the texture network its `displacement` reads, if any.
    pub displacements: Vec<Option<VaryingInput>>,
    /// Index in [`Self::list`] by material path.
    pub index: HashMap<&'d str, u32>,
    /// Dome light maps by light path.
    pub environments: BTreeMap<&'d str, Arc<DomeMap>>,
    /// The black material of mesh lights with no material response (UsdLux
    /// `noMaterialResponse`), when a mesh light asks for it.
    pub no_response: Option<u32>,
}

impl<'d> Materials<'d> {
    /// Resolves every material network (compiling the textured ones) and reads the dome
    /// lights' maps, building mip pyramids only for textures a material or dome reads; the
    /// cache keeps exactly those.
    pub(super) fn resolve(desc: &'d SceneDesc, cache: &mut BlasCache, warnings: &mut Vec<String>) -> Self {
        let pyramids = RefCell::new(HashMap::new());
        let source = |hash: &str, space: ColorSpace| -> Option<Arc<Texture>> {
            let key = (hash.to_string(), space);
            let known = cache.textures.get(&key).cloned().or_else(|| pyramids.borrow().get(&key).cloned());
            let t = match known {
                Some(t) => t,
                None => {
                    let image = desc.textures.get(hash)?;
                    let _span = tracing::info_span!("mipmap", hash, bytes = image.bytes()).entered();
                    Arc::new(Texture::new(image, space))
                }
            };
            pyramids.borrow_mut().insert(key, Arc::clone(&t));
            Some(t)
        };
        let mut out = Materials {
            list: vec![Material::preview_surface_default()],
            textured: vec![None],
            displacements: vec![None],
            index: HashMap::new(),
            environments: BTreeMap::new(),
            no_response: None,
        };
        for (path, network) in &desc.materials {
            let mut report = ResolveReport::default();
            let varying = TexturedMaterial::compile(network, path, &source, &mut report);
            out.displacements.push(VaryingInput::displacement(network, &source, &mut report));
            let (m, r) = match &varying {
                Some(t) => t.mean(),
                None => network.resolve(path),
            };
            report.warnings.extend(r.warnings);
            warnings.extend(report.warnings);
            out.index.insert(path.as_str(), out.list.len() as u32);
            out.list.push(m);
            out.textured.push(varying.map(Arc::new));
        }
        // Dome light maps, read as the materials' textures are (linear for float files), with
        // their distributions kept from the last commit when the texture is the same.
        let mut domes = HashMap::new();
        for (path, l) in &desc.lights {
            let Some(t) = &l.texture else { continue };
            match source(&t.hash, ColorSpace::Auto) {
                Some(tex) => {
                    let key = (t.hash.clone(), ColorSpace::Auto);
                    let dome = match cache.domes.get(&key).or_else(|| domes.get(&key)) {
                        Some(d) if Arc::ptr_eq(d.texture(), &tex) => Arc::clone(d),
                        _ => Arc::new(DomeMap::new(tex)),
                    };
                    domes.insert(key, Arc::clone(&dome));
                    out.environments.insert(path.as_str(), dome);
                }
                None => warnings.push(format!("{path}: texture '{}' is not on the server; the dome is its constant colour", t.source)),
            }
        }
        cache.textures = pyramids.into_inner();
        cache.domes = domes;
        let reflects_nothing = |m: &MeshDesc| m.light.as_ref().is_some_and(|l| l.sync == MaterialSync::NoMaterialResponse);
        if desc.meshes.values().any(reflects_nothing) {
            out.no_response = Some(out.list.len() as u32);
            // Black Lambert and no specular (F0 = 0.08 · specular = 0): nothing reflects.
            out.list.push(Material::principled(Principled { lambert: true, base_color: Vec3::ZERO, specular: 0.0, ..Default::default() }));
            out.textured.push(None);
            out.displacements.push(None);
        }
        out
    }

    /// The material mesh `mesh` at `prim` renders with: its bound one, or the black one of a
    /// mesh light with no material response.
    pub(super) fn for_mesh(&self, prim: &str, mesh: &MeshDesc) -> u32 {
        match (&mesh.light, self.no_response) {
            (Some(l), Some(black)) if l.sync == MaterialSync::NoMaterialResponse => black,
            _ => self.of(prim, &mesh.material),
        }
    }

    /// The material bound at `path` for prim `prim`, or the default where it is missing.
    pub(super) fn of(&self, prim: &str, path: &str) -> u32 {
        if path.is_empty() {
            return 0;
        }
        match self.index.get(path) {
            Some(&i) => i,
            None => {
                tracing::warn!(prim, material = path, "bound material is not in the scene; using the default");
                0
            }
        }
    }

    /// The material at `path`.
    pub fn at(&self, path: &str) -> &Material {
        &self.list[self.index[path] as usize]
    }

    /// True when material `path`'s subsurface medium lies behind a smooth boundary
    /// (roughness up to [`crate::caustics::SMOOTH_GLASS`]): full path tracing lights it only
    /// by chance.
    pub(super) fn smooth_behind(&self, path: &str) -> bool {
        ShadowGlass::of_medium_boundary(self.at(path)).is_some_and(|b| b.roughness <= crate::caustics::SMOOTH_GLASS)
    }

    /// Material `path`'s inputs that vary over the surface, if any.
    pub fn textured_at(&self, path: &str) -> Option<&TexturedMaterial> {
        self.textured[self.index[path] as usize].as_deref()
    }

    /// The texture network material `path`'s `displacement` reads, if any.
    pub(super) fn displacement_at(&self, path: &str) -> Option<&VaryingInput> {
        self.displacements[self.index[path] as usize].as_ref()
    }

    /// Materials with no effect on light (cut out, index-matched clear glass) remove their
    /// surfaces altogether; a textured material is cut out point by point, never as a whole.
    pub(super) fn removes_its_surfaces(&self, m: u32) -> bool {
        self.textured[m as usize].is_none() && self.list[m as usize].is_invisible()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::{LightDesc, LightKind};
    use crate::texture::{Image, TextureRef};

    /// A scene of one dome reading a 16 × 8 map of content `hash`, bright at texel `spot`.
    fn dome_scene(hash: &str, spot: usize) -> SceneDesc {
        let mut texels = vec![0.1f32; 16 * 8 * 3];
        texels[spot * 3..spot * 3 + 3].fill(50.0);
        let mut desc = SceneDesc::default();
        desc.textures.insert(hash.into(), Arc::new(Image::from_f32(16, 8, 3, &texels)));
        let mut dome = LightDesc::new(LightKind::Dome, glam::Affine3A::IDENTITY, 1.0);
        dome.texture = Some(TextureRef { hash: hash.into(), source: "sky.exr".into() });
        desc.lights.insert("/Sky".into(), dome);
        desc
    }

    /// Commits that read the same dome texture share its distribution (building it took 28 ms
    /// a commit for a 1 024 × 512 grid); a dome turned shares it too, a new texture builds its
    /// own, and the cache keeps only what the last commit read.
    #[test]
    fn commits_share_a_dome_maps_distribution_while_its_texture_is_the_same() {
        let mut cache = BlasCache::default();
        let mut warnings = Vec::new();
        let desc = dome_scene("sha256:a", 40);
        let first = Arc::clone(&Materials::resolve(&desc, &mut cache, &mut warnings).environments["/Sky"]);
        let again = Arc::clone(&Materials::resolve(&desc, &mut cache, &mut warnings).environments["/Sky"]);
        assert!(Arc::ptr_eq(&first, &again), "an unchanged dome builds its distribution again");
        let mut turned = dome_scene("sha256:a", 40);
        turned.lights.get_mut("/Sky").unwrap().transform = glam::Affine3A::from_rotation_y(1.0);
        let after_turn = Arc::clone(&Materials::resolve(&turned, &mut cache, &mut warnings).environments["/Sky"]);
        assert!(Arc::ptr_eq(&first, &after_turn), "a turn changes the placement, not the map");
        let other = dome_scene("sha256:b", 90);
        let new_map = Arc::clone(&Materials::resolve(&other, &mut cache, &mut warnings).environments["/Sky"]);
        assert!(!Arc::ptr_eq(&first, &new_map), "a new texture needs its own distribution");
        assert_eq!(cache.domes.len(), 1, "the cache keeps only the dome the last commit read");
        assert!(warnings.is_empty(), "{warnings:?}");
    }
}
