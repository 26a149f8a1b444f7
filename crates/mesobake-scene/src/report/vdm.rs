//! `mesobake report vdm`: what each knob of the view-dependent displacement map costs and
//! buys on a height-field scene, next to the GDM of the same detail. Each row changes one
//! knob of the scene's `vdm` settings (curvature count, view directions, bake method, rank,
//! quantization): the package's bytes, bake and compression seconds, the displacement
//! error compression adds (RMSE and silhouette flips against its own bake), and the CPU
//! render's PSNR, FLIP and mask against the ground truth with its time, and the real-time
//! frame time and PSNR where an adapter exists. The GDM row renders the scene's default GDM
//! package. With both bake methods in the sweep, the paper's bake is also measured against
//! the exact one on the scene's grid.

use crate::LoadedScene;
use crate::package::{ScenePackageParams, gdm_scene_package, input_identity};
use crate::preview::gdm_preview;
use crate::report::Steps;
use crate::report::accuracy::table;
use crate::report::plot::labelled_scatter;
use crate::technique::Technique;
use crate::vdm::{VdmSettings, relief_depth};
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::vdm::compress;
use mesobake_bake::package::vdm as vdm_package;
use mesobake_bake::vdm::compare::{VdmError, compare as compare_vdm};
use mesobake_bake::vdm::{self, Vdm, VdmMethod};
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::Gpu;
use mesobake_gpu::vdm_pipeline::VdmPreview;
use mesobake_render::gdm_lookup::package_lookup;
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::image::{Comparison, Image, compare};
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use mesobake_render::vdm_renderer::VdmRenderer;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The knobs the report turns, one at a time, around the scene's own `vdm` settings.
#[derive(Clone, Debug, PartialEq)]
pub struct VdmSweep {
    /// Curvature counts (over the scene's range).
    pub curvatures: Vec<u32>,
    /// View direction grids [Nθ, Nφ].
    pub directions: Vec<[u32; 2]>,
    /// Bake methods.
    pub methods: Vec<VdmMethod>,
    /// VDM ranks (the MVM keeps the scene's rank, or fewer).
    pub ranks: Vec<usize>,
    /// Number formats of the factors.
    pub quantizations: Vec<Quantization>,
    /// Real-time frames timed per row (0: none).
    pub frames: u32,
}

/// One row: a VDM setting, or the GDM.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VdmReportRow {
    /// `vdm` or `gdm`.
    pub technique: Technique,
    /// What the row changes from the scene's settings (`scene` for none).
    pub setting: String,
    /// The VDM settings (none for the GDM row).
    pub vdm: Option<VdmSettings>,
    /// Package bytes.
    pub bytes: u64,
    /// Seconds baking (and for a VDM, compressing) the package.
    pub bake_s: f64,
    /// RMS displacement error compression adds, over samples both call hits (tile units).
    pub rmse: Option<f64>,
    /// Fraction of samples whose silhouette decision compression flips.
    pub flip_rate: Option<f64>,
    /// The CPU render's seconds.
    pub cpu_s: f64,
    /// The CPU render against the truth.
    pub error: Comparison,
    /// Mean real-time frame time, ms (where an adapter exists).
    pub frame_ms: Option<f64>,
    /// The real-time image's PSNR against the truth, dB (where an adapter exists).
    pub realtime_psnr_db: Option<f64>,
}

/// The report on one scene.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VdmReport {
    /// The scene's name.
    pub scene: String,
    /// The real-time adapter, if any.
    pub adapter: Option<String>,
    /// Seconds the ground truth took.
    pub truth_s: f64,
    /// The paper's bake against the exact bake on the scene's grid (both methods swept).
    pub paper_against_exact: Option<VdmError>,
    /// The rows: the scene's settings first, then each knob, then the GDM.
    pub rows: Vec<VdmReportRow>,
}

/// The settings the sweep covers: the scene's, then each knob changed alone, labelled.
fn settings(base: VdmSettings, sweep: &VdmSweep) -> Vec<(String, VdmSettings)> {
    let mut out = vec![("scene".to_owned(), base)];
    let mut add = |label: String, s: VdmSettings| {
        if s != base {
            out.push((label, s));
        }
    };
    for &rank in &sweep.ranks {
        let mvm_rank = base.mvm_rank.min(rank);
        add(
            format!("rank {rank}"),
            VdmSettings {
                rank,
                mvm_rank,
                ..base
            },
        );
    }
    for &quantization in &sweep.quantizations {
        add(
            quantization.to_string(),
            VdmSettings {
                quantization,
                ..base
            },
        );
    }
    for &curvatures in &sweep.curvatures {
        add(
            format!("{curvatures} curvatures"),
            VdmSettings { curvatures, ..base },
        );
    }
    for &directions in &sweep.directions {
        let [t, p] = directions;
        add(format!("{t}×{p} views"), VdmSettings { directions, ..base });
    }
    for &method in &sweep.methods {
        add(
            format!("{} bake", method.name()),
            VdmSettings { method, ..base },
        );
    }
    out
}

/// Whether two settings share their bake (they differ only in compression).
fn same_bake(a: &VdmSettings, b: &VdmSettings) -> bool {
    a.grid() == b.grid() && a.params() == b.params()
}

/// Runs the sweep on `loaded` (a height-field scene named `name`, its files relative to
/// `dir`).
pub fn vdm_report(
    name: &str,
    loaded: &LoadedScene,
    dir: &Path,
    sweep: &VdmSweep,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<VdmReport> {
    let field = loaded.relief_field()?;
    let scene = &loaded.scene;
    let depth = relief_depth(&loaded.shell)?;
    let relief = vdm::Relief { field, depth };
    let input = input_identity(scene, dir)?;
    let gpu = if sweep.frames > 0 {
        Gpu::open(None).ok()
    } else {
        None
    };
    let settings = settings(scene.vdm, sweep);
    let total = settings.len() as u64 + 2;
    let mut steps = Steps::new(observer, total);
    let start = Instant::now();
    let truth = {
        let r = TruthRenderer::new(
            &loaded.shell,
            loaded.mesostructure.caster(),
            &loaded.material,
        );
        let shot = scene.shot();
        render_image(&shot.camera, |o, d| r.radiance(&shot, o, d))
    };
    let truth_s = start.elapsed().as_secs_f64();
    steps.step()?;
    let mut report = VdmReport {
        scene: name.to_owned(),
        adapter: gpu.as_ref().map(|g| g.adapter.name.clone()),
        truth_s,
        paper_against_exact: None,
        rows: Vec::new(),
    };
    // The scene's bake serves every setting that differs only in compression; any other
    // setting bakes its own, held for its row alone.
    let base = scene.vdm;
    let bake = |s: &VdmSettings| -> Result<(Vdm, f64)> {
        s.validate()?;
        let start = Instant::now();
        let baked = vdm::bake(relief, s.grid(), s.params(), limits, &())?;
        Ok((baked, start.elapsed().as_secs_f64()))
    };
    let (scene_vdm, scene_bake_s) = bake(&base)?;
    for (label, s) in &settings {
        let own;
        let (baked, bake_s) = if same_bake(&base, s) {
            (&scene_vdm, scene_bake_s)
        } else {
            own = bake(s)?;
            (&own.0, own.1)
        };
        if s.grid() == base.grid() {
            report.paper_against_exact = match (base.method, s.method) {
                (VdmMethod::Paper, VdmMethod::Exact) => Some(compare_vdm(&scene_vdm, baked)?),
                (VdmMethod::Exact, VdmMethod::Paper) => Some(compare_vdm(baked, &scene_vdm)?),
                _ => report.paper_against_exact.take(),
            };
        }
        let start = Instant::now();
        let compressed = compress(baked, s.rank, s.mvm_rank, s.quantization, limits)?;
        let compress_s = start.elapsed().as_secs_f64();
        let bytes = vdm_package::encode(input.clone(), field, baked, s.params(), &compressed);
        let query = compressed.decode();
        let renderer = VdmRenderer::new(&loaded.shell, &query, relief)?;
        let start = Instant::now();
        let shot = scene.shot();
        let image = render_image(&shot.camera, |o, d| renderer.radiance(&shot, o, d));
        let cpu_s = start.elapsed().as_secs_f64();
        let realtime = match &gpu {
            Some(gpu) => {
                let preview = VdmPreview::new(gpu, &shot, &loaded.shell, &query, relief)?;
                let frame = preview.time_frames(sweep.frames, &())?;
                Some((frame, preview.render()?))
            }
            None => None,
        };
        report.rows.push(row(
            (Technique::Vdm, label.clone(), Some(*s)),
            (bytes.len() as u64, bake_s + compress_s),
            Some((compressed.accuracy.rmse, compressed.accuracy.flip_rate)),
            (cpu_s, compare(&truth, &image)?),
            realtime,
            &truth,
        )?);
        steps.step()?;
    }
    report.rows.push(gdm_row(
        loaded,
        dir,
        sweep.frames,
        gpu.as_ref(),
        &truth,
        limits,
    )?);
    steps.step()?;
    Ok(report)
}

/// The GDM row: the scene's default GDM package, rendered by the GDM renderer.
fn gdm_row(
    loaded: &LoadedScene,
    dir: &Path,
    frames: u32,
    gpu: Option<&Gpu>,
    truth: &Image,
    limits: &Limits,
) -> Result<VdmReportRow> {
    let scene = &loaded.scene;
    let start = Instant::now();
    let package = gdm_scene_package(loaded, dir, ScenePackageParams::default(), limits, &())?;
    let bake_s = start.elapsed().as_secs_f64();
    let lookup = package_lookup(&package)?;
    let renderer =
        GdmRenderer::new(&loaded.shell, &*lookup, &loaded.material, 0).with_quality(scene.quality);
    let start = Instant::now();
    let shot = scene.shot();
    let image = render_image(&shot.camera, |o, d| renderer.radiance(&shot, o, d));
    let cpu_s = start.elapsed().as_secs_f64();
    let realtime = match gpu {
        Some(gpu) => {
            let (image, preview) = gdm_preview(gpu, loaded, &package, frames, &())?;
            Some((preview.mean_frame_seconds.unwrap_or(f64::NAN), image))
        }
        None => None,
    };
    row(
        (Technique::Gdm, "occupancy package".into(), None),
        (package.bytes().len() as u64, bake_s),
        None,
        (cpu_s, compare(truth, &image)?),
        realtime,
        truth,
    )
}

/// A row from what was measured: (technique, setting, VDM settings), (bytes, bake seconds),
/// compression's (RMSE, flip rate), (CPU seconds, CPU error), (frame seconds, real-time
/// image).
fn row(
    (technique, setting, vdm): (Technique, String, Option<VdmSettings>),
    (bytes, bake_s): (u64, f64),
    compression: Option<(f64, f64)>,
    (cpu_s, error): (f64, Comparison),
    realtime: Option<(f64, Image)>,
    truth: &Image,
) -> Result<VdmReportRow> {
    let (frame_ms, realtime_psnr_db) = match realtime {
        Some((frame_s, image)) => (Some(frame_s * 1e3), Some(compare(truth, &image)?.psnr_db)),
        None => (None, None),
    };
    Ok(VdmReportRow {
        technique,
        setting,
        vdm,
        bytes,
        bake_s,
        rmse: compression.map(|c| c.0),
        flip_rate: compression.map(|c| c.1),
        cpu_s,
        error,
        frame_ms,
        realtime_psnr_db,
    })
}

/// The report as Markdown: the truth's time and the paper's bake error above one table.
pub fn markdown(report: &VdmReport) -> String {
    let opt = |v: Option<f64>, digits: usize| v.map_or("—".into(), |v| format!("{v:.digits$}"));
    let cells = report.rows.iter().map(|r| {
        let (grid, compression) = match &r.vdm {
            Some(s) => (
                format!(
                    "{}×{} × {} c, {}",
                    s.directions[0],
                    s.directions[1],
                    s.curvatures,
                    s.method.name()
                ),
                format!("{} + {} {}", s.rank, s.mvm_rank, s.quantization),
            ),
            None => ("—".into(), "—".into()),
        };
        vec![
            r.technique.name().to_owned(),
            r.setting.clone(),
            grid,
            compression,
            r.bytes.to_string(),
            format!("{:.2}", r.bake_s),
            opt(r.rmse, 4),
            opt(r.flip_rate.map(|f| 100.0 * f), 3),
            format!("{:.2}", r.error.psnr_db),
            format!("{:.4}", r.error.flip_mean),
            format!("{:.3}", 100.0 * r.error.mask_disagreement),
            format!("{:.3}", r.cpu_s),
            opt(r.frame_ms, 1),
            opt(r.realtime_psnr_db, 2),
        ]
    });
    let paper = match &report.paper_against_exact {
        Some(e) => format!(
            " The paper's bake against the exact bake: RMSE {:.4} tile, maximum {:.3}, hit \
             disagreements {:.3} % of {} samples.",
            e.rmse,
            e.max_abs,
            100.0 * e.hit_disagreements as f64 / e.samples.max(1) as f64,
            e.samples
        ),
        None => String::new(),
    };
    format!(
        "Scene {}: ground truth {:.2} s. Real-time adapter: {}.{paper}\n\n{}",
        report.scene,
        report.truth_s,
        report.adapter.as_deref().unwrap_or("none"),
        table(
            &[
                "technique",
                "setting",
                "views × curvatures, bake",
                "ranks, format",
                "bytes",
                "bake + compress s",
                "RMSE (tile)",
                "flips %",
                "PSNR dB",
                "FLIP",
                "mask %",
                "CPU s",
                "frame ms",
                "real-time PSNR dB",
            ],
            cells,
        )
    )
}

/// An SVG plot: CPU render PSNR against the truth over package bytes, one labelled point per
/// row.
pub fn svg_plot(report: &VdmReport) -> Result<String> {
    use plotters::style::colors::{BLUE, RED};
    let points: Vec<_> = (report.rows.iter())
        .map(|r| {
            let colour = if r.technique == Technique::Gdm {
                RED
            } else {
                BLUE
            };
            (r.bytes as f64, r.error.psnr_db, r.setting.clone(), colour)
        })
        .collect();
    labelled_scatter(
        &format!("{}: PSNR against package bytes", report.scene),
        ("package bytes", "PSNR against the truth (dB)"),
        &points,
    )
}
