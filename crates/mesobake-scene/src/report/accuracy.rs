//! `mesobake report accuracy`: what each direction resolution, SVD rank and quantization
//! costs in bake time, SVD time and package bytes, and what it buys in accuracy, all against
//! the exact uncompressed GDM. Rendered as Markdown, CSV and an SVG plot.

use crate::report::plot::plot_error;
use mesobake_bake::compress::gdm::quantize;
use mesobake_bake::compress::layout::GdmRows;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::{GramEigen, RankChoice};
use mesobake_bake::gdm::{self, EscapeConvention, Method};
use mesobake_bake::package::bake::{bake_info, load_input};
use mesobake_bake::package::{GdmPayload, Package};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::{Dims, DirectionGrid};
use std::path::Path;
use std::time::Instant;

/// The grid of settings the report covers.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// Direction resolutions.
    pub dirs: Vec<DirectionGrid>,
    /// SVD ranks.
    pub ranks: Vec<usize>,
    /// Quantizations.
    pub quantizations: Vec<Quantization>,
}

impl Default for Sweep {
    /// {8×16, 16×32, 32×64} × ranks {1, 2, 4, 8, 16} × {f32, f16}.
    fn default() -> Self {
        Sweep {
            dirs: [(8, 16), (16, 32), (32, 64)]
                .map(|(t, p)| DirectionGrid {
                    n_theta: t,
                    n_phi: p,
                })
                .to_vec(),
            ranks: vec![1, 2, 4, 8, 16],
            quantizations: vec![Quantization::F32, Quantization::F16],
        }
    }
}

/// One setting's costs and errors.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AccuracyRow {
    /// Direction grid, `Nθ×Nφ`.
    pub dirs: String,
    /// Rank kept.
    pub rank: usize,
    /// Quantization.
    pub quantization: Quantization,
    /// Seconds to bake the exact GDM at this direction resolution.
    pub bake_s: f64,
    /// Seconds of the truncated SVD (Gram matrix, eigendecomposition, projection).
    pub svd_s: f64,
    /// Size of the package.
    pub package_bytes: usize,
    /// Root-mean-square error, voxels.
    pub rmse: f64,
    /// Largest absolute error, voxels.
    pub max_abs: f64,
    /// Fraction of samples whose hit/escape classification flips.
    pub flip_rate: f64,
}

/// Runs the sweep on the input at `path` (grid `res` for OBJ tiles), reporting progress as
/// (settings done, settings in all).
pub fn accuracy(
    path: &Path,
    res: Option<Dims>,
    sweep: &Sweep,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Vec<AccuracyRow>> {
    let (input, meso) = load_input(path, res, false, limits)?;
    let total = (sweep.dirs.len() * sweep.ranks.len() * sweep.quantizations.len()) as u64;
    let mut rows = Vec::new();
    for &dirs in &sweep.dirs {
        let start = Instant::now();
        let mut g = gdm::exact::bake(meso.caster(), dirs, limits, &())?;
        g.set_escape_convention(EscapeConvention::Boundary);
        let bake_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let matrix = GdmRows::new(&g)?;
        let gram = GramEigen::new(&matrix, limits)?;
        let gram_s = start.elapsed().as_secs_f64();
        for &rank in &sweep.ranks {
            let start = Instant::now();
            let svd = gram.truncate(&matrix, RankChoice::Rank(rank), limits)?;
            let svd_s = gram_s + start.elapsed().as_secs_f64();
            for &q in &sweep.quantizations {
                if observer.cancelled() {
                    return Err(Error::Cancelled);
                }
                let c = quantize(&g, svd.clone(), RankChoice::Rank(rank), q)?;
                let info = bake_info(&g, Method::Exact, Default::default(), false);
                let bytes = Package::encode(
                    input.clone(),
                    info,
                    &GdmPayload::PaperSvd(Box::new(c.clone())),
                );
                rows.push(AccuracyRow {
                    dirs: dirs.to_string(),
                    rank: c.svd.rank,
                    quantization: q,
                    bake_s,
                    svd_s,
                    package_bytes: bytes.len(),
                    rmse: c.accuracy.rmse,
                    max_abs: c.accuracy.max_abs,
                    flip_rate: c.accuracy.flip_rate,
                });
                observer.progress(rows.len() as u64, total);
            }
        }
    }
    Ok(rows)
}

const COLUMNS: [&str; 9] = [
    "dirs",
    "rank",
    "quant",
    "bake s",
    "SVD s",
    "package bytes",
    "RMSE (voxel)",
    "max error (voxel)",
    "flips %",
];

fn cells(r: &AccuracyRow) -> [String; 9] {
    [
        r.dirs.clone(),
        r.rank.to_string(),
        r.quantization.to_string(),
        format!("{:.3}", r.bake_s),
        format!("{:.3}", r.svd_s),
        r.package_bytes.to_string(),
        format!("{:.4}", r.rmse),
        format!("{:.3}", r.max_abs),
        format!("{:.3}", 100.0 * r.flip_rate),
    ]
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[AccuracyRow]) -> String {
    table(&COLUMNS, rows.iter().map(|r| cells(r).to_vec()))
}

/// A Markdown table with a header of `columns` and one line per row of cells.
pub fn table(columns: &[&str], rows: impl IntoIterator<Item = Vec<String>>) -> String {
    let mut out = format!(
        "| {} |\n|{}\n",
        columns.join(" | "),
        "---|".repeat(columns.len())
    );
    for r in rows {
        out += &format!("| {} |\n", r.join(" | "));
    }
    out
}

/// The rows as CSV (header line, then one line per row; full precision).
pub fn csv(rows: &[AccuracyRow]) -> String {
    let mut out = String::from(
        "dirs,rank,quantization,bake_s,svd_s,package_bytes,rmse_voxel,max_abs_voxel,flip_rate\n",
    );
    for r in rows {
        out += &format!(
            "{},{},{},{},{},{},{},{},{}\n",
            r.dirs,
            r.rank,
            r.quantization,
            r.bake_s,
            r.svd_s,
            r.package_bytes,
            r.rmse,
            r.max_abs,
            r.flip_rate
        );
    }
    out
}

/// A quantity plotted for each row.
type Metric = fn(&AccuracyRow) -> f64;

/// An SVG plot: RMSE against bake + SVD time (left) and against package size (right), one
/// line per direction resolution and quantization through the ranks, log–log.
pub fn svg_plot(rows: &[AccuracyRow]) -> Result<String> {
    use plotters::prelude::*;
    let mut series: Vec<(String, Vec<&AccuracyRow>)> = Vec::new();
    for r in rows {
        let name = format!("{} {}", r.dirs, r.quantization);
        match series.iter_mut().find(|(n, _)| *n == name) {
            Some((_, members)) => members.push(r),
            None => series.push((name, vec![r])),
        }
    }
    let range = |f: Metric| {
        let values = rows.iter().map(f).filter(|v| *v > 0.0);
        let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if lo <= hi {
            (lo / 1.5)..(hi * 1.5)
        } else {
            1e-3..1.0
        }
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let panels = root.split_evenly((1, 2));
        let axes: [(&str, Metric); 2] = [
            ("bake + SVD time (s)", |r| r.bake_s + r.svd_s),
            ("package size (MiB)", |r| {
                r.package_bytes as f64 / (1 << 20) as f64
            }),
        ];
        for (panel, (label, x_of)) in panels.iter().zip(axes) {
            let mut chart = ChartBuilder::on(panel)
                .caption(format!("RMSE against {label}"), ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(56)
                .build_cartesian_2d(range(x_of).log_scale(), range(|r| r.rmse).log_scale())
                .map_err(plot_error)?;
            chart
                .configure_mesh()
                .x_desc(label)
                .y_desc("RMSE (voxel)")
                .draw()
                .map_err(plot_error)?;
            for (i, (name, members)) in series.iter().enumerate() {
                let color = Palette99::pick(i).to_rgba();
                let points: Vec<(f64, f64)> = members
                    .iter()
                    .map(|r| (x_of(r), r.rmse.max(1e-9)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(points, color.stroke_width(2)).point_size(3))
                    .map_err(plot_error)?
                    .label(name.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color));
            }
            chart
                .configure_series_labels()
                .border_style(BLACK)
                .background_style(WHITE.mix(0.8))
                .draw()
                .map_err(plot_error)?;
        }
        root.present().map_err(plot_error)?;
    }
    Ok(svg)
}
