//! The exact GDM bake: one ray per sample and direction, cast to its first hit or escape.

use super::caster::{Caster, Trace};
use super::{BakeObserver, Gdm};
use crate::error::Result;
use crate::grid::DirectionGrid;
use crate::limits::Limits;

/// Bakes every sample of every direction exactly: voxel grids with ray templates
/// ([`super::template`]), anything else one ray per sample, in parallel over (direction,
/// layer) pairs.
pub fn bake(
    caster: &(impl Caster + ?Sized),
    dirs: DirectionGrid,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    if caster.is_voxel_grid() && super::template::supports(caster.dims()) {
        return super::template::bake(caster.centres_inside(), dirs, limits, observer);
    }
    bake_per_ray(caster, dirs, limits, observer)
}

/// Bakes with one [`Caster::trace`] per sample and direction, in parallel over directions.
/// When the caster knows its [`Caster::surface_candidates`], one ray template per direction
/// first finds where each ray meets the first candidate voxel: rays that meet none escape
/// without being cast, the others start there.
pub fn bake_per_ray(
    caster: &(impl Caster + ?Sized),
    dirs: DirectionGrid,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    let dims = caster.dims();
    let mut gdm = Gdm::zeroed(dims, dirs, limits)?;
    let inside = caster.centres_inside();
    let candidates = caster
        .surface_candidates()
        .filter(|_| super::template::supports(dims));
    gdm.fill_directions(observer, |d, volume| {
        let v = dirs.vector_of(d);
        match candidates {
            Some(c) => super::template::bake_direction(c, v, volume),
            None => volume.fill(0.0),
        }
        for (n, value) in volume.iter_mut().enumerate() {
            let (i, j, k) = (
                n as u32 % dims.x,
                (n as u32 / dims.x) % dims.y,
                n as u32 / (dims.x * dims.y),
            );
            if inside.get(i, j, k) {
                *value = 0.0;
                continue;
            }
            if value.is_infinite() {
                continue; // no candidate voxel on the way: escapes
            }
            let start = (*value as f64 - 1e-4).max(0.0);
            let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
            *value = match caster.trace_from(o, v, start, f64::INFINITY) {
                Trace::Inside => 0.0,
                Trace::Hit(t) => t as f32,
                Trace::Escape(_) | Trace::Limit => f32::INFINITY,
            };
        }
    })?;
    Ok(gdm)
}
