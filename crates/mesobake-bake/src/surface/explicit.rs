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

use crate::mesostructure::mesh_tile::MeshTile;
use crate::mesostructure::trimesh::TriMesh;
use crate::surface::base_mesh::BaseMesh;
use crate::surface::shell::{Prism, PrismPoint, Shell, ShellParams};
use glam::{DVec2, DVec3};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

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

/// A tile vertex: a welded representative plus an integer lattice shift. Ordered by (id,
/// shift), the canonical order of an edge's endpoints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct TileVertex {
    id: u32,
    shift: [i64; 2],
}

/// The tile welded modulo the lattice and binned for lookups.
struct PreparedTile {
    /// Representative of each welded vertex: x, y in tile units, w = z / H.
    reps: Vec<DVec3>,
    /// Corners of each triangle.
    corners: Vec<[TileVertex; 3]>,
    /// (s, t) bounds of each triangle.
    boxes: Vec<(DVec2, DVec2)>,
    /// Bounds of the whole tile.
    lo: DVec2,
    hi: DVec2,
    /// Bins: `cells` × `cells` over [lo, hi], CSR lists of triangle indices.
    cells: usize,
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl PreparedTile {
    fn new(mesh: &TriMesh, height: f64) -> Result<PreparedTile> {
        if let Some(p) = mesh
            .positions
            .iter()
            .find(|p| p[0].abs().max(p[1].abs()) > MAX_TEXTURE_COORDINATE)
        {
            return Err(Error::MeshTile(format!(
                "vertex ({}, {}, {}) is too far from the tile (|x|, |y| at most \
                 {MAX_TEXTURE_COORDINATE})",
                p[0], p[1], p[2]
            )));
        }
        let mut ids: HashMap<[i64; 3], u32> = HashMap::new();
        let mut reps = Vec::new();
        let vertices: Vec<TileVertex> = mesh
            .positions
            .iter()
            .map(|p| {
                let q = p.map(|c| (c * WELD_SCALE).round() as i64);
                let key = [
                    q[0].rem_euclid(WELD_SCALE as i64),
                    q[1].rem_euclid(WELD_SCALE as i64),
                    q[2],
                ];
                let id = *ids.entry(key).or_insert_with(|| {
                    reps.push(DVec3::new(p[0], p[1], p[2] / height));
                    reps.len() as u32 - 1
                });
                let r = reps[id as usize];
                TileVertex {
                    id,
                    shift: [(p[0] - r.x).round() as i64, (p[1] - r.y).round() as i64],
                }
            })
            .collect();
        let mut corners = Vec::with_capacity(mesh.triangles.len());
        let mut boxes = Vec::with_capacity(mesh.triangles.len());
        for t in &mesh.triangles {
            let c = t.map(|i| vertices[i as usize]);
            if c[0].id == c[1].id || c[1].id == c[2].id || c[2].id == c[0].id {
                continue;
            }
            let xy = c.map(|v| point(&reps, v, [0, 0]).truncate());
            boxes.push((xy[0].min(xy[1]).min(xy[2]), xy[0].max(xy[1]).max(xy[2])));
            corners.push(c);
        }
        if corners.is_empty() {
            return Err(Error::MeshTile("no triangle with area is left".into()));
        }
        let lo = boxes.iter().fold(DVec2::INFINITY, |m, b| m.min(b.0));
        let hi = boxes.iter().fold(DVec2::NEG_INFINITY, |m, b| m.max(b.1));
        let cells = ((corners.len() as f64 / 4.0).sqrt() as usize).clamp(1, 64);
        let mut lists = vec![Vec::new(); cells * cells];
        let mut tile = PreparedTile {
            reps,
            corners,
            boxes,
            lo,
            hi,
            cells,
            starts: Vec::new(),
            items: Vec::new(),
        };
        for (n, b) in tile.boxes.iter().enumerate() {
            let (i0, j0) = tile.cell(b.0);
            let (i1, j1) = tile.cell(b.1);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    lists[j * cells + i].push(n as u32);
                }
            }
        }
        tile.starts.push(0);
        for list in &lists {
            tile.items.extend_from_slice(list);
            tile.starts.push(tile.items.len() as u32);
        }
        Ok(tile)
    }

    /// The bin of a point (clamped into the grid).
    fn cell(&self, p: DVec2) -> (usize, usize) {
        let size = (self.hi - self.lo).max(DVec2::splat(1e-300));
        let c = ((p - self.lo) / size * self.cells as f64).floor();
        let clamp = |x: f64| (x.max(0.0) as usize).min(self.cells - 1);
        (clamp(c.x), clamp(c.y))
    }

    /// Triangles whose bounds overlap [lo, hi] (tile-local), ascending, into `out`.
    fn query(&self, lo: DVec2, hi: DVec2, out: &mut Vec<u32>) {
        out.clear();
        if lo.x > self.hi.x || lo.y > self.hi.y || hi.x < self.lo.x || hi.y < self.lo.y {
            return;
        }
        let (i0, j0) = self.cell(lo);
        let (i1, j1) = self.cell(hi);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let c = j * self.cells + i;
                let list = &self.items[self.starts[c] as usize..self.starts[c + 1] as usize];
                out.extend(list.iter().copied().filter(|&n| {
                    let b = &self.boxes[n as usize];
                    b.0.x <= hi.x && b.0.y <= hi.y && b.1.x >= lo.x && b.1.y >= lo.y
                }));
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// Texture point of tile vertex `v` in the frame whose origin is the lattice point `origin`:
/// the representative plus the (exact, integer) shift relative to the frame.
fn point(reps: &[DVec3], v: TileVertex, origin: [i64; 2]) -> DVec3 {
    let r = reps[v.id as usize];
    DVec3::new(
        r.x + (v.shift[0] - origin[0]) as f64,
        r.y + (v.shift[1] - origin[1]) as f64,
        r.z,
    )
}

/// The lattice point at the integer part of a texture coordinate.
fn floor(u: DVec2) -> [i64; 2] {
    [u.x.floor() as i64, u.y.floor() as i64]
}

/// One side of a prism, oriented from the corner with the smaller welded id.
struct Side {
    /// Start and end corners (prism corner indices) of the oriented side.
    a: usize,
    b: usize,
    /// Frame origin: the lattice point at the start corner's texture coordinate.
    origin: [i64; 2],
    /// Start corner and direction in that frame.
    ua: DVec2,
    d: DVec2,
    /// +1 or −1: the prism lies where `sign · cross(d, x − ua) ≥ 0`.
    sign: f64,
    /// Start corner and direction in the prism's frame (for approximate classification).
    ua_p: DVec2,
    d_p: DVec2,
    /// No other prism shares this side.
    boundary: bool,
}

impl Side {
    /// cross(d, x − ua) for `x` in the side's frame: the canonical side value.
    fn canonical(&self, x: DVec2) -> f64 {
        self.d.x * (x.y - self.ua.y) - self.d.y * (x.x - self.ua.x)
    }

    /// Prism coordinates of the point of the side's line nearest `x` (side frame) at `w`.
    fn at(&self, x: DVec2, w: f64) -> PrismPoint {
        let r = x - self.ua;
        // Not clamped: a point beyond the side's ends lies outside a neighbouring plane, and
        // must stay there to be clipped away.
        let l = (r.x * self.d.x + r.y * self.d.y) / self.d.length_squared();
        let mut bary = [0.0; 3];
        bary[self.a] = 1.0 - l;
        bary[self.b] = l;
        PrismPoint { bary, w }
    }
}

/// A polygon vertex during clipping.
#[derive(Clone, Copy, Debug)]
struct Vert {
    /// Final prism coordinates.
    q: PrismPoint,
    /// Texture point in the prism's frame.
    tex: DVec3,
    /// Values of the five planes' inside functions (≥ 0 inside).
    f: [f64; 5],
    /// Bit i: the vertex lies exactly on plane i.
    on: u8,
}

/// What a polygon edge lies on: a tile edge (corner indices) or a clipping plane.
#[derive(Clone, Copy, Debug)]
enum Support {
    Edge(usize, usize),
    Plane(usize),
}

/// A subdivision node: prism coordinates and their exact image.
#[derive(Clone, Copy, Debug)]
struct Node {
    q: PrismPoint,
    p: DVec3,
}

/// One prism's share of the output (locally welded).
#[derive(Default)]
struct PrismOutput {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    sources: Vec<TriangleSource>,
    clipped: usize,
    depth_limited: usize,
    mirrored: bool,
    max_deviation: f64,
}

/// Everything one prism's clipping and subdivision need.
struct PrismContext<'a> {
    prism: &'a Prism,
    index: u32,
    tile: &'a PreparedTile,
    params: &'a ExplicitParams,
    /// Prism frame origin and the UV corners in it.
    origin: [i64; 2],
    corners: [DVec2; 3],
    /// Inverse of [c₁ − c₀, c₂ − c₀] (rows), for barycentric coordinates.
    inverse: [[f64; 2]; 2],
    sides: [Side; 3],
    /// Per side, its inside function at the opposite corner (> 0): the function is this times
    /// the opposite corner's barycentric coordinate.
    heights: [f64; 3],
    /// Per corner: frame origin and the corner in it.
    corner_origin: [[i64; 2]; 3],
    corner_local: [DVec2; 3],
    /// The mapping reverses orientation: swap windings.
    mirrored: bool,
}

impl<'a> PrismContext<'a> {
    fn new(
        prism: &'a Prism,
        index: u32,
        boundary: [bool; 3],
        tile: &'a PreparedTile,
        params: &'a ExplicitParams,
    ) -> Self {
        let uv = prism.uv;
        let (lo, _) = uv_bounds(prism);
        let origin = floor(lo);
        let local = |u: DVec2, o: [i64; 2]| u - DVec2::new(o[0] as f64, o[1] as f64);
        let corners = uv.map(|u| local(u, origin));
        let (e1, e2) = (corners[1] - corners[0], corners[2] - corners[0]);
        let det = e1.perp_dot(e2);
        let inverse = [[e2.y / det, -e2.x / det], [-e1.y / det, e1.x / det]];
        let uv_sign = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).signum();
        let sides = [0, 1, 2].map(|k| {
            let (i, j) = (k, (k + 1) % 3);
            let forward = (prism.welded[i], i) < (prism.welded[j], j);
            let (a, b) = if forward { (i, j) } else { (j, i) };
            let o = floor(uv[a]);
            let (ua, ub) = (local(uv[a], o), local(uv[b], o));
            Side {
                a,
                b,
                origin: o,
                ua,
                d: ub - ua,
                sign: if forward { uv_sign } else { -uv_sign },
                ua_p: corners[a],
                d_p: corners[b] - corners[a],
                boundary: boundary[k],
            }
        });
        let heights = [0, 1, 2].map(|k| {
            let s = &sides[k];
            let r = corners[(k + 2) % 3] - s.ua_p;
            s.sign * (s.d_p.x * r.y - s.d_p.y * r.x)
        });
        let corner_origin = uv.map(floor);
        let corner_local = [0, 1, 2].map(|c| local(uv[c], corner_origin[c]));
        let centre = PrismPoint {
            bary: [1.0 / 3.0; 3],
            w: 0.5,
        };
        let mirrored = prism
            .jacobian(centre)
            .is_some_and(|j| j.determinant() < 0.0);
        PrismContext {
            prism,
            index,
            tile,
            params,
            origin,
            corners,
            inverse,
            sides,
            heights,
            corner_origin,
            corner_local,
            mirrored,
        }
    }

    fn point(&self, v: TileVertex, origin: [i64; 2]) -> DVec3 {
        point(&self.tile.reps, v, origin)
    }

    /// Barycentric coordinates of a texture point in the prism's frame.
    fn bary(&self, tex: DVec3) -> [f64; 3] {
        let r = tex.truncate() - self.corners[0];
        let m = &self.inverse;
        let b1 = m[0][0] * r.x + m[0][1] * r.y;
        let b2 = m[1][0] * r.x + m[1][1] * r.y;
        [1.0 - b1 - b2, b1, b2]
    }

    /// Texture point (prism frame) of prism coordinates.
    fn texture(&self, q: PrismPoint) -> DVec3 {
        let c = &self.corners;
        (c[0] * q.bary[0] + c[1] * q.bary[1] + c[2] * q.bary[2]).extend(q.w)
    }

    /// The five inside functions at a texture point (prism frame), approximately.
    fn plane_values(&self, tex: DVec3) -> [f64; 5] {
        let mut f = [0.0; 5];
        for (k, s) in self.sides.iter().enumerate() {
            let r = tex.truncate() - s.ua_p;
            f[k] = s.sign * (s.d_p.x * r.y - s.d_p.y * r.x);
        }
        f[W0] = tex.z;
        f[W1] = 1.0 - tex.z;
        f
    }

    /// An original tile vertex, classified exactly in each side's frame.
    fn tile_vertex(&self, v: TileVertex) -> Vert {
        let tex = self.point(v, self.origin);
        let mut f = [0.0; 5];
        for (k, s) in self.sides.iter().enumerate() {
            f[k] = s.sign * s.canonical(self.point(v, s.origin).truncate());
        }
        f[W0] = tex.z;
        f[W1] = 1.0 - tex.z;
        let on = (0..5).fold(0u8, |m, i| if f[i] == 0.0 { m | 1 << i } else { m });
        let q = match on & 7 {
            0 => PrismPoint {
                bary: self.bary(tex),
                w: tex.z,
            },
            s if s.count_ones() == 1 => {
                let side = &self.sides[s.trailing_zeros() as usize];
                side.at(self.point(v, side.origin).truncate(), tex.z)
            }
            s => corner_point(corner_of(s), tex.z),
        };
        Vert { q, tex, f, on }
    }

    /// The endpoints of tile edge (i, j) of `tri` in canonical order, in the frame at `origin`.
    fn edge(&self, tri: &[TileVertex; 3], i: usize, j: usize, origin: [i64; 2]) -> (DVec3, DVec3) {
        let (p, r) = ordered(tri, i, j);
        (self.point(p, origin), self.point(r, origin))
    }

    /// The point where the polygon edge `s` → `e` lying on `support` crosses `plane`, computed
    /// from what defines it (see the module documentation), with inside-function values that
    /// every prism sharing one of its planes computes alike: on a side or at a corner, side j's
    /// value is its height times the barycentric coordinate of its opposite corner; inside,
    /// the edge endpoints' canonical side values interpolated.
    fn cut(
        &self,
        tri: &[TileVertex; 3],
        support: Support,
        plane: usize,
        s: &Vert,
        e: &Vert,
    ) -> Vert {
        let mut on = (s.on & e.on) | 1 << plane;
        if let Support::Plane(r) = support {
            on |= 1 << r;
        }
        let fixed_w = if on & 1 << W0 != 0 {
            Some(0.0)
        } else if on & 1 << W1 != 0 {
            Some(1.0)
        } else {
            None
        };
        // Fallback for degenerate configurations: interpolate between the polygon vertices.
        let t = s.f[plane] / (s.f[plane] - e.f[plane]);
        let fallback_tex = s.tex + (e.tex - s.tex) * t;
        // A cut on one side k, by a tile edge or by the tile plane's level line at w = 0 or 1:
        // on which side of each end corner of k the cutting line passes, evaluated in the
        // corner's frame as every prism around that corner does. Exactly through a corner:
        // the cut is that corner. Otherwise the signs decide, for all prisms alike, whether
        // the cut lies inside the other sides through that corner (a consistent symbolic
        // perturbation where round-off alone would not agree).
        let mut ends = None;
        if on & 7 == 1 << plane || (plane >= W0 && on & 7 != 0 && (on & 7).count_ones() == 1) {
            let k = (on & 7).trailing_zeros() as usize;
            let side = &self.sides[k];
            let predicates = match (support, fixed_w) {
                (Support::Edge(i, j), _) if plane == k => {
                    let (p, r) = self.edge(tri, i, j, side.origin);
                    let slope = (r - p).truncate().perp_dot(side.d);
                    let g = |c| self.edge_orientation(tri, i, j, c);
                    Some((g(side.a), g(side.b), slope))
                }
                (Support::Plane(_), Some(w)) => {
                    let h = |c| self.plane_height(tri, c, w);
                    let v = tri.map(|t| self.point(t, side.origin));
                    let n = (v[1] - v[0]).cross(v[2] - v[0]);
                    Some((h(side.a), h(side.b), n.x * side.d.x + n.y * side.d.y))
                }
                _ => None,
            };
            if let Some((ga, gb, slope)) = predicates {
                if ga == 0.0 {
                    on |= corner_sides(side.a);
                } else if gb == 0.0 {
                    on |= corner_sides(side.b);
                } else {
                    // Along k from a (μ = 0) to b (μ = 1) the predicate is ga + μ·slope: the cut
                    // is beyond a iff sign(ga) = −sign(slope), before b iff sign(gb) = sign(slope).
                    let beyond_a = ga.signum() * -slope.signum();
                    let before_b = gb.signum() * slope.signum();
                    ends = Some((k, beyond_a, before_b));
                }
            }
        }
        // A tile edge cut by w = 0 or 1 away from the sides: the side values of the cut are
        // the endpoints' canonical values interpolated (exactly 0: it is on that side).
        let mut interior = None;
        if let (Support::Edge(i, j), Some(c), 0) = (support, fixed_w, on & 7) {
            let (vp, vr) = ordered(tri, i, j);
            let (p, r) = (self.point(vp, self.origin), self.point(vr, self.origin));
            let t = (c - p.z) / (r.z - p.z);
            let mut f = [0.0; 3];
            for (k, side) in self.sides.iter().enumerate() {
                let fp = side.canonical(self.point(vp, side.origin).truncate());
                let fr = side.canonical(self.point(vr, side.origin).truncate());
                f[k] = side.sign * (fp + (fr - fp) * t);
                if f[k] == 0.0 {
                    on |= 1 << k;
                }
            }
            interior = Some(((p + (r - p) * t).truncate().extend(c), f));
        }
        let sides = on & 7;
        let (q, tex) = match sides.count_ones() {
            0 => {
                let tex = interior.map_or(fallback_tex, |i| i.0);
                let w = fixed_w.unwrap_or(tex.z);
                (
                    PrismPoint {
                        bary: self.bary(tex),
                        w,
                    },
                    tex,
                )
            }
            1 => {
                let k = sides.trailing_zeros() as usize;
                let side = &self.sides[k];
                let q = match support {
                    Support::Edge(i, j) => {
                        let (vp, vr) = ordered(tri, i, j);
                        let (p, r) = (self.point(vp, side.origin), self.point(vr, side.origin));
                        let t = match fixed_w {
                            Some(c) if plane >= W0 => (c - p.z) / (r.z - p.z),
                            _ => {
                                let (fp, fr) =
                                    (side.canonical(p.truncate()), side.canonical(r.truncate()));
                                fp / (fp - fr)
                            }
                        };
                        let x = p + (r - p) * t;
                        side.at(x.truncate(), fixed_w.unwrap_or(x.z))
                    }
                    Support::Plane(_) => match fixed_w {
                        Some(c) => self.side_level(tri, side, c),
                        None => None,
                    }
                    .unwrap_or_else(|| {
                        let o = side.origin;
                        let shift = DVec2::new(
                            (self.origin[0] - o[0]) as f64,
                            (self.origin[1] - o[1]) as f64,
                        );
                        side.at(fallback_tex.truncate() + shift, fallback_tex.z)
                    }),
                };
                let q = PrismPoint {
                    bary: q.bary,
                    w: fixed_w.unwrap_or(q.w),
                };
                (q, self.texture(q))
            }
            _ => {
                let c = corner_of(sides);
                let w = fixed_w.unwrap_or_else(|| {
                    // Through an edge of the tile that passes the corner exactly, from that
                    // edge (as the prisms cutting the edge itself compute it), else from the
                    // triangle's plane.
                    let edge = match support {
                        Support::Edge(i, j) => Some((i, j)),
                        Support::Plane(_) => [(0, 1), (1, 2), (2, 0)]
                            .into_iter()
                            .find(|&(i, j)| self.edge_orientation(tri, i, j, c) == 0.0),
                    };
                    let w = match edge {
                        Some((i, j)) => self.edge_at_corner(tri, i, j, c),
                        None => self.plane_at_corner(tri, c),
                    };
                    w.unwrap_or(fallback_tex.z)
                });
                let q = corner_point(c, w);
                (q, self.texture(q))
            }
        };
        let mut f = match (sides, interior) {
            (0, Some((_, f))) => [f[0], f[1], f[2], 0.0, 0.0],
            (0, None) => self.plane_values(tex),
            _ => {
                let mut f = [0.0; 5];
                for (j, h) in self.heights.iter().enumerate() {
                    let o = (j + 2) % 3;
                    f[j] = h * q.bary[o];
                    if let Some((k, beyond_a, before_b)) = ends {
                        // Side j ≠ k passes through one end of k; its value is proportional
                        // to the barycentric coordinate of the other end.
                        let side = &self.sides[k];
                        let sign = if o == side.b { beyond_a } else { before_b };
                        if j != k {
                            f[j] = sign * f[j].abs().max(f64::MIN_POSITIVE);
                        }
                    }
                }
                f
            }
        };
        f[W0] = q.w;
        f[W1] = 1.0 - q.w;
        for (i, v) in f.iter_mut().enumerate() {
            if on & (1 << i) != 0 {
                *v = 0.0;
            }
        }
        Vert { q, tex, f, on }
    }

    /// Where the tile triangle's plane meets `side` at height `w`, from the triangle's corners
    /// in the side's frame.
    fn side_level(&self, tri: &[TileVertex; 3], side: &Side, w: f64) -> Option<PrismPoint> {
        let v = tri.map(|t| self.point(t, side.origin));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let denom = n.x * side.d.x + n.y * side.d.y;
        let num = n.x * (side.ua.x - v[0].x) + n.y * (side.ua.y - v[0].y) + n.z * (w - v[0].z);
        let l = -num / denom;
        l.is_finite().then(|| side.at(side.ua + side.d * l, w))
    }

    /// Orientation of corner `c` against the (s, t) line of tile edge (i, j), in the corner's
    /// frame: zero iff the line passes exactly through the corner.
    fn edge_orientation(&self, tri: &[TileVertex; 3], i: usize, j: usize, c: usize) -> f64 {
        let (p, r) = self.edge(tri, i, j, self.corner_origin[c]);
        (r - p)
            .truncate()
            .perp_dot(self.corner_local[c] - p.truncate())
    }

    /// The tile triangle's plane function n·(x − v₀) at corner `c` and height `w`, in the
    /// corner's frame: zero iff the plane passes exactly through that point.
    fn plane_height(&self, tri: &[TileVertex; 3], c: usize, w: f64) -> f64 {
        let v = tri.map(|t| self.point(t, self.corner_origin[c]));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        n.dot(self.corner_local[c].extend(w) - v[0])
    }

    /// Height where tile edge (i, j) passes the vertical line of corner `c`, from the edge's
    /// endpoints in the corner's frame.
    fn edge_at_corner(&self, tri: &[TileVertex; 3], i: usize, j: usize, c: usize) -> Option<f64> {
        let (p, r) = self.edge(tri, i, j, self.corner_origin[c]);
        let d = (r - p).truncate();
        let t = (self.corner_local[c] - p.truncate()).dot(d) / d.length_squared();
        let w = p.z + (r.z - p.z) * t;
        w.is_finite().then_some(w)
    }

    /// Height of the tile triangle's plane on the vertical line of corner `c`.
    fn plane_at_corner(&self, tri: &[TileVertex; 3], c: usize) -> Option<f64> {
        let v = tri.map(|t| self.point(t, self.corner_origin[c]));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let u = self.corner_local[c];
        let w = v[0].z - (n.x * (u.x - v[0].x) + n.y * (u.y - v[0].y)) / n.z;
        w.is_finite().then_some(w)
    }

    /// Clips one tile triangle copy into `poly` (left empty when nothing is inside).
    fn clip(&self, tri: &[TileVertex; 3], verts: [Vert; 3], poly: &mut Vec<(Vert, Support)>) {
        poly.clear();
        poly.extend([
            (verts[0], Support::Edge(0, 1)),
            (verts[1], Support::Edge(1, 2)),
            (verts[2], Support::Edge(2, 0)),
        ]);
        let mut next = Vec::with_capacity(8);
        for plane in 0..5 {
            if poly.iter().all(|(v, _)| v.f[plane] >= 0.0) {
                continue;
            }
            if poly.iter().all(|(v, _)| v.f[plane] <= 0.0) {
                poly.clear();
                return;
            }
            next.clear();
            let n = poly.len();
            for i in 0..n {
                let (s, support) = poly[i];
                let e = poly[(i + 1) % n].0;
                let (fs, fe) = (s.f[plane], e.f[plane]);
                if fs >= 0.0 {
                    let out = if fs == 0.0 && fe < 0.0 {
                        Support::Plane(plane)
                    } else {
                        support
                    };
                    next.push((s, out));
                }
                if fs > 0.0 && fe < 0.0 {
                    next.push((self.cut(tri, support, plane, &s, &e), Support::Plane(plane)));
                } else if fs < 0.0 && fe > 0.0 {
                    next.push((self.cut(tri, support, plane, &s, &e), support));
                }
            }
            std::mem::swap(poly, &mut next);
        }
    }

    /// Whether a clipped polygon whose vertices all lie on the planes `common` is kept: only
    /// a tile face lying in one plane, and in a shared side only in the prism it faces out of.
    fn keep_flat(&self, tri: &[TileVertex; 3], verts: &[Vert; 3], common: u8) -> bool {
        if common.count_ones() != 1 || verts.iter().any(|v| v.on & common == 0) {
            return false;
        }
        let k = common.trailing_zeros() as usize;
        if k >= W0 || self.sides[k].boundary {
            return true;
        }
        let side = &self.sides[k];
        let v = tri.map(|t| self.point(t, self.origin));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        // Inward normal of the side: the gradient of its inside function.
        let inward = DVec2::new(-side.d_p.y, side.d_p.x) * side.sign;
        n.truncate().dot(inward) < 0.0
    }

    fn run(&self) -> PrismOutput {
        let mut out = PrismOutput {
            mirrored: self.mirrored,
            ..Default::default()
        };
        let mut welded: HashMap<[u64; 3], u32> = HashMap::new();
        let (lo, hi) = uv_bounds(self.prism);
        let slack = 1e-9 * (1.0 + lo.abs().max(hi.abs()).max_element());
        let (t_lo, t_hi) = (self.tile.lo, self.tile.hi);
        let m0 = (lo - t_hi - slack).ceil();
        let m1 = (hi - t_lo + slack).floor();
        let mut candidates = Vec::new();
        let mut poly = Vec::with_capacity(8);
        let mut n = m0.y;
        while n <= m1.y {
            let mut m = m0.x;
            while m <= m1.x {
                let offset = DVec2::new(m, n);
                self.tile
                    .query(lo - offset - slack, hi - offset + slack, &mut candidates);
                let shift = [m as i64, n as i64];
                for &c in &candidates {
                    let tri = self.tile.corners[c as usize].map(|v| TileVertex {
                        id: v.id,
                        shift: [v.shift[0] + shift[0], v.shift[1] + shift[1]],
                    });
                    self.triangle(&tri, &mut poly, &mut welded, &mut out);
                }
                m += 1.0;
            }
            n += 1.0;
        }
        out
    }

    /// Clips, triangulates, subdivides and emits one tile triangle copy.
    fn triangle(
        &self,
        tri: &[TileVertex; 3],
        poly: &mut Vec<(Vert, Support)>,
        welded: &mut HashMap<[u64; 3], u32>,
        out: &mut PrismOutput,
    ) {
        let verts = tri.map(|v| self.tile_vertex(v));
        if (0..5).any(|i| verts.iter().all(|v| v.f[i] < 0.0)) {
            return;
        }
        if verts.iter().any(|v| v.f.iter().any(|&f| f < 0.0)) {
            out.clipped += 1;
        }
        self.clip(tri, verts, poly);
        poly.dedup_by(|a, b| same_point(&a.0.q, &b.0.q));
        while poly.len() > 1 && same_point(&poly[0].0.q, &poly[poly.len() - 1].0.q) {
            poly.pop();
        }
        if poly.len() < 3 {
            return;
        }
        let common = poly.iter().fold(0x1f, |m, (v, _)| m & v.on);
        if common != 0 && !self.keep_flat(tri, &verts, common) {
            return;
        }
        let node = |v: &Vert| Node {
            q: v.q,
            p: self.prism.point(v.q),
        };
        let first = node(&poly[0].0);
        let mut previous = node(&poly[1].0);
        for (v, _) in &poly[2..] {
            let current = node(v);
            self.refine([first, previous, current], 0, welded, out);
            previous = current;
        }
    }

    /// The split decision for edge (a, b): its texture midpoint's node when it splits, and
    /// the deviation measured. Symmetric in a and b.
    fn split(&self, a: &Node, b: &Node) -> (Option<Node>, f64) {
        let q = PrismPoint {
            bary: [0, 1, 2].map(|i| (a.q.bary[i] + b.q.bary[i]) * 0.5),
            w: (a.q.w + b.q.w) * 0.5,
        };
        let p = self.prism.point(q);
        let deviation = (p - (a.p + b.p) * 0.5).length();
        let extent = (0..3)
            .map(|i| (a.q.bary[i] - b.q.bary[i]).abs())
            .fold((a.q.w - b.q.w).abs(), f64::max);
        let splits = deviation > self.params.tolerance && extent > MIN_EXTENT;
        (splits.then_some(Node { q, p }), deviation)
    }

    fn refine(
        &self,
        t: [Node; 3],
        depth: u32,
        welded: &mut HashMap<[u64; 3], u32>,
        out: &mut PrismOutput,
    ) {
        let decisions = [0, 1, 2].map(|e| self.split(&t[e], &t[(e + 1) % 3]));
        let count = decisions.iter().filter(|d| d.0.is_some()).count();
        if count == 0 || depth == MAX_DEPTH {
            if count > 0 {
                out.depth_limited += 1;
            }
            let deviation = decisions.iter().fold(0.0f64, |m, d| m.max(d.1));
            out.max_deviation = out.max_deviation.max(deviation);
            self.emit(t, welded, out);
            return;
        }
        let mids = decisions.map(|d| d.0);
        let next = depth + 1;
        let mut recurse = |t: [Node; 3]| self.refine(t, next, welded, out);
        match count {
            1 => {
                // Rotate so that edge 0 (a → b) splits.
                let e = mids.iter().position(Option::is_some).unwrap_or(0);
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let m = mids[e].unwrap_or(a);
                recurse([a, m, c]);
                recurse([m, b, c]);
            }
            2 => {
                // Rotate so that edge 2 (c → a) is the one kept.
                let keep = mids.iter().position(Option::is_none).unwrap_or(2);
                let e = (keep + 1) % 3;
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let (m1, m2) = (mids[e].unwrap_or(a), mids[(e + 1) % 3].unwrap_or(b));
                recurse([m1, b, m2]);
                if (m2.p - a.p).length_squared() <= (c.p - m1.p).length_squared() {
                    recurse([a, m1, m2]);
                    recurse([a, m2, c]);
                } else {
                    recurse([a, m1, c]);
                    recurse([m1, m2, c]);
                }
            }
            _ => {
                let [ab, bc, ca] = [0, 1, 2].map(|e| mids[e].unwrap_or(t[e]));
                recurse([t[0], ab, ca]);
                recurse([ab, t[1], bc]);
                recurse([ca, bc, t[2]]);
                recurse([ab, bc, ca]);
            }
        }
    }

    /// Appends a final triangle (windings swapped where the mapping mirrors).
    fn emit(&self, t: [Node; 3], welded: &mut HashMap<[u64; 3], u32>, out: &mut PrismOutput) {
        let t = if self.mirrored { [t[0], t[2], t[1]] } else { t };
        let ids = t.map(|n| {
            let next = out.positions.len() as u32;
            *welded.entry(position_key(n.p)).or_insert_with(|| {
                out.positions.push(n.p);
                next
            })
        });
        out.triangles.push(ids);
        if self.params.record_texture {
            out.sources.push(TriangleSource {
                prism: self.index,
                texture: t.map(|n| self.prism.texture(n.q)),
            });
        }
    }
}

/// The endpoints of tile edge (i, j) of `tri` in canonical order.
fn ordered(tri: &[TileVertex; 3], i: usize, j: usize) -> (TileVertex, TileVertex) {
    if tri[i] < tri[j] {
        (tri[i], tri[j])
    } else {
        (tri[j], tri[i])
    }
}

/// Whether two prism points are bit-identical.
fn same_point(a: &PrismPoint, b: &PrismPoint) -> bool {
    a.w == b.w && a.bary == b.bary
}

/// The corner shared by the sides in the bit set `sides` (at least two bits).
fn corner_of(sides: u8) -> usize {
    match sides & 7 {
        0b110 => 2,
        0b101 => 0,
        _ => 1,
    }
}

/// The bits of the two sides that meet at corner `c` (side k runs from corner k to k+1).
fn corner_sides(c: usize) -> u8 {
    1 << c | 1 << ((c + 2) % 3)
}

/// Prism coordinates of corner `c` at height `w`.
fn corner_point(c: usize, w: f64) -> PrismPoint {
    let mut bary = [0.0; 3];
    bary[c] = 1.0;
    PrismPoint { bary, w }
}

/// Everything an export reads: base mesh, shell parameters, tile and tile height.
#[derive(Clone, Debug)]
pub struct ExplicitInput {
    /// The validated base mesh.
    pub base: BaseMesh,
    /// How the base mesh is extruded.
    pub shell: ShellParams,
    /// The tile in tile units.
    pub tile: TriMesh,
    /// The tile's height H (tile units): its z ∈ [0, H] fills the shell.
    pub tile_height: f64,
}

impl ExplicitInput {
    /// Reads a base mesh OBJ and a tile OBJ. Without `thickness`, the shell is
    /// [`proportional_thickness`] thick.
    pub fn from_files(
        mesh: &Path,
        tile: &Path,
        thickness: Option<f64>,
        tiles_per_uv: [f64; 2],
        tile_height: f64,
        limits: &Limits,
    ) -> Result<ExplicitInput> {
        let (base, _) = BaseMesh::read_obj(mesh, limits)?;
        let tile = TriMesh::read_obj(tile, limits.memory_bytes / 8)?;
        let thickness = match thickness {
            Some(h) => h,
            None => proportional_thickness(&base, tiles_per_uv, tile_height)?,
        };
        Ok(ExplicitInput {
            base,
            shell: ShellParams {
                thickness,
                tiles_per_uv,
                smoothing: 0,
            },
            tile,
            tile_height,
        })
    }

    /// Builds the shell and exports; `tolerance` defaults to
    /// [`DEFAULT_RELATIVE_TOLERANCE`] × thickness.
    pub fn export(
        &self,
        tolerance: Option<f64>,
        record_texture: bool,
        limits: &Limits,
        observer: &dyn BakeObserver,
    ) -> Result<(Shell, Explicit)> {
        let shell = Shell::new(&self.base, self.shell)?;
        let params = ExplicitParams {
            tile_height: self.tile_height,
            tolerance: tolerance.unwrap_or(DEFAULT_RELATIVE_TOLERANCE * self.shell.thickness),
            record_texture,
        };
        let explicit = export(&shell, &self.tile, &params, limits, observer)?;
        Ok((shell, explicit))
    }
}

/// The shell thickness that keeps a tile's proportions: H times the tile's mean edge length
/// in object units, √(object area / area in tiles) over the base mesh.
pub fn proportional_thickness(
    base: &BaseMesh,
    tiles_per_uv: [f64; 2],
    tile_height: f64,
) -> Result<f64> {
    let (mut object, mut texture) = (0.0, 0.0);
    for t in &base.triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let p = [a, b, c].map(|i| base.positions[i]);
        let u = [a, b, c].map(|i| base.uvs[i] * DVec2::from(tiles_per_uv));
        object += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        texture += 0.5 * (u[1] - u[0]).perp_dot(u[2] - u[0]).abs();
    }
    let h = tile_height * (object / texture).sqrt();
    if h.is_finite() && h > 0.0 {
        Ok(h)
    } else {
        Err(Error::InvalidParameter(format!(
            "cannot derive a shell thickness from the base mesh's UV area ({texture} tiles²); \
             pass --thickness"
        )))
    }
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
