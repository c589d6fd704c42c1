//! Token constants for the [UsdProc](super) schema family.
//!
//! Mirrors Pixar's `pxr/usd/usdProc/tokens.h`.

// ── Concrete prim type names ────────────────────────────────────────
pub const T_GENERATIVE_PROCEDURAL: &str = "GenerativeProcedural";

// ── GenerativeProcedural attribute names ────────────────────────────
pub const A_PROCEDURAL_SYSTEM: &str = "proceduralSystem";
