//! The fast GDM bake: per-direction layer sweeps that reuse the layer already baked.
//!
//! For a direction going up (cos θ > 0) layers are processed from the top down (going down:
//! bottom up). From a sample in layer k the ray is cast *exactly* until it reaches the centre
//! plane of layer k+s (s = `stride`); a hit on the way is exact. Otherwise the remaining
//! distance is read from layer k+s at the point reached, from the four surrounding sample
//! centres (x/y wrap-around, [`super::interpolate::blend`]). All samples of a layer land
//! displaced by the same vector, so whole rows are read at once. Where the four agree — all
//! escape, or all hit at distances within `max_spread` voxels of each other, at most half the
//! weight in solid — the sample escapes or takes the bilinear mean of their hits; where they
//! disagree the ray is traced exactly to the end (on voxel grids, the 64 lanes of a word
//! together), so the approximation is confined to smooth regions.
//!
//! Knobs: `stride` (rays from layers closer than `stride` to the exit plane are traced to the
//! end, so stride ≥ Z is the exact bake) and `max_spread` (0 traces every ray that does not
//! escape with all its neighbours; +∞ interpolates wherever neighbours agree on hit or escape).

use super::Gdm;
use super::caster::{Caster, Trace};
use super::interpolate::LayerStencil;
use super::template::{self, Template};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::DirectionGrid;

pub use mesobake_package::manifest::FastParams;

/// Bakes with layer sweeps, in parallel over directions.
pub fn bake(
    caster: &(impl Caster + ?Sized),
    dirs: DirectionGrid,
    params: FastParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Gdm> {
    if params.stride == 0 || params.max_spread.is_nan() || params.max_spread < 0.0 {
        return Err(Error::InvalidParameter(format!(
            "fast bake: stride must be ≥ 1 layer and the spread ≥ 0 voxels, got {} and {}",
            params.stride, params.max_spread
        )));
    }
    let dims = caster.dims();
    let mut gdm = Gdm::zeroed(dims, dirs, limits)?;
    gdm.fill_directions(observer, |d, volume| {
        sweep_direction(caster, dirs.vector_of(d), params, volume)
    })?;
    Ok(gdm)
}

/// Fills one direction's X×Y×Z volume, layer by layer away from the exit plane.
fn sweep_direction(
    caster: &(impl Caster + ?Sized),
    v: [f64; 3],
    params: FastParams,
    volume: &mut [f32],
) {
    let dims = caster.dims();
    let inside = caster.centres_inside();
    let solid = inside.solid_layer_range();
    // Voxel grids walk one ray template per direction, 64 samples at a time.
    let template =
        (caster.is_voxel_grid() && template::supports(dims)).then(|| Template::new(dims, v));
    let distance = |t: Trace| match t {
        Trace::Inside => 0.0,
        Trace::Hit(t) => t as f32,
        Trace::Escape(_) | Trace::Limit => f32::INFINITY,
    };
    let layer = (dims.x * dims.y) as usize;
    let (mut reused, mut ambiguous) = (vec![0.0; dims.x as usize], vec![false; dims.x as usize]);
    let up = v[2] > 0.0;
    let layers: Vec<u32> = if up {
        (0..dims.z).rev().collect()
    } else {
        (0..dims.z).collect()
    };
    for k in layers {
        // When the stride reaches past the last layer the ray is traced to the end, exactly.
        let remaining = if up { dims.z - 1 - k } else { k };
        let step = if params.stride > remaining {
            0
        } else {
            params.stride
        };
        let (done_part, rest) = if up {
            let (below, above) = volume.split_at_mut((k as usize + 1) * layer);
            (above, &mut below[k as usize * layer..])
        } else {
            let (below, above) = volume.split_at_mut(k as usize * layer);
            (below, &mut above[..layer])
        };
        let target = if up { k + step } else { k - step };
        let target_layer: &[f32] = if step == 0 {
            &[]
        } else if up {
            &done_part[(target - k - 1) as usize * layer..][..layer]
        } else {
            &done_part[target as usize * layer..][..layer]
        };
        let t_step = if step == 0 {
            f64::INFINITY
        } else {
            step as f64 / v[2].abs()
        };
        // Every sample reaching the target layer lands displaced by the same vector; a row
        // of samples reads it in one pass (values from the target layer, ambiguity flags).
        let mut stencil =
            LayerStencil::new(dims, [t_step * v[0], t_step * v[1]], params.max_spread);
        let mut read_row = |j: u32, value: &mut [f32], ambiguous: &mut [bool]| {
            if step == 0 {
                value.fill(f32::INFINITY);
                ambiguous.fill(false);
            } else {
                stencil.read_row(target_layer, j, value, ambiguous);
                for d in value.iter_mut() {
                    *d = (t_step + *d as f64) as f32;
                }
            }
        };
        match &template {
            Some(tpl) => {
                // The steps inside this layer's slab, then the rest of the ray.
                let all = tpl.steps_within(solid, k, f64::INFINITY);
                let slab = tpl.steps_within(solid, k, t_step);
                let beyond = &all[slab.len()..];
                for j in 0..dims.y {
                    let out = &mut rest[(j * dims.x) as usize..][..dims.x as usize];
                    read_row(j, &mut reused, &mut ambiguous);
                    for w in 0..(dims.x as usize).div_ceil(64) {
                        let mut pending = tpl.walk_row(inside, slab, j, k, w, out);
                        let mut unresolved = 0u64;
                        while pending != 0 {
                            let lane = pending.trailing_zeros();
                            let i = 64 * w + lane as usize;
                            if ambiguous[i] {
                                unresolved |= 1 << lane;
                            } else {
                                out[i] = reused[i];
                            }
                            pending &= pending - 1;
                        }
                        // Ambiguous lanes walk the rest of the template together.
                        let mut escaped = tpl.walk_lanes(inside, beyond, j, k, w, unresolved, out);
                        while escaped != 0 {
                            out[64 * w + escaped.trailing_zeros() as usize] = f32::INFINITY;
                            escaped &= escaped - 1;
                        }
                    }
                }
            }
            None => {
                for j in 0..dims.y {
                    read_row(j, &mut reused, &mut ambiguous);
                    let out = &mut rest[(j * dims.x) as usize..][..dims.x as usize];
                    for (i, value) in out.iter_mut().enumerate() {
                        *value = if inside.get(i as u32, j, k) {
                            0.0
                        } else {
                            let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                            match caster.trace(o, v, t_step) {
                                Trace::Limit if !ambiguous[i] => reused[i],
                                Trace::Limit => {
                                    distance(caster.trace_from(o, v, t_step, f64::INFINITY))
                                }
                                t => distance(t),
                            }
                        };
                    }
                }
            }
        }
    }
}
