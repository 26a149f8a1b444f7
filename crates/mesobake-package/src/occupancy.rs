//! The occupancy codec: instead of a table of distances, the mesostructure itself — one byte
//! per voxel holding 0 for a solid voxel and otherwise the Chebyshev (L∞) distance in voxels
//! to the nearest solid voxel, periodic in x and y, with the layers outside 0..Z counted as
//! empty, saturating at [`MAX_DISTANCE`]. Renderers ray-march along each query, skipping a
//! voxel's distance minus one in every axis at once without missing anything, so the answers
//! are the exact GDM of the voxel grid at any position and direction.

use crate::error::{Error, Result};
use crate::grid::Dims;

/// Distances saturate at this value (meaning "at least this far").
pub const MAX_DISTANCE: u8 = u8::MAX;

/// A voxel grid's occupancy with its empty-space distances, as a package stores them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OccupancyField {
    dims: Dims,
    /// Per voxel (x fastest, then y, then z): 0 solid, else the distance to solid.
    distance: Vec<u8>,
}

impl OccupancyField {
    /// Encodes the grid `dims` whose solid voxels are those where `solid(i, j, k)` holds.
    pub fn from_solid(dims: Dims, solid: impl Fn(u32, u32, u32) -> bool) -> Self {
        OccupancyField {
            dims,
            distance: chebyshev_distances(dims, solid),
        }
    }

    /// Decodes and validates stored bytes: one per voxel of `dims`, and every distance the
    /// one its solid voxels (the zeros) imply, so that a march skipping by them is exact.
    pub fn from_bytes(dims: Dims, bytes: &[u8]) -> Result<Self> {
        if bytes.len() as u64 != dims.voxel_count() {
            return Err(Error::Package(format!(
                "the occupancy field holds {} bytes, not one per voxel of {dims} ({})",
                bytes.len(),
                dims.voxel_count()
            )));
        }
        let field = OccupancyField::from_solid(dims, |i, j, k| bytes[dims.index(i, j, k)] == 0);
        if field.distance != bytes {
            let voxel = bytes.iter().zip(&field.distance).position(|(a, b)| a != b);
            return Err(Error::Package(format!(
                "the occupancy field's distance at voxel {} is {}, but its solid voxels give {}",
                voxel.unwrap_or(0),
                voxel.map_or(0, |v| bytes[v]),
                voxel.map_or(0, |v| field.distance[v])
            )));
        }
        Ok(field)
    }

    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// The stored bytes: one per voxel, x fastest.
    pub fn bytes(&self) -> &[u8] {
        &self.distance
    }

    /// Whether voxel (i, j, k) is solid.
    pub fn is_solid(&self, i: u32, j: u32, k: u32) -> bool {
        self.distance[self.dims.index(i, j, k)] == 0
    }

    /// Solid voxels.
    pub fn solid_voxels(&self) -> u64 {
        self.distance.iter().filter(|&&d| d == 0).count() as u64
    }

    /// The distance from point `p` (voxel units, 0 ≤ z < Z) along unit direction `v` to the
    /// first solid voxel: 0 when `p` is in one, `None` when the ray leaves through the top or
    /// bottom plane first or `v` has no z component. A plain voxel-by-voxel traversal
    /// (Amanatides–Woo), periodic in x and y: the exact GDM of the voxel grid.
    pub fn march(&self, p: [f64; 3], v: [f64; 3]) -> Option<f64> {
        let dims = [self.dims.x as i64, self.dims.y as i64, self.dims.z as i64];
        if v[2] == 0.0
            || p.iter().chain(&v).any(|c| !c.is_finite())
            || !(0.0..dims[2] as f64).contains(&p[2])
        {
            return None;
        }
        let mut cell = p.map(|c| c.floor() as i64);
        let solid = |c: [i64; 3]| {
            let (i, j) = (c[0].rem_euclid(dims[0]), c[1].rem_euclid(dims[1]));
            self.is_solid(i as u32, j as u32, c[2] as u32)
        };
        if solid(cell) {
            return Some(0.0);
        }
        let step = v.map(|c| c.signum() as i64);
        let delta = v.map(|c| 1.0 / c.abs());
        let mut next: [f64; 3] = std::array::from_fn(|a| match v[a] {
            c if c > 0.0 => (cell[a] as f64 + 1.0 - p[a]) / c,
            c if c < 0.0 => (cell[a] as f64 - p[a]) / c,
            _ => f64::INFINITY,
        });
        loop {
            let axis = (0..3)
                .min_by(|&a, &b| next[a].total_cmp(&next[b]))
                .expect("3 axes");
            let t = next[axis];
            cell[axis] += step[axis];
            next[axis] += delta[axis];
            if !(0..dims[2]).contains(&cell[2]) {
                return None;
            }
            if solid(cell) {
                return Some(t);
            }
        }
    }
}

/// Every voxel's Chebyshev distance to the nearest voxel where `solid` holds (x fastest, then
/// y, then z), by three separable passes: after the x pass a voxel holds the distance along
/// its row; the y and z passes take the minimum over the line of max(|offset|, previous),
/// which is the L∞ distance.
pub fn chebyshev_distances(dims: Dims, solid: impl Fn(u32, u32, u32) -> bool) -> Vec<u8> {
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let cap = MAX_DISTANCE as u32;
    let mut dist = vec![cap; nx * ny * nz];
    // x pass: periodic 1D distance to the nearest solid voxel in the row.
    let mut row = vec![cap; nx];
    for k in 0..nz {
        for j in 0..ny {
            for (i, r) in row.iter_mut().enumerate() {
                *r = if solid(i as u32, j as u32, k as u32) {
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
    dist.into_iter().map(|d| d.min(cap) as u8).collect()
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

/// out[c] = min over positions p of the line of max(distance(c, p), f[p]), the distance
/// periodic (the shorter way round) when `periodic`. Every f is at most [`MAX_DISTANCE`], so
/// out is too (p = c). Linear time: the lower envelope of the "cones" max(|x − p|, f[p]) of
/// Meijster, Roerdink and Hesselink's distance transform for the chessboard metric (2000); a
/// periodic line is unrolled three times and its middle copy kept.
fn min_max_pass(f: &[u32], out: &mut [u32], periodic: bool) {
    let n = f.len();
    if !periodic {
        lower_envelope(f, out);
        return;
    }
    let tripled: Vec<u32> = f.iter().chain(f).chain(f).copied().collect();
    let mut all = vec![0; 3 * n];
    lower_envelope(&tripled, &mut all);
    out.copy_from_slice(&all[n..2 * n]);
}

/// out[x] = min over i of max(|x − i|, g[i]) on a line that does not wrap, by the lower
/// envelope of those functions (Meijster et al.'s second phase with the chessboard `Sep`).
fn lower_envelope(g: &[u32], out: &mut [u32]) {
    let m = g.len() as i64;
    let g = |i: i64| i64::from(g[i as usize]);
    let f = |x: i64, i: i64| (x - i).abs().max(g(i));
    // The last x at which cone i is at most cone u (i < u).
    let sep = |i: i64, u: i64| {
        if g(i) <= g(u) {
            (i + g(u)).max((i + u).div_euclid(2))
        } else {
            (u - g(i)).min((i + u).div_euclid(2))
        }
    };
    // s: the cones of the envelope, left to right; t: where each starts.
    let (mut s, mut t) = (vec![0i64], vec![0i64]);
    for u in 1..m {
        while let (Some(&sq), Some(&tq)) = (s.last(), t.last()) {
            if f(tq, sq) > f(tq, u) {
                s.pop();
                t.pop();
            } else {
                break;
            }
        }
        if s.is_empty() {
            s.push(u);
            t.push(0);
        } else {
            let w = 1 + sep(*s.last().expect("not empty"), u);
            if w < m {
                s.push(u);
                t.push(w);
            }
        }
    }
    for x in (0..m).rev() {
        let q = s.len() - 1;
        out[x as usize] = f(x, s[q]) as u32;
        if x == t[q] {
            s.pop();
            t.pop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SOLIDS: [(u32, u32, u32); 3] = [(1, 2, 0), (7, 5, 4), (3, 3, 2)];

    fn sample() -> OccupancyField {
        OccupancyField::from_solid(Dims::new(8, 6, 5).unwrap(), |i, j, k| {
            SOLIDS.contains(&(i, j, k))
        })
    }

    #[test]
    fn a_field_round_trips_and_its_distances_are_chebyshev_to_the_nearest_solid() {
        let field = sample();
        let back = OccupancyField::from_bytes(field.dims(), field.bytes()).unwrap();
        assert_eq!(back, field);
        assert_eq!(field.solid_voxels(), 3);
        assert!(SOLIDS.iter().all(|&(i, j, k)| back.is_solid(i, j, k)));
        // Brute force: L∞ distance, periodic in x and y, over the three solid voxels.
        let d = field.dims();
        for (v, &stored) in field.bytes().iter().enumerate() {
            let (i, j, k) = ((v % 8) as i64, (v / 8 % 6) as i64, (v / 48) as i64);
            let periodic =
                |a: i64, b: i64, n: i64| (a - b).rem_euclid(n).min((b - a).rem_euclid(n));
            let expected = SOLIDS
                .iter()
                .map(|&(x, y, z)| {
                    let (x, y, z) = (x as i64, y as i64, z as i64);
                    periodic(i, x, d.x as i64)
                        .max(periodic(j, y, d.y as i64))
                        .max((k - z).abs())
                })
                .min()
                .unwrap();
            assert_eq!(stored as i64, expected, "voxel {v}");
        }
    }

    /// The pass against its definition, evaluated plainly over every position (the shorter
    /// way round on periodic lines), on lines of every length to 40 with pseudo-random values
    /// from 0 to [`MAX_DISTANCE`], sparse zeros and runs of the cap among them.
    #[test]
    fn the_linear_pass_equals_its_definition() {
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for n in 1..=40usize {
            for trial in 0..30 {
                let f: Vec<u32> = (0..n)
                    .map(|_| match (trial % 3, next() % 8) {
                        (0, 0) => 0,
                        (0, _) => MAX_DISTANCE as u32,
                        (1, r) => r * 3,
                        _ => next() % (MAX_DISTANCE as u32 + 1),
                    })
                    .collect();
                for periodic in [false, true] {
                    let mut out = vec![0; n];
                    min_max_pass(&f, &mut out, periodic);
                    for (c, &got) in out.iter().enumerate() {
                        let expected = (0..n)
                            .map(|p| {
                                let d = c.abs_diff(p);
                                let d = if periodic { d.min(n - d) } else { d };
                                (d as u32).max(f[p])
                            })
                            .min()
                            .unwrap();
                        assert_eq!(got, expected, "n {n}, {periodic}, {f:?} at {c}");
                    }
                }
            }
        }
    }

    #[test]
    fn inconsistent_or_short_fields_are_refused_naming_the_voxel() {
        let field = sample();
        let mut bytes = field.bytes().to_vec();
        let e = OccupancyField::from_bytes(field.dims(), &bytes[1..]).unwrap_err();
        assert!(e.to_string().contains("not one per voxel"), "{e}");
        // A distance larger than the truth would let a march skip a solid voxel.
        bytes[0] += 1;
        let e = OccupancyField::from_bytes(field.dims(), &bytes).unwrap_err();
        assert!(e.to_string().contains("distance at voxel 0"), "{e}");
    }
}
