//! mesobake: an asset pipeline and baking server for mesostructure.
//!
//! This crate bakes generalized displacement maps (GDM) from tileable voxel volumes and mesh
//! tiles; see `ARCHITECTURE.md` for the map of the code and its invariants.

pub mod bench;
pub mod empty_space;
pub mod error;
pub mod flat_preview;
pub mod fsutil;
pub mod gdm;
pub mod grid;
pub mod input;
pub mod limits;
pub mod mesh_tile;
pub mod npy;
pub mod samples;
pub mod trimesh;
pub mod volume;
pub mod volume_format;

pub use error::{Error, Result};
