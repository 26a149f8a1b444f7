//! Compression of baked data: truncated SVD over the paper's matrix layouts, quantization of
//! the factors, and the accuracy it costs; and the occupancy codec, the GDM's exact
//! alternative.

pub mod accuracy;
pub mod gdm;
pub mod layout;
pub mod occupancy;
pub mod quantize;
pub mod split;
pub mod svd;
pub mod tiled;
