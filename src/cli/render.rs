//! `mesobake render` (a scene on the CPU: the truth or the GDM algorithm) and `mesobake
//! compare` (PSNR, error and mask disagreement of two images).

use super::output::{Progress, print_json};
use mesobake::package::AnyPackage;
use mesobake::render::gdm_renderer::Substitutions;
use mesobake::render::image::{Image, compare, difference};
use mesobake::render::quality::Quality;
use mesobake::scene::package::check_any_package_input;
use mesobake::scene::render::{MapSource, RenderMethod, load_scene, render_substituted};
use mesobake::scene::technique::Technique;
use mesobake::util::limits::Limits;
use mesobake::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `mesobake render`.
#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene (JSON; see docs/scene-format.md).
    #[arg(long)]
    scene: PathBuf,
    /// truth: exact mapping into the real mesostructure; gdm: the real-time algorithm;
    /// vdm (height fields): the VDM real-time algorithm; explicit (mesh tiles only): the
    /// tile's triangles mapped through the shell and ray cast as a plain mesh, the truth's
    /// independent check; cells (translucent media): the semi-transparent 3D texture
    /// algorithm. Default: the kind of --package, else cells for a translucent medium, else
    /// the scene's technique.
    #[arg(long)]
    method: Option<RenderMethod>,
    /// For --method gdm or vdm: render from this (GDM or VDM) package instead of baking. It
    /// must have been baked from the scene's mesostructure (unless --force).
    #[arg(long)]
    package: Option<PathBuf>,
    /// Render --package even when it was baked from another mesostructure than the scene's.
    #[arg(long, requires = "package")]
    force: bool,
    /// Output image (.png or .exr).
    #[arg(long)]
    out: PathBuf,
    /// Print a JSON summary (seconds per stage, hit pixels, shell report) on stdout.
    #[arg(long)]
    json: bool,
    /// For --method gdm, a reference run: parts of the algorithm replaced by the truth's,
    /// comma-separated (query: the exact cast along each chord; shadows: the truth's rays).
    /// See `report render`'s error budget.
    #[arg(long, default_value = "none")]
    substitute: Substitutions,
    /// For --method gdm: the per-pixel algorithm's accuracy knobs instead of the scene's
    /// `quality` (a preset, `paper`, `balanced` or `high`, or JSON settings as in a scene file).
    #[arg(long)]
    quality: Option<Quality>,
}

/// Renders the scene and writes the image.
pub fn render(args: RenderArgs, limits: &Limits) -> Result<()> {
    let RenderArgs {
        scene,
        method,
        package,
        force,
        out,
        json,
        substitute,
        quality,
    } = args;
    let start = Instant::now();
    let mut loaded = load_scene(&scene, limits)?;
    if let Some(quality) = quality {
        loaded.scene.quality = quality;
    }
    let load_s = start.elapsed().as_secs_f64();
    let dir = scene.parent().unwrap_or(Path::new("."));
    if package.is_some() && matches!(method, Some(RenderMethod::Truth | RenderMethod::Explicit)) {
        return Err(Error::InvalidParameter(
            "--package only applies to --method gdm, vdm and cells".into(),
        ));
    }
    let package = package
        .map(|path| -> Result<AnyPackage> {
            let package = AnyPackage::read(&path, limits)?;
            if !force {
                check_any_package_input(&package, &loaded.scene, dir)
                    .map_err(|e| e.context(path.display()))?;
            }
            Ok(package)
        })
        .transpose()?;
    let method = match (method, &package) {
        (Some(method), _) => method,
        (None, Some(AnyPackage::Gdm(_))) => RenderMethod::Gdm,
        (None, Some(AnyPackage::Vdm(_))) => RenderMethod::Vdm,
        (None, Some(AnyPackage::Medium(_))) => RenderMethod::Cells,
        (None, None) => match loaded.technique().technique {
            Technique::Vdm => RenderMethod::Vdm,
            Technique::Transparency => RenderMethod::Cells,
            Technique::Gdm | Technique::Auto => RenderMethod::Gdm,
        },
    };
    let source = match &package {
        Some(AnyPackage::Gdm(p)) => MapSource::Package(p),
        Some(AnyPackage::Vdm(p)) => MapSource::VdmPackage(p),
        Some(AnyPackage::Medium(p)) => MapSource::MediumPackage(p),
        None => MapSource::Bake,
    };
    let progress = Progress::new(match (method, &source) {
        (RenderMethod::Gdm, MapSource::Bake) => "baking GDM (exact)",
        (RenderMethod::Vdm, MapSource::Bake) => "baking VDM",
        _ => "rendering",
    });
    let mut rendered = render_substituted(&loaded, method, source, substitute, limits, &progress)?;
    progress.finish();
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
        print_json(&serde_json::json!({
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
        }));
    }
    Ok(())
}

/// Options of `mesobake compare`.
#[derive(clap::Args)]
pub struct CompareArgs {
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
}

/// Compares the two images.
pub fn compare_images(args: CompareArgs) -> Result<()> {
    let (a, b) = (Image::read(&args.a)?, Image::read(&args.b)?);
    let c = compare(&a, &b)?;
    if let Some(path) = args.diff {
        difference(&a, &b)?.write(&path)?;
    }
    if args.json {
        print_json(&serde_json::json!(c));
    } else {
        println!(
            "PSNR {:.2} dB, FLIP {:.4}, mean absolute error {:.5}, mask disagreement {:.4} % of \
             {} pixels",
            c.psnr_db,
            c.flip_mean,
            c.mean_abs_error,
            100.0 * c.mask_disagreement,
            c.pixels
        );
    }
    Ok(())
}
