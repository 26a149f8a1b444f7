//! Shading environment light at a GDM hit (the CPU twin of the GI shader): the incident SH
//! of the prism's three base vertices (PRT × environment), interpolated with the hit's
//! barycentric coordinates in texture space, dotted with the RTV's transfer towards the
//! viewer interpolated at the hit: the exact RTV of a bake, or the compressed one of a
//! package.
//!
//! The vertex frames (tangent along +u, bitangent, normal) stand in for the prism's texture
//! axes, which are orthonormal only where the mapping is conformal and voxels are cubic in
//! object space; directions in the RTV are texture-space directions.

use crate::package::Package;
use crate::scene::{LoadedScene, Scene};
use glam::{DVec2, DVec3};
use mesobake_bake::gdm::Gdm;
use mesobake_bake::gi::compressed_rtv::CompressedRtv;
use mesobake_bake::gi::environment::RgbSh;
use mesobake_bake::gi::prt::{self, Visibility};
use mesobake_bake::gi::rtv::{self, Glossy, Rtv, RtvParams, RtvStats};
use mesobake_bake::gi::sh::{self, COEFFS, ShMatrix};
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use serde::Serialize;
use std::time::Instant;

/// The transfer a [`GiShading`] reads.
enum Transfer {
    /// As baked.
    Exact(Rtv),
    /// As a package holds it.
    Compressed(CompressedRtv),
}

/// What the GI renderers need: the RTV, and the incident light per base vertex and prism.
pub struct GiShading {
    transfer: Transfer,
    /// Incident SH per base-mesh vertex, in its frame.
    incident: Vec<RgbSh>,
    /// Per prism: its base vertices and their texture coordinates (voxel units, x and y).
    prisms: Vec<([u32; 3], [DVec2; 3])>,
}

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

impl GiShading {
    /// Bakes the PRT and the RTV of `loaded` (whose scene calls for environment lighting)
    /// over its GDM `gdm`; shading reads the exact RTV.
    pub fn bake(
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
        let shading = GiShading::new(loaded, Transfer::Exact(rtv), &matrices, &mut report)?;
        Ok((shading, report))
    }

    /// Shading with the PRT and compressed RTV of `package` (baked for `loaded`'s base mesh).
    pub fn from_package(loaded: &LoadedScene, package: &Package) -> Result<GiShading> {
        let (rtv, matrices) = package.gi(&loaded.base)?;
        GiShading::new(
            loaded,
            Transfer::Compressed(rtv),
            &matrices,
            &mut GiReport::default(),
        )
    }

    fn new(
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
        let incident = matrices.iter().map(|m| prt::incident(m, &light)).collect();
        let d = match &transfer {
            Transfer::Exact(r) => r.dims(),
            Transfer::Compressed(r) => r.dims(),
        };
        let scale = DVec2::new(d.x as f64, d.y as f64);
        let prisms = loaded
            .shell
            .prisms
            .iter()
            .map(|p| {
                let vertices = loaded.base.triangles[p.triangle as usize];
                (vertices, p.uv.map(|uv| uv * scale))
            })
            .collect();
        Ok(GiShading {
            transfer,
            incident,
            prisms,
        })
    }

    /// Incident SH per base-mesh vertex (per channel, in the vertex frame).
    pub fn incident(&self) -> &[RgbSh] {
        &self.incident
    }

    /// Per prism: its base vertices and their texture coordinates (voxel units, x and y).
    pub fn prisms(&self) -> &[([u32; 3], [DVec2; 3])] {
        &self.prisms
    }

    /// The environment light leaving the hit at texture point `texture` (voxel units) of
    /// prism `prism`, reached along texture direction `view` (RGB radiance). A GDM hit can
    /// lie up to a voxel inside the solid, beyond the reach of the samples' interpolation;
    /// the RTV is then read up to [`MAX_BACKOFF`] voxels back along the view, and the hit is
    /// black only when no sample is found there.
    pub fn radiance(&self, prism: usize, texture: DVec3, view: DVec3) -> DVec3 {
        let (vertices, uv) = self.prisms[prism];
        // The RTV is indexed by the direction towards the viewer.
        let towards_eye = (-view).normalize_or(DVec3::Z);
        let Some(transfer) = (0..=MAX_BACKOFF_STEPS).find_map(|step| {
            let back = MAX_BACKOFF * f64::from(step) / f64::from(MAX_BACKOFF_STEPS);
            let t = texture - view * back;
            match &self.transfer {
                Transfer::Exact(r) => r.interpolate(t, towards_eye),
                Transfer::Compressed(r) => r.interpolate(t, towards_eye),
            }
        }) else {
            return DVec3::ZERO;
        };
        let b = barycentric(uv, texture.truncate());
        let mut out = [0.0; 3];
        for (c, out) in out.iter_mut().enumerate() {
            let mut light = [0.0; COEFFS];
            for (v, w) in vertices.iter().zip(b) {
                let inc = &self.incident[*v as usize][c];
                light.iter_mut().zip(inc).for_each(|(l, i)| *l += w * i);
            }
            *out = sh::dot(&transfer[c], &light).max(0.0);
        }
        DVec3::from(out)
    }
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
        glossy: scene.wants(Effect::EnvironmentGloss).then(|| Glossy {
            specular: scene.material.specular,
            exponent: scene.material.shininess / 4.0,
        }),
    }
}

/// How far back along the view, in voxels, a hit looks for RTV samples.
pub const MAX_BACKOFF: f64 = 1.5;

/// The back-off is tried in this many equal steps after the hit itself.
const MAX_BACKOFF_STEPS: u32 = 3;

/// Barycentric coordinates of `p` in triangle `t` (extrapolated outside, clamped to [0, 1]
/// and renormalized; the centroid for a degenerate triangle).
fn barycentric(t: [DVec2; 3], p: DVec2) -> [f64; 3] {
    let (e1, e2, q) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let det = e1.perp_dot(e2);
    if det.abs() < 1e-300 || !det.is_finite() {
        return [1.0 / 3.0; 3];
    }
    let (b1, b2) = (q.perp_dot(e2) / det, e1.perp_dot(q) / det);
    let b = [1.0 - b1 - b2, b1, b2].map(|v| v.clamp(0.0, 1.0));
    let sum: f64 = b.iter().sum();
    b.map(|v| v / sum)
}
