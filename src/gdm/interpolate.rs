//! Reading a GDM layer between its sample centres.

use crate::grid::{Dims, Wrap};
use crate::volume::Occupancy;

/// The GDM value at point `q` = (x, y) of layer `k` (on the plane z = k + ½) from that layer's
/// values (`layer`, x fastest, escapes +∞): bilinear between the four surrounding sample
/// centres, x and y wrapping around, leaving out centres inside solid. `None` (escape) when the
/// escaping neighbours carry at least half of the remaining weight; otherwise the weighted
/// mean of the hitting neighbours.
pub fn interpolate_layer(
    dims: Dims,
    inside: &Occupancy,
    k: u32,
    layer: &[f32],
    q: [f64; 2],
) -> Option<f32> {
    let u = q[0] - 0.5;
    let w = q[1] - 0.5;
    let (i0, j0) = (u.floor(), w.floor());
    let (fx, fy) = ((u - i0) as f32, (w - j0) as f32);
    let (i0, j0) = (i0 as i64, j0 as i64);
    let wrap = [Wrap::new(dims.x), Wrap::new(dims.y)];
    let mut escape_weight = 0.0f32;
    let mut hit_weight = 0.0f32;
    let mut hit_sum = 0.0f32;
    for (di, wx) in [(0, 1.0 - fx), (1, fx)] {
        for (dj, wy) in [(0, 1.0 - fy), (1, fy)] {
            let weight = wx * wy;
            if weight == 0.0 {
                continue;
            }
            let i = wrap[0].apply(i0 + di) as u32;
            let j = wrap[1].apply(j0 + dj) as u32;
            if inside.get(i, j, k) {
                continue;
            }
            let d = layer[(j * dims.x + i) as usize];
            if d.is_infinite() {
                escape_weight += weight;
            } else {
                hit_weight += weight;
                hit_sum += weight * d;
            }
        }
    }
    if escape_weight >= hit_weight {
        None
    } else {
        Some(hit_sum / hit_weight)
    }
}
