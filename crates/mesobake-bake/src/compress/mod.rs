//! Compression of baked data: truncated SVD over the paper's matrix layouts, quantization of
//! the factors, and the accuracy it costs; and the occupancy codec, the GDM's exact
//! alternative.

pub mod accuracy;
pub mod gdm;
pub mod layout;
pub mod split;
pub mod svd;
pub mod tiled;
pub mod vdm;

/// The occupancy codec, part of the package format.
pub use mesobake_package::occupancy;
/// Quantization of the SVD factors, part of the package format.
pub use mesobake_package::quantize;
