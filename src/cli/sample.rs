//! `mesobake sample` (a built-in sample as a volume or an OBJ tile), `mesobake import` (a
//! translucent medium from a raw RGBA file) and `mesobake demo` (a sample baked end to end
//! with a flat preview).

use super::output::Progress;
use clap::ValueEnum;
use mesobake_bake::gdm;
use mesobake_bake::gdm::npy;
use mesobake_bake::mesostructure::file_kind::FileKind;
use mesobake_bake::mesostructure::openvdb::{self, VdbImport};
use mesobake_bake::mesostructure::raw_medium::{self, RawFormat};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume_format;
use mesobake_core::fs::{read_bounded, write_atomic};
use mesobake_core::limits::Limits;
use mesobake_core::{Error, Result};
use mesobake_package::grid::{Dims, DirectionGrid};
use mesobake_render::flat_preview;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `mesobake sample`.
#[derive(clap::Args)]
pub struct SampleArgs {
    /// Which sample.
    kind: SampleKind,
    /// Grid X×Y×Z (X = Y); for OBJ tiles it sets the tile's height Z/X.
    #[arg(long, default_value = "64x64x32")]
    res: Dims,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
    /// Output kind.
    #[arg(long, value_enum, default_value_t = SampleFormat::Volume)]
    format: SampleFormat,
}

/// What `mesobake sample` writes.
#[derive(Clone, Copy, ValueEnum)]
enum SampleFormat {
    /// Binary voxel volume (.mbvol).
    Volume,
    /// Closed OBJ triangle tile.
    Obj,
}

/// Writes the sample.
pub fn sample(args: SampleArgs, limits: &Limits) -> Result<()> {
    let SampleArgs {
        kind,
        res,
        out,
        format,
    } = args;
    match format {
        SampleFormat::Volume => {
            let volume = samples::volume(kind, res, limits)?;
            volume_format::write(&volume, &out)
        }
        SampleFormat::Obj => {
            let mesh = samples::mesh(kind, res)?;
            let comment = format!(
                "mesobake sample {} tile: x, y period 1, z in [0, {}]",
                kind.name(),
                res.z as f64 / res.x as f64
            );
            write_atomic(&out, mesh.to_obj(&comment).as_bytes())
        }
    }
}

/// Options of `mesobake import`.
#[derive(clap::Args)]
pub struct ImportArgs {
    /// The voxels: an OpenVDB file (a level set becomes an opaque volume, a fog volume a
    /// translucent medium: docs/scene-format.md), a raw file (x fastest, then y, then z; RGB
    /// sRGB-encoded, A the opacity per voxel length) or an OpenEXR image (linear RGB, A the
    /// opacity; the Z slices stacked downwards, X wide and Y·Z tall).
    input: PathBuf,
    /// Grid X×Y×Z: of a raw or EXR file (required), or the index box of an OpenVDB grid from
    /// index (0, 0, 0) (by default its active voxels' bounding box).
    #[arg(long)]
    res: Option<Dims>,
    /// How the file stores the voxels (by default told by its content: OpenVDB and OpenEXR
    /// by their magic numbers, anything else raw RGBA8).
    #[arg(long, value_enum)]
    format: Option<ImportFormat>,
    /// The OpenVDB grid to import (by default the first level set or fog volume, else the
    /// float grid named `density`).
    #[arg(long)]
    grid: Option<String>,
    /// Multiplies an OpenVDB fog volume's density: a voxel's opacity is
    /// 1 − exp(−scale·density·voxel size).
    #[arg(long, default_value_t = 1.0)]
    density_scale: f64,
    /// Output volume (.mbvol, version 2).
    #[arg(long)]
    out: PathBuf,
}

/// The file formats `mesobake import` reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ImportFormat {
    /// OpenVDB: a level set or a fog volume.
    Vdb,
    /// Raw, one byte per channel, value/255.
    Rgba8,
    /// Raw, one little-endian f32 per channel, in [0, 1].
    Rgba32f,
    /// OpenEXR, the first layer's R, G, B and A channels.
    Exr,
}

/// Reads the input (its size checked before its voxels are read) and writes it as a volume.
pub fn import(args: ImportArgs, limits: &Limits) -> Result<()> {
    let ImportArgs {
        input,
        res,
        format,
        grid,
        density_scale,
        out,
    } = args;
    let format = match format {
        Some(format) => format,
        None => match FileKind::of_file(&input)? {
            FileKind::OpenVdb => ImportFormat::Vdb,
            FileKind::Exr => ImportFormat::Exr,
            _ => ImportFormat::Rgba8,
        },
    };
    let vdb_options = grid.is_some() || density_scale != 1.0;
    if vdb_options && format != ImportFormat::Vdb {
        return Err(Error::InvalidParameter(format!(
            "--grid and --density-scale apply to OpenVDB files; {} is read as {format:?}",
            input.display()
        )));
    }
    if format == ImportFormat::Vdb {
        return import_vdb(&input, res, grid, density_scale, &out, limits);
    }
    let res = res.ok_or_else(|| {
        Error::InvalidParameter(format!(
            "--res X×Y×Z is required to read {} as {format:?}",
            input.display()
        ))
    })?;
    let raw = match format {
        ImportFormat::Rgba8 => RawFormat::Rgba8,
        ImportFormat::Rgba32f => RawFormat::Rgba32f,
        ImportFormat::Exr | ImportFormat::Vdb => {
            let volume = raw_medium::medium_from_exr(&input, res, limits)?;
            return volume_format::write(&volume, &out);
        }
    };
    let len = std::fs::metadata(&input)
        .map_err(|e| Error::io(&input, e))?
        .len();
    raw_medium::check_size(len, res, raw, limits)?;
    let bytes = read_bounded(&input, "raw medium", limits.memory_bytes)?;
    let volume = raw_medium::medium_from_raw(&bytes, res, raw, limits)?;
    volume_format::write(&volume, &out)
}

/// Imports a grid of the OpenVDB file `input` and says what it became.
fn import_vdb(
    input: &Path,
    res: Option<Dims>,
    grid: Option<String>,
    density_scale: f64,
    out: &Path,
    limits: &Limits,
) -> Result<()> {
    let bytes = read_bounded(input, "OpenVDB file", limits.memory_bytes)?;
    let options = VdbImport {
        grid,
        res,
        density_scale,
    };
    let (volume, imported) =
        openvdb::import(&bytes, &options, limits).map_err(|e| e.context(input.display()))?;
    drop(bytes);
    volume_format::write(&volume, out)?;
    let [x, y, z] = imported.dims;
    let what = if imported.class == "level set" {
        "an opaque volume"
    } else {
        "a medium"
    };
    eprintln!(
        "imported the {} {:?} (voxel size {}) as {what} of {x}x{y}x{z} voxels from index {:?}{}",
        imported.class,
        imported.grid,
        imported.voxel_size,
        imported.origin,
        match &imported.color_grid {
            Some(c) => format!(", coloured by {c:?}"),
            None => String::new(),
        }
    );
    Ok(())
}

/// Options of `mesobake demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// Which sample.
    #[arg(long, value_enum, default_value_t = SampleKind::Chain)]
    sample: SampleKind,
    /// Grid X×Y×Z.
    #[arg(long, default_value = "64x64x32")]
    res: Dims,
    /// Output directory.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
}

/// Bakes the sample and renders its flat preview into the output directory.
pub fn demo(args: DemoArgs, limits: &Limits) -> Result<()> {
    let DemoArgs { sample, res, out } = args;
    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    let name = sample.name();
    let volume = samples::volume(sample, res, limits)?;
    volume_format::write(&volume, &out.join(format!("{name}.mbvol")))?;
    let mesh = samples::mesh(sample, res)?;
    let obj = out.join(format!("{name}.obj"));
    write_atomic(&obj, mesh.to_obj(name).as_bytes())?;
    let progress = Progress::new("baking GDM (exact)");
    let start = Instant::now();
    let caster = gdm::volume_caster::VolumeCaster::new(&volume);
    let g = gdm::exact::bake(&caster, DirectionGrid::PAPER, limits, &progress)?;
    progress.finish();
    eprintln!(
        "baked the {res} {name} GDM in {:.2} s",
        start.elapsed().as_secs_f64()
    );
    npy::write_gdm(&g, &out.join(format!("{name}-gdm.npy")))?;
    let setup = flat_preview::default_setup(&g);
    let rgb = flat_preview::render(&volume, &g, &setup)?;
    let png = flat_preview::encode_png(&rgb, setup.size, setup.size)?;
    let path = out.join(format!("{name}-preview.png"));
    write_atomic(&path, &png)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
