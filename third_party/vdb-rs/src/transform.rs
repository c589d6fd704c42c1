#[derive(Debug)]
pub enum Map {
    UniformScaleMap {
        scale_values: glam::DVec3,
        voxel_size: glam::DVec3,
        scale_values_inverse: glam::DVec3,
        inv_scale_sqr: glam::DVec3,
        inv_twice_scale: glam::DVec3,
    },
    ScaleTranslateMap {
        translation: glam::DVec3,
        scale_values: glam::DVec3,
        voxel_size: glam::DVec3,
        scale_values_inverse: glam::DVec3,
        inv_scale_sqr: glam::DVec3,
        inv_twice_scale: glam::DVec3,
    },
    /// OpenVDB's `AffineMap`, and its `UnitaryMap` (a rotation, stored as an affine map):
    /// index to world space as a matrix on column vectors.
    AffineMap { index_to_world: glam::DMat4 },
    /// OpenVDB's `TranslationMap`.
    TranslationMap { translation: glam::DVec3 },
}
