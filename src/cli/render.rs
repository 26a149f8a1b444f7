//! `mesobake render` (a scene on the CPU: the truth or the GDM algorithm) and `mesobake
//! compare` (PSNR, error and mask disagreement of two images).

use super::codec::CodecOptions;
use super::output::{Progress, print_json};
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::package::AnyPackage;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::limits::Limits;
use mesobake_core::quality::Quality;
use mesobake_core::samples_per_pixel::SamplesPerPixel;
use mesobake_core::{Error, Result};
use mesobake_render::gdm_renderer::Substitutions;
use mesobake_render::image::{Image, compare, difference};
use mesobake_scene::LoadedScene;
use mesobake_scene::objects::{self, SceneObject};
use mesobake_scene::package::{check_any_package_input, gdm_scene_package, scene_package};
use mesobake_scene::render::{MapSource, RenderMethod, render_objects, render_substituted};
use mesobake_scene::technique::Technique;
use std::path::{Path, PathBuf};
use std::str::FromStr;
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
    /// For --method gdm, vdm or cells: render from this (GDM, VDM or medium) package instead
    /// of the scene's. It must have been baked from the scene's mesostructure (unless
    /// --force).
    #[arg(long)]
    package: Option<PathBuf>,
    /// Without --package, the GDM that --method gdm queries: occupancy or paper-svd, the
    /// package `preview` and the server bake for the scene with that codec (--rank and
    /// --quant size paper-svd's SVD), or uncompressed, the exact GDM baked on the scene's
    /// grids and queried by the paper's interpolation. Without --package, every method
    /// renders what `preview` renders by default: the scene's package (occupancy).
    #[arg(long, default_value = "occupancy")]
    gdm_codec: GdmSource,
    /// SVD components to keep, --gdm-codec paper-svd only [default: 8].
    #[arg(long)]
    rank: Option<usize>,
    /// Number format of paper-svd's factors: f32, f16, or u8 [default: f16].
    #[arg(long)]
    quant: Option<Quantization>,
    /// Render --package even when it was baked from another mesostructure than the scene's.
    #[arg(long, requires = "package")]
    force: bool,
    /// Output image (.png or .exr).
    #[arg(long)]
    out: PathBuf,
    /// Camera rays averaged per pixel (1..=1024, stratified sub-pixel positions shared by
    /// every renderer; the pixel is their mean in linear light, a hit where at least half
    /// hit) instead of the scene camera's `samples_per_pixel` (default 1, the centre).
    #[arg(long)]
    spp: Option<SamplesPerPixel>,
    /// Print a JSON summary (seconds per stage, hit pixels, shell report) on stdout.
    #[arg(long)]
    json: bool,
    /// For --method gdm, a reference run: parts of the algorithm replaced by the truth's,
    /// comma-separated (query: the exact cast along each chord; shadows: the truth's rays);
    /// for --method vdm, shadows only. See `report render`'s error budget.
    #[arg(long, default_value = "none")]
    substitute: Substitutions,
    /// For --method gdm: the per-pixel algorithm's accuracy knobs instead of the scene's
    /// `quality` (a preset, `paper`, `balanced` or `high`, or JSON settings as in a scene file).
    #[arg(long)]
    quality: Option<Quality>,
}

/// The GDM a render without --package queries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GdmSource {
    /// The scene's package with this codec.
    Package(GdmCodec),
    /// The uncompressed GDM.
    Uncompressed,
}

impl FromStr for GdmSource {
    type Err = Error;
    fn from_str(text: &str) -> Result<GdmSource> {
        match text {
            "uncompressed" => Ok(GdmSource::Uncompressed),
            _ => text.parse().map(GdmSource::Package).map_err(|_| {
                Error::InvalidParameter(format!(
                    "GDM codec {text:?}: expected occupancy, paper-svd or uncompressed"
                ))
            }),
        }
    }
}

/// Renders the scene and writes the image.
pub fn render(args: RenderArgs, limits: &Limits) -> Result<()> {
    let RenderArgs {
        scene,
        method,
        package,
        gdm_codec,
        rank,
        quant,
        force,
        out,
        json,
        spp,
        substitute,
        quality,
    } = args;
    let start = Instant::now();
    let dir = scene.parent().unwrap_or(Path::new("."));
    let mut objects = objects::read(&scene)?;
    for object in &mut objects {
        if let Some(quality) = quality {
            object.scene.quality = quality;
        }
        if let Some(spp) = spp {
            object.scene.camera.set_samples_per_pixel(spp)?;
        }
    }
    let codec = CodecOptions {
        gdm_codec: match gdm_codec {
            GdmSource::Package(codec) => codec,
            GdmSource::Uncompressed => GdmCodec::default(),
        },
        rank,
        quant,
    };
    codec.check(None)?;
    if objects.len() > 1 {
        if package.is_some() || substitute != Substitutions::default() {
            return Err(Error::InvalidParameter(
                "--package and --substitute render one object; this scene has several".into(),
            ));
        }
        let several = Several {
            method,
            uncompressed: gdm_codec == GdmSource::Uncompressed,
            codec,
            out,
            json,
        };
        return render_several(&scene, objects, several, limits);
    }
    let scene_object = objects.remove(0).scene;
    let loaded = LoadedScene::load(scene_object, dir, limits)?;
    let load_s = start.elapsed().as_secs_f64();
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
    let codec_chosen = codec.is_chosen() || gdm_codec == GdmSource::Uncompressed;
    if codec_chosen
        && (package.is_some()
            || matches!(method, Some(RenderMethod::Truth | RenderMethod::Explicit)))
    {
        return Err(Error::InvalidParameter(
            "--gdm-codec, --rank and --quant choose the GDM that --method gdm queries without \
             --package"
                .into(),
        ));
    }
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
    // Without --package, the real-time methods render the scene's package, as `preview`
    // does (a method the scene's technique does not bake for bakes its own map).
    let package = match (package, method) {
        (Some(package), _) => Some(package),
        (None, RenderMethod::Truth | RenderMethod::Explicit) => None,
        (None, RenderMethod::Gdm) if gdm_codec == GdmSource::Uncompressed => None,
        (None, _) => {
            if method != RenderMethod::Cells {
                loaded.check_opaque(&format!("the {} renderer", method.name()))?;
            }
            let progress = Progress::new("baking the package");
            let params = codec.scene_params();
            let baked = if method == RenderMethod::Gdm {
                AnyPackage::Gdm(gdm_scene_package(&loaded, dir, params, limits, &progress)?)
            } else {
                scene_package(&loaded, dir, params, limits, &progress)?
            };
            progress.finish();
            let fits = matches!(
                (method, &baked),
                (RenderMethod::Gdm, AnyPackage::Gdm(_))
                    | (RenderMethod::Vdm, AnyPackage::Vdm(_))
                    | (RenderMethod::Cells, AnyPackage::Medium(_))
            );
            fits.then_some(baked)
        }
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
            "samples_per_pixel": loaded.scene.camera.samples_per_pixel,
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

/// What `render` does with a scene of several objects.
struct Several {
    /// Every object's method, or by default each its technique's.
    method: Option<RenderMethod>,
    /// Whether `gdm` queries each object's exact GDM instead of its package.
    uncompressed: bool,
    codec: CodecOptions,
    out: PathBuf,
    json: bool,
}

/// Renders a scene of several objects together (`--method truth`, `gdm` or `vdm`, by default
/// each object's technique), each object's package baked as `preview` would.
fn render_several(
    path: &Path,
    objects: Vec<SceneObject>,
    options: Several,
    limits: &Limits,
) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let start = Instant::now();
    let names: Vec<String> = objects.iter().map(|o| o.name.clone()).collect();
    let loaded = objects
        .into_iter()
        .map(|o| {
            let name = o.name;
            LoadedScene::load(o.scene, dir, limits)
                .map_err(|e| e.context(format!("object {name:?}")))
        })
        .collect::<Result<Vec<_>>>()?;
    let load_s = start.elapsed().as_secs_f64();
    let methods: Vec<RenderMethod> = loaded
        .iter()
        .map(|o| {
            options.method.unwrap_or(match o.technique().technique {
                Technique::Vdm => RenderMethod::Vdm,
                Technique::Transparency => RenderMethod::Cells,
                Technique::Gdm | Technique::Auto => RenderMethod::Gdm,
            })
        })
        .collect();
    let progress = Progress::new("baking the objects' packages");
    let params = options.codec.scene_params();
    let mut packages = Vec::new();
    for (o, method) in loaded.iter().zip(&methods) {
        packages.push(match method {
            RenderMethod::Gdm if !options.uncompressed => Some(AnyPackage::Gdm(gdm_scene_package(
                o, dir, params, limits, &progress,
            )?)),
            RenderMethod::Vdm => Some(scene_package(o, dir, params, limits, &progress)?),
            _ => None,
        });
    }
    let package_refs: Vec<Option<&AnyPackage>> = packages.iter().map(Option::as_ref).collect();
    let mut rendered = render_objects(&loaded, &methods, &package_refs, &progress, limits)?;
    progress.finish();
    rendered.seconds.load = load_s;
    rendered.image.write(&options.out)?;
    let image = &rendered.image;
    eprintln!(
        "wrote {} ({}×{}, {} objects, {} hit pixels) in {:.2} s of rendering",
        options.out.display(),
        image.width,
        image.height,
        loaded.len(),
        image.hits(),
        rendered.seconds.render
    );
    if options.json {
        let objects: Vec<_> = names
            .iter()
            .zip(&loaded)
            .map(|(name, o)| {
                serde_json::json!({
                    "name": name,
                    "base_mesh": o.base_report,
                    "shell": o.shell.report,
                })
            })
            .collect();
        print_json(&serde_json::json!({
            "scene": path,
            "output": options.out,
            "methods": methods,
            "samples_per_pixel": loaded[0].scene.camera.samples_per_pixel,
            "width": image.width,
            "height": image.height,
            "hit_pixels": image.hits(),
            "objects": objects,
            "seconds": rendered.seconds,
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
