//! Global illumination: bi-scale radiance transfer. Spherical harmonics ([`sh`]), environment
//! lighting projected to SH ([`environment`]) and the macro-scale per-vertex transfer
//! ([`prt`]); the radiance transfer volume builds on them.

pub mod environment;
pub mod prt;
pub mod sh;
