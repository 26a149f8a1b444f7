//! The `mesobake` command line: parses the arguments and dispatches to the command's module
//! under `cli/`.

mod cli;

use clap::{Parser, Subcommand};
use cli::{bench, explicit, gdm, package, preview, render, report, sample, server, vdm};
use mesobake_core::Result;
use mesobake_core::limits::{Limits, parse_bytes};
use mesobake_scene::bench::counting_alloc::CountingAlloc;
use std::process::ExitCode;

#[global_allocator]
static ALLOCATOR: CountingAlloc = CountingAlloc::new();

#[derive(Parser)]
#[command(
    name = "mesobake",
    version,
    about = "Bake mesostructure: generalized displacement maps and more"
)]
struct Cli {
    /// Most memory a bake, or any allocation sized by input, may take (e.g. 4GiB); default from
    /// MESOBAKE_MEMORY_LIMIT, else 4GiB.
    #[arg(long, global = true)]
    memory_limit: Option<String>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write a built-in procedural sample as a volume (.mbvol) or an OBJ tile.
    Sample(sample::SampleArgs),
    /// Import a translucent medium from a raw RGBA voxel file (8-bit or f32 channels) as a
    /// volume (.mbvol version 2: albedo and opacity; opaque voxels solid).
    Import(sample::ImportArgs),
    /// Bake the GDM of a volume or OBJ tile and write it as .npy (float32, shape
    /// (X, Y, Z, Nθ, Nφ), voxel units, escapes +inf, inside 0).
    Gdm(gdm::GdmArgs),
    /// Bake the view-dependent displacement map (VDM) of a height field or built-in relief
    /// and write it as .npy (float32, shape (curvatures, Nθ, Nφ, H, W), tile units, −1 for no
    /// hit); --compare measures the paper's resampled bake against the exact one.
    Vdm(vdm::VdmArgs),
    /// Write a built-in relief (height field) as a 16-bit grayscale PNG.
    Relief(vdm::ReliefArgs),
    /// Bake a GDM package (.mbpkg) for CI builds: bake, SVD-compress, quantize, measure the
    /// error and write the package. Output is byte-identical for identical inputs and options.
    Bake(package::BakeArgs),
    /// Download a package from a server and verify it (its bytes must hash to DIGEST and parse
    /// as a package) before writing it.
    Fetch(package::FetchArgs),
    /// Reconstruct the dense GDM from a package into .npy (the convention of `mesobake gdm`:
    /// escapes +inf), export the weight maps and eigenmaps as a multi-layer EXR, or the
    /// texture sections as KTX2 files.
    Unpack(package::UnpackArgs),
    /// Bake a built-in sample end to end and render a preview from its GDM: writes
    /// SAMPLE.mbvol, SAMPLE.obj, SAMPLE-gdm.npy and SAMPLE-preview.png into --out.
    Demo(sample::DemoArgs),
    /// Render a scene file on the CPU with the ground truth, a real-time algorithm's
    /// specification (GDM, VDM, or cells for translucent media) or the explicit geometry:
    /// .png (8-bit sRGB, alpha = hit mask) or .exr (linear float, A = hit mask).
    Render(render::RenderArgs),
    /// Render a scene with the real-time pipeline (WGSL shaders on wgpu, headless, on any
    /// adapter including Mesa's software Vulkan driver) from a package, or from one baked for
    /// the scene (exact GDM, then --rank and --quant): .png or .exr as for `render`.
    Preview(preview::PreviewArgs),
    /// Run the baking server: the HTTP API under /api/v1 on the configured address
    /// (default 127.0.0.1:8080) over SQLite or PostgreSQL and the local blob store.
    Serve(server::ConfigArgs),
    /// Run bake workers only (no HTTP server) against the configured database and blob
    /// store: more machines for the same queue.
    Worker(server::ConfigArgs),
    /// Issue, list and revoke API keys, in the database of the server's configuration
    /// (`--config`, `MESOBAKE_*`).
    Keys {
        #[command(subcommand)]
        which: server::KeysCommand,
    },
    /// Compare two images of equal size: PSNR (dB, sRGB values), mean absolute error and the
    /// fraction of pixels whose hit/miss mask differs.
    Compare(render::CompareArgs),
    /// Map a mesh tile's triangles through the shell into object space and write them as an
    /// OBJ or binary glTF (.glb): explicit geometry, subdivided so that every edge follows the curved mapping within
    /// --tolerance, welded (a closed tile on a closed base gives a closed mesh).
    Explicit(explicit::ExplicitArgs),
    /// Reports on what accuracy costs.
    Report {
        #[command(subcommand)]
        which: report::ReportCommand,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: bench::BenchCommand,
    },
    /// Print this command line's reference as Markdown (docs/cli.md is its output).
    #[command(hide = true)]
    HelpMarkdown,
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
        Command::Sample(args) => sample::sample(args, &limits),
        Command::Import(args) => sample::import(args, &limits),
        Command::Gdm(args) => gdm::gdm(args, &limits),
        Command::Vdm(args) => vdm::vdm(args, &limits),
        Command::Relief(args) => vdm::relief(args, &limits),
        Command::Bake(args) => package::bake(args, &limits),
        Command::Fetch(args) => package::fetch(args, &limits),
        Command::Unpack(args) => package::unpack(args, &limits),
        Command::Demo(args) => sample::demo(args, &limits),
        Command::Render(args) => render::render(args, &limits),
        Command::Preview(args) => preview::preview(args, &limits),
        Command::Serve(args) => server::serve(args, limits),
        Command::Worker(args) => server::worker(args, limits),
        Command::Keys { which } => server::keys(which),
        Command::Compare(args) => render::compare_images(args),
        Command::Explicit(args) => explicit::explicit(args, &limits),
        Command::Report { which } => report::report(which, &limits),
        Command::Bench { which } => bench::bench(which, &ALLOCATOR, &limits),
        Command::HelpMarkdown => {
            print!("{}", clap_markdown::help_markdown::<Cli>());
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if matches!(cli.command, Command::Bench { .. }) {
        ALLOCATOR.start_counting();
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
