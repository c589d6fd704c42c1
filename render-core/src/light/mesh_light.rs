//! UsdLux `MeshLightAPI` (and `LightAPI` applied to a mesh): a mesh that is itself a light.
//!
//! Its triangles become triangle lights, as an emissive material's do, with the radiance of
//! the light's inputs: `color · intensity · 2^exposure`, divided by the mesh's world-space
//! area under `normalize` (UsdLux "Quantities and Units"), and tinted by the bound material's
//! glow where `light:materialSyncMode` asks for it. Unlike the schema's wording for the
//! camera (which sees "the material's glow"), camera and bounce rays see the same radiance
//! the light sends to next-event estimation: one emitter, one radiance, so MIS between the
//! two estimates stays unbiased.

use glam::Vec3;

/// What the mesh's bound material does (UsdLux `light:materialSyncMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaterialSync {
    /// The material's glow (its emission colour, white when it has none) tints the light,
    /// and the material reflects as usual: `MeshLightAPI`'s fallback.
    #[default]
    GlowTintsLight,
    /// The light's colour alone; the material reflects as usual and its own glow is not
    /// added on top.
    Independent,
    /// As if no material were bound: the mesh emits and neither reflects nor transmits.
    /// `LightAPI`'s fallback, so a mesh with plain `LightAPI` applied gets it.
    NoMaterialResponse,
}

/// The light inputs of a mesh light.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshLight {
    /// `inputs:intensity`.
    pub intensity: f32,
    /// `inputs:exposure`.
    pub exposure: f32,
    /// `inputs:color` (times the colour temperature's RGB when enabled).
    pub color: Vec3,
    /// `inputs:normalize`: divide by the mesh's world-space area.
    pub normalize: bool,
    /// `inputs:diffuse`: scales what diffuse lobes receive from the light.
    pub diffuse: f32,
    /// `inputs:specular`: scales what specular and transmission lobes receive.
    pub specular: f32,
    /// `light:materialSyncMode`.
    pub sync: MaterialSync,
    /// The link collection whose prims alone the light illuminates; None: every prim.
    pub light_link: Option<String>,
    /// The link collection whose prims alone cast its shadows; None: every prim.
    pub shadow_link: Option<String>,
    /// The mesh prim this mesh is a part of (the faces of one of its `GeomSubset`s, or the
    /// faces no subset claims); None: a whole mesh. A mesh's parts are one light: under
    /// `normalize` they divide by their summed area, not each by its own.
    pub part_of: Option<String>,
}

impl Default for MeshLight {
    /// `MeshLightAPI`'s fallbacks: intensity 1, white, not normalized, glow tints the light.
    fn default() -> Self {
        MeshLight {
            intensity: 1.0,
            exposure: 0.0,
            color: Vec3::ONE,
            normalize: false,
            diffuse: 1.0,
            specular: 1.0,
            sync: MaterialSync::GlowTintsLight,
            light_link: None,
            shadow_link: None,
            part_of: None,
        }
    }
}

impl MeshLight {
    /// The radiance each triangle emits, for a material whose glow is `glow` (black when it
    /// has none) on a mesh of world-space area `area`. Zero when the inputs are not finite.
    pub fn radiance(&self, glow: Vec3, area: f32) -> Vec3 {
        let tint = match self.sync {
            MaterialSync::GlowTintsLight if glow.max_element() > 0.0 => glow,
            _ => Vec3::ONE,
        };
        let per_area = if self.normalize && area > 0.0 { 1.0 / area } else { 1.0 };
        let l = self.color.max(Vec3::ZERO) * tint * (self.intensity * self.exposure.exp2() * per_area);
        if crate::math::is_finite(l) { l.max(Vec3::ZERO) } else { Vec3::ZERO }
    }

    /// The (diffuse, specular) multipliers, as [`super::Light::multipliers`] holds them.
    pub fn multipliers(&self) -> (f32, f32) {
        let m = |x: f32| if x.is_finite() { x.max(0.0) } else { 1.0 };
        (m(self.diffuse), m(self.specular))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// UsdLux units: intensity × 2^exposure × colour, over the area when normalized; the glow
    /// tints only in its own mode and only when there is one.
    #[test]
    fn radiance_follows_the_usdlux_units_and_the_sync_mode() {
        let light = MeshLight { intensity: 3.0, exposure: 1.0, color: Vec3::new(1.0, 0.5, 0.25), ..Default::default() };
        assert_eq!(light.radiance(Vec3::ZERO, 4.0), Vec3::new(6.0, 3.0, 1.5));
        assert_eq!(light.radiance(Vec3::new(0.5, 1.0, 2.0), 4.0), Vec3::new(3.0, 3.0, 3.0));
        let normalized = MeshLight { normalize: true, ..light.clone() };
        assert_eq!(normalized.radiance(Vec3::ZERO, 4.0), Vec3::new(1.5, 0.75, 0.375));
        for sync in [MaterialSync::Independent, MaterialSync::NoMaterialResponse] {
            let l = MeshLight { sync, ..light.clone() };
            assert_eq!(l.radiance(Vec3::new(0.5, 1.0, 2.0), 4.0), Vec3::new(6.0, 3.0, 1.5), "{sync:?}");
        }
        let broken = MeshLight { intensity: f32::INFINITY, ..light };
        assert_eq!(broken.radiance(Vec3::ONE, 1.0), Vec3::ZERO);
        assert_eq!(MeshLight { normalize: true, ..Default::default() }.radiance(Vec3::ZERO, 0.0), Vec3::ONE);
    }
}
