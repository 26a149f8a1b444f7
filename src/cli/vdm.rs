//! `mesobake vdm`: the view-dependent displacement map of a relief as `.npy`, optionally
//! with the paper's bake measured against the exact one; `mesobake relief`: a built-in
//! relief as a 16-bit PNG.

use super::output::{Progress, print_json};
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::vdm::compress;
use mesobake_bake::mesostructure::height_field::HeightField;
use mesobake_bake::mesostructure::reliefs::{self, ReliefKind};
use mesobake_bake::package;
use mesobake_bake::vdm::{self, NO_HIT, Relief, Vdm, VdmGrid, VdmMethod, VdmParams};
use mesobake_core::fs::{read_bounded, write_atomic};
use mesobake_core::limits::Limits;
use mesobake_core::npy;
use mesobake_core::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

/// Where the heights come from.
#[derive(clap::Args)]
#[group(required = true, multiple = false)]
pub struct HeightSource {
    /// A grayscale PNG height field (8 or 16 bits; white is the reference surface).
    #[arg(long)]
    input: Option<PathBuf>,
    /// A built-in relief.
    #[arg(long, value_enum)]
    relief: Option<ReliefKind>,
}

/// Options of `mesobake vdm`.
#[derive(clap::Args)]
pub struct VdmArgs {
    #[command(flatten)]
    source: HeightSource,
    /// Texels per side of a built-in relief.
    #[arg(long, default_value_t = 128)]
    size: u32,
    /// Depth of height 0 below the reference surface, as a fraction of the tile's edge (the
    /// relief of a volume with Z = depth · X voxels).
    #[arg(long, default_value_t = 0.125)]
    depth: f64,
    /// View directions Nθ×Nφ (θ over (0, π/2)).
    #[arg(long, default_value = "8x32", value_parser = parse_pair)]
    dirs: [u32; 2],
    /// Curvatures sampled evenly over --curvature-range.
    #[arg(long, default_value_t = VdmGrid::PAPER.n_curvature)]
    curvatures: u32,
    /// Smallest and largest curvature, 1/tile (positive: convex).
    #[arg(long, default_value = "-2,3", value_parser = parse_range, allow_hyphen_values = true)]
    curvature_range: [f64; 2],
    /// exact: every ray cast on the bent relief; paper: flat casts bent and resampled.
    #[arg(long, default_value = "exact")]
    method: VdmMethod,
    /// The paper's bake: flat rays per θ bin before resampling (1 is the paper's).
    #[arg(long, default_value_t = 1)]
    oversampling: u32,
    /// Compress (MVM, joint SVD with shared weights) to this many components and report what
    /// it costs: silhouette flips, displacement error, bytes.
    #[arg(long)]
    rank: Option<usize>,
    /// Components of the MVM's reconstruction (the paper: 4 of 8).
    #[arg(long, default_value_t = 4)]
    mvm_rank: usize,
    /// Number format of the compressed factors.
    #[arg(long, default_value = "f16")]
    quant: Quantization,
    /// Also bake with the other method and report the paper's error against the exact bake.
    #[arg(long)]
    compare: bool,
    /// Output .npy: float32, shape (curvatures, Nθ, Nφ, H, W), tile units, −1 for no hit.
    #[arg(long, required_unless_present = "package")]
    out: Option<PathBuf>,
    /// Output VDM package (`.mbpkg`): the compressed VDM and MVM as textures (--rank
    /// defaults to 8 here, the paper's).
    #[arg(long)]
    package: Option<PathBuf>,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    json: bool,
}

/// Components kept when packaging without --rank: the paper's 8.
const DEFAULT_RANK: usize = 8;

/// Parses `AxB` (or `AXB`) as a pair of counts.
pub fn parse_pair(text: &str) -> std::result::Result<[u32; 2], String> {
    let (a, b) = text
        .split_once(['x', 'X'])
        .ok_or("expected NθxNφ, e.g. 8x32")?;
    let n = |s: &str| s.trim().parse::<u32>().map_err(|e| format!("{s:?}: {e}"));
    Ok([n(a)?, n(b)?])
}

fn parse_range(text: &str) -> std::result::Result<[f64; 2], String> {
    let (a, b) = text.split_once(',').ok_or("expected MIN,MAX, e.g. -2,3")?;
    let n = |s: &str| s.trim().parse::<f64>().map_err(|e| format!("{s:?}: {e}"));
    Ok([n(a)?, n(b)?])
}

/// Bakes the VDM and writes it.
pub fn vdm(args: VdmArgs, limits: &Limits) -> Result<()> {
    let start = Instant::now();
    let (field, input) = match (&args.source.input, args.source.relief) {
        (Some(path), _) => {
            let bytes = read_bounded(path, "height field", limits.memory_bytes)?;
            let field =
                HeightField::decode_png(&bytes, limits).map_err(|e| e.context(path.display()))?;
            (field, package::vdm::input_info("height_field", &bytes))
        }
        (None, Some(kind)) => {
            let field = reliefs::height_field(kind, args.size, limits)?;
            let png = field.to_png();
            (field, package::vdm::input_info("relief", &png))
        }
        (None, None) => unreachable!("clap requires one source"),
    };
    let load_s = start.elapsed().as_secs_f64();
    let grid = VdmGrid {
        n_theta: args.dirs[0],
        n_phi: args.dirs[1],
        n_curvature: args.curvatures,
        c_min: args.curvature_range[0],
        c_max: args.curvature_range[1],
    };
    let relief = Relief {
        field: &field,
        depth: args.depth,
    };
    let params_of = |method: VdmMethod| VdmParams::new(method, args.oversampling);
    let bake = |method: VdmMethod| -> Result<(Vdm, f64)> {
        let params = params_of(method);
        let progress = Progress::new(&format!("baking VDM ({})", method.name()));
        let start = Instant::now();
        let vdm = vdm::bake(relief, grid, params, limits, &progress)?;
        progress.finish();
        Ok((vdm, start.elapsed().as_secs_f64()))
    };
    let (baked, bake_s) = bake(args.method)?;
    let comparison = if args.compare {
        let other = match args.method {
            VdmMethod::Exact => VdmMethod::Paper,
            VdmMethod::Paper => VdmMethod::Exact,
        };
        let (second, second_s) = bake(other)?;
        let (paper, exact) = match args.method {
            VdmMethod::Exact => (&second, &baked),
            VdmMethod::Paper => (&baked, &second),
        };
        Some((vdm::compare(paper, exact)?, second_s))
    } else {
        None
    };
    let rank = args.rank.or(args.package.is_some().then_some(DEFAULT_RANK));
    let compression = match rank {
        Some(rank) => {
            let start = Instant::now();
            let c = compress(&baked, rank, args.mvm_rank.min(rank), args.quant, limits)?;
            let package = match &args.package {
                Some(path) => {
                    let encoding = Instant::now();
                    let bytes =
                        package::vdm::encode(input, &field, &baked, params_of(args.method), &c);
                    let encode_s = encoding.elapsed().as_secs_f64();
                    let parsing = Instant::now();
                    let parsed = package::vdm::VdmPackage::parse(bytes)?;
                    let parse_s = parsing.elapsed().as_secs_f64();
                    write_atomic(path, parsed.bytes())?;
                    eprintln!("wrote {}: {} bytes", path.display(), parsed.bytes().len());
                    Some(serde_json::json!({
                        "bytes": parsed.bytes().len(),
                        "encode_seconds": encode_s,
                        "parse_seconds": parse_s,
                    }))
                }
                None => None,
            };
            let bytes = (c.weights.codes.len() + c.eigen.codes.len()) as u64;
            eprintln!(
                "compressed to {} + {} components ({}): {bytes} bytes (from {}); silhouette \
                 flips {:.3} %, displacement RMSE {:.3e}",
                c.vdm_rank,
                c.mvm_rank,
                args.quant,
                4 * baked.values.len(),
                100.0 * c.accuracy.flip_rate,
                c.accuracy.rmse
            );
            Some(serde_json::json!({
                "vdm_rank": c.vdm_rank,
                "mvm_rank": c.mvm_rank,
                "quantization": args.quant,
                "bytes": bytes,
                "package": package,
                "uncompressed_bytes": 4 * baked.values.len(),
                "accuracy": c.accuracy,
                "seconds": start.elapsed().as_secs_f64(),
            }))
        }
        None => None,
    };
    let shape = [
        u64::from(grid.n_curvature),
        u64::from(grid.n_theta),
        u64::from(grid.n_phi),
        u64::from(baked.size.1),
        u64::from(baked.size.0),
    ];
    let start = Instant::now();
    if let Some(out) = &args.out {
        npy::write_array(out, &shape, &baked.values)?;
    }
    let write_s = start.elapsed().as_secs_f64();
    let hits = baked.values.iter().filter(|&&v| v != NO_HIT).count();
    eprintln!(
        "{} samples, {:.1} % hit, baked in {bake_s:.2} s",
        baked.values.len(),
        100.0 * hits as f64 / baked.values.len().max(1) as f64
    );
    if let Some((c, _)) = &comparison {
        eprintln!(
            "paper against exact: RMSE {:.3e} (max {:.3e}) where both hit; {} of {} samples \
             disagree on hitting",
            c.rmse, c.max_abs, c.hit_disagreements, c.samples
        );
    }
    if args.json {
        print_json(&serde_json::json!({
            "output": args.out,
            "package": args.package,
            "size": [baked.size.0, baked.size.1],
            "depth": args.depth,
            "grid": grid,
            "method": args.method,
            "oversampling": args.oversampling,
            "hit_fraction": hits as f64 / baked.values.len().max(1) as f64,
            "comparison": comparison.as_ref().map(|(c, _)| c),
            "compression": compression,
            "seconds": {
                "load": load_s,
                "bake": bake_s,
                "compare_bake": comparison.as_ref().map(|(_, s)| s),
                "write": write_s,
            },
        }));
    }
    Ok(())
}

/// Options of `mesobake relief`.
#[derive(clap::Args)]
pub struct ReliefArgs {
    /// The relief.
    #[arg(value_enum)]
    kind: ReliefKind,
    /// Pixels per side.
    #[arg(long, default_value_t = 128)]
    size: u32,
    /// Output PNG (16-bit grayscale).
    #[arg(long)]
    out: PathBuf,
}

/// Writes a built-in relief as a PNG.
pub fn relief(args: ReliefArgs, limits: &Limits) -> Result<()> {
    let field = reliefs::height_field(args.kind, args.size, limits)?;
    if args
        .out
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("png"))
    {
        return Err(Error::InvalidParameter(format!(
            "{}: a relief is written as PNG (name it .png)",
            args.out.display()
        )));
    }
    write_atomic(&args.out, &field.to_png())
}
