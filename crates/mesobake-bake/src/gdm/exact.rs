//! The exact GDM bake: every sample's ray in every direction, cast to its first hit or escape.

use super::Gdm;
use super::caster::{Caster, Trace};
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::DirectionGrid;

/// Bakes every sample of every direction exactly, in parallel over directions: with the
/// caster's own per-direction route where it has one ([`Caster::bake_direction`]: ray
/// templates over voxels or binned triangles), else one [`Caster::trace`] per sample.
pub fn bake(
    caster: &(impl Caster + ?Sized),
    dirs: DirectionGrid,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    let mut gdm = Gdm::zeroed(caster.dims(), dirs, limits)?;
    super::template::check_memory(caster.dims(), dirs, limits)?;
    gdm.fill_directions(observer, |d, volume| {
        let v = dirs.vector_of(d);
        if !caster.bake_direction(v, volume) {
            trace_direction(caster, v, volume);
        }
    })?;
    Ok(gdm)
}

/// Bakes with one [`Caster::trace`] per sample and direction, in parallel over directions:
/// the reference and baseline for the per-direction routes.
pub fn bake_per_ray(
    caster: &(impl Caster + ?Sized),
    dirs: DirectionGrid,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    let mut gdm = Gdm::zeroed(caster.dims(), dirs, limits)?;
    gdm.fill_directions(observer, |d, volume| {
        trace_direction(caster, dirs.vector_of(d), volume)
    })?;
    Ok(gdm)
}

/// Fills one direction's volume with one trace per sample.
fn trace_direction(caster: &(impl Caster + ?Sized), v: [f64; 3], volume: &mut [f32]) {
    let dims = caster.dims();
    let inside = caster.centres_inside();
    for (n, value) in volume.iter_mut().enumerate() {
        let (i, j, k) = (
            n as u32 % dims.x,
            (n as u32 / dims.x) % dims.y,
            n as u32 / (dims.x * dims.y),
        );
        *value = if inside.get(i, j, k) {
            0.0
        } else {
            let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
            match caster.trace(o, v, f64::INFINITY) {
                Trace::Inside => 0.0,
                Trace::Hit(t) => t as f32,
                Trace::Escape(_) | Trace::Limit => f32::INFINITY,
            }
        };
    }
}
