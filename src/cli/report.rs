//! `mesobake report`: what accuracy costs (GDM compression, the GDM renderer, radiance
//! transfer), as Markdown on stdout and files in `--out`.

use super::output::Progress;
use super::vdm::parse_pair;
use clap::Subcommand;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::vdm::VdmMethod;
use mesobake_core::fs::write_atomic;
use mesobake_core::limits::Limits;
use mesobake_core::samples_per_pixel::SamplesPerPixel;
use mesobake_core::{Error, Result};
use mesobake_gpu::gpu::Gpu;
use mesobake_package::grid::{Dims, DirectionGrid};
use mesobake_scene::LoadedScene;
use mesobake_scene::render::load_scene;
use mesobake_scene::report::{
    accuracy, codecs, conformance, gi, quality, render, transparency, vdm,
};
use std::path::{Path, PathBuf};

/// The reports.
#[derive(Subcommand)]
pub enum ReportCommand {
    /// Accuracy against time and bytes over direction resolutions × ranks × quantizations,
    /// against the exact uncompressed GDM, then every codec on --scenes (the codecs report at
    /// its defaults): Markdown on stdout; accuracy.md, accuracy.csv and accuracy.svg, and
    /// codecs.json and codecs.svg, in --out.
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
        /// Scene files for the codec section, comma-separated; an empty list skips it.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "scenes/torus-chain.json,scenes/plane-weave.json"
        )]
        scenes: Vec<PathBuf>,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
    /// Every GDM codec and size on scenes (and the blockwise SVD, evaluated on the CPU only):
    /// package bytes and bake seconds, sample flips and hit RMSE against the exact GDM, the
    /// CPU renderer's PSNR and mask against the ground truth and its time, the real-time frame
    /// time and PSNR (where an adapter exists), with the uncompressed GDM as the reference:
    /// Markdown on stdout; codecs.md, codecs.json and codecs.svg (PSNR against bytes) in --out.
    Codecs {
        /// Scene files, comma-separated.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "scenes/torus-chain.json,scenes/plane-weave.json"
        )]
        scenes: Vec<PathBuf>,
        /// paper-svd ranks, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "4,8,16")]
        ranks: Vec<usize>,
        /// paper-svd and tiled-svd quantization.
        #[arg(long, default_value = "f16")]
        quant: Quantization,
        /// Tile sides (texels) of the blockwise SVD evaluated beside the codecs, comma-separated
        /// (each at every rank); an empty list evaluates none.
        #[arg(long, value_delimiter = ',', default_value = "16")]
        tiles: Vec<u32>,
        /// Direction grids of the split GDM's escape bits, comma-separated (each at every rank,
        /// with the global basis and each tile side); an empty list evaluates none.
        #[arg(long, value_delimiter = ',', default_value = "4x8,8x16")]
        visibility: Vec<DirectionGrid>,
        /// Real-time frames to time per setting (0: none).
        #[arg(long, default_value_t = 5)]
        frames: u32,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
    /// The GDM renderer's image error against the ground truth on a scene, over direction
    /// resolutions × (exact GDM, SVD ranks) × refinement counts, with render times, then its
    /// error budget (the query and the shadows substituted by the truth's one at a time and
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
    /// The per-pixel GDM algorithm's accuracy knobs on scenes: every quality preset and each
    /// knob alone, rendered from the scene's default package by the CPU renderer (and by the
    /// real-time pipeline where an adapter exists), PSNR, FLIP and mask against the ground
    /// truth and the time of each: Markdown on stdout; quality.md, quality.json and
    /// quality.svg (PSNR against CPU time) in --out.
    Quality {
        /// Scene files, comma-separated (point or directional light).
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "scenes/torus-chain.json,scenes/plane-weave.json,scenes/mesh-tile/torus-chain-tile.json"
        )]
        scenes: Vec<PathBuf>,
        /// Render every scene at this many pixels across (and down) instead of its camera's.
        #[arg(long)]
        side: Option<u32>,
        /// Real-time frames to time per setting (0: none).
        #[arg(long, default_value_t = 3)]
        frames: u32,
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
    /// The VDM's knobs on a height-field scene, one at a time around its `vdm` settings
    /// (curvature count, view directions, bake method, rank, quantization), next to the GDM
    /// of the same detail: package bytes, bake seconds, the displacement error compression
    /// adds, the CPU render's PSNR, FLIP and mask against the ground truth and its time, and
    /// the real-time frame time and PSNR (where an adapter exists); with both bake methods,
    /// the paper's bake against the exact one. Markdown on stdout; vdm.md, vdm.json and
    /// vdm.svg (PSNR against bytes) in --out.
    Vdm {
        /// Scene file (a height-field mesostructure).
        #[arg(long, default_value = "scenes/torus-bumps.json")]
        scene: PathBuf,
        /// Curvature counts, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "4,8")]
        curvatures: Vec<u32>,
        /// View direction grids Nθ×Nφ, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "4x16", value_parser = parse_pair)]
        dirs: Vec<[u32; 2]>,
        /// Bake methods, comma-separated: a row each, and with both the paper's bake is
        /// measured against the exact one.
        #[arg(long, value_delimiter = ',', default_value = "paper,exact")]
        methods: Vec<VdmMethod>,
        /// VDM ranks, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "2,4,16")]
        ranks: Vec<usize>,
        /// Quantizations, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "f32,u8")]
        quants: Vec<Quantization>,
        /// Image side in pixels instead of the scene camera's (square images).
        #[arg(long)]
        side: Option<u32>,
        /// Real-time frames to time per row (0: none).
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
    /// Every scene × every technique it can use × every preset: the real-time algorithm's
    /// CPU specification (and the WGSL pipeline where an adapter exists) against the ground
    /// truth, both at --spp samples per pixel, the same at one sample, the CPU against the
    /// WGSL, and the bake, render and frame times, with the verdicts against the targets
    /// (≥ 25 dB at the default preset, ≥ 30 at the best). Markdown on stdout;
    /// conformance.md, conformance.json and conformance.png (per scene and technique at its
    /// default: truth | real-time | difference) in --out.
    Conformance {
        /// Scene files, comma-separated [default: every .json file in scenes/].
        #[arg(long, value_delimiter = ',')]
        scenes: Option<Vec<PathBuf>>,
        /// Samples per pixel of the truth and the real-time images.
        #[arg(long, default_value = "16")]
        spp: SamplesPerPixel,
        /// Each image's longer side in pixels (the scene camera's aspect kept).
        #[arg(long, default_value_t = 128)]
        side: u32,
        /// WGSL frames to time per row (0: none); without an adapter no WGSL row is made.
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
    /// The real-time algorithm of translucent media (`render --method cells`) against their
    /// ground truth: the scene's settings, each sample count per cell, exact integration, no
    /// shadows and the other real-time cell order, with PSNR, FLIP, mask and CPU seconds; the
    /// WGSL pipeline's frame time and its error against the truth and its CPU twin; the time
    /// to order every pixel's cells and to sort the cells for the view. Markdown on stdout; transparency.md, transparency.json and transparency.svg
    /// (PSNR against seconds) in --out.
    Transparency {
        /// Scene file (a translucent medium).
        #[arg(long, default_value = "scenes/torus-fur.json")]
        scene: PathBuf,
        /// Samples per cell, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1,4,16,64")]
        samples: Vec<u32>,
        /// Image side in pixels instead of the scene camera's (square images).
        #[arg(long)]
        side: Option<u32>,
        /// Real-time frames to time per row (0: none).
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Output directory.
        #[arg(long, default_value = "out/report")]
        out: PathBuf,
    },
}

/// Writes `files` (name, contents) into `out`, prints `table` and says what was written.
/// Refuses an image side outside 1..=[`mesobake_core::limits::MAX_IMAGE_SIDE`].
fn check_side(side: u32) -> Result<()> {
    if (1..=mesobake_core::limits::MAX_IMAGE_SIDE).contains(&side) {
        Ok(())
    } else {
        Err(Error::InvalidParameter(format!(
            "--side must be between 1 and {}, got {side}",
            mesobake_core::limits::MAX_IMAGE_SIDE
        )))
    }
}

fn publish(out: &Path, table: &str, files: &[(&str, &str)]) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    for (name, contents) in files {
        write_atomic(&out.join(name), contents.as_bytes())?;
    }
    print!("{table}");
    let names: Vec<&str> = files.iter().map(|(name, _)| *name).collect();
    let listed = match names.as_slice() {
        [rest @ .., last] if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => names.join(""),
    };
    eprintln!("wrote {listed} in {}", out.display());
    Ok(())
}

/// The codecs report on the scene files `scenes`, with a progress bar.
/// The scenes at `paths`, each with its name (the file stem) and folder.
fn load_named_scenes<'p>(
    paths: &'p [PathBuf],
    limits: &Limits,
) -> Result<Vec<(String, LoadedScene, &'p Path)>> {
    paths
        .iter()
        .map(|path| {
            let name = path
                .file_stem()
                .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
            let dir = path.parent().unwrap_or(Path::new("."));
            Ok((name, load_scene(path, limits)?, dir))
        })
        .collect()
}

fn run_codecs(
    scenes: &[PathBuf],
    sweep: &codecs::CodecSweep,
    limits: &Limits,
) -> Result<codecs::CodecReport> {
    let loaded = load_named_scenes(scenes, limits)?;
    let progress = Progress::new("codec report");
    let report = codecs::codec_report(&loaded, sweep, limits, &progress)?;
    progress.finish();
    Ok(report)
}

/// A report as pretty JSON.
fn to_json(report: &impl serde::Serialize) -> String {
    serde_json::to_string_pretty(report).expect("reports serialize")
}

/// Writes `STEM.md` (the table) and `STEM.json` (the report) into `out`, prints the table.
fn publish_report(
    out: &Path,
    stem: &str,
    table: &str,
    report: &impl serde::Serialize,
) -> Result<()> {
    let json = to_json(report);
    publish(
        out,
        table,
        &[
            (&format!("{stem}.md"), table),
            (&format!("{stem}.json"), &json),
        ],
    )
}

/// The `.json` files in `dir`, sorted.
fn scene_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.extension().is_some_and(|e| e == "json") {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// The scene at `path` with its file stem as its name, its image made `side`² if given.
fn load_named(path: &Path, side: Option<u32>, limits: &Limits) -> Result<(String, LoadedScene)> {
    let mut loaded = load_scene(path, limits)?;
    if let Some(side) = side {
        check_side(side)?;
        loaded.scene.camera.width = side;
        loaded.scene.camera.height = side;
    }
    let name = path
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    Ok((name, loaded))
}

/// Runs the report.
pub fn report(which: ReportCommand, limits: &Limits) -> Result<()> {
    match which {
        ReportCommand::Accuracy {
            input,
            res,
            dirs,
            ranks,
            quants,
            scenes,
            out,
        } => {
            let sweep = accuracy::Sweep {
                dirs,
                ranks,
                quantizations: quants,
            };
            let progress = Progress::new("accuracy report");
            let rows = accuracy::accuracy(&input, res, &sweep, limits, &progress)?;
            progress.finish();
            let mut table = accuracy::markdown(&rows);
            let csv = accuracy::csv(&rows);
            let svg = accuracy::svg_plot(&rows)?;
            let mut files = vec![("accuracy.csv", csv), ("accuracy.svg", svg)];
            let scenes: Vec<PathBuf> = scenes
                .into_iter()
                .filter(|p| !p.as_os_str().is_empty())
                .collect();
            if !scenes.is_empty() {
                let report = run_codecs(&scenes, &codecs::CodecSweep::default(), limits)?;
                table += &format!("\n## Codecs\n\n{}", codecs::markdown(&report));
                files.push(("codecs.json", to_json(&report)));
                files.push(("codecs.svg", codecs::svg_plot(&report)?));
            }
            files.push(("accuracy.md", table.clone()));
            let files: Vec<(&str, &str)> = files.iter().map(|(n, c)| (*n, c.as_str())).collect();
            publish(&out, &table, &files)
        }
        ReportCommand::Codecs {
            scenes,
            ranks,
            quant,
            tiles,
            visibility,
            frames,
            out,
        } => {
            let sweep = codecs::CodecSweep {
                ranks,
                quantization: quant,
                tiles,
                visibility,
                frames,
            };
            let report = run_codecs(&scenes, &sweep, limits)?;
            let table = codecs::markdown(&report);
            let json = to_json(&report);
            let svg = codecs::svg_plot(&report)?;
            publish(
                &out,
                &table,
                &[
                    ("codecs.md", &table),
                    ("codecs.json", &json),
                    ("codecs.svg", &svg),
                ],
            )
        }
        ReportCommand::Conformance {
            scenes,
            spp,
            side,
            frames,
            out,
        } => {
            check_side(side)?;
            let scenes = match scenes {
                Some(scenes) => scenes,
                None => scene_files(Path::new("scenes"))?,
            };
            let mut loaded = load_named_scenes(&scenes, limits)?;
            for (_, l, _) in &mut loaded {
                let c = &mut l.scene.camera;
                let longer = f64::from(c.width.max(c.height));
                let scale =
                    |n: u32| ((f64::from(n) * f64::from(side) / longer).round() as u32).max(1);
                (c.width, c.height) = (scale(c.width), scale(c.height));
            }
            let gpu = Gpu::open(None).ok();
            let progress = Progress::new("conformance report");
            let (report, sheet) = conformance::conformance_report(
                &mut loaded,
                spp,
                gpu.as_ref(),
                frames,
                limits,
                &progress,
            )?;
            progress.finish();
            let table = conformance::markdown(&report);
            let json = to_json(&report);
            publish(
                &out,
                &table,
                &[("conformance.md", &table), ("conformance.json", &json)],
            )?;
            sheet.write(&out.join("conformance.png"))
        }
        ReportCommand::Quality {
            scenes,
            side,
            frames,
            out,
        } => {
            let mut loaded = load_named_scenes(&scenes, limits)?;
            if let Some(side) = side {
                check_side(side)?;
                for (_, l, _) in &mut loaded {
                    l.scene.camera.width = side;
                    l.scene.camera.height = side;
                }
            }
            let progress = Progress::new("quality report");
            let report = quality::quality_report(
                &mut loaded,
                &quality::default_settings(),
                frames,
                limits,
                &progress,
            )?;
            progress.finish();
            let table = quality::markdown(&report);
            let json = to_json(&report);
            let svg = quality::svg_plot(&report)?;
            publish(
                &out,
                &table,
                &[
                    ("quality.md", &table),
                    ("quality.json", &json),
                    ("quality.svg", &svg),
                ],
            )
        }
        ReportCommand::Gi {
            scene,
            dirs,
            bounces,
            prt_samples,
            path_samples,
            rtv_ranks,
            image_scale,
            out,
        } => {
            let loaded = load_scene(&scene, limits)?;
            let sweep = gi::GiSweep {
                dirs,
                bounces,
                prt_samples,
                path_samples,
                rtv_ranks,
                image_scale,
            };
            let progress = Progress::new("GI accuracy report");
            let report = gi::gi_accuracy(&loaded, &sweep, limits, &progress)?;
            progress.finish();
            publish_report(&out, "gi-accuracy", &gi::markdown(&report), &report)
        }
        ReportCommand::Render {
            scene,
            dirs,
            ranks,
            quant,
            refinements,
            out,
        } => {
            let loaded = load_scene(&scene, limits)?;
            let sweep = render::RenderSweep {
                dirs,
                ranks,
                quantization: quant,
                refinements,
            };
            let progress = Progress::new("render accuracy report");
            let report = render::render_accuracy(&loaded, &sweep, limits, &progress)?;
            progress.finish();
            publish_report(&out, "render-accuracy", &render::markdown(&report), &report)
        }
        ReportCommand::Vdm {
            scene,
            curvatures,
            dirs,
            methods,
            ranks,
            quants,
            side,
            frames,
            out,
        } => {
            let (name, loaded) = load_named(&scene, side, limits)?;
            let sweep = vdm::VdmSweep {
                curvatures,
                directions: dirs,
                methods,
                ranks,
                quantizations: quants,
                frames,
            };
            let dir = scene.parent().unwrap_or(Path::new("."));
            let progress = Progress::new("VDM report");
            let report = vdm::vdm_report(&name, &loaded, dir, &sweep, limits, &progress)?;
            progress.finish();
            let table = vdm::markdown(&report);
            let json = to_json(&report);
            let svg = vdm::svg_plot(&report)?;
            publish(
                &out,
                &table,
                &[("vdm.md", &table), ("vdm.json", &json), ("vdm.svg", &svg)],
            )
        }
        ReportCommand::Transparency {
            scene,
            samples,
            side,
            frames,
            out,
        } => {
            let (name, loaded) = load_named(&scene, side, limits)?;
            let progress = Progress::new("transparency report");
            let report =
                transparency::transparency_report(&name, &loaded, &samples, frames, &progress)?;
            progress.finish();
            let table = transparency::markdown(&report);
            let json = to_json(&report);
            let svg = transparency::svg_plot(&report)?;
            publish(
                &out,
                &table,
                &[
                    ("transparency.md", &table),
                    ("transparency.json", &json),
                    ("transparency.svg", &svg),
                ],
            )
        }
    }
}
