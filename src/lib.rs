//! mesobake: an asset pipeline and baking server for mesostructure.
//!
//! The layers above the bakes (crate `mesobake-bake`), the CPU renderers (crate
//! `mesobake-render`) and the real-time preview (crate `mesobake-gpu`): scene files and their
//! pipelines, reports and benchmarks, and the server; see `ARCHITECTURE.md` for the map of the code and its invariants.

pub mod bench;
pub mod client;
pub mod report;
pub mod scene;
pub mod server;

pub use mesobake_core::{Error, Result};
/// The sampling grids, shared with the package format (crate `mesobake-package`).
pub use mesobake_package::grid;
