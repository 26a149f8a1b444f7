//! `mesobake preview`: a scene through the real-time pipeline (WGSL on wgpu, headless).

use super::codec::CodecOptions;
use super::output::{Progress, print_json};
use mesobake_bake::package::AnyPackage;
use mesobake_core::Result;
use mesobake_core::limits::Limits;
use mesobake_core::quality::Quality;
use mesobake_core::samples_per_pixel::SamplesPerPixel;
use mesobake_scene::LoadedScene;
use mesobake_scene::objects::{self, SceneObject};
use mesobake_scene::package::{check_any_package_input, scene_package};
use mesobake_scene::preview::{PreviewDevice, PreviewFallback, objects_technique};
use mesobake_scene::render::check_composable;
use mesobake_scene::technique::Technique;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `mesobake preview`.
#[derive(clap::Args)]
pub struct PreviewArgs {
    /// The scene (JSON; see docs/scene-format.md).
    #[arg(long)]
    scene: PathBuf,
    /// Output image (.png or .exr).
    #[arg(long)]
    out: PathBuf,
    /// Render from this package (GDM, VDM or medium; a GDM package's grid must be the scene's, and
    /// it must have been baked from the scene's mesostructure unless --force) instead of
    /// baking one. The package's kind picks the pipeline.
    #[arg(long)]
    package: Option<PathBuf>,
    /// Render --package even when it was baked from another mesostructure than the scene's.
    #[arg(long, requires = "package")]
    force: bool,
    /// How the package baked for the scene (without --package) answers GDM queries.
    #[command(flatten)]
    codec: CodecOptions,
    /// Also render this many frames and report the mean frame time.
    #[arg(long, default_value_t = 0)]
    frames: u32,
    /// Use the adapter whose name contains this (case-insensitive; default: the
    /// MESOBAKE_ADAPTER environment variable, else wgpu's choice).
    #[arg(long)]
    adapter: Option<String>,
    /// Where no GPU adapter exists (and none was named): cpu renders with the real-time
    /// pipeline's CPU twin (the GDM or VDM software renderer, which the WGSL follows), and
    /// the JSON says "renderer": "cpu"; none fails.
    #[arg(long, default_value = "cpu")]
    fallback: PreviewFallback,
    /// The per-pixel algorithm's accuracy knobs instead of the scene's `quality` (a preset,
    /// `paper`, `balanced` or `high`, or JSON settings as in a scene file).
    #[arg(long)]
    quality: Option<Quality>,
    /// Camera rays averaged per pixel (1..=1024, stratified sub-pixel positions shared by
    /// every renderer; the pixel is their mean in linear light, a hit where at least half
    /// hit) instead of the scene camera's `samples_per_pixel` (default 1, the centre).
    #[arg(long)]
    spp: Option<SamplesPerPixel>,
    /// Print a JSON summary (adapter, shader variant, GPU memory, seconds) on stdout.
    #[arg(long)]
    json: bool,
}

/// Renders the preview (baking a package for the scene unless one is given).
pub fn preview(args: PreviewArgs, limits: &Limits) -> Result<()> {
    let PreviewArgs {
        scene,
        out,
        package,
        force,
        codec,
        frames,
        adapter,
        fallback,
        quality,
        spp,
        json,
    } = args;
    codec.check(None)?;
    if package.is_some() && codec.is_chosen() {
        return Err(mesobake_core::Error::InvalidParameter(
            "--gdm-codec, --rank and --quant choose the package baked for the scene; \
             --package renders a package as it is"
                .into(),
        ));
    }
    let mut objects = objects::read(&scene)?;
    if objects.len() > 1 {
        if package.is_some() {
            return Err(mesobake_core::Error::InvalidParameter(
                "--package renders one object's package; a scene of several objects is \
                 previewed from a package baked for each object"
                    .into(),
            ));
        }
        let options = Several {
            codec,
            frames,
            adapter,
            fallback,
            quality,
            spp,
            out,
            json,
        };
        return preview_several(&scene, objects, options, limits);
    }
    let start = Instant::now();
    let dir = scene.parent().unwrap_or(Path::new("."));
    let mut loaded = LoadedScene::load(objects.remove(0).scene, dir, limits)?;
    if let Some(quality) = quality {
        loaded.scene.quality = quality;
    }
    if let Some(spp) = spp {
        loaded.scene.camera.set_samples_per_pixel(spp)?;
    }
    let load_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let package = if let Some(path) = &package {
        let package = AnyPackage::read(path, limits)?;
        if !force {
            check_any_package_input(&package, &loaded.scene, dir)
                .map_err(|e| e.context(path.display()))?;
        }
        package
    } else {
        let progress = Progress::new("baking the package");
        let p = scene_package(&loaded, dir, codec.scene_params(), limits, &progress)?;
        progress.finish();
        p
    };
    let package_s = start.elapsed().as_secs_f64();
    let device = PreviewDevice::open(adapter.as_deref(), fallback)?;
    let progress = Progress::new("rendering");
    let rendered = device.render(&loaded, &package, frames, &progress);
    progress.finish();
    let technique = Technique::of_package(&package).name();
    let (image, outcome) = rendered?;
    image.write(&out)?;
    let on = match (&outcome.gpu, &outcome.fallback_reason) {
        (Some(report), _) => format!(
            "{} ({})",
            report.adapter.name,
            report
                .variant
                .as_ref()
                .map_or(format!("the {} pipeline", report.technique), |v| v.name())
        ),
        (None, reason) => format!(
            "the CPU twin of the real-time pipeline, as no GPU adapter is usable ({})",
            reason.as_deref().unwrap_or("")
        ),
    };
    eprintln!(
        "wrote {} ({}×{}, {} hit pixels) on {on}",
        out.display(),
        image.width,
        image.height,
        image.hits(),
    );
    if let Some(report) = &outcome.gpu {
        eprintln!(
            "GPU memory {:.1} MB (package {:.1} MB)",
            report.memory.total() as f64 / 1e6,
            report.memory.package as f64 / 1e6
        );
    }
    let mean = outcome
        .gpu
        .as_ref()
        .and_then(|r| r.mean_frame_seconds)
        .or(outcome.cpu_mean_frame_seconds);
    if let Some(t) = mean {
        eprintln!("mean frame time over {frames} frames: {:.3} ms", t * 1e3);
    }
    if json {
        print_json(&serde_json::json!({
            "scene": scene,
            "output": out,
            "width": image.width,
            "height": image.height,
            "hit_pixels": image.hits(),
            "samples_per_pixel": loaded.scene.camera.samples_per_pixel,
            "seconds": { "load": load_s, "package": package_s },
            "technique": technique,
            "renderer": outcome.renderer,
            "fallback_reason": outcome.fallback_reason,
            "cpu_mean_frame_seconds": outcome.cpu_mean_frame_seconds,
            "preview": outcome.gpu,
        }));
    }
    Ok(())
}

/// What `preview` does with a scene of several objects.
struct Several {
    codec: CodecOptions,
    frames: u32,
    adapter: Option<String>,
    fallback: PreviewFallback,
    quality: Option<Quality>,
    spp: Option<SamplesPerPixel>,
    out: PathBuf,
    json: bool,
}

/// Previews a scene of several objects: a package baked for each object (as `bake --scene`
/// bakes it: GDM or VDM), all drawn together by the real-time pipeline.
fn preview_several(
    path: &Path,
    objects: Vec<SceneObject>,
    options: Several,
    limits: &Limits,
) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let start = Instant::now();
    let mut loaded = Vec::with_capacity(objects.len());
    for SceneObject { name, mut scene } in objects {
        if let Some(quality) = options.quality {
            scene.quality = quality;
        }
        if let Some(spp) = options.spp {
            scene.camera.set_samples_per_pixel(spp)?;
        }
        let object = LoadedScene::load(scene, dir, limits)
            .and_then(|object| check_composable(&object).map(|()| object))
            .map_err(|e| e.context(format!("object {name:?}")))?;
        loaded.push((name, object));
    }
    let load_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let progress = Progress::new("baking the objects' packages");
    let mut packages = Vec::with_capacity(loaded.len());
    for (_, o) in &loaded {
        let params = options.codec.scene_params();
        packages.push(scene_package(o, dir, params, limits, &progress)?);
    }
    progress.finish();
    let package_s = start.elapsed().as_secs_f64();
    let (names, loaded): (Vec<String>, Vec<LoadedScene>) = loaded.into_iter().unzip();
    let device = PreviewDevice::open(options.adapter.as_deref(), options.fallback)?;
    let progress = Progress::new("rendering");
    let rendered = device.render_objects(&loaded, &packages, options.frames, &progress);
    progress.finish();
    let (image, outcome) = rendered?;
    image.write(&options.out)?;
    eprintln!(
        "wrote {} ({}×{}, {} objects, {} hit pixels) on {}",
        options.out.display(),
        image.width,
        image.height,
        loaded.len(),
        image.hits(),
        outcome.renderer
    );
    if options.json {
        print_json(&serde_json::json!({
            "scene": path,
            "output": options.out,
            "objects": names,
            "width": image.width,
            "height": image.height,
            "hit_pixels": image.hits(),
            "samples_per_pixel": loaded[0].scene.camera.samples_per_pixel,
            "seconds": { "load": load_s, "package": package_s },
            "technique": objects_technique(&packages),
            "renderer": outcome.renderer,
            "fallback_reason": outcome.fallback_reason,
            "cpu_mean_frame_seconds": outcome.cpu_mean_frame_seconds,
            "preview": outcome.gpu,
        }));
    }
    Ok(())
}
