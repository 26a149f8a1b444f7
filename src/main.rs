//! The `mesobake` command line.

use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use mesobake::bake::gdm::{self, BakeObserver, Method};
use mesobake::bench::bakes as bench;
use mesobake::bench::counting_alloc::CountingAlloc;
use mesobake::client::Client;
use mesobake::compress::quantize::Quantization;
use mesobake::compress::svd::RankChoice;
use mesobake::grid::{Dims, DirectionGrid};
use mesobake::mesostructure::samples::{self, SampleKind};
use mesobake::mesostructure::{input, volume_format};
use mesobake::package::Package;
use mesobake::package::bake::{PackageParams, bake_package};
use mesobake::render::gdm_renderer::Substitutions;
use mesobake::render::image::{Image, compare, difference};
use mesobake::report::{accuracy as report, render as render_report};
use mesobake::scene::package::{ScenePackageParams, bake_scene_package, scene_package};
use mesobake::scene::preview::preview;
use mesobake::scene::render::{self as render_scene, GdmSource, RenderMethod};
use mesobake::util::fs::write_atomic;
use mesobake::util::limits::{Limits, parse_bytes};
use mesobake::util::npy;
use mesobake::{Error, Result};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[global_allocator]
static ALLOCATOR: CountingAlloc = CountingAlloc::new();

#[derive(Parser)]
#[command(
    name = "mesobake",
    version,
    about = "Bake mesostructure: generalized displacement maps and more"
)]
struct Cli {
    /// Largest allocation that input may ask for (e.g. 4GiB); default from
    /// MESOBAKE_MEMORY_LIMIT, else 4GiB.
    #[arg(long, global = true)]
    memory_limit: Option<String>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write a built-in procedural sample as a volume (.mbvol) or an OBJ tile.
    Sample {
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
    },
    /// Bake the GDM of a volume or OBJ tile and write it as .npy (float32, shape
    /// (X, Y, Z, Nθ, Nφ), voxel units, escapes +inf, inside 0).
    Gdm {
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
    },
    /// Bake a GDM package (.mbpkg) for CI builds: bake, SVD-compress, quantize, measure the
    /// error and write the package. Output is byte-identical for identical inputs and options.
    Bake {
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
    },
    /// Download a package from a server and verify it (its bytes must hash to DIGEST and parse
    /// as a package) before writing it.
    Fetch {
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
    },
    /// Reconstruct the dense GDM from a package into .npy (the convention of `mesobake gdm`:
    /// escapes +inf), optionally exporting the weight maps and eigenmaps as a multi-layer EXR.
    Unpack {
        /// The package.
        package: PathBuf,
        /// Output .npy file.
        #[arg(long)]
        out: PathBuf,
        /// Also write the dequantized factor maps as a multi-layer OpenEXR image.
        #[arg(long)]
        exr: Option<PathBuf>,
    },
    /// Bake a built-in sample end to end and render a preview from its GDM: writes
    /// SAMPLE.mbvol, SAMPLE.obj, SAMPLE-gdm.npy and SAMPLE-preview.png into --out.
    Demo {
        /// Which sample.
        #[arg(long, value_enum, default_value_t = SampleKind::Chain)]
        sample: SampleKind,
        /// Grid X×Y×Z.
        #[arg(long, default_value = "64x64x32")]
        res: Dims,
        /// Output directory.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
    },
    /// Render a scene file on the CPU with the ground truth or the GDM algorithm: .png
    /// (8-bit sRGB, alpha = hit mask) or .exr (linear float, A = hit mask).
    Render {
        /// The scene (JSON; see docs/scene-format.md).
        #[arg(long)]
        scene: PathBuf,
        /// truth: exact mapping into the real mesostructure; gdm: the real-time algorithm.
        #[arg(long, default_value = "gdm")]
        method: RenderMethod,
        /// For --method gdm: render from this package instead of baking the exact GDM.
        #[arg(long)]
        package: Option<PathBuf>,
        /// Output image (.png or .exr).
        #[arg(long)]
        out: PathBuf,
        /// Print a JSON summary (seconds per stage, hit pixels, shell report) on stdout.
        #[arg(long)]
        json: bool,
        /// For --method gdm, a reference run: parts of the algorithm replaced, comma-separated
        /// (query, frame: exact; shell-shadows: the GDM algorithm traced to the light through
        /// the shell; shadows: the truth's rays). See `report render`'s error budget.
        #[arg(long, default_value = "none")]
        substitute: Substitutions,
    },
    /// Render a scene with the real-time pipeline (WGSL shaders on wgpu, headless, on any
    /// adapter including Mesa's software Vulkan driver) from a package, or from one baked for
    /// the scene (exact GDM, then --rank and --quant): .png or .exr as for `render`.
    Preview {
        /// The scene (JSON; see docs/scene-format.md).
        #[arg(long)]
        scene: PathBuf,
        /// Output image (.png or .exr).
        #[arg(long)]
        out: PathBuf,
        /// Render from this package (its grid must be the scene's) instead of baking one.
        #[arg(long)]
        package: Option<PathBuf>,
        /// SVD components of the baked package.
        #[arg(long, default_value_t = 8, conflicts_with = "package")]
        rank: usize,
        /// Number format of the baked package: f32, f16 or u8.
        #[arg(long, default_value = "f16", conflicts_with = "package")]
        quant: Quantization,
        /// Also render this many frames and report the mean frame time.
        #[arg(long, default_value_t = 0)]
        frames: u32,
        /// Use the adapter whose name contains this (case-insensitive; default: the
        /// MESOBAKE_ADAPTER environment variable, else wgpu's choice).
        #[arg(long)]
        adapter: Option<String>,
        /// Print a JSON summary (adapter, shader variant, GPU memory, seconds) on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Run the baking server: the HTTP API under /api/v1 on the configured address
    /// (default 127.0.0.1:8080) over SQLite or PostgreSQL and the local blob store.
    Serve {
        /// A TOML file overriding config/default.toml (then MESOBAKE_* variables override it).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Run bake workers only (no HTTP server) against the configured database and blob
    /// store: more machines for the same queue.
    Worker {
        /// A TOML file overriding config/default.toml (then MESOBAKE_* variables override it).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Issue, list and revoke API keys, in the database of the server's configuration
    /// (`--config`, `MESOBAKE_*`).
    Keys {
        #[command(subcommand)]
        which: KeysCommand,
    },
    /// Compare two images of equal size: PSNR (dB, sRGB values), mean absolute error and the
    /// fraction of pixels whose hit/miss mask differs.
    Compare {
        /// First image (.png or .exr).
        a: PathBuf,
        /// Second image.
        b: PathBuf,
        /// Also write a difference image: red where only A hits, blue where only B hits,
        /// elsewhere the absolute difference ×4 in grey.
        #[arg(long)]
        diff: Option<PathBuf>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Map a mesh tile's triangles through the shell into object space and write them as an
    /// OBJ: explicit geometry, subdivided so that every edge follows the curved mapping within
    /// --tolerance, welded (a closed tile on a closed base gives a closed mesh).
    Explicit {
        /// Base mesh OBJ (with UVs).
        #[arg(long, required_unless_present = "scene", conflicts_with = "scene")]
        mesh: Option<PathBuf>,
        /// Tile OBJ in tile units: x, y over the unit tile (repeating), z in [0, --tile-height].
        #[arg(long, required_unless_present = "scene", conflicts_with = "scene")]
        tile: Option<PathBuf>,
        /// A scene file instead: its base mesh, shell, and OBJ tile or built-in sample (on the
        /// scene's resolution, tile height Z/X).
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Shell thickness in object units [default: the tile's edge length in object units
        /// × tile height, which keeps the tile's proportions].
        #[arg(long, conflicts_with = "scene")]
        thickness: Option<f64>,
        /// Tiles per UV unit along u and v, e.g. 24x10 [default: 1x1].
        #[arg(long, value_parser = mesobake::surface::explicit::parse_pair, conflicts_with = "scene")]
        tiles: Option<[f64; 2]>,
        /// The tile's height H in tile units (Z/X of its grid) [default: 0.5].
        #[arg(long, conflicts_with = "scene")]
        tile_height: Option<f64>,
        /// Largest distance (object units) between an output edge's midpoint and the exact
        /// mapping of its texture midpoint [default: 1e-3 × thickness].
        #[arg(long)]
        tolerance: Option<f64>,
        /// Output OBJ.
        #[arg(long)]
        out: PathBuf,
        /// Print the statistics as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Reports on what accuracy costs.
    Report {
        #[command(subcommand)]
        which: ReportCommand,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

/// What to bake and how: the options shared by `gdm` and `bake`.
#[derive(Args)]
struct BakeOptions {
    /// A .mbvol volume, an OBJ tile or a height-field PNG (required unless `bake --scene`).
    #[arg(long)]
    input: Option<PathBuf>,
    /// Grid X×Y×Z: required for OBJ tiles; for volumes it must match the volume.
    #[arg(long)]
    res: Option<Dims>,
    /// Direction grid Nθ×Nφ.
    #[arg(long, default_value = "16x32")]
    dirs: DirectionGrid,
    /// exact: one ray per sample and direction; fast: layer sweeps (see --stride).
    #[arg(long, default_value = "exact")]
    method: Method,
    /// Fast method: layers crossed exactly before interpolating (higher = slower, closer).
    #[arg(long, default_value_t = gdm::fast::FastParams::default().stride)]
    stride: u32,
    /// Fast method: largest spread (voxels) of neighbouring hit distances that is still
    /// interpolated; rays with more disagreeing neighbours are traced exactly.
    #[arg(long, default_value_t = gdm::fast::FastParams::default().max_spread)]
    spread: f32,
    /// Treat an open OBJ tile as infinitely thin sheets instead of refusing it.
    #[arg(long)]
    allow_open: bool,
}

impl BakeOptions {
    fn input(&self) -> Result<&Path> {
        self.input
            .as_deref()
            .ok_or_else(|| Error::InvalidParameter("--input FILE is required".into()))
    }

    fn fast(&self) -> gdm::fast::FastParams {
        gdm::fast::FastParams {
            stride: self.stride,
            max_spread: self.spread,
        }
    }
}

#[derive(Subcommand)]
enum KeysCommand {
    /// Create a key with the given scopes.
    Create {
        /// Comma-separated scopes: upload, bake, read.
        #[arg(long)]
        scopes: String,
        /// A note saying whose key it is.
        #[arg(long, default_value = "")]
        label: String,
        /// The server's configuration file (for its database).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// List the issued keys: id, scopes, label, issue time, whether revoked (never the
    /// keys themselves).
    List {
        /// The server's configuration file (for its database).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Revoke the key with this id (the part after `mbk_`, as `keys list` shows it).
    Revoke {
        /// The key's id.
        id: String,
        /// The server's configuration file (for its database).
        #[arg(long)]
        config: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// GDM bake workloads W1–W3 (Markdown table on stdout).
    Gdm {
        /// Also print the rows as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Truncated SVD of the W1 GDM matrix against nalgebra's full SVD (Markdown on stdout).
    Svd,
    /// Package sizes and errors on W1: rank 8 f16, and the smallest package with RMSE ≤ 0.5.
    Package,
    /// The server: upload-to-package time, upload throughput, job claim latency and package
    /// download throughput against nginx (needs nginx and wrk installed).
    Server {
        /// Database (default: a temporary SQLite file), e.g. postgres://127.0.0.1/bench.
        #[arg(long)]
        database_url: Option<String>,
    },
    /// The real-time preview's frame time against the CPU GDM renderer on the same scene and
    /// package, over image sizes and volume depths (Markdown table on stdout).
    Preview {
        /// Scene file.
        #[arg(long, default_value = "scenes/torus-chain.json")]
        scene: PathBuf,
        /// Square image sizes.
        #[arg(long, value_delimiter = ',', default_value = "512")]
        sizes: Vec<u32>,
        /// Volume depths Z (the scene's resolution otherwise).
        #[arg(long, value_delimiter = ',', default_value = "32")]
        depths: Vec<u32>,
        /// Frames timed per configuration.
        #[arg(long, default_value_t = 10)]
        frames: u32,
        /// Use the adapter whose name contains this.
        #[arg(long)]
        adapter: Option<String>,
    },
}

#[derive(Subcommand)]
enum ReportCommand {
    /// Accuracy against time and bytes over direction resolutions × ranks × quantizations,
    /// against the exact uncompressed GDM: Markdown on stdout; accuracy.md, accuracy.csv and
    /// accuracy.svg in --out.
    Accuracy {
        /// A .mbvol volume or a closed OBJ tile.
        #[arg(long)]
        input: PathBuf,
        /// Grid X×Y×Z: required for OBJ tiles.
        #[arg(long)]
        res: Option<Dims>,
        /// Direction grids, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "8x16,16x32,32x64")]
        dirs: Vec<DirectionGrid>,
        /// Ranks, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16")]
        ranks: Vec<usize>,
        /// Quantizations, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "f32,f16")]
        quants: Vec<Quantization>,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
    /// The GDM renderer's image error against the ground truth on a scene, over direction
    /// resolutions × (exact GDM, SVD ranks) × refinement counts, with render times, then its
    /// error budget (the query, the frame and the shadows substituted one at a time and all
    /// together): Markdown on stdout; render-accuracy.md and render-accuracy.json in --out.
    Render {
        /// Scene file.
        #[arg(long)]
        scene: PathBuf,
        /// Direction grids, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "8x16,16x32,32x64")]
        dirs: Vec<DirectionGrid>,
        /// SVD ranks, comma-separated (the exact GDM is always rendered too).
        #[arg(long, value_delimiter = ',', default_value = "2,4,8,16")]
        ranks: Vec<usize>,
        /// Quantization of the compressed factors.
        #[arg(long, default_value = "f16")]
        quant: Quantization,
        /// GDM refinement counts, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0,2")]
        refinements: Vec<u32>,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
    /// Global illumination on a scene with environment lighting: RTV error and time over
    /// direction grids × bounce counts, PRT error and time over visibility sample counts
    /// (the last grid, the most bounces and the most samples are the references): Markdown
    /// on stdout; gi-accuracy.md and gi-accuracy.json in --out.
    Gi {
        /// Scene file (its effects must call for environment_lighting).
        #[arg(long)]
        scene: PathBuf,
        /// Direction grids, comma-separated; the last is the reference.
        #[arg(long, value_delimiter = ',', default_value = "8x16,16x32,32x64")]
        dirs: Vec<DirectionGrid>,
        /// Bounce counts, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0,1,2,4,8")]
        bounces: Vec<u32>,
        /// PRT visibility samples per vertex, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "256,1024,4096,16384")]
        prt_samples: Vec<usize>,
        /// Path tracer paths per pixel, comma-separated; the largest is the reference image.
        #[arg(long, value_delimiter = ',', default_value = "1,4,16,64")]
        path_samples: Vec<u32>,
        /// RTV SVD ranks (1–16), comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16")]
        rtv_ranks: Vec<usize>,
        /// Divide the scene camera's width and height by this for the images.
        #[arg(long, default_value_t = 4)]
        image_scale: u32,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum SampleFormat {
    /// Binary voxel volume (.mbvol).
    Volume,
    /// Closed OBJ triangle tile.
    Obj,
}

#[derive(Clone, Copy, ValueEnum)]
enum EscapeArg {
    Inf,
    Boundary,
}

/// A progress bar on stderr, drawn only when stderr is a terminal.
/// A client of `server` with `api_key`, else the MESOBAKE_API_KEY environment variable.
fn client(server: &str, api_key: Option<String>) -> Result<Client> {
    Client::new(
        server,
        api_key.or_else(|| std::env::var("MESOBAKE_API_KEY").ok()),
    )
}

/// A tokio runtime for the commands that talk to the server's database.
fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Runtime::new()
        .map_err(|e| Error::InvalidParameter(format!("starting the runtime: {e}")))
}

/// Runs the server or the workers with logging to stderr. Bakes that were abandoned at
/// shutdown (their jobs handed back to the queue) are not waited for.
fn run_service(service: impl Future<Output = Result<()>>) -> Result<()> {
    tracing_subscriber::fmt()
        .with_max_level(tracing::Level::INFO)
        .with_writer(std::io::stderr)
        .init();
    let runtime = runtime()?;
    let result = runtime.block_on(service);
    runtime.shutdown_timeout(std::time::Duration::from_millis(100));
    result
}

/// `mesobake keys`: create, list or revoke keys in the configured database, saying which.
fn keys(which: KeysCommand) -> Result<()> {
    use mesobake::server::{auth::Scope, config::ServerConfig, db::Db};
    let config = match &which {
        KeysCommand::Create { config, .. }
        | KeysCommand::List { config }
        | KeysCommand::Revoke { config, .. } => ServerConfig::load(config.as_deref())?,
    };
    let database = config.database_url_redacted();
    runtime()?.block_on(async {
        let db = Db::connect(&config.database_url)
            .await
            .map_err(|e| Error::Database(format!("{database}: {e}")))?;
        match which {
            KeysCommand::Create { scopes, label, .. } => {
                let key = db
                    .create_api_key(&Scope::parse_list(&scopes)?, &label)
                    .await?;
                println!("{key}");
                eprintln!("key written to {database}");
            }
            KeysCommand::List { .. } => {
                eprintln!("keys in {database}");
                for k in db.api_keys().await? {
                    println!(
                        "{}",
                        serde_json::to_string(&k).expect("key infos serialize")
                    );
                }
            }
            KeysCommand::Revoke { id, .. } => {
                db.revoke_api_key(&id).await?;
                eprintln!("key {id} revoked in {database}");
            }
        }
        Ok(())
    })
}

struct Progress(ProgressBar);

impl Progress {
    fn new(what: &str) -> Self {
        let bar = if std::io::stderr().is_terminal() {
            ProgressBar::new(1)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({eta})")
                .expect("static template")
                .progress_chars("=> "),
        );
        bar.set_message(what.to_string());
        Progress(bar)
    }
}

impl BakeObserver for Progress {
    fn progress(&self, done: u64, total: u64) {
        self.0.set_length(total);
        self.0.set_position(done);
    }
}

fn run(cli: Cli) -> Result<()> {
    let limits = match &cli.memory_limit {
        Some(text) => Limits {
            memory_bytes: parse_bytes(text)?,
            ..Limits::default()
        },
        None => Limits::from_env()?,
    };
    match cli.command {
        Command::Sample {
            kind,
            res,
            out,
            format,
        } => match format {
            SampleFormat::Volume => {
                let volume = samples::volume(kind, res, &limits)?;
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
        },
        Command::Gdm {
            bake,
            escape,
            out,
            json,
        } => {
            let start = Instant::now();
            let meso = input::load(bake.input()?, bake.res, bake.allow_open, &limits)?;
            let load_s = start.elapsed().as_secs_f64();
            let progress = Progress::new("baking GDM");
            let start = Instant::now();
            let (method, fast) = (bake.method, bake.fast());
            let mut g = gdm::bake(meso.caster(), bake.dirs, method, fast, &limits, &progress)?;
            let bake_s = start.elapsed().as_secs_f64();
            progress.0.finish_and_clear();
            if let EscapeArg::Boundary = escape {
                g.set_escape_convention(gdm::EscapeConvention::Boundary);
            }
            let start = Instant::now();
            npy::write_gdm(&g, &out)?;
            let write_s = start.elapsed().as_secs_f64();
            if json {
                let summary = serde_json::json!({
                    "input": bake.input,
                    "output": out,
                    "res": g.dims().to_string(),
                    "dirs": g.dirs().to_string(),
                    "method": method,
                    "fast": fast,
                    "escape": g.escape_convention(),
                    "samples": g.data().len(),
                    "seconds": {"load": load_s, "bake": bake_s, "write": write_s},
                });
                println!("{summary}");
            }
            Ok(())
        }
        Command::Bake {
            scene: Some(scene),
            out,
            rank,
            quant,
            json,
            ..
        } => {
            let start = Instant::now();
            let loaded = render_scene::load_scene(&scene, &limits)?;
            let load_s = start.elapsed().as_secs_f64();
            let params = ScenePackageParams {
                rank: RankChoice::Rank(rank.unwrap_or(8)),
                quantization: quant,
            };
            let dir = scene.parent().unwrap_or(Path::new("."));
            let progress = Progress::new("baking GDM");
            let baked = bake_scene_package(&loaded, dir, params, &limits, &progress)?;
            progress.0.finish_and_clear();
            let start = Instant::now();
            write_atomic(&out, &baked.bytes)?;
            let write_s = start.elapsed().as_secs_f64();
            eprintln!(
                "wrote {} ({} bytes): stages {}",
                out.display(),
                baked.bytes.len(),
                baked.plan.stages.join(", ")
            );
            if json {
                let mut seconds = serde_json::Map::new();
                seconds.insert("load".into(), load_s.into());
                for (stage, s) in &baked.seconds {
                    seconds.insert(stage.clone(), (*s).into());
                }
                seconds.insert("write".into(), write_s.into());
                let summary = serde_json::json!({
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
                });
                println!("{summary}");
            }
            Ok(())
        }
        Command::Bake {
            bake,
            out,
            rank,
            max_rmse,
            quant,
            json,
            server: Some(server),
            api_key,
            ..
        } => {
            if max_rmse.is_some() || bake.method != Method::Exact || bake.allow_open {
                return Err(Error::InvalidParameter(
                    "--server bakes with the exact method and an explicit --rank; \
                     --max-rmse, --method fast and --allow-open are local only"
                        .into(),
                ));
            }
            let client = client(&server, api_key)?;
            let asset = client.upload(bake.input()?)?;
            let res = match bake.res {
                Some(r) => r,
                None => {
                    let d = &asset["summary"]["dims"];
                    let dim = |i: usize| d[i].as_u64().unwrap_or(0) as u32;
                    Dims::new(dim(0), dim(1), dim(2)).map_err(|_| {
                        Error::InvalidParameter("--res is required for OBJ tiles".into())
                    })?
                }
            };
            let job = client.submit(&asset, res, bake.dirs, rank.unwrap_or(8), quant)?;
            let id = job["id"].as_str().unwrap_or_default().to_owned();
            let bar = Progress::new(&format!("job {}", &id[..8.min(id.len())]));
            bar.0.set_length(1000);
            let done = client.wait(&id, |j| {
                bar.0
                    .set_position((j["progress"].as_f64().unwrap_or(0.0) * 1000.0) as u64)
            })?;
            bar.0.finish_and_clear();
            let digest = done["package_digest"].as_str().unwrap_or_default();
            let bytes = client.fetch(digest)?;
            write_atomic(&out, &bytes)?;
            eprintln!(
                "wrote {} ({} bytes, package {digest}) from job {id}",
                out.display(),
                bytes.len()
            );
            if json {
                println!(
                    "{}",
                    serde_json::json!({ "output": out, "bytes": bytes.len(), "digest": digest, "job": done })
                );
            }
            Ok(())
        }
        Command::Fetch {
            server,
            digest,
            out,
            api_key,
        } => {
            let client = client(&server, api_key)?;
            let bytes = client.fetch(&digest)?;
            write_atomic(&out, &bytes)?;
            eprintln!("wrote {} ({} bytes, verified)", out.display(), bytes.len());
            Ok(())
        }
        Command::Bake {
            bake,
            out,
            rank,
            max_rmse,
            quant,
            json,
            server: None,
            ..
        } => {
            let params = PackageParams {
                res: bake.res,
                dirs: bake.dirs,
                method: bake.method,
                fast: bake.fast(),
                rank: match max_rmse {
                    Some(e) => RankChoice::MaxRmse(e),
                    None => RankChoice::Rank(rank.unwrap_or(8)),
                },
                quantization: quant,
                allow_open: bake.allow_open,
            };
            let progress = Progress::new("baking GDM");
            let baked = bake_package(bake.input()?, &params, &limits, &progress)?;
            progress.0.finish_and_clear();
            let start = Instant::now();
            write_atomic(&out, &baked.bytes)?;
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
            if json {
                let summary = serde_json::json!({
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
                });
                println!("{summary}");
            }
            Ok(())
        }
        Command::Unpack { package, out, exr } => {
            let pkg = Package::read(&package, &limits)?;
            let g = pkg.reconstruct(&limits)?;
            npy::write_gdm(&g, &out)?;
            if let Some(path) = exr {
                mesobake::package::exr_export::write_factors(&pkg, &path)?;
            }
            Ok(())
        }
        Command::Demo { sample, res, out } => {
            std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
            let name = sample.name();
            let volume = samples::volume(sample, res, &limits)?;
            volume_format::write(&volume, &out.join(format!("{name}.mbvol")))?;
            let mesh = samples::mesh(sample, res)?;
            let obj = out.join(format!("{name}.obj"));
            write_atomic(&obj, mesh.to_obj(name).as_bytes())?;
            let progress = Progress::new("baking GDM (exact)");
            let start = Instant::now();
            let caster = mesobake::bake::gdm::volume_caster::VolumeCaster::new(&volume);
            let g = gdm::exact::bake(&caster, DirectionGrid::PAPER, &limits, &progress)?;
            progress.0.finish_and_clear();
            eprintln!(
                "baked the {res} {name} GDM in {:.2} s",
                start.elapsed().as_secs_f64()
            );
            npy::write_gdm(&g, &out.join(format!("{name}-gdm.npy")))?;
            let setup = mesobake::render::flat_preview::default_setup(&g);
            let rgb = mesobake::render::flat_preview::render(&volume, &g, &setup)?;
            let png = mesobake::render::flat_preview::encode_png(&rgb, setup.size, setup.size)?;
            let path = out.join(format!("{name}-preview.png"));
            write_atomic(&path, &png)?;
            eprintln!("wrote {}", path.display());
            Ok(())
        }
        Command::Render {
            scene,
            method,
            package,
            out,
            json,
            substitute,
        } => {
            let start = Instant::now();
            let loaded = render_scene::load_scene(&scene, &limits)?;
            let load_s = start.elapsed().as_secs_f64();
            let source = match (&package, method) {
                (Some(path), RenderMethod::Gdm) => GdmSource::Package(path),
                (None, _) => GdmSource::Bake,
                (Some(_), RenderMethod::Truth) => {
                    return Err(Error::InvalidParameter(
                        "--package only applies to --method gdm".into(),
                    ));
                }
            };
            let progress = Progress::new("baking GDM (exact)");
            let mut rendered = render_scene::render_substituted(
                &loaded, method, source, substitute, &limits, &progress,
            )?;
            progress.0.finish_and_clear();
            rendered.seconds.load = load_s;
            rendered.image.write(&out)?;
            let image = &rendered.image;
            eprintln!(
                "wrote {} ({}×{}, {} hit pixels) in {:.2} s of rendering",
                out.display(),
                image.width,
                image.height,
                image.hits(),
                rendered.seconds.render
            );
            if json {
                let summary = serde_json::json!({
                    "scene": scene,
                    "output": out,
                    "method": method,
                    "width": image.width,
                    "height": image.height,
                    "hit_pixels": image.hits(),
                    "base_mesh": loaded.base_report,
                    "shell": loaded.shell.report,
                    "seconds": rendered.seconds,
                    "gi": rendered.gi,
                });
                println!("{summary}");
            }
            Ok(())
        }
        Command::Serve { config } => {
            let config = mesobake::server::config::ServerConfig::load(config.as_deref())?;
            run_service(mesobake::server::serve(config, limits))
        }
        Command::Keys { which } => keys(which),
        Command::Worker { config } => {
            let config = mesobake::server::config::ServerConfig::load(config.as_deref())?;
            run_service(mesobake::server::work(config, limits))
        }
        Command::Preview {
            scene,
            out,
            package,
            rank,
            quant,
            frames,
            adapter,
            json,
        } => {
            let start = Instant::now();
            let loaded = render_scene::load_scene(&scene, &limits)?;
            let load_s = start.elapsed().as_secs_f64();
            let start = Instant::now();
            let package = match &package {
                Some(path) => Package::read(path, &limits)?,
                None => {
                    let progress = Progress::new("baking GDM (exact)");
                    let params = ScenePackageParams {
                        rank: RankChoice::Rank(rank),
                        quantization: quant,
                    };
                    let dir = scene.parent().unwrap_or(Path::new("."));
                    let p = scene_package(&loaded, dir, params, &limits, &progress)?;
                    progress.0.finish_and_clear();
                    p
                }
            };
            let package_s = start.elapsed().as_secs_f64();
            let gpu = mesobake::realtime::gpu::Gpu::open(adapter.as_deref())?;
            let (image, report) = preview(&gpu, &loaded, &package, frames)?;
            image.write(&out)?;
            eprintln!(
                "wrote {} ({}×{}, {} hit pixels) on {} ({})",
                out.display(),
                image.width,
                image.height,
                image.hits(),
                report.adapter.name,
                report.variant.name()
            );
            eprintln!(
                "GPU memory {:.1} MB (package {:.1} MB)",
                report.memory.total() as f64 / 1e6,
                report.memory.package as f64 / 1e6
            );
            if let Some(t) = report.mean_frame_seconds {
                eprintln!("mean frame time over {frames} frames: {:.3} ms", t * 1e3);
            }
            if json {
                let summary = serde_json::json!({
                    "scene": scene,
                    "output": out,
                    "width": image.width,
                    "height": image.height,
                    "hit_pixels": image.hits(),
                    "seconds": { "load": load_s, "package": package_s },
                    "preview": report,
                });
                println!("{summary}");
            }
            Ok(())
        }
        Command::Explicit {
            mesh,
            tile,
            scene,
            thickness,
            tiles,
            tile_height,
            tolerance,
            out,
            json,
        } => {
            use mesobake::surface::explicit::ExplicitInput;
            let input = match (&scene, &mesh, &tile) {
                (Some(scene), _, _) => ExplicitInput::from_scene(scene, &limits)?,
                (None, Some(mesh), Some(tile)) => ExplicitInput::from_files(
                    mesh,
                    tile,
                    thickness,
                    tiles.unwrap_or([1.0, 1.0]),
                    tile_height.unwrap_or(0.5),
                    &limits,
                )?,
                _ => {
                    return Err(Error::InvalidParameter(
                        "explicit needs --scene, or --mesh and --tile".into(),
                    ));
                }
            };
            eprintln!(
                "mapping {} tile triangles through the shell of {} base triangles",
                input.tile.triangles.len(),
                input.base.triangles.len()
            );
            let (shell, explicit) = input.export(tolerance, false, &limits)?;
            let s = &explicit.stats;
            let start = Instant::now();
            let comment = format!(
                "mesobake explicit: {} triangles, {} vertices; tolerance {:e} (object units), \
                 largest measured edge deviation {:e}",
                s.triangles_out, s.vertices_out, s.tolerance, s.max_deviation
            );
            write_atomic(&out, explicit.mesh.to_obj(&comment).as_bytes())?;
            let write_s = start.elapsed().as_secs_f64();
            eprintln!(
                "wrote {}: {} triangles, {} vertices from {} tile triangles over {} prisms \
                 ({} clipped) in {:.2} s; largest edge deviation {:.3e} (tolerance {:.3e})",
                out.display(),
                s.triangles_out,
                s.vertices_out,
                s.triangles_in,
                s.prisms,
                s.triangles_clipped,
                s.seconds,
                s.max_deviation,
                s.tolerance
            );
            if json {
                let summary = serde_json::json!({
                    "output": out,
                    "thickness": input.shell.thickness,
                    "tiles_per_uv": input.shell.tiles_per_uv,
                    "tile_height": input.tile_height,
                    "stats": s,
                    "shell": shell.report,
                    "seconds": {"export": s.seconds, "write": write_s},
                });
                println!("{summary}");
            }
            Ok(())
        }
        Command::Compare { a, b, diff, json } => {
            let (a, b) = (Image::read(&a)?, Image::read(&b)?);
            let c = compare(&a, &b)?;
            if let Some(path) = diff {
                difference(&a, &b)?.write(&path)?;
            }
            if json {
                println!("{}", serde_json::json!(c));
            } else {
                println!(
                    "PSNR {:.2} dB, mean absolute error {:.5}, mask disagreement {:.4} % of {} pixels",
                    c.psnr_db,
                    c.mean_abs_error,
                    100.0 * c.mask_disagreement,
                    c.pixels
                );
            }
            Ok(())
        }
        Command::Report {
            which:
                ReportCommand::Accuracy {
                    input,
                    res,
                    dirs,
                    ranks,
                    quants,
                    out,
                },
        } => {
            let sweep = report::Sweep {
                dirs,
                ranks,
                quantizations: quants,
            };
            let progress = Progress::new("accuracy report");
            let rows = report::accuracy(&input, res, &sweep, &limits, &progress)?;
            progress.0.finish_and_clear();
            let table = report::markdown(&rows);
            std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
            let fsutil = mesobake::util::fs::write_atomic;
            fsutil(&out.join("accuracy.md"), table.as_bytes())?;
            fsutil(&out.join("accuracy.csv"), report::csv(&rows).as_bytes())?;
            fsutil(
                &out.join("accuracy.svg"),
                report::svg_plot(&rows)?.as_bytes(),
            )?;
            print!("{table}");
            eprintln!(
                "wrote accuracy.md, accuracy.csv and accuracy.svg in {}",
                out.display()
            );
            Ok(())
        }
        Command::Report {
            which:
                ReportCommand::Gi {
                    scene,
                    dirs,
                    bounces,
                    prt_samples,
                    path_samples,
                    rtv_ranks,
                    image_scale,
                    out,
                },
        } => {
            let loaded = render_scene::load_scene(&scene, &limits)?;
            let sweep = mesobake::report::gi::GiSweep {
                dirs,
                bounces,
                prt_samples,
                path_samples,
                rtv_ranks,
                image_scale,
            };
            let progress = Progress::new("GI accuracy report");
            let report = mesobake::report::gi::gi_accuracy(&loaded, &sweep, &limits, &progress)?;
            progress.0.finish_and_clear();
            let table = mesobake::report::gi::markdown(&report);
            std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
            let json = serde_json::to_string_pretty(&report).expect("report serializes");
            write_atomic(&out.join("gi-accuracy.md"), table.as_bytes())?;
            write_atomic(&out.join("gi-accuracy.json"), json.as_bytes())?;
            print!("{table}");
            eprintln!(
                "wrote gi-accuracy.md and gi-accuracy.json in {}",
                out.display()
            );
            Ok(())
        }
        Command::Report {
            which:
                ReportCommand::Render {
                    scene,
                    dirs,
                    ranks,
                    quant,
                    refinements,
                    out,
                },
        } => {
            let loaded = render_scene::load_scene(&scene, &limits)?;
            let sweep = render_report::RenderSweep {
                dirs,
                ranks,
                quantization: quant,
                refinements,
            };
            let progress = Progress::new("render accuracy report");
            let report = render_report::render_accuracy(&loaded, &sweep, &limits, &progress)?;
            progress.0.finish_and_clear();
            let table = render_report::markdown(&report);
            std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
            let json = serde_json::to_string_pretty(&report).expect("report serializes");
            write_atomic(&out.join("render-accuracy.md"), table.as_bytes())?;
            write_atomic(&out.join("render-accuracy.json"), json.as_bytes())?;
            print!("{table}");
            eprintln!(
                "wrote render-accuracy.md and render-accuracy.json in {}",
                out.display()
            );
            Ok(())
        }
        Command::Bench {
            which: BenchCommand::Gdm { json },
        } => {
            eprintln!(
                "mesobake bench gdm on {} threads ({})",
                rayon::current_num_threads(),
                std::env::consts::ARCH
            );
            let rows = bench::run(&ALLOCATOR, &limits)?;
            print!("{}", bench::markdown(&rows));
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&rows)
                        .map_err(|e| Error::InvalidParameter(e.to_string()))?
                );
            }
            Ok(())
        }
        Command::Bench {
            which: BenchCommand::Package,
        } => {
            print!("{}", bench::package_markdown(&bench::run_package(&limits)?));
            Ok(())
        }
        Command::Bench {
            which:
                BenchCommand::Preview {
                    scene,
                    sizes,
                    depths,
                    frames,
                    adapter,
                },
        } => {
            let progress = Progress::new("baking GDM (exact)");
            let (adapter, rows) = mesobake::bench::preview::run(
                &scene,
                &sizes,
                &depths,
                frames,
                adapter.as_deref(),
                &limits,
                &progress,
            )?;
            progress.0.finish_and_clear();
            print!("{}", mesobake::bench::preview::markdown(&adapter, &rows));
            Ok(())
        }
        Command::Bench {
            which: BenchCommand::Server { database_url },
        } => {
            print!(
                "{}",
                mesobake::bench::server::run(database_url.as_deref(), &limits)?
            );
            Ok(())
        }
        Command::Bench {
            which: BenchCommand::Svd,
        } => {
            eprintln!(
                "mesobake bench svd on {} threads",
                rayon::current_num_threads()
            );
            print!("{}", bench::svd_markdown(&bench::run_svd(&limits)?));
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
