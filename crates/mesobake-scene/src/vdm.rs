//! A scene's view-dependent displacement map: how it is baked and compressed
//! ([`VdmSettings`]), the depth of its relief in tiles, and the bake itself.

use super::LoadedScene;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::vdm::{CompressedVdm, MAX_VDM_RANK, compress};
use mesobake_bake::mesostructure::height_field::HeightField;
use mesobake_bake::surface::shell::Shell;
use mesobake_bake::vdm::{self, MAX_OVERSAMPLING, Relief, Vdm, VdmGrid, VdmMethod, VdmParams};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_core::quality::ShadowMethod;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// How a scene's VDM is baked and compressed: the paper's grid and compression by default,
/// with the paper's resampling bake (the exact bake is the accurate, slower choice).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VdmSettings {
    /// View directions [Nθ, Nφ].
    pub directions: [u32; 2],
    /// Curvature samples.
    pub curvatures: u32,
    /// The curvature range [min, max], 1/tile (positive: convex).
    pub curvature_range: [f64; 2],
    /// The bake.
    pub method: VdmMethod,
    /// The paper's bake: flat rays per θ bin before resampling.
    pub oversampling: u32,
    /// Components of the VDM's reconstruction.
    pub rank: usize,
    /// Components of the MVM's reconstruction (≤ `rank`).
    pub mvm_rank: usize,
    /// Number format of the factors.
    pub quantization: Quantization,
    /// Rendering: texels of the height field searched along the view ray around the VDM's
    /// hit for the exact crossing (0: the paper's lookup alone; at most
    /// [`MAX_REFINE_TEXELS`]).
    pub refine_texels: u32,
    /// Rendering: the shadow test (`local`: the paper's, the relief above the hit only;
    /// `shell`: also every entry of the light's ray into the top surface, so the base
    /// mesh's far side and the relief on it cast shadows).
    pub shadows: ShadowMethod,
}

/// The widest search [`VdmSettings::refine_texels`] may ask for.
pub const MAX_REFINE_TEXELS: u32 = 64;

impl Default for VdmSettings {
    fn default() -> Self {
        let g = VdmGrid::PAPER;
        VdmSettings {
            directions: [g.n_theta, g.n_phi],
            curvatures: g.n_curvature,
            curvature_range: [g.c_min, g.c_max],
            method: VdmMethod::Paper,
            oversampling: 1,
            rank: 8,
            mvm_rank: 4,
            quantization: Quantization::F16,
            refine_texels: 0,
            shadows: ShadowMethod::Local,
        }
    }
}

impl VdmSettings {
    /// Whether these are the defaults (left out when a scene is written).
    pub fn is_default(&self) -> bool {
        *self == VdmSettings::default()
    }

    /// Checks what can be checked before the shell is built: the grid's counts and range,
    /// the ranks and the oversampling (the curvatures against the relief's depth are
    /// checked when baking).
    pub fn validate(&self) -> Result<()> {
        let scene = |e: Error| Error::Scene(format!("vdm: {e}"));
        self.grid().validate(0.0).map_err(|e| scene(e.into()))?;
        if !(1..=MAX_VDM_RANK).contains(&self.rank) || !(1..=self.rank).contains(&self.mvm_rank) {
            return Err(scene(Error::InvalidParameter(format!(
                "rank must be 1 to {MAX_VDM_RANK} and mvm_rank 1 to rank, got {} and {}",
                self.rank, self.mvm_rank
            ))));
        }
        if !(1..=MAX_OVERSAMPLING).contains(&self.oversampling) {
            return Err(scene(Error::InvalidParameter(format!(
                "oversampling must be 1 to {MAX_OVERSAMPLING}, got {}",
                self.oversampling
            ))));
        }
        if self.refine_texels > MAX_REFINE_TEXELS {
            return Err(scene(Error::InvalidParameter(format!(
                "refine_texels must be 0 to {MAX_REFINE_TEXELS}, got {}",
                self.refine_texels
            ))));
        }
        Ok(())
    }

    /// The view and curvature grid.
    pub fn grid(&self) -> VdmGrid {
        VdmGrid {
            n_theta: self.directions[0],
            n_phi: self.directions[1],
            n_curvature: self.curvatures,
            c_min: self.curvature_range[0],
            c_max: self.curvature_range[1],
        }
    }

    /// The bake's parameters.
    pub fn params(&self) -> VdmParams {
        VdmParams::new(self.method, self.oversampling)
    }
}

/// The relief's depth in tiles on `shell`: the thickness over the mean edge of a tile on the
/// reference surface, sqrt(object area / texture area) over the top triangles, so that the
/// VDM's space is on average as deep, relative to the tile, as the shell.
pub fn relief_depth(shell: &Shell) -> Result<f64> {
    let (mut object, mut texture) = (0.0, 0.0);
    for p in &shell.prisms {
        let [a, b, c] = p.top();
        object += 0.5 * (b - a).cross(c - a).length();
        texture += 0.5 * (p.uv[1] - p.uv[0]).perp_dot(p.uv[2] - p.uv[0]).abs();
    }
    let depth = shell.params.thickness / (object / texture).sqrt();
    if depth.is_finite() && depth > 0.0 {
        Ok(depth)
    } else {
        Err(Error::Scene(
            "the shell's reference surface has no area to map a relief onto".into(),
        ))
    }
}

/// A scene's VDM as renderers use it: the compressed map, its height field and depth.
pub struct SceneVdm {
    /// The height field it was baked from.
    pub field: HeightField,
    /// The relief's depth (tiles).
    pub depth: f64,
    /// The baked map.
    pub vdm: Vdm,
    /// The compressed map.
    pub compressed: CompressedVdm,
    /// Seconds baking (stage `bake_vdm`) and compressing (stage `compress_vdm`).
    pub seconds: [f64; 2],
}

impl SceneVdm {
    /// The relief it was baked from.
    pub fn relief(&self) -> Relief<'_> {
        Relief {
            field: &self.field,
            depth: self.depth,
        }
    }
}

impl LoadedScene {
    /// The height field of the scene's mesostructure, for VDM techniques.
    pub fn relief_field(&self) -> Result<&HeightField> {
        self.height_field.as_ref().ok_or_else(|| {
            Error::Scene(
                "VDM needs a height-field mesostructure (a height_field PNG or a built-in relief)"
                    .into(),
            )
        })
    }

    /// Bakes and compresses the VDM of the scene's height field as its [`VdmSettings`] say,
    /// telling `observer` of the stages `bake_vdm` and `compress_vdm`.
    pub fn bake_vdm(&self, limits: &Limits, observer: &dyn BakeObserver) -> Result<SceneVdm> {
        let settings = &self.scene.vdm;
        let field = self.relief_field()?;
        let depth = relief_depth(&self.shell)?;
        let relief = Relief { field, depth };
        let start = Instant::now();
        observer.stage("bake_vdm");
        let vdm = vdm::bake(relief, settings.grid(), settings.params(), limits, observer)?;
        let bake_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        observer.stage("compress_vdm");
        let compressed = compress(
            &vdm,
            settings.rank,
            settings.mvm_rank,
            settings.quantization,
            limits,
        )?;
        Ok(SceneVdm {
            field: field.clone(),
            depth,
            vdm,
            compressed,
            seconds: [bake_s, start.elapsed().as_secs_f64()],
        })
    }
}
