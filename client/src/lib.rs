//! Tessera's client library: reads USD, syncs it to a render server over gRPC, assembles
//! the streamed tiles and writes EXR and PNG. The CLI (`tessera`) is a thin layer over it,
//! and a DCC plugin embeds the same library.

// `!(x > 0.0)` rejects NaN too, which is the point wherever it appears (as in render-core).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod commands;
pub mod denoise;
pub mod exit;
pub mod farm;
pub mod film;
pub mod fuzzing;
pub mod live;
pub mod output;
pub mod quality;
pub mod remote;
pub mod sync;
pub mod usd;
