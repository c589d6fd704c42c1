//! Light linking in Hydra's form: a prim belongs to named link collections (Hydra's
//! "categories"), and a light may name one collection whose prims alone it illuminates
//! (UsdLux `collection:lightLink`) and one whose prims alone cast its shadows
//! (`collection:shadowLink`). A light that names none reaches, and is shadowed by, everything.
//!
//! Prims with the same collections share a group; each instance and volume knows its group, and
//! a group lists its collections sorted, so "does light L reach this point" is one search in a
//! short list. Memory grows with the collections the prims name, never with lights × prims.

use std::collections::HashMap;

use super::commit::EmitterRun;
use super::{InstanceData, SceneDesc};

/// The receiver group of a point that belongs to no link collection (and of every point when
/// the scene links nothing).
pub const NO_GROUP: u32 = 0;

/// Which lights reach which prims, and which prims cast which lights' shadows.
#[derive(Clone, Debug, Default)]
pub struct LightLinks {
    /// Per instance in the TLAS, its group.
    instance_group: Vec<u32>,
    /// Per volume (path order), its group.
    volume_group: Vec<u32>,
    /// Per group, the range of its collections in `members`.
    groups: Vec<(u32, u32)>,
    /// The groups' collection ids, each group's sorted.
    members: Vec<u32>,
    /// Per light (committed order), the collection whose prims alone it illuminates.
    light_link: Vec<Option<u32>>,
    /// Per light, the collection whose prims alone cast its shadows.
    shadow_link: Vec<Option<u32>>,
}

/// Interns collection names as ids and prims' collection lists as groups.
#[derive(Default)]
struct Interner<'d> {
    ids: HashMap<&'d str, u32>,
    groups: HashMap<Vec<u32>, u32>,
    links: LightLinks,
}

impl<'d> Interner<'d> {
    fn id(&mut self, name: &'d str) -> u32 {
        let next = self.ids.len() as u32;
        *self.ids.entry(name).or_insert(next)
    }

    /// The group of a prim in `collections`; ids of collections no light names are dropped, so
    /// prims that differ only in those share a group.
    fn group(&mut self, collections: impl Iterator<Item = &'d String>) -> u32 {
        let mut ids: Vec<u32> = collections.filter_map(|c| self.ids.get(c.as_str()).copied()).collect();
        ids.sort_unstable();
        ids.dedup();
        if ids.is_empty() {
            return NO_GROUP;
        }
        let next = self.links.groups.len() as u32;
        *self.groups.entry(ids).or_insert_with_key(|ids| {
            let start = self.links.members.len() as u32;
            self.links.members.extend_from_slice(ids);
            self.links.groups.push((start, self.links.members.len() as u32));
            next
        })
    }
}

impl LightLinks {
    /// The links of a committed scene: `lights` are the committed UsdLux lights' paths in
    /// order, `emitters` the runs of triangle lights that follow them (a mesh light's links
    /// each of its triangles; an emissive material's link nothing), `instances` the TLAS's
    /// instances with their prims' paths. None when no light names a collection.
    pub(super) fn build(
        desc: &SceneDesc,
        lights: &[String],
        emitters: &[EmitterRun],
        instances: &[InstanceData],
        prim_paths: &[String],
    ) -> Option<LightLinks> {
        let mut interner = Interner::default();
        interner.links.groups.push((0, 0)); // NO_GROUP
        let links_of = |path: &String| desc.lights.get(path).map(|l| (l.light_link.as_deref(), l.shadow_link.as_deref()));
        for (light, shadow) in lights.iter().filter_map(links_of) {
            let (l, s) = (light.map(|c| interner.id(c)), shadow.map(|c| interner.id(c)));
            interner.links.light_link.push(l);
            interner.links.shadow_link.push(s);
        }
        for run in emitters.iter().filter(|r| r.links.0.is_some() || r.links.1.is_some()) {
            let (l, s) = (run.links.0.as_deref().map(|c| interner.id(c)), run.links.1.as_deref().map(|c| interner.id(c)));
            // Lights between the linked runs link nothing.
            interner.links.light_link.resize(run.first as usize, None);
            interner.links.shadow_link.resize(run.first as usize, None);
            interner.links.light_link.extend(std::iter::repeat_n(l, run.count as usize));
            interner.links.shadow_link.extend(std::iter::repeat_n(s, run.count as usize));
        }
        if interner.ids.is_empty() {
            return None;
        }
        for inst in instances {
            let path = &prim_paths[inst.prim as usize];
            let own = desc.meshes.get(path).map(|m| &m.link_collections);
            // An instancer's instances belong to its collections and to its prototype's.
            let instancer = desc.instancers.get(path);
            let prototype = instancer.and_then(|i| desc.meshes.get(&i.prototype)).map(|m| &m.link_collections);
            let all = own.into_iter().chain(instancer.map(|i| &i.link_collections)).chain(prototype).flatten();
            let group = interner.group(all);
            interner.links.instance_group.push(group);
        }
        for volume in desc.volumes.values() {
            let group = interner.group(volume.link_collections.iter());
            interner.links.volume_group.push(group);
        }
        Some(interner.links)
    }

    /// How many receiver groups there are (group 0, [`NO_GROUP`], included).
    pub fn group_count(&self) -> usize {
        self.groups.len()
    }

    /// The group of the surface of instance `instance`.
    #[inline]
    pub fn instance_group(&self, instance: u32) -> u32 {
        self.instance_group.get(instance as usize).copied().unwrap_or(NO_GROUP)
    }

    /// The group of volume `volume`.
    #[inline]
    pub fn volume_group(&self, volume: usize) -> u32 {
        self.volume_group.get(volume).copied().unwrap_or(NO_GROUP)
    }

    /// True when `group` holds collection `id`.
    fn holds(&self, group: u32, id: u32) -> bool {
        let (start, end) = self.groups[group as usize];
        self.members[start as usize..end as usize].binary_search(&id).is_ok()
    }

    /// True when light `light` illuminates points of `group`.
    #[inline]
    pub fn illuminates(&self, light: usize, group: u32) -> bool {
        match self.light_link.get(light).copied().flatten() {
            None => true,
            Some(id) => self.holds(group, id),
        }
    }

    /// True when only some prims cast light `light`'s shadows.
    #[inline]
    pub fn shadow_linked(&self, light: usize) -> bool {
        self.shadow_link.get(light).is_some_and(Option::is_some)
    }

    /// True when instance `instance` casts light `light`'s shadows.
    #[inline]
    pub fn casts_shadow(&self, light: usize, instance: u32) -> bool {
        self.group_casts_shadow(light, self.instance_group(instance))
    }

    /// True when volume `volume` casts light `light`'s shadows.
    #[inline]
    pub fn volume_casts_shadow(&self, light: usize, volume: usize) -> bool {
        self.group_casts_shadow(light, self.volume_group(volume))
    }

    /// True when prims of `group` cast light `light`'s shadows: every group, unless the light
    /// has a shadow link.
    #[inline]
    fn group_casts_shadow(&self, light: usize, group: u32) -> bool {
        self.shadow_link.get(light).copied().flatten().is_none_or(|id| self.holds(group, id))
    }

    /// The lights (committed order) that link anything, for the plan: (light linked, shadow
    /// linked).
    pub fn linked(&self) -> impl Iterator<Item = (usize, bool, bool)> + '_ {
        let both = self.light_link.iter().zip(&self.shadow_link);
        both.enumerate().filter(|(_, (l, s))| l.is_some() || s.is_some()).map(|(i, (l, s))| (i, l.is_some(), s.is_some()))
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{Affine3A, Vec3};

    use super::*;
    use crate::geometry::Mesh;
    use crate::light::{LightDesc, LightKind};
    use crate::plan::Feature;
    use crate::scene::{BlasCache, InstancerDesc, MeshDesc, commit};

    fn mesh(visible: bool, collections: &[&str]) -> MeshDesc {
        let triangle = Mesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], indices: vec![[0, 1, 2]], ..Default::default() };
        MeshDesc {
            mesh: Arc::new(triangle),
            transform: Affine3A::IDENTITY,
            motion: Vec::new(),
            material: String::new(),
            visible,
            link_collections: collections.iter().map(|c| c.to_string()).collect(),
            light: None,
        }
    }

    fn light(light_link: Option<&str>, shadow_link: Option<&str>) -> LightDesc {
        let mut l = LightDesc::new(LightKind::Sphere { radius: 0.1 }, Affine3A::from_translation(Vec3::Z), 1.0);
        (l.light_link, l.shadow_link) = (light_link.map(str::to_string), shadow_link.map(str::to_string));
        l
    }

    /// Meshes and instancers in the collections lights name: prims whose collections differ
    /// only in one no light names share a group, an instancer's instances hold its collections
    /// and its prototype's, and each light reaches and is shadowed by exactly what it names.
    #[test]
    fn lights_reach_and_are_shadowed_by_the_prims_their_collections_hold() {
        let mut desc = SceneDesc::default();
        desc.meshes.insert("/A".into(), mesh(true, &["key"]));
        desc.meshes.insert("/B".into(), mesh(true, &["key", "unused"]));
        desc.meshes.insert("/C".into(), mesh(true, &[]));
        desc.meshes.insert("/Proto".into(), mesh(false, &["key"]));
        let transforms = vec![Affine3A::from_translation(Vec3::X * 3.0)];
        let instancer = InstancerDesc { prototype: "/Proto".into(), transforms, motion: Vec::new(), link_collections: vec!["rim".into()] };
        desc.instancers.insert("/Scatter".into(), instancer);
        desc.lights.insert("/Key".into(), light(Some("key"), None));
        desc.lights.insert("/Rim".into(), light(None, Some("rim")));
        desc.lights.insert("/Fill".into(), light(None, None));
        let scene = commit(&desc, &mut BlasCache::default()).unwrap();
        let links = scene.links.as_ref().expect("two lights link");
        // Instances: /A, /B, /C, then the instancer's; lights in path order: Fill, Key, Rim.
        let groups: Vec<u32> = (0..4).map(|i| links.instance_group(i)).collect();
        assert_eq!((groups[0] == groups[1], groups[2]), (true, NO_GROUP), "{groups:?}");
        let (fill, key, rim) = (0, 1, 2);
        let reached: Vec<bool> = groups.iter().map(|&g| links.illuminates(key, g)).collect();
        assert_eq!(reached, [true, true, false, true]);
        assert!(groups.iter().all(|&g| links.illuminates(fill, g) && links.illuminates(rim, g)));
        let shadowing: Vec<bool> = (0..4).map(|i| links.casts_shadow(rim, i)).collect();
        assert_eq!(shadowing, [false, false, false, true]);
        assert!((0..4).all(|i| links.casts_shadow(key, i)) && !links.shadow_linked(key) && links.shadow_linked(rim));
        assert_eq!(scene.plan.prims(Feature::LightLinking), ["/Key"]);
        assert_eq!(scene.plan.prims(Feature::ShadowLinking), ["/Rim"]);
    }

    /// A mesh light links each of its triangle lights (after the UsdLux lights and any
    /// emissive material's triangles, which link nothing), and the plan names it once.
    #[test]
    fn a_mesh_lights_triangles_reach_what_its_link_holds() {
        let mut desc = SceneDesc::default();
        let quad = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        };
        let linked = crate::light::MeshLight { light_link: Some("glow".into()), ..Default::default() };
        let glow = MeshDesc { mesh: Arc::new(quad), light: Some(linked), ..mesh(true, &[]) };
        desc.meshes.insert("/A".into(), mesh(true, &["glow"]));
        desc.meshes.insert("/C".into(), mesh(true, &[]));
        desc.meshes.insert("/Glow".into(), glow);
        desc.lights.insert("/Fill".into(), light(None, None));
        let scene = commit(&desc, &mut BlasCache::default()).unwrap();
        let links = scene.links.as_ref().expect("the mesh light links");
        // Lights: /Fill, then the glow's two triangles. Instances: /A, /C, /Glow.
        assert_eq!(scene.lights.lights.len(), 3);
        let (a, c) = (links.instance_group(0), links.instance_group(1));
        for triangle in [1, 2] {
            assert!(links.illuminates(triangle, a) && !links.illuminates(triangle, c), "triangle light {triangle}");
        }
        assert!(links.illuminates(0, a) && links.illuminates(0, c), "the fill links nothing");
        assert_eq!(scene.plan.prims(Feature::LightLinking), ["/Glow"]);
    }

    /// Collections alone link nothing: without a light that names one, the scene has no links
    /// and the plan no linking.
    #[test]
    fn collections_no_light_names_link_nothing() {
        let mut desc = SceneDesc::default();
        desc.meshes.insert("/A".into(), mesh(true, &["key"]));
        desc.lights.insert("/Fill".into(), light(None, None));
        let scene = commit(&desc, &mut BlasCache::default()).unwrap();
        assert!(scene.links.is_none());
        assert!(!scene.plan.features.has_any(&[Feature::LightLinking, Feature::ShadowLinking]));
    }
}
