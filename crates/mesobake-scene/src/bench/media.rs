//! `mesobake bench media`: the paper's largest translucent case (8 640 base triangles,
//! 25 920 tetrahedra, a 128×128×32 texture, 10 samples per cell) by default: the real-time
//! pipeline's frame time in each cell order against the CPU specification's seconds per
//! image in the same run, the per-view sort's share, and each WGSL image against the CPU's.

use crate::{LoadedScene, Scene};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::{AdapterDescription, Gpu};
use mesobake_gpu::medium_pipeline::MediumPreview;
use mesobake_render::image::{Comparison, compare};
use mesobake_render::medium_cells::CellRenderer;
use mesobake_render::medium_settings::{CellIntegration, CellOrder, TransparencySettings};
use mesobake_render::render_image;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The paper's largest case's cell count (on the torus-fur scene: a 96 × 45 torus, 8 640
/// triangles, with the medium on a 128×128×32 grid, `mesobake bench media`'s defaults).
pub const PAPER_CELLS: usize = 25_920;

/// One cell order at one image size.
#[derive(Clone, Debug, Serialize)]
pub struct MediaBenchRow {
    /// The cell order's name as scenes write it.
    pub order: &'static str,
    /// Image side in pixels (square images).
    pub size: u32,
    /// The CPU specification, seconds per image (rayon over all cores).
    pub cpu_seconds: f64,
    /// The real-time pipeline, mean seconds per frame (the per-view sort included); none
    /// where the adapter refused it ([`Error::LoopBudget`]).
    pub gpu_seconds: Option<f64>,
    /// Seconds sorting the cells for the view once (per-view orders only).
    pub sort_seconds: Option<f64>,
    /// Pixels whose ray crosses two cells in the wrong order, and the cycles the sort broke
    /// (per-view orders only).
    pub misordered: Option<(usize, usize)>,
    /// The WGSL image against the CPU specification's.
    pub wgsl_vs_cpu: Option<Comparison>,
    /// Why the adapter refused the row.
    pub refused: Option<String>,
}

/// What the benchmark ran on.
#[derive(Clone, Debug, Serialize)]
pub struct MediaBench {
    /// The adapter.
    pub adapter: AdapterDescription,
    /// Cells in the shell.
    pub cells: usize,
    /// The medium's grid.
    pub texture: [u32; 3],
    /// The integration measured.
    pub transparency: TransparencySettings,
    /// The rows.
    pub rows: Vec<MediaBenchRow>,
}

/// What to measure.
pub struct MediaBenchParams<'a> {
    /// The translucent scene; its base mesh must be a built-in torus.
    pub scene: &'a Path,
    /// The torus's segments.
    pub segments: [u32; 2],
    /// The medium's grid.
    pub texture: [u32; 3],
    /// Samples per cell (0: exact integration).
    pub samples: u32,
    /// Square image sizes.
    pub sizes: &'a [u32],
    /// Frames timed per row.
    pub frames: u32,
    /// The adapter whose name contains this.
    pub adapter: Option<&'a str>,
    /// Whether to shade shadows (where the scene asks for them).
    pub shadows: bool,
}

/// Runs the benchmark: the scene with the torus and grid of `params`, over its sizes and
/// both cell orders.
pub fn run(params: &MediaBenchParams, limits: &Limits) -> Result<MediaBench> {
    let gpu = Gpu::open(params.adapter)?;
    let scene_path = params.scene;
    let mut json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(scene_path).map_err(|e| Error::io(scene_path, e))?,
    )
    .map_err(|e| Error::Scene(format!("{}: {e}", scene_path.display())))?;
    let torus = json
        .pointer_mut("/base_mesh/builtin/torus")
        .ok_or_else(|| {
            Error::InvalidParameter(format!(
                "bench media: {} does not use a built-in torus",
                scene_path.display()
            ))
        })?;
    torus["segments"] = serde_json::json!(params.segments);
    json["resolution"] = serde_json::json!(params.texture);
    if !params.shadows {
        json["effects"] = serde_json::json!([]);
    }
    let scene = Scene::from_json(&json.to_string())?;
    let dir = scene_path.parent().unwrap_or(Path::new("."));
    let mut loaded = LoadedScene::load(scene, dir, limits)?;
    let (samples, sizes, frames) = (params.samples, params.sizes, params.frames);
    let medium = loaded.medium.clone().ok_or_else(|| {
        Error::InvalidParameter(format!(
            "bench media: {} has no translucent medium",
            scene_path.display()
        ))
    })?;
    let base = TransparencySettings {
        integration: if samples == 0 {
            CellIntegration::Exact
        } else {
            CellIntegration::Samples
        },
        samples: samples.max(1),
        ..loaded.scene.transparency
    };
    base.validate()?;
    let cpu = CellRenderer::new(&loaded.shell, &medium, base);
    let d = medium.dims();
    let mut rows = Vec::new();
    for &size in sizes {
        loaded.scene.camera.width = size;
        loaded.scene.camera.height = size;
        let start = Instant::now();
        let scene = &loaded.scene;
        let shot = scene.shot();
        let cpu_image = render_image(&shot.camera, |o, d| cpu.radiance(&shot, o, d));
        let cpu_seconds = start.elapsed().as_secs_f64();
        for order in CellOrder::ALL {
            let mut scene = loaded.scene.clone();
            scene.transparency = TransparencySettings { order, ..base };
            let mut row = MediaBenchRow {
                order: scene.transparency.order_name(),
                size,
                cpu_seconds,
                gpu_seconds: None,
                sort_seconds: None,
                misordered: order.view_sort().map(|sort| {
                    let view = cpu.cells().view_order(&scene.camera, sort);
                    let pixels = cpu.cells().misordered_pixels(&scene.camera, &view.order);
                    (pixels, view.cycles_broken)
                }),
                wgsl_vs_cpu: None,
                refused: None,
            };
            let rendered = MediumPreview::new(
                &gpu,
                &scene.shot(),
                CellRenderer::new(&loaded.shell, &medium, scene.transparency),
            )
            .and_then(|p| Ok((p.render()?, p)));
            match rendered {
                Ok((image, preview)) => {
                    row.gpu_seconds = Some(preview.time_frames(frames, &())?);
                    row.sort_seconds = preview.sort_seconds();
                    row.wgsl_vs_cpu = Some(compare(&cpu_image, &image)?);
                }
                Err(e @ Error::LoopBudget { .. }) => row.refused = Some(e.to_string()),
                Err(e) => return Err(e),
            }
            rows.push(row);
        }
    }
    Ok(MediaBench {
        adapter: gpu.adapter.clone(),
        cells: cpu.cells().len(),
        texture: [d.x, d.y, d.z],
        transparency: base,
        rows,
    })
}

/// The benchmark as Markdown: the setting above one table.
pub fn markdown(bench: &MediaBench) -> String {
    let a = &bench.adapter;
    let integration = match bench.transparency.integration {
        CellIntegration::Exact => "exact integration".to_owned(),
        CellIntegration::Samples => format!("{} samples per cell", bench.transparency.samples),
    };
    let mut out = format!(
        "Adapter: {} ({}, {}, {}); {} cells (the paper's largest case: {PAPER_CELLS}), texture \
         {}×{}×{}, {integration}\n\n",
        a.name,
        a.backend,
        a.device_type,
        a.driver,
        bench.cells,
        bench.texture[0],
        bench.texture[1],
        bench.texture[2],
    );
    out += "| order | image | CPU image (s) | real-time frame (ms) | per-view sort (ms) | misordered pixels | cycles broken | WGSL vs CPU PSNR (dB) | mask |\n";
    out += "|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    let ms = |s: Option<f64>| s.map_or("–".to_owned(), |s| format!("{:.1}", s * 1e3));
    for r in &bench.rows {
        let (psnr, mask) = r
            .wgsl_vs_cpu
            .as_ref()
            .map_or(("–".into(), "–".into()), |c| {
                (
                    format!("{:.2}", c.psnr_db),
                    format!("{:.3} %", 100.0 * c.mask_disagreement),
                )
            });
        let (misordered, cycles) = r.misordered.map_or(("–".into(), "–".into()), |(p, c)| {
            (p.to_string(), c.to_string())
        });
        out += &format!(
            "| {} | {size}×{size} | {:.3} | {} | {} | {misordered} | {cycles} | {psnr} | {mask} |\n",
            r.order,
            r.cpu_seconds,
            ms(r.gpu_seconds),
            ms(r.sort_seconds),
            size = r.size,
        );
    }
    for r in bench.rows.iter().filter(|r| r.refused.is_some()) {
        out += &format!(
            "\n{} order refused: {}\n",
            r.order,
            r.refused.as_deref().unwrap_or("")
        );
    }
    out
}
