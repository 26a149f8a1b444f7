//! The view-dependent displacement map (VDM) of a height field: d(x, y, θ, φ, c), the
//! distance along the viewing ray from the reference surface to the mesostructure, for a
//! reference surface bent to curvature c along the view direction; −1 ([`NO_HIT`]) where the
//! ray meets no mesostructure.
//!
//! **Units and conventions.** Texture units throughout: the tile is 1 × 1 in (x, y), so
//! lengths, the relief `depth` and d are fractions of the tile's edge, and curvatures are in
//! 1/tile (the paper's −2 … 3). The reference surface is the top of the relief (z = 0); the
//! mesostructure surface lies `depth · (1 − h(x, y))` below it, h the height field in [0, 1]
//! (h = 1 touches the reference surface). Sample (i, j) is texel centre ((i + ½)/W,
//! (j + ½)/H). The view ray enters the surface at polar angle θ from the inward normal, moving
//! along azimuth φ in texture space: direction (sin θ cos φ, sin θ sin φ, −cos θ); θ_a =
//! (a + ½)·(π/2)/Nθ and φ_b = (b + ½)·2π/Nφ (bin centres, so never 0 or π/2), c_k evenly
//! from c_min to c_max. Positive curvature is convex (the surface bends away from the ray).
//!
//! **Curved surfaces** (the paper's appendix): the surface is a cylinder of radius 1/c whose
//! axis is perpendicular to the view's azimuth ([`bend`]); a point at arc length σ along the
//! azimuth and depth t maps to the circle of radius 1/c − t. The VDM then stores
//! d = l / sin θ with l the arc length σ of the hit, so that the texture offset of the hit is
//! always d · (sin θ cos φ, sin θ sin φ); on a flat surface that is the ray's length.
//!
//! Two bakes ([`VdmMethod`]): [`exact`] casts every ray against the bent relief;
//! [`paper`] bends the zero-curvature hits and resamples them over θ, as the paper does.

pub mod bend;
pub mod compare;
pub mod exact;

pub use compare::{VdmError, compare};
pub mod paper;

use crate::bake::gdm::BakeObserver;
use crate::error::{Error, Result};
use crate::mesostructure::height_field::HeightField;
use crate::util::limits::Limits;

/// The value of a sample whose ray meets no mesostructure.
pub const NO_HIT: f32 = -1.0;

pub use mesobake_package::vdm::{MAX_AXIS, MAX_OVERSAMPLING, VdmGrid, VdmMethod};

/// How to bake a VDM: the method and its knob.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VdmParams {
    /// The bake.
    pub method: VdmMethod,
    /// The paper's bake: flat rays cast per θ bin before resampling (1 is the paper's).
    pub oversampling: u32,
}

impl VdmParams {
    /// `method` with `oversampling`, which only the paper's bake has (1 for the exact one).
    pub fn new(method: VdmMethod, oversampling: u32) -> VdmParams {
        VdmParams {
            method,
            oversampling: match method {
                VdmMethod::Exact => 1,
                VdmMethod::Paper => oversampling,
            },
        }
    }

    /// The exact bake.
    pub const EXACT: VdmParams = VdmParams {
        method: VdmMethod::Exact,
        oversampling: 1,
    };
}

/// A relief: a height field and how deep it reaches below the reference surface.
#[derive(Clone, Copy, Debug)]
pub struct Relief<'a> {
    /// Heights in [0, 1].
    pub field: &'a HeightField,
    /// Depth of height 0 below the reference surface (tile units, > 0).
    pub depth: f64,
}

impl Relief<'_> {
    /// Depth of the mesostructure surface below the reference surface at texture point
    /// (u, v): depth · (1 − h(u, v)), h bilinear and periodic.
    pub fn surface_depth(&self, u: f64, v: f64) -> f64 {
        self.depth * (1.0 - self.field.sample(u, v))
    }

    /// Bounds on how fast `surface_depth` changes, block by block.
    pub fn slopes(&self) -> SlopeMap {
        SlopeMap::new(self)
    }
}

/// Texels per side of a [`SlopeMap`] block.
const SLOPE_BLOCK: u32 = 8;

/// Bounds on the slope of a relief's depth (its bilinear interpolation's, per unit of texture
/// distance), per block of cells, so that sphere tracing can step far over flat regions and
/// still never skip a crossing near steep ones. Cell (i, j) is the bilinear patch between texel
/// centres (i, j) and (i + 1, j + 1); its gradient is at most the Euclidean sum of its largest
/// edge slopes along x and y.
#[derive(Clone, Debug)]
pub struct SlopeMap {
    size: (u32, u32),
    blocks: (u32, u32),
    /// Per block, the largest slope of its cells.
    max: Vec<f64>,
    /// Texture distance covered by [`SlopeMap::near`] around any point.
    reach: f64,
}

impl SlopeMap {
    fn new(relief: &Relief) -> SlopeMap {
        let (w, h) = relief.field.size();
        let height = |i: u32, j: u32| {
            relief.field.sample(
                (f64::from(i % w) + 0.5) / f64::from(w),
                (f64::from(j % h) + 0.5) / f64::from(h),
            )
        };
        let blocks = (w.div_ceil(SLOPE_BLOCK), h.div_ceil(SLOPE_BLOCK));
        let mut max = vec![0.0f64; (blocks.0 * blocks.1) as usize];
        for j in 0..h {
            for i in 0..w {
                let corners = [
                    height(i, j),
                    height(i + 1, j),
                    height(i, j + 1),
                    height(i + 1, j + 1),
                ];
                let sx = (corners[1] - corners[0])
                    .abs()
                    .max((corners[3] - corners[2]).abs());
                let sy = (corners[2] - corners[0])
                    .abs()
                    .max((corners[3] - corners[1]).abs());
                let slope = relief.depth * (sx * f64::from(w)).hypot(sy * f64::from(h));
                let block = ((j / SLOPE_BLOCK) * blocks.0 + i / SLOPE_BLOCK) as usize;
                max[block] = max[block].max(slope);
            }
        }
        // The 3 × 3 blocks around a cell cover at least the smallest block's width of cells on
        // every side (the last block of a row or column may be partial).
        let cells = |n: u32| SLOPE_BLOCK.min(n - SLOPE_BLOCK * (n.div_ceil(SLOPE_BLOCK) - 1));
        let reach = (f64::from(cells(w)) / f64::from(w)).min(f64::from(cells(h)) / f64::from(h));
        SlopeMap {
            size: (w, h),
            blocks,
            max,
            reach,
        }
    }

    /// The largest slope within [`SlopeMap::reach`] of texture point (u, v).
    pub fn near(&self, u: f64, v: f64) -> f64 {
        let (w, h) = self.size;
        let cell =
            |x: f64, n: u32| ((x * f64::from(n) - 0.5).floor() as i64).rem_euclid(i64::from(n));
        let (bx, by) = (
            cell(u, w) / i64::from(SLOPE_BLOCK),
            cell(v, h) / i64::from(SLOPE_BLOCK),
        );
        let (nx, ny) = (i64::from(self.blocks.0), i64::from(self.blocks.1));
        let mut most = 0.0f64;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let block = (by + dy).rem_euclid(ny) * nx + (bx + dx).rem_euclid(nx);
                most = most.max(self.max[block as usize]);
            }
        }
        most
    }

    /// The texture distance around any point that [`SlopeMap::near`] covers.
    pub fn reach(&self) -> f64 {
        self.reach
    }
}

/// A baked VDM: `values[((k·Nθ + a)·Nφ + b)·W·H + j·W + i]` for curvature k, view (a, b),
/// texel (i, j), so that each (curvature, view) is one W × H image.
#[derive(Clone, Debug, PartialEq)]
pub struct Vdm {
    /// Texels along x and y (the height field's).
    pub size: (u32, u32),
    /// The view and curvature grid.
    pub grid: VdmGrid,
    /// The relief's depth (tile units).
    pub depth: f64,
    /// The samples (tile units, or [`NO_HIT`]).
    pub values: Vec<f32>,
}

impl Vdm {
    /// The sample at texel (i, j), view (a, b), curvature k.
    pub fn get(&self, i: u32, j: u32, a: u32, b: u32, k: u32) -> f32 {
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        let g = &self.grid;
        let image =
            ((k as usize * g.n_theta as usize + a as usize) * g.n_phi as usize) + b as usize;
        self.values[image * w * h + j as usize * w + i as usize]
    }
}

/// Bakes the VDM of `relief` on `grid` as `params` say, reporting progress to `observer`.
pub fn bake(
    relief: Relief,
    grid: VdmGrid,
    params: VdmParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Vdm> {
    if !(1..=MAX_OVERSAMPLING).contains(&params.oversampling) {
        return Err(Error::InvalidParameter(format!(
            "VDM oversampling must be 1 to {MAX_OVERSAMPLING}, got {}",
            params.oversampling
        )));
    }
    if !(relief.depth.is_finite() && relief.depth > 0.0) {
        return Err(Error::InvalidParameter(format!(
            "the relief depth must be finite and positive, got {}",
            relief.depth
        )));
    }
    grid.validate(relief.depth)?;
    let (w, h) = relief.field.size();
    let count = u64::from(w)
        * u64::from(h)
        * u64::from(grid.n_theta)
        * u64::from(grid.n_phi)
        * u64::from(grid.n_curvature);
    limits.check("the VDM", count, 4)?;
    let values = match params.method {
        VdmMethod::Exact => exact::bake(relief, grid, observer)?,
        VdmMethod::Paper => paper::bake(relief, grid, params.oversampling, observer)?,
    };
    Ok(Vdm {
        size: (w, h),
        grid,
        depth: relief.depth,
        values,
    })
}
