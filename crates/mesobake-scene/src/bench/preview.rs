//! `mesobake bench preview`: the real-time pipeline's frame time against the CPU GDM software
//! renderer on the same scene and package, in the same run, over every GDM codec, quality
//! preset, image size and volume depth, with and without the early depth test.

use crate::package::{ScenePackageParams, gdm_scene_package};
use crate::preview::gdm_pipeline;
use crate::{LoadedScene, Scene};
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_core::quality::Preset;
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::{AdapterDescription, Gpu};
use mesobake_render::gdm_lookup::package_lookup;
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::render_image;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// One measured configuration.
#[derive(Clone, Debug, Serialize)]
pub struct PreviewBenchRow {
    /// The package's GDM codec.
    pub codec: GdmCodec,
    /// The quality preset.
    pub preset: Preset,
    /// Image side in pixels (square images).
    pub size: u32,
    /// Volume depth Z (layers).
    pub depth: u32,
    /// CPU GDM software renderer, seconds per image (rayon over all cores).
    pub cpu_seconds: f64,
    /// Real-time pipeline, mean seconds per frame.
    pub gpu_seconds: f64,
    /// The same without the early depth test (`None` where the adapter has none).
    pub gpu_seconds_without_early_z: Option<f64>,
}

/// Runs the benchmark on the scene at `scene_path` with the adapter named `adapter`.
#[allow(clippy::too_many_arguments)]
pub fn run(
    scene_path: &Path,
    presets: &[Preset],
    sizes: &[u32],
    depths: &[u32],
    frames: u32,
    adapter: Option<&str>,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<(AdapterDescription, Vec<PreviewBenchRow>)> {
    let gpu = Gpu::open(adapter)?;
    let base = Scene::read(scene_path)?;
    let dir = scene_path.parent().unwrap_or(Path::new("."));
    let mut rows = Vec::new();
    for &depth in depths {
        let mut scene = base.clone();
        scene.resolution[2] = depth;
        let mut loaded = LoadedScene::load(scene, dir, limits)?;
        for codec in GdmCodec::ALL {
            let params = ScenePackageParams {
                codec,
                ..ScenePackageParams::default()
            };
            let package = gdm_scene_package(&loaded, dir, params, limits, observer)?;
            let lookup = package_lookup(&package)?;
            for (&preset, &size) in presets
                .iter()
                .flat_map(|p| sizes.iter().map(move |s| (p, s)))
            {
                loaded.scene.quality = preset.quality();
                loaded.scene.camera.width = size;
                loaded.scene.camera.height = size;
                let scene = &loaded.scene;
                let start = Instant::now();
                let r = GdmRenderer::new(
                    &loaded.shell,
                    &*lookup,
                    &loaded.material,
                    scene.gdm_refinements,
                )
                .with_quality(scene.quality);
                let shot = scene.shot();
                render_image(&shot.camera, |o, d| r.radiance(&shot, o, d));
                let cpu_seconds = start.elapsed().as_secs_f64();
                let time = |early_z: bool| -> Result<(bool, f64)> {
                    let preview = gdm_pipeline(&gpu, &loaded, &package, early_z)?;
                    Ok((
                        preview.variant().is_some_and(|v| v.early_depth_test),
                        preview.time_frames(frames, &())?,
                    ))
                };
                let (has_early_z, gpu_seconds) = time(true)?;
                let gpu_seconds_without_early_z = if has_early_z {
                    Some(time(false)?.1)
                } else {
                    None
                };
                rows.push(PreviewBenchRow {
                    codec,
                    preset,
                    size,
                    depth,
                    cpu_seconds,
                    gpu_seconds,
                    gpu_seconds_without_early_z,
                });
            }
        }
    }
    Ok((gpu.adapter, rows))
}

/// The results as a Markdown table.
pub fn markdown(adapter: &AdapterDescription, rows: &[PreviewBenchRow]) -> String {
    let mut out = format!(
        "Adapter: {} ({}, {}, {})\n\n",
        adapter.name, adapter.backend, adapter.device_type, adapter.driver
    );
    out += "| codec | preset | image | Z | CPU GDM renderer (s) | real-time frame (ms) | FPS | CPU / real-time | frame without early-z (ms) |\n";
    out += "|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in rows {
        out += &format!(
            "| {} | {} | {size}×{size} | {} | {:.3} | {:.2} | {:.1} | {:.2} | {} |\n",
            r.codec,
            r.preset.name(),
            r.depth,
            r.cpu_seconds,
            r.gpu_seconds * 1e3,
            1.0 / r.gpu_seconds,
            r.cpu_seconds / r.gpu_seconds,
            r.gpu_seconds_without_early_z
                .map_or("—".to_owned(), |t| format!("{:.2}", t * 1e3)),
            size = r.size,
        );
    }
    out
}
