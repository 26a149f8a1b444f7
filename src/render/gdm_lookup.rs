//! GDM queries at continuous positions and directions, as the renderers and shaders make
//! them: d(T, V) for a texture point T (voxel units) and a unit texture-space direction V.
//!
//! Interpolation (the same for raw GDMs and packages, mirroring GPU texture filtering):
//! positions are linear between voxel centres, x and y periodic, z clamped to the centres of
//! the first and last layers; directions are linear between bin centres, φ periodic, θ clamped
//! to the first and last bins.
//! - A raw GDM interpolates over all 32 corners (x, y, z, θ, φ). Escaping corners vote: the
//!   query escapes when their weight is at least ½; otherwise the distance is the weighted
//!   mean of the hitting corners.
//! - A package reconstructs d̃ = Σᵢ W̃ᵢ(x, y, φ)·Ẽᵢ(θ, z), each factor interpolated on its
//!   own (trilinear in the weight maps' 3D textures, bilinear in the eigenmaps' 2D ones), and
//!   applies the package's escape rule d̃ ≥ (1 − μ)·b̃ with the boundary distance b̃
//!   interpolated like the eigenmaps.

use crate::compress::accuracy::is_escape;
use crate::compress::quantize::QuantizedFactor;
use crate::gdm::{ESCAPE_TOLERANCE, EscapeConvention, Gdm};
use crate::grid::{Dims, DirectionGrid, Wrap};
use crate::package::Package;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::{PI, TAU};

/// The answer to one query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lookup {
    /// Solid at this distance (voxel units; 0 inside solid).
    Hit(f64),
    /// The ray leaves through the top or bottom plane first.
    Escape,
}

/// Something that answers GDM queries.
pub trait GdmLookup: Sync {
    /// The voxel grid.
    fn dims(&self) -> Dims;
    /// d(`t`, `v`): `t` in voxel units, `v` a unit texture-space direction.
    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup;
}

/// Linear interpolation taps along one axis: two indices and the weight of the second.
#[derive(Clone, Copy, Debug)]
struct Taps {
    index: [u32; 2],
    frac: f64,
}

impl Taps {
    fn periodic(coord: f64, n: u32) -> Taps {
        let f = coord.floor();
        let wrap = Wrap::new(n);
        Taps {
            index: [wrap.apply(f as i64) as u32, wrap.apply(f as i64 + 1) as u32],
            frac: coord - f,
        }
    }

    fn clamped(coord: f64, n: u32) -> Taps {
        let c = coord.clamp(0.0, (n - 1) as f64);
        let f = c.floor();
        let i = f as u32;
        Taps {
            index: [i, (i + 1).min(n - 1)],
            frac: c - f,
        }
    }

    fn weight(&self, side: u32) -> f64 {
        if side == 1 {
            self.frac
        } else {
            1.0 - self.frac
        }
    }
}

/// Position and direction taps of one query.
struct QueryTaps {
    x: Taps,
    y: Taps,
    z: Taps,
    theta: Taps,
    phi: Taps,
}

impl QueryTaps {
    fn new(dims: Dims, dirs: DirectionGrid, t: DVec3, v: DVec3) -> QueryTaps {
        let theta = v.z.clamp(-1.0, 1.0).acos();
        let phi = v.y.atan2(v.x).rem_euclid(TAU);
        QueryTaps {
            x: Taps::periodic(t.x - 0.5, dims.x),
            y: Taps::periodic(t.y - 0.5, dims.y),
            z: Taps::clamped(t.z - 0.5, dims.z),
            theta: Taps::clamped(theta / PI * dirs.n_theta as f64 - 0.5, dirs.n_theta),
            phi: Taps::periodic(phi / TAU * dirs.n_phi as f64 - 0.5, dirs.n_phi),
        }
    }
}

/// Texels per side of the cubic bricks a [`RawLookup`] stores each direction's volume in.
const BRICK: usize = 4;

/// One direction's X×Y×Z volume laid out in [`BRICK`]³ bricks (x fastest within a brick,
/// then y, then z; the bricks in the same order), as GPUs tile 3D textures: the 2×2×2 spatial
/// taps of a query then fall in one or two 64-byte cache lines instead of four (the torus +
/// chain render took 10 % less time, docs/BENCHMARKS.md). A texel's offset is the sum of one
/// term per axis.
#[derive(Clone, Debug)]
struct BrickLayout {
    /// The offset terms of x index i, y index j and z index k.
    x: Vec<usize>,
    y: Vec<usize>,
    z: Vec<usize>,
    /// Texels per direction, the padding of partial bricks included.
    stride: usize,
}

impl BrickLayout {
    fn new(dims: Dims) -> BrickLayout {
        let [bx, by, bz] = [dims.x, dims.y, dims.z].map(|n| (n as usize).div_ceil(BRICK));
        let texels = BRICK * BRICK * BRICK;
        let axis = |n: u32, brick_step: usize, texel_step: usize| -> Vec<usize> {
            (0..n as usize)
                .map(|i| i / BRICK * brick_step + i % BRICK * texel_step)
                .collect()
        };
        BrickLayout {
            x: axis(dims.x, texels, 1),
            y: axis(dims.y, texels * bx, BRICK),
            z: axis(dims.z, texels * bx * by, BRICK * BRICK),
            stride: texels * bx * by * bz,
        }
    }

    fn offset(&self, i: u32, j: u32, k: u32) -> usize {
        self.x[i as usize] + self.y[j as usize] + self.z[k as usize]
    }
}

/// Queries on a dense GDM as baked (either escape convention).
pub struct RawLookup<'a> {
    gdm: &'a Gdm,
    layout: BrickLayout,
    /// The GDM's values in `layout`, one direction after another.
    bricked: Vec<f32>,
    /// Per direction bin θ and layer k (index θ·Z + k): stored values at or above this are
    /// escapes (`+∞` in the infinite convention).
    escape_from: Vec<f32>,
}

impl<'a> RawLookup<'a> {
    /// Wraps `gdm`.
    pub fn new(gdm: &'a Gdm) -> Self {
        let (dims, dirs) = (gdm.dims(), gdm.dirs());
        let escape_from = (0..dirs.n_theta)
            .flat_map(|a| (0..dims.z).map(move |k| (a, k)))
            .map(|(a, k)| match gdm.escape_convention() {
                EscapeConvention::Infinite => f32::INFINITY,
                EscapeConvention::Boundary => ESCAPE_TOLERANCE * gdm.boundary_distance(k, a),
            })
            .collect();
        let layout = BrickLayout::new(dims);
        let mut bricked = vec![0.0; layout.stride * dirs.count()];
        let stride = gdm.direction_stride();
        bricked
            .par_chunks_mut(layout.stride)
            .zip(gdm.data().par_chunks(stride))
            .for_each(|(dst, src)| {
                for k in 0..dims.z {
                    for j in 0..dims.y {
                        for i in 0..dims.x {
                            dst[layout.offset(i, j, k)] = src[dims.index(i, j, k)];
                        }
                    }
                }
            });
        RawLookup {
            gdm,
            layout,
            bricked,
            escape_from,
        }
    }
}

impl GdmLookup for RawLookup<'_> {
    fn dims(&self) -> Dims {
        self.gdm.dims()
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        let g = self.gdm;
        let (dims, data) = (g.dims(), &self.bricked);
        let q = QueryTaps::new(dims, g.dirs(), t, v);
        // The 8 spatial taps: weight, offset within one direction's bricks, layer.
        let spatial: [(f64, usize, u32); 8] = std::array::from_fn(|c| {
            let s = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let (i, j, k) = (q.x.index[s[0]], q.y.index[s[1]], q.z.index[s[2]]);
            let w = q.x.weight(s[0] as u32) * q.y.weight(s[1] as u32) * q.z.weight(s[2] as u32);
            (w, self.layout.offset(i, j, k), k)
        });
        let (mut escape, mut hit, mut sum) = (0.0, 0.0, 0.0);
        for (sa, &a) in q.theta.index.iter().enumerate() {
            let escape_from = &self.escape_from[(a * dims.z) as usize..];
            for (sb, &b) in q.phi.index.iter().enumerate() {
                let w_dir = q.theta.weight(sa as u32) * q.phi.weight(sb as u32);
                if w_dir == 0.0 {
                    continue;
                }
                let base = (a * g.dirs().n_phi + b) as usize * self.layout.stride;
                for &(w, index, k) in &spatial {
                    let w = w * w_dir;
                    let value = data[base + index];
                    if value >= escape_from[k as usize] {
                        escape += w;
                    } else {
                        hit += w;
                        sum += w * value as f64;
                    }
                }
            }
        }
        if escape >= 0.5 || hit == 0.0 {
            Lookup::Escape
        } else {
            Lookup::Hit(sum / hit)
        }
    }
}

/// Queries on a package's factors: the reconstruction a shader computes.
pub struct PackageLookup {
    dims: Dims,
    dirs: DirectionGrid,
    rank: usize,
    /// Dequantized weights, rows (φ, y, x) as in the package's 3D textures.
    weights: Vec<f32>,
    /// Dequantized eigenmaps, rows (θ, z).
    eigen: Vec<f32>,
    /// Boundary distance per (θ, z).
    boundary: Vec<f32>,
    margin: f32,
}

impl PackageLookup {
    /// Unpacks `package`'s factors.
    pub fn new(package: &Package) -> Self {
        let (w, e) = package.factors();
        let margin = package.manifest().gdm.accuracy.escape_margin;
        Self::from_factors(package.dims(), package.dirs(), &w, &e, margin)
    }

    /// From quantized factors as a package holds them (weight maps rows (φ, y, x), eigenmaps
    /// rows (θ, z)) and the escape margin μ.
    pub fn from_factors(
        dims: Dims,
        dirs: DirectionGrid,
        weights: &QuantizedFactor,
        eigen: &QuantizedFactor,
        margin: f32,
    ) -> Self {
        let boundary = (0..dirs.n_theta)
            .flat_map(|a| (0..dims.z).map(move |k| (a, k)))
            .map(|(a, k)| crate::gdm::boundary_distance(dims, &dirs, k, a))
            .collect();
        PackageLookup {
            dims,
            dirs,
            rank: weights.rank,
            weights: weights.dequantize(),
            eigen: eigen.dequantize(),
            boundary,
            margin,
        }
    }
}

impl GdmLookup for PackageLookup {
    fn dims(&self) -> Dims {
        self.dims
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        let (d, k) = (self.dims, self.rank);
        let q = QueryTaps::new(d, self.dirs, t, v);
        let w_taps: [(f64, usize); 8] = std::array::from_fn(|c| {
            let s = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let weight =
                q.x.weight(s[0] as u32) * q.y.weight(s[1] as u32) * q.phi.weight(s[2] as u32);
            let row = (q.phi.index[s[2]] * d.y + q.y.index[s[1]]) * d.x + q.x.index[s[0]];
            (weight, row as usize * k)
        });
        let e_taps: [(f64, usize); 4] = std::array::from_fn(|c| {
            let s = [c & 1, (c >> 1) & 1];
            let weight = q.theta.weight(s[0] as u32) * q.z.weight(s[1] as u32);
            (
                weight,
                (q.theta.index[s[0]] * d.z + q.z.index[s[1]]) as usize,
            )
        });
        let mut dist = 0.0;
        for i in 0..k {
            let w: f64 = w_taps
                .iter()
                .map(|&(c, r)| c * self.weights[r + i] as f64)
                .sum();
            let e: f64 = e_taps
                .iter()
                .map(|&(c, r)| c * self.eigen[r * k + i] as f64)
                .sum();
            dist += w * e;
        }
        let boundary: f64 = e_taps
            .iter()
            .map(|&(c, r)| c * self.boundary[r] as f64)
            .sum();
        if is_escape(dist as f32, boundary as f32, self.margin) {
            Lookup::Escape
        } else {
            Lookup::Hit(dist.max(0.0))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brick_offsets_are_distinct_and_inside_the_stride() {
        // Dimensions that are and are not multiples of the brick size.
        for [x, y, z] in [[8, 4, 4], [5, 7, 3], [1, 1, 9]] {
            let dims = Dims::new(x, y, z).unwrap();
            let layout = BrickLayout::new(dims);
            let mut seen = vec![false; layout.stride];
            for k in 0..dims.z {
                for j in 0..dims.y {
                    for i in 0..dims.x {
                        let o = layout.offset(i, j, k);
                        assert!(o < layout.stride, "{dims}: ({i}, {j}, {k}) → {o}");
                        assert!(!seen[o], "{dims}: offset {o} used twice");
                        seen[o] = true;
                    }
                }
            }
            // Padding only completes the last brick along each axis.
            let padded = |n: u32| (n as usize).div_ceil(BRICK) * BRICK;
            assert_eq!(
                layout.stride,
                padded(dims.x) * padded(dims.y) * padded(dims.z)
            );
        }
    }

    #[test]
    fn x_neighbours_share_a_brick_row_and_z_neighbours_are_one_row_group_apart() {
        let layout = BrickLayout::new(Dims::new(16, 16, 16).unwrap());
        assert_eq!(layout.offset(1, 0, 0) - layout.offset(0, 0, 0), 1);
        assert_eq!(layout.offset(0, 1, 0) - layout.offset(0, 0, 0), BRICK);
        assert_eq!(
            layout.offset(0, 0, 1) - layout.offset(0, 0, 0),
            BRICK * BRICK
        );
        // The next brick along x starts after a whole brick.
        assert_eq!(layout.offset(4, 0, 0), BRICK * BRICK * BRICK);
    }
}
