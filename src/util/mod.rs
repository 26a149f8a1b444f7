//! Utilities every stage shares: atomic file writes ([`fs`]), the limits on what input may
//! allocate ([`limits`]) and `.npy` export ([`npy`]).

pub mod fs;
pub mod limits;
pub mod npy;
