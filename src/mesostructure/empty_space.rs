//! Empty-space distances for skipping during voxel traversal.
//!
//! For every voxel, the Chebyshev (L∞) distance in voxels to the nearest solid voxel, periodic
//! in x and y, with the layers outside 0..Z counted as empty. A value r ≥ 1 means every voxel
//! within r−1 of it along each axis is empty, so a ray can cross that whole box in one step
//! without missing anything: skipping stays exact.

use crate::grid::Wrap;
use crate::mesostructure::volume::Occupancy;

/// Distances saturate at this value (meaning "at least this far").
pub const MAX_DISTANCE: u8 = u8::MAX;

/// Per-voxel Chebyshev distance to the nearest solid voxel (0 for solid voxels).
#[derive(Clone, Debug)]
pub struct EmptySpace {
    wrap: [Wrap; 2],
    nx: i64,
    ny: i64,
    distance: Vec<u8>,
}

impl EmptySpace {
    /// Computes the distances with three separable passes (x, y, z): after the x pass a voxel
    /// holds the distance along its row; the y and z passes take min over the line of
    /// max(|offset|, previous), which is the L∞ distance.
    pub fn new(occ: &Occupancy) -> Self {
        let dims = occ.dims();
        let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
        let cap = MAX_DISTANCE as u32;
        let mut dist = vec![cap; nx * ny * nz];

        // x pass: periodic 1D distance to the nearest solid voxel in the row.
        let mut row = vec![cap; nx];
        for k in 0..nz {
            for j in 0..ny {
                for (i, r) in row.iter_mut().enumerate() {
                    *r = if occ.get(i as u32, j as u32, k as u32) {
                        0
                    } else {
                        cap
                    };
                }
                let out = &mut dist[(k * ny + j) * nx..][..nx];
                min_max_pass(&row, out, true);
            }
        }
        // y pass (periodic), then z pass (not periodic: outside the volume nothing is solid).
        pass_along_lines(
            &mut dist,
            ny,
            nx,
            (0..nz).flat_map(|k| (0..nx).map(move |i| k * ny * nx + i)),
            true,
        );
        pass_along_lines(&mut dist, nz, nx * ny, 0..nx * ny, false);
        EmptySpace {
            wrap: [Wrap::new(dims.x), Wrap::new(dims.y)],
            nx: nx as i64,
            ny: ny as i64,
            distance: dist.into_iter().map(|d| d.min(cap) as u8).collect(),
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

/// Runs [`min_max_pass`] along every line of `len` values `step` apart starting at `starts`.
fn pass_along_lines(
    dist: &mut [u32],
    len: usize,
    step: usize,
    starts: impl Iterator<Item = usize>,
    periodic: bool,
) {
    let mut line = vec![0; len];
    let mut res = vec![0; len];
    for start in starts {
        for (n, l) in line.iter_mut().enumerate() {
            *l = dist[start + n * step];
        }
        min_max_pass(&line, &mut res, periodic);
        for (n, r) in res.iter().enumerate() {
            dist[start + n * step] = *r;
        }
    }
}

/// out[c] = min over offsets o of max(|o|, f[c+o]), capped at [`MAX_DISTANCE`]; indices wrap
/// when `periodic`, otherwise lie inside the line.
fn min_max_pass(f: &[u32], out: &mut [u32], periodic: bool) {
    let n = f.len() as i64;
    let reach = if periodic { n / 2 + 1 } else { n };
    for c in 0..n {
        let mut best = f[c as usize];
        let mut o = 1;
        while o < best as i64 && o <= reach {
            for p in [c - o, c + o] {
                let idx = if periodic {
                    p.rem_euclid(n)
                } else if (0..n).contains(&p) {
                    p
                } else {
                    continue;
                };
                best = best.min((o as u32).max(f[idx as usize]));
            }
            o += 1;
        }
        out[c as usize] = best;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Dims;

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
