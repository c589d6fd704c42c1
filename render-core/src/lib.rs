//! Tessera's renderer as a library: scene commit, BVH, materials, lights, a progressive
//! unidirectional path tracer and the film it accumulates into.
//!
//! # Conventions
//!
//! * **Space and units.** World space is right-handed, in scene units, as USD authors it.
//!   Colours are linear Rec.709. Radiance values are UsdLux's: a light of intensity 1,
//!   exposure 0 and colour white seen head-on gives a pixel value of 1.
//! * **Directions.** In BSDF code both `wo` (towards the viewer / previous vertex) and `wi`
//!   (towards the light / next vertex) point *away* from the surface, in the local shading
//!   frame whose +Z is the shading normal (pbrt's convention).
//! * **Cosines.** `Lobe::eval` returns f(wo, wi) *without* the cosine factor; the integrator
//!   multiplies by |cos θi|. `LobeSample::weight` is f·|cos θi|/pdf.
//! * **Determinism.** A pixel's samples depend only on (seed, pixel, sample index); the film
//!   accumulates each pixel's samples in index order in f64, so images are bit-identical
//!   whatever the thread count or tile order.
//! * **Simulate only what the scene calls for.** [`scene::commit`] derives the scene's
//!   features and reports them as a [`plan::RenderPlan`].

#![deny(missing_docs)]
// `!(pdf > 0.0)` is the renderer's idiom for "not a usable positive number": unlike
// `pdf <= 0.0` it also rejects NaN, which is the point wherever it appears.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bsdf;
pub mod bvh;
pub mod camera;
pub mod caustics;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod motion;
pub mod plan;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod subsurface;
pub mod tangents;
pub mod texture;
pub mod volume;

pub use glam;
