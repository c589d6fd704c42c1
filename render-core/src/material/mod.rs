//! Materials: node graphs as Hydra delivers them, resolved per material into one
//! uber-material parameter set, which builds a [`Bsdf`] holding only its non-zero lobes.
//!
//! The vertical slice maps UsdPreviewSurface's `diffuseColor` and `emissiveColor`; the
//! layered front-ends and the full lobe set arrive with the material issues, behind the
//! same interface: `resolve(network) -> Material`, then `Material::bsdf()`.

mod network;

pub use network::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue, ResolveReport};

use glam::Vec3;

use crate::bsdf::{Bsdf, Lambert, Lobe};

/// The uber-material parameter set of one material instance.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Diffuse reflectance (linear RGB, each in [0, 1]).
    pub diffuse: Vec3,
    /// Emitted radiance, in the same units as UsdLux radiance.
    pub emission: Vec3,
}

impl Default for Material {
    /// UsdPreviewSurface's defaults: diffuse 0.18 grey, no emission.
    fn default() -> Self {
        Material { diffuse: Vec3::splat(0.18), emission: Vec3::ZERO }
    }
}

impl Material {
    /// The lobes at a shading point; only non-zero lobes are added.
    pub fn bsdf(&self) -> Bsdf {
        let mut bsdf = Bsdf::default();
        if self.diffuse.max_element() > 0.0 {
            bsdf.push(Lobe::Lambert(Lambert { r: self.diffuse }));
        }
        bsdf
    }

    /// True when the material emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
