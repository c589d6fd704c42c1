//! Materials: node graphs as Hydra delivers them, resolved per material into one
//! uber-material parameter set, which builds a [`Bsdf`] holding only its non-zero lobes.
//!
//! Every front-end resolves to the uber-material ([`Uber`]): UsdPreviewSurface and
//! `tessera:Principled` through Disney's parameters ([`Principled`]), the DreamWorks-style
//! `tessera:Metal`, `tessera:Refractive`, `tessera:SolidDielectric` and `tessera:Fabric`
//! directly ([`native`]), and `tessera:Layer` by blending two resolved materials
//! (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.2: parameter resolution, then closure creation).

mod desc;
pub mod glitter;
pub mod graph;
mod inputs;
mod mix;
pub mod native;
pub mod network;
mod preview;
mod principled;
pub mod uber;

pub use graph::{BUMP, ShadingPoint, TexturedMaterial, Tilt, VaryingInput};
pub use network::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue, ResolveReport, UDIM_TILES};
pub use principled::Principled;
pub use uber::Uber;

use uber::Mix;

use glam::Vec3;

use crate::bsdf::Bsdf;

/// The uber-material parameter set of one material instance.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Material {
    /// Scattering.
    pub surface: Uber,
    /// Emitted radiance, in the same units as UsdLux radiance.
    pub emission: Vec3,
    /// Cut out everywhere: UsdPreviewSurface `opacity` below a positive `opacityThreshold`.
    /// With constant inputs (textures are not supported yet) that removes the whole surface,
    /// which then neither renders nor shadows.
    pub cut_out: bool,
    /// Share of rays that pass the surface unbent, as if it were not there: UsdPreviewSurface
    /// `opacityMode` `presence` with `opacity` below 1 (partial coverage, like a sparse veil).
    pub pass_through: f32,
    /// Which way anisotropic lobes' first axis runs on the surface.
    pub tangent: Tangent,
}

/// Which way anisotropic lobes' first axis (GGX's αx, a fabric's threads) runs on a surface:
/// the shared `tangent` and `anisotropyRotation` inputs of Tessera's own shaders.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Tangent {
    /// Object-space direction, made perpendicular to the shading normal where shaded (a
    /// mesh's per-vertex tangents, through a primvar reader); zero: around the object's up
    /// axis ([`crate::math::Frame::from_normal_around`]).
    pub direction: Vec3,
    /// Turn about the normal, counter-clockwise, in fractions of a full turn (Cycles' and
    /// Standard Surface's specular rotation).
    pub rotation: f32,
    /// Without a `direction`, run along the mesh's dP/ds (where its texture coordinate s
    /// grows: MaterialX's default tangent) instead of around the object's up axis.
    pub along_st: bool,
}

impl Material {
    /// UsdPreviewSurface with every input at its specification default (diffuse 0.18,
    /// roughness 0.5, ior 1.5, no metal): the fallback of unbound meshes and of materials
    /// without a surface shader, as Hydra's fallback material is.
    pub fn preview_surface_default() -> Self {
        Material {
            surface: Principled::preview_surface_default().uber(),
            emission: Vec3::ZERO,
            cut_out: false,
            pass_through: 0.0,
            tangent: Tangent::default(),
        }
    }

    /// A material of Disney principled parameters.
    pub fn principled(p: Principled) -> Self {
        Material { surface: p.uber(), emission: Vec3::ZERO, cut_out: false, pass_through: 0.0, tangent: Tangent::default() }
    }

    /// The lobes at a shading point; `energy_compensation` switches the Kulla-Conty layer.
    pub fn bsdf(&self, energy_compensation: bool) -> Bsdf {
        self.surface.bsdf(energy_compensation)
    }

    /// "A over B" (`tessera:Layer`): `self` is B, `mask` A's coverage. Emission blends
    /// linearly; a cut-out follows the side that covers more.
    pub fn layered_under(&self, a: &Material, mask: f32) -> Material {
        let m = if mask.is_finite() { mask.clamp(0.0, 1.0) } else { 0.0 };
        Material {
            surface: self.surface.layered_under(&a.surface, m),
            emission: self.emission.lerp(a.emission, m),
            cut_out: if m > 0.5 { a.cut_out } else { self.cut_out },
            pass_through: self.pass_through.mix(1.0 - m, &a.pass_through, m),
            tangent: if m > 0.5 { a.tangent } else { self.tangent },
        }
    }

    /// `self` beneath the flakes of `glitter` (a resolved `tessera:Glitter`): the glitter's
    /// flakes over this material's families, coats and emission.
    pub fn under_glitter(&self, glitter: &Material) -> Material {
        let mut m = self.clone();
        m.surface.glitter = glitter.surface.glitter;
        m
    }

    /// True when the material has no effect on light at all, so its surfaces can be left
    /// out of the scene: cut out, or clear glass whose IOR is exactly 1 (an index-matched
    /// interface neither reflects nor bends, so dropping it is exact, shadows included) and
    /// without a film (which makes it a soap bubble's wall).
    pub fn is_invisible(&self) -> bool {
        let u = &self.surface;
        let g = &u.glass.params;
        let unfilmed = g.thin || !(g.film_thickness > 0.0);
        let clear_glass = u.glass.weight >= 1.0 && g.ior == 1.0 && (g.bend_ior == 1.0 || g.thin) && g.color == Vec3::ONE && unfilmed;
        self.cut_out
            || self.pass_through >= 1.0
            || (clear_glass
                && u.clearcoat.weight == 0.0
                && u.sheen.weight == 0.0
                && u.fuzz.weight == 0.0
                && !u.has_glitter()
                && !self.is_emissive())
    }

    /// The subsurface medium behind the surface, if any.
    pub fn medium(&self) -> Option<crate::subsurface::Medium> {
        self.surface.medium()
    }

    /// True when the material emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
