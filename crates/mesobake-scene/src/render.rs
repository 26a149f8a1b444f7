//! Scene → image: loads what the scene names, bakes or reads the GDM when the method needs
//! one, picks the renderer and times each stage (`mesobake render`).

use crate::gi::{self, GiReport};
use crate::{LoadedScene, Scene};
use glam::DVec3;
use mesobake_bake::mesostructure::height_field::HeightField;
use mesobake_bake::mesostructure::medium::Medium;
use mesobake_bake::package::AnyPackage;
use mesobake_bake::package::Package;
use mesobake_bake::package::medium::{self as medium_package, MediumPackage};
use mesobake_bake::package::vdm::VdmPackage;
use mesobake_bake::vdm::Relief;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::vdm::VdmQuery;
use mesobake_render::explicit::ExplicitRenderer;
use mesobake_render::gdm_lookup::{GdmLookup, RawLookup, package_lookup};
use mesobake_render::gdm_renderer::{GdmRenderer, Substitutions};
use mesobake_render::image::Image;
use mesobake_render::medium_cells::CellRenderer;
use mesobake_render::medium_truth::MediumTruth;
use mesobake_render::objects::{self, Object, ObjectRenderer};
use mesobake_render::render_image_observed;
use mesobake_render::truth::TruthRenderer;
use mesobake_render::vdm_renderer::VdmRenderer;
use serde::Serialize;
use std::path::Path;
use std::str::FromStr;
use std::time::Instant;

/// Which renderer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RenderMethod {
    /// The ground truth: exact mapping, real mesostructure.
    Truth,
    /// The GDM per-pixel algorithm (the real-time pipeline's specification).
    Gdm,
    /// The explicit geometry (mesh tiles only): the tile's triangles mapped through the shell,
    /// ray cast as a plain mesh; the truth's independent check.
    Explicit,
    /// The VDM per-pixel algorithm (height-field mesostructure): the shell's top surface
    /// rendered with the view-dependent displacement map.
    Vdm,
    /// The real-time algorithm of semi-transparent 3D textures (translucent media): the
    /// shell's tetrahedra, each integrated and composited in order.
    Cells,
}

impl RenderMethod {
    /// Every method.
    pub const ALL: [RenderMethod; 5] = [
        RenderMethod::Truth,
        RenderMethod::Gdm,
        RenderMethod::Explicit,
        RenderMethod::Vdm,
        RenderMethod::Cells,
    ];

    /// The method's name, as `--method` takes it.
    pub fn name(&self) -> &'static str {
        match self {
            RenderMethod::Truth => "truth",
            RenderMethod::Gdm => "gdm",
            RenderMethod::Explicit => "explicit",
            RenderMethod::Vdm => "vdm",
            RenderMethod::Cells => "cells",
        }
    }
}

impl FromStr for RenderMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match RenderMethod::ALL.into_iter().find(|m| m.name() == s) {
            Some(m) => Ok(m),
            None => Err(Error::InvalidParameter(format!(
                "render method {s:?}: expected truth, gdm, vdm, explicit or cells"
            ))),
        }
    }
}

/// Seconds per stage of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RenderSeconds {
    /// Loading the scene's inputs and building the shell.
    pub load: f64,
    /// Baking or reading the GDM (or the VDM); 0 for the ground truth.
    pub gdm: f64,
    /// Building the acceleration structure and rendering the pixels.
    pub render: f64,
}

/// A rendered scene.
pub struct Rendered {
    /// The image.
    pub image: Image,
    /// Seconds per stage.
    pub seconds: RenderSeconds,
    /// The GI bakes, when the scene calls for environment lighting.
    pub gi: Option<GiReport>,
}

/// The GDM a `gdm` render or the VDM a `vdm` render uses.
pub enum MapSource<'a> {
    /// Bake the scene's: the exact GDM of its mesostructure on its grids, or the VDM of its
    /// height field as its VDM settings say.
    Bake,
    /// This GDM package (its grid must match the scene's resolution).
    Package(&'a Package),
    /// This medium package (of the scene's translucent medium; method cells).
    MediumPackage(&'a MediumPackage),
    /// This VDM package (of the scene's height field).
    VdmPackage(&'a VdmPackage),
}

/// Reads the scene at `path` and loads its inputs (paths relative to the scene's folder).
pub fn load_scene(path: &Path, limits: &Limits) -> Result<LoadedScene> {
    let scene = Scene::read(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    LoadedScene::load(scene, dir, limits)
}

/// Renders `loaded` with `method`.
pub fn render(
    loaded: &LoadedScene,
    method: RenderMethod,
    source: MapSource,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Rendered> {
    render_substituted(
        loaded,
        method,
        source,
        Substitutions::default(),
        limits,
        observer,
    )
}

/// Renders `loaded` with `method`, the GDM renderer with parts of its algorithm substituted
/// (a reference run: see [`Substitutions`]), or the VDM renderer with its shadow test
/// substituted ([`VdmRenderer::with_exact_shadows`]).
pub fn render_substituted(
    loaded: &LoadedScene,
    method: RenderMethod,
    source: MapSource,
    substitutions: Substitutions,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Rendered> {
    let vdm_shadows = Substitutions {
        exact_query: false,
        exact_shadows: true,
    };
    if !(method == RenderMethod::Gdm
        || substitutions == Substitutions::default()
        || method == RenderMethod::Vdm && substitutions == vdm_shadows)
    {
        return Err(Error::InvalidParameter(
            "substitutions apply to the GDM renderer (method gdm), and shadows alone to the \
             VDM renderer (method vdm)"
                .into(),
        ));
    }
    let scene = &loaded.scene;
    let mut seconds = RenderSeconds::default();
    let environment = scene.wants(Effect::EnvironmentLighting);
    let shot = scene.shot();
    let mut gi_report = None;
    if let Some(medium) = &loaded.medium {
        return render_medium(loaded, medium, method, source, observer);
    }
    if let MapSource::MediumPackage(_) = source {
        return Err(Error::InvalidParameter(
            "a medium package (mesobake-medium-package) renders translucent scenes (the \
             transparency technique); this scene's mesostructure is opaque"
                .into(),
        ));
    }
    let image = match method {
        RenderMethod::Truth if environment => {
            let start = Instant::now();
            let tracer = loaded.path_tracer(&shot, scene.gi.path_samples)?;
            observer.stage("rendering");
            let image =
                render_image_observed(&shot.camera, observer, |o, d| tracer.radiance(&shot, o, d))?;
            seconds.render = start.elapsed().as_secs_f64();
            image
        }
        RenderMethod::Vdm | RenderMethod::Explicit if environment => {
            return Err(Error::InvalidParameter(
                "environment lighting is rendered by the path tracer (method truth) or the GDM \
                 renderer; the explicit and VDM renderers shade point and directional lights \
                 only"
                    .into(),
            ));
        }
        RenderMethod::Explicit => {
            let start = Instant::now();
            let r = ExplicitRenderer::new(
                &loaded.shell,
                &loaded.mesostructure,
                &loaded.material,
                scene.dims()?,
                limits,
            )?;
            observer.stage("rendering");
            let image =
                render_image_observed(&shot.camera, observer, |o, d| r.radiance(&shot, o, d))?;
            seconds.render = start.elapsed().as_secs_f64();
            image
        }
        RenderMethod::Vdm => {
            let start = Instant::now();
            let (baked, field);
            let (query, relief) = match source {
                MapSource::Bake => {
                    baked = loaded.bake_vdm(limits, observer)?;
                    (baked.compressed.decode(), baked.relief())
                }
                MapSource::VdmPackage(pkg) => {
                    field = mesobake_bake::package::vdm::height_field(pkg)?;
                    let depth = pkg.manifest().relief.depth;
                    (
                        pkg.query(),
                        Relief {
                            field: &field,
                            depth,
                        },
                    )
                }
                MapSource::Package(_) | MapSource::MediumPackage(_) => {
                    return Err(Error::InvalidParameter(
                        "method vdm renders a VDM package (mesobake-vdm-package), and this is a \
                         GDM package (mesobake-package)"
                            .into(),
                    ));
                }
            };
            seconds.gdm = start.elapsed().as_secs_f64();
            let start = Instant::now();
            let truth = (substitutions.exact_shadows).then(|| {
                let caster = loaded.mesostructure.caster();
                TruthRenderer::new(&loaded.shell, caster, &loaded.material)
            });
            let mut r = VdmRenderer::new(&loaded.shell, &query, relief)?;
            if let Some(truth) = &truth {
                r = r.with_exact_shadows(truth);
            }
            observer.stage("rendering");
            let image =
                render_image_observed(&shot.camera, observer, |o, d| r.radiance(&shot, o, d))?;
            seconds.render = start.elapsed().as_secs_f64();
            image
        }
        RenderMethod::Cells => {
            return Err(Error::InvalidParameter(
                "the cells renderer renders translucent media (a `medium` mesostructure or a \
                 volume with an opacity channel); this scene's mesostructure is opaque"
                    .into(),
            ));
        }
        RenderMethod::Truth => {
            let start = Instant::now();
            let caster = loaded.mesostructure.caster();
            let r = TruthRenderer::new(&loaded.shell, caster, &loaded.material);
            observer.stage("rendering");
            let image =
                render_image_observed(&shot.camera, observer, |o, d| r.radiance(&shot, o, d))?;
            seconds.render = start.elapsed().as_secs_f64();
            image
        }
        RenderMethod::Gdm => {
            let start = Instant::now();
            let (raw, raw_lookup, from_package);
            let mut gi = None;
            let lookup: &dyn GdmLookup = match source {
                MapSource::Bake => {
                    raw = loaded.bake_gdm(limits, observer)?;
                    raw_lookup = RawLookup::new(&raw);
                    if environment {
                        let (shading, report) = gi::bake_shading(loaded, &raw, limits, observer)?;
                        gi = Some(shading);
                        gi_report = Some(report);
                    }
                    &raw_lookup
                }
                MapSource::VdmPackage(_) | MapSource::MediumPackage(_) => {
                    return Err(Error::InvalidParameter(
                        "method gdm renders a GDM package (mesobake-package), and this is a VDM \
                         package (mesobake-vdm-package)"
                            .into(),
                    ));
                }
                MapSource::Package(pkg) => {
                    pkg.check_grid(scene.dims()?)?;
                    if environment {
                        gi = Some(gi::shading_from_package(loaded, pkg)?);
                    }
                    from_package = package_lookup(pkg)?;
                    &*from_package
                }
            };
            seconds.gdm = start.elapsed().as_secs_f64();
            let start = Instant::now();
            // Only a substituted run needs the truth (and its BVH, in the render time).
            let truth = (substitutions != Substitutions::default()).then(|| {
                let caster = loaded.mesostructure.caster();
                TruthRenderer::new(&loaded.shell, caster, &loaded.material)
            });
            let mut r = GdmRenderer::new(
                &loaded.shell,
                lookup,
                &loaded.material,
                scene.gdm_refinements,
            )
            .with_quality(scene.quality);
            if let Some(truth) = &truth {
                r = r.with_substitutions(substitutions, truth);
            }
            if let Some(gi) = &gi {
                r = r.with_gi(gi);
            }
            observer.stage("rendering");
            let image =
                render_image_observed(&shot.camera, observer, |o, d| r.radiance(&shot, o, d))?;
            seconds.render = start.elapsed().as_secs_f64();
            image
        }
    };
    Ok(Rendered {
        image,
        seconds,
        gi: gi_report,
    })
}

/// Renders a translucent medium: its ground truth or the real-time algorithm's CPU
/// specification.
fn render_medium(
    loaded: &LoadedScene,
    medium: &Medium,
    method: RenderMethod,
    source: MapSource,
    observer: &dyn BakeObserver,
) -> Result<Rendered> {
    let scene = &loaded.scene;
    if !matches!(method, RenderMethod::Truth | RenderMethod::Cells) {
        loaded.check_opaque(&format!("the {} renderer", method.name()))?;
    }
    let levels = match source {
        MapSource::MediumPackage(p) if method == RenderMethod::Cells => {
            Some(medium_package::levels(p, scene.transparency.mipmap)?)
        }
        MapSource::Bake => None,
        _ => {
            return Err(Error::InvalidParameter(
                "a translucent scene renders with method truth (from the scene) or cells (from \
                 the scene or its medium package, mesobake-medium-package)"
                    .into(),
            ));
        }
    };
    if scene.wants(Effect::EnvironmentLighting) {
        return Err(Error::InvalidParameter(
            "environment lighting of translucent media is not rendered yet: light them with \
             point, directional and ambient lights"
                .into(),
        ));
    }
    let start = Instant::now();
    let shot = scene.shot();
    let truth;
    let cells;
    let r: &(dyn Fn(DVec3, DVec3) -> Option<DVec3> + Sync) = if method == RenderMethod::Truth {
        truth = MediumTruth::new(&loaded.shell, medium);
        &|o, d| truth.radiance(&shot, o, d)
    } else {
        cells = match &levels {
            Some(levels) => CellRenderer::with_levels(&loaded.shell, levels, scene.transparency),
            None => CellRenderer::new(&loaded.shell, medium, scene.transparency),
        };
        &|o, d| cells.radiance(&shot, o, d)
    };
    observer.stage("rendering");
    let image = render_image_observed(&shot.camera, observer, r)?;
    Ok(Rendered {
        image,
        seconds: RenderSeconds {
            render: start.elapsed().as_secs_f64(),
            ..RenderSeconds::default()
        },
        gi: None,
    })
}

/// Refuses an object that a scene of several objects cannot render yet: one lit by the
/// environment, or a translucent one.
pub fn check_composable(loaded: &LoadedScene) -> Result<()> {
    if loaded.scene.wants(Effect::EnvironmentLighting) {
        return Err(Error::InvalidParameter(
            "environment lighting of a scene with several objects is not rendered yet: \
             light them with point, directional and ambient lights"
                .into(),
        ));
    }
    loaded.check_opaque("a scene with several objects (translucent objects come later)")
}

/// Renders several objects together ([`crate::objects`]): the nearest object's hit at each
/// pixel, shaded with the others' shadows. Object i renders with `methods[i]`: `truth` (its
/// ground truth) or its real-time specification, `gdm` or `vdm`, from `packages[i]` when
/// given (of object i's mesostructure), else from its exact GDM or its baked VDM.
pub fn render_objects(
    objects: &[LoadedScene],
    methods: &[RenderMethod],
    packages: &[Option<&AnyPackage>],
    observer: &dyn BakeObserver,
    limits: &Limits,
) -> Result<Rendered> {
    for (loaded, method) in objects.iter().zip(methods) {
        check_composable(loaded)?;
        if !matches!(
            method,
            RenderMethod::Truth | RenderMethod::Gdm | RenderMethod::Vdm
        ) {
            return Err(Error::InvalidParameter(format!(
                "a scene with several objects renders with method truth, gdm or vdm, not {}",
                method.name()
            )));
        }
    }
    let mut seconds = RenderSeconds::default();
    let start = Instant::now();
    let package = |i: usize| packages.get(i).copied().flatten();
    let mut maps = Vec::new();
    for (i, (loaded, &method)) in objects.iter().zip(methods).enumerate() {
        maps.push(match (method, package(i)) {
            (RenderMethod::Gdm, Some(AnyPackage::Gdm(pkg))) => {
                pkg.check_grid(loaded.scene.dims()?)?;
                ObjectMap::Gdm(Gdm::Package(package_lookup(pkg)?))
            }
            (RenderMethod::Gdm, _) => ObjectMap::Gdm(Gdm::Raw(loaded.bake_gdm(limits, observer)?)),
            (RenderMethod::Vdm, Some(AnyPackage::Vdm(pkg))) => ObjectMap::Vdm {
                query: pkg.query(),
                field: mesobake_bake::package::vdm::height_field(pkg)?,
                depth: pkg.manifest().relief.depth,
            },
            (RenderMethod::Vdm, _) => {
                let baked = loaded.bake_vdm(limits, observer)?;
                ObjectMap::Vdm {
                    query: baked.compressed.decode(),
                    depth: baked.depth,
                    field: baked.field,
                }
            }
            _ => ObjectMap::None,
        });
    }
    seconds.gdm = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let shots: Vec<_> = objects.iter().map(|o| o.scene.shot()).collect();
    let raw_lookups: Vec<Option<RawLookup>> = maps
        .iter()
        .map(|m| match m {
            ObjectMap::Gdm(Gdm::Raw(raw)) => Some(RawLookup::new(raw)),
            _ => None,
        })
        .collect();
    let mut renderers: Vec<Box<dyn ObjectRenderer + '_>> = Vec::new();
    for ((o, map), raw) in objects.iter().zip(&maps).zip(&raw_lookups) {
        renderers.push(match map {
            ObjectMap::None => Box::new(TruthRenderer::new(
                &o.shell,
                o.mesostructure.caster(),
                &o.material,
            )),
            ObjectMap::Gdm(gdm) => {
                let lookup: &dyn GdmLookup = match (gdm, raw) {
                    (Gdm::Package(lookup), _) => &**lookup,
                    (Gdm::Raw(_), Some(raw)) => raw,
                    (Gdm::Raw(_), None) => unreachable!("every raw GDM has its lookup"),
                };
                Box::new(
                    GdmRenderer::new(&o.shell, lookup, &o.material, o.scene.gdm_refinements)
                        .with_quality(o.scene.quality),
                )
            }
            ObjectMap::Vdm {
                query,
                field,
                depth,
            } => {
                let relief = Relief {
                    field,
                    depth: *depth,
                };
                Box::new(VdmRenderer::new(&o.shell, query, relief)?)
            }
        });
    }
    let composed: Vec<Object> = renderers
        .iter()
        .zip(&shots)
        .map(|(renderer, shot)| Object {
            renderer: &**renderer,
            shot,
        })
        .collect();
    observer.stage("rendering");
    let image = render_image_observed(&shots[0].camera, observer, |o, d| {
        objects::radiance(&composed, o, d)
    })?;
    seconds.render = start.elapsed().as_secs_f64();
    Ok(Rendered {
        image,
        seconds,
        gi: None,
    })
}

/// What one object's real-time renderer reads.
enum ObjectMap {
    /// Nothing: the object renders its ground truth.
    None,
    /// A GDM.
    Gdm(Gdm),
    /// A VDM, with the height field and depth of its relief.
    Vdm {
        query: VdmQuery,
        field: HeightField,
        depth: f64,
    },
}

/// Where an object's GDM lookups come from.
enum Gdm {
    /// Its package.
    Package(Box<dyn GdmLookup>),
    /// Its exact GDM.
    Raw(mesobake_bake::gdm::Gdm),
}
