//! Reading a GDM layer between its sample centres.
//!
//! Layer values follow the GDM's raw convention: 0 inside solid, +∞ for escapes, else the hit
//! distance (> 0 for a sample outside solid). A point between four sample centres is read by
//! [`blend`]: bilinear weights, neighbours in solid carry no distance, and the point escapes
//! unless hitting neighbours outweigh escaping ones.

use mesobake_package::grid::{Dims, Wrap};

/// A layer read at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blend {
    /// The weighted mean distance of the hitting neighbours, or +∞ (escape) when escaping
    /// neighbours carry at least as much weight as hitting ones.
    pub value: f32,
    /// Whether interpolating guesses: some neighbours hit and others escape, more than half
    /// the weight lies in solid (the point is at a surface), or the hit distances differ by
    /// more than the allowed spread (different surfaces).
    pub ambiguous: bool,
}

/// Blends four layer values with their bilinear weights; hit distances may differ by up to
/// `max_spread` voxels before the blend is ambiguous (branch-free, so that row loops
/// vectorize).
#[inline(always)]
pub fn blend(values: [f32; 4], weights: [f32; 4], max_spread: f32) -> Blend {
    let (mut hit, mut escape, mut solid, mut sum) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for (d, w) in values.into_iter().zip(weights) {
        let is_solid = d == 0.0;
        let is_escape = d == f32::INFINITY;
        let is_hit = !is_solid & !is_escape & (w > 0.0);
        solid += if is_solid { w } else { 0.0 };
        escape += if is_escape { w } else { 0.0 };
        hit += if is_hit { w } else { 0.0 };
        sum += if is_hit { w * d } else { 0.0 };
        lo = if is_hit { lo.min(d) } else { lo };
        hi = if is_hit { hi.max(d) } else { hi };
    }
    Blend {
        value: if hit > escape {
            sum / hit
        } else {
            f32::INFINITY
        },
        ambiguous: (hit > 0.0 && escape > 0.0) | (solid > 0.5) | (hi - lo > max_spread),
    }
}

/// Reads a layer at a fixed offset from every sample centre: a sweep reads the layer below or
/// above each sample displaced by the same vector, so the bilinear weights and integer
/// offsets are computed once per layer and whole rows are read at once.
#[derive(Clone, Debug)]
pub struct LayerStencil {
    dims: Dims,
    /// Integer part of the offset, wrapped onto 0..X and 0..Y.
    base: [u32; 2],
    /// Bilinear weights of the neighbours (0,0), (0,1), (1,0), (1,1) (x offset first).
    weights: [f32; 4],
    max_spread: f32,
    /// The four neighbours' values, one row of samples each.
    gathered: [Vec<f32>; 4],
}

impl LayerStencil {
    /// The stencil reading the point displaced by `offset` = (dx, dy) voxels from a sample
    /// centre, on a grid of `dims` (x and y wrap around).
    pub fn new(dims: Dims, offset: [f64; 2], max_spread: f32) -> Self {
        let (bx, by) = (offset[0].floor(), offset[1].floor());
        let (fx, fy) = ((offset[0] - bx) as f32, (offset[1] - by) as f32);
        LayerStencil {
            dims,
            base: [
                Wrap::new(dims.x).apply(bx as i64) as u32,
                Wrap::new(dims.y).apply(by as i64) as u32,
            ],
            weights: [
                (1.0 - fx) * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * (1.0 - fy),
                fx * fy,
            ],
            max_spread,
            gathered: Default::default(),
        }
    }

    /// Reads `layer` (x fastest) for every sample of row `j`: `value[i]` and `ambiguous[i]`
    /// describe the point displaced from sample (i, j).
    pub fn read_row(&mut self, layer: &[f32], j: u32, value: &mut [f32], ambiguous: &mut [bool]) {
        let (x, y) = (self.dims.x as usize, self.dims.y as usize);
        let j0 = (j as usize + self.base[1] as usize) % y;
        let rows = [j0, (j0 + 1) % y].map(|r| &layer[r * x..][..x]);
        for (n, buffer) in self.gathered.iter_mut().enumerate() {
            // Row (n & 1) rotated left by the x offset (n >> 1 adds one column).
            let shift = (self.base[0] as usize + (n >> 1)) % x;
            let row = rows[n & 1];
            buffer.clear();
            buffer.extend_from_slice(&row[shift..]);
            buffer.extend_from_slice(&row[..shift]);
        }
        let [a, b, c, d] = &self.gathered;
        for i in 0..x {
            let r = blend([a[i], b[i], c[i], d[i]], self.weights, self.max_spread);
            value[i] = r.value;
            ambiguous[i] = r.ambiguous;
        }
    }
}

/// Reads `layer` (one GDM layer, x fastest) at point `q` = (x, y) of its centre plane with
/// [`blend`]: the distance there, +∞ for an escape; x and y wrap around.
pub fn sample_layer(dims: Dims, layer: &[f32], q: [f64; 2]) -> f32 {
    let stencil = LayerStencil::new(dims, [q[0] - 0.5, q[1] - 0.5], f32::INFINITY);
    let (x, y) = (dims.x, dims.y);
    let [i0, j0] = stencil.base;
    let value = |n: usize| {
        let i = (i0 + (n >> 1) as u32) % x;
        let j = (j0 + (n & 1) as u32) % y;
        layer[(j * x + i) as usize]
    };
    blend([0, 1, 2, 3].map(value), stencil.weights, f32::INFINITY).value
}

#[cfg(test)]
mod tests {
    use super::*;

    const STRICT: f32 = 1.0;

    #[test]
    fn blend_rules() {
        let w = [0.25; 4];
        // Agreeing hits: the mean (exact in f32 for these values), not ambiguous.
        assert_eq!(
            blend([2.0, 2.5, 3.0, 2.5], w, STRICT),
            Blend {
                value: 2.5,
                ambiguous: false
            }
        );
        // Hits spread over more than 1 voxel: ambiguous.
        assert!(blend([2.0, 2.0, 3.5, 2.0], w, STRICT).ambiguous);
        // Hit and escape: ambiguous; escape wins ties.
        let mixed = blend([2.0, 2.0, f32::INFINITY, f32::INFINITY], w, STRICT);
        assert!(mixed.ambiguous && mixed.value.is_infinite());
        // Half the weight in solid is tolerated, more is not.
        assert_eq!(blend([0.0, 0.0, 4.0, 4.0], w, STRICT).value, 4.0);
        assert!(!blend([0.0, 0.0, 4.0, 4.0], w, STRICT).ambiguous);
        assert!(blend([0.0, 0.0, 0.0, 4.0], w, STRICT).ambiguous);
        // A neighbour of weight 0 counts for nothing, whatever it holds.
        let r = blend([f32::INFINITY, 1.0, 0.0, 1.5], [0.0, 0.5, 0.0, 0.5], STRICT);
        assert_eq!(
            r,
            Blend {
                value: 1.25,
                ambiguous: false
            }
        );
    }

    /// A row read equals point reads at the displaced positions, wrap-around included
    /// (tolerance: 1e-5 relative, the weights being rounded once per stencil versus per point).
    #[test]
    fn row_read_matches_point_reads() {
        let dims = Dims::new(7, 5, 1).unwrap();
        let layer: Vec<f32> = (0..35)
            .map(|n| match n % 9 {
                0 => f32::INFINITY,
                4 => 0.0,
                m => 1.0 + 0.1 * m as f32 + 0.01 * n as f32,
            })
            .collect();
        for offset in [[0.25, 0.75], [-3.6, 9.2], [13.0, -0.5]] {
            let mut stencil = LayerStencil::new(dims, offset, f32::INFINITY);
            let (mut value, mut ambiguous) = (vec![0.0; 7], vec![false; 7]);
            for j in 0..5 {
                stencil.read_row(&layer, j, &mut value, &mut ambiguous);
                for i in 0..7 {
                    let q = [i as f64 + 0.5 + offset[0], j as f64 + 0.5 + offset[1]];
                    let point = sample_layer(dims, &layer, q);
                    let row = value[i as usize];
                    assert!(
                        row == point || (row - point).abs() <= 1e-5 * point.abs(),
                        "offset {offset:?} sample ({i},{j}): row {row} point {point}"
                    );
                }
            }
        }
    }
}
