//! Renderers, real-time pipelines and scenes (`mesobake-render`, `mesobake-gpu`, `mesobake-scene`):
//! the CPU specifications against the truth and closed forms, the WGSL against its CPU twin on
//! every scene, GI, media, codecs, quality presets, supersampling. One test binary per crate under
//! test, so that the suite links few; one module per subject.

#[path = "../common/mod.rs"]
mod common;

mod codecs;
mod every_scene;
mod explicit_render;
mod gi;
mod gi_packages;
mod medium_package;
mod medium_preview;
mod medium_render;
mod objects;
mod objects_preview;
mod preview;
mod quality;
mod render;
mod supersampling;
mod vdm_render;
