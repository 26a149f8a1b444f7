//! Environment light for a scene: its macro-scale PRT, its RTV bake and the shading of a GDM
//! hit with them ([`GiShading`], exact after a bake or compressed from a package).

use crate::{LoadedScene, Scene};
use mesobake_bake::gdm::Gdm;
use mesobake_bake::gi::prt::{self, Visibility};
use mesobake_bake::gi::rtv::{self, RtvParams, RtvStats};
use mesobake_bake::gi::sh::ShMatrix;
use mesobake_bake::package::Package;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_render::gi_shading::{GiShading, Transfer};
use serde::Serialize;
use std::time::Instant;

/// Seconds and counts of the GI bakes.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct GiReport {
    /// Projecting the environment to SH.
    pub environment_seconds: f64,
    /// The macro-scale PRT (all vertices).
    pub prt_seconds: f64,
    /// Whether the PRT is shadowed by the base mesh.
    pub macro_shadows: bool,
    /// The RTV bake.
    pub rtv: RtvStats,
}

/// Bakes the PRT and the RTV of `loaded` (whose scene calls for environment lighting) over
/// its GDM `gdm`; shading reads the exact RTV.
pub fn bake_shading(
    loaded: &LoadedScene,
    gdm: &Gdm,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<(GiShading, GiReport)> {
    let mut report = GiReport::default();
    let start = Instant::now();
    let matrices = prt_matrices(loaded)?;
    report.macro_shadows = loaded.scene.wants(Effect::MacroShadows);
    report.prt_seconds = start.elapsed().as_secs_f64();
    let (rtv, stats) = rtv::bake(
        gdm,
        &loaded.material,
        &rtv_params(&loaded.scene),
        limits,
        observer,
    )?;
    report.rtv = stats;
    let shading = shading(loaded, Transfer::Exact(rtv), &matrices, &mut report)?;
    Ok((shading, report))
}

/// Shading with the PRT and compressed RTV of `package` (baked for `loaded`'s base mesh).
pub fn shading_from_package(loaded: &LoadedScene, package: &Package) -> Result<GiShading> {
    let (rtv, matrices) = package.gi(&loaded.base)?;
    shading(
        loaded,
        Transfer::Compressed(rtv),
        &matrices,
        &mut GiReport::default(),
    )
}

/// The shading from `package` where `loaded`'s scene calls for environment lighting, else
/// none.
pub fn called_for_shading(loaded: &LoadedScene, package: &Package) -> Result<Option<GiShading>> {
    if loaded.scene.wants(Effect::EnvironmentLighting) {
        shading_from_package(loaded, package).map(Some)
    } else {
        Ok(None)
    }
}

/// Shading with `transfer` under `loaded`'s environment, timing its projection in `report`.
fn shading(
    loaded: &LoadedScene,
    transfer: Transfer,
    matrices: &[ShMatrix],
    report: &mut GiReport,
) -> Result<GiShading> {
    let environment = loaded.environment.as_ref().ok_or_else(|| {
        Error::Scene("effects call for environment_lighting but no environment is given".into())
    })?;
    let start = Instant::now();
    let light = environment.project();
    report.environment_seconds = start.elapsed().as_secs_f64();
    Ok(GiShading::new(
        transfer,
        matrices,
        &light,
        &loaded.shell,
        &loaded.base,
    ))
}

/// The macro-scale PRT of `loaded`'s base mesh: shadowed when the scene calls for macro
/// shadows, a pure rotation into each vertex frame otherwise.
pub fn prt_matrices(loaded: &LoadedScene) -> Result<Vec<ShMatrix>> {
    let visibility = if loaded.scene.wants(Effect::MacroShadows) {
        Visibility::Shadowed {
            samples: loaded.scene.gi.prt_samples,
        }
    } else {
        Visibility::Unshadowed
    };
    Ok(prt::transfer(&loaded.base, visibility)?.matrices)
}

/// The RTV knobs `scene` asks for: its bounces, and its material's specular lobe when it
/// calls for environment gloss (Blinn–Phong exponent n ≈ Phong exponent 4·s).
pub fn rtv_params(scene: &Scene) -> RtvParams {
    RtvParams {
        bounces: scene.gi.bounces,
        glossy: scene.shot().environment_gloss(),
    }
}
