//! Scene → image with the real-time pipeline (`mesobake preview`, the server's previews):
//! renders a scene with its package ([`crate::package`]) on the GPU and optionally
//! times frames; where no adapter exists, by its CPU twin if asked to ([`PreviewDevice`]).
//! The package's kind picks the pipeline: the GDM's, the VDM's or the translucent media's; a
//! scene of several objects is drawn from a GDM or VDM package per object, each by its
//! technique's passes into shared targets ([`objects_preview`]), its CPU twin the objects'
//! real-time renderers composed.

use crate::LoadedScene;
use crate::gi;
use crate::render::{RenderMethod, check_composable, render_objects};
use crate::technique::Technique;
use mesobake_bake::mesostructure::medium::Medium;
use mesobake_bake::package::medium as medium_package;
use mesobake_bake::package::vdm::{VdmPackage, height_field};
use mesobake_bake::package::{AnyPackage, Package};
use mesobake_bake::vdm::Relief;
use mesobake_core::camera::Camera;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::{BakeObserver, CancellationOf};
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::{ADAPTER_ENV, AdapterDescription, Gpu};
use mesobake_gpu::medium_pipeline::MediumPreview;
use mesobake_gpu::pipeline::{ObjectTechnique, Preview, PreviewObject};
use mesobake_gpu::resources::GpuMemory;
use mesobake_gpu::variant::ShaderVariant;
use mesobake_gpu::vdm_pipeline::VdmPreview;
use mesobake_render::gdm_lookup::package_lookup;
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::image::Image;
use mesobake_render::medium_cells::CellRenderer;
use mesobake_render::render_image_observed;
use mesobake_render::sampling::supersample;
use mesobake_render::shot::Shot;
use mesobake_render::vdm_renderer::VdmRenderer;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// What a preview does where no GPU adapter exists at all.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PreviewFallback {
    /// Render with the CPU twin of the real-time pipeline: the GDM (or VDM) software
    /// renderer, its specification, which the tests hold the WGSL to (≥ 35 dB).
    #[default]
    Cpu,
    /// Fail with the adapter error.
    None,
}

impl std::str::FromStr for PreviewFallback {
    type Err = Error;

    fn from_str(text: &str) -> Result<PreviewFallback> {
        match text {
            "cpu" => Ok(PreviewFallback::Cpu),
            "none" => Ok(PreviewFallback::None),
            _ => Err(Error::InvalidParameter(format!(
                "preview fallback {text:?}: expected cpu or none"
            ))),
        }
    }
}

/// Where previews render: the GPU, or the CPU twin where no adapter exists.
pub enum PreviewDevice {
    /// The real-time pipeline on this adapter.
    Gpu(Gpu),
    /// The CPU twin, and why (the adapter error).
    Cpu {
        /// The error opening an adapter gave.
        reason: String,
    },
}

impl PreviewDevice {
    /// Opens the adapter as [`Gpu::open`] does. When that fails and no adapter was named
    /// (`name`, [`ADAPTER_ENV`]), `fallback` decides: the CPU twin, or the error. A named
    /// adapter that is missing is always an error.
    pub fn open(name: Option<&str>, fallback: PreviewFallback) -> Result<PreviewDevice> {
        let named = name.is_some() || std::env::var(ADAPTER_ENV).is_ok_and(|s| !s.is_empty());
        match Gpu::open(name) {
            Ok(gpu) => Ok(PreviewDevice::Gpu(gpu)),
            Err(e) if !named && fallback == PreviewFallback::Cpu => Ok(PreviewDevice::Cpu {
                reason: e.to_string(),
            }),
            Err(e) => Err(e),
        }
    }

    /// `gpu` or `cpu`.
    pub fn renderer(&self) -> &'static str {
        match self {
            PreviewDevice::Gpu(_) => "gpu",
            PreviewDevice::Cpu { .. } => "cpu",
        }
    }

    /// Renders `loaded` with `package`; with `frames` > 0, also times that many frames,
    /// reporting them to `observer` (stage `timing frames`).
    pub fn render(
        &self,
        loaded: &LoadedScene,
        package: &AnyPackage,
        frames: u32,
        observer: &dyn BakeObserver,
    ) -> Result<(Image, PreviewOutcome)> {
        self.run(
            |gpu| preview(gpu, loaded, package, frames, observer),
            || render_on_cpu(loaded, package, &CancellationOf(observer)),
            frames,
            observer,
        )
    }

    /// Renders several objects together, each from its GDM or VDM package
    /// ([`objects_preview`]), or where no adapter exists by the CPU twin ([`render_objects`]
    /// with each package's renderer); with `frames` > 0, also times that many frames.
    pub fn render_objects(
        &self,
        objects: &[LoadedScene],
        packages: &[AnyPackage],
        frames: u32,
        observer: &dyn BakeObserver,
    ) -> Result<(Image, PreviewOutcome)> {
        let methods = object_methods(objects, packages)?;
        let given: Vec<Option<&AnyPackage>> = packages.iter().map(Some).collect();
        self.run(
            |gpu| objects_preview(gpu, objects, packages, frames, observer),
            || {
                // Every object has its package: nothing is baked, so no limit applies.
                let cancel = CancellationOf(observer);
                let limits = Limits::default();
                Ok(render_objects(objects, &methods, &given, &cancel, &limits)?.image)
            },
            frames,
            observer,
        )
    }

    /// Renders with `on_gpu`, or with `on_cpu` (timing `frames` more of them) where there is
    /// no adapter or the adapter cut the pipeline's loops short ([`Error::LoopBudget`]).
    fn run(
        &self,
        on_gpu: impl FnOnce(&Gpu) -> Result<(Image, PreviewReport)>,
        on_cpu: impl Fn() -> Result<Image>,
        frames: u32,
        observer: &dyn BakeObserver,
    ) -> Result<(Image, PreviewOutcome)> {
        let reason = match self {
            PreviewDevice::Gpu(gpu) => match on_gpu(gpu) {
                Ok((image, report)) => {
                    let outcome = PreviewOutcome {
                        renderer: "gpu",
                        fallback_reason: None,
                        gpu: Some(report),
                        cpu_mean_frame_seconds: None,
                    };
                    return Ok((image, outcome));
                }
                Err(e @ Error::LoopBudget { .. }) => e.to_string(),
                Err(e) => return Err(e),
            },
            PreviewDevice::Cpu { reason } => reason.clone(),
        };
        let image = on_cpu()?;
        observer.stage("timing frames");
        let start = Instant::now();
        for frame in 1..=frames {
            on_cpu()?;
            observer.progress(frame.into(), frames.into());
        }
        let mean = (frames > 0).then(|| start.elapsed().as_secs_f64() / frames as f64);
        let outcome = PreviewOutcome {
            renderer: "cpu",
            fallback_reason: Some(reason),
            gpu: None,
            cpu_mean_frame_seconds: mean,
        };
        Ok((image, outcome))
    }
}

/// What rendered a preview, and what it measured.
#[derive(Clone, Debug, Serialize)]
pub struct PreviewOutcome {
    /// `gpu` (the WGSL pipeline) or `cpu` (its CPU twin, where no adapter exists or the
    /// adapter cut the pipeline short).
    pub renderer: &'static str,
    /// Why the CPU twin rendered: the adapter error, or the loop budget it ran out of.
    pub fallback_reason: Option<String>,
    /// The real-time pipeline's report, for `gpu`.
    pub gpu: Option<PreviewReport>,
    /// The CPU twin's mean seconds per frame over the timed frames, for `cpu`.
    pub cpu_mean_frame_seconds: Option<f64>,
}

/// The real-time pipeline's CPU twin, the specification the WGSL follows: the GDM software
/// renderer on a GDM package ([`gdm_render_on_cpu`]), the VDM software renderer on a VDM
/// package, the cells renderer on a medium package's levels. Stops with
/// [`Error::Cancelled`] within a tile of `observer` asking it to.
pub fn render_on_cpu(
    loaded: &LoadedScene,
    package: &AnyPackage,
    observer: &dyn BakeObserver,
) -> Result<Image> {
    match package {
        AnyPackage::Medium(p) => {
            let settings = loaded.scene.transparency;
            let levels = medium_package::levels(p, settings.mipmap)?;
            let cells = CellRenderer::with_levels(&loaded.shell, &levels, settings);
            cells_image(loaded, &cells, observer)
        }
        AnyPackage::Gdm(p) => gdm_render_on_cpu(loaded, p, observer),
        AnyPackage::Vdm(p) => {
            let field = height_field(p)?;
            let relief = Relief {
                field: &field,
                depth: p.manifest().relief.depth,
            };
            let query = p.query();
            let r = VdmRenderer::new(&loaded.shell, &query, relief)?;
            let shot = loaded.scene.shot();
            render_image_observed(&shot.camera, observer, |o, d| r.radiance(&shot, o, d))
        }
    }
}

/// The GDM pipeline's CPU twin: the GDM software renderer on `package`, with its RTV and PRT
/// when the scene calls for environment lighting; cancelled as [`render_on_cpu`] is.
pub fn gdm_render_on_cpu(
    loaded: &LoadedScene,
    package: &Package,
    observer: &dyn BakeObserver,
) -> Result<Image> {
    package.check_grid(loaded.material.dims())?;
    let scene = &loaded.scene;
    let lookup = package_lookup(package)?;
    let gi = gi::called_for_shading(loaded, package)?;
    let mut r = GdmRenderer::new(
        &loaded.shell,
        &*lookup,
        &loaded.material,
        scene.gdm_refinements,
    )
    .with_quality(scene.quality);
    if let Some(gi) = &gi {
        r = r.with_gi(gi);
    }
    let shot = scene.shot();
    render_image_observed(&shot.camera, observer, |o, d| r.radiance(&shot, o, d))
}

/// What a preview ran on, chose and measured.
#[derive(Clone, Debug, Serialize)]
pub struct PreviewReport {
    /// The adapter.
    pub adapter: AdapterDescription,
    /// The pipeline: the package's technique, `gdm`, `vdm` or `transparency`.
    pub technique: &'static str,
    /// The GDM shader variant the scene's effects chose (none for the VDM and media
    /// pipelines, which have one each).
    pub variant: Option<ShaderVariant>,
    /// GPU memory per kind of resource.
    pub memory: GpuMemory,
    /// Seconds to upload the scene and build the pipeline.
    pub setup_seconds: f64,
    /// Seconds for the first image, a frame per sample per pixel, read-backs included.
    pub first_frame_seconds: f64,
    /// Mean seconds per frame over the timed frames (none when no frames were timed).
    pub mean_frame_seconds: Option<f64>,
    /// Frames timed.
    pub frames: u32,
}

/// Renders `loaded` with `package` on `gpu` by the package's pipeline; with `frames` > 0,
/// also times that many frames.
pub fn preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    package: &AnyPackage,
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    match package {
        AnyPackage::Gdm(package) => gdm_preview(gpu, loaded, package, frames, observer),
        AnyPackage::Vdm(package) => vdm_preview(gpu, loaded, package, frames, observer),
        AnyPackage::Medium(package) => {
            let settings = loaded.scene.transparency;
            let levels = medium_package::levels(package, settings.mipmap)?;
            let cells = CellRenderer::with_levels(&loaded.shell, &levels, settings);
            cells_preview(gpu, loaded, cells, frames, observer)
        }
    }
}

/// The GDM pipeline for `loaded` with `package` (and, where the scene calls for environment
/// lighting, the package's RTV with the scene's environment), with the early depth test
/// where `early_depth_test` allows it and the adapter has it.
pub fn gdm_pipeline<'g>(
    gpu: &'g Gpu,
    loaded: &LoadedScene,
    package: &Package,
    early_depth_test: bool,
) -> Result<Preview<'g>> {
    let gi = gi::called_for_shading(loaded, package)?;
    Preview::new(
        gpu,
        &loaded.scene.shot(),
        &loaded.shell,
        &loaded.material,
        package,
        gi.as_ref(),
        early_depth_test,
    )
}

/// [`preview`] by the GDM pipeline.
pub fn gdm_preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    package: &Package,
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    let start = Instant::now();
    let preview = gdm_pipeline(gpu, loaded, package, true)?;
    let setup = (preview.variant(), start.elapsed().as_secs_f64());
    measure(
        gpu,
        &loaded.scene.camera,
        &preview,
        Technique::Gdm.name(),
        setup,
        frames,
        observer,
    )
}

/// The real-time method of each object's package (one each, in order: GDM or VDM), or the
/// error naming the first object the preview of several objects cannot draw.
fn object_methods(objects: &[LoadedScene], packages: &[AnyPackage]) -> Result<Vec<RenderMethod>> {
    if objects.len() != packages.len() {
        return Err(Error::InvalidParameter(format!(
            "{} objects but {} packages: a preview of several objects takes one package per object",
            objects.len(),
            packages.len()
        )));
    }
    let mut methods = Vec::with_capacity(packages.len());
    for (i, (object, package)) in objects.iter().zip(packages).enumerate() {
        check_composable(object)?;
        methods.push(match package {
            AnyPackage::Gdm(p) => {
                p.check_grid(object.material.dims())?;
                RenderMethod::Gdm
            }
            AnyPackage::Vdm(_) => RenderMethod::Vdm,
            other => {
                return Err(Error::InvalidParameter(format!(
                    "object {} has a {} package: the preview of several objects draws GDM and \
                     VDM objects",
                    i + 1,
                    Technique::of_package(other).name()
                )));
            }
        });
    }
    Ok(methods)
}

/// Renders several objects together on `gpu` ([`Preview::of_objects`]), each from its GDM
/// or VDM package (one object alone by its technique's own pipeline, as [`preview`] draws
/// it); with `frames` > 0, also times that many frames.
pub fn objects_preview(
    gpu: &Gpu,
    objects: &[LoadedScene],
    packages: &[AnyPackage],
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    object_methods(objects, packages)?;
    if let ([object], [package]) = (objects, packages) {
        return preview(gpu, object, package, frames, observer);
    }
    let start = Instant::now();
    let shots: Vec<Shot> = objects.iter().map(|o| o.scene.shot()).collect();
    // The VDM objects' factors and height fields, which their parts borrow.
    let mut reliefs = Vec::new();
    for package in packages {
        reliefs.push(match package {
            AnyPackage::Vdm(p) => Some((p.query(), height_field(p)?, p.manifest().relief.depth)),
            _ => None,
        });
    }
    let mut parts = Vec::with_capacity(objects.len());
    for ((o, shot), (package, relief)) in objects
        .iter()
        .zip(&shots)
        .zip(packages.iter().zip(&reliefs))
    {
        let technique = match (package, relief) {
            (AnyPackage::Gdm(package), _) => ObjectTechnique::Gdm {
                material: &o.material,
                package,
                gi: None,
            },
            (_, Some((query, field, depth))) => ObjectTechnique::Vdm {
                query,
                relief: Relief {
                    field,
                    depth: *depth,
                },
            },
            // `object_methods` refused it already.
            (other, None) => {
                return Err(Error::InvalidParameter(format!(
                    "the preview of several objects draws no {} package",
                    Technique::of_package(other).name()
                )));
            }
        };
        parts.push(PreviewObject {
            shot,
            shell: &o.shell,
            technique,
        });
    }
    let preview = Preview::of_objects(gpu, &parts, true)?;
    let setup = (preview.variant(), start.elapsed().as_secs_f64());
    let camera = &shots[0].camera;
    let technique = objects_technique(packages);
    measure(gpu, camera, &preview, technique, setup, frames, observer)
}

/// The technique a preview of several objects reports: theirs where they share one, else
/// `mixed`.
pub fn objects_technique(packages: &[AnyPackage]) -> &'static str {
    let mut names = packages.iter().map(|p| Technique::of_package(p).name());
    let first = names.next().unwrap_or("gdm");
    if names.all(|n| n == first) {
        first
    } else {
        "mixed"
    }
}

/// [`preview`] by the VDM pipeline.
fn vdm_preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    package: &VdmPackage,
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    let start = Instant::now();
    let field = height_field(package)?;
    let relief = Relief {
        field: &field,
        depth: package.manifest().relief.depth,
    };
    let shot = loaded.scene.shot();
    let preview = VdmPreview::new(gpu, &shot, &loaded.shell, &package.query(), relief)?;
    let setup = (None, start.elapsed().as_secs_f64());
    measure(
        gpu,
        &loaded.scene.camera,
        &preview,
        Technique::Vdm.name(),
        setup,
        frames,
        observer,
    )
}

/// `loaded`'s translucent medium, or the error that its mesostructure is opaque.
fn translucent(loaded: &LoadedScene) -> Result<&Medium> {
    loaded.medium.as_ref().ok_or_else(|| {
        Error::Scene(
            "the translucent-media pipeline renders translucent media only; this scene's \
             mesostructure is opaque"
                .into(),
        )
    })
}

/// The cells renderer over `loaded`'s own medium (no package), with the scene's
/// transparency settings.
fn scene_cells(loaded: &LoadedScene) -> Result<CellRenderer<'_>> {
    let medium = translucent(loaded)?;
    Ok(CellRenderer::new(
        &loaded.shell,
        medium,
        loaded.scene.transparency,
    ))
}

/// The image `cells` renders of `loaded`'s scene, cancelled as [`render_on_cpu`] is.
fn cells_image(
    loaded: &LoadedScene,
    cells: &CellRenderer,
    observer: &dyn BakeObserver,
) -> Result<Image> {
    let shot = loaded.scene.shot();
    render_image_observed(&shot.camera, observer, |o, d| cells.radiance(&shot, o, d))
}

/// The translucent-media pipeline's CPU twin on `loaded`'s own medium (no package):
/// [`CellRenderer`] with the scene's transparency settings.
pub fn medium_render_on_cpu(loaded: &LoadedScene) -> Result<Image> {
    cells_image(loaded, &scene_cells(loaded)?, &())
}

/// Renders `loaded`'s own translucent medium (no package) with the translucent-media
/// pipeline on `gpu`; with `frames` > 0, also times that many frames.
pub fn medium_preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    cells_preview(gpu, loaded, scene_cells(loaded)?, frames, observer)
}

/// Renders what `cells` holds of `loaded` with the translucent-media pipeline on `gpu`; with
/// `frames` > 0, also times that many frames.
fn cells_preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    cells: CellRenderer,
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    let start = Instant::now();
    let preview = MediumPreview::new(gpu, &loaded.scene.shot(), cells)?;
    let setup = (None, start.elapsed().as_secs_f64());
    let technique = Technique::Transparency.name();
    let camera = &loaded.scene.camera;
    measure(gpu, camera, &preview, technique, setup, frames, observer)
}

/// Renders the first image of `pipeline`, a frame per sample of the camera's samples per
/// pixel (timed, read-backs included) and, with `frames` > 0, times that many more frames
/// of one sample; `setup` is the shader variant and the seconds setting it up took.
fn measure(
    gpu: &Gpu,
    camera: &Camera,
    pipeline: &dyn RealtimePipeline,
    technique: &'static str,
    (variant, setup_seconds): (Option<ShaderVariant>, f64),
    frames: u32,
    observer: &dyn BakeObserver,
) -> Result<(Image, PreviewReport)> {
    let start = Instant::now();
    let image = supersample(camera, |offset| {
        if observer.cancelled() {
            return Err(Error::Cancelled);
        }
        pipeline.set_subpixel(offset);
        pipeline.render()
    })?;
    pipeline.set_subpixel(camera.subpixel);
    let first_frame_seconds = start.elapsed().as_secs_f64();
    let mean_frame_seconds = if frames > 0 {
        observer.stage("timing frames");
        Some(pipeline.time_frames(frames, observer)?)
    } else {
        None
    };
    let report = PreviewReport {
        adapter: gpu.adapter.clone(),
        technique,
        variant,
        memory: pipeline.memory(),
        setup_seconds,
        first_frame_seconds,
        mean_frame_seconds,
        frames,
    };
    Ok((image, report))
}
