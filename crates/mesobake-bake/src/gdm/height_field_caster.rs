//! Exact ray casting against a height field: the surface z = Z·h(x/X, y/Y) over the voxel grid
//! X×Y×Z, h bilinear between pixel centres and periodic ([`HeightField::sample`]), solid
//! below it down to the floor z = 0 (where a height of 0 lies). The ray is followed cell by
//! cell of the bilinear patches (a 2D DDA between pixel centres); within a cell the height
//! along the ray is a quadratic in the ray parameter and the ray's z is linear, so the first
//! crossing is a root of a quadratic, solved in closed form. This is the geometry a VDM is
//! baked from, so the ground truth of a height-field scene renders exactly what the VDM
//! approximates.

use super::caster::{Caster, Trace};
use crate::mesostructure::height_field::HeightField;
use crate::mesostructure::volume::Occupancy;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;

/// Cells a ray may cross before it is reported as escaping (only horizontal rays, which never
/// leave through z = 0 or z = Z, come near it).
const MAX_CELLS: u64 = 1 << 22;

/// A height field ready for ray casting on a voxel grid.
pub struct HeightFieldCaster {
    field: HeightField,
    dims: Dims,
    centres: Occupancy,
}

impl HeightFieldCaster {
    /// The caster of `field` on grid `dims`. Its sample centres inside solid are those of
    /// the volume under the field ([`HeightField::to_volume`], whose bottom layer is solid so
    /// that voxel codecs keep the floor).
    pub fn new(field: HeightField, dims: Dims, limits: &Limits) -> Result<Self> {
        let centres = field.to_volume(dims, limits)?.occupancy();
        Ok(HeightFieldCaster {
            field,
            dims,
            centres,
        })
    }

    /// The height field.
    pub fn field(&self) -> &HeightField {
        &self.field
    }

    /// Surface height (voxels) at voxel coordinates (x, y).
    fn surface(&self, x: f64, y: f64) -> f64 {
        let d = self.dims;
        self.field.sample(x / f64::from(d.x), y / f64::from(d.y)) * f64::from(d.z)
    }

    /// The pixel value at (i, j), wrapped, in voxels of height.
    fn corner(&self, i: i64, j: i64) -> f64 {
        let (w, h) = self.field.size();
        let (i, j) = (i.rem_euclid(i64::from(w)), j.rem_euclid(i64::from(h)));
        f64::from(self.field.heights()[(j * i64::from(w) + i) as usize]) * f64::from(self.dims.z)
    }

    /// The first t in [t0, t1] where the ray (z(t) = z0 + t·vz) meets the bilinear patch of
    /// cell (i, j), the ray's pixel-grid coordinates being (gx0 + t·gx, gy0 + t·gy).
    #[allow(clippy::too_many_arguments)]
    fn cell_hit(
        &self,
        (i, j): (i64, i64),
        (gx0, gx): (f64, f64),
        (gy0, gy): (f64, f64),
        (z0, vz): (f64, f64),
        t0: f64,
        t1: f64,
    ) -> Option<f64> {
        let (h00, h10, h01, h11) = (
            self.corner(i, j),
            self.corner(i + 1, j),
            self.corner(i, j + 1),
            self.corner(i + 1, j + 1),
        );
        // Local coordinates fx = a + b·t, fy = c + d·t; g(t) = height − z(t), a hit where
        // g ≥ 0: g = q2·t² + q1·t + q0.
        let (a, b, c, d) = (gx0 - i as f64, gx, gy0 - j as f64, gy);
        let (ex, ey, exy) = (h10 - h00, h01 - h00, h00 - h10 - h01 + h11);
        let q2 = exy * b * d;
        let q1 = ex * b + ey * d + exy * (a * d + b * c) - vz;
        let q0 = h00 + ex * a + ey * c + exy * a * c - z0;
        let g = |t: f64| (q2 * t + q1) * t + q0;
        if g(t0) >= 0.0 {
            return Some(t0);
        }
        let mut roots = [f64::INFINITY; 2];
        if q2.abs() > 1e-300 {
            let disc = q1 * q1 - 4.0 * q2 * q0;
            if disc >= 0.0 {
                // The numerically stable pair of roots.
                let s = -0.5 * (q1 + q1.signum() * disc.sqrt());
                roots = [s / q2, if s != 0.0 { q0 / s } else { f64::INFINITY }];
            }
        } else if q1 != 0.0 {
            roots[0] = -q0 / q1;
        }
        roots
            .into_iter()
            .filter(|&t| t >= t0 && t <= t1)
            .min_by(f64::total_cmp)
            .or_else(|| (g(t1) >= 0.0).then_some(t1))
    }
}

impl Caster for HeightFieldCaster {
    fn dims(&self) -> Dims {
        self.dims
    }

    fn centres_inside(&self) -> &Occupancy {
        &self.centres
    }

    fn trace(&self, origin: [f64; 3], dir: [f64; 3], max_t: f64) -> Trace {
        let d = self.dims;
        let (w, h) = self.field.size();
        let [x0, y0, z0] = origin;
        if z0 <= self.surface(x0, y0) || z0 <= 0.0 {
            return Trace::Inside;
        }
        // Where the ray leaves the slab: through the top (an escape) or onto the floor.
        let (t_top, t_floor) = if dir[2] > 0.0 {
            ((f64::from(d.z) - z0) / dir[2], f64::INFINITY)
        } else if dir[2] < 0.0 {
            (f64::INFINITY, -z0 / dir[2])
        } else {
            (f64::INFINITY, f64::INFINITY)
        };
        // A chord that ends on the floor (the shell's base, up to rounding) meets it.
        let floor_reached = t_floor.is_finite() && t_floor <= max_t + 1e-9 * (1.0 + max_t);
        let end = if floor_reached {
            t_floor
        } else {
            t_top.min(max_t)
        };
        // Pixel-grid coordinates: pixel centres at integers.
        let (sx, sy) = (f64::from(w) / f64::from(d.x), f64::from(h) / f64::from(d.y));
        let (gx0, gy0) = (x0 * sx - 0.5, y0 * sy - 0.5);
        let (gx, gy) = (dir[0] * sx, dir[1] * sy);
        let mut cell = (gx0.floor() as i64, gy0.floor() as i64);
        let step = |v: f64| if v > 0.0 { 1 } else { -1 };
        let next = |g0: f64, g: f64, c: i64| {
            if g == 0.0 {
                f64::INFINITY
            } else {
                ((c + i64::from(g > 0.0)) as f64 - g0) / g
            }
        };
        let mut t = 0.0;
        for _ in 0..MAX_CELLS {
            let (tx, ty) = (next(gx0, gx, cell.0), next(gy0, gy, cell.1));
            let t1 = tx.min(ty).min(end);
            if let Some(hit) = self.cell_hit(cell, (gx0, gx), (gy0, gy), (z0, dir[2]), t, t1) {
                return Trace::Hit(hit);
            }
            if t1 >= end {
                return if floor_reached {
                    Trace::Hit(t_floor)
                } else if end == t_top {
                    Trace::Escape(t_top)
                } else {
                    Trace::Limit
                };
            }
            t = t1;
            if tx <= ty {
                cell.0 += step(gx);
            }
            if ty <= tx {
                cell.1 += step(gy);
            }
        }
        Trace::Escape(f64::INFINITY)
    }
}
