//! The package commands: `mesobake bake` (an input's or a scene's package, here or on a
//! server), `mesobake fetch` (a verified download) and `mesobake unpack` (a package back to
//! `.npy` and EXR).

use super::codec::CodecOptions;
use super::gdm::BakeOptions;
use super::output::{Progress, print_json};
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::gdm::Method;
use mesobake_bake::gdm::npy::write_gdm;
use mesobake_bake::package::bake::{PackageParams, bake_package};
use mesobake_bake::package::container;
use mesobake_bake::package::manifest::{Section, TextureDimension};
use mesobake_bake::package::vdm::VdmPackage;
use mesobake_bake::package::{GdmPayload, Package};
use mesobake_bake::vdm::{NO_HIT, VdmGrid};
use mesobake_core::fs::{read_bounded, write_atomic};
use mesobake_core::limits::Limits;
use mesobake_core::npy::write_array;
use mesobake_core::{Error, Result};
use mesobake_package::grid::Dims;
use mesobake_package::vdm::{VDM_FORMAT_NAME, VdmQuery};
use mesobake_scene::LoadedScene;
use mesobake_scene::objects::{self, SceneObject};
use mesobake_scene::package::{ScenePayload, bake_scene_package, plan_package};
use mesobake_server::client::Client;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `mesobake bake`.
#[derive(clap::Args)]
pub struct BakeArgs {
    #[command(flatten)]
    bake: BakeOptions,
    /// Bake a scene's package instead of an input's, for the technique the scene chooses: a
    /// VDM package (its `vdm` settings), or a GDM package on the scene's grids with exactly
    /// the stages its effects call for (PRT and RTV with environment lighting); --json
    /// lists the technique and the stages run and skipped, with reasons.
    #[arg(long, conflicts_with_all = ["input", "res", "max_rmse", "server", "method", "allow_open"])]
    scene: Option<PathBuf>,
    /// Output package (.mbpkg); for a scene of several objects, the folder that receives one
    /// package per object, NAME.mbpkg.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    codec: CodecOptions,
    /// Keep the fewest SVD components whose optimal RMSE (voxels) is at most this, paper-svd
    /// only.
    #[arg(long, conflicts_with = "rank")]
    max_rmse: Option<f64>,
    /// Print a JSON summary (sizes, rank, errors, seconds per stage) on stdout.
    #[arg(long)]
    json: bool,
    /// Bake on this server (e.g. http://127.0.0.1:8080) instead of here: upload the input,
    /// follow the job, download and verify the package (exact method, --rank only).
    #[arg(long)]
    server: Option<String>,
    /// API key for --server (default: the MESOBAKE_API_KEY environment variable).
    #[arg(long)]
    api_key: Option<String>,
}

/// Bakes a scene's package, an input's package on a server, or an input's package here.
pub fn bake(args: BakeArgs, limits: &Limits) -> Result<()> {
    args.codec
        .check(args.max_rmse.is_some().then_some("--max-rmse"))?;
    if let Some(scene) = &args.scene {
        return bake_scene(scene, &args, limits);
    }
    if let Some(server) = &args.server {
        return bake_on_server(server, args.api_key.clone(), &args, limits);
    }
    bake_input(&args, limits)
}

/// `bake --scene` of a scene with several objects: one package per object (what each object's
/// real-time renderer reads), `OUT/NAME.mbpkg`, every object planned before any is baked.
fn bake_objects(
    scene: &Path,
    objects: Vec<SceneObject>,
    args: &BakeArgs,
    limits: &Limits,
) -> Result<()> {
    let params = args.codec.scene_params();
    let dir = scene.parent().unwrap_or(Path::new("."));
    let mut files = std::collections::BTreeSet::new();
    let mut outputs = Vec::new();
    for object in &objects {
        plan_package(&object.scene, dir, params, limits)
            .map_err(|e| e.context(format!("object {:?}", object.name)))?;
        let file: String = object
            .name
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if !files.insert(file.clone()) {
            return Err(Error::Scene(format!(
                "two objects are named {file:?} as files: name them apart"
            )));
        }
        outputs.push(args.out.join(format!("{file}.mbpkg")));
    }
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let mut summaries = Vec::new();
    for (object, out) in objects.into_iter().zip(outputs) {
        let name = object.name;
        let loaded = LoadedScene::load(object.scene, dir, limits)
            .map_err(|e| e.context(format!("object {name:?}")))?;
        let progress = Progress::new(&format!("baking {name}"));
        let baked = bake_scene_package(&loaded, dir, params, limits, &progress)?;
        progress.finish();
        write_atomic(&out, &baked.bytes)?;
        eprintln!(
            "wrote {} ({} bytes): {name}, {} package",
            out.display(),
            baked.bytes.len(),
            baked.plan.technique.technique.name(),
        );
        summaries.push(serde_json::json!({
            "name": name,
            "output": out,
            "bytes": baked.bytes.len(),
            "plan": baked.plan,
        }));
    }
    if args.json {
        print_json(&serde_json::json!({ "scene": scene, "objects": summaries }));
    }
    Ok(())
}

/// `bake --scene`: the stages the scene's effects call for.
fn bake_scene(scene: &Path, args: &BakeArgs, limits: &Limits) -> Result<()> {
    let out = &args.out;
    let start = Instant::now();
    let params = args.codec.scene_params();
    let dir = scene.parent().unwrap_or(Path::new("."));
    let mut objects = objects::read(scene)?;
    if objects.len() > 1 {
        return bake_objects(scene, objects, args, limits);
    }
    // Planned first: a bake the memory limit cannot hold is refused before loading.
    let read = objects.remove(0).scene;
    plan_package(&read, dir, params, limits)?;
    let loaded = LoadedScene::load(read, dir, limits)?;
    let load_s = start.elapsed().as_secs_f64();
    let progress = Progress::new("baking");
    let baked = bake_scene_package(&loaded, dir, params, limits, &progress)?;
    progress.finish();
    let start = Instant::now();
    write_atomic(out, &baked.bytes)?;
    let write_s = start.elapsed().as_secs_f64();
    let technique = &baked.plan.technique;
    eprintln!(
        "wrote {} ({} bytes): {} package ({}); stages {}",
        out.display(),
        baked.bytes.len(),
        technique.technique.name(),
        technique.reason,
        baked.plan.stages.join(", ")
    );
    if args.json {
        let mut seconds = serde_json::Map::new();
        seconds.insert("load".into(), load_s.into());
        for (stage, s) in &baked.seconds {
            seconds.insert(stage.clone(), (*s).into());
        }
        seconds.insert("write".into(), write_s.into());
        print_json(&serde_json::json!({
            "scene": scene,
            "output": out,
            "bytes": baked.bytes.len(),
            "plan": baked.plan,
            "seconds": seconds,
            "technique": baked.plan.technique.technique,
            "gdm": match &baked.payload {
                ScenePayload::Gdm(payload) => payload_summary(payload),
                _ => serde_json::Value::Null,
            },
            "vdm": match &baked.payload {
                ScenePayload::Vdm { rank, mvm_rank, quantization, accuracy } => serde_json::json!({
                    "rank": rank,
                    "mvm_rank": mvm_rank,
                    "quantization": quantization,
                    "accuracy": accuracy,
                }),
                _ => serde_json::Value::Null,
            },
            "medium": match &baked.payload {
                ScenePayload::Medium { levels, quantization, accuracy } => serde_json::json!({
                    "levels": levels,
                    "quantization": quantization,
                    "accuracy": accuracy,
                }),
                _ => serde_json::Value::Null,
            },
            "gi": baked.gi,
        }));
    }
    Ok(())
}

/// `bake --server`: upload, follow the job, download and verify.
fn bake_on_server(
    server: &str,
    api_key: Option<String>,
    args: &BakeArgs,
    limits: &Limits,
) -> Result<()> {
    let (bake, out) = (&args.bake, &args.out);
    if args.max_rmse.is_some() || bake.method != Method::Exact || bake.allow_open {
        return Err(Error::InvalidParameter(
            "--server bakes with the exact method and an explicit --rank; \
             --max-rmse, --method fast and --allow-open are local only"
                .into(),
        ));
    }
    let client = client(server, api_key)?;
    let asset = client.upload(bake.input()?, limits)?;
    let res = match bake.res {
        Some(r) => r,
        None => {
            let d = &asset["summary"]["dims"];
            let dim = |i: usize| d[i].as_u64().unwrap_or(0) as u32;
            Dims::new(dim(0), dim(1), dim(2))
                .map_err(|_| Error::InvalidParameter("--res is required for OBJ tiles".into()))?
        }
    };
    let job = client.submit(
        &asset,
        res,
        bake.dirs,
        args.codec.gdm_codec,
        args.codec.rank(),
        args.codec.quant.unwrap_or_default(),
    )?;
    let id = job["id"].as_str().unwrap_or_default().to_owned();
    let bar = Progress::new(&format!("job {}", &id[..8.min(id.len())]));
    let done = client.wait(&id, |j| {
        bar.set(
            (j["progress"].as_f64().unwrap_or(0.0) * 1000.0) as u64,
            1000,
        )
    })?;
    bar.finish();
    let digest = done["package_digest"].as_str().unwrap_or_default();
    let bytes = client.fetch(digest, limits)?;
    write_atomic(out, &bytes)?;
    eprintln!(
        "wrote {} ({} bytes, package {digest}) from job {id}",
        out.display(),
        bytes.len()
    );
    if args.json {
        print_json(
            &serde_json::json!({ "output": out, "bytes": bytes.len(), "digest": digest, "job": done }),
        );
    }
    Ok(())
}

/// What a package's GDM payload is, for `--json`: the codec, and the SVD's rank, format and
/// measured error, or the occupancy's solid voxels.
fn payload_summary(payload: &GdmPayload) -> serde_json::Value {
    match payload {
        GdmPayload::PaperSvd(g) => serde_json::json!({
            "codec": payload.codec(),
            "rank": g.svd.rank,
            "quantization": g.weights.format,
            "accuracy": g.accuracy,
            "svd_rmse": g.svd.optimal_rmse(g.svd.rank),
        }),
        GdmPayload::Occupancy(field) => serde_json::json!({
            "codec": payload.codec(),
            "solid_voxels": field.solid_voxels(),
        }),
    }
}

/// `bake --input`: bake, compress, measure and write here.
fn bake_input(args: &BakeArgs, limits: &Limits) -> Result<()> {
    let (bake, out) = (&args.bake, &args.out);
    let params = PackageParams {
        res: bake.res,
        dirs: bake.dirs,
        codec: args.codec.gdm_codec,
        method: bake.method,
        fast: bake.fast(),
        rank: match args.max_rmse {
            Some(e) => RankChoice::MaxRmse(e),
            None => RankChoice::Rank(args.codec.rank()),
        },
        quantization: args.codec.quant.unwrap_or_default(),
        allow_open: bake.allow_open,
    };
    let progress = Progress::new("baking");
    let baked = bake_package(bake.input()?, &params, limits, &progress)?;
    progress.finish();
    let start = Instant::now();
    write_atomic(out, &baked.bytes)?;
    let write_s = start.elapsed().as_secs_f64();
    match &baked.gdm {
        GdmPayload::PaperSvd(g) => eprintln!(
            "wrote {} ({} bytes): paper-svd, rank {}, {}, RMSE {:.4} voxel, max {:.3}, \
             hit/escape flips {:.4} %",
            out.display(),
            baked.bytes.len(),
            g.svd.rank,
            g.weights.format,
            g.accuracy.rmse,
            g.accuracy.max_abs,
            100.0 * g.accuracy.flip_rate
        ),
        GdmPayload::Occupancy(field) => eprintln!(
            "wrote {} ({} bytes): occupancy, {} solid voxels of {}",
            out.display(),
            baked.bytes.len(),
            field.solid_voxels(),
            field.dims().voxel_count()
        ),
    }
    if args.json {
        print_json(&serde_json::json!({
            "input": bake.input,
            "output": out,
            "bytes": baked.bytes.len(),
            "gdm": payload_summary(&baked.gdm),
            "seconds": {
                "load": baked.seconds.load,
                "bake": baked.seconds.bake,
                "svd": baked.seconds.svd,
                "quantize": baked.seconds.quantize,
                "encode": baked.seconds.encode,
                "write": write_s,
            },
        }));
    }
    Ok(())
}

/// A client of `server` with `api_key`, else the MESOBAKE_API_KEY environment variable.
fn client(server: &str, api_key: Option<String>) -> Result<Client> {
    Client::new(
        server,
        api_key.or_else(|| std::env::var("MESOBAKE_API_KEY").ok()),
    )
}

/// Options of `mesobake fetch`.
#[derive(clap::Args)]
pub struct FetchArgs {
    /// The server, e.g. http://127.0.0.1:8080.
    #[arg(long)]
    server: String,
    /// The package's digest.
    digest: String,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
    /// API key (default: the MESOBAKE_API_KEY environment variable).
    #[arg(long)]
    api_key: Option<String>,
}

/// Downloads, verifies and writes a package.
pub fn fetch(args: FetchArgs, limits: &Limits) -> Result<()> {
    let client = client(&args.server, args.api_key)?;
    let bytes = client.fetch(&args.digest, limits)?;
    write_atomic(&args.out, &bytes)?;
    eprintln!(
        "wrote {} ({} bytes, verified)",
        args.out.display(),
        bytes.len()
    );
    Ok(())
}

/// Options of `mesobake unpack`.
#[derive(clap::Args)]
pub struct UnpackArgs {
    /// The package.
    package: PathBuf,
    /// Write the reconstructed GDM (or VDM, −1 for silhouettes) as a .npy file.
    #[arg(long, required_unless_present_any = ["exr", "ktx2"])]
    out: Option<PathBuf>,
    /// Also write the dequantized factor maps as a multi-layer OpenEXR image.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Also write every texture section as a KTX 2.0 file `<section>.ktx2` in this directory
    /// (created if missing), for engines' texture tooling.
    #[arg(long)]
    ktx2: Option<PathBuf>,
}

/// Writes a package's reconstruction, factor maps or textures, as asked.
pub fn unpack(args: UnpackArgs, limits: &Limits) -> Result<()> {
    let bytes = read_bounded(&args.package, "package", limits.memory_bytes)?;
    let context = |e: mesobake_package::Error| Error::from(e).context(args.package.display());
    if container::format(&bytes).map_err(context)? == VDM_FORMAT_NAME {
        let pkg = VdmPackage::parse_within(bytes, limits.memory_bytes).map_err(context)?;
        if args.exr.is_some() {
            return Err(Error::InvalidParameter(
                "--exr writes a GDM package's factor maps; this is a VDM package".into(),
            ));
        }
        if let Some(out) = &args.out {
            let values = reconstruct_vdm(
                &pkg.query(),
                &pkg.manifest().bake.grid,
                pkg.manifest().relief.size,
            );
            let g = pkg.manifest().bake.grid;
            let [w, h] = pkg.manifest().relief.size;
            let shape = [g.n_curvature, g.n_theta, g.n_phi, h, w].map(u64::from);
            write_array(out, &shape, &values)?;
        }
        return write_ktx2(args.ktx2.as_deref(), &pkg.manifest().sections, |name| {
            pkg.section(name)
        });
    }
    let pkg =
        Package::parse_within(bytes, limits).map_err(|e| e.context(args.package.display()))?;
    if let Some(out) = &args.out {
        write_gdm(&pkg.reconstruct(limits)?, out)?;
    }
    if let Some(path) = args.exr {
        mesobake_bake::package::exr_export::write_factors(&pkg, &path)?;
    }
    write_ktx2(args.ktx2.as_deref(), &pkg.manifest().sections, |name| {
        pkg.section(name)
    })
}

/// A VDM package's reconstruction in the bake's layout, −1 where its MVM calls the view a
/// silhouette.
fn reconstruct_vdm(query: &VdmQuery, g: &VdmGrid, [w, h]: [u32; 2]) -> Vec<f32> {
    let mut values = Vec::with_capacity((g.n_curvature * g.n_theta * g.n_phi * w * h) as usize);
    for k in 0..g.n_curvature {
        for a in 0..g.n_theta {
            for b in 0..g.n_phi {
                for j in 0..h {
                    for i in 0..w {
                        values.push(query.distance(i, j, a, b, k).unwrap_or(NO_HIT));
                    }
                }
            }
        }
    }
    values
}

/// Writes every texture section as `<name>.ktx2` in `dir`, when asked.
fn write_ktx2<'a>(
    dir: Option<&Path>,
    sections: &[Section],
    bytes_of: impl Fn(&str) -> Option<&'a [u8]>,
) -> Result<()> {
    let Some(dir) = dir else { return Ok(()) };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut written = 0;
    for section in sections {
        if section.texture.dimension == TextureDimension::Buffer {
            continue;
        }
        let data = bytes_of(&section.name).expect("listed");
        let file = mesobake_bake::package::ktx2::write(&section.texture, data)?;
        write_atomic(&dir.join(format!("{}.ktx2", section.name)), &file)?;
        written += 1;
    }
    eprintln!("wrote {written} KTX2 textures to {}", dir.display());
    Ok(())
}
