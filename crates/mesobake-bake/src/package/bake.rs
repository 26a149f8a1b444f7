//! From an input file to a package: load, bake, compress, encode (or, for the occupancy
//! codec, load, encode the occupancy field, encode). The stages `mesobake bake`
//! runs (and that the server will queue), with the time each takes.

use crate::compress::gdm::{CompressedGdm, compress};
use crate::compress::layout::GdmRows;
use crate::compress::quantize::Quantization;
use crate::compress::svd::{GramEigen, RankChoice};
use crate::gdm::fast::FastParams;
use crate::gdm::input::{self, Mesostructure};
use crate::gdm::{self, EscapeConvention, Gdm, Method};
use crate::package::{GdmPayload, Package};
use mesobake_core::error::{Error, Result};
use mesobake_core::fs::read_bounded;
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::{Dims, DirectionGrid};
use mesobake_package::manifest::{BakeInfo, GdmCodec, InputInfo};
use std::path::Path;
use std::time::Instant;

/// Everything that decides a package's content (with the input's bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackageParams {
    /// Voxel grid: required for OBJ tiles; for volumes it must match when given.
    pub res: Option<Dims>,
    /// Direction grid.
    pub dirs: DirectionGrid,
    /// What answers the renderers' GDM queries.
    pub codec: GdmCodec,
    /// Baking algorithm (of `paper-svd`'s GDM).
    pub method: Method,
    /// Knobs of [`Method::Fast`].
    pub fast: FastParams,
    /// How many SVD components to keep.
    pub rank: RankChoice,
    /// Number format of the factors.
    pub quantization: Quantization,
    /// Accept open OBJ tiles as thin sheets.
    pub allow_open: bool,
}

/// The largest SVD rank a bake may ask for, on the command line and on the server alike.
pub const MAX_RANK: usize = 64;

/// Checks the codec options a bake asks for, the same for every door (CLI and server): an SVD
/// size (`rank`, `quantization`) only with `paper-svd`, and a rank in 1..=[`MAX_RANK`].
pub fn check_codec_options(
    codec: GdmCodec,
    rank: Option<usize>,
    quantization: Option<Quantization>,
) -> Result<()> {
    if codec != GdmCodec::PaperSvd {
        let given = [rank.map(|_| "rank"), quantization.map(|_| "quantization")];
        if let Some(option) = given.into_iter().flatten().next() {
            return Err(Error::InvalidParameter(format!(
                "{option} sizes the paper-svd codec's SVD, but the codec is {codec}: ask for \
                 the paper-svd codec, or leave {option} out"
            )));
        }
    }
    match rank {
        Some(k) if !(1..=MAX_RANK).contains(&k) => Err(Error::InvalidParameter(format!(
            "rank must be in 1..={MAX_RANK}, got {k}"
        ))),
        _ => Ok(()),
    }
}

/// Seconds spent in each stage.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageSeconds {
    /// Reading, hashing and preparing the input.
    pub load: f64,
    /// Baking the GDM (`paper-svd`), or encoding the occupancy field (`occupancy`).
    pub bake: f64,
    /// The truncated SVD (Gram matrix, eigendecomposition and projection).
    pub svd: f64,
    /// Quantizing the factors and measuring the reconstruction's error.
    pub quantize: f64,
    /// Encoding the package.
    pub encode: f64,
}

/// A baked package and what it took.
pub struct BakedPackage {
    /// The package's bytes.
    pub bytes: Vec<u8>,
    /// The GDM payload they encode.
    pub gdm: GdmPayload,
    /// Time per stage.
    pub seconds: StageSeconds,
}

/// Reads `path`, returning its bytes' identity and the loaded mesostructure.
pub fn load_input(
    path: &Path,
    res: Option<Dims>,
    allow_open: bool,
    limits: &Limits,
) -> Result<(InputInfo, Mesostructure)> {
    let bytes = read_bounded(path, "input", limits.memory_bytes)?;
    let meso = input::load(path, res, allow_open, limits)?;
    let kind = match meso {
        Mesostructure::Volume(_) => "volume",
        Mesostructure::Mesh(_) => "mesh",
        Mesostructure::HeightField(_) => "height_field",
    };
    let info = InputInfo {
        kind: kind.into(),
        bytes: bytes.len() as u64,
        blake3: blake3::hash(&bytes).to_hex().to_string(),
    };
    Ok((info, meso))
}

/// The parameters of the bake that made `g`, as recorded in a manifest (`fast` only
/// matters for [`Method::Fast`]).
pub fn bake_info(g: &Gdm, method: Method, fast: FastParams, allow_open: bool) -> BakeInfo {
    let (d, dirs) = (g.dims(), g.dirs());
    BakeInfo {
        res: [d.x, d.y, d.z],
        dirs: [dirs.n_theta, dirs.n_phi],
        method,
        fast: (method == Method::Fast).then_some(fast),
        allow_open,
    }
}

/// Bakes the package of the input at `path`.
pub fn bake_package(
    path: &Path,
    params: &PackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<BakedPackage> {
    let mut seconds = StageSeconds::default();
    let start = Instant::now();
    let (input, meso) = load_input(path, params.res, params.allow_open, limits)?;
    seconds.load = start.elapsed().as_secs_f64();

    let start = Instant::now();
    if params.codec == GdmCodec::Occupancy {
        observer.stage("occupancy");
        let field = meso.caster().centres_inside().field();
        let info = BakeInfo {
            res: [field.dims().x, field.dims().y, field.dims().z],
            dirs: [params.dirs.n_theta, params.dirs.n_phi],
            method: params.method,
            fast: None,
            allow_open: params.allow_open,
        };
        let gdm = GdmPayload::Occupancy(field);
        seconds.bake = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let bytes = Package::encode(input, info, &gdm);
        seconds.encode = start.elapsed().as_secs_f64();
        return Ok(BakedPackage {
            bytes,
            gdm,
            seconds,
        });
    }
    let mut g = gdm::bake(
        meso.caster(),
        params.dirs,
        params.method,
        params.fast,
        limits,
        observer,
    )?;
    g.set_escape_convention(EscapeConvention::Boundary);
    seconds.bake = start.elapsed().as_secs_f64();

    let info = bake_info(&g, params.method, params.fast, params.allow_open);
    observer.stage("compress");
    let gdm = GdmPayload::PaperSvd(Box::new(compress_gdm(
        &g,
        params,
        limits,
        observer,
        &mut seconds,
    )?));
    let start = Instant::now();
    let bytes = Package::encode(input, info, &gdm);
    seconds.encode = start.elapsed().as_secs_f64();
    Ok(BakedPackage {
        bytes,
        gdm,
        seconds,
    })
}

/// The SVD and quantization of `g` (boundary escape convention) with `params`' rank and
/// quantization, timed into `seconds`; `observer` may cancel them until the SVD's Gram matrix
/// is formed.
pub fn compress_gdm(
    g: &Gdm,
    params: &PackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
    seconds: &mut StageSeconds,
) -> Result<CompressedGdm> {
    let start = Instant::now();
    let gram = GramEigen::observed(&GdmRows::new(g)?, limits, observer)?;
    let gram_s = start.elapsed().as_secs_f64();
    let compressed = compress(g, &gram, params.rank, params.quantization, limits)?;
    seconds.svd = gram_s + compressed.seconds.svd;
    seconds.quantize = compressed.seconds.quantize;
    Ok(compressed)
}
