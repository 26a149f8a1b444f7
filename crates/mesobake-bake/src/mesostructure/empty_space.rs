//! Empty-space distances for skipping during voxel traversal.
//!
//! For every voxel, the Chebyshev (L∞) distance in voxels to the nearest solid voxel, periodic
//! in x and y, with the layers outside 0..Z counted as empty. A value r ≥ 1 means every voxel
//! within r−1 of it along each axis is empty, so a ray can cross that whole box in one step
//! without missing anything: skipping stays exact.

use crate::mesostructure::volume::Occupancy;
use mesobake_package::grid::Wrap;
pub use mesobake_package::occupancy::MAX_DISTANCE;
use mesobake_package::occupancy::chebyshev_distances;

/// Per-voxel Chebyshev distance to the nearest solid voxel (0 for solid voxels).
#[derive(Clone, Debug)]
pub struct EmptySpace {
    wrap: [Wrap; 2],
    nx: i64,
    ny: i64,
    distance: Vec<u8>,
}

impl EmptySpace {
    /// Computes the distances ([`chebyshev_distances`], shared with the package format's
    /// occupancy codec).
    pub fn new(occ: &Occupancy) -> Self {
        let dims = occ.dims();
        EmptySpace {
            wrap: [Wrap::new(dims.x), Wrap::new(dims.y)],
            nx: dims.x as i64,
            ny: dims.y as i64,
            distance: chebyshev_distances(dims, |i, j, k| occ.get(i, j, k)),
        }
    }

    /// Every voxel's distance, x fastest, then y, then z.
    pub fn distances(&self) -> &[u8] {
        &self.distance
    }

    /// Distance at voxel (i, j, k) with i, j wrapped and 0 ≤ k < Z.
    #[inline]
    pub fn get(&self, i: i64, j: i64, k: i64) -> u8 {
        let i = self.wrap[0].apply(i) as i64;
        let j = self.wrap[1].apply(j) as i64;
        self.distance[((k * self.ny + j) * self.nx + i) as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesobake_package::grid::Dims;

    /// Brute force over all solid voxels, against the separable passes, exactly.
    #[test]
    fn matches_brute_force() {
        let dims = Dims::new(9, 7, 5).unwrap();
        let mut occ = Occupancy::empty(dims);
        for &(i, j, k) in &[(0u32, 0u32, 0u32), (8, 3, 4), (4, 6, 2)] {
            occ.set(i, j, k);
        }
        let es = EmptySpace::new(&occ);
        for k in 0..5i64 {
            for j in 0..7i64 {
                for i in 0..9i64 {
                    let mut best = MAX_DISTANCE as i64;
                    for &(si, sj, sk) in &[(0i64, 0i64, 0i64), (8, 3, 4), (4, 6, 2)] {
                        let di = (i - si).rem_euclid(9).min((si - i).rem_euclid(9));
                        let dj = (j - sj).rem_euclid(7).min((sj - j).rem_euclid(7));
                        let dk = (k - sk).abs();
                        best = best.min(di.max(dj).max(dk));
                    }
                    assert_eq!(es.get(i, j, k) as i64, best, "voxel {i},{j},{k}");
                }
            }
        }
    }
}
