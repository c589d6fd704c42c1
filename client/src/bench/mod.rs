//! The renderer's benchmarks, run in-process (no server: the timings are the renderer's
//! own) by `tessera bench ...` and by the tests that hold their numbers: what each quality
//! knob costs and buys (`accuracy`), what the render plan saves (`effects`), many lights at
//! equal time (`lights`), on the shared harness (`harness`). The Mitsuba and Embree
//! anchors are in `client/benches/` and `render-core/benches/` (`cargo bench`).

pub mod accuracy;
pub mod effects;
pub mod harness;
pub mod lights;

pub use harness::Knobs;
