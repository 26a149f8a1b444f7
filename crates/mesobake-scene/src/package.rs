//! A scene's package: exactly the stages its technique and effects call for ([`plan`]), run
//! in order ([`bake_scene_package`]). Used by `mesobake bake --scene`, `mesobake preview` and
//! the server's bake jobs.
//!
//! A VDM scene ([`crate::technique`]): the VDM of its height field as its `vdm`
//! settings say, compressed, in a VDM package. A GDM scene: always what the codec needs: the occupancy field, or the exact GDM on the scene's grids and
//! its SVD compression (`paper-svd`). With `environment_lighting`: the macro-scale PRT of the
//! base mesh (shadowed with `macro_shadows`), the exact GDM for the RTV's visibility, the RTV
//! (glossy with `environment_gloss`) and its compression. The
//! environment itself is not baked in: packages hold transfer, which any environment lights.

use crate::gi::{prt_matrices, rtv_params};
use crate::memory::bake_memory;
use crate::plan::{Plan, plan};
use crate::technique::{self, Technique, TechniqueChoice};
use crate::{LoadedScene, MesostructureSource, Scene, load_base_mesh};
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::gdm::fast::FastParams;
use mesobake_bake::gdm::{EscapeConvention, Method};
use mesobake_bake::gi::compressed_rtv::{CompressedRtv, RtvCompression};
use mesobake_bake::gi::prt::geometry_hash;
use mesobake_bake::gi::rtv::{self, RtvStats};
use mesobake_bake::mesostructure::{reliefs, volume_format};
use mesobake_bake::package::bake::{PackageParams, StageSeconds, compress_gdm};
use mesobake_bake::package::gi::GiPayload;
use mesobake_bake::package::manifest::{BakeInfo, GdmCodec};
use mesobake_bake::package::manifest::{GiInfo, InputInfo};
use mesobake_bake::package::medium as medium_package;
use mesobake_bake::package::vdm as vdm_package;
use mesobake_bake::package::{AnyPackage, GdmPayload, Package};
use mesobake_bake::surface::shell::Shell;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::medium::{MediumAccuracy, MediumManifest};
use mesobake_package::vdm::VdmAccuracy;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

/// How a package is made for a scene that names none.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScenePackageParams {
    /// What answers the renderers' GDM queries.
    pub codec: GdmCodec,
    /// SVD components (`paper-svd`).
    pub rank: RankChoice,
    /// Number format of the factors (`paper-svd`).
    pub quantization: Quantization,
}

impl Default for ScenePackageParams {
    /// The defaults of `mesobake bake`: the occupancy codec (for `paper-svd`: rank 8 in f16).
    fn default() -> Self {
        ScenePackageParams {
            codec: GdmCodec::default(),
            rank: RankChoice::Rank(8),
            quantization: Quantization::F16,
        }
    }
}

/// What the radiance-transfer stages made and measured.
#[derive(Clone, Debug, Serialize)]
pub struct GiBake {
    /// The RTV bake.
    pub rtv: RtvStats,
    /// The RTV's compression.
    pub compression: RtvCompression,
    /// Whether the PRT is shadowed.
    pub macro_shadows: bool,
}

/// What a scene's package holds for its technique.
pub enum ScenePayload {
    /// A GDM package's payload.
    Gdm(GdmPayload),
    /// A VDM package's compression.
    Vdm {
        /// Components of the VDM's reconstruction.
        rank: usize,
        /// Components of the MVM's reconstruction.
        mvm_rank: usize,
        /// Number format of the factors.
        quantization: Quantization,
        /// Measured against the bake.
        accuracy: VdmAccuracy,
    },
    /// A medium package's levels.
    Medium {
        /// Grids of the levels stored, level 0 first.
        levels: Vec<[u32; 3]>,
        /// Number format of the textures.
        quantization: Quantization,
        /// The stored values' error.
        accuracy: MediumAccuracy,
    },
}

/// A scene's package and what making it took.
pub struct ScenePackage {
    /// The package's bytes (a GDM or a VDM package, as the plan's technique says).
    pub bytes: Vec<u8>,
    /// What it holds.
    pub payload: ScenePayload,
    /// The stages run and skipped.
    pub plan: Plan,
    /// Seconds per stage run (`load` is the caller's), in `plan` order.
    pub seconds: Vec<(String, f64)>,
    /// The radiance transfer's figures, when baked.
    pub gi: Option<GiBake>,
}

/// The plan of `scene`'s package made with `params` (its files relative to `base_dir`),
/// without loading its mesostructure: the technique chosen on its base mesh and shell (a
/// volume probed for an opacity channel) and checked, its peak memory ([`bake_memory`])
/// checked against `limits`, then the stages it calls for ([`plan`]). Parameters that do
/// not apply to the technique are an error.
pub fn plan_package(
    scene: &Scene,
    base_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
) -> Result<Plan> {
    let (base, report) = load_base_mesh(scene, base_dir, limits)?;
    let translucent = match &scene.mesostructure {
        MesostructureSource::Volume(path) => {
            volume_format::has_opacity(&base_dir.join(path), limits)?
        }
        _ => false,
    };
    let shell = Shell::new(&base, scene.shell)?;
    let surface = technique::Surface::of(&report, &shell).with_translucent(translucent);
    let choice = technique::choose(scene, &surface);
    technique::check(scene, &choice, &surface)?;
    check_params(&choice, params)?;
    let gdm_params = (params.codec, params.rank);
    bake_memory(scene, base_dir, choice.technique, gdm_params)?.check(limits)?;
    Ok(plan(scene, params.codec, choice))
}

/// What a package of `technique` for `scene` made with `params` depends on, as JSON: equal
/// keys, equal packages. A medium package: the mesostructure, its grid, whether the mip-map
/// is baked and the quantization (never the base mesh or the shell, so an animated surface
/// bakes nothing). A VDM package: the height field, the VDM settings, and what the relief's
/// depth depends on (the base mesh, its scale and the shell). A GDM package: the
/// mesostructure, its grids and the package parameters; with environment lighting also what
/// the PRT and RTV depend on (the base mesh, the material, the GI knobs and effects). Never
/// the camera, lights or environment, which a package does not hold.
pub fn package_key(
    scene: &Scene,
    technique: Technique,
    params: ScenePackageParams,
) -> serde_json::Value {
    let s = scene;
    let version = mesobake_bake::package::container::VERSION;
    match technique {
        Technique::Transparency => {
            return serde_json::json!({
                "version": version,
                "technique": technique,
                "mesostructure": s.mesostructure,
                "resolution": s.resolution,
                "mipmap": s.transparency.mipmap,
                "quantization": s.transparency.quantization,
            });
        }
        Technique::Vdm => {
            return serde_json::json!({
                "version": version,
                "technique": technique,
                "mesostructure": s.mesostructure,
                "resolution": s.resolution,
                "vdm": s.vdm,
                "base_mesh": s.base_mesh,
                "mesh_scale": s.mesh_scale,
                "shell": s.shell,
            });
        }
        Technique::Gdm | Technique::Auto => {}
    }
    let mut key = serde_json::json!({
        "version": version,
        "mesostructure": s.mesostructure,
        "resolution": s.resolution,
        "directions": s.directions,
        "codec": params.codec,
    });
    if params.codec == GdmCodec::PaperSvd {
        key["rank"] = serde_json::json!(params.rank);
        key["quantization"] = serde_json::json!(params.quantization);
    }
    if s.wants(Effect::EnvironmentLighting) {
        let effects: Vec<Effect> = [Effect::MacroShadows, Effect::EnvironmentGloss]
            .into_iter()
            .filter(|e| s.wants(*e))
            .collect();
        key["gi"] = serde_json::json!({
            "base_mesh": s.base_mesh,
            "mesh_scale": s.mesh_scale,
            "material": s.material,
            "gi": [s.gi.bounces as usize, s.gi.prt_samples, s.gi.rtv_rank],
            "effects": effects,
        });
    }
    key
}

/// Checks that `params` apply to a package for `technique`: a VDM package is made as the
/// scene's `vdm` settings say, a medium package as its `transparency` settings say, so GDM
/// package parameters other than the defaults are an error.
pub fn check_params(technique: &TechniqueChoice, params: ScenePackageParams) -> Result<()> {
    let settings = match technique.technique {
        Technique::Vdm => "vdm",
        Technique::Transparency => "transparency",
        _ => return Ok(()),
    };
    if params != ScenePackageParams::default() {
        return Err(Error::InvalidParameter(format!(
            "the scene's technique is {settings} ({}): its package is made as the scene's \
             `{settings}` settings say, and the GDM codec, rank and quantization do not apply",
            technique.reason
        )));
    }
    Ok(())
}

/// Bakes the package of `loaded` as [`plan`] says, for the technique
/// [`LoadedScene::technique`] chooses. The manifest's input identity is the hash of the
/// mesostructure file the scene names, or of the scene's `mesostructure` and `resolution`
/// entries for a built-in sample (of the relief's PNG for a built-in relief).
pub fn bake_scene_package(
    loaded: &LoadedScene,
    scene_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<ScenePackage> {
    let technique = loaded.technique();
    bake_technique_package(loaded, technique, scene_dir, params, limits, observer)
}

/// [`bake_scene_package`] for `technique` instead of the scene's choice.
fn bake_technique_package(
    loaded: &LoadedScene,
    technique: TechniqueChoice,
    scene_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<ScenePackage> {
    let scene = &loaded.scene;
    technique::check(scene, &technique, &loaded.surface())?;
    check_params(&technique, params)?;
    let plan = plan(scene, params.codec, technique);
    let input = input_identity(scene, scene_dir)?;
    match plan.technique.technique {
        Technique::Vdm => return bake_vdm_package(loaded, input, plan, limits, observer),
        Technique::Transparency => return bake_medium_package(loaded, input, plan, observer),
        _ => {}
    }
    let mut seconds = Vec::new();
    let (dims, dirs) = (scene.dims()?, scene.dirs()?);
    let info = BakeInfo {
        res: [dims.x, dims.y, dims.z],
        dirs: [dirs.n_theta, dirs.n_phi],
        method: Method::Exact,
        fast: None,
        allow_open: false,
    };
    let gdm = if plan.runs("bake_gdm") {
        let start = Instant::now();
        observer.stage("bake_gdm");
        let mut g = loaded.bake_gdm(limits, observer)?;
        seconds.push(("bake_gdm".to_owned(), start.elapsed().as_secs_f64()));
        g.set_escape_convention(EscapeConvention::Boundary);
        Some(g)
    } else {
        None
    };
    let payload = match (params.codec, &gdm) {
        (GdmCodec::PaperSvd, Some(g)) => {
            let package_params = PackageParams {
                res: Some(dims),
                dirs,
                codec: params.codec,
                method: Method::Exact,
                fast: FastParams::default(),
                rank: params.rank,
                quantization: params.quantization,
                allow_open: false,
            };
            let mut stage = StageSeconds::default();
            observer.stage("compress");
            let compressed = compress_gdm(g, &package_params, limits, observer, &mut stage)?;
            seconds.push(("compress".to_owned(), stage.svd + stage.quantize));
            GdmPayload::PaperSvd(Box::new(compressed))
        }
        _ => {
            let start = Instant::now();
            observer.stage("occupancy");
            let field = loaded.mesostructure.caster().centres_inside().field();
            seconds.push(("occupancy".to_owned(), start.elapsed().as_secs_f64()));
            GdmPayload::Occupancy(field)
        }
    };

    let transfer = if scene.wants(Effect::EnvironmentLighting) {
        let start = Instant::now();
        observer.stage("bake_prt");
        let prt = prt_matrices(loaded)?;
        seconds.push(("bake_prt".to_owned(), start.elapsed().as_secs_f64()));
        let start = Instant::now();
        let rtv_params = rtv_params(scene);
        observer.stage("bake_rtv");
        let g = gdm.as_ref().expect("the plan bakes the GDM for the RTV");
        let (rtv, stats) = rtv::bake(g, &loaded.material, &rtv_params, limits, observer)?;
        seconds.push(("bake_rtv".to_owned(), start.elapsed().as_secs_f64()));
        observer.stage("compress_rtv");
        let (compressed, compression, compress_s) =
            CompressedRtv::compress(&rtv, dirs, scene.gi.rtv_rank, limits)?;
        seconds.push(("compress_rtv".to_owned(), compress_s));
        let macro_shadows = scene.wants(Effect::MacroShadows);
        let info = GiInfo {
            samples: stats.samples as u32,
            bounces: rtv_params.bounces,
            glossy: rtv_params.glossy,
            compression: compression.clone(),
            vertices: loaded.base.positions.len() as u32,
            macro_shadows,
            base_mesh: geometry_hash(&loaded.base),
        };
        let figures = GiBake {
            rtv: stats,
            compression,
            macro_shadows,
        };
        Some((info, compressed, prt, figures))
    } else {
        None
    };
    let start = Instant::now();
    observer.stage("encode");
    let transfer_payload = transfer.as_ref().map(|(info, rtv, prt, _)| GiPayload {
        info: info.clone(),
        rtv,
        prt,
    });
    let bytes = Package::encode_with(input, info, &payload, transfer_payload.as_ref());
    seconds.push(("encode".to_owned(), start.elapsed().as_secs_f64()));
    let gi = transfer.map(|t| t.3);
    Ok(ScenePackage {
        bytes,
        payload: ScenePayload::Gdm(payload),
        plan,
        seconds,
        gi,
    })
}

/// The VDM package of `loaded`'s height field, identified by `input`, as `plan` says.
fn bake_vdm_package(
    loaded: &LoadedScene,
    input: InputInfo,
    plan: Plan,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<ScenePackage> {
    let baked = loaded.bake_vdm(limits, observer)?;
    let start = Instant::now();
    observer.stage("encode");
    let c = &baked.compressed;
    let bytes = vdm_package::encode(
        input,
        &baked.field,
        &baked.vdm,
        loaded.scene.vdm.params(),
        c,
    );
    let seconds = vec![
        ("bake_vdm".to_owned(), baked.seconds[0]),
        ("compress_vdm".to_owned(), baked.seconds[1]),
        ("encode".to_owned(), start.elapsed().as_secs_f64()),
    ];
    Ok(ScenePackage {
        bytes,
        payload: ScenePayload::Vdm {
            rank: c.vdm_rank,
            mvm_rank: c.mvm_rank,
            quantization: c.weights.format,
            accuracy: c.accuracy,
        },
        plan,
        seconds,
        gi: None,
    })
}

/// The medium package of `loaded`'s translucent medium, identified by `input`, as `plan`
/// says.
fn bake_medium_package(
    loaded: &LoadedScene,
    input: InputInfo,
    plan: Plan,
    observer: &dyn BakeObserver,
) -> Result<ScenePackage> {
    let medium = (loaded.medium.as_ref()).expect("the transparency technique loads a medium");
    let mut seconds = Vec::new();
    let coarser = if plan.runs("medium_mips") {
        let start = Instant::now();
        observer.stage("medium_mips");
        let coarser = medium.coarser_levels();
        seconds.push(("medium_mips".to_owned(), start.elapsed().as_secs_f64()));
        coarser
    } else {
        Vec::new()
    };
    let start = Instant::now();
    observer.stage("encode");
    let q = loaded.scene.transparency.quantization;
    let bytes = medium_package::encode(input, medium, &coarser, q);
    seconds.push(("encode".to_owned(), start.elapsed().as_secs_f64()));
    // The manifest alone (the container checked, the textures not decoded again).
    let manifest: MediumManifest = mesobake_bake::package::container::parse(&bytes)?;
    let info = &manifest.medium;
    Ok(ScenePackage {
        bytes,
        payload: ScenePayload::Medium {
            levels: info.levels.iter().map(|l| l.res).collect(),
            quantization: q,
            accuracy: info.accuracy,
        },
        plan,
        seconds,
        gi: None,
    })
}

/// [`bake_scene_package`], parsed.
pub fn scene_package(
    loaded: &LoadedScene,
    scene_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<AnyPackage> {
    AnyPackage::parse(bake_scene_package(loaded, scene_dir, params, limits, observer)?.bytes)
}

/// The scene's GDM package, whatever technique it chooses (for comparisons and the GDM
/// pipeline's measurements), parsed.
pub fn gdm_scene_package(
    loaded: &LoadedScene,
    scene_dir: &Path,
    params: ScenePackageParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Package> {
    let technique = TechniqueChoice {
        technique: Technique::Gdm,
        reason: "a GDM package was asked for".into(),
    };
    let baked = bake_technique_package(loaded, technique, scene_dir, params, limits, observer)?;
    Package::parse(baked.bytes)
}

/// Checks that `package` was baked from `scene`'s mesostructure: its grid is the scene's
/// resolution and its manifest's input identity is the one [`bake_scene_package`] records
/// for the scene (files it names resolved against `scene_dir`). Another mesostructure's
/// package would render the scene's shell with the wrong geometry, silently.
pub fn check_package_input(package: &Package, scene: &Scene, scene_dir: &Path) -> Result<()> {
    package.check_grid(scene.dims()?)?;
    check_input(&package.manifest().input, scene, scene_dir)
}

/// Checks that a package of any kind was baked from `scene`'s mesostructure, as
/// [`check_package_input`] (a GDM package) and [`check_input`] say; a medium package's level
/// 0 must also be the scene's grid.
pub fn check_any_package_input(
    package: &AnyPackage,
    scene: &Scene,
    scene_dir: &Path,
) -> Result<()> {
    match package {
        AnyPackage::Gdm(p) => check_package_input(p, scene, scene_dir),
        AnyPackage::Vdm(p) => check_input(&p.manifest().input, scene, scene_dir),
        AnyPackage::Medium(p) => {
            let res = p.manifest().medium.levels[0].res;
            if res != scene.resolution {
                return Err(Error::Scene(format!(
                    "the package holds a {}x{}x{} medium but the scene's resolution is {}x{}x{}",
                    res[0],
                    res[1],
                    res[2],
                    scene.resolution[0],
                    scene.resolution[1],
                    scene.resolution[2]
                )));
            }
            check_input(&p.manifest().input, scene, scene_dir)
        }
    }
}

/// Checks that a package's recorded input identity `found` is that of `scene`'s
/// mesostructure (see [`check_package_input`]; a VDM package's height field is identified
/// the same way).
pub fn check_input(found: &InputInfo, scene: &Scene, scene_dir: &Path) -> Result<()> {
    let expected = input_identity(scene, scene_dir)?;
    if found.blake3 == expected.blake3 {
        return Ok(());
    }
    let short = |h: &str| h.chars().take(12).collect::<String>();
    Err(Error::Scene(format!(
        "the package was baked from another mesostructure ({} input, BLAKE3 {}…) than the \
         scene names ({} input, BLAKE3 {}…); bake it for this scene, or pass --force to \
         render it anyway",
        found.kind,
        short(&found.blake3),
        expected.kind,
        short(&expected.blake3)
    )))
}

/// The identity of `scene`'s mesostructure input, as a manifest records it: a file's bytes
/// (hashed as they stream, never held), or the description of a generated input.
pub fn input_identity(scene: &Scene, scene_dir: &Path) -> Result<InputInfo> {
    let generated = |identity: Vec<u8>| (identity.len() as u64, blake3::hash(&identity));
    let (bytes, hash) = match &scene.mesostructure {
        MesostructureSource::Sample(_)
        | MesostructureSource::SampleTile(_)
        | MesostructureSource::Medium(_) => generated(
            serde_json::to_vec(&(&scene.mesostructure, scene.resolution))
                .map_err(|e| Error::Scene(e.to_string()))?,
        ),
        MesostructureSource::Volume(p)
        | MesostructureSource::Tile(p)
        | MesostructureSource::HeightField(p) => {
            let path = scene_dir.join(p);
            let io = |e| Error::io(&path, e);
            let mut hasher = blake3::Hasher::new();
            let bytes = std::io::copy(&mut std::fs::File::open(&path).map_err(io)?, &mut hasher)
                .map_err(io)?;
            (bytes, hasher.finalize())
        }
        MesostructureSource::Relief(kind) => generated(
            reliefs::height_field(*kind, scene.resolution[0], &Limits::default())?.to_png(),
        ),
    };
    Ok(InputInfo {
        kind: match scene.mesostructure {
            MesostructureSource::HeightField(_) => "height_field",
            MesostructureSource::Relief(_) => "relief",
            MesostructureSource::Tile(_) | MesostructureSource::SampleTile(_) => "mesh",
            MesostructureSource::Volume(_) | MesostructureSource::Sample(_) => "volume",
            MesostructureSource::Medium(_) => "medium",
        }
        .into(),
        bytes,
        blake3: hash.to_hex().to_string(),
    })
}
