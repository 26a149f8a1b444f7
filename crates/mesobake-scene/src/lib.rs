//! mesobake's scenes and their pipelines: the scene file, one JSON document (serde) that
//! every renderer and the server read (the format and its coordinate conventions are
//! specified in `docs/scene-format.md`), and [`LoadedScene`], its inputs loaded. Then what a
//! scene calls for, in order: [`technique`] and [`plan`] (the stages its effects need),
//! [`package`] (baking them), [`render`] (CPU images) and [`preview`] (the real-time
//! pipeline); and what they cost and buy, measured: [`report`] and [`bench`]. It knows
//! nothing of HTTP or SQL.

pub mod bench;
pub mod explicit;
pub mod gi;
pub mod memory;
pub mod objects;
pub mod package;
pub mod plan;
pub mod preview;
pub mod render;
pub mod report;
pub mod technique;
pub mod transform;
pub mod vdm;

use glam::DVec3;
use mesobake_bake::gdm::Gdm;
use mesobake_bake::gdm::caster::Caster;
use mesobake_bake::gdm::height_field_caster::HeightFieldCaster;
use mesobake_bake::gdm::input::Mesostructure;
use mesobake_bake::gdm::mesh_caster::MeshCaster;
use mesobake_bake::gdm::volume_caster::VolumeCaster;
use mesobake_bake::gi::environment::{Environment, Sky};
use mesobake_bake::mesostructure::height_field::HeightField;
use mesobake_bake::mesostructure::material::MaterialVolume;
use mesobake_bake::mesostructure::media::{self, MediumKind};
use mesobake_bake::mesostructure::medium::{self, Medium};
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::reliefs::{self, ReliefKind};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_bake::mesostructure::volume_format;
use mesobake_bake::surface::base_mesh::{BaseMesh, BuiltinMesh, GltfSelection, MeshReport};
use mesobake_bake::surface::shell::{Shell, ShellParams};
use mesobake_core::camera::Camera;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::fs::read_bounded;
use mesobake_core::light::{Light, MaterialParams};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_core::quality::{MAX_GDM_REFINEMENTS, Quality};
use mesobake_package::grid::{Dims, DirectionGrid};
use mesobake_render::medium_settings::TransparencySettings;
use mesobake_render::path_tracer::PathTracer;
use mesobake_render::shot::Shot;
use mesobake_render::truth::TruthRenderer;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use technique::{Technique, TechniqueChoice};
use transform::ObjectTransform;
use vdm::VdmSettings;

/// Largest accepted scene file.
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// A scene as written in its JSON file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The surface the mesostructure is mapped onto.
    pub base_mesh: BaseMeshSource,
    /// Uniform scale applied to the base mesh's positions (object units per mesh unit).
    #[serde(default = "one")]
    pub mesh_scale: f64,
    /// Where the base mesh stands: scaled, rotated and translated after `mesh_scale` (an
    /// object of a scene with several, [`objects`]).
    #[serde(default, skip_serializing_if = "ObjectTransform::is_identity")]
    pub transform: ObjectTransform,
    /// The mesostructure sample.
    pub mesostructure: MesostructureSource,
    /// The technique that renders it: `gdm`, `vdm` (height fields), or `auto` (the default:
    /// [`technique::choose`]).
    #[serde(default, skip_serializing_if = "Technique::is_auto")]
    pub technique: Technique,
    /// Voxel grid X×Y×Z of the mesostructure (samples and tiles are sampled on it; a volume
    /// must have it).
    #[serde(default = "default_resolution")]
    pub resolution: [u32; 3],
    /// Direction grid Nθ×Nφ of the GDM.
    #[serde(default = "default_directions")]
    pub directions: [u32; 2],
    /// Extra GDM queries per hit in the GDM renderers, each from one voxel short of the
    /// previous answer (0 = the paper's single query; at most [`MAX_GDM_REFINEMENTS`]).
    #[serde(default = "default_gdm_refinements")]
    pub gdm_refinements: u32,
    /// The per-pixel algorithm's accuracy knobs (a preset or settings; the paper's by
    /// default).
    #[serde(default, skip_serializing_if = "Quality::is_paper")]
    pub quality: Quality,
    /// How the base mesh is extruded into the shell.
    pub shell: ShellParams,
    /// Reflectance.
    #[serde(default)]
    pub material: MaterialParams,
    /// The pinhole camera.
    pub camera: Camera,
    /// Light sources.
    #[serde(default)]
    pub lights: Vec<Light>,
    /// The effects the scene calls for; nothing else is baked or shaded.
    #[serde(default)]
    pub effects: Vec<Effect>,
    /// Distant environment light (shaded only when the effects call for
    /// `environment_lighting`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentSource>,
    /// Knobs of the global-illumination bakes.
    #[serde(default, skip_serializing_if = "GiParams::is_default")]
    pub gi: GiParams,
    /// How the VDM of a height-field mesostructure is baked and compressed.
    #[serde(default, skip_serializing_if = "VdmSettings::is_default")]
    pub vdm: VdmSettings,
    /// How a translucent medium is integrated by the real-time algorithm.
    #[serde(default, skip_serializing_if = "TransparencySettings::is_default")]
    pub transparency: TransparencySettings,
}

/// Where a scene's environment light comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum EnvironmentSource {
    /// A built-in procedural sky.
    Sky(Sky),
    /// A lat-long OpenEXR radiance map (relative paths are relative to the scene file).
    Exr(PathBuf),
}

/// The accuracy knobs of the global-illumination bakes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GiParams {
    /// Interreflection bounces in the RTV (0 = direct light only; at most
    /// [`mesobake_bake::gi::rtv::MAX_BOUNCES`]).
    pub bounces: u32,
    /// Visibility directions per base-mesh vertex in the shadowed PRT (16 to 2²⁰).
    pub prt_samples: usize,
    /// Width of the lat-long map a procedural sky is rendered to (height is half).
    pub sky_width: usize,
    /// Paths per pixel of the ground truth's path tracer (1–4096).
    pub path_samples: u32,
    /// Most bounces of a path (1–64).
    pub path_depth: u32,
    /// SVD components per RTV matrix in a package (1 to
    /// [`mesobake_bake::gi::compressed_rtv::MAX_RTV_RANK`]).
    pub rtv_rank: usize,
}

impl Default for GiParams {
    /// Four bounces, 1024 PRT directions, a 256×128 sky, 16 paths of at most 8 bounces, RTV
    /// rank 4 (the paper's).
    fn default() -> Self {
        GiParams {
            bounces: 4,
            prt_samples: 1024,
            sky_width: 256,
            path_samples: 16,
            path_depth: 8,
            rtv_rank: 4,
        }
    }
}

impl GiParams {
    fn is_default(&self) -> bool {
        *self == GiParams::default()
    }
}

fn one() -> f64 {
    1.0
}

fn default_resolution() -> [u32; 3] {
    [64, 64, 32]
}

fn default_directions() -> [u32; 2] {
    [16, 32]
}

fn default_gdm_refinements() -> u32 {
    0
}

/// Where the base mesh comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum BaseMeshSource {
    /// A built-in mesh with its parameters.
    Builtin(BuiltinMesh),
    /// An OBJ file (relative paths are relative to the scene file).
    Obj(PathBuf),
    /// A glTF 2.0 file (`.gltf` or `.glb`): its default scene's triangles in world space.
    Gltf(GltfSource),
}

/// A glTF base mesh: the file, or the file with the primitives and UV set to use.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum GltfSource {
    /// Every triangle primitive of the default scene, with TEXCOORD_0.
    File(PathBuf),
    /// The primitives of one material, or another UV set.
    Selected {
        /// The glTF or GLB file (relative paths are relative to the scene file).
        file: PathBuf,
        /// Only the primitives of this material (all when absent).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        material: Option<String>,
        /// The TEXCOORD set (0 when absent).
        #[serde(default)]
        texcoord: u32,
    },
}

impl GltfSource {
    /// The file.
    pub fn file_mut(&mut self) -> &mut PathBuf {
        match self {
            GltfSource::File(file) | GltfSource::Selected { file, .. } => file,
        }
    }

    /// The file.
    pub fn file(&self) -> &Path {
        match self {
            GltfSource::File(file) | GltfSource::Selected { file, .. } => file,
        }
    }

    /// Which primitives, with which UV set.
    pub fn selection(&self) -> GltfSelection<'_> {
        match self {
            GltfSource::File(_) => GltfSelection::default(),
            GltfSource::Selected {
                material, texcoord, ..
            } => GltfSelection {
                material: material.as_deref(),
                texcoord: *texcoord,
            },
        }
    }
}

/// Where the mesostructure comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum MesostructureSource {
    /// A built-in sample, voxelized on the scene's resolution.
    Sample(SampleKind),
    /// A built-in sample as its closed triangle tile (the analytic primitives tessellated,
    /// as `mesobake sample --format obj` writes it), cast exactly like an OBJ tile.
    SampleTile(SampleKind),
    /// A `.mbvol` volume file.
    Volume(PathBuf),
    /// A closed OBJ tile, sampled on the scene's resolution.
    Tile(PathBuf),
    /// A grayscale PNG height field ([`mesobake_bake::mesostructure::height_field`]), the volume under it on the
    /// scene's resolution.
    HeightField(PathBuf),
    /// A built-in relief ([`mesobake_bake::mesostructure::reliefs`]) of X × X pixels (the scene's
    /// resolution must have X = Y), the volume under it on the scene's resolution.
    Relief(ReliefKind),
    /// A built-in translucent medium ([`mesobake_bake::mesostructure::media`]) on the scene's
    /// resolution (X = Y).
    Medium(MediumKind),
}

impl Scene {
    /// Parses and validates scene JSON.
    pub fn from_json(text: &str) -> Result<Scene> {
        let scene: Scene = serde_json::from_str(text).map_err(|e| {
            let value = serde_json::from_str::<serde_json::Value>(text);
            match value {
                Ok(v) if v.get("objects").is_some() => Error::Scene(
                    "the scene holds several objects (`objects`), and this takes a scene of one: \
                     `mesobake render`, `preview` and `bake --scene` take several, as do the \
                     server's `POST /api/v1/object-jobs` and `/api/v1/preview`"
                        .into(),
                ),
                _ => Error::Scene(e.to_string()),
            }
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads a scene file (at most [`MAX_SCENE_BYTES`]).
    pub fn read(path: &Path) -> Result<Scene> {
        Scene::from_json(&read_scene_text(path)?).map_err(|e| e.context(path.display()))
    }

    /// Whether the scene calls for `effect`.
    pub fn wants(&self, effect: Effect) -> bool {
        self.effects.contains(&effect)
    }

    /// What the renderers read of the scene: its camera, lights, material, effects and the
    /// real-time algorithms' knobs.
    pub fn shot(&self) -> Shot {
        Shot {
            camera: self.camera,
            lights: self.lights.clone(),
            material: self.material,
            effects: self.effects.clone(),
            quality: self.quality,
            gdm_refinements: self.gdm_refinements,
            vdm_refine_texels: self.vdm.refine_texels,
            vdm_shadows: self.vdm.shadows,
        }
    }

    /// The voxel grid.
    pub fn dims(&self) -> Result<Dims> {
        let [x, y, z] = self.resolution;
        Ok(Dims::new(x, y, z)?)
    }

    /// The direction grid.
    pub fn dirs(&self) -> Result<DirectionGrid> {
        Ok(DirectionGrid::new(self.directions[0], self.directions[1])?)
    }

    fn validate(&self) -> Result<()> {
        self.dims()?;
        self.dirs()?;
        if !(self.mesh_scale.is_finite() && self.mesh_scale > 0.0) {
            return Err(Error::Scene(format!(
                "mesh_scale must be finite and positive, got {}",
                self.mesh_scale
            )));
        }
        if self.gdm_refinements > MAX_GDM_REFINEMENTS {
            return Err(Error::Scene(format!(
                "gdm_refinements must be at most {MAX_GDM_REFINEMENTS}, got {}",
                self.gdm_refinements
            )));
        }
        self.transform.validate()?;
        self.quality.validate()?;
        self.vdm.validate()?;
        self.transparency.validate()?;
        technique::validate(self)?;
        self.shell.validate()?;
        self.camera.validate()?;
        for light in &self.lights {
            light.validate()?;
        }
        if self.wants(Effect::EnvironmentLighting) {
            match &self.environment {
                None => {
                    return Err(Error::Scene(
                        "effects call for environment_lighting but no environment is given".into(),
                    ));
                }
                Some(EnvironmentSource::Sky(sky)) => {
                    sky.validate().map_err(|e| Error::Scene(e.to_string()))?
                }
                Some(EnvironmentSource::Exr(_)) => {}
            }
            let g = &self.gi;
            if g.bounces > mesobake_bake::gi::rtv::MAX_BOUNCES
                || !(16..=1 << 20).contains(&g.prt_samples)
                || !(4..=8192).contains(&g.sky_width)
                || !(1..=4096).contains(&g.path_samples)
                || !(1..=64).contains(&g.path_depth)
                || !(1..=mesobake_bake::gi::compressed_rtv::MAX_RTV_RANK).contains(&g.rtv_rank)
            {
                return Err(Error::Scene(format!(
                    "gi: bounces must be at most {}, prt_samples 16–{}, sky_width 4–8192, \
                     path_samples 1–4096, path_depth 1–64, rtv_rank 1–{}; got {g:?}",
                    mesobake_bake::gi::rtv::MAX_BOUNCES,
                    1 << 20,
                    mesobake_bake::gi::compressed_rtv::MAX_RTV_RANK,
                )));
            }
            let m = &self.material;
            if self.wants(Effect::EnvironmentGloss)
                && !(m.specular.iter().all(|k| *k <= 1.0)
                    && m.shininess <= 4.0 * mesobake_bake::gi::rtv::MAX_EXPONENT)
            {
                return Err(Error::Scene(format!(
                    "environment_gloss needs a specular colour of at most 1 and a shininess of \
                     at most {}; got {:?} and {}",
                    4.0 * mesobake_bake::gi::rtv::MAX_EXPONENT,
                    m.specular,
                    m.shininess
                )));
            }
        } else if self.wants(Effect::EnvironmentGloss) || self.wants(Effect::MacroShadows) {
            return Err(Error::Scene(
                "environment_gloss and macro_shadows refine environment_lighting, which the \
                 effects do not call for"
                    .into(),
            ));
        }
        let m = &self.material;
        let colours_ok = (m.albedo.iter().chain(&m.specular)).all(|c| c.is_finite() && *c >= 0.0);
        if !colours_ok || !m.shininess.is_finite() || m.shininess < 0.0 {
            return Err(Error::Scene(
                "material: colours and shininess must be finite and non-negative".into(),
            ));
        }
        Ok(())
    }

    /// Returns the scene with every length scaled by `factor` (mesh, thickness, camera,
    /// lights; point intensities by factor² so irradiance is unchanged): it must render the
    /// same image.
    pub fn scaled(&self, factor: f64) -> Scene {
        let mut s = self.clone();
        let scale = |v: [f64; 3]| v.map(|c| c * factor);
        s.shell.thickness *= factor;
        s.camera.eye = scale(s.camera.eye);
        s.camera.target = scale(s.camera.target);
        for light in &mut s.lights {
            if let Light::Point {
                position,
                intensity,
            } = light
            {
                *position = scale(*position);
                *intensity = intensity.map(|c| c * factor * factor);
            }
        }
        s.mesh_scale *= factor;
        s.transform.translate = scale(s.transform.translate);
        s
    }
}

/// The text of the scene file at `path` (at most [`MAX_SCENE_BYTES`], UTF-8).
fn read_scene_text(path: &Path) -> Result<String> {
    let bytes = read_bounded(path, "scene", MAX_SCENE_BYTES).map_err(|e| match e {
        Error::MemoryLimit { needed, .. } => Error::Scene(format!(
            "{} is {needed} bytes or more, over the {MAX_SCENE_BYTES}-byte limit for scene files",
            path.display()
        )),
        e => e,
    })?;
    String::from_utf8(bytes)
        .map_err(|e| Error::Scene(format!("{} is not UTF-8 text: {e}", path.display())))
}

/// The base mesh `scene` names, scaled by its `mesh_scale`, with what validating it found
/// (relative paths resolved against `base_dir`).
pub fn load_base_mesh(
    scene: &Scene,
    base_dir: &Path,
    limits: &Limits,
) -> Result<(BaseMesh, MeshReport)> {
    let (mut base, report) = match &scene.base_mesh {
        BaseMeshSource::Builtin(b) => b.build()?,
        BaseMeshSource::Obj(p) => BaseMesh::read_obj(&base_dir.join(p), limits)?,
        BaseMeshSource::Gltf(g) => {
            BaseMesh::read_gltf(&base_dir.join(g.file()), g.selection(), limits)?
        }
    };
    for p in &mut base.positions {
        *p *= scene.mesh_scale;
    }
    scene
        .transform
        .apply(&mut base.positions, &mut base.normals);
    base.check_coordinates().map_err(|e| {
        Error::Scene(format!(
            "mesh_scale {} and transform {:?}: {e}",
            scene.mesh_scale, scene.transform
        ))
    })?;
    Ok((base, report))
}

/// A scene with its inputs loaded: base mesh, shell, mesostructure and material volume.
pub struct LoadedScene {
    /// The scene as written.
    pub scene: Scene,
    /// The validated base mesh.
    pub base: BaseMesh,
    /// What validating the base mesh found.
    pub base_report: MeshReport,
    /// The extruded shell.
    pub shell: Shell,
    /// The mesostructure, ready for ray casting.
    pub mesostructure: Mesostructure,
    /// Albedo and normals of the mesostructure.
    pub material: MaterialVolume,
    /// The height field of a height-field or relief mesostructure (what a VDM is baked from).
    pub height_field: Option<HeightField>,
    /// The translucent medium of a medium, or of a volume with an opacity channel; its opaque
    /// voxels are then `mesostructure`.
    pub medium: Option<Medium>,
    /// The environment map, loaded only when the effects call for environment lighting.
    pub environment: Option<Environment>,
}

impl LoadedScene {
    /// Loads everything `scene` names; relative paths are resolved against `base_dir`.
    pub fn load(scene: Scene, base_dir: &Path, limits: &Limits) -> Result<LoadedScene> {
        let resolve = |p: &Path| base_dir.join(p);
        let (base, base_report) = load_base_mesh(&scene, base_dir, limits)?;
        let shell = Shell::new(&base, scene.shell)?;
        let dims = scene.dims()?;
        let default_albedo = DVec3::from(scene.material.albedo);
        let mut height_field = None;
        let mut medium = None;
        let as_medium = technique::is_translucent(&scene);
        let mut volume_input = |volume: Volume| {
            if volume.opacity().is_some() || as_medium {
                medium = Some(Medium::from_volume(&volume, default_albedo));
            }
            let material = MaterialVolume::from_volume(&volume, default_albedo);
            (Mesostructure::Volume(VolumeCaster::new(&volume)), material)
        };
        let (mesostructure, material) = match &scene.mesostructure {
            MesostructureSource::Sample(kind) => {
                volume_input(samples::volume(*kind, dims, limits)?)
            }
            MesostructureSource::Medium(kind) => volume_input(media::volume(*kind, dims, limits)?),
            MesostructureSource::Volume(p) => {
                let volume = volume_format::read(&resolve(p), limits)?;
                if volume.dims() != dims {
                    return Err(Error::Scene(format!(
                        "{} is a {} volume but the scene's resolution is {dims}",
                        p.display(),
                        volume.dims()
                    )));
                }
                volume_input(volume)
            }
            MesostructureSource::HeightField(_) | MesostructureSource::Relief(_) => {
                let field = match &scene.mesostructure {
                    MesostructureSource::HeightField(p) => HeightField::read(&resolve(p), limits)?,
                    MesostructureSource::Relief(kind) if dims.x == dims.y => {
                        reliefs::height_field(*kind, dims.x, limits)?
                    }
                    _ => {
                        return Err(Error::Scene(format!(
                            "a built-in relief is square: the resolution {dims} needs X = Y"
                        )));
                    }
                };
                let material = MaterialVolume::from_height_field(&field, dims, default_albedo);
                height_field = Some(field.clone());
                let caster = HeightFieldCaster::new(field, dims, limits)?;
                (Mesostructure::HeightField(caster), material)
            }
            MesostructureSource::Tile(_) | MesostructureSource::SampleTile(_) => {
                let mesh = match &scene.mesostructure {
                    MesostructureSource::SampleTile(kind) => samples::mesh(*kind, dims)?,
                    MesostructureSource::Tile(p) => {
                        TriMesh::read_obj(&resolve(p), limits.memory_bytes / 8)?
                    }
                    _ => unreachable!("matched above"),
                };
                let caster = MeshCaster::new(&MeshTile::new(mesh, false)?, dims, limits)?;
                let material =
                    MaterialVolume::from_occupancy(caster.centres_inside(), None, default_albedo);
                (Mesostructure::Mesh(Box::new(caster)), material)
            }
        };
        if as_medium && medium.is_none() {
            // A mesh tile or a height field: its voxels whose centres are inside, α = 1.
            let solid = mesostructure.caster().centres_inside();
            medium = Some(Medium::from_occupancy(solid, default_albedo));
        }
        let environment = match &scene.environment {
            Some(source) if scene.wants(Effect::EnvironmentLighting) => Some(match source {
                EnvironmentSource::Sky(sky) => {
                    sky.to_map(scene.gi.sky_width, (scene.gi.sky_width / 2).max(1))?
                }
                EnvironmentSource::Exr(p) => Environment::read_exr(&resolve(p), limits)?,
            }),
            _ => None,
        };
        Ok(LoadedScene {
            scene,
            base,
            base_report,
            shell,
            mesostructure,
            material,
            height_field,
            medium,
            environment,
        })
    }

    /// The technique that renders the scene, and why ([`technique::choose`]).
    pub fn technique(&self) -> TechniqueChoice {
        technique::choose(&self.scene, &self.surface())
    }

    /// What the technique's choice needs to know of the scene's surface.
    pub fn surface(&self) -> technique::Surface {
        technique::Surface::of(&self.base_report, &self.shell)
            .with_translucent(self.medium.is_some())
    }

    /// Refuses a translucent mesostructure for `what`, which only represents opaque ones.
    pub fn check_opaque(&self, what: &str) -> Result<()> {
        match &self.medium {
            None => Ok(()),
            Some(_) => Err(Error::Scene(medium::translucent_refusal(what))),
        }
    }

    /// The path tracer over this scene's mesostructure and base mesh, lit as `shot` says,
    /// with `samples` paths per pixel of at most the scene's `gi.path_depth` bounces.
    pub fn path_tracer(&self, shot: &Shot, samples: u32) -> Result<PathTracer<'_>> {
        let truth = TruthRenderer::new(&self.shell, self.mesostructure.caster(), &self.material);
        PathTracer::new(
            truth,
            &self.base,
            self.environment.as_ref(),
            shot,
            samples,
            self.scene.gi.path_depth,
        )
    }

    /// Bakes the exact GDM of the scene's mesostructure on its grids.
    pub fn bake_gdm(&self, limits: &Limits, observer: &dyn BakeObserver) -> Result<Gdm> {
        self.check_opaque("a GDM bake")?;
        mesobake_bake::gdm::exact::bake(
            self.mesostructure.caster(),
            self.scene.dirs()?,
            limits,
            observer,
        )
    }
}
