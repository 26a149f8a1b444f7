//! The exact GDM bake: one ray per sample and direction, cast to its first hit or escape.

use super::caster::{Caster, Trace};
use super::{BakeObserver, Gdm};
use crate::error::{Error, Result};
use crate::grid::DirectionGrid;
use crate::limits::Limits;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

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

/// Bakes with one [`Caster::trace`] per sample and direction.
pub fn bake_per_ray(
    caster: &(impl Caster + ?Sized),
    dirs: DirectionGrid,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    let dims = caster.dims();
    let mut gdm = Gdm::zeroed(dims, dirs, limits)?;
    let layer = (dims.x * dims.y) as usize;
    let total = (dirs.count() * dims.z as usize) as u64;
    let done = AtomicU64::new(0);
    let inside = caster.centres_inside();
    gdm.data_mut()
        .par_chunks_mut(layer)
        .enumerate()
        .try_for_each(|(chunk, out)| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let d = chunk / dims.z as usize;
            let k = (chunk % dims.z as usize) as u32;
            let v = dirs.vector_of(d);
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let value = &mut out[(j * dims.x + i) as usize];
                    if inside.get(i, j, k) {
                        *value = 0.0;
                        continue;
                    }
                    let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                    *value = match caster.trace(o, v, f64::INFINITY) {
                        Trace::Inside => 0.0,
                        Trace::Hit(t) => t as f32,
                        Trace::Escape(_) | Trace::Limit => f32::INFINITY,
                    };
                }
            }
            observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            Ok(())
        })?;
    Ok(gdm)
}
