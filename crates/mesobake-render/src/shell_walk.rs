//! A ray's path through the shell, shared by the renderers that follow the exact mapping (the
//! ground truth of opaque mesostructure and that of translucent media):
//! 1. candidate prisms come from a BVH over the prisms' bounding boxes (a prism lies in the
//!    convex hull of its six corners), visited by entry distance;
//! 2. in a prism, every boundary crossing is found exactly: the top and bottom planes, and
//!    each bilinear fin by its quadratic; the ray is inside the prism on the intervals between
//!    crossings whose midpoint the inverse mapping ([`Prism::locate`]) puts inside;
//! 3. on each interval the texture-space image of the ray, a curve, is split into chords
//!    until each chord's midpoint lies within [`CHORD_TOLERANCE`] voxels of the curve (and no
//!    chord is longer than [`MAX_CHORD`] voxels).

use super::accel::BoxBvh;
use glam::DVec3;
use mesobake_bake::surface::shell::{Prism, PrismPoint, Shell, cubic_roots};
use mesobake_package::grid::Dims;
use std::ops::ControlFlow;

/// Largest distance, in voxels, between a chord's midpoint and the texture-space curve it
/// replaces.
pub const CHORD_TOLERANCE: f64 = 0.01;

/// Longest chord in voxels (keeps the midpoint test meaningful on long segments).
pub const MAX_CHORD: f64 = 8.0;

/// Tolerance of the inverse mapping's inside test, in barycentric / w units.
const LOCATE_TOLERANCE: f64 = 1e-7;

/// One straight texture-space piece of a ray's image in a prism, from end 0 to end 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chord {
    /// Ray parameters of its ends.
    pub t: [f64; 2],
    /// Prism coordinates of its ends.
    pub point: [PrismPoint; 2],
    /// Texture coordinates of its ends (voxel units, z clamped to the volume).
    pub texture: [DVec3; 2],
}

impl Chord {
    /// The ray parameter at texture-space distance `s` from end 0 (linear along the chord).
    pub fn t_at(&self, s: f64) -> f64 {
        let len = (self.texture[1] - self.texture[0]).length();
        self.t[0] + s / len * (self.t[1] - self.t[0])
    }

    /// The prism coordinates at texture-space distance `s` from end 0 (linear along the chord).
    pub fn point_at(&self, s: f64) -> PrismPoint {
        let f = s / (self.texture[1] - self.texture[0]).length();
        let [a, b] = self.point;
        PrismPoint {
            bary: [0, 1, 2].map(|k| a.bary[k] + (b.bary[k] - a.bary[k]) * f),
            w: a.w + (b.w - a.w) * f,
        }
    }
}

/// The shell of one scene, ready for walking rays through it.
pub struct ShellWalk<'a> {
    shell: &'a Shell,
    bvh: BoxBvh,
    scale: DVec3,
}

impl<'a> ShellWalk<'a> {
    /// Prepares `shell` for a mesostructure of resolution `dims`.
    pub fn new(shell: &'a Shell, dims: Dims) -> Self {
        let boxes = shell
            .prisms
            .iter()
            .map(|p| {
                let top = p.top();
                let mut lo = p.bottom[0];
                let mut hi = p.bottom[0];
                for c in p.bottom.iter().chain(&top) {
                    lo = lo.min(*c);
                    hi = hi.max(*c);
                }
                (lo, hi)
            })
            .collect();
        ShellWalk {
            shell,
            bvh: BoxBvh::new(boxes),
            scale: DVec3::new(dims.x as f64, dims.y as f64, dims.z as f64),
        }
    }

    /// The shell.
    pub fn shell(&self) -> &'a Shell {
        self.shell
    }

    /// The texture's resolution as a vector: texture coordinates × scale = voxel units.
    pub fn scale(&self) -> DVec3 {
        self.scale
    }

    /// The prisms whose bounding boxes `origin + t·dir`, t ∈ [`t_min`, `t_max`], passes
    /// through, as (entry parameter, prism index) in order of entry.
    pub fn candidates(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Vec<(f64, usize)> {
        let mut candidates = Vec::new();
        self.bvh
            .candidates(origin, dir, t_min, t_max, |i, t| candidates.push((t, i)));
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        candidates
    }

    /// Every interval of the ray, within [`t_min`, `t_max`], inside some prism, as
    /// (start, end, prism) in order along the ray.
    pub fn intervals(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Vec<(f64, f64, usize)> {
        let mut out = Vec::new();
        for (_, i) in self.candidates(origin, dir, t_min, t_max) {
            for (a, b) in self.inside(i, origin, dir, t_min, t_max) {
                out.push((a, b, i));
            }
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
        out
    }

    /// The intervals of the ray, within [`t_min`, `t_max`], inside prism `i`, in order (an
    /// unbounded ray ends at its last crossing).
    pub fn inside(
        &self,
        i: usize,
        o: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Vec<(f64, f64)> {
        let prism = &self.shell.prisms[i];
        let mut ts = crossings(prism, o, dir);
        ts.retain(|t| *t > t_min && *t < t_max);
        ts.sort_by(f64::total_cmp);
        let Some(&last) = ts.last() else {
            return Vec::new();
        };
        let end = if t_max.is_finite() { t_max } else { last };
        let mut points = Vec::with_capacity(ts.len() + 2);
        points.push(t_min);
        points.extend(ts);
        points.push(end);
        let inside = |t: f64| prism.locate(o + dir * t, LOCATE_TOLERANCE, None).is_some();
        let mut out = Vec::new();
        let mut start: Option<f64> = None;
        for w in points.windows(2) {
            let (a, b) = (w[0], w[1]);
            if b <= a {
                continue;
            }
            if inside(0.5 * (a + b)) {
                start.get_or_insert(a);
            } else if let Some(s) = start.take() {
                out.push((s, a));
            }
        }
        if let Some(s) = start {
            out.push((s, end));
        }
        out
    }

    /// Calls `f` on the chords of the texture-space image of the ray over [`ta`, `tb`] (inside
    /// prism `i`), nearest first, until it breaks; returns what it broke with.
    pub fn chords<B>(
        &self,
        i: usize,
        o: DVec3,
        dir: DVec3,
        (ta, tb): (f64, f64),
        mut f: impl FnMut(&Chord) -> ControlFlow<B>,
    ) -> Option<B> {
        let prism = &self.shell.prisms[i];
        let z_top = self.scale.z;
        let at = |t: f64, hint: Option<PrismPoint>| -> Option<(PrismPoint, DVec3)> {
            let q = prism.locate(o + dir * t, 1e-6, hint)?.clamped();
            Some((q, prism.texture(q) * self.scale))
        };
        let first = at(ta, None)?;
        let last = at(tb, Some(first.0))?;
        // Chords in order: a stack of pending segments, the nearest on top.
        let mut stack = vec![(ta, first, tb, last, 0u32)];
        while let Some((t0, a, t1, b, depth)) = stack.pop() {
            let tm = 0.5 * (t0 + t1);
            let chord = b.1 - a.1;
            if depth < 40
                && let Some(m) = at(tm, Some(a.0))
            {
                let deviation = (m.1 - 0.5 * (a.1 + b.1)).length();
                if deviation > CHORD_TOLERANCE || chord.length() > MAX_CHORD {
                    stack.push((tm, m, t1, b, depth + 1));
                    stack.push((t0, a, tm, m, depth + 1));
                    continue;
                }
            }
            let start = DVec3::new(a.1.x, a.1.y, a.1.z.clamp(0.0, z_top));
            let len = (b.1 - start).length();
            if len.is_nan() || len <= 1e-12 {
                continue;
            }
            let chord = Chord {
                t: [t0, t1],
                point: [a.0, b.0],
                texture: [start, b.1],
            };
            if let ControlFlow::Break(out) = f(&chord) {
                return Some(out);
            }
        }
        None
    }
}

/// Every ray parameter where the ray may cross the prism's boundary: the top and bottom
/// planes, and the roots of each fin's quadratic (the heights w where the ray meets the line
/// through the fin's level segment), a superset of the true crossings.
fn crossings(prism: &Prism, o: DVec3, dir: DVec3) -> Vec<f64> {
    let mut ts = Vec::with_capacity(8);
    let top = prism.top();
    for tri in [top, prism.bottom] {
        let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let cos = n.dot(dir);
        if cos != 0.0 {
            ts.push(n.dot(tri[0] - o) / cos);
        }
    }
    for k in 0..3 {
        let (i, j) = (k, (k + 1) % 3);
        let (a0, a1) = (prism.bottom[i] - o, prism.extrusion[i]);
        let (e0, e1) = (
            prism.bottom[j] - prism.bottom[i],
            prism.extrusion[j] - prism.extrusion[i],
        );
        // g(w) = (a0 + w a1)·(dir × (e0 + w e1))
        let c = [
            a0.dot(dir.cross(e0)),
            a1.dot(dir.cross(e0)) + a0.dot(dir.cross(e1)),
            a1.dot(dir.cross(e1)),
            0.0,
        ];
        for w in cubic_roots(c, -1e-6, 1.0 + 1e-6) {
            // The ray parameter of the closest point to the line Q_i(w) + s·E(w).
            let (r, e) = (a0 + a1 * w, e0 + e1 * w);
            let (dd, de, ee) = (dir.dot(dir), dir.dot(e), e.dot(e));
            let det = dd * ee - de * de;
            if det > 0.0 {
                ts.push((dir.dot(r) * ee - de * e.dot(r)) / det);
            }
        }
    }
    ts.retain(|t| t.is_finite());
    ts
}
