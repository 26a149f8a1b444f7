//! Scene → image with the real-time pipeline (`mesobake preview`): loads the scene, reads
//! its package or bakes one (exact GDM, then SVD and quantization as `mesobake bake` does),
//! renders on the GPU and optionally times frames.

use crate::bake_package::{
    BakedPackage, PackageParams, StageSeconds, bake_info, compress_and_encode,
};
use crate::compress::quantize::Quantization;
use crate::compress::svd::RankChoice;
use crate::error::{Error, Result};
use crate::gdm::fast::FastParams;
use crate::gdm::{BakeObserver, EscapeConvention, Method};
use crate::limits::Limits;
use crate::package::Package;
use crate::package::manifest::InputInfo;
use crate::realtime::gpu::{AdapterDescription, Gpu};
use crate::realtime::pipeline::Preview;
use crate::realtime::resources::GpuMemory;
use crate::realtime::variant::ShaderVariant;
use crate::render::image::Image;
use crate::render_scene::bake_gdm;
use crate::scene::{LoadedScene, MesostructureSource};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// How a package is made for a scene that names none.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct ScenePackageParams {
    /// SVD components.
    pub rank: RankChoice,
    /// Number format of the factors.
    pub quantization: Quantization,
}

impl Default for ScenePackageParams {
    /// Rank 8 in f16, the defaults of `mesobake bake`.
    fn default() -> Self {
        ScenePackageParams {
            rank: RankChoice::Rank(8),
            quantization: Quantization::F16,
        }
    }
}

/// The package of a loaded scene's mesostructure: the exact GDM on the scene's grids,
/// compressed with `params`. The manifest's input identity is the hash of the mesostructure
/// file the scene names, or of the scene's `mesostructure` and `resolution` entries for a
/// built-in sample.
pub fn bake_scene_package(
    loaded: &LoadedScene,
    scene_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<BakedPackage> {
    let scene = &loaded.scene;
    let identity = match &scene.mesostructure {
        MesostructureSource::Sample(_) => {
            serde_json::to_vec(&(&scene.mesostructure, scene.resolution))
                .map_err(|e| Error::Scene(e.to_string()))?
        }
        MesostructureSource::Volume(p)
        | MesostructureSource::Tile(p)
        | MesostructureSource::HeightField(p) => {
            let path = scene_dir.join(p);
            std::fs::read(&path).map_err(|e| Error::io(path, e))?
        }
    };
    let input = InputInfo {
        kind: match scene.mesostructure {
            MesostructureSource::HeightField(_) => "height_field",
            MesostructureSource::Tile(_) => "mesh",
            MesostructureSource::Volume(_) | MesostructureSource::Sample(_) => "volume",
        }
        .into(),
        bytes: identity.len() as u64,
        blake3: blake3::hash(&identity).to_hex().to_string(),
    };
    let mut seconds = StageSeconds::default();
    let start = Instant::now();
    let mut g = bake_gdm(loaded, limits, observer)?;
    seconds.bake = start.elapsed().as_secs_f64();
    g.set_escape_convention(EscapeConvention::Boundary);
    let package_params = PackageParams {
        res: Some(g.dims()),
        dirs: g.dirs(),
        method: Method::Exact,
        fast: FastParams::default(),
        rank: params.rank,
        quantization: params.quantization,
        allow_open: false,
    };
    let info = bake_info(&g, Method::Exact, FastParams::default(), false);
    let (bytes, gdm) = compress_and_encode(
        &g,
        input,
        info,
        &package_params,
        limits,
        observer,
        &mut seconds,
    )?;
    Ok(BakedPackage {
        bytes,
        gdm,
        seconds,
    })
}

/// [`bake_scene_package`], parsed.
pub fn scene_package(
    loaded: &LoadedScene,
    scene_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Package> {
    Package::parse(bake_scene_package(loaded, scene_dir, params, limits, observer)?.bytes)
}

/// What a preview ran on, chose and measured.
#[derive(Clone, Debug, Serialize)]
pub struct PreviewReport {
    /// The adapter.
    pub adapter: AdapterDescription,
    /// The shader variant the scene's effects chose.
    pub variant: ShaderVariant,
    /// GPU memory per kind of resource.
    pub memory: GpuMemory,
    /// Seconds to upload the scene and build the pipeline.
    pub setup_seconds: f64,
    /// Seconds for the first frame, read-back included.
    pub first_frame_seconds: f64,
    /// Mean seconds per frame over the timed frames (none when no frames were timed).
    pub mean_frame_seconds: Option<f64>,
    /// Frames timed.
    pub frames: u32,
}

/// Renders `loaded` with `package` on `gpu`; with `frames` > 0, also times that many frames.
pub fn preview(
    gpu: &Gpu,
    loaded: &LoadedScene,
    package: &Package,
    frames: u32,
) -> Result<(Image, PreviewReport)> {
    let start = Instant::now();
    let preview = Preview::new(gpu, loaded, package, true)?;
    let setup_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let image = preview.render()?;
    let first_frame_seconds = start.elapsed().as_secs_f64();
    let mean_frame_seconds = if frames > 0 {
        Some(preview.time_frames(frames)?)
    } else {
        None
    };
    Ok((
        image,
        PreviewReport {
            adapter: preview.adapter().clone(),
            variant: preview.variant(),
            memory: preview.memory(),
            setup_seconds,
            first_frame_seconds,
            mean_frame_seconds,
            frames,
        },
    ))
}
