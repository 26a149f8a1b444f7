//! Ray casting into a periodic triangle-mesh tile with an obvhs compressed wide BVH.
//!
//! The tile is scaled to voxel units (one tile = X voxels; X must equal Y so that cells are
//! cubes). The BVH holds, in the local frame of one tile cell \[0,X\]×\[0,Y\], every periodic copy
//! of a triangle that overlaps the cell. A ray walks the cells it crosses (a 2D DDA over tile
//! cells) and queries the BVH for the part of the ray inside each cell: the first hit found is
//! the first hit on the whole tiling. The walk ends at the plane z = 0 or z = Z.
//!
//! Inside or outside: a sample centre is inside when the non-zero winding number says so
//! (crossings counted +1 leaving and −1 entering a surface, along a ray going up past all
//! geometry), decided by a majority of three rays in fixed, generic upward directions so that
//! a ray grazing an edge cannot flip the answer.

use super::caster::{Caster, Trace};
use super::mesh_template::BinnedTriangles;
use crate::mesostructure::mesh_tile::MeshTile;
use crate::mesostructure::trimesh::TriMesh;
use crate::mesostructure::volume::Occupancy;
use glam::Vec3A;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use obvhs::{
    BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris, ray::Ray, ray::RayHit,
    triangle::Triangle,
};
use rayon::prelude::*;
use std::time::Duration;

/// Fixed generic upward directions for the inside vote.
const VOTE_DIRECTIONS: [[f64; 3]; 3] = [
    [0.123_456_7, 0.056_789_1, 1.0],
    [-0.083_129_3, 0.142_271_9, 1.0],
    [0.041_711_3, -0.113_917_7, 1.0],
];

/// Rays parallel to the planes are followed for at most this many tile periods.
const HORIZONTAL_PERIODS: f64 = 64.0;

/// A mesh tile ready for ray casting on an X×Y×Z grid.
pub struct MeshCaster {
    dims: Dims,
    /// Triangles in BVH order, cell-local voxel units.
    tris: Vec<Triangle>,
    bvh: CwBvh,
    /// Highest z of any triangle, voxel units.
    z_max: f64,
    inside: Occupancy,
    /// The triangles binned by voxel for template bakes, when the grid supports templates.
    bins: Option<BinnedTriangles>,
    /// The tile as given (tile units).
    mesh: TriMesh,
}

impl MeshCaster {
    /// Prepares `tile` for the grid `dims` (requires X = Y) and classifies the sample centres.
    pub fn new(tile: &MeshTile, dims: Dims, limits: &Limits) -> Result<Self> {
        if dims.x != dims.y {
            return Err(Error::InvalidParameter(format!(
                "a mesh tile spans [0,1)² so its grid needs X = Y for cubic cells; got {dims}"
            )));
        }
        limits.check("sample classification", dims.voxel_count(), 1)?;
        let scale = dims.x as f64;
        let mut tris = Vec::new();
        let mut z_max = f64::NEG_INFINITY;
        for n in 0..tile.mesh.triangles.len() {
            let corners = tile.mesh.corners(n);
            // Move the triangle so that its first corner lies in [0,1)².
            let shift = [corners[0][0].floor(), corners[0][1].floor()];
            let local = corners.map(|p| {
                [
                    (p[0] - shift[0]) * scale,
                    (p[1] - shift[1]) * scale,
                    p[2] * scale,
                ]
            });
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let c =
                        local.map(|p| [p[0] + dx as f64 * scale, p[1] + dy as f64 * scale, p[2]]);
                    let overlaps = |axis: usize| {
                        let lo = c[0][axis].min(c[1][axis]).min(c[2][axis]);
                        let hi = c[0][axis].max(c[1][axis]).max(c[2][axis]);
                        hi >= 0.0 && lo <= scale
                    };
                    if overlaps(0) && overlaps(1) {
                        let v = c.map(|p| Vec3A::new(p[0] as f32, p[1] as f32, p[2] as f32));
                        tris.push(Triangle {
                            v0: v[0],
                            v1: v[1],
                            v2: v[2],
                        });
                    }
                }
            }
            z_max = z_max.max(local.iter().map(|p| p[2]).fold(f64::NEG_INFINITY, f64::max));
        }
        limits.check("mesh tile triangles", tris.len() as u64, 256)?;
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::very_slow_build(),
            &mut Duration::default(),
        );
        let tris: Vec<Triangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        let bins = super::template::supports(dims)
            .then(|| BinnedTriangles::new(&tris, dims, limits))
            .transpose()?;
        let mut caster = MeshCaster {
            dims,
            tris,
            bvh,
            z_max,
            inside: Occupancy::empty(dims),
            bins,
            mesh: tile.mesh.clone(),
        };
        if tile.closed {
            caster.inside = caster.classify_centres();
        }
        Ok(caster)
    }

    /// The tile's triangles as given, in tile units.
    pub fn tile(&self) -> &TriMesh {
        &self.mesh
    }

    fn classify_centres(&self) -> Occupancy {
        let dims = self.dims;
        let votes: Vec<[f64; 3]> = VOTE_DIRECTIONS
            .iter()
            .map(|d| {
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                [d[0] / n, d[1] / n, d[2] / n]
            })
            .collect();
        let layers: Vec<Vec<(u32, u32)>> = (0..dims.z)
            .into_par_iter()
            .map(|k| {
                let mut solid = Vec::new();
                for j in 0..dims.y {
                    for i in 0..dims.x {
                        let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                        let inside_votes = votes
                            .iter()
                            .filter(|v| self.winding_number(o, **v) != 0)
                            .count();
                        if inside_votes >= 2 {
                            solid.push((i, j));
                        }
                    }
                }
                solid
            })
            .collect();
        let mut occ = Occupancy::empty(dims);
        for (k, solid) in layers.iter().enumerate() {
            for &(i, j) in solid {
                occ.set(i, j, k as u32);
            }
        }
        occ
    }

    /// Sum over surface crossings of +1 (leaving) / −1 (entering) along an upward ray.
    fn winding_number(&self, o: [f64; 3], v: [f64; 3]) -> i32 {
        let t_end = (self.z_max + 1.0 - o[2]) / v[2];
        let mut winding = 0;
        self.walk_cells(o, v, 0.0, t_end, |ray, t0, t1| {
            self.bvh.ray_traverse_anyhit(*ray, |r, id| {
                let tri = &self.tris[id];
                let t = tri.intersect(r);
                if t >= t0 && t < t1 {
                    let n = tri.compute_normal();
                    winding += if n.dot(r.direction) > 0.0 { 1 } else { -1 };
                }
            });
            false
        });
        winding
    }

    /// Calls `visit(ray, t0, t1)` with the cell-local ray for each tile cell the ray crosses
    /// between t = 0 and `t_end`, in order, until `visit` returns true. Returns whether it did.
    fn walk_cells(
        &self,
        o: [f64; 3],
        v: [f64; 3],
        t_start: f64,
        t_end: f64,
        mut visit: impl FnMut(&Ray, f32, f32) -> bool,
    ) -> bool {
        let size = self.dims.x as f64;
        let mut cell = [
            ((o[0] + t_start * v[0]) / size).floor(),
            ((o[1] + t_start * v[1]) / size).floor(),
        ];
        let mut t = t_start;
        let dir = Vec3A::new(v[0] as f32, v[1] as f32, v[2] as f32);
        loop {
            let mut t_next = t_end;
            let mut axis = None;
            for a in 0..2 {
                if v[a] != 0.0 {
                    let wall = (cell[a] + if v[a] > 0.0 { 1.0 } else { 0.0 }) * size;
                    let tw = (wall - o[a]) / v[a];
                    if tw < t_next {
                        t_next = tw;
                        axis = Some(a);
                    }
                }
            }
            let local = Vec3A::new(
                (o[0] - cell[0] * size) as f32,
                (o[1] - cell[1] * size) as f32,
                o[2] as f32,
            );
            // A hair of overlap between cells so that a hit exactly on a wall is not lost.
            let ray = Ray::new(local, dir, t as f32, (t_next * (1.0 + 1e-6) + 1e-6) as f32);
            if visit(&ray, t as f32, t_next as f32) {
                return true;
            }
            match axis {
                None => return false,
                Some(a) => {
                    cell[a] += v[a].signum();
                    t = t_next;
                }
            }
        }
    }
}

impl Caster for MeshCaster {
    fn dims(&self) -> Dims {
        self.dims
    }

    fn centres_inside(&self) -> &Occupancy {
        &self.inside
    }

    fn trace(&self, o: [f64; 3], v: [f64; 3], max_t: f64) -> Trace {
        self.trace_from(o, v, 0.0, max_t)
    }

    fn bake_direction(&self, dir: [f64; 3], volume: &mut [f32]) -> bool {
        match &self.bins {
            Some(bins) => bins.bake_direction(&self.inside, dir, volume),
            None => return false,
        }
        true
    }

    fn trace_from(&self, o: [f64; 3], v: [f64; 3], t_min: f64, max_t: f64) -> Trace {
        self.first_hit(o, v, t_min, max_t).0
    }

    fn hit_normal(&self, o: [f64; 3], v: [f64; 3], max_t: f64) -> Option<[f64; 3]> {
        let (trace, triangle) = self.first_hit(o, v, 0.0, max_t);
        let n = self.tris[triangle? as usize].compute_normal();
        let n = [n.x as f64, n.y as f64, n.z as f64];
        (matches!(trace, Trace::Hit(_)) && n.iter().all(|c| c.is_finite())).then_some(n)
    }
}

impl MeshCaster {
    /// [`Caster::trace_from`], with the index (in BVH order) of the triangle hit.
    fn first_hit(&self, o: [f64; 3], v: [f64; 3], t_min: f64, max_t: f64) -> (Trace, Option<u32>) {
        let top = self.dims.z as f64;
        let t_plane = if v[2] > 0.0 {
            (top - o[2]) / v[2]
        } else if v[2] < 0.0 {
            -o[2] / v[2]
        } else {
            HORIZONTAL_PERIODS * 2.0 * top.max(self.dims.x as f64) * self.dims.x as f64
        };
        let t_end = t_plane.min(max_t);
        let mut hit = RayHit::none();
        let found = self.walk_cells(o, v, t_min.min(t_end), t_end, |ray, _, _| {
            self.bvh
                .ray_traverse(*ray, &mut hit, |r, id| self.tris[id].intersect(r))
        });
        let trace = if found {
            if hit.t <= 0.0 {
                Trace::Inside
            } else {
                Trace::Hit(hit.t as f64)
            }
        } else if t_plane <= max_t {
            Trace::Escape(if v[2] == 0.0 { f64::INFINITY } else { t_plane })
        } else {
            Trace::Limit
        };
        (trace, found.then_some(hit.primitive_id))
    }
}
