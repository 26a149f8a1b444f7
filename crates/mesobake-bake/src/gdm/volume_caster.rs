//! Exact ray casting through a periodic voxel grid: a 3D DDA over closed voxel boxes with
//! exact empty-space skipping.
//!
//! Semantics: solid voxels are closed boxes, so a ray that only touches a solid voxel along an
//! edge or at a corner hits it there, and a point on a solid face is inside. Every event time
//! is a plane crossing computed as `(plane − o) · (1/v)`, so rays that cross several planes at
//! once (exactly through an edge or corner) see equal times and check every voxel touching the
//! crossing point.

use super::caster::{Caster, Trace};
use crate::mesostructure::empty_space::EmptySpace;
use crate::mesostructure::volume::{Occupancy, Volume};
use mesobake_package::grid::Dims;

/// Horizontal rays (v_z = 0) never leave the volume; they are followed for at most this many
/// tile periods before being reported as escaping. Grid directions are never horizontal.
const HORIZONTAL_PERIODS: f64 = 64.0;

/// A voxel volume ready for ray casting.
pub struct VolumeCaster {
    occ: Occupancy,
    space: Option<EmptySpace>,
    /// Lowest and highest solid layers.
    solid_layers: Option<(i64, i64)>,
}

impl VolumeCaster {
    /// A caster with exact empty-space skipping.
    pub fn new(volume: &Volume) -> Self {
        Self::from_occupancy(volume.occupancy(), true)
    }

    /// A caster over an occupancy grid; `skip_empty_space` false gives the plain one-voxel-
    /// at-a-time DDA, the baseline the skipping traversal is measured and tested against.
    pub fn from_occupancy(occ: Occupancy, skip_empty_space: bool) -> Self {
        let space = skip_empty_space.then(|| EmptySpace::new(&occ));
        let solid_layers = occ.solid_layer_range().map(|(a, b)| (a as i64, b as i64));
        VolumeCaster {
            occ,
            space,
            solid_layers,
        }
    }

    /// Whether any voxel touching a crossing point is solid: for each axis the entered voxel
    /// and, where the point lies on a plane (an exit axis of several, a tie, or a ray stuck
    /// in a plane, whose two voxels `stuck_lo..=stuck_hi` never change), the one behind it.
    #[cold]
    #[allow(clippy::too_many_arguments)]
    fn touches_at_crossing(
        &self,
        cell: [i64; 3],
        v: [f64; 3],
        exit_axes: u8,
        ties: u8,
        stuck: &[bool; 3],
        stuck_lo: &[i64; 3],
        stuck_hi: &[i64; 3],
    ) -> bool {
        let several = exit_axes.count_ones() > 1;
        let mut lo = cell;
        let mut hi = cell;
        for a in 0..3 {
            let on_plane = (several && exit_axes & (1 << a) != 0) || ties & (1 << a) != 0;
            if stuck[a] {
                lo[a] = stuck_lo[a];
                hi[a] = stuck_hi[a];
            } else if on_plane {
                let behind = cell[a] - v[a].signum() as i64;
                lo[a] = cell[a].min(behind);
                hi[a] = cell[a].max(behind);
            }
        }
        self.touches_solid(lo, hi)
    }

    fn touches_solid(&self, lo: [i64; 3], hi: [i64; 3]) -> bool {
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    if self.occ.get_periodic(i, j, k) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

impl Caster for VolumeCaster {
    fn dims(&self) -> Dims {
        self.occ.dims()
    }

    fn centres_inside(&self) -> &Occupancy {
        &self.occ
    }

    fn is_voxel_grid(&self) -> bool {
        true
    }

    fn bake_direction(&self, dir: [f64; 3], volume: &mut [f32]) -> bool {
        let supported = super::template::supports(self.occ.dims());
        if supported {
            super::template::bake_direction(&self.occ, dir, volume);
        }
        supported
    }

    fn trace(&self, o: [f64; 3], v: [f64; 3], max_t: f64) -> Trace {
        let dims = self.occ.dims();
        let nz = dims.z as i64;
        let top = dims.z as f64;
        let inv = [1.0 / v[0], 1.0 / v[1], 1.0 / v[2]];

        // Voxels touching the origin, and the voxel the ray enters.
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        let mut cell = [0i64; 3];
        let mut stuck = [false; 3];
        for a in 0..3 {
            let f = o[a].floor();
            let fi = f as i64;
            let on_plane = o[a] == f;
            lo[a] = if on_plane { fi - 1 } else { fi };
            hi[a] = fi;
            cell[a] = if on_plane && v[a] < 0.0 { fi - 1 } else { fi };
            stuck[a] = on_plane && v[a] == 0.0;
        }
        // A ray gliding along the top plane stays in the top layer for the escape checks.
        if stuck[2] {
            cell[2] = cell[2].min(nz - 1);
        }
        if self.touches_solid(lo, hi) {
            return Trace::Inside;
        }
        let limit = if v[2] == 0.0 {
            max_t.min(HORIZONTAL_PERIODS * (dims.x + dims.y) as f64 * (dims.x.max(dims.y)) as f64)
        } else {
            max_t
        };
        let any_stuck = stuck.iter().any(|&s| s);

        loop {
            if cell[2] < 0 || cell[2] >= nz {
                let plane = if v[2] > 0.0 { top } else { 0.0 };
                return Trace::Escape((plane - o[2]) * inv[2]);
            }
            // Above the highest (or below the lowest) solid layer and moving away: escape.
            let away = match self.solid_layers {
                None => v[2] != 0.0,
                Some((zlo, zhi)) => (v[2] > 0.0 && cell[2] > zhi) || (v[2] < 0.0 && cell[2] < zlo),
            };
            if away {
                let plane = if v[2] > 0.0 { top } else { 0.0 };
                return Trace::Escape((plane - o[2]) * inv[2]);
            }
            let r = match &self.space {
                Some(space) if !any_stuck => space.get(cell[0], cell[1], cell[2]).max(1) as i64,
                _ => 1,
            };

            // Leave the empty box of voxels within r−1 of `cell`.
            let mut t_exit = f64::INFINITY;
            let mut exit_axes = 0u8;
            for a in 0..3 {
                if v[a] == 0.0 {
                    continue;
                }
                let mut plane = if v[a] > 0.0 {
                    cell[a] + r
                } else {
                    cell[a] - r + 1
                };
                if a == 2 {
                    plane = plane.clamp(0, nz);
                }
                let t = (plane as f64 - o[a]) * inv[a];
                if t < t_exit {
                    t_exit = t;
                    exit_axes = 1 << a;
                } else if t == t_exit {
                    exit_axes |= 1 << a;
                }
            }
            if t_exit > limit {
                return if limit < max_t {
                    Trace::Escape(f64::INFINITY)
                } else {
                    Trace::Limit
                };
            }

            // The voxel entered next; `ties` marks axes where the crossing point lies on a
            // voxel plane, so that voxels on both sides touch it.
            let mut ties = 0u8;
            for a in 0..3 {
                if exit_axes & (1 << a) != 0 {
                    cell[a] = if v[a] > 0.0 { cell[a] + r } else { cell[a] - r };
                } else if r > 1 && v[a] != 0.0 && !stuck[a] {
                    let p = o[a] + t_exit * v[a];
                    let f = (p.floor() as i64).clamp(cell[a] - r + 1, cell[a] + r - 1);
                    if p == f as f64 && f > cell[a] - r + 1 {
                        ties |= 1 << a;
                        cell[a] = if v[a] > 0.0 { f } else { f - 1 };
                    } else {
                        cell[a] = f;
                    }
                }
            }
            let hit = if exit_axes.count_ones() == 1 && ties == 0 && !any_stuck {
                // The common case: one face crossed; the voxel behind it is in the empty box.
                self.occ.get_periodic(cell[0], cell[1], cell[2])
            } else {
                self.touches_at_crossing(cell, v, exit_axes, ties, &stuck, &lo, &hi)
            };
            if hit {
                return Trace::Hit(t_exit);
            }
        }
    }
}
