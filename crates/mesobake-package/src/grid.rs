//! The sampling grids of a bake: voxel resolution (x, y, z) and direction grid (θ, φ).
//!
//! Conventions (shared by every bake path and by the `.npy` export):
//! - sample (i, j, k) sits at the voxel centre (i+½, j+½, k+½), in voxel units (edge = 1);
//! - direction (a, b) is θ = (a+½)·π/Nθ, φ = (b+½)·2π/Nφ, v = (sinθ cosφ, sinθ sinφ, cosθ),
//!   with z pointing out of the surface. Samples sit at bin centres, so no direction is a pole;
//!   Nθ is even, so none is horizontal (cos θ ≠ 0); with even Nφ none is axis-aligned in x/y.

use crate::error::{Error, Result};
use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

/// Largest accepted size along any axis of a grid.
pub const MAX_AXIS: u32 = 1 << 16;

/// A voxel resolution X×Y×Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Dims {
    /// Voxels along x (tiles periodically).
    pub x: u32,
    /// Voxels along y (tiles periodically).
    pub y: u32,
    /// Voxels along z, from the base surface (k = 0) to the outer shell.
    pub z: u32,
}

impl Dims {
    /// A validated resolution: every axis in 1..=[`MAX_AXIS`].
    pub fn new(x: u32, y: u32, z: u32) -> Result<Self> {
        for (name, n) in [("x", x), ("y", y), ("z", z)] {
            if n == 0 || n > MAX_AXIS {
                return Err(Error::InvalidParameter(format!(
                    "resolution {x}x{y}x{z}: {name} must be in 1..={MAX_AXIS}"
                )));
            }
        }
        Ok(Dims { x, y, z })
    }

    /// Number of voxels, X·Y·Z (cannot overflow u64 given [`MAX_AXIS`]).
    pub fn voxel_count(&self) -> u64 {
        self.x as u64 * self.y as u64 * self.z as u64
    }

    /// Linear index of voxel (i, j, k), x fastest.
    #[inline]
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        (i as usize) + self.x as usize * (j as usize + self.y as usize * k as usize)
    }
}

impl fmt::Display for Dims {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}x{}", self.x, self.y, self.z)
    }
}

impl FromStr for Dims {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let parts = parse_axes(s, 3, "resolution (e.g. 64x64x32)")?;
        Dims::new(parts[0], parts[1], parts[2])
    }
}

/// The direction grid Nθ × Nφ.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DirectionGrid {
    /// Polar samples over θ ∈ (0, π).
    pub n_theta: u32,
    /// Azimuthal samples over φ ∈ (0, 2π).
    pub n_phi: u32,
}

/// Largest accepted direction count along θ or φ.
pub const MAX_DIRECTIONS_PER_AXIS: u32 = 4096;

impl DirectionGrid {
    /// The paper's grid: 16 θ × 32 φ.
    pub const PAPER: DirectionGrid = DirectionGrid {
        n_theta: 16,
        n_phi: 32,
    };

    /// A validated grid: both counts in 1..=[`MAX_DIRECTIONS_PER_AXIS`], Nθ even (an odd Nθ
    /// puts a bin centre at θ = π/2, a ray parallel to the surface that never leaves the
    /// tiled volume).
    pub fn new(n_theta: u32, n_phi: u32) -> Result<Self> {
        if n_theta % 2 == 1 {
            return Err(Error::InvalidParameter(format!(
                "direction grid {n_theta}x{n_phi}: the θ count must be even, or one bin \
                 would be parallel to the surface"
            )));
        }
        for (name, n) in [("θ", n_theta), ("φ", n_phi)] {
            if n == 0 || n > MAX_DIRECTIONS_PER_AXIS {
                return Err(Error::InvalidParameter(format!(
                    "direction grid {n_theta}x{n_phi}: {name} count must be in 1..={MAX_DIRECTIONS_PER_AXIS}"
                )));
            }
        }
        Ok(DirectionGrid { n_theta, n_phi })
    }

    /// Number of directions Nθ·Nφ.
    pub fn count(&self) -> usize {
        self.n_theta as usize * self.n_phi as usize
    }

    /// Polar angle of θ-bin `a`: (a+½)·π/Nθ.
    pub fn theta(&self, a: u32) -> f64 {
        (a as f64 + 0.5) * PI / self.n_theta as f64
    }

    /// Azimuth of φ-bin `b`: (b+½)·2π/Nφ.
    pub fn phi(&self, b: u32) -> f64 {
        (b as f64 + 0.5) * 2.0 * PI / self.n_phi as f64
    }

    /// Unit vector of direction (a, b).
    pub fn vector(&self, a: u32, b: u32) -> [f64; 3] {
        spherical_to_vector(self.theta(a), self.phi(b))
    }

    /// Unit vector of the flat direction index `d = a·Nφ + b`.
    pub fn vector_of(&self, d: usize) -> [f64; 3] {
        let a = (d / self.n_phi as usize) as u32;
        let b = (d % self.n_phi as usize) as u32;
        self.vector(a, b)
    }
}

/// The eight voxels whose centres surround texture point `t` (voxel units) and their
/// trilinear weights (summing to 1): x and y periodic, z clamped into the grid.
pub fn trilinear_corners(dims: Dims, t: [f64; 3]) -> [([u32; 3], f64); 8] {
    let f = [
        t[0] - 0.5,
        t[1] - 0.5,
        (t[2] - 0.5).clamp(0.0, (dims.z - 1) as f64),
    ];
    let base = f.map(f64::floor);
    let frac = [f[0] - base[0], f[1] - base[1], f[2] - base[2]];
    let (wx, wy) = (Wrap::new(dims.x), Wrap::new(dims.y));
    std::array::from_fn(|c| {
        let d = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        let w: f64 = (0..3)
            .map(|a| if d[a] == 1 { frac[a] } else { 1.0 - frac[a] })
            .product();
        let i = wx.apply(base[0] as i64 + d[0] as i64) as u32;
        let j = wy.apply(base[1] as i64 + d[1] as i64) as u32;
        let k = (base[2] as u32 + d[2] as u32).min(dims.z - 1);
        ([i, j, k], w)
    })
}

/// The four direction bins whose centres surround unit vector `v` and their bilinear weights
/// (summing to 1): θ clamped to the first and last bins, φ periodic. Bins as (a, b).
pub fn bilinear_direction_corners(dirs: DirectionGrid, v: [f64; 3]) -> [([u32; 2], f64); 4] {
    let theta = v[2].clamp(-1.0, 1.0).acos();
    let phi = v[1].atan2(v[0]).rem_euclid(std::f64::consts::TAU);
    let ft = (theta / std::f64::consts::PI * dirs.n_theta as f64 - 0.5)
        .clamp(0.0, (dirs.n_theta - 1) as f64);
    let fp = phi / std::f64::consts::TAU * dirs.n_phi as f64 - 0.5;
    let (bt, bp) = (ft.floor(), fp.floor());
    let (tt, tp) = (ft - bt, fp - bp);
    let wrap = Wrap::new(dirs.n_phi);
    std::array::from_fn(|c| {
        let (da, db) = (c & 1, c >> 1);
        let w = if da == 1 { tt } else { 1.0 - tt } * if db == 1 { tp } else { 1.0 - tp };
        let a = (bt as u32 + da as u32).min(dirs.n_theta - 1);
        let b = wrap.apply(bp as i64 + db as i64) as u32;
        ([a, b], w)
    })
}

/// Distance from the centre of layer `k` to the top (cos θ > 0) or bottom plane along
/// θ-bin `a`: what a ray that escapes travels inside the volume.
pub fn boundary_distance(dims: Dims, dirs: &DirectionGrid, k: u32, a: u32) -> f32 {
    let cos_theta = dirs.theta(a).cos();
    let z = k as f64 + 0.5;
    let d = if cos_theta > 0.0 {
        (dims.z as f64 - z) / cos_theta
    } else {
        -z / cos_theta
    };
    d as f32
}

/// v = (sinθ cosφ, sinθ sinφ, cosθ).
pub fn spherical_to_vector(theta: f64, phi: f64) -> [f64; 3] {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    [st * cp, st * sp, ct]
}

impl fmt::Display for DirectionGrid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.n_theta, self.n_phi)
    }
}

impl FromStr for DirectionGrid {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let parts = parse_axes(s, 2, "direction grid (e.g. 16x32)")?;
        DirectionGrid::new(parts[0], parts[1])
    }
}

fn parse_axes(s: &str, n: usize, what: &str) -> Result<Vec<u32>> {
    let parts: Vec<&str> = s.split(['x', 'X', '×']).collect();
    if parts.len() != n {
        return Err(Error::InvalidParameter(format!(
            "{s:?} is not a {what}: expected {n} numbers separated by 'x'"
        )));
    }
    parts
        .iter()
        .map(|p| {
            p.trim().parse::<u32>().map_err(|_| {
                Error::InvalidParameter(format!("{s:?} is not a {what}: {p:?} is not a count"))
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_validates() {
        assert_eq!(
            "64x64x32".parse::<Dims>().unwrap(),
            Dims::new(64, 64, 32).unwrap()
        );
        assert!("64x0x32".parse::<Dims>().is_err());
        assert!("64x64".parse::<Dims>().is_err());
        assert!("64xax32".parse::<Dims>().is_err());
        assert!("100000x1x1".parse::<Dims>().is_err());
        assert_eq!(
            "16x32".parse::<DirectionGrid>().unwrap(),
            DirectionGrid::PAPER
        );
        assert!("0x32".parse::<DirectionGrid>().is_err());
        assert!(
            "3x4"
                .parse::<DirectionGrid>()
                .unwrap_err()
                .to_string()
                .contains("even")
        );
    }

    #[test]
    fn directions_are_unit_and_at_bin_centres() {
        let g = DirectionGrid::PAPER;
        for d in 0..g.count() {
            let v = g.vector_of(d);
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((n - 1.0).abs() < 1e-12);
            assert!(v[2] != 0.0, "no horizontal direction on the grid");
        }
        assert!((g.theta(0) - PI / 32.0).abs() < 1e-15);
        assert!((g.phi(31) - (31.5 / 32.0) * 2.0 * PI).abs() < 1e-12);
    }
}

/// Wraps unbounded integer coordinates onto a periodic axis of length n, with a mask when n is a
/// power of two (the common case) and a Euclidean remainder otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wrap {
    n: i64,
    mask: i64,
}

impl Wrap {
    /// Wrapping onto 0..n (n ≥ 1).
    pub fn new(n: u32) -> Self {
        let n = n as i64;
        let mask = if n.count_ones() == 1 { n - 1 } else { -1 };
        Wrap { n, mask }
    }

    /// i mod n, in 0..n.
    #[inline(always)]
    pub fn apply(&self, i: i64) -> usize {
        if self.mask >= 0 {
            (i & self.mask) as usize
        } else {
            i.rem_euclid(self.n) as usize
        }
    }
}
