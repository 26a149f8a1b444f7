//! Scene → image with the real-time pipeline (`mesobake preview`): renders a scene with its
//! package ([`crate::scene::package`]) on the GPU and optionally times frames.

use crate::error::Result;
use crate::package::Package;
use crate::realtime::gpu::{AdapterDescription, Gpu};
use crate::realtime::pipeline::Preview;
use crate::realtime::resources::GpuMemory;
use crate::realtime::variant::ShaderVariant;
use crate::render::image::Image;
use crate::scene::LoadedScene;
use serde::Serialize;
use std::time::Instant;

/// What a preview ran on, chose and measured.
#[derive(Clone, Debug, Serialize)]
pub struct PreviewReport {
    /// The adapter.
    pub adapter: AdapterDescription,
    /// The shader variant the scene's effects chose.
    pub variant: ShaderVariant,
    /// GPU memory per kind of resource.
    pub memory: GpuMemory,
    /// Seconds to upload the scene and build the pipeline.
    pub setup_seconds: f64,
    /// Seconds for the first frame, read-back included.
    pub first_frame_seconds: f64,
    /// Mean seconds per frame over the timed frames (none when no frames were timed).
    pub mean_frame_seconds: Option<f64>,
    /// Frames timed.
    pub frames: u32,
}

/// Renders `loaded` with `package` on `gpu`; with `frames` > 0, also times that many frames.
pub fn preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    package: &Package,
    frames: u32,
) -> Result<(Image, PreviewReport)> {
    let start = Instant::now();
    let preview = Preview::new(gpu, loaded, package, true)?;
    let setup_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let image = preview.render()?;
    let first_frame_seconds = start.elapsed().as_secs_f64();
    let mean_frame_seconds = if frames > 0 {
        Some(preview.time_frames(frames)?)
    } else {
        None
    };
    Ok((
        image,
        PreviewReport {
            adapter: preview.adapter().clone(),
            variant: preview.variant(),
            memory: preview.memory(),
            setup_seconds,
            first_frame_seconds,
            mean_frame_seconds,
            frames,
        },
    ))
}
