//! The tile as the export reads it: vertices welded modulo the lattice (each a representative
//! position and an integer lattice shift) and triangles binned by their (s, t) bounds (step 1
//! of the algorithm in the parent module).

use super::*;

/// A tile vertex: a welded representative plus an integer lattice shift. Ordered by (id,
/// shift), the canonical order of an edge's endpoints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct TileVertex {
    pub(super) id: u32,
    pub(super) shift: [i64; 2],
}

/// The tile welded modulo the lattice and binned for lookups.
pub(super) struct PreparedTile {
    /// Representative of each welded vertex: x, y in tile units, w = z / H.
    pub(super) reps: Vec<DVec3>,
    /// Corners of each triangle.
    pub(super) corners: Vec<[TileVertex; 3]>,
    /// (s, t) bounds of each triangle.
    pub(super) boxes: Vec<(DVec2, DVec2)>,
    /// Bounds of the whole tile.
    pub(super) lo: DVec2,
    pub(super) hi: DVec2,
    /// Bins: `cells` × `cells` over [lo, hi], CSR lists of triangle indices.
    pub(super) cells: usize,
    pub(super) starts: Vec<u32>,
    pub(super) items: Vec<u32>,
}

impl PreparedTile {
    pub(super) fn new(mesh: &TriMesh, height: f64) -> Result<PreparedTile> {
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
    pub(super) fn cell(&self, p: DVec2) -> (usize, usize) {
        let size = (self.hi - self.lo).max(DVec2::splat(1e-300));
        let c = ((p - self.lo) / size * self.cells as f64).floor();
        let clamp = |x: f64| (x.max(0.0) as usize).min(self.cells - 1);
        (clamp(c.x), clamp(c.y))
    }

    /// Triangles whose bounds overlap [lo, hi] (tile-local), ascending, into `out`.
    pub(super) fn query(&self, lo: DVec2, hi: DVec2, out: &mut Vec<u32>) {
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
pub(super) fn point(reps: &[DVec3], v: TileVertex, origin: [i64; 2]) -> DVec3 {
    let r = reps[v.id as usize];
    DVec3::new(
        r.x + (v.shift[0] - origin[0]) as f64,
        r.y + (v.shift[1] - origin[1]) as f64,
        r.z,
    )
}

/// The lattice point at the integer part of a texture coordinate.
pub(super) fn floor(u: DVec2) -> [i64; 2] {
    [u.x.floor() as i64, u.y.floor() as i64]
}
