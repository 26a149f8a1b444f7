//! The generalized displacement map: d(x, y, z, θ, φ), the distance along direction (θ, φ) from
//! sample (x, y, z) to the nearest solid mesostructure on the tiled volume.
//!
//! Three cases (GDM paper, Fig. 2b): a hit gives its distance; a ray that leaves through the
//! top or bottom plane without a hit *escapes*; a sample inside solid gives 0. Escapes are
//! stored in one of two conventions ([`EscapeConvention`]); both keep them recoverable.

pub mod caster;
pub mod compare;
pub mod exact;
pub mod fast;
pub mod height_field_caster;
pub mod input;
pub mod interpolate;
pub mod mesh_caster;
pub mod mesh_template;
pub mod npy;
pub mod template;
pub mod volume_caster;

use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::{Dims, DirectionGrid, boundary_distance};

/// How a GDM stores rays that escape without a hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EscapeConvention {
    /// Escapes are +∞ (the paper's d_max; the `.npy` export's convention).
    Infinite,
    /// Escapes hold the distance to the top or bottom plane along the ray (the paper's
    /// replacement for compression). A sample escapes iff its value is at least
    /// [`ESCAPE_TOLERANCE`] times that boundary distance.
    Boundary,
}

/// Relative tolerance of the escape test in the boundary convention. A true hit can only reach
/// its boundary distance where the ray touches solid exactly on the top or bottom plane.
pub const ESCAPE_TOLERANCE: f32 = 1.0 - 1e-5;

/// A dense GDM over a voxel grid and a direction grid.
///
/// Memory layout is direction-major: `data[((a·Nφ + b)·Z + k)·Y·X + j·X + i]`, so each
/// direction is one contiguous X×Y×Z volume (x fastest) and bakers can work a direction (or a
/// layer of one) at a time without sharing writes. The `.npy` export transposes on the fly.
#[derive(Clone, Debug, PartialEq)]
pub struct Gdm {
    dims: Dims,
    dirs: DirectionGrid,
    escape: EscapeConvention,
    data: Vec<f32>,
}

impl Gdm {
    /// A GDM filled with zeros, refusing sizes over the memory limit before allocating.
    pub fn zeroed(dims: Dims, dirs: DirectionGrid, limits: &Limits) -> Result<Self> {
        let count = dims.voxel_count() * dirs.count() as u64;
        limits.check(&format!("a {dims} GDM with {dirs} directions"), count, 4)?;
        Ok(Gdm {
            dims,
            dirs,
            escape: EscapeConvention::Infinite,
            data: vec![0.0; count as usize],
        })
    }

    /// A GDM holding `values` (laid out as documented on the type) in convention `escape`.
    pub fn from_values(
        dims: Dims,
        dirs: DirectionGrid,
        escape: EscapeConvention,
        values: Vec<f32>,
    ) -> Result<Self> {
        let count = dims.voxel_count() * dirs.count() as u64;
        if values.len() as u64 != count {
            return Err(mesobake_core::Error::InvalidParameter(format!(
                "a {dims} GDM with {dirs} directions has {count} values, not {}",
                values.len()
            )));
        }
        Ok(Gdm {
            dims,
            dirs,
            escape,
            data: values,
        })
    }

    /// The values, giving up the GDM.
    pub fn into_values(self) -> Vec<f32> {
        self.data
    }

    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// The direction grid.
    pub fn dirs(&self) -> DirectionGrid {
        self.dirs
    }

    /// The escape convention of the stored values.
    pub fn escape_convention(&self) -> EscapeConvention {
        self.escape
    }

    /// All values, direction-major (see the type's documentation).
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Fills each direction's X×Y×Z volume with `fill(direction index, volume)`, in parallel
    /// over directions, reporting progress per direction and stopping on cancellation.
    pub(crate) fn fill_directions(
        &mut self,
        observer: &dyn BakeObserver,
        fill: impl Fn(usize, &mut [f32]) + Sync,
    ) -> Result<()> {
        use rayon::prelude::*;
        let total = self.dirs.count() as u64;
        let done = std::sync::atomic::AtomicU64::new(0);
        let stride = self.direction_stride();
        self.data
            .par_chunks_mut(stride)
            .enumerate()
            .try_for_each(|(d, volume)| {
                if observer.cancelled() {
                    return Err(mesobake_core::Error::Cancelled);
                }
                fill(d, volume);
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                observer.progress(n, total);
                Ok(())
            })
    }

    /// Number of values in one direction's volume, X·Y·Z.
    pub fn direction_stride(&self) -> usize {
        self.dims.voxel_count() as usize
    }

    /// Flat index of sample (i, j, k) in direction (a, b).
    #[inline]
    pub fn index(&self, i: u32, j: u32, k: u32, a: u32, b: u32) -> usize {
        let d = a as usize * self.dirs.n_phi as usize + b as usize;
        d * self.direction_stride() + self.dims.index(i, j, k)
    }

    /// The stored value at sample (i, j, k), direction (a, b).
    pub fn get(&self, i: u32, j: u32, k: u32, a: u32, b: u32) -> f32 {
        self.data[self.index(i, j, k, a, b)]
    }

    /// Distance from the centre of layer `k` to the top (cos θ > 0) or bottom plane along
    /// direction (a, b).
    pub fn boundary_distance(&self, k: u32, a: u32) -> f32 {
        boundary_distance(self.dims, &self.dirs, k, a)
    }

    /// Whether the stored value of sample (i, j, k), direction (a, b) is an escape.
    pub fn is_escape(&self, i: u32, j: u32, k: u32, a: u32, b: u32) -> bool {
        let v = self.get(i, j, k, a, b);
        match self.escape {
            EscapeConvention::Infinite => v.is_infinite(),
            EscapeConvention::Boundary => v >= ESCAPE_TOLERANCE * self.boundary_distance(k, a),
        }
    }

    /// Converts the stored values to `convention` in place; converting back restores the
    /// original values exactly (escapes are re-detected with [`ESCAPE_TOLERANCE`]).
    pub fn set_escape_convention(&mut self, convention: EscapeConvention) {
        if convention == self.escape {
            return;
        }
        let (dims, dirs) = (self.dims, self.dirs);
        let layer = (dims.x * dims.y) as usize;
        let stride = self.direction_stride();
        for (d, volume) in self.data.chunks_mut(stride).enumerate() {
            let a = (d / dirs.n_phi as usize) as u32;
            for (k, values) in volume.chunks_mut(layer).enumerate() {
                let boundary = boundary_distance(dims, &dirs, k as u32, a);
                for v in values {
                    *v = match convention {
                        EscapeConvention::Boundary if v.is_infinite() => boundary,
                        EscapeConvention::Infinite if *v >= ESCAPE_TOLERANCE * boundary => {
                            f32::INFINITY
                        }
                        _ => *v,
                    };
                }
            }
        }
        self.escape = convention;
    }
}

pub use mesobake_package::manifest::Method;

/// Bakes the GDM of `caster` on its grid with `method` (`fast`: the knobs of
/// [`Method::Fast`]). Values use the [`EscapeConvention::Infinite`].
pub fn bake(
    caster: &(impl caster::Caster + ?Sized),
    dirs: DirectionGrid,
    method: Method,
    fast: fast::FastParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    match method {
        Method::Exact => exact::bake(caster, dirs, limits, observer),
        Method::Fast => fast::bake(caster, dirs, fast, limits, observer),
    }
}
