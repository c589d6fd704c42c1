//! Linear blending of material parameters, which layering and glitter share.

/// Linear interpolation of parameters from `self` (weight `wa`) towards `other` (weight `wb`).
pub trait Mix: Sized {
    /// The blend; with `wa + wb = 0` it is `self`.
    fn mix(&self, wa: f32, other: &Self, wb: f32) -> Self;
}
