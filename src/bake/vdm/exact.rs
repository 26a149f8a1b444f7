//! The exact VDM bake: every ray cast against the relief bent to its curvature ([`Bend`]),
//! solved in closed form per bilinear cell.
//!
//! All rays entering at one texel along one azimuth φ on one curvature c lie in one plane and
//! share one line of texture space, p + σ·(cos φ, sin φ). Along that line the relief's depth
//! D(σ) is quadratic inside each cell of the bilinear interpolation (the patch between four
//! texel centres). A ray entering at polar angle θ lies at depth
//! t(σ) = R·(1 − 1 / (cos(σ/R) + sin(σ/R)·cot θ)) below the reference surface bent to radius
//! R = 1/c (σ·cot θ on the flat surface, c = 0). The march steps once from cell to cell along
//! the line for the whole fan of θ: rays from one point in one plane never cross, so a
//! steeper ray lies below a shallower one everywhere and hits no later along the line
//! ([`Fan`]). In each cell the gap g(σ) = D(σ) − t(σ) is bounded from below (D's
//! minimum, t's maximum, both exact), and only where the bound does not rule a crossing out is
//! the first root found: Newton steps kept inside the bracket, to [`TOLERANCE`]; where the
//! gap is still positive at the cell's end, the cell is halved until its bound rules the
//! crossing out or it is shorter than [`TOLERANCE`] (a touch, not a crossing). A convex
//! surface's ray that climbs back out through the reference surface (at σ = R·(π − 2θ))
//! without meeting the relief is [`NO_HIT`], and so is every shallower ray of its fan.

use super::bend::Bend;
use super::{NO_HIT, Relief, VdmGrid};
use crate::bake::gdm::BakeObserver;
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicU64, Ordering};

/// Largest error of a hit's arc length σ along the reference surface (tile units).
pub const TOLERANCE: f64 = 1e-7;

/// Bakes every fan (texel, azimuth, curvature): curvature by curvature, its azimuths in
/// parallel, so that beside the VDM only one curvature's values are held twice.
pub fn bake(relief: Relief, grid: VdmGrid, observer: &dyn BakeObserver) -> Result<Vec<f32>> {
    let (w, h) = relief.field.size();
    let texels = (w * h) as usize;
    let (n_theta, n_phi) = (grid.n_theta as usize, grid.n_phi as usize);
    let fans = (grid.n_curvature * grid.n_phi) as u64;
    let done = AtomicU64::new(0);
    let mut values = vec![NO_HIT; grid.n_curvature as usize * n_theta * n_phi * texels];
    for (k, curvature) in values.chunks_mut(n_theta * n_phi * texels).enumerate() {
        let c = grid.curvature(k as u32);
        let thetas: Vec<f64> = (0..grid.n_theta).map(|a| grid.theta(a)).collect();
        let fan = Fan::new(&thetas, Bend { c });
        // Per azimuth: [a][texel].
        let blocks: Vec<Vec<f32>> = (0..grid.n_phi)
            .into_par_iter()
            .map(|b| {
                if observer.cancelled() {
                    return Err(Error::Cancelled);
                }
                let mut block = vec![NO_HIT; n_theta * texels];
                let mut hits = vec![None; n_theta];
                for texel in 0..texels {
                    let p = [
                        (f64::from(texel as u32 % w) + 0.5) / f64::from(w),
                        (f64::from(texel as u32 / w) + 0.5) / f64::from(h),
                    ];
                    fan.cast(relief, p, grid.phi(b), &mut hits);
                    for (a, hit) in hits.iter().enumerate() {
                        block[a * texels + texel] = hit.map_or(NO_HIT, |d| d as f32);
                    }
                }
                observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, fans);
                Ok(block)
            })
            .collect::<Result<_>>()?;
        for (b, block) in blocks.iter().enumerate() {
            for (a, image) in block.chunks_exact(texels).enumerate() {
                curvature[(a * n_phi + b) * texels..][..texels].copy_from_slice(image);
            }
        }
    }
    Ok(values)
}

/// The VDM value of the ray entering at texture point `p` at angles (θ, φ) on the relief
/// bent by `bend`: l / sin θ, l the arc length to the hit; `None` without a hit.
pub fn cast(relief: Relief, p: [f64; 2], theta: f64, phi: f64, bend: Bend) -> Option<f64> {
    let mut hit = [None];
    Fan::new(&[theta], bend).cast(relief, p, phi, &mut hit);
    hit[0]
}

/// The rays of one set of polar angles θ on one bent surface, prepared once: cast together
/// from any entry point along any azimuth, in one march.
pub struct Fan {
    c: f64,
    rays: Vec<BentRay>,
}

impl Fan {
    /// The fan of `thetas` (ascending, in (0, π/2)) on the surface bent by `bend`.
    pub fn new(thetas: &[f64], bend: Bend) -> Fan {
        debug_assert!(thetas.is_sorted());
        Fan {
            c: bend.c,
            rays: thetas.iter().map(|&th| BentRay::new(th, bend.c)).collect(),
        }
    }

    /// The VDM values of the fan's rays entering at `p` along azimuth `phi`, written to `out`
    /// in θ order (as [`cast`] gives them).
    pub fn cast(&self, relief: Relief, p: [f64; 2], phi: f64, out: &mut [Option<f64>]) {
        march(relief, p, phi, self.c, &self.rays, out);
    }
}

/// [`Fan::cast`].
fn march(relief: Relief, p: [f64; 2], phi: f64, c: f64, rays: &[BentRay], out: &mut [Option<f64>]) {
    debug_assert_eq!(rays.len(), out.len());
    out.fill(None);
    let field = relief.field;
    let (w, h) = field.size();
    let (sin_phi, cos_phi) = phi.sin_cos();
    // The line in grid units (texel centres at integers), per unit of σ.
    let start = [p[0] * f64::from(w) - 0.5, p[1] * f64::from(h) - 0.5];
    let speed = [cos_phi * f64::from(w), sin_phi * f64::from(h)];
    let size = [i64::from(w), i64::from(h)];
    // The cell the line enters first (where it starts on a cell boundary, the one it moves
    // into), unwrapped, and its lower corner's texel wrapped into the tile.
    let mut cell = [0, 1].map(|axis| {
        let x = start[axis];
        if speed[axis] < 0.0 {
            x.ceil() as i64 - 1
        } else {
            x.floor() as i64
        }
    });
    let mut texel = [0, 1].map(|axis| cell[axis].rem_euclid(size[axis]));
    let step = speed.map(|v| if v > 0.0 { 1 } else { -1 });
    // Where the line next crosses a cell boundary along each axis.
    let next_boundary = |axis: usize, cell: i64| {
        let v = speed[axis];
        if v == 0.0 {
            f64::INFINITY
        } else {
            let boundary = if v > 0.0 { cell + 1 } else { cell } as f64;
            (boundary - start[axis]) / v
        }
    };
    // Every ray hits the floor (depth) by depth · tan θ on a flat or concave surface; a convex
    // one's leaves before its end. A cap against rounding only.
    let cap = rays.last().map_or(0.0, |r| relief.depth * r.tan_theta) + 4.0;
    let (mut sigma, mut a) = (0.0, 0);
    let mut bent = Bent::at(c, 0.0);
    while a < rays.len() && sigma < cap {
        let next = [next_boundary(0, cell[0]), next_boundary(1, cell[1])];
        let end = next[0].min(next[1]).min(cap);
        let bent_end = Bent::at(c, end);
        let piece = Piece::new(relief, texel, cell, start, speed, sigma, end);
        // The fan's rays, steepest first, from where the last one hit.
        let (mut from, mut t_from) = (sigma, rays[a].depth_bent(bent));
        while a < rays.len() {
            let ray = &rays[a];
            if from >= ray.end {
                // It left the relief, and so does every shallower ray.
                return;
            }
            // Just short of a concave surface's asymptote the ray lies below every relief.
            let to = end.min(ray.end).min(ray.asymptote * (1.0 - 1e-12));
            let t_to = if to == end {
                ray.depth_bent(bent_end)
            } else {
                ray.depth(to).0
            };
            match first_crossing(&piece, ray, (from, t_from), (to, t_to)) {
                Some(hit) => {
                    out[a] = Some(hit / ray.sin_theta);
                    from = hit;
                    a += 1;
                    if let Some(next_ray) = rays.get(a) {
                        t_from = next_ray.depth(hit).0;
                    }
                }
                None => break,
            }
        }
        for axis in 0..2 {
            if next[axis] == end {
                cell[axis] += step[axis];
                texel[axis] = (texel[axis] + step[axis]).rem_euclid(size[axis]);
            }
        }
        sigma = end;
        bent = bent_end;
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
    fn at(c: f64, sigma: f64) -> Bent {
        let (sin, cos) = if c == 0.0 {
            (0.0, 1.0)
        } else {
            (sigma * c).sin_cos()
        };
        Bent { sigma, sin, cos }
    }
}

/// One ray of a fan: its depth below the bent reference surface against σ.
struct BentRay {
    sin_theta: f64,
    cot_theta: f64,
    tan_theta: f64,
    /// The curvature, and R = 1/c (0 on the flat surface).
    c: f64,
    r: f64,
    /// Where it climbs back through the reference surface (convex), else infinity.
    end: f64,
    /// Where it lies infinitely deep (concave: R·θ, the arc its line never passes), else
    /// infinity.
    asymptote: f64,
    /// Where it lies deepest (convex), else infinity; its depth there.
    deepest: (f64, f64),
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
            sin_theta,
            cot_theta: cos_theta / sin_theta,
            tan_theta: sin_theta / cos_theta,
            c,
            r,
            end,
            asymptote,
            deepest,
        }
    }

    /// Depth t and dt/dσ at arc length σ.
    fn depth(&self, sigma: f64) -> (f64, f64) {
        let bent = Bent::at(self.c, sigma);
        let x = bent.cos + bent.sin * self.cot_theta;
        (
            self.depth_bent(bent),
            (bent.cos * self.cot_theta - bent.sin) / (x * x),
        )
    }

    /// Depth at the σ of `bent`.
    fn depth_bent(&self, bent: Bent) -> f64 {
        if self.c == 0.0 {
            bent.sigma * self.cot_theta
        } else {
            self.r * (1.0 - 1.0 / (bent.cos + bent.sin * self.cot_theta))
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

/// The relief's depth along the line within one bilinear cell: D(σ) = d0 + d1·s + d2·s²,
/// s = σ − `from`, for σ in [`from`, `to`].
struct Piece {
    from: f64,
    to: f64,
    d: [f64; 3],
    /// The least depth over the whole cell (at its highest corner).
    shallowest: f64,
}

impl Piece {
    /// The piece [`from`, `to`] of the line `start + σ·speed` (grid units) in cell `cell`
    /// (unwrapped), whose lower corner is texel `texel` of the tile.
    fn new(
        relief: Relief,
        texel: [i64; 2],
        cell: [i64; 2],
        start: [f64; 2],
        speed: [f64; 2],
        from: f64,
        to: f64,
    ) -> Piece {
        let field = relief.field;
        let (w, h) = field.size();
        let (w, h) = (w as usize, h as usize);
        let [i, j] = texel.map(|t| t as usize);
        let (i1, j1) = (
            if i + 1 == w { 0 } else { i + 1 },
            if j + 1 == h { 0 } else { j + 1 },
        );
        let heights = field.heights();
        let at = |i: usize, j: usize| f64::from(heights[j * w + i]);
        let (h00, h10, h01, h11) = (at(i, j), at(i1, j), at(i, j1), at(i1, j1));
        // Position within the cell at `from`, and its rate per unit of σ.
        let x0 = start[0] + speed[0] * from - cell[0] as f64;
        let y0 = start[1] + speed[1] * from - cell[1] as f64;
        let (ex, ey) = (speed[0], speed[1]);
        let (bx, by, k) = (h10 - h00, h01 - h00, h11 - h10 - h01 + h00);
        let height = [
            h00 + bx * x0 + by * y0 + k * x0 * y0,
            bx * ex + by * ey + k * (x0 * ey + y0 * ex),
            k * ex * ey,
        ];
        let depth = relief.depth;
        Piece {
            from,
            to,
            shallowest: depth * (1.0 - h00.max(h10).max(h01).max(h11)),
            d: [
                depth * (1.0 - height[0]),
                -depth * height[1],
                -depth * height[2],
            ],
        }
    }

    /// D and dD/dσ at σ.
    fn depth(&self, sigma: f64) -> (f64, f64) {
        let s = sigma - self.from;
        let [d0, d1, d2] = self.d;
        (d0 + s * (d1 + s * d2), d1 + 2.0 * s * d2)
    }

    /// The least depth over [a, b]: at an end or at the quadratic's vertex.
    fn shallowest_on(&self, a: f64, b: f64) -> f64 {
        let ends = self.depth(a).0.min(self.depth(b).0);
        let [_, d1, d2] = self.d;
        if d2 > 0.0 {
            let vertex = self.from - d1 / (2.0 * d2);
            if (a..=b).contains(&vertex) {
                return ends.min(self.depth(vertex).0);
            }
        }
        ends
    }
}

/// The first σ in [a, b] (within the piece) where `ray` reaches the relief, given that it has
/// not before a, and the ray's depths `t_a` and `t_b` at the ends.
fn first_crossing(
    piece: &Piece,
    ray: &BentRay,
    (a, t_a): (f64, f64),
    (b, t_b): (f64, f64),
) -> Option<f64> {
    debug_assert!(piece.from <= a && b <= piece.to);
    let deepest = ray.deepest_on((a, t_a), (b, t_b));
    if deepest < piece.shallowest {
        return None;
    }
    let ga = piece.depth(a).0 - t_a;
    if ga <= 0.0 {
        return Some(a);
    }
    if b <= a || piece.shallowest_on(a, b) - deepest > 0.0 {
        return None;
    }
    let gb = piece.depth(b).0 - t_b;
    if gb > 0.0 {
        // Positive at both ends: a crossing needs a dip between them.
        if b - a < TOLERANCE {
            return None;
        }
        let mid = (0.5 * (a + b), ray.depth(0.5 * (a + b)).0);
        return first_crossing(piece, ray, (a, t_a), mid)
            .or_else(|| first_crossing(piece, ray, mid, (b, t_b)));
    }
    // Bracketed: Newton steps, falling back to bisection where one would leave the bracket.
    let gap = |sigma: f64| {
        let (d, dd) = piece.depth(sigma);
        let (t, dt) = ray.depth(sigma);
        (d - t, dd - dt)
    };
    let (mut lo, mut hi) = (a, b);
    let mut x = a + (b - a) * ga / (ga - gb);
    for _ in 0..64 {
        let (g, dg) = gap(x);
        if g > 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        if hi - lo <= TOLERANCE {
            break;
        }
        let newton = x - g / dg;
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= TOLERANCE * 0.25 {
            return Some(next);
        }
        x = next;
    }
    Some(hi)
}
