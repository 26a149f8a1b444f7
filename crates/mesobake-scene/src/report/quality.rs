//! `mesobake report quality`: what each accuracy knob of the per-pixel GDM algorithm
//! (`render::quality`) buys against the ground truth and what it costs in time, on several
//! scenes: every preset and every knob alone, rendered by the CPU specification (and, where
//! an adapter exists, by the real-time pipeline) from the scene's default package, against
//! the truth rendered once per scene. PSNR against time is the curve the user chooses on.

use crate::LoadedScene;
use crate::package::{ScenePackageParams, gdm_scene_package};
use crate::report::Steps;
use crate::report::accuracy::table;
use crate::report::plot::{plot_error, scene_panels};
use mesobake_bake::package::Package;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_core::quality::{Preset, Quality, ShadingFrame, ShadowMethod};
use mesobake_gpu::gpu::Gpu;
use mesobake_render::gdm_lookup::package_lookup;
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::image::compare;
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The settings the report covers by default: the presets, and each knob alone on the
/// paper's algorithm (chords at 2, 4 and 8).
pub fn default_settings() -> Vec<Quality> {
    let paper = Preset::Paper.quality();
    let mut settings = vec![paper];
    settings.push(Quality {
        shadows: ShadowMethod::Shell,
        ..paper
    });
    for chords in [2, 4, 8] {
        settings.push(Quality { chords, ..paper });
    }
    settings.push(Quality {
        frame: ShadingFrame::Jacobian,
        ..paper
    });
    settings.push(Preset::Balanced.quality());
    settings.push(Quality {
        chords: 4,
        ..Preset::High.quality()
    });
    settings.push(Preset::High.quality());
    settings
}

/// One setting on one scene.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct QualityRow {
    /// The scene's name.
    pub scene: String,
    /// The setting ([`Quality::label`]).
    pub quality: String,
    /// Seconds the CPU renderer took.
    pub cpu_s: f64,
    /// CPU render PSNR against the truth, dB (sRGB).
    pub psnr_db: f64,
    /// Mean ꟻLIP error of the CPU render against the truth.
    pub flip_mean: f64,
    /// Fraction of pixels whose hit/miss mask differs from the truth's.
    pub mask_disagreement: f64,
    /// Mean real-time frame time, ms (where an adapter exists).
    pub frame_ms: Option<f64>,
    /// Real-time image PSNR against the truth, dB (where an adapter exists).
    pub realtime_psnr_db: Option<f64>,
}

/// The report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct QualityReport {
    /// The adapter the real-time rows ran on, if any.
    pub adapter: Option<String>,
    /// Per scene: its name and the seconds its truth took.
    pub truths: Vec<(String, f64)>,
    /// Per scene, per setting.
    pub rows: Vec<QualityRow>,
}

/// Renders every setting of `settings` on every scene (`name`, loaded scene, its folder),
/// timing `frames` real-time frames per setting where an adapter exists (0: none). Each
/// scene's `quality` is left as it was.
pub fn quality_report(
    scenes: &mut [(String, LoadedScene, &Path)],
    settings: &[Quality],
    frames: u32,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<QualityReport> {
    for (name, loaded, _) in scenes.iter() {
        if loaded.scene.wants(Effect::EnvironmentLighting) {
            return Err(Error::InvalidParameter(format!(
                "scene {name}: the quality report covers point and directional light; \
                 environment lighting has its own report (report gi)"
            )));
        }
    }
    let gpu = if frames > 0 {
        Gpu::open(None).ok()
    } else {
        None
    };
    let total = (scenes.len() * (2 + settings.len())) as u64;
    let mut steps = Steps::new(observer, total);
    let mut report = QualityReport {
        adapter: gpu.as_ref().map(|g| g.adapter.name.clone()),
        truths: Vec::new(),
        rows: Vec::new(),
    };
    for (name, loaded, dir) in scenes.iter_mut() {
        let start = Instant::now();
        let truth = {
            let scene = &loaded.scene;
            let caster = loaded.mesostructure.caster();
            let truth_renderer = TruthRenderer::new(&loaded.shell, caster, &loaded.material);
            let shot = scene.shot();
            render_image(&shot.camera, |o, d| truth_renderer.radiance(&shot, o, d))
        };
        report
            .truths
            .push((name.clone(), start.elapsed().as_secs_f64()));
        steps.step()?;
        let package: Package =
            gdm_scene_package(loaded, dir, ScenePackageParams::default(), limits, &())?;
        let lookup = package_lookup(&package)?;
        steps.step()?;
        let scene_quality = loaded.scene.quality;
        for &quality in settings {
            quality.validate()?;
            let start = Instant::now();
            let image = {
                let scene = &loaded.scene;
                let r = GdmRenderer::new(
                    &loaded.shell,
                    &*lookup,
                    &loaded.material,
                    scene.gdm_refinements,
                )
                .with_quality(quality);
                let shot = scene.shot();
                render_image(&shot.camera, |o, d| r.radiance(&shot, o, d))
            };
            let cpu_s = start.elapsed().as_secs_f64();
            let c = compare(&truth, &image)?;
            let (frame_ms, realtime_psnr_db) = match &gpu {
                Some(gpu) => {
                    loaded.scene.quality = quality;
                    let result = crate::preview::gdm_preview(gpu, loaded, &package, frames, &());
                    loaded.scene.quality = scene_quality;
                    let (image, preview) = result?;
                    let c = compare(&truth, &image)?;
                    (preview.mean_frame_seconds.map(|s| s * 1e3), Some(c.psnr_db))
                }
                None => (None, None),
            };
            report.rows.push(QualityRow {
                scene: name.clone(),
                quality: quality.label(),
                cpu_s,
                psnr_db: c.psnr_db,
                flip_mean: c.flip_mean,
                mask_disagreement: c.mask_disagreement,
                frame_ms,
                realtime_psnr_db,
            });
            steps.step()?;
        }
    }
    Ok(report)
}

/// The report as Markdown: one table, the truth's time per scene above it.
pub fn markdown(report: &QualityReport) -> String {
    let opt = |v: Option<f64>, digits: usize| v.map_or("—".into(), |v| format!("{v:.digits$}"));
    let truth_of = |scene: &str| {
        report
            .truths
            .iter()
            .find(|(s, _)| s == scene)
            .map_or(f64::NAN, |t| t.1)
    };
    let cells = report.rows.iter().map(|r| {
        vec![
            r.scene.clone(),
            r.quality.clone(),
            format!("{:.2}", r.psnr_db),
            format!("{:.4}", r.flip_mean),
            format!("{:.3}", 100.0 * r.mask_disagreement),
            format!("{:.3}", r.cpu_s),
            format!("{:.3}", r.cpu_s / truth_of(&r.scene)),
            opt(r.frame_ms, 1),
            opt(r.realtime_psnr_db, 2),
        ]
    });
    let truths: Vec<String> = report
        .truths
        .iter()
        .map(|(s, t)| format!("{s} {t:.2} s"))
        .collect();
    format!(
        "Ground truth: {}. Real-time adapter: {}.\n\n{}",
        truths.join(", "),
        report.adapter.as_deref().unwrap_or("none"),
        table(
            &[
                "scene",
                "quality",
                "PSNR dB",
                "FLIP",
                "mask %",
                "CPU s",
                "CPU / truth time",
                "frame ms",
                "real-time PSNR dB",
            ],
            cells,
        )
    )
}

/// An SVG plot per scene: CPU render PSNR against the truth over CPU seconds, one point per
/// setting, labelled.
pub fn svg_plot(report: &QualityReport) -> Result<String> {
    use plotters::prelude::*;
    let scenes: Vec<&str> = report.truths.iter().map(|(s, _)| s.as_str()).collect();
    scene_panels(&scenes, |panel, scene| {
        let rows: Vec<&QualityRow> = report.rows.iter().filter(|r| r.scene == *scene).collect();
        let fold = |f: &dyn Fn(&QualityRow) -> f64| {
            rows.iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
                    (lo.min(f(r)), hi.max(f(r)))
                })
        };
        let (t_lo, t_hi) = fold(&|r| r.cpu_s);
        let (p_lo, p_hi) = fold(&|r| r.psnr_db);
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("{scene}: PSNR against CPU time"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d((t_lo * 0.8)..(t_hi * 1.25), (p_lo - 1.5)..(p_hi + 1.5))
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc("CPU render seconds")
            .y_desc("PSNR against the truth (dB)")
            .draw()
            .map_err(plot_error)?;
        chart
            .draw_series(rows.iter().map(|r| {
                EmptyElement::at((r.cpu_s, r.psnr_db))
                    + Circle::new((0, 0), 4, BLUE.filled())
                    + Text::new(r.quality.clone(), (6, -6), ("sans-serif", 12))
            }))
            .map_err(plot_error)?;
        Ok(())
    })
}
