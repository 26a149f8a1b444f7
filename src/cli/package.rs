//! The package commands: `mesobake bake` (an input's or a scene's package, here or on a
//! server), `mesobake fetch` (a verified download) and `mesobake unpack` (a package back to
//! `.npy` and EXR).

use super::gdm::BakeOptions;
use super::output::{Progress, print_json};
use mesobake::bake::gdm::Method;
use mesobake::client::Client;
use mesobake::compress::quantize::Quantization;
use mesobake::compress::svd::RankChoice;
use mesobake::grid::Dims;
use mesobake::package::Package;
use mesobake::package::bake::{PackageParams, bake_package};
use mesobake::scene::package::{ScenePackageParams, bake_scene_package};
use mesobake::scene::render::load_scene;
use mesobake::util::fs::write_atomic;
use mesobake::util::limits::Limits;
use mesobake::util::npy;
use mesobake::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `mesobake bake`.
#[derive(clap::Args)]
pub struct BakeArgs {
    #[command(flatten)]
    bake: BakeOptions,
    /// Bake a scene's package instead of an input's: the GDM on the scene's grids and
    /// exactly the stages its effects call for (PRT and RTV with environment lighting);
    /// --json lists the stages run and skipped, with reasons.
    #[arg(long, conflicts_with_all = ["input", "res", "max_rmse", "server", "method", "allow_open"])]
    scene: Option<PathBuf>,
    /// Output package (.mbpkg).
    #[arg(long)]
    out: PathBuf,
    /// SVD components to keep [default: 8].
    #[arg(long, conflicts_with = "max_rmse")]
    rank: Option<usize>,
    /// Keep the fewest components whose optimal RMSE (voxels) is at most this.
    #[arg(long)]
    max_rmse: Option<f64>,
    /// Number format of weight maps and eigenmaps: f32, f16, or u8 (per-map scale and bias).
    #[arg(long, default_value = "f16")]
    quant: Quantization,
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
    if let Some(scene) = &args.scene {
        return bake_scene(scene, &args, limits);
    }
    if let Some(server) = &args.server {
        return bake_on_server(server, args.api_key.clone(), &args);
    }
    bake_input(&args, limits)
}

/// `bake --scene`: the stages the scene's effects call for.
fn bake_scene(scene: &Path, args: &BakeArgs, limits: &Limits) -> Result<()> {
    let (out, quant) = (&args.out, args.quant);
    let start = Instant::now();
    let loaded = load_scene(scene, limits)?;
    let load_s = start.elapsed().as_secs_f64();
    let params = ScenePackageParams {
        rank: RankChoice::Rank(args.rank.unwrap_or(8)),
        quantization: quant,
    };
    let dir = scene.parent().unwrap_or(Path::new("."));
    let progress = Progress::new("baking GDM");
    let baked = bake_scene_package(&loaded, dir, params, limits, &progress)?;
    progress.finish();
    let start = Instant::now();
    write_atomic(out, &baked.bytes)?;
    let write_s = start.elapsed().as_secs_f64();
    eprintln!(
        "wrote {} ({} bytes): stages {}",
        out.display(),
        baked.bytes.len(),
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
            "gdm": {
                "rank": baked.gdm.svd.rank,
                "quantization": quant,
                "accuracy": baked.gdm.accuracy,
                "svd_rmse": baked.gdm.svd.optimal_rmse(baked.gdm.svd.rank),
            },
            "gi": baked.gi,
        }));
    }
    Ok(())
}

/// `bake --server`: upload, follow the job, download and verify.
fn bake_on_server(server: &str, api_key: Option<String>, args: &BakeArgs) -> Result<()> {
    let (bake, out) = (&args.bake, &args.out);
    if args.max_rmse.is_some() || bake.method != Method::Exact || bake.allow_open {
        return Err(Error::InvalidParameter(
            "--server bakes with the exact method and an explicit --rank; \
             --max-rmse, --method fast and --allow-open are local only"
                .into(),
        ));
    }
    let client = client(server, api_key)?;
    let asset = client.upload(bake.input()?)?;
    let res = match bake.res {
        Some(r) => r,
        None => {
            let d = &asset["summary"]["dims"];
            let dim = |i: usize| d[i].as_u64().unwrap_or(0) as u32;
            Dims::new(dim(0), dim(1), dim(2))
                .map_err(|_| Error::InvalidParameter("--res is required for OBJ tiles".into()))?
        }
    };
    let job = client.submit(&asset, res, bake.dirs, args.rank.unwrap_or(8), args.quant)?;
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
    let bytes = client.fetch(digest)?;
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

/// `bake --input`: bake, compress, measure and write here.
fn bake_input(args: &BakeArgs, limits: &Limits) -> Result<()> {
    let (bake, out, quant) = (&args.bake, &args.out, args.quant);
    let params = PackageParams {
        res: bake.res,
        dirs: bake.dirs,
        method: bake.method,
        fast: bake.fast(),
        rank: match args.max_rmse {
            Some(e) => RankChoice::MaxRmse(e),
            None => RankChoice::Rank(args.rank.unwrap_or(8)),
        },
        quantization: quant,
        allow_open: bake.allow_open,
    };
    let progress = Progress::new("baking GDM");
    let baked = bake_package(bake.input()?, &params, limits, &progress)?;
    progress.finish();
    let start = Instant::now();
    write_atomic(out, &baked.bytes)?;
    let write_s = start.elapsed().as_secs_f64();
    let a = &baked.gdm.accuracy;
    eprintln!(
        "wrote {} ({} bytes): rank {}, {quant}, RMSE {:.4} voxel, max {:.3}, \
         hit/escape flips {:.4} %",
        out.display(),
        baked.bytes.len(),
        baked.gdm.svd.rank,
        a.rmse,
        a.max_abs,
        100.0 * a.flip_rate
    );
    if args.json {
        print_json(&serde_json::json!({
            "input": bake.input,
            "output": out,
            "bytes": baked.bytes.len(),
            "rank": baked.gdm.svd.rank,
            "quantization": quant,
            "accuracy": a,
            "svd_rmse": baked.gdm.svd.optimal_rmse(baked.gdm.svd.rank),
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
pub fn fetch(args: FetchArgs) -> Result<()> {
    let client = client(&args.server, args.api_key)?;
    let bytes = client.fetch(&args.digest)?;
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
    /// Output .npy file.
    #[arg(long)]
    out: PathBuf,
    /// Also write the dequantized factor maps as a multi-layer OpenEXR image.
    #[arg(long)]
    exr: Option<PathBuf>,
}

/// Writes a package's reconstruction (and optionally its factor maps).
pub fn unpack(args: UnpackArgs, limits: &Limits) -> Result<()> {
    let pkg = Package::read(&args.package, limits)?;
    let g = pkg.reconstruct(limits)?;
    npy::write_gdm(&g, &args.out)?;
    if let Some(path) = args.exr {
        mesobake::package::exr_export::write_factors(&pkg, &path)?;
    }
    Ok(())
}
