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

use crate::mesostructure::height_field::HeightField;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

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

/// Bakes a VDM of `size` texels on `grid` azimuth by azimuth, in parallel: `prepare(b)` makes
/// what azimuth b's texels share, and `texel(shared, [x, y], out)` writes one texel's values
/// on that azimuth to `out`, by curvature, then θ. Each azimuth writes its own images of the
/// result, a row at a time (storing every texel's values straight to images an image apart
/// stalls on the scattered stores).
fn bake_by_azimuth<S>(
    (w, h): (u32, u32),
    grid: VdmGrid,
    observer: &dyn BakeObserver,
    prepare: impl Fn(u32) -> S + Sync,
    texel: impl Fn(&mut S, [u32; 2], &mut [f32]) + Sync,
) -> Result<Vec<f32>> {
    let (width, texels) = (w as usize, (w * h) as usize);
    let n_phi = grid.n_phi as usize;
    let per_texel = grid.n_curvature as usize * grid.n_theta as usize;
    let done = AtomicU64::new(0);
    // Zeroed, which the allocator leaves to the system's untouched pages: every value is
    // written by its azimuth's task.
    let mut values = vec![0.0; per_texel * n_phi * texels];
    // Image (k·Nθ + a)·Nφ + b belongs to azimuth b; each azimuth's by curvature, then θ.
    let mut images: Vec<Vec<&mut [f32]>> =
        (0..n_phi).map(|_| Vec::with_capacity(per_texel)).collect();
    for (i, image) in values.chunks_exact_mut(texels).enumerate() {
        images[i % n_phi].push(image);
    }
    images
        .into_par_iter()
        .enumerate()
        .try_for_each(|(b, mut images)| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let mut shared = prepare(b as u32);
            let mut column = vec![0.0; per_texel];
            let mut rows = vec![0.0; per_texel * width];
            for y in 0..h {
                for x in 0..w {
                    texel(&mut shared, [x, y], &mut column);
                    for (row, &value) in rows.chunks_exact_mut(width).zip(&column) {
                        row[x as usize] = value;
                    }
                }
                let y = y as usize;
                for (image, row) in images.iter_mut().zip(rows.chunks_exact(width)) {
                    image[y * width..][..width].copy_from_slice(row);
                }
            }
            observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, n_phi as u64);
            Ok(())
        })?;
    Ok(values)
}
