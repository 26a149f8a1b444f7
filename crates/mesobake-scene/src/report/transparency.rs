//! `mesobake report transparency`: what the real-time algorithm of translucent media costs
//! and buys on a translucent scene. Every row renders the scene with the cells
//! ([`CellRenderer`]) and compares the image with the ground truth ([`MediumTruth`]) of the
//! scene as it is: the scene's own settings, each sample count per cell, exact integration,
//! (where the scene has shadows) each shadow method and shadow-map resolution and the same
//! without shadows, the real-time pipeline's other cell orders, and the medium package's
//! other number formats. Every row renders what its medium package delivers (the medium,
//! its mip-map where the row filters, quantized as the row says). With frames to time and an adapter, each row also renders with the WGSL
//! pipeline ([`MediumPreview`]): its mean frame time, and its image against the truth and
//! against its CPU twin. The time to find and order every pixel's cells (the per-pixel
//! sorted lists) on the CPU, and for each per-view sort the time to sort the cells once for
//! the view and the pixels it misorders, are measured on their own.

use crate::LoadedScene;
use crate::report::Steps;
use crate::report::accuracy::table;
use crate::report::plot::labelled_scatter;
use glam::DVec3;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::mesostructure::medium::Medium;
use mesobake_bake::package::manifest::InputInfo;
use mesobake_bake::package::medium::{self as medium_package, MediumPackage};
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::observer::BakeObserver;
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::Gpu;
use mesobake_gpu::medium_pipeline::MediumPreview;
use mesobake_render::image::{Comparison, Image, compare};
use mesobake_render::medium_cells::CellRenderer;
use mesobake_render::medium_settings::{
    CellIntegration, CellOrder, ShadowMethod, TransparencySettings,
};
use mesobake_render::medium_truth::MediumTruth;
use mesobake_render::render_image;
use serde::Serialize;
use std::time::Instant;

/// One row: a setting of the cells.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TransparencyRow {
    /// What the row changes from the scene (`scene` for nothing).
    pub setting: String,
    /// The integration.
    pub transparency: TransparencySettings,
    /// Whether the row shades shadows.
    pub shadows: bool,
    /// Bytes of the row's medium package.
    pub package_bytes: usize,
    /// The CPU render's seconds, building the shadow maps included.
    pub cpu_s: f64,
    /// Of those, the seconds building the shadow maps (none without maps).
    pub shadow_map_s: Option<f64>,
    /// The render against the truth.
    pub error: Comparison,
    /// The WGSL pipeline's mean seconds per frame (none without an adapter or frames).
    pub frame_s: Option<f64>,
    /// The WGSL image against the truth.
    pub realtime_error: Option<Comparison>,
    /// The WGSL image against the CPU render of the row (its specification).
    pub realtime_vs_cpu: Option<Comparison>,
}

/// What one per-view order costs and gets wrong for the scene's view.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewOrderMeasure {
    /// The order's name as scenes write it.
    pub order: &'static str,
    /// Seconds sorting the cells once (the order's work per frame).
    pub sort_s: f64,
    /// Cycles the sort broke.
    pub cycles_broken: usize,
    /// Pixels whose ray crosses two cells in the wrong order
    /// ([`CellMesh::misordered_pixels`](mesobake_render::medium_cells::CellMesh::misordered_pixels)).
    pub misordered_pixels: usize,
}

/// The report on one scene.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TransparencyReport {
    /// The scene's name.
    pub scene: String,
    /// Image size.
    pub pixels: [u32; 2],
    /// Cells (tetrahedra) in the shell.
    pub cells: usize,
    /// Seconds the ground truth took.
    pub truth_s: f64,
    /// Seconds finding and ordering the cells under every pixel (no integration).
    pub order_s: f64,
    /// Mean cells crossed per pixel that meets any.
    pub mean_crossings: f64,
    /// Each per-view order's sort for the scene's view.
    pub view_orders: Vec<ViewOrderMeasure>,
    /// The adapter the real-time rows ran on.
    pub adapter: Option<String>,
    /// The rows.
    pub rows: Vec<TransparencyRow>,
}

/// Measures `loaded` (a translucent scene): its settings, each of `samples` per cell, exact
/// integration, without shadows and in the other cell order; with `frames` > 0 and an
/// adapter, also the WGSL pipeline over that many frames per row.
pub fn transparency_report(
    name: &str,
    loaded: &LoadedScene,
    samples: &[u32],
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<TransparencyReport> {
    let medium = loaded.medium.as_ref().ok_or_else(|| {
        Error::InvalidParameter(format!(
            "report transparency: scene {name} has no translucent medium (a `medium` \
             mesostructure or a volume with an opacity channel)"
        ))
    })?;
    let base = loaded.scene.transparency;
    let mut settings = vec![("scene".to_owned(), base, true)];
    let mut add = |label: String, s: TransparencySettings, shadows: bool| {
        if !settings.iter().any(|&(_, t, sh)| t == s && sh == shadows) {
            settings.push((label, s, shadows));
        }
    };
    for &n in samples {
        let s = TransparencySettings {
            integration: CellIntegration::Samples,
            samples: n,
            ..base
        };
        s.validate()?;
        let plural = if n == 1 { "" } else { "s" };
        add(format!("{n} sample{plural}"), s, true);
    }
    let exact = TransparencySettings {
        integration: CellIntegration::Exact,
        ..base
    };
    add("exact".into(), exact, true);
    let shadows = loaded.scene.wants(Effect::Shadows);
    if shadows {
        add("no shadows".into(), base, false);
        let deep = |size, levels| TransparencySettings {
            shadows: ShadowMethod::DeepMap,
            shadow_map_size: size,
            shadow_levels: levels,
            ..base
        };
        let methods = [
            (
                "shadow rays",
                TransparencySettings {
                    shadows: ShadowMethod::Rays,
                    ..base
                },
            ),
            ("deep map", deep(base.shadow_map_size, base.shadow_levels)),
            ("coarse deep map", deep(128, 8)),
            ("fine deep map", deep(1024, 16)),
            (
                "depth map",
                TransparencySettings {
                    shadows: ShadowMethod::DepthMap,
                    ..base
                },
            ),
        ];
        for (label, s) in methods {
            add(label.into(), s, true);
        }
    }
    for order in CellOrder::ALL.into_iter().filter(|&o| o != base.order) {
        let s = TransparencySettings { order, ..base };
        add(format!("{} order", s.order_name()), s, true);
    }
    for q in Quantization::ALL {
        let s = TransparencySettings {
            quantization: q,
            ..base
        };
        add(format!("package {q}"), s, true);
    }
    let gpu = if frames > 0 {
        Gpu::open(None).ok()
    } else {
        None
    };
    let mut steps = Steps::new(observer, settings.len() as u64 + 2);
    let scene = &loaded.scene;
    let timed = |f: &dyn Fn() -> Image| {
        let start = Instant::now();
        let image = f();
        (image, start.elapsed().as_secs_f64())
    };
    let (truth, truth_s) = timed(&|| {
        let r = MediumTruth::new(&loaded.shell, medium);
        let shot = scene.shot();
        render_image(&shot.camera, |o, d| r.radiance(&shot, o, d))
    });
    steps.step()?;
    let cells = CellRenderer::new(&loaded.shell, medium, base);
    let (crossings, order_s) = timed(&|| {
        render_image(&scene.camera, |o, d| {
            let n = cells.cells().crossings(o, d, 0.0, f64::INFINITY).len();
            (n > 0).then_some(DVec3::splat(n as f64))
        })
    });
    let met: Vec<f64> = (crossings.rgb.iter().zip(&crossings.mask))
        .filter(|(_, hit)| **hit)
        .map(|(c, _)| f64::from(c[0]))
        .collect();
    let mean_crossings = met.iter().sum::<f64>() / met.len().max(1) as f64;
    steps.step()?;
    let mut rows = Vec::new();
    for (setting, transparency, shadows) in settings {
        let mut shaded = scene.clone();
        if !shadows {
            shaded.effects.retain(|&e| e != Effect::Shadows);
        }
        let map_s = std::cell::Cell::new(None);
        let (levels, package_bytes) = packaged(medium, transparency)?;
        let shot = shaded.shot();
        let (image, cpu_s) = timed(&|| {
            let r = CellRenderer::with_levels(&loaded.shell, &levels, transparency);
            if shaded.wants(Effect::Shadows) && transparency.shadows != ShadowMethod::Rays {
                let start = Instant::now();
                r.shadow_maps(&shot);
                map_s.set(Some(start.elapsed().as_secs_f64()));
            }
            render_image(&shot.camera, |o, d| r.radiance(&shot, o, d))
        });
        let (mut frame_s, mut realtime_error, mut realtime_vs_cpu) = (None, None, None);
        if let Some(gpu) = &gpu {
            shaded.transparency = transparency;
            let rendered = MediumPreview::new(
                gpu,
                &shot,
                CellRenderer::with_levels(&loaded.shell, &levels, transparency),
            )
            .and_then(|p| Ok((p.render()?, p)));
            match rendered {
                Ok((realtime, preview)) => {
                    frame_s = Some(preview.time_frames(frames, &())?);
                    realtime_error = Some(compare(&truth, &realtime)?);
                    realtime_vs_cpu = Some(compare(&image, &realtime)?);
                }
                // The adapter cannot run the row (the software driver's loop budget): a dash.
                Err(Error::LoopBudget { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        rows.push(TransparencyRow {
            setting,
            transparency,
            shadows: shaded.wants(Effect::Shadows),
            package_bytes,
            cpu_s,
            shadow_map_s: map_s.get(),
            error: compare(&truth, &image)?,
            frame_s,
            realtime_error,
            realtime_vs_cpu,
        });
        steps.step()?;
    }
    let view_orders = (CellOrder::ALL.into_iter())
        .filter_map(|order| {
            let sort = order.view_sort()?;
            let start = Instant::now();
            let view = cells.cells().view_order(&scene.camera, sort);
            let sort_s = start.elapsed().as_secs_f64();
            Some(ViewOrderMeasure {
                order: order.name(),
                sort_s,
                cycles_broken: view.cycles_broken,
                misordered_pixels: cells.cells().misordered_pixels(&scene.camera, &view.order),
            })
        })
        .collect();
    Ok(TransparencyReport {
        scene: name.to_owned(),
        pixels: [scene.camera.width, scene.camera.height],
        cells: cells.cells().len(),
        truth_s,
        order_s,
        mean_crossings,
        view_orders,
        adapter: gpu.map(|g| g.adapter.name),
        rows,
    })
}

/// The levels `medium`'s package for `settings` delivers (its mip-map where they filter,
/// quantized as they say), and the package's bytes.
fn packaged(medium: &Medium, settings: TransparencySettings) -> Result<(Vec<Medium>, usize)> {
    let coarser = match settings.mipmap {
        true => medium.coarser_levels(),
        false => Vec::new(),
    };
    let input = InputInfo {
        kind: "medium".into(),
        bytes: 0,
        blake3: blake3::hash(&[]).to_hex().to_string(),
    };
    let package = MediumPackage::parse(medium_package::encode(
        input,
        medium,
        &coarser,
        settings.quantization,
    ))?;
    Ok((
        medium_package::levels(&package, settings.mipmap)?,
        package.bytes().len(),
    ))
}

/// The report as Markdown: the truth's and the ordering's times above one table.
pub fn markdown(report: &TransparencyReport) -> String {
    let cells = report.rows.iter().map(|r| {
        let integration = match r.transparency.integration {
            CellIntegration::Exact => "exact".to_owned(),
            CellIntegration::Samples => format!("{} per cell", r.transparency.samples),
        };
        vec![
            r.setting.clone(),
            integration,
            shadow_setting(r),
            format!(
                "{} {:.2} MB",
                r.transparency.quantization,
                r.package_bytes as f64 / 1e6
            ),
            format!("{:.2}", r.error.psnr_db),
            format!("{:.4}", r.error.flip_mean),
            format!("{:.3}", 100.0 * r.error.mask_disagreement),
            format!("{:.3}", r.cpu_s),
            optional(r.shadow_map_s, 3),
            r.transparency.order_name().to_owned(),
            optional(r.frame_s.map(|s| s * 1e3), 1),
            optional(r.realtime_error.as_ref().map(|c| c.psnr_db), 2),
            optional(r.realtime_vs_cpu.as_ref().map(|c| c.psnr_db), 2),
            optional(
                r.realtime_vs_cpu
                    .as_ref()
                    .map(|c| 100.0 * c.mask_disagreement),
                3,
            ),
        ]
    });
    let view_orders: Vec<String> = (report.view_orders.iter())
        .map(|v| {
            format!(
                "{} {:.4} s ({} cycles broken, {} pixels misordered)",
                v.order, v.sort_s, v.cycles_broken, v.misordered_pixels
            )
        })
        .collect();
    format!(
        "Scene {} at {}×{}, {} cells: ground truth {:.2} s; finding and ordering every pixel's \
         cells {:.3} s ({:.1} cells per covered pixel); sorting the cells for the view once: \
         {}. Real-time columns: {}.\n\n{}",
        report.scene,
        report.pixels[0],
        report.pixels[1],
        report.cells,
        report.truth_s,
        report.order_s,
        report.mean_crossings,
        view_orders.join("; "),
        report
            .adapter
            .as_deref()
            .unwrap_or("not measured (no adapter, or --frames 0)"),
        table(
            &[
                "setting",
                "integration",
                "shadows",
                "package",
                "PSNR dB",
                "FLIP",
                "mask %",
                "CPU s",
                "of which maps s",
                "WGSL order",
                "frame ms",
                "WGSL PSNR dB",
                "WGSL vs CPU dB",
                "WGSL vs CPU mask %",
            ],
            cells,
        )
    )
}

/// A row's shadows: `no`, `rays`, or the map's method and resolution.
fn shadow_setting(r: &TransparencyRow) -> String {
    let t = &r.transparency;
    match (r.shadows, t.shadows) {
        (false, _) => "no".into(),
        (true, ShadowMethod::Rays) => "rays".into(),
        (true, ShadowMethod::DeepMap) => {
            format!("deep map {}² × {}", t.shadow_map_size, t.shadow_levels)
        }
        (true, ShadowMethod::DepthMap) => format!("depth map {}²", t.shadow_map_size),
    }
}

/// `value` with `digits` decimals, or a dash.
fn optional(value: Option<f64>, digits: usize) -> String {
    value.map_or("–".to_owned(), |v| format!("{v:.digits$}"))
}

/// An SVG plot: PSNR against the truth over CPU seconds, one labelled point per row.
pub fn svg_plot(report: &TransparencyReport) -> Result<String> {
    let points: Vec<_> = (report.rows.iter())
        .map(|r| {
            let label = r.setting.clone();
            (
                r.cpu_s.max(1e-4),
                r.error.psnr_db,
                label,
                plotters::style::colors::BLUE,
            )
        })
        .collect();
    labelled_scatter(
        &format!("{}: PSNR against CPU seconds", report.scene),
        ("CPU seconds", "PSNR against the truth (dB)"),
        &points,
    )
}
