//! The features a scene calls for, found from its materials, instancers, lights and cameras,
//! with the prims that call for each. Light features are added by the lights step
//! (the commit's lights step), which knows which lights emit.

use super::SceneDesc;
use super::materials::Materials;
use crate::material::{Material, TexturedMaterial, Uber};
use crate::plan::{Feature, RenderPlan};

/// Whether a material (or its textures) calls for a feature.
type Asks<T> = fn(&T) -> bool;

/// What each material-borne feature asks of a material's lobes.
const LOBE_FEATURES: [(Feature, Asks<Uber>); 13] = [
    (Feature::Diffuse, |u| u.plastic.weight > 0.0 || (u.fabric.weight > 0.0 && u.fabric.params.specular < 1.0)),
    (Feature::Metal, |u| u.metal.weight > 0.0),
    (Feature::Transmission, |u| u.has_refraction()),
    (Feature::ThinTransmission, |u| u.glass.weight > 0.0 && u.glass.params.thin),
    (Feature::DiffuseTransmission, |u| u.plastic.weight > 0.0 && u.plastic.params.diffuse_transmission > 0.0),
    (Feature::Clearcoat, |u| u.clearcoat.weight > 0.0 && u.specular_control > 0.0),
    (Feature::Sheen, |u| {
        u.sheen.weight > 0.0 || u.fuzz.weight > 0.0 || (u.plastic.weight > 0.0 && u.plastic.params.disney_sheen.max_element() > 0.0)
    }),
    (Feature::Fabric, |u| u.fabric.weight > 0.0 && u.fabric.params.specular > 0.0),
    (Feature::Hair, |u| u.hair.weight > 0.0),
    (Feature::Glitter, |u| u.has_glitter()),
    (Feature::ThinFilm, |u| {
        use crate::bsdf::SpecularFresnel::{ThinFilm, ThinFilmConductor};
        let film_fresnel = (u.plastic.weight > 0.0 && u.plastic.params.specular.is_some_and(|s| matches!(s.fresnel, ThinFilm { .. })))
            || (u.metal.weight > 0.0 && matches!(u.metal.params.fresnel, ThinFilmConductor { .. }))
            || (u.has_refraction() && u.glass.params.film_thickness > 0.0);
        (u.thin_film.weight > 0.0 || film_fresnel) && u.specular_control > 0.0
    }),
    (Feature::DoubleSpecular, |u| {
        (u.metal.weight > 0.0 && u.metal.params.mix2 > 0.0)
            || (u.plastic.weight > 0.0 && u.plastic.params.specular.is_some_and(|s| s.mix2 > 0.0))
    }),
    (Feature::Anisotropy, |u| {
        (u.metal.weight > 0.0 && u.metal.params.anisotropic != 0.0)
            || (u.plastic.weight > 0.0 && u.plastic.params.specular.is_some_and(|s| s.anisotropic != 0.0))
            || (u.glass.weight > 0.0 && u.glass.params.anisotropic != 0.0)
    }),
];

/// What each texture feature asks of a textured material.
const TEXTURE_FEATURES: [(Feature, Asks<TexturedMaterial>); 5] = [
    (Feature::Textures, |_| true),
    (Feature::NormalMaps, |t| t.has_normal_map()),
    (Feature::BumpMaps, |t| t.has_bump()),
    (Feature::TexturedCutouts, |t| t.may_see_through()),
    (Feature::TexturedEmission, |t| t.emission_varies()),
];

/// The plan of everything but the lights: materials' lobes, textures, presence and media,
/// instancing, dome maps and thin-lens cameras.
pub(super) fn plan_of(desc: &SceneDesc, materials: &Materials) -> RenderPlan {
    let mut plan = RenderPlan::default();
    let materials_where =
        |pred: &dyn Fn(&Material) -> bool| -> Vec<String> { desc.materials.keys().filter(|m| pred(materials.at(m))).cloned().collect() };
    for (feature, pred) in LOBE_FEATURES {
        plan.call_for(feature, materials_where(&|m| pred(&m.surface)));
    }
    let displaced = desc.materials.iter().filter(|(path, network)| super::displace::amount_of(network, path, materials).is_some());
    plan.call_for(Feature::Displacement, displaced.map(|(path, _)| path.clone()));
    plan.call_for(Feature::PartialPresence, materials_where(&|m| m.pass_through > 0.0));
    plan.call_for(Feature::Subsurface, materials_where(&|m| m.medium().is_some()));
    for (feature, pred) in TEXTURE_FEATURES {
        plan.call_for(feature, desc.materials.keys().filter(|m| materials.textured_at(m).is_some_and(pred)).cloned());
    }
    plan.call_for(Feature::EnvironmentMap, materials.environments.keys().map(|p| p.to_string()));
    plan.call_for(Feature::Instancing, desc.instancers.keys().cloned());
    let thin_lens = desc.cameras.iter().filter(|(_, c)| !c.orthographic && c.f_stop > 0.0 && c.focus_distance > 0.0);
    plan.call_for(Feature::DepthOfField, thin_lens.map(|(p, _)| p.clone()));
    let moving_meshes = desc.meshes.iter().filter(|(_, m)| m.visible && (!m.motion.is_empty() || !m.mesh.deformation.is_empty()));
    let moving_cameras = desc.cameras.iter().filter(|(_, c)| !c.motion.is_empty());
    let moving_instancers = desc.instancers.iter().filter(|(_, i)| !i.motion.is_empty());
    let moving_lights = desc.lights.iter().filter(|(_, l)| !l.motion.is_empty());
    let moving_volumes = desc.volumes.iter().filter(|(_, v)| !v.motion.is_empty());
    let moving = moving_meshes.map(|(p, _)| p).chain(moving_instancers.map(|(p, _)| p)).chain(moving_cameras.map(|(p, _)| p));
    let moving = moving.chain(moving_lights.map(|(p, _)| p)).chain(moving_volumes.map(|(p, _)| p));
    plan.call_for(Feature::MotionBlur, moving.cloned());
    plan.call_for(Feature::Volumes, desc.volumes.keys().cloned());
    plan
}
