//! mesobake's real-time preview: the GDM pipeline of the paper in WGSL (`shaders/`), run
//! headless on wgpu (any adapter, including Mesa's software Vulkan driver). It renders the
//! same image as [`mesobake_render::gdm_renderer`], its executable specification, from a
//! package's textures uploaded as they are laid out. Like the CPU renderers, a pipeline reads
//! a [`mesobake_render::shot::Shot`], never a scene file; it knows nothing of HTTP or SQL.
//!
//! - [`gpu`]: adapter choice and device;
//! - [`variant`]: the shader variants, chosen from the shot's effects and knobs;
//! - [`resources`]: package, material and shell uploads, with the GPU memory they take;
//! - [`pipeline`]: the GDM pipeline, and the preview of several objects (GDM and VDM);
//! - [`frames`]: what every pipeline shares: a frame rendered and read back, frames timed;
//!   `view` (the view and light uniforms) and `bindings` (bind group plumbing) what they
//!   upload alike; `object_passes` what the passes of several objects share;
//! - [`target`]: the colour and depth target every pipeline draws into, and its read-back;
//! - [`vdm_pipeline`]: the VDM pipeline (height fields), whose specification is
//!   [`mesobake_render::vdm_renderer`];
//! - [`vdm_objects`]: a VDM object among several in the preview's shared targets;
//! - [`medium_pipeline`]: the translucent-media pipeline (semi-transparent 3D textures),
//!   whose specification is [`mesobake_render::medium_cells`].

mod bindings;
pub mod frames;
pub mod gpu;
pub mod medium_pipeline;
mod object_passes;
pub mod pipeline;
pub mod resources;
pub mod target;
pub mod variant;
pub mod vdm_objects;
pub mod vdm_pipeline;
mod view;
#[cfg(test)]
mod wgsl_twin;
