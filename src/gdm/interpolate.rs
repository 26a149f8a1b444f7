//! Reading a GDM layer between its sample centres.

use crate::grid::{Dims, Wrap};
use crate::volume::Occupancy;

/// The four sample centres around a point of a layer, summarized for interpolation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LayerSample {
    /// Bilinear weight of neighbours whose ray hits.
    pub hit_weight: f32,
    /// Bilinear weight of neighbours whose ray escapes.
    pub escape_weight: f32,
    /// Bilinear weight of neighbours inside solid (they carry no distance).
    pub solid_weight: f32,
    /// Weighted mean distance of the hitting neighbours.
    pub mean_hit: f32,
    /// Largest minus smallest distance among the hitting neighbours.
    pub spread: f32,
}

impl LayerSample {
    /// The interpolated value: `None` (escape) when escaping neighbours carry at least as much
    /// weight as hitting ones, else the weighted mean of the hits.
    pub fn blend(&self) -> Option<f32> {
        (self.hit_weight > self.escape_weight).then_some(self.mean_hit)
    }

    /// Whether the neighbours disagree, so that interpolating would guess: some hit and some
    /// escape, one lies in solid (the point is next to a surface), or the hit distances differ
    /// by more than `max_spread` voxels (different surfaces).
    pub fn is_ambiguous(&self, max_spread: f32) -> bool {
        (self.hit_weight > 0.0 && self.escape_weight > 0.0)
            || self.solid_weight > 0.0
            || self.spread > max_spread
    }
}

/// Summarizes the four sample centres around point `q` = (x, y) of layer `k` (the plane
/// z = k + ½) from that layer's values (`layer`, x fastest, escapes +∞), with bilinear
/// weights; x and y wrap around.
pub fn sample_layer(
    dims: Dims,
    inside: &Occupancy,
    k: u32,
    layer: &[f32],
    q: [f64; 2],
) -> LayerSample {
    let u = q[0] - 0.5;
    let w = q[1] - 0.5;
    let (i0, j0) = (u.floor(), w.floor());
    let (fx, fy) = ((u - i0) as f32, (w - j0) as f32);
    let (i0, j0) = (i0 as i64, j0 as i64);
    let wrap = [Wrap::new(dims.x), Wrap::new(dims.y)];
    let mut s = LayerSample::default();
    let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f32);
    for (di, wx) in [(0, 1.0 - fx), (1, fx)] {
        for (dj, wy) in [(0, 1.0 - fy), (1, fy)] {
            let weight = wx * wy;
            if weight == 0.0 {
                continue;
            }
            let i = wrap[0].apply(i0 + di) as u32;
            let j = wrap[1].apply(j0 + dj) as u32;
            if inside.get(i, j, k) {
                s.solid_weight += weight;
                continue;
            }
            let d = layer[(j * dims.x + i) as usize];
            if d.is_infinite() {
                s.escape_weight += weight;
            } else {
                s.hit_weight += weight;
                sum += weight * d;
                lo = lo.min(d);
                hi = hi.max(d);
            }
        }
    }
    if s.hit_weight > 0.0 {
        s.mean_hit = sum / s.hit_weight;
        s.spread = hi - lo;
    }
    s
}
