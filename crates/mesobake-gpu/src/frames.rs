//! What the three real-time pipelines (GDM, VDM, media) share: each records and submits its
//! own frame into a [`Target`]; [`RealtimePipeline`] renders one frame with its read-back and
//! times a run of frames, the same way for all three.

use super::gpu::Gpu;
use super::resources::GpuMemory;
use super::target::Target;
use mesobake_core::error::Result;
use mesobake_core::observer::BakeObserver;
use mesobake_render::image::Image;
use std::time::Instant;

/// A real-time pipeline ready to draw frames of one shot.
pub trait RealtimePipeline {
    /// The device it runs on.
    fn gpu(&self) -> &Gpu;

    /// The target its frames fill.
    fn target(&self) -> &Target;

    /// Records one frame (and, with `read_back`, the copy of the target into its read-back
    /// buffer) and submits it.
    fn submit_frame(&self, read_back: bool);

    /// Moves the next frames' rays to `offset` in each pixel (from its top-left corner).
    fn set_subpixel(&self, offset: [f64; 2]);

    /// GPU memory per kind of resource.
    fn memory(&self) -> GpuMemory;

    /// Refuses a frame just read back that the adapter did not render whole (default:
    /// nothing to check).
    fn check_frame(&self) -> Result<()> {
        Ok(())
    }

    /// Renders one frame and reads it back.
    fn render(&self) -> Result<Image> {
        self.gpu()
            .checked("rendering", || self.submit_frame(true))?;
        let image = self.target().read(self.gpu())?;
        self.check_frame()?;
        Ok(image)
    }

    /// Mean seconds per frame over `frames` frames (after one warm-up frame), each submitted
    /// and waited for, reported to `observer` as it finishes.
    fn time_frames(&self, frames: u32, observer: &dyn BakeObserver) -> Result<f64> {
        let gpu = self.gpu();
        self.submit_frame(false);
        gpu.wait()?;
        let start = Instant::now();
        for frame in 1..=frames {
            self.submit_frame(false);
            gpu.wait()?;
            observer.progress(frame.into(), frames.into());
        }
        Ok(start.elapsed().as_secs_f64() / frames.max(1) as f64)
    }
}
