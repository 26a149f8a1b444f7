//! Explicit geometry: the tile's triangles mapped through the shell into object space, as a
//! conventional displacement pipeline or an offline renderer would consume them (`mesobake
//! explicit`), and a third way to check rendered images.
//!
//! # Algorithm
//!
//! Texture space is (s, t, w): s, t in tile units (UV × tiling), w = z / H ∈ [0, 1] with H the
//! tile's height (Z/X of its voxel grid). The tile repeats with period 1 in s and t.
//!
//! 1. **Tile.** Vertices are welded modulo the lattice (closer than 2⁻²⁰ of a tile, as
//!    [`crate::mesostructure::mesh_tile`] does): each becomes a representative position plus an integer
//!    lattice shift, so that copies of one vertex in neighbouring tile instances have exactly
//!    the same coordinates. Triangles are binned on a 2D grid by their (s, t) bounds.
//! 2. **Copies.** For each prism, every tile instance (m, n) whose translated bounding box
//!    overlaps the prism's UV bounding box contributes its binned triangles, translated to
//!    (x + m, y + n, z / H).
//! 3. **Clipping** (Sutherland–Hodgman in texture space) against the three vertical
//!    half-spaces of the prism's UV triangle and 0 ≤ w ≤ 1; the convex polygon left is fan
//!    triangulated. Every new point is computed from what defines it, never from the order in
//!    which clipping met it, so that the two prisms sharing a side and the two tile triangles
//!    sharing an edge get bit-identical points:
//!    - an edge of the tile cut by a plane: endpoints sorted by (welded id, lattice shift);
//!    - a side of the UV triangle: oriented from its corner with the smaller welded vertex id,
//!      evaluated in a frame anchored at the integer part of that corner's UV (so an integer
//!      UV offset across a seam, as in the built-in torus, changes nothing); a point on it is
//!      stored as its parameter λ along that oriented side;
//!    - the tile triangle's plane cut by two planes (a side and w = 0 or 1, or two sides at a
//!      prism corner): from the triangle's own corners; where a tile edge passes exactly
//!      through the corner, from that edge, as the prisms cutting the edge compute it.
//!
//!    Inside/outside decisions are canonical too: original tile vertices are classified in
//!    each side's frame; a point on a side gets the other sides' values from its canonical
//!    barycentric coordinates, with the sign at each end of the side decided by the
//!    orientation of the cutting line against that prism corner, evaluated in the corner's
//!    frame as every prism around the corner does (a line exactly through the corner gives
//!    the corner); a cut by w = 0 or 1 inside a prism interpolates its edge's canonical side
//!    values. So a tile feature within round-off of a prism side or corner is put on the same
//!    side of it by all prisms.
//!
//!    A tile face lying exactly in a side shared by two prisms is kept by one of them only
//!    (the one it faces out of); faces in w = 0 or w = 1 are kept.
//! 4. **Mapping.** Every vertex is held as prism coordinates (barycentric b over the base
//!    triangle, w) and mapped with [`Prism::point`]. On a side the third coordinate is exactly
//!    0 and the other two are 1 − λ and λ, so the neighbouring prism computes the same sum;
//!    at a prism corner b is a unit vector.
//! 5. **Adaptive subdivision.** Along a straight texture segment P is quadratic (bᵢ and w are
//!    affine in the segment parameter, P = Σ bᵢ (Bᵢ + w·h·dᵢ)), so the distance between the
//!    image of the texture midpoint and the chord's midpoint is the largest distance between
//!    curve and chord. An edge is split at its texture midpoint iff that distance exceeds the
//!    tolerance, unless its extent in prism coordinates is below 2⁻²⁰ — a decision that
//!    depends only on its two endpoints and is symmetric in them. A triangle splits by the
//!    standard patterns (1 edge: bisection; 2 edges: a corner triangle and a quad cut by its
//!    shorter diagonal; 3 edges: four triangles) and recursion continues on the pieces. Two
//!    triangles sharing an edge therefore split it identically: no T-junctions.
//!
//! # Guarantees
//!
//! - **Tolerance** (default 10⁻³ × shell thickness, object units): every output edge's
//!   midpoint lies within the tolerance of the exact image of its texture midpoint, hence
//!   every point of the edge within the tolerance of the exact curve; over a triangle, whose
//!   deviation is a quadratic vanishing at its corners, within 4/3 of it. The largest measured
//!   edge deviation is reported ([`ExplicitStats::max_deviation`]); it exceeds the tolerance
//!   only where the extent floor or the recursion cap stopped splitting
//!   ([`ExplicitStats::depth_limited`]).
//! - **Welding and closure**: output vertices with bit-identical positions are merged
//!   (−0 = +0), then edges at most 10⁻⁹ × thickness long are collapsed, the triangles that
//!   degenerate are dropped and pairs of opposite triangles over the same vertices among
//!   them cancel (the zero-area slivers where a tile vertex lies within round-off of a side).
//!   A closed tile on a closed base mesh, with UV seams at whole tiles and no folded prism,
//!   gives a closed, consistently oriented mesh: every directed edge is used as often as its
//!   reverse, and (as tested on the built-in torus with `weave` and `chain`) exactly once.
//!   Near-coincidences can leave a few edges shared by four triangles of such slivers, still
//!   balanced. Open bases give open output.
//! - **Orientation**: where the mapping preserves orientation (Jacobian determinant > 0:
//!   texture x, y, w map to a right-handed frame), outward faces stay outward. Prisms whose
//!   mapping reverses it (flipped UVs: mirrored mesostructure) get their windings swapped so
//!   faces still point out of the solid ([`ExplicitStats::mirrored_prisms`]). The sign is
//!   taken at the prism's centre: an inverted or folded prism (see
//!   [`crate::surface::shell::ShellReport`]) is not one-to-one, and the part beyond its fold comes out
//!   inside out and may intersect its neighbours ([`ExplicitStats::folded_prisms`]).
//! - Deterministic: prisms run in parallel but are merged in order.

mod clip;
mod input;
mod tile;

use crate::mesostructure::mesh_tile::MeshTile;
use crate::mesostructure::trimesh::TriMesh;
use crate::surface::base_mesh::BaseMesh;
use crate::surface::shell::{Prism, PrismPoint, Shell, ShellParams};
use clip::{PrismContext, PrismOutput};
use glam::{DVec2, DVec3};
pub use input::{ExplicitInput, proportional_thickness};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use tile::PreparedTile;

/// Default tolerance as a fraction of the shell thickness.
pub const DEFAULT_RELATIVE_TOLERANCE: f64 = 1e-3;

/// Tile vertices closer than 1/2²⁰ of a tile (after wrapping) are one vertex, as in
/// [`crate::mesostructure::mesh_tile`].
const WELD_SCALE: f64 = (1u64 << 20) as f64;

/// Edges shorter than this in prism coordinates (barycentric and w) are never split.
const MIN_EXTENT: f64 = 1.0 / (1u64 << 20) as f64;

/// Output edges at most this × the shell thickness long are collapsed.
const SLIVER_RELATIVE: f64 = 1e-9;

/// Recursion cap of the triangle subdivision (beyond the extent floor, a safety net).
const MAX_DEPTH: u32 = 40;

/// Bytes budgeted per output triangle (mesh, welding tables, OBJ text) for the memory limit.
const BYTES_PER_TRIANGLE: u64 = 160;

/// Largest |texture coordinate| (tile units) accepted: lattice shifts stay exact integers.
const MAX_TEXTURE_COORDINATE: f64 = (1u64 << 40) as f64;

/// Plane indices: 0..3 the prism's sides (side k over the base edge from corner k to k+1),
/// then w = 0 and w = 1.
const W0: usize = 3;
const W1: usize = 4;

/// How to export.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExplicitParams {
    /// The tile's height H in tile units (Z/X of its voxel grid): tile z ∈ [0, H] is the
    /// shell's w ∈ [0, 1].
    pub tile_height: f64,
    /// Largest distance (object units) between an output edge's midpoint and the exact image
    /// of its texture midpoint.
    pub tolerance: f64,
    /// Also return each output triangle's prism and texture coordinates
    /// ([`Explicit::sources`]).
    pub record_texture: bool,
}

/// Where an output triangle came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleSource {
    /// Index of the prism in [`Shell::prisms`].
    pub prism: u32,
    /// Texture coordinates (s, t in tile units, w) of the corners, in the triangle's order.
    pub texture: [DVec3; 3],
}

/// What an export did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ExplicitStats {
    /// Prisms of the shell.
    pub prisms: usize,
    /// Tile triangles in (zero-area ones dropped).
    pub triangles_in: usize,
    /// Whether the tile is closed on the tiling ([`crate::mesostructure::mesh_tile::TileReport::is_closed`]).
    pub tile_closed: bool,
    /// Copies of tile triangles cut by a prism side or by w = 0 or 1.
    pub triangles_clipped: usize,
    /// Triangles out.
    pub triangles_out: usize,
    /// Vertices out (after welding).
    pub vertices_out: usize,
    /// Output triangles dropped: welding merged two of their corners (also after collapsing
    /// edges shorter than 10⁻⁹ × thickness), or they were a pair of opposite slivers over the
    /// same three vertices.
    pub degenerate_dropped: usize,
    /// The tolerance (object units).
    pub tolerance: f64,
    /// Largest distance between an output edge's midpoint and the exact image of its texture
    /// midpoint (object units).
    pub max_deviation: f64,
    /// Triangles whose subdivision stopped at the recursion cap.
    pub depth_limited: usize,
    /// Prisms whose mapping reverses orientation at their centre (windings swapped).
    pub mirrored_prisms: usize,
    /// Prisms that fold ([`crate::surface::shell::ShellReport::folded`]): output there is not
    /// one-to-one.
    pub folded_prisms: usize,
    /// Wall-clock seconds of the export.
    pub seconds: f64,
}

/// The exported geometry.
#[derive(Clone, Debug)]
pub struct Explicit {
    /// Welded object-space triangles, counter-clockwise seen from outside.
    pub mesh: TriMesh,
    /// Per output triangle, its prism and texture coordinates, when
    /// [`ExplicitParams::record_texture`] is set.
    pub sources: Option<Vec<TriangleSource>>,
    /// Statistics.
    pub stats: ExplicitStats,
}

/// Maps `tile` (tile units, z in [0, `params.tile_height`], repeating in x and y) through
/// `shell` into object space; see the module documentation. `observer` hears of each prism
/// finished and may cancel.
pub fn export(
    shell: &Shell,
    tile: &TriMesh,
    params: &ExplicitParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Explicit> {
    let start = Instant::now();
    if !(params.tile_height.is_finite() && params.tile_height > 0.0) {
        return Err(Error::InvalidParameter(format!(
            "the tile height must be finite and positive, got {}",
            params.tile_height
        )));
    }
    if !(params.tolerance.is_finite() && params.tolerance > 0.0) {
        return Err(Error::InvalidParameter(format!(
            "the tolerance must be finite and positive, got {}",
            params.tolerance
        )));
    }
    let validated = MeshTile::new(tile.clone(), true)?;
    let tile = PreparedTile::new(&validated.mesh, params.tile_height)?;
    for p in &shell.prisms {
        if !p
            .uv
            .iter()
            .all(|u| u.abs().max_element() <= MAX_TEXTURE_COORDINATE)
        {
            return Err(Error::InvalidParameter(format!(
                "base triangle {}: texture coordinates {:?} (tile units) are too large for \
                 explicit export (at most {MAX_TEXTURE_COORDINATE})",
                p.triangle, p.uv
            )));
        }
    }
    // Refuse absurd outputs before doing the work: the expected triangle count is the tile's
    // triangles times the tiles covered, plus the tile copies visited.
    let mut estimate = 0.0f64;
    for p in &shell.prisms {
        let area = 0.5 * (p.uv[1] - p.uv[0]).perp_dot(p.uv[2] - p.uv[0]).abs();
        let (lo, hi) = uv_bounds(p);
        let copies = (hi - lo + tile.hi - tile.lo + 2.0).max(DVec2::ZERO);
        estimate += area * tile.corners.len() as f64 + copies.x * copies.y;
    }
    limits.check(
        "explicit geometry (estimated triangles)",
        estimate.min(u64::MAX as f64) as u64,
        BYTES_PER_TRIANGLE,
    )?;
    let budget = limits.memory_bytes / BYTES_PER_TRIANGLE;
    let produced = AtomicU64::new(0);
    let finished = AtomicU64::new(0);
    let prisms = shell.prisms.len() as u64;
    let boundary = boundary_sides(shell);
    let outputs: Vec<PrismOutput> = shell
        .prisms
        .par_iter()
        .enumerate()
        .map(|(index, prism)| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let ctx = PrismContext::new(prism, index as u32, boundary[index], &tile, params);
            let out = ctx.run();
            observer.progress(finished.fetch_add(1, Ordering::Relaxed) + 1, prisms);
            let total = produced.fetch_add(out.triangles.len() as u64, Ordering::Relaxed)
                + out.triangles.len() as u64;
            if total > budget {
                return Err(Error::MemoryLimit {
                    what: "explicit geometry".into(),
                    needed: total.saturating_mul(BYTES_PER_TRIANGLE),
                    limit: limits.memory_bytes,
                });
            }
            Ok(out)
        })
        .collect::<Result<_>>()?;

    let mut stats = ExplicitStats {
        prisms: shell.prisms.len(),
        triangles_in: tile.corners.len(),
        tile_closed: validated.closed,
        tolerance: params.tolerance,
        folded_prisms: shell.report.folded,
        ..Default::default()
    };
    let vertex_count: usize = outputs.iter().map(|o| o.positions.len()).sum();
    let triangle_count: usize = outputs.iter().map(|o| o.triangles.len()).sum();
    let mut mesh = TriMesh {
        positions: Vec::with_capacity(vertex_count / 2),
        triangles: Vec::with_capacity(triangle_count),
    };
    let mut sources = params
        .record_texture
        .then(|| Vec::with_capacity(triangle_count));
    let mut ids: HashMap<[u64; 3], u32> = HashMap::with_capacity(vertex_count / 2);
    for out in &outputs {
        stats.triangles_clipped += out.clipped;
        stats.depth_limited += out.depth_limited;
        stats.mirrored_prisms += usize::from(out.mirrored);
        stats.max_deviation = stats.max_deviation.max(out.max_deviation);
        let global: Vec<u32> = out
            .positions
            .iter()
            .map(|p| {
                let next = mesh.positions.len() as u32;
                *ids.entry(position_key(*p)).or_insert_with(|| {
                    mesh.positions.push([p.x + 0.0, p.y + 0.0, p.z + 0.0]);
                    next
                })
            })
            .collect();
        for (n, t) in out.triangles.iter().enumerate() {
            let g = t.map(|i| global[i as usize]);
            if g[0] == g[1] || g[1] == g[2] || g[2] == g[0] {
                stats.degenerate_dropped += 1;
                continue;
            }
            mesh.triangles.push(g);
            if let Some(s) = &mut sources {
                s.push(out.sources[n]);
            }
        }
    }
    stats.degenerate_dropped += collapse_slivers(
        &mut mesh,
        sources.as_mut(),
        SLIVER_RELATIVE * shell.params.thickness,
    );
    stats.triangles_out = mesh.triangles.len();
    stats.vertices_out = mesh.positions.len();
    stats.seconds = start.elapsed().as_secs_f64();
    Ok(Explicit {
        mesh,
        sources,
        stats,
    })
}

/// Cleans up where a tile vertex lies within round-off of a prism side and the two prisms'
/// pieces meet in slivers: collapses output edges at most `size` long (union–find, the
/// smallest vertex index representing each group), drops the triangles that degenerate, then
/// removes pairs of opposite triangles over the same three vertices among those touched.
/// Every step keeps each directed edge balanced by its reverse, so closure is kept. Drops
/// vertices left unused. Returns the number of triangles removed.
fn collapse_slivers(
    mesh: &mut TriMesh,
    mut sources: Option<&mut Vec<TriangleSource>>,
    size: f64,
) -> usize {
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            parent[v as usize] = parent[parent[v as usize] as usize];
            v = parent[v as usize];
        }
        v
    }
    let position = |v: u32| DVec3::from(mesh.positions[v as usize]);
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let mut merged = false;
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if (position(a) - position(b)).abs().max_element() <= size {
                let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                if ra != rb {
                    parent[ra.max(rb) as usize] = ra.min(rb);
                    merged = true;
                }
            }
        }
    }
    if !merged {
        return 0;
    }
    let mut removed = vec![false; mesh.triangles.len()];
    let mut open: HashMap<[u32; 3], Vec<(usize, bool)>> = HashMap::new();
    for (n, t) in mesh.triangles.iter_mut().enumerate() {
        let r = t.map(|v| root(&mut parent, v));
        let touched = r != *t;
        *t = r;
        if r[0] == r[1] || r[1] == r[2] || r[2] == r[0] {
            removed[n] = true;
        } else if touched {
            // Rotate the smallest id first; the order of the other two is the orientation.
            let m = (0..3).min_by_key(|&k| r[k]).unwrap_or(0);
            let (x, y) = (r[(m + 1) % 3], r[(m + 2) % 3]);
            let list = open.entry([r[m], x.min(y), x.max(y)]).or_default();
            if let Some(i) = list.iter().position(|&(_, up)| up != (x < y)) {
                removed[list.swap_remove(i).0] = true;
                removed[n] = true;
            } else {
                list.push((n, x < y));
            }
        }
    }
    let mut keep = removed.iter().map(|r| !r);
    mesh.triangles.retain(|_| keep.next().unwrap_or(true));
    if let Some(s) = sources.as_mut() {
        let mut keep = removed.iter().map(|r| !r);
        s.retain(|_| keep.next().unwrap_or(true));
    }
    let mut index = vec![u32::MAX; mesh.positions.len()];
    let mut positions = Vec::with_capacity(mesh.positions.len());
    for t in &mut mesh.triangles {
        for v in t.iter_mut() {
            if index[*v as usize] == u32::MAX {
                index[*v as usize] = positions.len() as u32;
                positions.push(mesh.positions[*v as usize]);
            }
            *v = index[*v as usize];
        }
    }
    mesh.positions = positions;
    removed.iter().filter(|&&r| r).count()
}

/// Welding key of an object position: its bits with −0 read as +0.
fn position_key(p: DVec3) -> [u64; 3] {
    [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits())
}

/// Bounding box of a prism's UV triangle (tile units).
fn uv_bounds(p: &Prism) -> (DVec2, DVec2) {
    let lo = p.uv[0].min(p.uv[1]).min(p.uv[2]);
    let hi = p.uv[0].max(p.uv[1]).max(p.uv[2]);
    (lo, hi)
}

/// For each prism, which of its sides no other prism shares (by welded vertex ids).
fn boundary_sides(shell: &Shell) -> Vec<[bool; 3]> {
    let key = |p: &Prism, k: usize| {
        let (a, b) = (p.welded[k], p.welded[(k + 1) % 3]);
        (a.min(b), a.max(b))
    };
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for p in &shell.prisms {
        for k in 0..3 {
            *count.entry(key(p, k)).or_insert(0) += 1;
        }
    }
    shell
        .prisms
        .iter()
        .map(|p| [0, 1, 2].map(|k| count[&key(p, k)] == 1))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit square in the xy plane as two triangles, UV = xy, normals +z.
    fn square() -> BaseMesh {
        BaseMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            normals: vec![DVec3::Z; 4],
            uvs: vec![DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    /// An axis-aligned box as 12 outward triangles.
    fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> TriMesh {
        let positions = (0..8)
            .map(|i| [0, 1, 2].map(|a| if i >> a & 1 == 1 { hi[a] } else { lo[a] }))
            .collect();
        // Faces as quads (counter-clockwise from outside), corner index = x + 2y + 4z.
        let quads = [
            [0, 2, 3, 1], // z = lo
            [4, 5, 7, 6], // z = hi
            [0, 1, 5, 4], // y = lo
            [2, 6, 7, 3], // y = hi
            [0, 4, 6, 2], // x = lo
            [1, 3, 7, 5], // x = hi
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriMesh {
            positions,
            triangles,
        }
    }

    fn area(mesh: &TriMesh) -> f64 {
        (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t).map(DVec3::from);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    fn flat_export(tile: &TriMesh) -> Explicit {
        let shell = Shell::new(
            &square(),
            ShellParams {
                thickness: 0.25,
                tiles_per_uv: [2.0, 2.0],
                smoothing: 0,
            },
        )
        .unwrap();
        let params = ExplicitParams {
            tile_height: 0.5,
            tolerance: 1e-6,
            record_texture: true,
        };
        export(&shell, tile, &params, &Limits::default(), &()).unwrap()
    }

    #[test]
    fn flat_base_maps_affinely_and_keeps_the_area() {
        // Tile units → object: s/2, t/2 (2 tiles per unit), w·0.25 = z/H·0.25 = z/2. The box
        // crosses the tile border in x, reaches below w = 0 and is cut by the square's
        // diagonal (the side between the two prisms) and by its border.
        let tile = cuboid([0.7, 0.3, -0.1], [1.2, 0.6, 0.3]);
        let out = flat_export(&tile);
        let sources = out.sources.as_ref().unwrap();
        assert_eq!(sources.len(), out.mesh.triangles.len());
        for (t, s) in out.mesh.triangles.iter().zip(sources) {
            for (&v, tex) in t.iter().zip(s.texture) {
                let p = DVec3::from(out.mesh.positions[v as usize]);
                let want = DVec3::new(tex.x * 0.5, tex.y * 0.5, tex.z * 0.25);
                // Affine map evaluated in f64: round-off only (1e-12).
                assert!((p - want).length() < 1e-12, "{p} vs {want} ({tex})");
            }
        }
        // Expected area, per copy in y (y ∈ [0.3, 0.6] + n, n = 0, 1, inside [0, 2]): the
        // copies in x clipped to [0, 2] are [0, 0.2], [0.7, 1.2], [1.7, 2] (length 1 in all),
        // with 4 x-faces inside; z is clipped to [0, 0.3] and the bottom face drops out.
        let (dy, dz, length) = (0.3, 0.3, 1.0);
        let per_copy = 4.0 * dy * dz + 2.0 * length * dz + length * dy;
        let expected = 2.0 * per_copy * 0.25; // areas scale by 0.5²
        // Summed over ~100 triangles in f64: 1e-12 relative.
        assert!(
            (area(&out.mesh) - expected).abs() < 1e-12 * expected,
            "{} vs {expected}",
            area(&out.mesh)
        );
        // Flat and affine: nothing to subdivide, no deviation beyond round-off.
        assert!(out.stats.max_deviation < 1e-14, "{:?}", out.stats);
        assert!(out.stats.triangles_clipped > 0);
    }

    #[test]
    fn a_face_in_a_shared_side_is_kept_once() {
        // A triangle lying in the plane s = t, the side shared by the two prisms over the
        // square's diagonal: both prisms contain it; exactly one keeps it (the map scales
        // lengths by ½, areas by ¼).
        let tile = TriMesh {
            positions: vec![[0.2, 0.2, 0.05], [0.7, 0.7, 0.05], [0.4, 0.4, 0.4]],
            triangles: vec![[0, 1, 2]],
        };
        // Its four copies: (0, 0) and (1, 1) lie in the diagonal, (1, 0) and (0, 1) inside one
        // prism each.
        let out = flat_export(&tile);
        let want = 4.0 * area(&tile) * 0.25;
        assert!(
            (area(&out.mesh) - want).abs() < 1e-12,
            "{} vs {want}",
            area(&out.mesh)
        );
    }
}
