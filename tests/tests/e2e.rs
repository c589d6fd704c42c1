//! End-to-end tests: the real server on loopback, the real client, committed fixtures.
//! One binary (as ripgrep does) so the workspace links it once.

mod anisotropy;
mod aovs;
mod bump;
mod caustics;
mod conformance;
mod curves;
mod denoise;
mod displacement;
mod energy;
mod environment;
mod errors;
mod furnace;
mod fuzz;
mod grpc;
mod hard;
mod hostile;
mod images;
mod interactive;
mod light_linking;
mod light_units;
mod materials;
mod materialx;
mod memory;
mod mesh_lights;
mod motion;
mod points;
mod preview_surface;
mod sampling;
mod shared_build;
mod skinning;
mod subdivision;
mod textures;
mod usd;
mod volumes;
