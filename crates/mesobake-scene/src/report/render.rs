//! `mesobake report render`: how the GDM renderer's image falls away from the ground truth
//! as the direction resolution, the SVD rank and the refinement count go down, and what each
//! setting costs in render time. The truth is rendered once; every GDM setting is rendered
//! from the exact GDM baked at its direction resolution ("exact") or from that GDM compressed
//! as a package would hold it (boundary convention, rank k, quantized), and compared. The
//! error budget then substitutes the algorithm's own approximations ([`Substitutions`]) one
//! at a time and all together, to show what each one costs.

use crate::LoadedScene;
use crate::report::accuracy::table;
use mesobake_bake::compress::gdm::quantize;
use mesobake_bake::compress::layout::GdmRows;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::{GramEigen, RankChoice};
use mesobake_bake::gdm::{self, EscapeConvention};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::DirectionGrid;
use mesobake_render::gdm_lookup::{GdmLookup, PackageLookup, RawLookup};
use mesobake_render::gdm_renderer::{GdmRenderer, Substitutions};
use mesobake_render::image::{Image, compare};
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use std::time::Instant;

/// The settings the report covers.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSweep {
    /// Direction resolutions.
    pub dirs: Vec<DirectionGrid>,
    /// SVD ranks (the exact GDM is always included).
    pub ranks: Vec<usize>,
    /// Quantization of the compressed factors.
    pub quantization: Quantization,
    /// GDM refinement counts.
    pub refinements: Vec<u32>,
}

/// One setting's image error against the truth and its render time.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RenderAccuracyRow {
    /// Direction grid, `Nθ×Nφ`.
    pub dirs: String,
    /// SVD rank, or `None` for the exact uncompressed GDM.
    pub rank: Option<usize>,
    /// GDM refinement queries per hit.
    pub refinements: u32,
    /// The parts of the algorithm substituted ([`Substitutions::label`]).
    pub substituted: String,
    /// Seconds to render (acceleration structure and pixels).
    pub render_s: f64,
    /// PSNR against the truth, dB (sRGB).
    pub psnr_db: f64,
    /// Mean ꟻLIP error against the truth.
    pub flip_mean: f64,
    /// Mean absolute error against the truth (sRGB).
    pub mean_abs_error: f64,
    /// Fraction of pixels whose hit/miss mask differs from the truth's.
    pub mask_disagreement: f64,
}

/// The report: the truth's render time and one row per setting.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RenderReport {
    /// Seconds the ground truth took.
    pub truth_s: f64,
    /// Rows in sweep order: per direction grid, exact then each rank, each refinement count.
    pub rows: Vec<RenderAccuracyRow>,
    /// The error budget: the exact GDM on the scene's direction grid without refinements,
    /// with each of [`Substitutions::BUDGET`].
    pub budget: Vec<RenderAccuracyRow>,
}

/// Runs the sweep on `loaded`, reporting progress as (renders done, renders in all).
pub fn render_accuracy(
    loaded: &LoadedScene,
    sweep: &RenderSweep,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<RenderReport> {
    let scene = &loaded.scene;
    let total = (1
        + sweep.dirs.len() * (1 + sweep.ranks.len()) * sweep.refinements.len()
        + Substitutions::BUDGET.len()) as u64;
    let start = Instant::now();
    let caster = loaded.mesostructure.caster();
    let truth_renderer = TruthRenderer::new(&loaded.shell, caster, &loaded.material);
    let shot = scene.shot();
    let truth = render_image(&shot.camera, |o, d| truth_renderer.radiance(&shot, o, d));
    let truth_s = start.elapsed().as_secs_f64();
    let mut rows = Vec::new();
    let mut done = 1;
    observer.progress(done, total);
    let mut measure = |dirs: DirectionGrid,
                       rank,
                       lookup: &dyn GdmLookup,
                       refinements,
                       subs: Substitutions|
     -> Result<RenderAccuracyRow> {
        if observer.cancelled() {
            return Err(Error::Cancelled);
        }
        let start = Instant::now();
        let r = GdmRenderer::new(&loaded.shell, lookup, &loaded.material, refinements)
            .with_substitutions(subs, &truth_renderer);
        let shot = scene.shot();
        let image: Image = render_image(&shot.camera, |o, d| r.radiance(&shot, o, d));
        let render_s = start.elapsed().as_secs_f64();
        let c = compare(&truth, &image)?;
        done += 1;
        observer.progress(done, total);
        Ok(RenderAccuracyRow {
            dirs: dirs.to_string(),
            rank,
            refinements,
            substituted: subs.label(),
            render_s,
            psnr_db: c.psnr_db,
            flip_mean: c.flip_mean,
            mean_abs_error: c.mean_abs_error,
            mask_disagreement: c.mask_disagreement,
        })
    };
    let mut sweep_refinements = |dirs, rank, lookup: &dyn GdmLookup| -> Result<()> {
        for &refinements in &sweep.refinements {
            rows.push(measure(
                dirs,
                rank,
                lookup,
                refinements,
                Substitutions::default(),
            )?);
        }
        Ok(())
    };
    for &dirs in &sweep.dirs {
        let mut g = gdm::exact::bake(caster, dirs, limits, &())?;
        sweep_refinements(dirs, None, &RawLookup::new(&g))?;
        if sweep.ranks.is_empty() {
            continue;
        }
        g.set_escape_convention(EscapeConvention::Boundary);
        let matrix = GdmRows::new(&g)?;
        let gram = GramEigen::new(&matrix, limits)?;
        for &rank in &sweep.ranks {
            let svd = gram.truncate(&matrix, RankChoice::Rank(rank), limits)?;
            let c = quantize(&g, svd, RankChoice::Rank(rank), sweep.quantization)?;
            let lookup = PackageLookup::from_factors(
                g.dims(),
                dirs,
                &c.weights,
                &c.eigen,
                c.accuracy.escape_margin,
            );
            sweep_refinements(dirs, Some(c.svd.rank), &lookup)?;
        }
    }
    let dirs = scene.dirs()?;
    let g = gdm::exact::bake(caster, dirs, limits, &())?;
    let lookup = RawLookup::new(&g);
    let budget = Substitutions::BUDGET
        .into_iter()
        .map(|subs| measure(dirs, None, &lookup, 0, subs))
        .collect::<Result<_>>()?;
    Ok(RenderReport {
        truth_s,
        rows,
        budget,
    })
}

/// The report as Markdown: the truth's time, the sweep's table and the error budget's.
pub fn markdown(report: &RenderReport) -> String {
    let table_of = |rows: &[RenderAccuracyRow]| {
        let cells = rows.iter().map(|r| {
            vec![
                r.dirs.clone(),
                r.rank.map_or("exact".into(), |k| k.to_string()),
                r.refinements.to_string(),
                r.substituted.clone(),
                format!("{:.3}", r.render_s),
                format!("{:.2}", report.truth_s / r.render_s),
                format!("{:.2}", r.psnr_db),
                format!("{:.4}", r.flip_mean),
                format!("{:.4}", r.mean_abs_error),
                format!("{:.3}", 100.0 * r.mask_disagreement),
            ]
        });
        table(
            &[
                "dirs",
                "rank",
                "refinements",
                "substituted",
                "render s",
                "truth / GDM time",
                "PSNR dB",
                "FLIP",
                "mean abs error",
                "mask disagreement %",
            ],
            cells,
        )
    };
    format!(
        "Ground truth: {:.3} s.\n\n{}\nError budget: parts of the GDM algorithm substituted \
         by the truth's (query: exact cast along the fragment's straight segment; shadows: the \
         truth's shadow rays), with the paper's settings of the quality knobs.\n\n{}",
        report.truth_s,
        table_of(&report.rows),
        table_of(&report.budget),
    )
}
