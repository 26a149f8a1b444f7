//! Exact GDM bake of mesh tiles with ray templates over voxel-binned triangles.
//!
//! Each voxel of the grid lists the triangles (cell-local periodic copies, as in the BVH of
//! [`super::mesh_caster`]) whose bounding box, grown by 10⁻³ voxel, overlaps the voxel's
//! closed box. For one direction every sample's ray visits the same sequence of voxel offsets
//! (the ray template of [`super::template`]), so a row of 64 samples finds, one
//! rotate-and-mask per template step, the lanes whose ray enters a voxel with triangles, and
//! only those lanes test that voxel's triangles. A lane keeps the nearest intersection found
//! so far and stops before the first voxel it enters later than that: any nearer
//! intersection lies in a voxel entered earlier, whose triangles were all tested. The ray
//! origin and triangle test are those of the BVH path (same f32 arithmetic, ray in the local
//! frame of the tile cell the voxel belongs to), so both paths return the same distances.

use super::template::{Template, rotated_word};
use crate::mesostructure::volume::Occupancy;
use glam::Vec3A;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use obvhs::triangle::Triangle;

/// A triangle with its edges and normal computed once, intersected exactly like
/// [`Triangle::intersect`] (Möller–Trumbore, no culling).
#[derive(Clone, Copy, Debug)]
struct PreparedTriangle {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    n: Vec3A,
}

impl PreparedTriangle {
    fn new(t: &Triangle) -> Self {
        let e1 = t.v0 - t.v1;
        let e2 = t.v2 - t.v0;
        PreparedTriangle {
            v0: t.v0,
            e1,
            e2,
            n: e1.cross(e2),
        }
    }

    /// Distance t ≥ 0 along the ray to the triangle, +∞ for a miss.
    #[inline(always)]
    fn intersect(&self, origin: Vec3A, dir: Vec3A) -> f32 {
        let c = self.v0 - origin;
        let r = dir.cross(c);
        let inv_det = 1.0 / self.n.dot(dir);
        let u = r.dot(self.e2) * inv_det;
        let v = r.dot(self.e1) * inv_det;
        let w = 1.0 - u - v;
        let signs = u.to_bits() | v.to_bits() | w.to_bits();
        if inv_det != 0.0 && signs & 0x8000_0000 == 0 {
            let t = self.n.dot(c) * inv_det;
            if t >= 0.0 {
                return t;
            }
        }
        f32::INFINITY
    }
}

/// Cell-local triangles binned by the voxels their bounding boxes overlap.
pub(crate) struct BinnedTriangles {
    dims: Dims,
    tris: Vec<PreparedTriangle>,
    /// Triangles of voxel n: `ids[offsets[n]..offsets[n + 1]]`.
    offsets: Vec<u32>,
    ids: Vec<u32>,
    /// Voxels with at least one triangle.
    occupied: Occupancy,
}

/// Bounding boxes are grown by this many voxels so that f32 rounding cannot drop a triangle
/// from a voxel it touches.
const BIN_MARGIN: f32 = 1e-3;

impl BinnedTriangles {
    /// Bins `tris` (cell-local voxel units, copies overlapping the cell included) on `dims`.
    pub(crate) fn new(tris: &[Triangle], dims: Dims, limits: &Limits) -> Result<Self> {
        let voxel_ranges = |t: &Triangle| {
            let lo = t.v0.min(t.v1).min(t.v2) - Vec3A::splat(BIN_MARGIN);
            let hi = t.v0.max(t.v1).max(t.v2) + Vec3A::splat(BIN_MARGIN);
            let n = [dims.x, dims.y, dims.z];
            let range = |a: usize| {
                let first = (lo[a].floor() as i64).max(0);
                let last = (hi[a].floor() as i64).min(n[a] as i64 - 1);
                first as usize..(last + 1).max(first) as usize
            };
            [range(0), range(1), range(2)]
        };
        let voxels = dims.voxel_count() as usize;
        // Bounded by the bounding boxes' voxel counts, checked before anything is allocated.
        let bound: u64 = tris
            .iter()
            .map(|t| {
                voxel_ranges(t)
                    .iter()
                    .map(|r| r.len() as u64)
                    .product::<u64>()
            })
            .sum();
        limits.check("the voxel bins of the mesh tile", bound + voxels as u64, 4)?;
        if bound > u32::MAX as u64 {
            return Err(Error::InvalidParameter(format!(
                "the mesh tile's triangles overlap up to {bound} voxels in all, more than 2³² on {dims}"
            )));
        }
        let mut counts = vec![0u32; voxels + 1];
        let each_voxel = |t: &Triangle, f: &mut dyn FnMut(usize)| {
            let [x, y, z] = voxel_ranges(t);
            let corners = [t.v0, t.v1, t.v2].map(|p| p.to_array().map(f64::from));
            for k in z {
                for j in y.clone() {
                    for i in x.clone() {
                        let centre = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                        if triangle_overlaps_cube(corners, centre, 0.5 + BIN_MARGIN as f64) {
                            f(dims.index(i as u32, j as u32, k as u32));
                        }
                    }
                }
            }
        };
        for t in tris {
            each_voxel(t, &mut |n| counts[n + 1] += 1);
        }
        let total = counts.iter().map(|&c| c as u64).sum::<u64>();
        for n in 0..voxels {
            counts[n + 1] += counts[n];
        }
        let offsets = counts;
        let mut cursor = offsets.clone();
        let mut ids = vec![0u32; total as usize];
        let mut occupied = Occupancy::empty(dims);
        for (id, t) in tris.iter().enumerate() {
            each_voxel(t, &mut |n| {
                ids[cursor[n] as usize] = id as u32;
                cursor[n] += 1;
            });
        }
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let n = dims.index(i, j, k);
                    if offsets[n + 1] > offsets[n] {
                        occupied.set(i, j, k);
                    }
                }
            }
        }
        Ok(BinnedTriangles {
            dims,
            tris: tris.iter().map(PreparedTriangle::new).collect(),
            offsets,
            ids,
            occupied,
        })
    }

    /// Fills one direction's X×Y×Z volume: 0 for samples `inside` solid (or on the surface),
    /// the distance of the first intersection, +∞ for rays that leave the volume first.
    pub(crate) fn bake_direction(&self, inside: &Occupancy, v: [f64; 3], volume: &mut [f32]) {
        let dims = self.dims;
        let template = Template::new(dims, v);
        // Rays can only meet triangles in layers that hold some.
        let solid = self.occupied.solid_layer_range();
        let dir = Vec3A::new(v[0] as f32, v[1] as f32, v[2] as f32);
        let (x, y) = (dims.x as i64, dims.y as i64);
        let nx = dims.x as usize;
        // Tests the triangles of the voxel at `offset` from sample (i, j, k) (unwrapped x
        // and y, layer offset) along the ray from that sample.
        let test_voxel = |i: i64, j: u32, k: u32, offset: [i64; 3], best: &mut f32| {
            let (gi, gj) = (i + offset[0], j as i64 + offset[1]);
            // The tile cell the voxel lies in gives the ray's local frame.
            let (cx, cy) = (gi.div_euclid(x), gj.div_euclid(y));
            let origin = Vec3A::new(
                (i as f64 + 0.5 - (cx * x) as f64) as f32,
                (j as f64 + 0.5 - (cy * y) as f64) as f32,
                (k as f64 + 0.5) as f32,
            );
            let kk = (k as i64 + offset[2]) as u32;
            let n = dims.index((gi - cx * x) as u32, (gj - cy * y) as u32, kk);
            for &id in &self.ids[self.offsets[n] as usize..self.offsets[n + 1] as usize] {
                *best = best.min(self.tris[id as usize].intersect(origin, dir));
            }
        };
        let mut best = [f32::INFINITY; 64];
        for k in 0..dims.z {
            let steps = template.steps_within(solid, k, f64::INFINITY);
            for j in 0..dims.y {
                let out = &mut volume[(k as usize * dims.y as usize + j as usize) * nx..][..nx];
                for w in 0..nx.div_ceil(64) {
                    let lanes = (nx - 64 * w).min(64);
                    let mask = if lanes == 64 {
                        u64::MAX
                    } else {
                        (1u64 << lanes) - 1
                    };
                    let own = inside.row(j, k)[w] & mask;
                    let mut active = !own & mask;
                    let mut found = 0u64;
                    best[..lanes].fill(f32::INFINITY);
                    // The sample's own voxel first (offset 0, entered at t = 0), then the
                    // template's voxels in order.
                    let voxels = std::iter::once((0, 0, 0, 0.0, [0, 0])).chain(
                        steps
                            .iter()
                            .map(|s| (s.shift, s.dj, s.dk, s.t, s.unwrapped)),
                    );
                    for (shift, dj, dk, t, unwrapped) in voxels {
                        // Lanes whose nearest intersection comes before this voxel are done.
                        let mut open = found & active;
                        while open != 0 {
                            let lane = open.trailing_zeros();
                            if best[lane as usize] <= t {
                                active &= !(1 << lane);
                            }
                            open &= open - 1;
                        }
                        if active == 0 {
                            break;
                        }
                        let row = self.occupied.row((j + dj) % dims.y, (k as i32 + dk) as u32);
                        let mut lanes_in = rotated_word(row, dims.x, shift, w) & active;
                        let offset = [unwrapped[0] as i64, unwrapped[1] as i64, dk as i64];
                        while lanes_in != 0 {
                            let lane = lanes_in.trailing_zeros();
                            lanes_in &= lanes_in - 1;
                            let b = &mut best[lane as usize];
                            test_voxel((64 * w) as i64 + lane as i64, j, k, offset, b);
                            if b.is_finite() {
                                found |= 1 << lane;
                            }
                        }
                    }
                    for (lane, value) in out[64 * w..][..lanes].iter_mut().enumerate() {
                        *value = if own >> lane & 1 != 0 {
                            0.0
                        } else {
                            best[lane]
                        };
                    }
                }
            }
        }
    }
}

/// Whether the triangle overlaps the axis-aligned cube of half-size `half` around `centre`
/// (separating-axis test: the cube's axes, the triangle's normal and the nine edge-axis cross
/// products; Akenine-Möller 2001). Touching counts as overlapping.
fn triangle_overlaps_cube(tri: [[f64; 3]; 3], centre: [f64; 3], half: f64) -> bool {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let v = tri.map(|p| sub(p, centre));
    // Separated along `axis` when the triangle's projection misses the cube's.
    let separated = |axis: [f64; 3]| {
        let p = v.map(|c| dot(c, axis));
        let r = half * (axis[0].abs() + axis[1].abs() + axis[2].abs());
        p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
    };
    let edges = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
    let units = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    !(units.iter().any(|&u| separated(u))
        || separated(cross(edges[0], edges[1]))
        || edges
            .iter()
            .any(|&e| units.iter().any(|&u| separated(cross(u, e)))))
}
