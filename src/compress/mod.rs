//! Compression of baked data: truncated SVD over the paper's matrix layouts.

pub mod layout;
pub mod svd;
