//! Voxel mesostructure volumes: density with a solid threshold, optional per-voxel albedo and
//! opacity (a translucent medium, [`crate::mesostructure::medium`]), tileable in x and y. The file format lives in [`crate::mesostructure::volume_format`].

use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, Wrap};
use mesobake_package::occupancy::OccupancyField;

/// A tileable X×Y×Z mesostructure volume. Voxel (i, j, k) is the box [i,i+1]×[j,j+1]×[k,k+1]
/// in voxel units; it is solid when its density is at least the threshold.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    dims: Dims,
    density: Vec<f32>,
    threshold: f32,
    albedo: Option<Vec<[u8; 3]>>,
    opacity: Option<Vec<f32>>,
}

impl Volume {
    /// A volume from densities (x fastest, then y, then z), validated: the length must match
    /// the dimensions, every density and the threshold must be finite.
    pub fn new(
        dims: Dims,
        density: Vec<f32>,
        threshold: f32,
        albedo: Option<Vec<[u8; 3]>>,
    ) -> Result<Self> {
        let n = dims.voxel_count() as usize;
        if density.len() != n {
            return Err(Error::VolumeFormat(format!(
                "{} densities given for a {dims} volume of {n} voxels",
                density.len()
            )));
        }
        if !threshold.is_finite() {
            return Err(Error::VolumeFormat(format!(
                "solid threshold is {threshold}, not a finite number"
            )));
        }
        if let Some(bad) = density.iter().position(|d| !d.is_finite()) {
            let (i, j, k) = unravel(dims, bad);
            return Err(Error::VolumeFormat(format!(
                "density of voxel ({i}, {j}, {k}) is {}, not a finite number",
                density[bad]
            )));
        }
        if let Some(a) = &albedo
            && a.len() != n
        {
            return Err(Error::VolumeFormat(format!(
                "{} albedo values given for a {dims} volume of {n} voxels",
                a.len()
            )));
        }
        Ok(Volume {
            dims,
            density,
            threshold,
            albedo,
            opacity: None,
        })
    }

    /// The same volume with a per-voxel opacity (x fastest): the opacity of one voxel length
    /// of the medium, in [0, 1] (see [`crate::mesostructure::medium`]).
    pub fn with_opacity(self, opacity: Vec<f32>) -> Result<Self> {
        let n = self.density.len();
        if opacity.len() != n {
            return Err(Error::VolumeFormat(format!(
                "{} opacities given for a {} volume of {n} voxels",
                opacity.len(),
                self.dims
            )));
        }
        if let Some(bad) = opacity.iter().position(|a| !(0.0..=1.0).contains(a)) {
            let (i, j, k) = unravel(self.dims, bad);
            return Err(Error::VolumeFormat(format!(
                "opacity of voxel ({i}, {j}, {k}) is {}, not a number in [0, 1]",
                opacity[bad]
            )));
        }
        Ok(Volume {
            opacity: Some(opacity),
            ..self
        })
    }

    /// A volume whose voxel (i, j, k) is solid iff `solid(i, j, k)`; density 1 or 0,
    /// threshold ½, no albedo.
    pub fn from_fn(
        dims: Dims,
        limits: &Limits,
        solid: impl Fn(u32, u32, u32) -> bool,
    ) -> Result<Self> {
        limits.check("volume densities", dims.voxel_count(), 4)?;
        let mut density = Vec::with_capacity(dims.voxel_count() as usize);
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    density.push(if solid(i, j, k) { 1.0 } else { 0.0 });
                }
            }
        }
        Volume::new(dims, density, 0.5, None)
    }

    /// The resolution.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Densities, x fastest.
    pub fn density(&self) -> &[f32] {
        &self.density
    }

    /// Density at and above which a voxel is solid.
    pub fn threshold(&self) -> f32 {
        self.threshold
    }

    /// Per-voxel sRGB albedo, x fastest, when the volume has one.
    pub fn albedo(&self) -> Option<&[[u8; 3]]> {
        self.albedo.as_deref()
    }

    /// Per-voxel opacity per voxel length, x fastest, when the volume is a translucent medium.
    pub fn opacity(&self) -> Option<&[f32]> {
        self.opacity.as_deref()
    }

    /// Whether voxel (i, j, k) is solid.
    pub fn is_solid(&self, i: u32, j: u32, k: u32) -> bool {
        self.density[self.dims.index(i, j, k)] >= self.threshold
    }

    /// The solid/empty classification as a bitset.
    pub fn occupancy(&self) -> Occupancy {
        let mut occ = Occupancy::empty(self.dims);
        for k in 0..self.dims.z {
            for j in 0..self.dims.y {
                for i in 0..self.dims.x {
                    if self.is_solid(i, j, k) {
                        occ.set(i, j, k);
                    }
                }
            }
        }
        occ
    }
}

fn unravel(dims: Dims, index: usize) -> (usize, usize, usize) {
    let x = dims.x as usize;
    let y = dims.y as usize;
    (index % x, (index / x) % y, index / (x * y))
}

/// A bit per voxel, x rows packed into 64-bit words: 16 KiB for 64×64×32, so traversals stay
/// in the L1 cache.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Occupancy {
    dims: Dims,
    wrap: [Wrap; 2],
    words_per_row: usize,
    words: Vec<u64>,
}

impl Occupancy {
    /// The occupancy that `field` encodes (its solid voxels).
    pub fn of_field(field: &OccupancyField) -> Self {
        let dims = field.dims();
        let mut occ = Occupancy::empty(dims);
        for (v, _) in field.bytes().iter().enumerate().filter(|(_, d)| **d == 0) {
            let (i, j, k) = unravel(dims, v);
            occ.set(i as u32, j as u32, k as u32);
        }
        occ
    }

    /// This occupancy as the occupancy codec stores it, with its empty-space distances.
    pub fn field(&self) -> OccupancyField {
        OccupancyField::from_solid(self.dims, |i, j, k| self.get(i, j, k))
    }

    /// All voxels empty.
    pub fn empty(dims: Dims) -> Self {
        let words_per_row = (dims.x as usize).div_ceil(64);
        Occupancy {
            dims,
            wrap: [Wrap::new(dims.x), Wrap::new(dims.y)],
            words_per_row,
            words: vec![0; words_per_row * dims.y as usize * dims.z as usize],
        }
    }

    /// The resolution.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Marks voxel (i, j, k) solid.
    pub fn set(&mut self, i: u32, j: u32, k: u32) {
        let w = self.word(j, k) + (i as usize >> 6);
        self.words[w] |= 1 << (i & 63);
    }

    #[inline]
    fn word(&self, j: u32, k: u32) -> usize {
        (k as usize * self.dims.y as usize + j as usize) * self.words_per_row
    }

    /// Whether voxel (i, j, k) is solid; indices must be in range.
    #[inline]
    pub fn get(&self, i: u32, j: u32, k: u32) -> bool {
        let w = self.word(j, k) + (i as usize >> 6);
        (self.words[w] >> (i & 63)) & 1 != 0
    }

    /// Whether the voxel at unbounded integer coordinates is solid: x and y wrap around
    /// (tiling), layers outside 0..Z are empty.
    #[inline]
    pub fn get_periodic(&self, i: i64, j: i64, k: i64) -> bool {
        if k < 0 || k >= self.dims.z as i64 {
            return false;
        }
        let i = self.wrap[0].apply(i) as u32;
        let j = self.wrap[1].apply(j) as u32;
        self.get(i, j, k as u32)
    }

    /// The 64-bit words of row (j, k): bit i of word w is voxel (64w + i, j, k).
    #[inline]
    pub fn row(&self, j: u32, k: u32) -> &[u64] {
        let w = self.word(j, k);
        &self.words[w..w + self.words_per_row]
    }

    /// Number of solid voxels.
    pub fn solid_count(&self) -> u64 {
        self.words.iter().map(|w| w.count_ones() as u64).sum()
    }

    /// Lowest and highest layers holding a solid voxel, or `None` when the volume is empty.
    pub fn solid_layer_range(&self) -> Option<(u32, u32)> {
        let per_layer = self.words_per_row * self.dims.y as usize;
        let solid_layer = |k: &u32| {
            let s = *k as usize * per_layer;
            self.words[s..s + per_layer].iter().any(|&w| w != 0)
        };
        let lo = (0..self.dims.z).find(solid_layer)?;
        let hi = (0..self.dims.z).rev().find(solid_layer)?;
        Some((lo, hi))
    }
}
