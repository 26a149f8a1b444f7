//! `mesobake bench gdm`: the GDM bake workloads W1–W3 of the benchmark plan, timed in one run
//! with their baselines, error against the exact bake and peak memory.

use mesobake_bake::compress::accuracy::Accuracy;
use mesobake_bake::compress::layout::GdmRows;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::{
    DenseRows, GramEigen, RankChoice, RowSource, Truncated, truncated_svd,
};
use mesobake_bake::gdm::caster::Caster;
use mesobake_bake::gdm::compare::{GdmError, compare};
use mesobake_bake::gdm::fast::FastParams;
use mesobake_bake::gdm::mesh_caster::MeshCaster;
use mesobake_bake::gdm::volume_caster::VolumeCaster;
use mesobake_bake::gdm::{EscapeConvention, Gdm, exact, fast};
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::package::manifest::InputInfo;
use mesobake_bake::package::{GdmPayload, Package};
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};
use std::time::Instant;

/// Peak heap usage, measured by the binary's allocator.
pub trait MemoryProbe {
    /// Starts a new measurement window.
    fn reset_peak(&self);
    /// Highest number of live heap bytes since the last reset.
    fn peak_bytes(&self) -> u64;
    /// Live heap bytes now.
    fn current_bytes(&self) -> u64;
}

/// One measured row of the table.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// Workload id and description.
    pub workload: String,
    /// Bake path.
    pub path: String,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Rays cast (samples not inside solid × directions), millions per second.
    pub mrays_per_s: f64,
    /// Peak heap over the dense float32 output size.
    pub peak_over_output: f64,
    /// Error against the workload's exact reference, when this row is approximate.
    pub error: Option<GdmError>,
}

fn rays(caster: &dyn Caster, dirs: DirectionGrid) -> f64 {
    let dims = caster.dims();
    (dims.voxel_count() - caster.centres_inside().solid_count()) as f64 * dirs.count() as f64
}

fn timed<T>(probe: &dyn MemoryProbe, f: impl FnOnce() -> Result<T>) -> Result<(T, f64, u64)> {
    probe.reset_peak();
    let before = probe.current_bytes();
    let start = Instant::now();
    let out = f()?;
    let secs = start.elapsed().as_secs_f64();
    Ok((out, secs, probe.peak_bytes().saturating_sub(before)))
}

fn row(
    workload: &str,
    path: &str,
    rays: f64,
    secs: f64,
    peak: u64,
    out: &Gdm,
    error: Option<GdmError>,
) -> Row {
    Row {
        workload: workload.to_string(),
        path: path.to_string(),
        seconds: secs,
        mrays_per_s: rays / secs / 1e6,
        peak_over_output: peak as f64 / (out.data().len() as f64 * 4.0),
        error,
    }
}

/// A baseline row: time scaled from a subset of directions, no error or memory figures.
fn baseline(workload: &str, what: &str, seconds: f64, mrays_per_s: f64) -> Row {
    Row {
        workload: workload.to_string(),
        path: format!("baseline: {what}"),
        seconds,
        mrays_per_s,
        peak_over_output: f64::NAN,
        error: None,
    }
}

/// The fast-bake settings measured: the default, then each knob pushed towards speed.
const FAST_SETTINGS: [FastParams; 3] = [
    FastParams {
        stride: 2,
        max_spread: 1.0,
    },
    FastParams {
        stride: 1,
        max_spread: 1.0,
    },
    FastParams {
        stride: 2,
        max_spread: f32::INFINITY,
    },
];

fn describe(p: FastParams) -> String {
    format!("stride {}, spread {}", p.stride, p.max_spread)
}

/// Times one bake of `caster` per fast setting against `exact_gdm`.
fn fast_rows(
    probe: &dyn MemoryProbe,
    limits: &Limits,
    id: &str,
    kind: &str,
    caster: &dyn Caster,
    exact_gdm: &Gdm,
    settings: &[FastParams],
) -> Result<Vec<Row>> {
    let dirs = exact_gdm.dirs();
    let n = rays(caster, dirs);
    let mut rows = Vec::new();
    for &params in settings {
        let (g, secs, peak) = timed(probe, || fast::bake(caster, dirs, params, limits, &()))?;
        let err = compare(&g, exact_gdm)?;
        let path = format!("{kind} fast ({})", describe(params));
        rows.push(row(id, &path, n, secs, peak, &g, Some(err)));
    }
    Ok(rows)
}

/// Runs W1 (chain volume 64×64×32), W2 (bark volume 128×128×16) and W3 (chain OBJ tile
/// 64×64×32), all with 16×32 directions. The per-ray baselines (DDA with and without
/// empty-space skipping, BVH traversal) run on 2×8 directions spread over the sphere and their times are
/// scaled to the full grid.
pub fn run(probe: &dyn MemoryProbe, limits: &Limits) -> Result<Vec<Row>> {
    let dirs = DirectionGrid::PAPER;
    let subset = DirectionGrid::new(2, 8)?;
    let scale = dirs.count() as f64 / subset.count() as f64;
    let mut rows = Vec::new();
    for (id, kind, dims) in [
        (
            "W1 chain 64x64x32",
            SampleKind::Chain,
            Dims::new(64, 64, 32)?,
        ),
        (
            "W2 bark 128x128x16",
            SampleKind::Bark,
            Dims::new(128, 128, 16)?,
        ),
    ] {
        let volume = samples::volume(kind, dims, limits)?;
        let caster = VolumeCaster::new(&volume);
        let n = rays(&caster, dirs);
        let (exact_gdm, secs, peak) = timed(probe, || exact::bake(&caster, dirs, limits, &()))?;
        let path = "volume exact (ray templates, 64 rays per word)";
        rows.push(row(id, path, n, secs, peak, &exact_gdm, None));
        let plain = VolumeCaster::from_occupancy(volume.occupancy(), false);
        for (name, c) in [
            ("DDA + empty-space skipping", &caster),
            ("plain DDA", &plain),
        ] {
            let (_, secs, _) = timed(probe, || exact::bake_per_ray(c, subset, limits, &()))?;
            rows.push(baseline(
                id,
                &format!("per-ray {name} ({subset} directions, time ×{scale})"),
                secs * scale,
                rays(c, subset) / secs / 1e6,
            ));
        }
        rows.extend(fast_rows(
            probe,
            limits,
            id,
            "volume",
            &caster,
            &exact_gdm,
            &FAST_SETTINGS,
        )?);
    }
    let dims = Dims::new(64, 64, 32)?;
    let tile = MeshTile::new(samples::mesh(SampleKind::Chain, dims)?, false)?;
    let (caster, secs_setup, _) = timed(probe, || MeshCaster::new(&tile, dims, limits))?;
    let n = rays(&caster, dirs);
    let (exact_gdm, secs, peak) = timed(probe, || exact::bake(&caster, dirs, limits, &()))?;
    let id = "W3 chain OBJ 64x64x32";
    let path =
        format!("mesh exact (ray templates over voxel-binned triangles; +{secs_setup:.2} s setup)");
    rows.push(row(id, &path, n, secs, peak, &exact_gdm, None));
    let (_, secs, _) = timed(probe, || exact::bake_per_ray(&caster, subset, limits, &()))?;
    rows.push(baseline(
        id,
        &format!("per-ray obvhs CWBVH traversal ({subset} directions, time ×{scale})"),
        secs * scale,
        rays(&caster, subset) / secs / 1e6,
    ));
    rows.extend(fast_rows(
        probe,
        limits,
        id,
        "mesh",
        &caster,
        &exact_gdm,
        &[FastParams::default()],
    )?);
    Ok(rows)
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| workload | path | time (s) | Mrays/s | peak / output | mean abs err (vox) | max abs err (vox) | class. mismatch |\n|---|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let (mean, max, mis) = match &r.error {
            Some(e) => (
                format!("{:.4}", e.mean_abs_error),
                format!("{:.2}", e.max_abs_error),
                format!("{:.3} %", e.classification_mismatch * 100.0),
            ),
            None => ("exact".into(), "exact".into(), "—".into()),
        };
        let peak = if r.peak_over_output.is_finite() {
            format!("{:.2}", r.peak_over_output)
        } else {
            "—".into()
        };
        s += &format!(
            "| {} | {} | {:.3} | {:.1} | {} | {} | {} | {} |\n",
            r.workload, r.path, r.seconds, r.mrays_per_s, peak, mean, max, mis
        );
    }
    s
}

/// One measured row of the SVD table.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SvdRow {
    /// What was factored.
    pub matrix: String,
    /// Algorithm and rank.
    pub method: String,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Root-mean-square reconstruction error over all entries, voxels.
    pub rmse: f64,
    /// The optimal RMSE of that rank (Eckart–Young, from the spectrum).
    pub optimal_rmse: f64,
}

/// RMSE of a factorization over the whole matrix, read block by block.
fn svd_rmse(a: &dyn RowSource, t: &Truncated) -> f64 {
    let n = a.cols();
    let mut buf = vec![0.0f32; 1024 * n];
    let mut sum = 0.0f64;
    let mut r = 0;
    while r < a.rows() {
        let count = 1024.min(a.rows() - r);
        a.read_rows(r, &mut buf[..count * n]);
        for (q, &v) in buf[..count * n].iter().enumerate() {
            let d = v as f64 - t.reconstruct(r + q / n, q % n) as f64;
            sum += d * d;
        }
        r += count;
    }
    (sum / (a.rows() * n) as f64).sqrt()
}

/// The W1 GDM (chain 64×64×32, 16×32 directions, exact) with boundary escapes.
fn w1_gdm(limits: &Limits) -> Result<mesobake_bake::gdm::Gdm> {
    let volume = samples::volume(SampleKind::Chain, Dims::new(64, 64, 32)?, limits)?;
    let caster = VolumeCaster::new(&volume);
    let mut gdm = exact::bake(&caster, DirectionGrid::PAPER, limits, &())?;
    gdm.set_escape_convention(EscapeConvention::Boundary);
    Ok(gdm)
}

/// The SVD benchmark: the W1 GDM (chain 64×64×32, 16×32 directions, boundary escapes) as the
/// paper's 131072 × 512 matrix to rank 16, and nalgebra's full SVD on a slice of its rows
/// against ours on the same slice.
pub fn run_svd(limits: &Limits) -> Result<Vec<SvdRow>> {
    let gdm = w1_gdm(limits)?;
    let a = GdmRows::new(&gdm)?;
    let (m, n) = (a.rows(), a.cols());
    let mut rows = Vec::new();
    let mut measure = |matrix: String, source: &dyn RowSource, k: usize| -> Result<()> {
        let start = Instant::now();
        let t = truncated_svd(source, RankChoice::Rank(k), limits)?;
        let seconds = start.elapsed().as_secs_f64();
        rows.push(SvdRow {
            matrix,
            method: format!("Gram eigen + projection, rank {k}"),
            seconds,
            rmse: svd_rmse(source, &t),
            optimal_rmse: t.optimal_rmse(t.rank),
        });
        Ok(())
    };
    measure(format!("W1 GDM {m}×{n}"), &a, 16)?;
    // The slice: its first rows, dense.
    let slice_rows = 4096;
    let mut slice = vec![0.0f32; slice_rows * n];
    a.read_rows(0, &mut slice);
    let dense = DenseRows::new(&slice, n)?;
    measure(format!("W1 slice {slice_rows}×{n}"), &dense, 16)?;
    let start = Instant::now();
    let full = nalgebra::DMatrix::from_row_slice(slice_rows, n, &slice)
        .map(f64::from)
        .svd(true, true);
    let seconds = start.elapsed().as_secs_f64();
    let mut s: Vec<f64> = full.singular_values.iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    let tail: f64 = s.iter().skip(16).map(|x| x * x).sum();
    rows.push(SvdRow {
        matrix: format!("W1 slice {slice_rows}×{n}"),
        method: "baseline: nalgebra full SVD (f64), truncated to 16".into(),
        seconds,
        rmse: (tail / (slice_rows * n) as f64).sqrt(),
        optimal_rmse: (tail / (slice_rows * n) as f64).sqrt(),
    });
    Ok(rows)
}

/// The SVD rows as a Markdown table.
pub fn svd_markdown(rows: &[SvdRow]) -> String {
    let mut s = String::from(
        "| matrix | method | time (s) | RMSE (vox) | optimal RMSE (vox) |\n|---|---|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {:.3} | {:.5} | {:.5} |\n",
            r.matrix, r.method, r.seconds, r.rmse, r.optimal_rmse
        );
    }
    s
}

/// One package of the package benchmark.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PackageRow {
    /// Why this package is in the table.
    pub setting: String,
    /// Rank kept.
    pub rank: usize,
    /// Quantization.
    pub quantization: Quantization,
    /// Package size in bytes.
    pub bytes: usize,
    /// Accuracy against the exact GDM.
    pub accuracy: Accuracy,
}

/// Target RMSE of the smallest-package search, voxels.
pub const PACKAGE_TARGET_RMSE: f64 = 0.5;

/// The package benchmark on W1: the paper's setting (rank 8, f16), and per quantization the
/// smallest rank whose measured RMSE (quantization included) is at most
/// [`PACKAGE_TARGET_RMSE`], found by bisection on the leading components of one SVD.
pub fn run_package(limits: &Limits) -> Result<Vec<PackageRow>> {
    let gdm = w1_gdm(limits)?;
    let a = GdmRows::new(&gdm)?;
    let gram = GramEigen::new(&a, limits)?;
    let input = InputInfo {
        kind: "volume".into(),
        bytes: 0,
        blake3: blake3::hash(b"chain 64x64x32 (built in)")
            .to_hex()
            .to_string(),
    };
    let row = |setting: String, svd: Truncated, q: Quantization| -> Result<PackageRow> {
        let choice = RankChoice::Rank(svd.rank);
        let c = mesobake_bake::compress::gdm::quantize(&gdm, svd, choice, q)?;
        let method = mesobake_bake::gdm::Method::Exact;
        let info = mesobake_bake::package::bake::bake_info(&gdm, method, Default::default(), false);
        Ok(PackageRow {
            setting,
            rank: c.svd.rank,
            quantization: q,
            bytes: Package::encode(
                input.clone(),
                info,
                &GdmPayload::PaperSvd(Box::new(c.clone())),
            )
            .len(),
            accuracy: c.accuracy,
        })
    };
    let mut rows = vec![row(
        "the paper's setting".into(),
        gram.truncate(&a, RankChoice::Rank(8), limits)?,
        Quantization::F16,
    )?];
    // The optimal error reaches the target at k0; quantization needs a few more components.
    let k0 = gram
        .truncate(&a, RankChoice::MaxRmse(PACKAGE_TARGET_RMSE), limits)?
        .rank;
    let widest = gram.truncate(&a, RankChoice::Rank(k0 + 64), limits)?;
    for q in [Quantization::F16, Quantization::U8] {
        let (mut lo, mut hi) = (k0, widest.rank);
        let mut best = row(String::new(), widest.leading(hi), q)?;
        if best.accuracy.rmse > PACKAGE_TARGET_RMSE {
            best.setting = format!("RMSE ≤ {PACKAGE_TARGET_RMSE} not reached by rank {hi}");
            rows.push(best);
            continue;
        }
        while lo < hi {
            let mid = (lo + hi) / 2;
            let candidate = row(String::new(), widest.leading(mid), q)?;
            if candidate.accuracy.rmse <= PACKAGE_TARGET_RMSE {
                (hi, best) = (mid, candidate);
            } else {
                lo = mid + 1;
            }
        }
        best.setting = format!("smallest {q} package with RMSE ≤ {PACKAGE_TARGET_RMSE}");
        rows.push(best);
    }
    Ok(rows)
}

/// The package rows as a Markdown table.
pub fn package_markdown(rows: &[PackageRow]) -> String {
    let mut s = String::from(
        "| setting | rank | quant | bytes | MiB | RMSE (vox) | max (vox) | flips % | margin μ |\n\
         |---|---:|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let a = &r.accuracy;
        s += &format!(
            "| {} | {} | {} | {} | {:.3} | {:.4} | {:.2} | {:.3} | {:.4} |\n",
            r.setting,
            r.rank,
            r.quantization,
            r.bytes,
            r.bytes as f64 / (1 << 20) as f64,
            a.rmse,
            a.max_abs,
            100.0 * a.flip_rate,
            a.escape_margin
        );
    }
    s
}
