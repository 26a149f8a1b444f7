//! mesobake: an asset pipeline and baking server for mesostructure.
//!
//! This crate bakes generalized displacement maps (GDM) from tileable voxel volumes and mesh
//! tiles; see `ARCHITECTURE.md` for the map of the code and its invariants.
//!
//! ```
//! use mesobake::bake::gdm::{self, volume_caster::VolumeCaster};
//! use mesobake::grid::{DirectionGrid, Dims};
//! use mesobake_core::limits::Limits;
//! use mesobake::mesostructure::volume::Volume;
//!
//! // A floor: layer 0 of an 8×8×4 volume is solid.
//! let limits = Limits::default();
//! let volume = Volume::from_fn(Dims::new(8, 8, 4)?, &limits, |_, _, k| k == 0)?;
//! let dirs = DirectionGrid::new(2, 4)?; // θ = 45° (up) and 135° (down)
//! let g = gdm::exact::bake(&VolumeCaster::new(&volume), dirs, &limits, &())?;
//! // From the centre of layer 2 (z = 2.5), looking down at 45°, the floor (z = 1) is
//! // 1.5·√2 away; looking up, the ray escapes.
//! assert!((g.get(3, 3, 2, 1, 0) - 1.5 * 2f32.sqrt()).abs() < 1e-5);
//! assert!(g.get(3, 3, 2, 0, 0).is_infinite());
//! assert_eq!(g.get(3, 3, 0, 1, 0), 0.0);
//! # Ok::<(), mesobake::Error>(())
//! ```

pub mod bake;
pub mod bench;
pub mod client;
pub mod compress;
pub mod mesostructure;
pub mod package;
pub mod realtime;
pub mod render;
pub mod report;
pub mod scene;
pub mod server;
pub mod surface;

pub use mesobake_core::{Error, Result};
/// The sampling grids, shared with the package format (crate `mesobake-package`).
pub use mesobake_package::grid;
