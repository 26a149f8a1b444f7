//! `mesobake report codecs`: every GDM codec and size on the same scenes, against the same
//! ground truth. Per scene the truth and the exact uncompressed GDM are made once; then each
//! codec setting bakes the scene's package as `mesobake bake --scene` would, and is measured
//! on the samples (hit/escape flips and distance error of what the package answers, against
//! the exact GDM), on the CPU renderer's image (PSNR and mask against the truth, render time)
//! and, where an adapter exists, on the real-time pipeline (mean frame time, and its image
//! against the truth). The uncompressed GDM is the reference row: what the paper's algorithm
//! reaches with no compression at all. Two SVD-based GDM codecs are evaluated beside the
//! package codecs, on the CPU renderer only (neither is a package codec): blockwise SVD
//! (`tiled-svd`, [`compress_tiled`]) and the split GDM (`split-svd`, [`compress_split`]: the
//! primary query's distances capped at the scene's longest prism segment and compressed by
//! SVD, the shadow query's escape bits at a reduced direction resolution).

use crate::LoadedScene;
use crate::package::{ScenePackageParams, gdm_scene_package};
use crate::report::Steps;
use crate::report::accuracy::table;
use crate::report::plot::{plot_error, scene_panels};
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::split::{CAP_MARGIN, SplitGdm, compress_split};
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::compress::tiled::compress_tiled;
use mesobake_bake::gdm::{EscapeConvention, Gdm};
use mesobake_bake::package::bake::check_codec_options;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_gpu::gpu::Gpu;
use mesobake_package::grid::DirectionGrid;
use mesobake_render::gdm_lookup::{GdmLookup, RawLookup, SplitLookup, package_lookup};
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::image::compare;
use mesobake_render::prepared_prism::{longest_segment, prepare_prisms};
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use std::path::Path;
use std::time::Instant;

/// The settings the report covers: the occupancy codec, `paper-svd` at each rank, and the
/// evaluated SVD codecs.
#[derive(Clone, Debug, PartialEq)]
pub struct CodecSweep {
    /// `paper-svd` ranks.
    pub ranks: Vec<usize>,
    /// `paper-svd` and `tiled-svd` quantization.
    pub quantization: Quantization,
    /// `tiled-svd` tile sides in texels (each at every rank; none: no tiled rows).
    pub tiles: Vec<u32>,
    /// `split-svd` visibility direction grids (each at every rank, with the global basis and
    /// each of `tiles`; none: no split rows).
    pub visibility: Vec<DirectionGrid>,
    /// Real-time frames to time per setting (0: no real-time rows).
    pub frames: u32,
}

impl Default for CodecSweep {
    /// The defaults of `mesobake report codecs`: ranks 4, 8, 16 in f16, tiles of 16, escape
    /// bits at 4×8 and 8×16, 5 real-time frames.
    fn default() -> Self {
        CodecSweep {
            ranks: vec![4, 8, 16],
            quantization: Quantization::F16,
            tiles: vec![16],
            visibility: [(4, 8), (8, 16)]
                .map(|(n_theta, n_phi)| DirectionGrid { n_theta, n_phi })
                .to_vec(),
            frames: 5,
        }
    }
}

/// One codec setting on one scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CodecRow {
    /// The scene's file stem.
    pub scene: String,
    /// `occupancy`, `paper-svd`, `tiled-svd` or `split-svd` (evaluated, not package codecs)
    /// or `uncompressed` (the exact GDM as baked, f32).
    pub codec: String,
    /// The codec's settings but its rank (`f16`, `16×16 tiles f16`): rows of one series
    /// differ in rank only, and make one line of the plot.
    pub series: String,
    /// The rank, for the SVD-based codecs.
    pub rank: Option<usize>,
    /// The series and the rank: `16×16 tiles f16, rank 8`.
    pub setting: String,
    /// Bytes of the package (for `uncompressed`, of the f32 GDM).
    pub bytes: u64,
    /// Seconds to make it: the package's stages, or the exact bake.
    pub bake_s: f64,
    /// Fraction of the GDM's samples whose hit-or-escape answer differs from the exact GDM's
    /// (`split-svd`: hit within the cap or not).
    pub flip_rate: f64,
    /// Root-mean-square d − d_exact over the samples a primary query can reach (exact hits
    /// within the scene's distance cap) where both hit, voxels.
    pub hit_rmse: f64,
    /// `split-svd`, whose shadow queries have their own representation: the fraction of the
    /// GDM's samples where that representation's hit-or-escape answer differs from the exact
    /// GDM's. Other codecs answer shadow queries like the samples.
    pub shadow_flip_rate: Option<f64>,
    /// CPU GDM renderer: seconds for the image.
    pub render_s: f64,
    /// CPU image against the truth: PSNR (dB, sRGB).
    pub psnr_db: f64,
    /// CPU image against the truth: mean ꟻLIP error.
    pub flip_mean: f64,
    /// CPU image against the truth: fraction of pixels whose hit mask differs.
    pub mask_disagreement: f64,
    /// Real-time pipeline: mean milliseconds per frame (none without an adapter, and for
    /// `uncompressed`, which it cannot hold).
    pub frame_ms: Option<f64>,
    /// Real-time image against the truth: PSNR (dB).
    pub realtime_psnr_db: Option<f64>,
}

impl CodecRow {
    /// The plot line the row lies on: the codec and its series.
    pub fn line(&self) -> String {
        format!("{} {}", self.codec, self.series)
            .trim_end()
            .to_string()
    }
}

/// The report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CodecReport {
    /// The adapter the real-time rows ran on, if any.
    pub adapter: Option<String>,
    /// Per scene: its file stem and the seconds its ground truth took.
    pub truth_s: Vec<(String, f64)>,
    /// Per scene: its file stem and its distance cap, the longest texture-space segment a prism
    /// holds (voxels): the hit RMSE's reach and the `split-svd` rows' cap.
    pub caps: Vec<(String, f64)>,
    /// Per scene: uncompressed, occupancy, `paper-svd` by rank, `tiled-svd` by tile side and
    /// rank, then `split-svd` by visibility grid, basis and rank.
    pub rows: Vec<CodecRow>,
}

/// Runs the sweep on each of `scenes` (file stem, loaded scene, its directory), reporting
/// progress as (settings done, settings in all).
pub fn codec_report(
    scenes: &[(String, LoadedScene, &Path)],
    sweep: &CodecSweep,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<CodecReport> {
    for &k in &sweep.ranks {
        check_codec_options(GdmCodec::PaperSvd, Some(k), None)?;
    }
    let gpu = if sweep.frames > 0 {
        Gpu::open(None).ok()
    } else {
        None
    };
    // Each package setting with its rank.
    let settings: Vec<(ScenePackageParams, Option<usize>)> =
        std::iter::once((ScenePackageParams::default(), None))
            .chain(sweep.ranks.iter().map(|&k| {
                let params = ScenePackageParams {
                    codec: GdmCodec::PaperSvd,
                    rank: RankChoice::Rank(k),
                    quantization: sweep.quantization,
                };
                (params, Some(k))
            }))
            .collect();
    let quant = sweep.quantization;
    let tiled = sweep.tiles.len() * sweep.ranks.len();
    let split = sweep.visibility.len() * (1 + sweep.tiles.len()) * sweep.ranks.len();
    let total = (scenes.len() * (2 + settings.len() + tiled + split)) as u64;
    let mut steps = Steps::new(observer, total);
    let mut report = CodecReport {
        adapter: gpu.as_ref().map(|g| g.adapter.name.clone()),
        truth_s: Vec::new(),
        caps: Vec::new(),
        rows: Vec::new(),
    };
    for (name, loaded, dir) in scenes {
        let scene = &loaded.scene;
        let start = Instant::now();
        let caster = loaded.mesostructure.caster();
        let truth_renderer = TruthRenderer::new(&loaded.shell, caster, &loaded.material);
        let shot = scene.shot();
        let truth = render_image(&shot.camera, |o, d| truth_renderer.radiance(&shot, o, d));
        report
            .truth_s
            .push((name.clone(), start.elapsed().as_secs_f64()));
        steps.step()?;
        // One row: the CPU renderer's image with `lookup` against the truth, with the rest.
        let row = |(codec, series, rank): (&str, String, Option<usize>),
                   (bytes, bake_s): (u64, f64),
                   (flip_rate, hit_rmse): (f64, f64),
                   shadow_flip_rate: Option<f64>,
                   lookup: &dyn GdmLookup,
                   (frame_ms, realtime_psnr_db): (Option<f64>, Option<f64>)|
         -> Result<CodecRow> {
            let start = Instant::now();
            let r = GdmRenderer::new(
                &loaded.shell,
                lookup,
                &loaded.material,
                scene.gdm_refinements,
            )
            .with_quality(scene.quality);
            let shot = scene.shot();
            let image = render_image(&shot.camera, |o, d| r.radiance(&shot, o, d));
            let render_s = start.elapsed().as_secs_f64();
            let c = compare(&truth, &image)?;
            Ok(CodecRow {
                scene: name.clone(),
                codec: codec.into(),
                setting: match (rank, series.is_empty()) {
                    (Some(k), true) => format!("rank {k}"),
                    (Some(k), false) => format!("{series}, rank {k}"),
                    (None, _) => series.clone(),
                },
                series,
                rank,
                bytes,
                bake_s,
                flip_rate,
                hit_rmse,
                shadow_flip_rate,
                render_s,
                psnr_db: c.psnr_db,
                flip_mean: c.flip_mean,
                mask_disagreement: c.mask_disagreement,
                frame_ms,
                realtime_psnr_db,
            })
        };

        let start = Instant::now();
        let mut exact = loaded.bake_gdm(limits, &())?;
        exact.set_escape_convention(EscapeConvention::Infinite);
        let bake_s = start.elapsed().as_secs_f64();
        let dims = exact.dims();
        let cap = longest_segment(&prepare_prisms(&loaded.shell, dims)) as f32;
        report.caps.push((name.clone(), cap as f64));
        report.rows.push(row(
            ("uncompressed", "f32".into(), None),
            (exact.data().len() as u64 * 4, bake_s),
            (0.0, 0.0),
            None,
            &RawLookup::new(&exact),
            (None, None),
        )?);
        steps.step()?;

        for &(params, rank) in &settings {
            let start = Instant::now();
            let package = gdm_scene_package(loaded, dir, params, limits, &())?;
            let bake_s = start.elapsed().as_secs_f64();
            let bytes = package.bytes().len() as u64;
            let samples = sample_errors(&package.reconstruct(limits)?, &exact, cap);
            let realtime = match &gpu {
                Some(gpu) => {
                    let (image, preview) =
                        crate::preview::gdm_preview(gpu, loaded, &package, sweep.frames, &())?;
                    let c = compare(&truth, &image)?;
                    (preview.mean_frame_seconds.map(|s| s * 1e3), Some(c.psnr_db))
                }
                None => (None, None),
            };
            report.rows.push(row(
                (
                    params.codec.name(),
                    rank.map_or(String::new(), |_| quant.to_string()),
                    rank,
                ),
                (bytes, bake_s),
                samples,
                None,
                &*package_lookup(&package)?,
                realtime,
            )?);
            steps.step()?;
        }

        let mut boundary = exact.clone();
        boundary.set_escape_convention(EscapeConvention::Boundary);
        for &tile in &sweep.tiles {
            for &rank in &sweep.ranks {
                let start = Instant::now();
                let t = compress_tiled(&boundary, tile, rank, sweep.quantization, limits)?;
                let bake_s = bake_s + start.elapsed().as_secs_f64();
                report.rows.push(row(
                    (
                        "tiled-svd",
                        format!("{tile}×{tile} tiles {quant}"),
                        Some(rank),
                    ),
                    (t.bytes(), bake_s),
                    sample_errors(&t.reconstruction, &exact, cap),
                    None,
                    &RawLookup::new(&t.reconstruction),
                    (None, None),
                )?);
                steps.step()?;
            }
        }

        let within_cap = capped(&exact, cap)?;
        let bases = std::iter::once(dims.x).chain(sweep.tiles.iter().copied());
        for &grid in &sweep.visibility {
            let shadow =
                mesobake_bake::gdm::exact::bake(loaded.mesostructure.caster(), grid, limits, &())?;
            for tile in bases.clone() {
                let basis = if tile == dims.x {
                    "global basis".to_string()
                } else {
                    format!("{tile}×{tile} tiles")
                };
                let series = format!(
                    "{basis} {quant}, escape bits {}×{}",
                    grid.n_theta, grid.n_phi
                );
                for &rank in &sweep.ranks {
                    let start = Instant::now();
                    let split = compress_split(
                        &boundary,
                        cap,
                        (tile, rank, sweep.quantization),
                        &shadow,
                        limits,
                    )?;
                    let bake_s = bake_s + start.elapsed().as_secs_f64();
                    report.rows.push(row(
                        ("split-svd", series.clone(), Some(rank)),
                        (split.bytes(), bake_s),
                        sample_errors(&split.primary.reconstruction, &within_cap, cap),
                        Some(shadow_flips(&split, &exact)),
                        &SplitLookup::new(&split),
                        (None, None),
                    )?);
                    steps.step()?;
                }
            }
        }
    }
    Ok(report)
}

/// `exact` (escapes +∞) with the distances a split GDM capped at `cap` reads as escapes.
fn capped(exact: &Gdm, cap: f32) -> Result<Gdm> {
    let values = exact
        .data()
        .iter()
        .map(|&d| {
            if d >= cap - CAP_MARGIN {
                f32::INFINITY
            } else {
                d
            }
        })
        .collect();
    Gdm::from_values(
        exact.dims(),
        exact.dirs(),
        EscapeConvention::Infinite,
        values,
    )
}

/// The fraction of `exact`'s samples (escapes +∞) whose escape answer `split`'s shadow query
/// gets wrong, asked at the sample's position and direction.
fn shadow_flips(split: &SplitGdm, exact: &Gdm) -> f64 {
    use rayon::prelude::*;
    let lookup = SplitLookup::new(split);
    let (dims, dirs) = (exact.dims(), exact.dirs());
    let stride = exact.direction_stride();
    let flips: u64 = exact
        .data()
        .par_chunks(stride)
        .enumerate()
        .map(|(d, volume)| {
            let v = glam::DVec3::from_array(dirs.vector_of(d));
            let mut flips = 0u64;
            for k in 0..dims.z {
                for j in 0..dims.y {
                    for i in 0..dims.x {
                        let t = glam::DVec3::new(i as f64, j as f64, k as f64) + 0.5;
                        let escapes = volume[dims.index(i, j, k)].is_infinite();
                        flips += u64::from(lookup.escapes(t, v) != escapes);
                    }
                }
            }
            flips
        })
        .sum();
    flips as f64 / exact.data().len().max(1) as f64
}

/// Hit/escape flips of `approx` against `exact` (same grids, escapes +∞), as a fraction of
/// all samples, and the RMSE over the samples a primary query can reach (`exact` hits within
/// the distance `cap`) where both hit.
fn sample_errors(approx: &Gdm, exact: &Gdm, cap: f32) -> (f64, f64) {
    let (mut flips, mut both, mut sum_sq) = (0u64, 0u64, 0.0f64);
    for (&a, &e) in approx.data().iter().zip(exact.data()) {
        if a.is_finite() != e.is_finite() {
            flips += 1;
        } else if e < cap {
            both += 1;
            sum_sq += (a as f64 - e as f64).powi(2);
        }
    }
    let samples = exact.data().len().max(1) as f64;
    (flips as f64 / samples, (sum_sq / both.max(1) as f64).sqrt())
}

/// The report as Markdown: one table over all scenes.
pub fn markdown(report: &CodecReport) -> String {
    let truths: Vec<String> = report
        .truth_s
        .iter()
        .map(|(scene, s)| format!("{scene} {s:.2} s"))
        .collect();
    let opt = |v: Option<f64>, digits: usize| v.map_or("—".into(), |v| format!("{v:.digits$}"));
    let rows = report.rows.iter().map(|r| {
        vec![
            r.scene.clone(),
            r.codec.clone(),
            r.setting.clone(),
            r.bytes.to_string(),
            format!("{:.2}", r.bake_s),
            format!("{:.3}", 100.0 * r.flip_rate),
            format!("{:.3}", r.hit_rmse),
            opt(r.shadow_flip_rate.map(|f| 100.0 * f), 3),
            format!("{:.2}", r.render_s),
            format!("{:.2}", r.psnr_db),
            format!("{:.4}", r.flip_mean),
            format!("{:.3}", 100.0 * r.mask_disagreement),
            opt(r.frame_ms, 1),
            opt(r.realtime_psnr_db, 2),
        ]
    });
    let caps: Vec<String> = report
        .caps
        .iter()
        .map(|(scene, cap)| format!("{scene} {cap:.1}"))
        .collect();
    format!(
        "Ground truth: {}. Real-time adapter: {}. Distance caps (the longest texture-space \
         segment of a prism, voxels): {}.\n\n{}",
        truths.join(", "),
        report.adapter.as_deref().unwrap_or("none"),
        caps.join(", "),
        table(
            &[
                "scene",
                "codec",
                "setting",
                "bytes",
                "bake s",
                "sample flips %",
                "hit RMSE ≤ cap (voxel)",
                "shadow flips %",
                "CPU render s",
                "CPU PSNR dB",
                "CPU FLIP",
                "CPU mask %",
                "real-time frame ms",
                "real-time PSNR dB",
            ],
            rows,
        )
    )
}

/// An SVG plot per scene: CPU render PSNR against the truth over bytes (log), one line per
/// codec through its sizes.
pub fn svg_plot(report: &CodecReport) -> Result<String> {
    use plotters::prelude::*;
    let scenes: Vec<&str> = report.truth_s.iter().map(|(s, _)| s.as_str()).collect();
    scene_panels(&scenes, |panel, scene| {
        let rows: Vec<&CodecRow> = report.rows.iter().filter(|r| r.scene == *scene).collect();
        let (lo, hi) = rows.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r.bytes as f64), hi.max(r.bytes as f64))
        });
        let (p_lo, p_hi) = rows.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r.psnr_db), hi.max(r.psnr_db))
        });
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("{scene}: PSNR against the truth"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(
                ((lo / 2.0)..(hi * 2.0)).log_scale(),
                (p_lo - 2.0)..(p_hi + 2.0),
            )
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc("bytes")
            .y_desc("CPU render PSNR (dB)")
            .draw()
            .map_err(plot_error)?;
        let mut lines: Vec<String> = rows.iter().map(|r| r.line()).collect();
        lines.dedup();
        for (i, line) in lines.into_iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let mut points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.line() == line)
                .map(|r| (r.bytes as f64, r.psnr_db))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(LineSeries::new(points, color.stroke_width(2)).point_size(4))
                .map_err(plot_error)?
                .label(line)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color));
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(plot_error)?;
        Ok(())
    })
}
