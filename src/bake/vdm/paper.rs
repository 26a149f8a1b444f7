//! The paper's VDM bake (its appendix): for each texel and azimuth the rays at the grid's θ
//! are cast once, on the flat relief (or `oversampling` rays per θ bin, evenly over (0, π/2),
//! a knob the paper leaves at 1); for each curvature their hit points are bent with the
//! surface ([`Bend`]), which moves each to a new view angle θ′ from the entry point, and the
//! values l / sin θ′ are resampled over the uniform θ grid by linear interpolation. Hits whose
//! θ′ does not exceed every earlier one (reordered: occluded after bending) are discarded.
//! Below the first θ′ the first value holds; beyond the last, a convex surface gives
//! [`NO_HIT`] (no intersection exists) and a flat or concave one holds the last value.

use super::bend::Bend;
use super::exact::{Fans, Scratch};
use super::{NO_HIT, Relief, VdmGrid};
use crate::bake::gdm::BakeObserver;
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;
use std::sync::atomic::{AtomicU64, Ordering};

/// Bakes in parallel over azimuths, casting `oversampling` flat rays per θ bin (1 is the
/// paper's: one per bin, at the bins' angles).
pub fn bake(
    relief: Relief,
    grid: VdmGrid,
    oversampling: u32,
    observer: &dyn BakeObserver,
) -> Result<Vec<f32>> {
    let (w, h) = relief.field.size();
    let texels = (w * h) as usize;
    let (n_theta, n_phi, n_c) = (
        grid.n_theta as usize,
        grid.n_phi as usize,
        grid.n_curvature as usize,
    );
    let casts = grid.n_theta * oversampling;
    let thetas: Vec<f64> = (0..casts)
        .map(|m| (f64::from(m) + 0.5) * FRAC_PI_2 / f64::from(casts))
        .collect();
    let flat_fan = Fans::new(relief, &thetas, &[0.0]);
    let sin_cos: Vec<(f64, f64)> = thetas.iter().map(|theta| theta.sin_cos()).collect();
    let grid_thetas: Vec<f64> = (0..grid.n_theta).map(|a| grid.theta(a)).collect();
    let curvatures: Vec<f64> = (0..grid.n_curvature).map(|k| grid.curvature(k)).collect();
    let done = AtomicU64::new(0);
    let per_phi: Vec<Vec<f32>> = (0..grid.n_phi)
        .into_par_iter()
        .map(|b| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let course = flat_fan.course(grid.phi(b));
            let mut flat = vec![None; thetas.len()];
            let mut scratch = Scratch::default();
            let (mut hits, mut seen) = (Vec::new(), Vec::new());
            let mut column = vec![NO_HIT; n_theta];
            // [k][a][texel] for this azimuth.
            let mut out = vec![NO_HIT; n_c * n_theta * texels];
            for texel in 0..texels {
                let texel_at = [texel as u32 % w, texel as u32 / w];
                flat_fan.cast_from(&course, texel_at, &mut flat, &mut scratch);
                hits.clear();
                hits.extend(
                    (sin_cos.iter().zip(&flat))
                        .filter_map(|(&(sin, cos), &d)| Some((d? * sin, d? * cos))),
                );
                for (k, &c) in curvatures.iter().enumerate() {
                    resample(&hits, &grid_thetas, Bend { c }, &mut seen, &mut column);
                    for (a, &v) in column.iter().enumerate() {
                        out[(k * n_theta + a) * texels + texel] = v;
                    }
                }
            }
            observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, n_phi as u64);
            Ok(out)
        })
        .collect::<Result<_>>()?;
    let mut values = vec![NO_HIT; n_c * n_theta * n_phi * texels];
    for (b, block) in per_phi.iter().enumerate() {
        for (ka, image) in block.chunks_exact(texels).enumerate() {
            let (k, a) = (ka / n_theta, ka % n_theta);
            values[((k * n_theta + a) * n_phi + b) * texels..][..texels].copy_from_slice(image);
        }
    }
    Ok(values)
}

/// The VDM column over the grid's θ (`thetas`) for one curvature, from the flat hits (σ, t)
/// in θ order, written to `column`; `seen` is scratch space.
pub fn resample(
    hits: &[(f64, f64)],
    thetas: &[f64],
    bend: Bend,
    seen: &mut Vec<(f64, f64)>,
    column: &mut [f32],
) {
    // (θ′, l / sin θ′) of the hits still seen in order after bending.
    seen.clear();
    for &(sigma, t) in hits {
        let q = bend.to_plane(sigma, t);
        let theta = q[0].atan2(-q[1]);
        // sin θ′ = q_u / |q|.
        let d = if sigma == 0.0 {
            t
        } else {
            sigma * (q[0] * q[0] + q[1] * q[1]).sqrt() / q[0]
        };
        if seen.last().is_none_or(|&(last, _)| theta > last) {
            seen.push((theta, d));
        }
    }
    let (Some(&(first_theta, first)), Some(&(last_theta, last))) = (seen.first(), seen.last())
    else {
        column.fill(NO_HIT);
        return;
    };
    for (value, &theta) in column.iter_mut().zip(thetas) {
        *value = if theta <= first_theta {
            first as f32
        } else if theta > last_theta {
            if bend.c > 0.0 { NO_HIT } else { last as f32 }
        } else {
            let q = seen.partition_point(|&(th, _)| th < theta);
            let ((t0, d0), (t1, d1)) = (seen[q - 1], seen[q]);
            (d0 + (d1 - d0) * (theta - t0) / (t1 - t0)) as f32
        };
    }
}
