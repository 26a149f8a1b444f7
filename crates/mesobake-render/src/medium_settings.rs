//! How a scene's translucent medium is rendered by the real-time algorithm of semi-transparent
//! 3D textures ([`crate::medium_cells`]).

use crate::cell_order::ViewSort;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_core::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Most samples per cell.
pub const MAX_CELL_SAMPLES: u32 = 1024;

/// How a ray's stretch through one cell is integrated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CellIntegration {
    /// A fixed number of samples per cell, each standing for an equal share of the stretch
    /// (the paper's choice).
    Samples,
    /// Every voxel the stretch crosses, in closed form (a 3D DDA): the default, more
    /// accurate and on the CPU faster than the samples that come near it.
    #[default]
    Exact,
}

/// How the real-time pipeline (WGSL) finds the cells a pixel's ray crosses in order. The
/// CPU specification always keeps the per-pixel list.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CellOrder {
    /// Per pixel, the sorted list of the cells the ray crosses (from a BVH over the cells):
    /// always the exact order, no cycles to break.
    #[default]
    PerPixel,
    /// The cells sorted once per view on the CPU by SXMPVO ([`crate::cell_order`]),
    /// drawn back to front and blended: the paper's algorithm; exact at pixel centres
    /// unless the cells' constraints form a cycle.
    PerView,
    /// The same with the cheaper MPVONC sort (no relations across gaps in the mesh, the
    /// farthest centroid first instead): wrong where one part of the shell reaches behind
    /// another.
    PerViewMpvo,
}

impl CellOrder {
    /// Every order.
    pub const ALL: [CellOrder; 3] = [
        CellOrder::PerPixel,
        CellOrder::PerView,
        CellOrder::PerViewMpvo,
    ];

    /// The order's name as scenes write it.
    pub fn name(self) -> &'static str {
        match self {
            CellOrder::PerPixel => "per-pixel",
            CellOrder::PerView => "per-view",
            CellOrder::PerViewMpvo => "per-view-mpvo",
        }
    }

    /// The per-view sort, for the orders that sort once per view.
    pub fn view_sort(self) -> Option<ViewSort> {
        match self {
            CellOrder::PerPixel => None,
            CellOrder::PerView => Some(ViewSort::Sxmpvo),
            CellOrder::PerViewMpvo => Some(ViewSort::Mpvonc),
        }
    }
}

/// How the real-time algorithm finds what of each light reaches a point in the medium
/// ([`crate::medium_shadow_map`]), where the scene calls for shadows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShadowMethod {
    /// A ray through the cells towards the light from every sample, integrated like the
    /// camera rays: the reference the maps are measured against.
    Rays,
    /// A deep shadow map per light, rebuilt every frame: per light-space texel, the depths
    /// at which the light's transmittance falls through `shadow_levels` fixed levels (steps
    /// such as an opaque surface kept exact), read linearly in depth and bilinearly across
    /// texels. Volumetric shadows.
    #[default]
    DeepMap,
    /// The paper's shadow map: per light-space texel one depth, where the light's
    /// transmittance falls to ½; read with a 2 × 2 percentage-closer filter. Shadows are
    /// all or nothing per texel.
    DepthMap,
}

/// The real-time algorithm's knobs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TransparencySettings {
    /// How each cell is integrated.
    pub integration: CellIntegration,
    /// Samples per cell for [`CellIntegration::Samples`] (1 to [`MAX_CELL_SAMPLES`]).
    pub samples: u32,
    /// Whether each crossing reads the level of the opacity-aware mip-map that its pixel's
    /// footprint calls for ([`mesobake_bake::mesostructure::medium::Medium::coarser`]).
    pub mipmap: bool,
    /// Added to the level the footprint calls for (negative: sharper; at most
    /// [`MAX_MIP_BIAS`] either way).
    pub mip_bias: f64,
    /// How the real-time pipeline orders the cells.
    pub order: CellOrder,
    /// How shadows are found (where the scene asks for them).
    pub shadows: ShadowMethod,
    /// Texels along each side of a shadow map.
    pub shadow_map_size: u32,
    /// Transmittance levels whose depths a deep-map texel stores.
    pub shadow_levels: u32,
    /// Number format of the medium package's colour and opacity (`f32` exact, `f16` or `u8`;
    /// normals never below f16).
    pub quantization: Quantization,
}

/// Largest shadow map side.
pub const MAX_SHADOW_MAP_SIZE: u32 = 4096;

/// Most levels per deep-map texel.
pub const MAX_SHADOW_LEVELS: u32 = 256;

/// Most values one light's deep map holds (texels × levels), refused before allocating.
pub const MAX_SHADOW_MAP_VALUES: u64 = 1 << 25;

/// Largest mip level bias either way.
pub const MAX_MIP_BIAS: f64 = 8.0;

impl Default for TransparencySettings {
    /// Exact integration; 16 samples per cell where `integration` is `samples` (the paper
    /// takes 10 to 15 per image); no mip-map, so that one ray per pixel integrates what the
    /// ground truth integrates; with it, one level sharper than the footprint's (averaged
    /// opacity darkens shadows through coarse voxels: on the fur scene bias −1 measured
    /// nearest a supersampled truth); packages in f16 (as close to the truth as f32 on every
    /// sample scene, at half the bytes: docs/BENCHMARKS.md).
    fn default() -> Self {
        TransparencySettings {
            integration: CellIntegration::Exact,
            samples: 16,
            mipmap: false,
            mip_bias: -1.0,
            order: CellOrder::PerPixel,
            shadows: ShadowMethod::DeepMap,
            shadow_map_size: 256,
            shadow_levels: 32,
            quantization: Quantization::F16,
        }
    }
}

impl TransparencySettings {
    /// Whether these are the defaults (left out when a scene is written).
    pub fn is_default(&self) -> bool {
        *self == TransparencySettings::default()
    }

    /// The cell order's name as scenes write it.
    pub fn order_name(&self) -> &'static str {
        self.order.name()
    }

    /// The shadow method's name as scenes write it.
    pub fn shadows_name(&self) -> &'static str {
        match self.shadows {
            ShadowMethod::Rays => "rays",
            ShadowMethod::DeepMap => "deep-map",
            ShadowMethod::DepthMap => "depth-map",
        }
    }

    /// Checks the sample count, the bias and the shadow maps' sizes.
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_SHADOW_MAP_SIZE).contains(&self.shadow_map_size) {
            return Err(Error::Scene(format!(
                "transparency: shadow_map_size must be 1 to {MAX_SHADOW_MAP_SIZE}, got {}",
                self.shadow_map_size
            )));
        }
        if !(1..=MAX_SHADOW_LEVELS).contains(&self.shadow_levels) {
            return Err(Error::Scene(format!(
                "transparency: shadow_levels must be 1 to {MAX_SHADOW_LEVELS}, got {}",
                self.shadow_levels
            )));
        }
        let values = u64::from(self.shadow_map_size).pow(2) * u64::from(self.shadow_levels);
        if self.shadows == ShadowMethod::DeepMap && values > MAX_SHADOW_MAP_VALUES {
            return Err(Error::Scene(format!(
                "transparency: a deep map of {0}² texels × {1} levels holds {values} values \
                 per light; at most {MAX_SHADOW_MAP_VALUES}",
                self.shadow_map_size, self.shadow_levels
            )));
        }
        if self.mip_bias.is_nan() || self.mip_bias.abs() > MAX_MIP_BIAS {
            return Err(Error::Scene(format!(
                "transparency: mip_bias must be within ±{MAX_MIP_BIAS}, got {}",
                self.mip_bias
            )));
        }
        if !(1..=MAX_CELL_SAMPLES).contains(&self.samples) {
            return Err(Error::Scene(format!(
                "transparency: samples must be 1 to {MAX_CELL_SAMPLES}, got {}",
                self.samples
            )));
        }
        Ok(())
    }
}
