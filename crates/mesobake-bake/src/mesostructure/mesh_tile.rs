//! OBJ mesostructure tiles: a triangle mesh repeated with period 1 in x and y, validated as a
//! closed surface *on the tiling*.
//!
//! A tile may cross the borders of [0,1)² (a link sticking into the next tile); what matters is
//! that, with vertices identified modulo the lattice (x, y) ↦ (x+m, y+n), every edge is shared
//! by exactly two triangles that traverse it in opposite directions. Then inside/outside is
//! well defined (non-zero winding number, see [`crate::gdm::mesh_caster`]), also where closed
//! parts overlap. Open tiles are rejected by default: with `allow_open` they are treated as
//! infinitely thin sheets (no sample is inside solid; rays stop at the sheet).

use crate::mesostructure::trimesh::{TriMesh, cross, sub};
use mesobake_core::error::{Error, Result};
use std::collections::{HashMap, HashSet};

/// Vertices closer than 1/2²⁰ of a tile (after wrapping) are the same vertex.
const WELD_SCALE: f64 = (1u64 << 20) as f64;

/// What validation found in a tile.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TileReport {
    /// Triangles in the file.
    pub triangles: usize,
    /// Triangles with zero area (dropped).
    pub degenerate: usize,
    /// Triangles on the same welded corners as an earlier one, either way round (dropped:
    /// they add no surface, and many copies of one triangle made the BVH build quadratic).
    pub duplicates: usize,
    /// Edges with a triangle on one side only.
    pub boundary_edges: usize,
    /// Edges used twice in the same direction or by more than two triangles.
    pub inconsistent_edges: usize,
}

impl TileReport {
    /// Whether the tile is a closed, consistently oriented surface on the tiling.
    pub fn is_closed(&self) -> bool {
        self.boundary_edges == 0 && self.inconsistent_edges == 0
    }
}

/// A validated tile: the non-degenerate triangles and the validation report.
#[derive(Clone, Debug)]
pub struct MeshTile {
    /// Triangles in tile units (x, y period 1).
    pub mesh: TriMesh,
    /// What validation found.
    pub report: TileReport,
    /// Whether the tile is treated as closed solid (false: thin sheets, see module docs).
    pub closed: bool,
}

impl MeshTile {
    /// Validates `mesh` as a tile. Errors name the problem: no usable triangles, a triangle
    /// wider than a tile period, or (unless `allow_open`) an open or inconsistently oriented
    /// surface.
    pub fn new(mesh: TriMesh, allow_open: bool) -> Result<Self> {
        let mut report = TileReport {
            triangles: mesh.triangles.len(),
            ..Default::default()
        };
        let mut ids: HashMap<[i64; 3], u32> = HashMap::new();
        let welded: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let key = [
                    ((p[0] * WELD_SCALE).round() as i64).rem_euclid(WELD_SCALE as i64),
                    ((p[1] * WELD_SCALE).round() as i64).rem_euclid(WELD_SCALE as i64),
                    (p[2] * WELD_SCALE).round() as i64,
                ];
                let next = ids.len() as u32;
                *ids.entry(key).or_insert(next)
            })
            .collect();
        let mut kept = TriMesh {
            positions: mesh.positions.clone(),
            triangles: Vec::with_capacity(mesh.triangles.len()),
        };
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        let mut seen: HashSet<[u32; 3]> = HashSet::new();
        for (n, t) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = mesh.corners(n);
            for axis in 0..2 {
                let lo = a[axis].min(b[axis]).min(c[axis]);
                let hi = a[axis].max(b[axis]).max(c[axis]);
                if hi - lo >= 1.0 {
                    return Err(Error::MeshTile(format!(
                        "triangle {} spans {:.3} tile periods along {}; triangles must be \
                         narrower than one tile",
                        n + 1,
                        hi - lo,
                        ["x", "y"][axis]
                    )));
                }
            }
            let w = t.map(|v| welded[v as usize]);
            let area2 = cross(sub(b, a), sub(c, a));
            if w[0] == w[1] || w[1] == w[2] || w[2] == w[0] || area2 == [0.0; 3] {
                report.degenerate += 1;
                continue;
            }
            let mut corners = w;
            corners.sort_unstable();
            if !seen.insert(corners) {
                report.duplicates += 1;
                continue;
            }
            kept.triangles.push(*t);
            for e in [(w[0], w[1]), (w[1], w[2]), (w[2], w[0])] {
                *edges.entry(e).or_insert(0) += 1;
            }
        }
        if kept.triangles.is_empty() {
            return Err(Error::MeshTile(format!(
                "all {} triangles are degenerate (zero area)",
                report.triangles
            )));
        }
        for (&(a, b), &n) in &edges {
            let reverse = edges.get(&(b, a)).copied().unwrap_or(0);
            if n > 1 || reverse > 1 {
                report.inconsistent_edges += 1;
            } else if reverse == 0 {
                report.boundary_edges += 1;
            }
        }
        if !report.is_closed() && !allow_open {
            return Err(Error::MeshTile(format!(
                "the tile is not a closed surface on the tiling: {} boundary edges and {} \
                 edges used inconsistently (same direction twice, or by more than two \
                 triangles); inside and outside are undefined. Close the surface, or pass \
                 --allow-open to treat it as infinitely thin sheets",
                report.boundary_edges, report.inconsistent_edges
            )));
        }
        let closed = report.is_closed();
        Ok(MeshTile {
            mesh: kept,
            report,
            closed,
        })
    }
}
