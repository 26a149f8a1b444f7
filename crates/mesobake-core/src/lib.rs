//! mesobake's core: what every layer shares and nothing above it defines. The one error type,
//! the limits on what input may allocate, atomic file writes, progress and cancellation, and
//! the vocabulary of a view (camera, samples per pixel, lights, material, effects, the
//! per-pixel algorithm's quality knobs). It knows nothing of scene files, bakes, renderers,
//! GPUs, HTTP or SQL.

pub mod camera;
pub mod color;
pub mod effect;
pub mod error;
pub mod fs;
pub mod light;
pub mod limits;
pub mod npy;
pub mod observer;
pub mod quality;
pub mod samples_per_pixel;

pub use error::{Error, Result};
