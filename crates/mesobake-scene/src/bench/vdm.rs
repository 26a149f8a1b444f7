//! `mesobake bench vdm`: VDM against GDM on one height-field scene, in the same run: the CPU
//! renderers' seconds per image and the real-time pipelines' frame times, and each image's
//! error against the ground truth (the height field cast exactly through the shell).

use crate::LoadedScene;
use crate::package::{ScenePackageParams, gdm_scene_package};
use crate::preview::gdm_pipeline;
use crate::render::load_scene;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::{AdapterDescription, Gpu};
use mesobake_gpu::vdm_pipeline::VdmPreview;
use mesobake_render::gdm_lookup::package_lookup;
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::image::{Comparison, compare};
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use mesobake_render::vdm_renderer::VdmRenderer;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// One technique at one image size.
#[derive(Clone, Debug, Serialize)]
pub struct VdmBenchRow {
    /// `gdm` (the default occupancy package) or `vdm` (the scene's VDM settings).
    pub technique: &'static str,
    /// Image side in pixels (square images).
    pub size: u32,
    /// Baking what the technique renders from, seconds.
    pub bake_seconds: f64,
    /// The CPU renderer, seconds per image (rayon over all cores).
    pub cpu_seconds: f64,
    /// The real-time pipeline, mean seconds per frame.
    pub gpu_seconds: f64,
    /// The ground truth's seconds for the same image.
    pub truth_seconds: f64,
    /// The CPU image against the truth.
    pub error: Comparison,
}

fn timed<T>(f: impl FnOnce() -> Result<T>) -> Result<(T, f64)> {
    let start = Instant::now();
    let value = f()?;
    Ok((value, start.elapsed().as_secs_f64()))
}

/// Runs the benchmark on the scene at `scene_path` (a height-field mesostructure) with the
/// adapter named `adapter`.
pub fn run(
    scene_path: &Path,
    sizes: &[u32],
    frames: u32,
    adapter: Option<&str>,
    limits: &Limits,
) -> Result<(AdapterDescription, Vec<VdmBenchRow>)> {
    let gpu = Gpu::open(adapter)?;
    let mut loaded: LoadedScene = load_scene(scene_path, limits)?;
    let dir = scene_path.parent().unwrap_or(Path::new("."));
    let (package, gdm_bake) =
        timed(|| gdm_scene_package(&loaded, dir, ScenePackageParams::default(), limits, &()))?;
    let lookup = package_lookup(&package)?;
    let (baked, vdm_bake) = timed(|| loaded.bake_vdm(limits, &()))?;
    let query = baked.compressed.decode();
    let relief = baked.relief();
    let mut rows = Vec::new();
    for &size in sizes {
        loaded.scene.camera.width = size;
        loaded.scene.camera.height = size;
        let scene = &loaded.scene;
        let shot = scene.shot();
        let camera = &shot.camera;
        let truth = TruthRenderer::new(
            &loaded.shell,
            loaded.mesostructure.caster(),
            &loaded.material,
        );
        let (truth_image, truth_seconds) =
            timed(|| Ok(render_image(camera, |o, d| truth.radiance(&shot, o, d))))?;
        let gdm = GdmRenderer::new(&loaded.shell, &*lookup, &loaded.material, 0)
            .with_quality(scene.quality);
        let (image, cpu_seconds) =
            timed(|| Ok(render_image(camera, |o, d| gdm.radiance(&shot, o, d))))?;
        let gpu_seconds = gdm_pipeline(&gpu, &loaded, &package, true)?.time_frames(frames, &())?;
        rows.push(VdmBenchRow {
            technique: "gdm",
            size,
            bake_seconds: gdm_bake,
            cpu_seconds,
            gpu_seconds,
            truth_seconds,
            error: compare(&truth_image, &image)?,
        });
        let vdm = VdmRenderer::new(&loaded.shell, &query, relief)?;
        let (image, cpu_seconds) =
            timed(|| Ok(render_image(camera, |o, d| vdm.radiance(&shot, o, d))))?;
        let gpu_seconds = VdmPreview::new(&gpu, &shot, &loaded.shell, &query, relief)?
            .time_frames(frames, &())?;
        rows.push(VdmBenchRow {
            technique: "vdm",
            size,
            bake_seconds: vdm_bake,
            cpu_seconds,
            gpu_seconds,
            truth_seconds,
            error: compare(&truth_image, &image)?,
        });
    }
    Ok((gpu.adapter, rows))
}

/// The results as a Markdown table.
pub fn markdown(adapter: &AdapterDescription, rows: &[VdmBenchRow]) -> String {
    let mut out = format!(
        "Adapter: {} ({}, {}, {})\n\n",
        adapter.name, adapter.backend, adapter.device_type, adapter.driver
    );
    out += "| technique | image | bake (s) | CPU image (s) | real-time frame (ms) | truth image (s) | PSNR (dB) | FLIP | mask |\n";
    out += "|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in rows {
        out += &format!(
            "| {} | {size}×{size} | {:.2} | {:.3} | {:.1} | {:.2} | {:.2} | {:.4} | {:.3} % |\n",
            r.technique,
            r.bake_seconds,
            r.cpu_seconds,
            r.gpu_seconds * 1e3,
            r.truth_seconds,
            r.error.psnr_db,
            r.error.flip_mean,
            100.0 * r.error.mask_disagreement,
            size = r.size,
        );
    }
    out
}
