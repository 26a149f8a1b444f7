//! Global illumination: bi-scale radiance transfer. Spherical harmonics ([`sh`]), environment
//! lighting projected to SH ([`environment`]) and the macro-scale per-vertex transfer
//! ([`prt`]), the meso-scale radiance transfer volume ([`rtv`]) and its compression
//! ([`compressed_rtv`]). Shading a scene with them lives in `scene::gi`.

pub mod compressed_rtv;
pub mod environment;
pub mod prt;
pub mod rtv;
pub mod sh;
