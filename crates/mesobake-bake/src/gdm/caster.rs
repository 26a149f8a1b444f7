//! What the GDM bakers need from a mesostructure: which sample centres lie in solid, and the
//! first solid along a ray on the periodic tiling.

use crate::mesostructure::volume::Occupancy;
use mesobake_package::grid::Dims;

/// Outcome of casting one ray through the tiled mesostructure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Trace {
    /// The origin lies in solid (or on its surface): the GDM value is 0.
    Inside,
    /// The first solid point along the ray is at this distance.
    Hit(f64),
    /// The ray left through the top or bottom plane at this distance without a hit
    /// (+∞ for a ray parallel to the planes that never met solid within its length limit).
    Escape(f64),
    /// Nothing was hit up to the caller's distance limit (the ray is still inside the volume).
    Limit,
}

/// A tileable mesostructure that rays can be cast into, in voxel units: x and y repeat with
/// periods X and Y, and rays leave only through the planes z = 0 and z = Z.
pub trait Caster: Sync {
    /// The sampling grid; sample (i, j, k) sits at (i+½, j+½, k+½).
    fn dims(&self) -> Dims;

    /// Which sample centres lie inside solid.
    fn centres_inside(&self) -> &Occupancy;

    /// The first solid point along `origin + t·dir` for 0 ≤ t ≤ `max_t`. `origin` must have
    /// 0 ≤ z ≤ Z and finite coordinates; `dir` must be a finite unit vector.
    fn trace(&self, origin: [f64; 3], dir: [f64; 3], max_t: f64) -> Trace;

    /// Whether the mesostructure *is* the voxel grid of [`Caster::centres_inside`] (solid
    /// voxels as closed boxes), so that exact bakes may use ray templates.
    fn is_voxel_grid(&self) -> bool {
        false
    }

    /// Fills one direction's X×Y×Z volume exactly (the values of one [`Caster::trace`] per
    /// sample) by a faster route when the caster has one, and returns whether it did;
    /// otherwise leaves `volume` alone.
    fn bake_direction(&self, _dir: [f64; 3], _volume: &mut [f32]) -> bool {
        false
    }

    /// Like [`Caster::trace`], for a caller that knows there is no solid before `t_min`.
    fn trace_from(&self, origin: [f64; 3], dir: [f64; 3], _t_min: f64, max_t: f64) -> Trace {
        self.trace(origin, dir, max_t)
    }

    /// The unit outward normal of the surface that [`Caster::trace`] hits along the same ray,
    /// where the caster holds that surface exactly (a mesh tile: the hit triangle's normal);
    /// `None` for voxel boxes, whose shading normal is the material volume's smooth one by
    /// choice, and where the ray hits nothing or starts in solid.
    fn hit_normal(&self, _origin: [f64; 3], _dir: [f64; 3], _max_t: f64) -> Option<[f64; 3]> {
        None
    }
}
