//! Materials: node graphs as Hydra delivers them, resolved per material into one
//! uber-material parameter set, which builds a [`Bsdf`] holding only its non-zero lobes.
//!
//! Front-ends (UsdPreviewSurface, `tessera:Principled`) resolve to the principled
//! uber-material ([`Principled`]), whose `bsdf()` holds only its non-zero lobes. The layered
//! DreamWorks-style front-ends arrive with the layered-materials issue behind the same
//! interface: `resolve(network) -> Material`, then `Material::bsdf()`.

mod network;
mod principled;

pub use network::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue, ResolveReport};
pub use principled::Principled;

use glam::Vec3;

use crate::bsdf::Bsdf;

/// The uber-material parameter set of one material instance.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Material {
    /// Scattering.
    pub principled: Principled,
    /// Emitted radiance, in the same units as UsdLux radiance.
    pub emission: Vec3,
    /// Cut out everywhere: UsdPreviewSurface `opacity` below a positive `opacityThreshold`.
    /// With constant inputs (textures are not supported yet) that removes the whole surface,
    /// which then neither renders nor shadows.
    pub cut_out: bool,
}

impl Material {
    /// UsdPreviewSurface with every input at its specification default (diffuse 0.18,
    /// roughness 0.5, ior 1.5, no metal): the fallback of unbound meshes and of materials
    /// without a surface shader, as Hydra's fallback material is.
    pub fn preview_surface_default() -> Self {
        Material {
            principled: Principled { lambert: true, base_color: Vec3::splat(0.18), roughness: 0.5, specular: 0.5, ..Default::default() },
            emission: Vec3::ZERO,
            cut_out: false,
        }
    }

    /// The lobes at a shading point; `energy_compensation` switches the Kulla-Conty layer.
    pub fn bsdf(&self, energy_compensation: bool) -> Bsdf {
        self.principled.bsdf(energy_compensation)
    }

    /// True when the material has no effect on light at all, so its surfaces can be left
    /// out of the scene: cut out, or clear glass whose IOR is exactly 1 (an index-matched
    /// interface neither reflects nor bends, so dropping it is exact, shadows included).
    pub fn is_invisible(&self) -> bool {
        let p = self.principled.sanitized();
        let clear = p.transmission_color.unwrap_or(p.base_color) == Vec3::ONE;
        self.cut_out || (p.spec_trans == 1.0 && p.metallic == 0.0 && p.ior == 1.0 && clear && p.clearcoat == 0.0 && !self.is_emissive())
    }

    /// True when the material emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
