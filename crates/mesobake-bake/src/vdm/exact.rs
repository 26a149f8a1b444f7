//! The exact VDM bake: every ray cast against the relief bent to its curvature ([`Bend`]),
//! solved in closed form per bilinear cell.
//!
//! All rays entering at one texel along one azimuth φ on one curvature c lie in one plane and
//! share one line of texture space, p + σ·(cos φ, sin φ). Along that line the relief's depth
//! D(σ) is quadratic inside each cell of the bilinear interpolation (the patch between four
//! texel centres). A ray entering at polar angle θ lies at depth
//! t(σ) = R·(1 − sin θ / sin(θ + σ/R)) below the reference surface bent to radius R = 1/c
//! (σ·cot θ on the flat surface, c = 0). Texel centres lie on grid points, so the lines from
//! all of them along one azimuth cross the grid at the same σ: the cells are walked once per
//! azimuth ([`Course`]), and each texel's line only looks up the heights at their corners.
//! Every curvature's rays then march over them ([`Fans`]), and three orderings spare the
//! march work:
//!
//! - rays from one point in one plane never cross, so a steeper ray lies below a shallower one
//!   everywhere and hits no later along the line: each ray's search starts where the last hit;
//! - t(σ) falls as c grows at every σ (a more convex surface curves away from the ray), so a
//!   ray hits no earlier than on a flatter surface: the curvatures march in ascending order,
//!   and a ray's march starts at the cell where its flatter twin was settled and its search
//!   where that twin hit;
//! - t rises with σ up to a convex surface's turning point and falls after it symmetrically,
//!   so the first σ where a ray reaches each of `LAYERS` depths, tabled per ray, rules out
//!   without a sine every cell whose highest corner it reaches only after leaving the cell or
//!   has climbed back above before entering it, and, in a cell looked at, every ray that does
//!   not lie below the relief's highest point along the line there.
//!
//! Where the relief's depth does not change along the line in a cell (a flat cell), a ray
//! hits where it first reaches that depth, in closed form (`BentRay::first_at_depth`; tabled
//! per ray for the relief's most common plateaus). In any other cell not ruled out, the
//! search follows the sign of the gap g(σ) = D(σ) − t(σ) scaled by x = sin(θ + σc)/sin θ > 0,
//! G = R − (R − D)·x, which needs no division. The root of G's quadratic model is tried
//! first: where Newton's step from it is within a quarter of [`TOLERANCE`], it is the hit.
//! Else, where G is negative there or at the cell's end, Newton steps kept inside the bracket
//! find the crossing to [`TOLERANCE`]. Where it is positive at both ends, the gap is bounded
//! from below (the ray under its chord or tangent, `first_crossing`), and where the bound
//! cannot rule a dip out, the cell is halved until it can or is shorter than [`TOLERANCE`] (a
//! touch, not a crossing). A convex surface's ray that climbs back out through the reference
//! surface (at σ = R·(π − 2θ)) without meeting the relief is [`NO_HIT`], and so is every
//! shallower ray of its fan.

use super::bend::Bend;
use super::{NO_HIT, Relief, VdmGrid, bake_by_azimuth};
use crate::mesostructure::height_field::HeightField;
use mesobake_core::error::Result;
use mesobake_core::observer::BakeObserver;
use std::f64::consts::PI;

/// Largest error of a hit's arc length σ along the reference surface (tile units).
pub const TOLERANCE: f64 = 1e-7;

/// Bakes every fan (texel, azimuth, curvature): azimuths in parallel, and at each texel
/// every curvature over one walk of the line's cells ([`Fans::cast_from`]).
pub fn bake(relief: Relief, grid: VdmGrid, observer: &dyn BakeObserver) -> Result<Vec<f32>> {
    let (thetas, curvatures) = (grid.thetas(), grid.curvatures());
    let fans = Fans::new(relief, &thetas, &curvatures);
    let per_texel = thetas.len() * curvatures.len();
    bake_by_azimuth(
        relief.field.size(),
        grid,
        observer,
        |b| {
            let course = fans.course(grid.phi(b));
            (course, vec![None; per_texel], Scratch::default())
        },
        |(course, hits, scratch), texel, out| {
            fans.cast_from(course, texel, hits, scratch);
            for (value, hit) in out.iter_mut().zip(hits.iter()) {
                *value = hit.map_or(NO_HIT, |d| d as f32);
            }
        },
    )
}

/// The VDM value of the ray entering at texture point `p` at angles (θ, φ) on the relief
/// bent by `bend`: l / sin θ, l the arc length to the hit; `None` without a hit.
pub fn cast(relief: Relief, p: [f64; 2], theta: f64, phi: f64, bend: Bend) -> Option<f64> {
    let mut hit = [None];
    Fans::new(relief, &[theta], &[bend.c]).cast(p, phi, &mut hit, &mut Scratch::default());
    hit[0]
}

/// The rays of one set of polar angles θ on one relief bent to each of a set of curvatures,
/// prepared once: cast together from any entry point along any azimuth, in one march along
/// the line for every curvature.
pub struct Fans<'a> {
    relief: Relief<'a>,
    layers: Layers,
    /// Per curvature, ascending.
    fans: Vec<Fan>,
    /// Per ray of every fan (curvature k's ray a at k·Nθ + a), where it first reaches the
    /// top of each of the [`LAYERS`], i·depth/[`LAYERS`] (rounded down; infinity for a convex
    /// surface's ray that never does): what a march looks up at every cell.
    reach: Vec<[f64; LAYERS]>,
    /// The depths of the most common flat cells ([`plateaus`]).
    plateaus: Vec<f64>,
    /// Where every march ends: every ray hits the floor (depth) by depth · tan θ on a flat
    /// or concave surface, and a convex one's leaves before; a cap against rounding only.
    cap: f64,
}

/// The rays of a [`Fans`] on one curvature.
struct Fan {
    c: f64,
    rays: Vec<BentRay>,
    /// Per ray, where it first reaches each of the plateaus (exactly): ray a's at
    /// a·plateaus + i.
    plateau_reach: Vec<f64>,
}

/// The depth layers the march's bounds are rounded to, layer i from i·depth/[`LAYERS`] down
/// (a cell whose highest corner lies in layer i is passed over by a ray that has not reached
/// layer i's top).
const LAYERS: usize = 256;

/// The last of the [`LAYERS`] whose top lies at or above `fraction` of the relief's depth
/// (rounded down).
fn layer(fraction: f64) -> u8 {
    (fraction * LAYERS as f64 * (1.0 - 1e-9)).clamp(0.0, (LAYERS - 1) as f64) as u8
}

impl<'a> Fans<'a> {
    /// The fans of `thetas` (ascending, in (0, π/2)) on `relief` bent to each of
    /// `curvatures` (ascending).
    pub fn new(relief: Relief<'a>, thetas: &[f64], curvatures: &[f64]) -> Fans<'a> {
        debug_assert!(thetas.is_sorted() && curvatures.is_sorted());
        let plateaus = plateaus(relief);
        let fans = curvatures
            .iter()
            .map(|&c| {
                let rays: Vec<BentRay> = thetas.iter().map(|&th| BentRay::new(th, c)).collect();
                let plateau_reach = rays
                    .iter()
                    .flat_map(|ray| plateaus.iter().map(|&depth| ray.reach(depth)))
                    .collect();
                Fan {
                    c,
                    rays,
                    plateau_reach,
                }
            })
            .collect::<Vec<_>>();
        let rays = || fans.iter().flat_map(|fan| &fan.rays);
        let reach = rays()
            .map(|ray| {
                std::array::from_fn(|i| {
                    ray.reach(relief.depth * i as f64 / LAYERS as f64) * (1.0 - 1e-9)
                })
            })
            .collect();
        let cap = thetas.last().map_or(0.0, |th| relief.depth * th.tan()) + 4.0;
        Fans {
            relief,
            layers: Layers::new(relief.field),
            fans,
            reach,
            plateaus,
            cap,
        }
    }

    /// Where ray `a` of `fan` first lies `depth` deep: tabled for the plateaus.
    fn reach_of(&self, fan: &Fan, a: usize, depth: f64) -> f64 {
        match self.plateaus.iter().position(|&plateau| plateau == depth) {
            Some(i) => fan.plateau_reach[a * self.plateaus.len() + i],
            None => fan.rays[a].reach(depth),
        }
    }

    /// The cells of the lines from the texel centres along azimuth `phi`, as far as a march
    /// may need them ([`Fans::cast_from`]).
    pub fn course(&self, phi: f64) -> Course {
        self.course_from([0.0; 2], phi)
    }

    /// The same from `fraction` of a cell past any grid point (grid units).
    fn course_from(&self, fraction: [f64; 2], phi: f64) -> Course {
        let curvatures: Vec<f64> = self.fans.iter().map(|fan| fan.c).collect();
        let size = self.relief.field.size();
        Course::new(size, fraction, phi, self.cap, &curvatures)
    }

    /// The VDM values of every curvature's rays entering at `p` along azimuth `phi`, written
    /// to `out` by curvature, then θ (as [`cast`] gives them).
    pub fn cast(&self, p: [f64; 2], phi: f64, out: &mut [Option<f64>], scratch: &mut Scratch) {
        let (w, h) = self.relief.field.size();
        // In grid units (texel centres at integers): the grid point at or below, wrapped
        // into the tile, and how far past it.
        let start = [p[0] * f64::from(w) - 0.5, p[1] * f64::from(h) - 0.5];
        let below = start.map(f64::floor);
        let texel = [0, 1].map(|axis| (below[axis] as i64).rem_euclid([w, h][axis].into()) as u32);
        let fraction = [0, 1].map(|axis| start[axis] - below[axis]);
        let course = self.course_from(fraction, phi);
        self.cast_from(&course, texel, out, scratch);
    }

    /// The VDM values of every curvature's rays entering along `course` from the grid point
    /// at `texel`, written to `out` by curvature, then θ.
    ///
    /// The line's cells are walked once, as far as any curvature needs them, and kept; each
    /// curvature then marches over them in turn, the flattest first. On a more convex surface
    /// a ray lies shallower all along (t(σ) falls as c grows), so it hits no earlier than on
    /// the flatter one: its march starts at the cell where that ray was settled, and its
    /// search where that ray hit.
    pub fn cast_from(
        &self,
        course: &Course,
        texel: [u32; 2],
        out: &mut [Option<f64>],
        scratch: &mut Scratch,
    ) {
        let n = self.fans.first().map_or(0, |fan| fan.rays.len());
        debug_assert_eq!(out.len(), n * self.fans.len());
        out.fill(None);
        let Scratch {
            cells,
            pieces,
            settled,
        } = scratch;
        settled.clear();
        settled.resize(out.len(), NEVER);
        cells.clear();
        pieces.clear();
        let mut walk = Walk {
            course,
            texel,
            cells,
            pieces,
        };
        for k in 0..self.fans.len() {
            self.march(k, &mut walk, out, settled);
        }
        // Arc lengths to VDM values, l / sin θ.
        for (fan, out) in self.fans.iter().zip(out.chunks_exact_mut(n.max(1))) {
            for (ray, hit) in fan.rays.iter().zip(out) {
                *hit = hit.map(|l| l * ray.cosec_theta);
            }
        }
    }

    /// Marches curvature `k`'s rays over the line's cells, the steepest first, each from
    /// where the one before hit: arc lengths to `out` (`None` for no hit), and the cell where
    /// each ray was settled (hit, or left the relief) to `settled`. The flatter curvature's
    /// are settled already.
    fn march(&self, k: usize, walk: &mut Walk, out: &mut [Option<f64>], settled: &mut [usize]) {
        let fan = &self.fans[k];
        let (n, c) = (fan.rays.len(), fan.c);
        let (out_before, out) = out.split_at_mut(k * n);
        let (settled_before, settled) = settled.split_at_mut(k * n);
        let flatter = k
            .checked_sub(1)
            .map(|f| (&out_before[f * n..], &settled_before[f * n..]));
        let (out, settled) = (&mut out[..n], &mut settled[..n]);
        let course = walk.course;
        // The cell the march is in; the sines at the start of the last cell searched in, and
        // at the last hit in it.
        let mut i = 0;
        let (mut looked, mut bent, mut last) = (NEVER, Bent::START, Bent::START);
        let mut previous = 0.0;
        let mut a = 0;
        'rays: while a < n {
            let ray_index = k * n + a;
            // Where the flatter surface's ray `a` hit, short by the tolerance (0 if it left
            // the relief); this one is not looked for before the cell where that was settled.
            let beyond = match flatter {
                Some((hits, settled_at)) => {
                    if settled_at[a] == NEVER {
                        return;
                    }
                    i = i.max(settled_at[a]);
                    hits[a].map_or(0.0, |hit| (hit - 2.0 * TOLERANCE).max(0.0))
                }
                None => 0.0,
            };
            // The search starts no earlier than this.
            let floor = later(beyond, previous);
            let reach = &self.reach[ray_index];
            let ray = &fan.rays[a];
            loop {
                // Past the cells the ray does not reach within (it reaches their highest
                // corner's layer after leaving them, or climbs back above it before entering),
                // or where its search would start beyond them, to the first it may hit in.
                let Some(skip) = walk.cells[i..].iter().position(|cell| {
                    let (from, reached) =
                        (later(cell.start, floor), reach[usize::from(cell.layer)]);
                    cell.start >= ray.end
                        || (cell.end >= reached && from <= ray.mirror - reached && from < cell.end)
                }) else {
                    i = walk.cells.len();
                    if walk.extend(&self.layers) {
                        continue;
                    }
                    // The line ended first.
                    return;
                };
                i += skip;
                let cell = &walk.cells[i];
                let (from, end) = (later(cell.start, floor), cell.end);
                if from >= ray.end {
                    // It left the relief, and so does every shallower ray.
                    settled[a..].fill(i);
                    return;
                }
                // The cell needs a closer look: its piece.
                let piece = walk.piece(self.relief, i);
                let to = if end < ray.last { end } else { ray.last };
                let hit = if let Some(depth) = piece.constant() {
                    ray.first_at_depth(self.reach_of(fan, a, depth), from, to)
                } else if to < reach[usize::from(piece.layer)]
                    || from > ray.mirror - reach[usize::from(piece.layer)]
                {
                    None
                } else {
                    // The sines at the cell's start, where the search first needs them.
                    if looked != i {
                        bent = course.bent(k, i);
                        (looked, last) = (i, bent);
                    }
                    first_crossing(piece, bent, ray, last.advanced(c, from), to).map(|at| {
                        last = at;
                        at.sigma
                    })
                };
                match hit {
                    Some(hit) => {
                        (out[a], settled[a], previous) = (Some(hit), i, hit);
                        a += 1;
                        continue 'rays;
                    }
                    None => i += 1,
                }
            }
        }
    }
}

/// The later of two σ (never NaN), without `f64::max`'s care for NaN, in the march's inner
/// loops.
fn later(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

/// The cell index of a ray never settled.
const NEVER: usize = usize::MAX;

/// What a march ([`Fans::cast_from`]) keeps, held between marches so that they allocate nothing.
#[derive(Default)]
pub struct Scratch {
    /// The line's cells walked so far, and the pieces of those looked at closely.
    cells: Vec<Cell>,
    pieces: Vec<Option<Piece>>,
    /// Per ray (as in [`Fans::reach`]), the cell where it was settled, or [`NEVER`].
    settled: Vec<usize>,
}

/// One bilinear cell along the line: what a ray's march checks at every cell (its span
/// copied from the [`Course`] beside the line's own layer, so that the scan reads one array).
struct Cell {
    /// Where the line enters and leaves it (σ).
    start: f64,
    end: f64,
    /// Its highest corner's layer ([`Layers`]).
    layer: u8,
}

/// The cells a line crosses from `fraction` of a cell past a grid point along one azimuth:
/// the same for every grid point, so walked once per azimuth and shared by the lines from
/// every texel centre.
pub struct Course {
    /// Where the line enters and leaves each cell (σ).
    spans: Vec<[f64; 2]>,
    /// Where each cell lies.
    places: Vec<Place>,
    /// sin and cos of σ·c where the line enters each cell, on each of the fans' curvatures
    /// (curvature k's at k·cells + i): where a search starts from.
    sines: Vec<[f64; 2]>,
    /// The line's speed (grid units per unit of σ), and the tile's size (texels).
    speed: [f64; 2],
    size: [u32; 2],
}

/// Where a cell of a [`Course`] lies: its lower corner, offset from the grid point the line
/// starts from and wrapped into the tile, and the line's position within it where it enters.
struct Place {
    offset: [u32; 2],
    entry: [f64; 2],
}

impl Course {
    /// The cells of a tile of `w` × `h` texels crossed by the line from `fraction` (grid
    /// units) past a grid point along azimuth `phi`, up to σ = `cap`, with the sines on each
    /// of `curvatures`.
    fn new(
        (w, h): (u32, u32),
        fraction: [f64; 2],
        phi: f64,
        cap: f64,
        curvatures: &[f64],
    ) -> Course {
        let mut line = Line::new([w, h], fraction, phi);
        let (mut spans, mut places) = (Vec::new(), Vec::new());
        let mut start = 0.0;
        while start < cap {
            let end = line.cell_exit().min(cap);
            spans.push([start, end]);
            places.push(Place {
                offset: line.texel.map(|t| t as u32),
                entry: [0, 1].map(|axis| {
                    line.start[axis] + line.speed[axis] * start - line.cell[axis] as f64
                }),
            });
            line.step(end);
            start = end;
        }
        let sines = curvatures
            .iter()
            .flat_map(|&c| {
                spans.iter().map(move |&[start, _]| {
                    let Bent { sin, cos, .. } = Bent::at(c, start);
                    [sin, cos]
                })
            })
            .collect();
        Course {
            spans,
            places,
            sines,
            speed: line.speed,
            size: [w, h],
        }
    }

    /// The sines of σ·c where the line enters cell `cell`, on curvature `k`.
    fn bent(&self, k: usize, cell: usize) -> Bent {
        let [sin, cos] = self.sines[k * self.spans.len() + cell];
        Bent {
            sigma: self.spans[cell][0],
            sin,
            cos,
        }
    }

    /// The texel at the lower corner of cell `cell` of the line from the grid point at
    /// `texel`.
    fn corner(&self, texel: [u32; 2], cell: usize) -> [usize; 2] {
        let offset = self.places[cell].offset;
        [0, 1].map(|axis| {
            let (texel, size) = (texel[axis] + offset[axis], self.size[axis]);
            (if texel >= size { texel - size } else { texel }) as usize
        })
    }

    /// The relief's depth along the line from the grid point at `texel` across its cell
    /// `cell`.
    fn piece(&self, relief: Relief, texel: [u32; 2], cell: usize) -> Piece {
        let [from, to] = self.spans[cell];
        let field = relief.field;
        let [w, h] = self.size.map(|n| n as usize);
        let [i, j] = self.corner(texel, cell);
        let (i1, j1) = (
            if i + 1 == w { 0 } else { i + 1 },
            if j + 1 == h { 0 } else { j + 1 },
        );
        let heights = field.heights();
        let at = |i: usize, j: usize| f64::from(heights[j * w + i]);
        let (h00, h10, h01, h11) = (at(i, j), at(i1, j), at(i, j1), at(i1, j1));
        // Position within the cell at `from`, and its rate per unit of σ.
        let [x0, y0] = self.places[cell].entry;
        let [ex, ey] = self.speed;
        let (bx, by, k) = (h10 - h00, h01 - h00, h11 - h10 - h01 + h00);
        let height = [
            h00 + bx * x0 + by * y0 + k * x0 * y0,
            bx * ex + by * ey + k * (x0 * ey + y0 * ex),
            k * ex * ey,
        ];
        let depth = relief.depth;
        let d = [
            depth * (1.0 - height[0]),
            -depth * height[1],
            -depth * height[2],
        ];
        let shallowest = least_on(d[0], d[1], d[2], to - from).1;
        Piece {
            from,
            to,
            d,
            shallowest,
            layer: layer(shallowest / depth),
        }
    }
}

/// The cells of one texel's line along a [`Course`], walked on as far as a march asks for
/// them.
struct Walk<'s> {
    course: &'s Course,
    /// The grid point the line starts from.
    texel: [u32; 2],
    cells: &'s mut Vec<Cell>,
    pieces: &'s mut Vec<Option<Piece>>,
}

impl Walk<'_> {
    /// Cells walked at a time.
    const STRIDE: usize = 8;

    /// Walks [`Walk::STRIDE`] cells further, or fewer where the course ends; `false` if it
    /// had already.
    fn extend(&mut self, layers: &Layers) -> bool {
        let walked = self.cells.len();
        let course = self.course;
        let to = (walked + Self::STRIDE).min(course.spans.len());
        for (i, &[start, end]) in course.spans.iter().enumerate().take(to).skip(walked) {
            self.cells.push(Cell {
                start,
                end,
                layer: layers.of(course.corner(self.texel, i)),
            });
            self.pieces.push(None);
        }
        to > walked
    }

    /// The relief's depth along the line in cell `i` (walked already).
    fn piece(&mut self, relief: Relief, i: usize) -> &Piece {
        let (course, texel) = (self.course, self.texel);
        self.pieces[i].get_or_insert_with(|| course.piece(relief, texel, i))
    }
}

/// The depths of the flat cells (four equal corners) of `relief` that are most common (up
/// to four), as [`Course::piece`] computes them.
fn plateaus(relief: Relief) -> Vec<f64> {
    let mut counts: Vec<(f32, usize)> = Vec::new();
    for [corner, rest @ ..] in cell_corners(relief.field) {
        if rest == [corner; 3] {
            match counts.iter().position(|(height, _)| *height == corner) {
                Some(i) => counts[i].1 += 1,
                None if counts.len() < 64 => counts.push((corner, 1)),
                None => {}
            }
        }
    }
    counts.sort_by_key(|&(_, count)| std::cmp::Reverse(count));
    counts
        .iter()
        .take(4)
        .map(|&(height, _)| relief.depth * (1.0 - f64::from(height)))
        .collect()
}

/// The heights at the four corners of every bilinear cell of `field` (periodic), the cell
/// whose lower corner is texel (i, j) at j·W + i: (i, j), (i + 1, j), (i, j + 1),
/// (i + 1, j + 1).
fn cell_corners(field: &HeightField) -> impl Iterator<Item = [f32; 4]> + '_ {
    let (w, h) = field.size();
    let (w, h) = (w as usize, h as usize);
    let heights = field.heights();
    let at = move |i: usize, j: usize| heights[(j % h) * w + i % w];
    (0..h)
        .flat_map(move |j| (0..w).map(move |i| (i, j)))
        .map(move |(i, j)| [at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)])
}

/// Per bilinear cell, the depth layer of its highest corner: the last layer whose top lies at
/// or above it.
struct Layers {
    width: usize,
    layers: Vec<u8>,
}

impl Layers {
    fn new(field: &HeightField) -> Layers {
        let layers = cell_corners(field)
            .map(|corners| {
                let top = corners.into_iter().fold(f32::MIN, f32::max);
                layer(1.0 - f64::from(top))
            })
            .collect();
        Layers {
            width: field.size().0 as usize,
            layers,
        }
    }

    /// The layer of the cell whose lower corner is `texel`.
    fn of(&self, texel: [usize; 2]) -> u8 {
        self.layers[texel[1] * self.width + texel[0]]
    }
}

/// The line p + σ·(cos φ, sin φ) through the tile's bilinear cells, and the cell it is in.
struct Line {
    /// In grid units (texel centres at integers), at σ = 0 and per unit of σ.
    start: [f64; 2],
    speed: [f64; 2],
    /// 1 / speed, per axis.
    slowness: [f64; 2],
    /// The cell (unwrapped), and its lower corner's texel wrapped into the tile.
    cell: [i64; 2],
    texel: [i64; 2],
    size: [i64; 2],
    /// The σ where the line leaves the cell through its face across each axis.
    exits: [f64; 2],
}

impl Line {
    /// The line from `start` (grid units) along azimuth `phi` in a tile of `size` texels.
    fn new([w, h]: [u32; 2], start: [f64; 2], phi: f64) -> Line {
        let (sin_phi, cos_phi) = phi.sin_cos();
        let speed = [cos_phi * f64::from(w), sin_phi * f64::from(h)];
        let size = [i64::from(w), i64::from(h)];
        let mut line = Line {
            start,
            speed,
            slowness: speed.map(|v| 1.0 / v),
            cell: [0; 2],
            texel: [0; 2],
            size,
            exits: [0.0; 2],
        };
        line.jump(0.0);
        line
    }

    /// Moves to the cell the line is in at `sigma` (where that is on a cell boundary, the one
    /// it moves into).
    fn jump(&mut self, sigma: f64) {
        let cell = [0, 1].map(|axis| {
            let x = self.start[axis] + self.speed[axis] * sigma;
            if self.speed[axis] < 0.0 {
                x.ceil() as i64 - 1
            } else {
                x.floor() as i64
            }
        });
        self.enter(cell);
    }

    /// Moves into `cell`.
    fn enter(&mut self, cell: [i64; 2]) {
        self.cell = cell;
        self.texel = [0, 1].map(|axis| cell[axis].rem_euclid(self.size[axis]));
        self.exits = [0, 1].map(|axis| self.exit(axis));
    }

    /// The σ where the line crosses grid line `at` of `axis` (infinity if parallel).
    fn crossing(&self, axis: usize, at: i64) -> f64 {
        if self.speed[axis] == 0.0 {
            f64::INFINITY
        } else {
            (at as f64 - self.start[axis]) * self.slowness[axis]
        }
    }

    /// Where the line leaves its cell through the face across `axis`.
    fn exit(&self, axis: usize) -> f64 {
        let cell = self.cell[axis];
        self.crossing(
            axis,
            if self.speed[axis] > 0.0 {
                cell + 1
            } else {
                cell
            },
        )
    }

    /// Where the line leaves its cell.
    fn cell_exit(&self) -> f64 {
        self.exits[0].min(self.exits[1])
    }

    /// Moves into the next cell, the line having reached its exit at `sigma`.
    fn step(&mut self, sigma: f64) {
        for axis in 0..2 {
            if self.exits[axis] == sigma {
                let size = self.size[axis];
                let texel = &mut self.texel[axis];
                if self.speed[axis] > 0.0 {
                    self.cell[axis] += 1;
                    *texel = if *texel + 1 == size { 0 } else { *texel + 1 };
                } else {
                    self.cell[axis] -= 1;
                    *texel = if *texel == 0 { size - 1 } else { *texel - 1 };
                }
                self.exits[axis] = self.exit(axis);
            }
        }
    }
}

/// sin and cos of σ·c at one σ, which every ray of a fan shares (σ itself on the flat
/// surface).
#[derive(Clone, Copy)]
struct Bent {
    sigma: f64,
    sin: f64,
    cos: f64,
}

impl Bent {
    /// At σ = 0, where every march starts, on every curvature.
    const START: Bent = Bent {
        sigma: 0.0,
        sin: 0.0,
        cos: 1.0,
    };

    /// The sines of σ·c at `sigma` on curvature `c`.
    fn at(c: f64, sigma: f64) -> Bent {
        let (sin, cos) = (sigma * c).sin_cos();
        Bent { sigma, sin, cos }
    }

    /// The same at `sigma`, near this σ: within 1/16 radian by the angle-sum formulas and
    /// Taylor series of the difference (exact to rounding there), else [`Bent::at`]. Saves
    /// the search a sine per step.
    fn advanced(self, c: f64, sigma: f64) -> Bent {
        if c == 0.0 || sigma == self.sigma {
            return Bent { sigma, ..self };
        }
        let d = (sigma - self.sigma) * c;
        if d.abs() > 1.0 / 16.0 {
            return Bent::at(c, sigma);
        }
        let d2 = d * d;
        const SIN: [f64; 4] = [1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0];
        const COS: [f64; 5] = [1.0, -0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0];
        let sin_d = d * polynomial(d2, SIN);
        let cos_d = polynomial(d2, COS);
        Bent {
            sigma,
            sin: self.sin.mul_add(cos_d, self.cos * sin_d),
            cos: self.cos.mul_add(cos_d, -(self.sin * sin_d)),
        }
    }
}

/// One ray of a fan: its depth below the bent reference surface against σ.
struct BentRay {
    theta: f64,
    sin_theta: f64,
    cosec_theta: f64,
    cot_theta: f64,
    tan_theta: f64,
    /// The curvature, and R = 1/c (0 on the flat surface).
    c: f64,
    r: f64,
    /// Where it climbs back through the reference surface (convex), else infinity.
    end: f64,
    /// Where a search for its hit ends: where it climbs out (convex), or just short of
    /// where it lies infinitely deep (concave: R·θ, the arc its line never passes), below
    /// every relief.
    last: f64,
    /// Where it lies deepest (convex), else infinity; its depth there.
    deepest: (f64, f64),
    /// Twice that σ (convex), else infinity: the ray lies symmetrically about its deepest
    /// point, so it climbs back above a depth it first reaches at σ at `mirror` − σ.
    mirror: f64,
}

impl BentRay {
    fn new(theta: f64, c: f64) -> BentRay {
        let (sin_theta, cos_theta) = theta.sin_cos();
        let r = if c == 0.0 { 0.0 } else { 1.0 / c };
        let asymptote = if c < 0.0 { -r * theta } else { f64::INFINITY };
        let (end, deepest) = if c > 0.0 {
            (
                r * (PI - 2.0 * theta),
                (r * (PI / 2.0 - theta), r * (1.0 - sin_theta)),
            )
        } else {
            (f64::INFINITY, (f64::INFINITY, f64::INFINITY))
        };
        BentRay {
            theta,
            sin_theta,
            cosec_theta: 1.0 / sin_theta,
            cot_theta: cos_theta / sin_theta,
            tan_theta: sin_theta / cos_theta,
            c,
            r,
            end,
            last: end.min(asymptote * (1.0 - 1e-12)),
            deepest,
            mirror: 2.0 * deepest.0,
        }
    }

    /// The first σ where the ray lies `depth` deep (infinity if it never does): where
    /// sin(θ + σ·c) = sin θ / (1 − depth·c), t(σ) = R·(1 − sin θ / sin(θ + σ·c)).
    fn reach(&self, depth: f64) -> f64 {
        if self.c == 0.0 {
            return depth * self.tan_theta;
        }
        let q = self.sin_theta / (1.0 - depth * self.c);
        if q > 1.0 {
            f64::INFINITY
        } else {
            (q.asin() - self.theta) / self.c
        }
    }

    /// The ray's depth t and dt/dσ at the σ of `bent`: with x = sin u / sin θ and
    /// y = cos u / sin θ (u = θ + σc), t = R·(1 − 1/x) and t′ = y / x².
    fn depth_and_slope(&self, bent: Bent) -> (f64, f64) {
        let (x, y) = self.xy(bent);
        // One division: the compiler shares `depth_bent`'s.
        (self.depth_bent(bent), y / (x * x))
    }

    /// G = x·(D − t), the gap between `piece` and the ray scaled by x = sin u / sin θ
    /// (u = θ + σc, x > 0 wherever the ray is defined), at the σ of `bent`, with dG/dσ and
    /// ½·d²G/dσ²: G = R − (R − D)·x (D − σ·cot θ on the flat surface) needs no division,
    /// and has the gap's sign. With y = cos u / sin θ (x′ = c·y, y′ = −c·x),
    /// G′ = D′·x − (1 − c·D)·y and G″ = D″·x + 2c·D′·y + c·(1 − c·D)·x.
    fn scaled_gap(&self, piece: &Piece, bent: Bent) -> Scaled {
        let (d, slope, bending) = piece.depth(bent.sigma);
        let (x, y) = self.xy(bent);
        let c = self.c;
        let g = if c == 0.0 {
            (-bent.sigma).mul_add(self.cot_theta, d)
        } else {
            (d - self.r).mul_add(x, self.r)
        };
        let shrink = (-c).mul_add(d, 1.0);
        Scaled {
            g,
            slope: slope.mul_add(x, -(shrink * y)),
            half_bending: 0.5 * bending.mul_add(x, (2.0 * c * slope).mul_add(y, c * shrink * x)),
        }
    }

    /// Depth at the σ of `bent`.
    fn depth_bent(&self, bent: Bent) -> f64 {
        if self.c == 0.0 {
            bent.sigma * self.cot_theta
        } else {
            self.r * (1.0 - 1.0 / self.xy(bent).0)
        }
    }

    /// x = sin u / sin θ and y = cos u / sin θ (u = θ + σc) at the σ of `bent`.
    fn xy(&self, bent: Bent) -> (f64, f64) {
        (
            bent.sin.mul_add(self.cot_theta, bent.cos),
            bent.cos.mul_add(self.cot_theta, -bent.sin),
        )
    }

    /// The first σ in [`from`, `to`] where the ray lies at least as deep as a depth it first
    /// reaches at `reach` ([`BentRay::reach`]), given that it does not before `from`:
    /// `reach`, or `from` if it already has and has not climbed back above it (a convex
    /// surface's ray does, symmetrically about its deepest point).
    fn first_at_depth(&self, reach: f64, from: f64, to: f64) -> Option<f64> {
        if reach > to {
            None
        } else if reach >= from {
            Some(reach)
        } else {
            (from <= self.mirror - reach).then_some(from)
        }
    }

    /// The greatest depth over [a, b], given the depths at its ends: at an end, or where the
    /// convex surface's ray turns.
    fn deepest_on(&self, (a, t_a): (f64, f64), (b, t_b): (f64, f64)) -> f64 {
        let ends = t_a.max(t_b);
        if (a..=b).contains(&self.deepest.0) {
            ends.max(self.deepest.1)
        } else {
            ends
        }
    }
}

/// The scaled gap G at one σ, dG/dσ and ½·d²G/dσ² ([`BentRay::scaled_gap`]).
#[derive(Clone, Copy)]
struct Scaled {
    g: f64,
    slope: f64,
    half_bending: f64,
}

/// The relief's depth along the line within one bilinear cell: D(σ) = d0 + d1·s + d2·s²,
/// s = σ − `from`, for σ in [`from`, `to`].
struct Piece {
    from: f64,
    to: f64,
    d: [f64; 3],
    /// The least depth along the line over [`from`, `to`], and the last of the [`LAYERS`]
    /// whose top lies at or above it.
    shallowest: f64,
    layer: u8,
}

impl Piece {
    /// The depth, where it does not change along the line (a flat cell, or a line along a
    /// level direction of one).
    fn constant(&self) -> Option<f64> {
        (self.d[1] == 0.0 && self.d[2] == 0.0).then_some(self.d[0])
    }

    /// D, dD/dσ and d²D/dσ² at σ.
    fn depth(&self, sigma: f64) -> (f64, f64, f64) {
        let s = sigma - self.from;
        let [d0, d1, d2] = self.d;
        (
            s.mul_add(s.mul_add(d2, d1), d0),
            (2.0 * s).mul_add(d2, d1),
            2.0 * d2,
        )
    }
}

/// The sines at the first σ in [a, b] (within the piece) where `ray` reaches the relief (to
/// [`TOLERANCE`]), given that it has not before a, the ray's sines at a (`from`), and `bent`
/// at the piece's start (which the sines anywhere else are advanced from).
///
/// The search follows the sign of the scaled gap G = x·g ([`BentRay::scaled_gap`]), which
/// needs no division. The root of G's quadratic model at a, where it lies in (a, b), is
/// evaluated first: where G there is negative or falling and Newton's step from it is within
/// a quarter of [`TOLERANCE`], it is the hit (and G at b is not needed). Else, where G is
/// negative there or at b, Newton steps kept inside the bracket find the crossing to
/// [`TOLERANCE`].
///
/// Where the gap is positive at both ends, a crossing needs a dip between them, ruled out by
/// a bound on the gap g(σ) = D(σ) − t(σ) itself: it is nearly the quadratic
/// e(s) = g(a) + (D′(a) − m)·s + d2·s², s = σ − a, with m the slope of a line through the ray
/// at a: the ray's depth curves up on a flat or concave surface (d²t/dσ² =
/// −c·sin θ·(sin²u + 2cos²u)/sin³u) and down on a convex one, so it lies under its chord in
/// the first case and under its tangent at a in the second, and then g ≥ e. Where the bound
/// cannot decide, the piece is halved until it can or is shorter than [`TOLERANCE`] (a
/// touch, not a crossing).
fn first_crossing(piece: &Piece, bent: Bent, ray: &BentRay, from: Bent, b: f64) -> Option<Bent> {
    let a = from.sigma;
    debug_assert!(piece.from <= a && b <= piece.to);
    let at_a = ray.scaled_gap(piece, from);
    if at_a.g <= 0.0 {
        return Some(from);
    }
    if b <= a {
        return None;
    }
    // The model's root first: where G there is at a root to the tolerance (negative, or
    // falling towards one), that is the hit, and G at b is not needed.
    let (mut lo, mut g_lo, mut guess, mut bracket) = (a, at_a.g, None, None);
    let model = first_root(at_a.g, at_a.slope, at_a.half_bending).map(|s| a + s);
    if let Some(x) = model.filter(|x| *x > a && *x < b) {
        let at = bent.advanced(ray.c, x);
        let at_x = ray.scaled_gap(piece, at);
        if converged(&at_x) && (at_x.g <= 0.0 || at_x.slope < 0.0) {
            return Some(at);
        }
        if at_x.g <= 0.0 {
            bracket = Some((at, at_x.g));
        } else {
            (lo, g_lo) = (x, at_x.g);
        }
        guess = Some(x - at_x.g / at_x.slope);
    }
    let (hi, g_hi) = match bracket {
        Some(bracket) => bracket,
        None => {
            let to = bent.advanced(ray.c, b);
            let g_b = ray.scaled_gap(piece, to).g;
            if g_b <= 0.0 {
                (to, g_b)
            } else {
                // Positive at both ends: a crossing needs a dip between them.
                let ((t_a, slope), t_b) = (ray.depth_and_slope(from), ray.depth_bent(to));
                if ray.deepest_on((a, t_a), (b, t_b)) < piece.shallowest {
                    return None;
                }
                let (d_a, slope_a, _) = piece.depth(a);
                // The gap lies above e under the line the ray lies under.
                let m = if ray.c > 0.0 {
                    slope
                } else {
                    (t_b - t_a) / (b - a)
                };
                let (s, least) = least_on(d_a - t_a, slope_a - m, piece.d[2], b - a);
                if least > 0.0 {
                    return None;
                }
                // Where e is least the gap is least, nearly: a bracket if it has dipped there.
                let x = a + s;
                let at_x = bent.advanced(ray.c, x);
                let g_x = ray.scaled_gap(piece, at_x).g;
                if g_x > 0.0 {
                    // A touch within rounding, or a dip too narrow for e to find: halve.
                    if b - a < TOLERANCE {
                        return None;
                    }
                    let mid = bent.advanced(ray.c, 0.5 * (a + b));
                    return first_crossing(piece, bent, ray, from, mid.sigma)
                        .or_else(|| first_crossing(piece, bent, ray, mid, b));
                }
                if x <= lo {
                    (lo, g_lo) = (a, at_a.g);
                }
                (at_x, g_x)
            }
        }
    };
    // Bracketed: Newton steps, falling back to bisection where one would leave the bracket.
    let (mut lo, mut hi) = (lo, hi);
    let mut x = guess
        .filter(|x| *x > lo && *x < hi.sigma)
        .unwrap_or(lo + (hi.sigma - lo) * g_lo / (g_lo - g_hi));
    for _ in 0..64 {
        let at = bent.advanced(ray.c, x);
        let at_x = ray.scaled_gap(piece, at);
        if at_x.g > 0.0 {
            lo = x;
        } else {
            hi = at;
        }
        if hi.sigma - lo <= TOLERANCE {
            break;
        }
        if converged(&at_x) {
            return Some(at);
        }
        let newton = x - at_x.g / at_x.slope;
        x = if newton > lo && newton < hi.sigma {
            newton
        } else {
            0.5 * (lo + hi.sigma)
        };
    }
    Some(hi)
}

/// The polynomial with `c` (constant first, 1 to 8 coefficients) at `x`, by Estrin's scheme
/// with fused multiply-adds: pairs of terms summed independently, then pairs of pairs, a
/// chain of at most three steps instead of Horner's N − 1.
#[inline(always)]
fn polynomial<const N: usize>(x: f64, c: [f64; N]) -> f64 {
    const { assert!(N >= 1 && N <= 8) };
    let pair = |i: usize| {
        if i + 1 < N {
            c[i + 1].mul_add(x, c[i])
        } else {
            c[i]
        }
    };
    if N <= 2 {
        return pair(0);
    }
    let x2 = x * x;
    let low = pair(2).mul_add(x2, pair(0));
    if N <= 4 {
        return low;
    }
    let high = if N <= 6 {
        pair(4)
    } else {
        pair(6).mul_add(x2, pair(4))
    };
    high.mul_add(x2 * x2, low)
}

/// Whether Newton's step from a point, g / g′, is within a quarter of [`TOLERANCE`] (tested
/// without the division).
fn converged(at: &Scaled) -> bool {
    at.g.abs() <= TOLERANCE * 0.25 * at.slope.abs()
}

/// The least of e(s) = e0 + e1·s + e2·s² over [0, len], and where.
fn least_on(e0: f64, e1: f64, e2: f64, len: f64) -> (f64, f64) {
    let e = |s: f64| e0 + s * (e1 + s * e2);
    let mut least = if e(len) < e0 {
        (len, e(len))
    } else {
        (0.0, e0)
    };
    if e2 > 0.0 {
        let vertex = -e1 / (2.0 * e2);
        if vertex > 0.0 && vertex < len && e(vertex) < least.1 {
            least = (vertex, e(vertex));
        }
    }
    least
}

/// The least positive root of e0 + e1·s + e2·s² (e0 > 0), if any.
fn first_root(e0: f64, e1: f64, e2: f64) -> Option<f64> {
    if e1 < 0.0 {
        // Near the line's root t = e0 / −e1, the root is t·C(ε) with ε = e0·e2 / e1² and
        // C(ε) = (1 − √(1 − 4ε)) / 2ε = Σ Catalan(n)·εⁿ: by series where |ε| ≤ 1/32 (to
        // 429·ε⁷ < 1.3·10⁻⁸ relative), without a square root.
        let r = -1.0 / e1;
        let t = e0 * r;
        let eps = t * e2 * r;
        if eps.abs() <= 1.0 / 32.0 {
            const CATALAN: [f64; 7] = [1.0, 1.0, 2.0, 5.0, 14.0, 42.0, 132.0];
            return Some(t * polynomial(eps, CATALAN));
        }
    }
    if e2 == 0.0 {
        return (e1 < 0.0).then(|| -e0 / e1);
    }
    let disc = e1 * e1 - 4.0 * e0 * e2;
    if disc < 0.0 {
        return None;
    }
    // Without cancellation: the roots are q / e2 and e0 / q, of product e0 / e2 and sum
    // −e1 / e2. With e1 < 0, q > 0 and e0 / q is positive, and the lesser where both are
    // (q² ≥ e1² / 4 ≥ e0·e2); with e1 ≥ 0, q < 0 and only q / e2 can be, where e2 < 0.
    let q = -0.5 * (e1 + disc.sqrt().copysign(e1));
    if e1 < 0.0 {
        Some(e0 / q)
    } else {
        (e2 < 0.0).then(|| q / e2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plateaus of small periodic tiles, counted by hand: the depths of the cells whose
    /// four corners are equal, the most common first, and nothing for sloped cells.
    #[test]
    fn the_plateaus_are_the_depths_of_the_flat_cells_most_common_first() {
        let plateaus_of = |heights: Vec<f32>| {
            let field = HeightField::new(4, 4, heights).unwrap();
            plateaus(Relief {
                field: &field,
                depth: 0.25,
            })
        };
        // Rows 0–2 at 0 but texel (1, 1) at 1, row 3 at 0.5: flat only at 0, in cells
        // (2, 0), (3, 0), (2, 1) and (3, 1).
        let mut heights = vec![0.0; 16];
        heights[12..].fill(0.5);
        heights[5] = 1.0;
        assert_eq!(plateaus_of(heights), vec![0.25]);
        // Row 0 and texels (0, 1), (1, 1) at 0, the rest at 0.5: flat at 0.5 in cells
        // (2, 1) and (0..4, 2), five of them, and at 0 in cell (0, 0) alone.
        let mut heights = vec![0.5; 16];
        heights[..6].fill(0.0);
        assert_eq!(plateaus_of(heights), vec![0.125, 0.25]);
    }

    /// `polynomial` (Estrin's scheme) against Horner's rule written out, for every length it
    /// takes, at points of both signs, within 4·10⁻¹⁶ relative to the sum of the terms'
    /// magnitudes (a few roundings).
    #[test]
    fn estrins_scheme_sums_the_same_polynomial_as_horners_rule() {
        fn check<const N: usize>(c: [f64; N]) {
            for x in [-0.7, -0.06, 0.0, 0.03, 0.5, 1.3] {
                let horner = c.iter().rev().fold(0.0, |acc, k| acc * x + k);
                let scale: f64 = (0..N).map(|i| (c[i] * x.powi(i as i32)).abs()).sum();
                let got = polynomial(x, c);
                assert!(
                    (got - horner).abs() <= 4e-16 * scale,
                    "N = {N}, x = {x}: {got} vs {horner}"
                );
            }
        }
        let c = [0.9, -1.7, 2.3, 0.4, -3.1, 1.1, 0.6, -0.2];
        check::<1>([c[0]]);
        check::<2>([c[0], c[1]]);
        check::<3>([c[0], c[1], c[2]]);
        check::<4>([c[0], c[1], c[2], c[3]]);
        check::<5>([c[0], c[1], c[2], c[3], c[4]]);
        check::<6>([c[0], c[1], c[2], c[3], c[4], c[5]]);
        check::<7>([c[0], c[1], c[2], c[3], c[4], c[5], c[6]]);
        check::<8>(c);
    }

    /// `Bent::advanced` (series of the step, then the angle-sum formulas) against `sin_cos`
    /// at the new σ, for steps up to its 1/16 radian on curvatures of both signs, within
    /// 10⁻¹⁵.
    #[test]
    fn advanced_sines_are_the_sines_at_the_new_point() {
        for c in [-2.0, -0.4, 0.7, 3.0] {
            for sigma in [0.0, 0.1, 0.35] {
                let start = Bent::at(c, sigma);
                for step in [-1.0 / 16.0, -0.01, 1e-7, 0.02, 1.0 / 16.0] {
                    let to = sigma + step / c;
                    let (got, want) = (start.advanced(c, to), Bent::at(c, to));
                    assert!(
                        (got.sin - want.sin).abs() <= 1e-15 && (got.cos - want.cos).abs() <= 1e-15,
                        "c {c}, σ {sigma} → {to}: ({}, {}) vs ({}, {})",
                        got.sin,
                        got.cos,
                        want.sin,
                        want.cos
                    );
                }
            }
        }
    }

    /// `first_root` (its series where |ε| ≤ 1/32, its closed form elsewhere) against the
    /// textbook quadratic formula, on models with both signs of e1 and e2, within 10⁻¹²
    /// relative (the models on the series' side have |ε| ≤ 10⁻³, where its truncation is
    /// below 10⁻¹⁸).
    #[test]
    fn the_models_first_root_is_the_quadratic_formulas() {
        for (e0, e1, e2) in [
            (1e-3f64, -1.0f64, 0.1f64),
            (1e-3, -1.0, -0.2),
            (2e-4, -0.5, 0.0),
            (1e-2, -0.3, 2.0),
            (1e-2, -0.3, -2.0),
            (1e-2, 0.4, -3.0),
            (1e-2, 0.4, 3.0),
            (1e-2, -0.1, 1.0),
        ] {
            let disc = e1 * e1 - 4.0 * e0 * e2;
            let textbook = if e2 == 0.0 {
                (e1 < 0.0).then(|| -e0 / e1)
            } else if disc < 0.0 {
                None
            } else {
                [-1.0, 1.0]
                    .map(|sign| (-e1 + sign * disc.sqrt()) / (2.0 * e2))
                    .into_iter()
                    .filter(|s| *s > 0.0)
                    .reduce(f64::min)
            };
            match (first_root(e0, e1, e2), textbook) {
                (Some(got), Some(want)) => assert!(
                    (got - want).abs() <= 1e-12 * want,
                    "{e0} {e1} {e2}: {got} vs {want}"
                ),
                (None, None) => {}
                (got, want) => panic!("{e0} {e1} {e2}: {got:?} vs {want:?}"),
            }
        }
    }

    /// `first_at_depth` against a plain scan of the ray's depth from `from` in steps of 10⁻⁵
    /// (tolerance: one step), on concave, flat and convex surfaces, starting before the ray
    /// reaches the depth, after it, and (convex) after it has climbed back above it.
    #[test]
    fn a_rays_first_point_at_a_depth_is_what_a_scan_of_its_depth_finds() {
        const STEP: f64 = 1e-5;
        for c in [-2.0, -0.5, 0.0, 1.5, 3.0] {
            for theta in [0.3, 0.9, 1.4] {
                let ray = BentRay::new(theta, c);
                let last = ray.last.min(4.0);
                for depth in [0.01, 0.05, 0.12] {
                    for from in [0.0, 0.3, 0.7, 0.9, 0.97, 0.995].map(|f| f * last) {
                        let to = last;
                        let scan = (0..)
                            .map(|i| from + STEP * f64::from(i))
                            .take_while(|sigma| *sigma <= to)
                            .find(|sigma| ray.depth_bent(Bent::at(c, *sigma)) >= depth);
                        let got = ray.first_at_depth(ray.reach(depth), from, to);
                        match (got, scan) {
                            (Some(got), Some(scan)) => assert!(
                                (got - scan).abs() <= STEP,
                                "c {c}, θ {theta}, depth {depth}, from {from}: {got} vs {scan}"
                            ),
                            (None, None) => {}
                            _ => panic!(
                                "c {c}, θ {theta}, depth {depth}, from {from}: {got:?} vs {scan:?}"
                            ),
                        }
                    }
                }
            }
        }
    }
}
