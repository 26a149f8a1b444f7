//! `mesobake gdm`: the raw GDM of an input as `.npy`, and the bake options it shares with
//! `mesobake bake`.

use super::output::{Progress, print_json};
use clap::ValueEnum;
use mesobake_bake::gdm::input;
use mesobake_bake::gdm::npy;
use mesobake_bake::gdm::{self, Method};
use mesobake_core::limits::Limits;
use mesobake_core::{Error, Result};
use mesobake_package::grid::{Dims, DirectionGrid};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to bake and how: the options shared by `gdm` and `bake`.
#[derive(clap::Args)]
pub struct BakeOptions {
    /// A .mbvol volume, an OBJ tile or a height-field PNG (required unless `bake --scene`).
    #[arg(long)]
    pub input: Option<PathBuf>,
    /// Grid X×Y×Z: required for OBJ tiles; for volumes it must match the volume.
    #[arg(long)]
    pub res: Option<Dims>,
    /// Direction grid Nθ×Nφ.
    #[arg(long, default_value = "16x32")]
    pub dirs: DirectionGrid,
    /// exact: one ray per sample and direction; fast: layer sweeps (see --stride).
    #[arg(long, default_value = "exact")]
    pub method: Method,
    /// Fast method: layers crossed exactly before interpolating (higher = slower, closer).
    #[arg(long, default_value_t = gdm::fast::FastParams::default().stride)]
    pub stride: u32,
    /// Fast method: largest spread (voxels) of neighbouring hit distances that is still
    /// interpolated; rays with more disagreeing neighbours are traced exactly.
    #[arg(long, default_value_t = gdm::fast::FastParams::default().max_spread)]
    pub spread: f32,
    /// Treat an open OBJ tile as infinitely thin sheets instead of refusing it.
    #[arg(long)]
    pub allow_open: bool,
}

impl BakeOptions {
    /// The input file, which these commands require.
    pub fn input(&self) -> Result<&Path> {
        self.input
            .as_deref()
            .ok_or_else(|| Error::InvalidParameter("--input FILE is required".into()))
    }

    /// The fast method's knobs.
    pub fn fast(&self) -> gdm::fast::FastParams {
        gdm::fast::FastParams {
            stride: self.stride,
            max_spread: self.spread,
        }
    }
}

/// Options of `mesobake gdm`.
#[derive(clap::Args)]
pub struct GdmArgs {
    #[command(flatten)]
    bake: BakeOptions,
    /// Escape values in the file: inf (+inf), or boundary (distance to the top/bottom
    /// plane along the ray, the convention used for compression).
    #[arg(long, value_enum, default_value_t = EscapeArg::Inf)]
    escape: EscapeArg,
    /// Output .npy file.
    #[arg(long)]
    out: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    json: bool,
}

/// How escapes are written.
#[derive(Clone, Copy, ValueEnum)]
enum EscapeArg {
    Inf,
    Boundary,
}

/// Bakes the GDM and writes it as `.npy`.
pub fn gdm(args: GdmArgs, limits: &Limits) -> Result<()> {
    let GdmArgs {
        bake,
        escape,
        out,
        json,
    } = args;
    let start = Instant::now();
    let meso = input::load(bake.input()?, bake.res, bake.allow_open, limits)?;
    let load_s = start.elapsed().as_secs_f64();
    let progress = Progress::new("baking GDM");
    let start = Instant::now();
    let (method, fast) = (bake.method, bake.fast());
    let mut g = gdm::bake(meso.caster(), bake.dirs, method, fast, limits, &progress)?;
    let bake_s = start.elapsed().as_secs_f64();
    progress.finish();
    if let EscapeArg::Boundary = escape {
        g.set_escape_convention(gdm::EscapeConvention::Boundary);
    }
    let start = Instant::now();
    npy::write_gdm(&g, &out)?;
    let write_s = start.elapsed().as_secs_f64();
    if json {
        print_json(&serde_json::json!({
            "input": bake.input,
            "output": out,
            "res": g.dims().to_string(),
            "dirs": g.dirs().to_string(),
            "method": method,
            "fast": fast,
            "escape": g.escape_convention(),
            "samples": g.data().len(),
            "seconds": {"load": load_s, "bake": bake_s, "write": write_s},
        }));
    }
    Ok(())
}
