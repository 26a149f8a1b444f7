//! `mesobake report conformance`: every scene × every technique it can use × every preset,
//! the real-time algorithm (its CPU specification, and the WGSL pipeline where an adapter
//! exists) against the supersampled ground truth, both sides at N samples per pixel, so that
//! the error measured is the algorithm's and not aliasing; the same at one sample per pixel
//! beside it; the CPU specification against the WGSL; and the bake, render and frame times.
//!
//! Techniques per scene: the one the scene chooses, and the GDM besides for every opaque
//! mesostructure (the GDM represents any). Settings ([`Setting`]): the GDM's three presets
//! (`render::quality`); the VDM at the scene's settings and at the paper's (the lookup alone,
//! the local shadow test); translucent media at the scene's settings and, where the scene
//! shadows them with maps, with shadows traced through the cells (the maps' reference).
//! Packages are the scene's defaults (the `occupancy` codec for the GDM).

use crate::package::{ScenePackageParams, gdm_scene_package, scene_package};
use crate::preview::{preview, render_on_cpu};
use crate::render::{MapSource, RenderMethod, render};
use crate::report::Steps;
use crate::report::accuracy::table;
use crate::technique::Technique;
use crate::{LoadedScene, Scene};
use mesobake_bake::package::AnyPackage;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_core::quality::{Preset, ShadowMethod};
use mesobake_core::samples_per_pixel::SamplesPerPixel;
use mesobake_gpu::gpu::Gpu;
use mesobake_render::image::{Comparison, Image, compare, difference};
use mesobake_render::medium_settings::ShadowMethod as MediumShadows;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The target at a technique's default preset, dB against the truth (both at N samples).
pub const DEFAULT_TARGET_DB: f64 = 25.0;

/// The target at a technique's best preset.
pub const BEST_TARGET_DB: f64 = 30.0;

/// One technique at one preset on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct ConformanceRow {
    /// The scene's name.
    pub scene: String,
    /// The technique (`gdm`, `vdm`, `transparency`).
    pub technique: &'static str,
    /// The setting: a GDM preset (`paper`, `balanced`, `high`), `scene` (the scene's own),
    /// the VDM's `paper` or the translucent media's `shadow rays` (see the module's
    /// documentation).
    pub preset: &'static str,
    /// Whether this is the scene's own technique at the scene's setting (what `preview`
    /// and the server render by default).
    pub is_default: bool,
    /// Seconds to bake the package.
    pub bake_s: f64,
    /// Seconds the CPU specification took at N samples per pixel.
    pub cpu_s: f64,
    /// The CPU specification at N samples against the truth at N.
    pub cpu: Comparison,
    /// The CPU specification at one sample against the truth at one.
    pub cpu_1spp: Comparison,
    /// The WGSL pipeline at N samples against the truth at N (where an adapter exists).
    pub gpu: Option<Comparison>,
    /// The WGSL pipeline against the CPU specification, both at N samples.
    pub agreement: Option<Comparison>,
    /// The WGSL pipeline's mean frame time at one sample per pixel, ms.
    pub frame_ms: Option<f64>,
    /// Why the adapter refused the WGSL pipeline (its loop budget), if it did.
    pub refused: Option<String>,
}

/// A scene's truths.
#[derive(Clone, Debug, Serialize)]
pub struct SceneTruth {
    /// The scene's name.
    pub scene: String,
    /// Its image size.
    pub width: u32,
    /// Its image size.
    pub height: u32,
    /// Seconds the truth took at N samples per pixel.
    pub seconds: f64,
    /// Seconds it took at one.
    pub seconds_1spp: f64,
}

/// The report.
#[derive(Clone, Debug, Serialize)]
pub struct ConformanceReport {
    /// Samples per pixel of the truth and the real-time images (N).
    pub samples_per_pixel: u32,
    /// The adapter of the WGSL rows, if any.
    pub adapter: Option<String>,
    /// The truths, a scene each.
    pub truths: Vec<SceneTruth>,
    /// The rows, scene by scene.
    pub rows: Vec<ConformanceRow>,
    /// Seconds the whole report took.
    pub seconds: f64,
}

/// What the report's rows are measured against, and what their contact sheet shows.
struct Truths {
    n: Image,
    one: Image,
}

/// A package to measure, with the settings to measure it at.
struct Candidate {
    technique: Technique,
    package: AnyPackage,
    bake_s: f64,
    settings: Vec<Setting>,
}

/// What a technique is measured at, besides its package.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Setting {
    /// One of the GDM's presets.
    Preset(Preset),
    /// The scene's own settings.
    Scene,
    /// The VDM as the paper renders it: the lookup alone, the local shadow test.
    VdmPaper,
    /// Translucent media shadowed by rays through the cells, the deep maps' reference.
    ShadowRays,
}

impl Setting {
    /// The settings a technique is measured at on `scene`: the GDM's presets; the scene's
    /// own and each other that changes it.
    fn all(technique: Technique, scene: &Scene) -> Vec<Setting> {
        let other = match technique {
            Technique::Gdm => return Preset::ALL.map(Setting::Preset).to_vec(),
            Technique::Vdm => Setting::VdmPaper,
            Technique::Transparency => Setting::ShadowRays,
            Technique::Auto => return vec![Setting::Scene],
        };
        let mut changed = scene.clone();
        other.apply(&mut changed);
        let mut out = vec![Setting::Scene];
        if changed != *scene {
            out.push(other);
        }
        out
    }

    /// Its name in the report.
    fn name(self) -> &'static str {
        match self {
            Setting::Preset(p) => p.name(),
            Setting::Scene => "scene",
            Setting::VdmPaper => "paper",
            Setting::ShadowRays => "shadow rays",
        }
    }

    /// Changes `scene` to it.
    fn apply(self, scene: &mut Scene) {
        match self {
            Setting::Preset(p) => scene.quality = p.quality(),
            Setting::Scene => {}
            Setting::VdmPaper => {
                scene.vdm.refine_texels = 0;
                scene.vdm.shadows = ShadowMethod::Local;
            }
            Setting::ShadowRays => {
                if scene.wants(Effect::Shadows) {
                    scene.transparency.shadows = MediumShadows::Rays;
                }
            }
        }
    }
}

/// Measures every scene of `scenes` (name, loaded scene, its folder) at `spp` samples per
/// pixel, timing `frames` WGSL frames per row where an adapter exists (`gpu`). Returns the
/// report and the contact sheet: per scene and technique at its default preset, the truth,
/// the real-time image (WGSL where there is an adapter, else the CPU specification) and
/// their difference, side by side.
pub fn conformance_report(
    scenes: &mut [(String, LoadedScene, &Path)],
    spp: SamplesPerPixel,
    gpu: Option<&Gpu>,
    frames: u32,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<(ConformanceReport, Image)> {
    let start = Instant::now();
    let mut steps = Steps::new(observer, scenes.len() as u64 * 6);
    let mut report = ConformanceReport {
        samples_per_pixel: spp.get(),
        adapter: gpu.map(|g| g.adapter.name.clone()),
        truths: Vec::new(),
        rows: Vec::new(),
        seconds: 0.0,
    };
    let mut sheet_rows: Vec<[Image; 3]> = Vec::new();
    for (name, loaded, dir) in scenes.iter_mut() {
        let camera = loaded.scene.camera;
        let at = |loaded: &mut LoadedScene, n: SamplesPerPixel| -> Result<()> {
            loaded.scene.camera = camera;
            loaded.scene.camera.set_samples_per_pixel(n)
        };
        let timed_truth = |loaded: &LoadedScene| -> Result<(Image, f64)> {
            let start = Instant::now();
            let r = render(loaded, RenderMethod::Truth, MapSource::Bake, limits, &())?;
            Ok((r.image, start.elapsed().as_secs_f64()))
        };
        at(loaded, spp)?;
        let (truth_n, seconds) = timed_truth(loaded)?;
        at(loaded, SamplesPerPixel::ONE)?;
        let (truth_1, seconds_1spp) = timed_truth(loaded)?;
        steps.step()?;
        report.truths.push(SceneTruth {
            scene: name.clone(),
            width: camera.width,
            height: camera.height,
            seconds,
            seconds_1spp,
        });
        let truths = Truths {
            n: truth_n,
            one: truth_1,
        };
        for candidate in candidates(loaded, dir, limits)? {
            steps.step()?;
            let own = loaded.scene.clone();
            for &setting in &candidate.settings {
                setting.apply(&mut loaded.scene);
                let is_default =
                    candidate.technique == loaded.technique().technique && loaded.scene == own;
                let measured = measure(loaded, &candidate, &truths, (spp, camera), gpu, frames);
                loaded.scene = own.clone();
                let (row, shown) = measured?;
                let row = ConformanceRow {
                    scene: name.clone(),
                    preset: setting.name(),
                    is_default,
                    ..row
                };
                if is_default {
                    let diff = difference(&truths.n, &shown)?;
                    sheet_rows.push([truths.n.clone(), shown, diff]);
                }
                report.rows.push(row);
            }
        }
        loaded.scene.camera = camera;
        steps.step()?;
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok((report, contact_sheet(&sheet_rows)))
}

/// The packages a scene is measured with: its own technique's, and the GDM's besides for an
/// opaque mesostructure.
fn candidates(loaded: &LoadedScene, dir: &Path, limits: &Limits) -> Result<Vec<Candidate>> {
    let scene = &loaded.scene;
    let start = Instant::now();
    let package = scene_package(loaded, dir, ScenePackageParams::default(), limits, &())?;
    let technique = Technique::of_package(&package);
    let mut out = vec![Candidate {
        technique,
        package,
        bake_s: start.elapsed().as_secs_f64(),
        settings: Setting::all(technique, scene),
    }];
    if loaded.medium.is_none() && out[0].technique != Technique::Gdm {
        let start = Instant::now();
        let package = gdm_scene_package(loaded, dir, ScenePackageParams::default(), limits, &())?;
        out.push(Candidate {
            technique: Technique::Gdm,
            package: AnyPackage::Gdm(package),
            bake_s: start.elapsed().as_secs_f64(),
            settings: Setting::all(Technique::Gdm, scene),
        });
    }
    Ok(out)
}

/// One row (its scene, preset and default flag left to fill) and the real-time image at N
/// samples that the contact sheet shows.
fn measure(
    loaded: &mut LoadedScene,
    candidate: &Candidate,
    truths: &Truths,
    (spp, camera): (SamplesPerPixel, mesobake_core::camera::Camera),
    gpu: Option<&Gpu>,
    frames: u32,
) -> Result<(ConformanceRow, Image)> {
    let package = &candidate.package;
    loaded.scene.camera = camera;
    let cpu_1 = render_on_cpu(loaded, package, &())?;
    loaded.scene.camera.set_samples_per_pixel(spp)?;
    let start = Instant::now();
    let cpu_n = render_on_cpu(loaded, package, &())?;
    let cpu_s = start.elapsed().as_secs_f64();
    let (mut gpu_n, mut frame_ms, mut refused) = (None, None, None);
    if let Some(gpu) = gpu {
        match preview(gpu, loaded, package, frames, &()) {
            Ok((image, report)) => {
                gpu_n = Some(image);
                frame_ms = report.mean_frame_seconds.map(|s| s * 1e3);
            }
            Err(e @ Error::LoopBudget { .. }) => refused = Some(e.to_string()),
            Err(e) => return Err(e),
        }
    }
    loaded.scene.camera = camera;
    let row = ConformanceRow {
        scene: String::new(),
        technique: candidate.technique.name(),
        preset: "",
        is_default: false,
        bake_s: candidate.bake_s,
        cpu_s,
        cpu: compare(&truths.n, &cpu_n)?,
        cpu_1spp: compare(&truths.one, &cpu_1)?,
        gpu: gpu_n.as_ref().map(|g| compare(&truths.n, g)).transpose()?,
        agreement: gpu_n.as_ref().map(|g| compare(&cpu_n, g)).transpose()?,
        frame_ms,
        refused,
    };
    Ok((row, gpu_n.unwrap_or(cpu_n)))
}

/// The rows' images side by side, rows stacked, on black, each cell as large as the largest
/// image.
fn contact_sheet(rows: &[[Image; 3]]) -> Image {
    let cell_w = rows.iter().flatten().map(|i| i.width).max().unwrap_or(1);
    let cell_h = rows.iter().flatten().map(|i| i.height).max().unwrap_or(1);
    let mut sheet = Image::new(3 * cell_w, (rows.len() as u32).max(1) * cell_h);
    for (r, row) in rows.iter().enumerate() {
        for (c, image) in row.iter().enumerate() {
            let (x0, y0) = (c as u32 * cell_w, r as u32 * cell_h);
            for y in 0..image.height {
                for x in 0..image.width {
                    let from = (y * image.width + x) as usize;
                    let to = ((y0 + y) * sheet.width + x0 + x) as usize;
                    sheet.rgb[to] = image.rgb[from];
                    sheet.mask[to] = true;
                }
            }
        }
    }
    sheet
}

/// Whether a scene's technique meets the targets: its default row at
/// [`DEFAULT_TARGET_DB`], its best row at [`BEST_TARGET_DB`] (the WGSL's figure where
/// measured, else the CPU specification's).
fn verdicts(report: &ConformanceReport) -> Vec<Vec<String>> {
    let psnr = |r: &ConformanceRow| r.gpu.map_or(r.cpu.psnr_db, |g| g.psnr_db);
    let mut groups: Vec<(&str, &str)> = report
        .rows
        .iter()
        .map(|r| (r.scene.as_str(), r.technique))
        .collect();
    groups.dedup();
    groups
        .into_iter()
        .map(|(scene, technique)| {
            let rows: Vec<&ConformanceRow> = (report.rows.iter())
                .filter(|r| r.scene == scene && r.technique == technique)
                .collect();
            let best = rows
                .iter()
                .max_by(|a, b| psnr(a).total_cmp(&psnr(b)))
                .expect("a group has rows");
            // The scene's own technique and quality; for a technique it does not use, that
            // technique's default (the paper's preset, or the scene's settings).
            let default = (rows.iter().find(|r| r.is_default)).or_else(|| {
                rows.iter()
                    .find(|r| r.preset == "paper" || r.preset == "scene")
            });
            let mark = |ok: bool| if ok { "yes" } else { "**no**" }.to_string();
            vec![
                scene.to_string(),
                technique.to_string(),
                default.map_or("—".into(), |r| format!("{:.2}", psnr(r))),
                mark(default.is_some_and(|r| psnr(r) >= DEFAULT_TARGET_DB)),
                format!("{:.2} ({})", psnr(best), best.preset),
                mark(psnr(best) >= BEST_TARGET_DB),
            ]
        })
        .collect()
}

/// The report as Markdown: the verdicts against the targets, then every row.
pub fn markdown(report: &ConformanceReport) -> String {
    let n = report.samples_per_pixel;
    let opt =
        |c: Option<Comparison>, f: fn(&Comparison) -> String| c.as_ref().map_or("—".into(), f);
    let db = |c: &Comparison| format!("{:.2}", c.psnr_db);
    let mut out = format!(
        "Real-time against the ground truth, both at {n} samples per pixel (PSNR over sRGB, \
         FLIP, hit/miss mask disagreement), and at 1 sample per pixel; WGSL on {}; \
         {:.0} s in all.\n\nTargets: ≥ {DEFAULT_TARGET_DB} dB at the default preset, \
         ≥ {BEST_TARGET_DB} dB at the best (the WGSL's figure where measured). WGSL \
         \"refused\": the adapter's loop budget cut the pipeline short (`refused` in the JSON \
         says where), so the CPU specification's figure stands.\n\n",
        report
            .adapter
            .as_deref()
            .unwrap_or("no adapter (CPU specification only)"),
        report.seconds
    );
    out += &table(
        &[
            "scene",
            "technique",
            "default dB",
            "≥ 25",
            "best dB (preset)",
            "≥ 30",
        ],
        verdicts(report),
    );
    out += "\n";
    let truth_s = |scene: &str| {
        (report.truths.iter())
            .find(|t| t.scene == scene)
            .map_or(f64::NAN, |t| t.seconds)
    };
    let cells = report.rows.iter().map(|r| {
        vec![
            r.scene.clone(),
            format!("{}{}", r.technique, if r.is_default { " *" } else { "" }),
            r.preset.to_string(),
            db(&r.cpu),
            format!("{:.4}", r.cpu.flip_mean),
            format!("{:.3}", 100.0 * r.cpu.mask_disagreement),
            match &r.refused {
                Some(_) => "refused".into(),
                None => opt(r.gpu, db),
            },
            db(&r.cpu_1spp),
            opt(r.agreement, db),
            opt(r.agreement, |c| {
                format!("{:.3}", 100.0 * c.mask_disagreement)
            }),
            format!("{:.2}", r.bake_s),
            format!("{:.2}", r.cpu_s),
            format!("{:.1}", truth_s(&r.scene)),
            r.frame_ms.map_or("—".into(), |t| format!("{t:.1}")),
        ]
    });
    let n_col = |s: &str| format!("{s} ({n} spp)");
    out += &table(
        &[
            "scene",
            "technique (* default)",
            "preset",
            &n_col("CPU dB"),
            "CPU FLIP",
            "CPU mask %",
            &n_col("WGSL dB"),
            "CPU dB (1 spp)",
            "CPU vs WGSL dB",
            "CPU vs WGSL mask %",
            "bake s",
            &n_col("CPU s"),
            &n_col("truth s"),
            "frame ms",
        ],
        cells,
    );
    out
}
