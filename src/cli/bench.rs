//! `mesobake bench`: speed and memory against baselines measured in the same run (see
//! docs/BENCHMARKS.md).

use super::output::Progress;
use clap::Subcommand;
use mesobake_core::limits::Limits;
use mesobake_core::quality::Preset;
use mesobake_core::{Error, Result};
use mesobake_scene::bench::counting_alloc::CountingAlloc;
use mesobake_scene::bench::{bakes, media, preview, vdm};
use mesobake_server::bench as server;
use std::path::PathBuf;

/// The benchmarks.
#[derive(Subcommand)]
pub enum BenchCommand {
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
        /// Quality presets, comma-separated: paper, balanced, high.
        #[arg(long, value_delimiter = ',', default_value = "paper")]
        presets: Vec<Preset>,
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
    /// VDM against GDM on a height-field scene: bake, CPU image and real-time frame times,
    /// and each image's error against the truth (Markdown table on stdout).
    Vdm {
        /// Scene file (a height-field mesostructure).
        #[arg(long, default_value = "scenes/torus-bumps.json")]
        scene: PathBuf,
        /// Square image sizes.
        #[arg(long, value_delimiter = ',', default_value = "512")]
        sizes: Vec<u32>,
        /// Frames timed per configuration.
        #[arg(long, default_value_t = 10)]
        frames: u32,
        /// Use the adapter whose name contains this.
        #[arg(long)]
        adapter: Option<String>,
    },
    /// The translucent-media pipeline on the paper's largest case (a 96×45 torus: 8 640
    /// triangles, 25 920 cells; a 128×128×32 medium; 10 samples per cell): frame time in
    /// each cell order against the CPU specification, in the same run.
    Media {
        /// Scene file (a translucent medium on a built-in torus).
        #[arg(long, default_value = "scenes/torus-fur.json")]
        scene: PathBuf,
        /// The torus's segments (around, across).
        #[arg(long, value_delimiter = ',', default_value = "96,45")]
        segments: Vec<u32>,
        /// The medium's grid.
        #[arg(long, value_delimiter = ',', default_value = "128,128,32")]
        texture: Vec<u32>,
        /// Samples per cell (0: exact integration).
        #[arg(long, default_value_t = 10)]
        samples: u32,
        /// Square image sizes.
        #[arg(long, value_delimiter = ',', default_value = "256")]
        sizes: Vec<u32>,
        /// Frames timed per configuration.
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Use the adapter whose name contains this.
        #[arg(long)]
        adapter: Option<String>,
        /// Leave out the scene's shadows.
        #[arg(long)]
        no_shadows: bool,
    },
}

/// Runs the benchmark, reading heap use from `allocator` (the binary's global allocator).
pub fn bench(which: BenchCommand, allocator: &CountingAlloc, limits: &Limits) -> Result<()> {
    match which {
        BenchCommand::Gdm { json } => {
            eprintln!(
                "mesobake bench gdm on {} threads ({})",
                rayon::current_num_threads(),
                std::env::consts::ARCH
            );
            let rows = bakes::run(allocator, limits)?;
            print!("{}", bakes::markdown(&rows));
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&rows)
                        .map_err(|e| Error::InvalidParameter(e.to_string()))?
                );
            }
        }
        BenchCommand::Package => {
            print!("{}", bakes::package_markdown(&bakes::run_package(limits)?));
        }
        BenchCommand::Preview {
            scene,
            presets,
            sizes,
            depths,
            frames,
            adapter,
        } => {
            let progress = Progress::new("baking GDM (exact)");
            let (adapter, rows) = preview::run(
                &scene,
                &presets,
                &sizes,
                &depths,
                frames,
                adapter.as_deref(),
                limits,
                &progress,
            )?;
            progress.finish();
            print!("{}", preview::markdown(&adapter, &rows));
        }
        BenchCommand::Vdm {
            scene,
            sizes,
            frames,
            adapter,
        } => {
            let (adapter, rows) = vdm::run(&scene, &sizes, frames, adapter.as_deref(), limits)?;
            print!("{}", vdm::markdown(&adapter, &rows));
        }
        BenchCommand::Media {
            scene,
            segments,
            texture,
            samples,
            sizes,
            frames,
            adapter,
            no_shadows,
        } => {
            let (Ok(segments), Ok(texture)) = (segments.try_into(), texture.try_into()) else {
                return Err(Error::InvalidParameter(
                    "--segments takes two numbers and --texture three".into(),
                ));
            };
            let params = media::MediaBenchParams {
                scene: &scene,
                segments,
                texture,
                samples,
                sizes: &sizes,
                frames,
                adapter: adapter.as_deref(),
                shadows: !no_shadows,
            };
            print!("{}", media::markdown(&media::run(&params, limits)?));
        }
        BenchCommand::Server { database_url } => {
            print!("{}", server::run(database_url.as_deref(), limits)?);
        }
        BenchCommand::Svd => {
            eprintln!(
                "mesobake bench svd on {} threads",
                rayon::current_num_threads()
            );
            print!("{}", bakes::svd_markdown(&bakes::run_svd(limits)?));
        }
    }
    Ok(())
}
