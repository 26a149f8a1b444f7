//! Candidate search for camera and shadow rays: an obvhs wide BVH over padded f64 bounding
//! boxes. It only proposes primitives; every renderer tests them exactly in f64.

use glam::{DVec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    cwbvh::CwBvh,
    cwbvh::builder::build_cwbvh,
    ray::{Ray, RayHit},
};
use std::time::Duration;

/// A BVH over boxes given in f64.
pub struct BoxBvh {
    bvh: CwBvh,
    /// The f64 boxes, in input order.
    boxes: Vec<(DVec3, DVec3)>,
}

impl BoxBvh {
    /// Builds over `boxes` (min, max), each padded ([`padded_f32_box`]) so that f32 traversal
    /// never loses a primitive an f64 test would hit.
    pub fn new(boxes: Vec<(DVec3, DVec3)>) -> BoxBvh {
        let f32_boxes: Vec<Aabb> = boxes.iter().map(|&b| padded_f32_box(b)).collect();
        let bvh = build_cwbvh(
            &f32_boxes,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        BoxBvh { bvh, boxes }
    }

    /// Calls `f(index, t_enter)` for every box the ray `origin + t·dir`, t ∈ [`t_min`, `t_max`],
    /// passes through (a superset: the f32 traversal of the padded boxes).
    pub fn candidates(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
        mut f: impl FnMut(usize, f64),
    ) {
        if self.boxes.is_empty() {
            return;
        }
        let ray = self.ray(origin, dir, t_min, t_max);
        self.bvh.ray_traverse_anyhit(ray, |_, id| {
            let index = self.bvh.primitive_indices[id] as usize;
            if let Some(t) = slab(self.boxes[index], origin, dir, t_min, t_max) {
                f(index, t);
            }
        });
    }

    /// Nearest-hit search: calls `f(index)` for candidate boxes along `origin + t·dir`, t > 0
    /// (the f32 traversal's superset, without an f64 box test), where `f` answers with the ray parameter of its primitive's nearest hit (or `None`);
    /// boxes entered beyond the nearest answer so far are skipped. Returns that answer and its
    /// box.
    pub fn nearest(
        &self,
        origin: DVec3,
        dir: DVec3,
        mut f: impl FnMut(usize) -> Option<f64>,
    ) -> Option<(f64, usize)> {
        let mut best: Option<(f64, usize)> = None;
        if self.boxes.is_empty() {
            return None;
        }
        let ray = self.ray(origin, dir, 0.0, f64::INFINITY);
        let mut hit = RayHit::none();
        self.bvh.ray_traverse(ray, &mut hit, |_, id| {
            let index = self.bvh.primitive_indices[id] as usize;
            match f(index) {
                Some(t) if best.is_none_or(|b| t < b.0) => {
                    best = Some((t, index));
                    // The traversal culls boxes entered beyond this, in its shifted parameter
                    // (rounded up: never culls a box an f64 test would enter first).
                    up(t + f64::from(TRAVERSAL_SHIFT)) * 1.000_001
                }
                _ => f32::INFINITY,
            }
        });
        best
    }

    /// The f32 traversal ray for `[t_min, t_max]`, started [`TRAVERSAL_SHIFT`] back along
    /// `dir` (its parameters shifted by as much).
    fn ray(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> Ray {
        // obvhs mis-traverses directions with negative zeros; adding +0 makes them positive.
        let dir = dir + DVec3::ZERO;
        let shift = f64::from(TRAVERSAL_SHIFT);
        Ray::new(
            (origin - dir * shift).as_vec3a(),
            dir.as_vec3a(),
            ((t_min + shift) as f32).max(0.0),
            if t_max.is_finite() {
                (t_max + shift) as f32 * 1.000_001 + 1e-30
            } else {
                f32::INFINITY
            },
        )
    }
}

/// How far back along the ray (in ray parameter) the f32 traversal starts: obvhs's node
/// test culls every box the ray leaves before parameter 10⁻⁴ (an absolute constant), which
/// at small scene scales is the whole shell around a shadow ray's origin. Starting twice that
/// far back keeps every box from the origin on; the boxes behind it that this adds are
/// dropped by the f64 box test.
const TRAVERSAL_SHIFT: f32 = 2e-4;

/// The f32 box that holds the f64 box (min, max) with room to spare: padded outwards by a
/// relative 1e-5 of its extent plus 1e-6 of its magnitude, rounded outwards.
pub fn padded_f32_box((lo, hi): (DVec3, DVec3)) -> Aabb {
    let pad = (hi - lo).max_element() * 1e-5 + lo.abs().max(hi.abs()).max_element() * 1e-6;
    let down = |v: DVec3| Vec3A::new(down(v.x), down(v.y), down(v.z));
    let up = |v: DVec3| Vec3A::new(up(v.x), up(v.y), up(v.z));
    Aabb::new(down(lo - pad), up(hi + pad))
}

fn down(x: f64) -> f32 {
    let y = x as f32;
    if y as f64 > x { y.next_down() } else { y }
}

fn up(x: f64) -> f32 {
    let y = x as f32;
    if (y as f64) < x { y.next_up() } else { y }
}

/// Entry parameter of the ray into the box, padded by 1e-9 of its size, or `None`.
fn slab((lo, hi): (DVec3, DVec3), o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
    let pad = (hi - lo).max_element() * 1e-9 + 1e-300;
    let (lo, hi) = (lo - pad, hi + pad);
    let (mut t0, mut t1) = (t_min, t_max);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (mut a0, mut a1) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        if a0 > a1 {
            std::mem::swap(&mut a0, &mut a1);
        }
        t0 = t0.max(a0);
        t1 = t1.min(a1);
    }
    (t0 <= t1).then_some(t0)
}
