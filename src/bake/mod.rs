//! The bakes: precomputed visibility and light transport of a mesostructure. The
//! generalized displacement map ([`gdm`]) and the radiance transfer of global illumination
//! ([`gi`]: spherical harmonics, the macro-scale PRT, the radiance transfer volume). Each
//! knows nothing of scenes' cameras, files, HTTP or SQL.

pub mod gdm;
pub mod gi;
pub mod vdm;
