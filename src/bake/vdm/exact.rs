//! The exact VDM bake: every ray cast against the relief bent to its curvature ([`Bend`]).
//! Sphere tracing on the gap g(τ) = depth of the surface under the ray − depth of the ray,
//! whose rate of change near the ray is bounded ([`SlopeMap`]), each step staying within the
//! bound's reach, so no step skips a crossing (steps are at least 1/[`MIN_STEP_PER_TEXEL`]
//! texel); then bisection to [`TOLERANCE`]. A convex surface's ray that climbs back out through the
//! reference surface without meeting the relief is [`NO_HIT`].

use super::bend::Bend;
use super::{NO_HIT, Relief, SlopeMap, VdmGrid};
use crate::bake::gdm::BakeObserver;
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Largest error of a hit's position along the ray (tile units).
pub const TOLERANCE: f64 = 1e-7;

/// The smallest sphere-tracing step is 1/this of a texel: a crossing shorter than that
/// along the ray (a grazing touch of a crest) may be stepped over.
pub const MIN_STEP_PER_TEXEL: f64 = 16.0;

/// Bakes every (curvature, view) image in parallel.
pub fn bake(relief: Relief, grid: VdmGrid, observer: &dyn BakeObserver) -> Result<Vec<f32>> {
    let (w, h) = relief.field.size();
    let texels = (w * h) as usize;
    let images = (grid.n_curvature * grid.n_theta * grid.n_phi) as usize;
    let slopes = relief.slopes();
    let done = AtomicU64::new(0);
    let mut values = vec![0.0f32; texels * images];
    values
        .par_chunks_mut(texels)
        .enumerate()
        .try_for_each(|(image, out)| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let b = (image % grid.n_phi as usize) as u32;
            let a = (image / grid.n_phi as usize % grid.n_theta as usize) as u32;
            let k = (image / (grid.n_phi * grid.n_theta) as usize) as u32;
            let (theta, phi, bend) = (
                grid.theta(a),
                grid.phi(b),
                Bend {
                    c: grid.curvature(k),
                },
            );
            for (t, v) in out.iter_mut().enumerate() {
                let x = (f64::from(t as u32 % w) + 0.5) / f64::from(w);
                let y = (f64::from(t as u32 / w) + 0.5) / f64::from(h);
                *v = cast(relief, &slopes, [x, y], theta, phi, bend).map_or(NO_HIT, |d| d as f32);
            }
            observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, images as u64);
            Ok(())
        })?;
    Ok(values)
}

/// The VDM value of the ray entering at texture point `p` at angles (θ, φ) on the relief
/// bent by `bend`: l / sin θ, l the arc length to the hit; `None` without a hit.
pub fn cast(
    relief: Relief,
    slopes: &SlopeMap,
    p: [f64; 2],
    theta: f64,
    phi: f64,
    bend: Bend,
) -> Option<f64> {
    let (sin_phi, cos_phi) = phi.sin_cos();
    // The gap between the surface and the ray at distance τ, and the ray's relief coords.
    let at = |sigma: f64| [p[0] + sigma * cos_phi, p[1] + sigma * sin_phi];
    let gap = |tau: f64| {
        let (sigma, t) = bend.to_relief(Bend::ray(theta, tau));
        let [u, v] = at(sigma);
        (relief.surface_depth(u, v) - t, sigma, t)
    };
    // |dσ/dτ| and |dt/dτ| are at most R/(R − t) ≤ 1/(1 − |c|·depth) inside the relief, so a
    // step of τ moves σ at most `speed` times as far: within the slope bound's reach.
    let speed = 1.0 / (1.0 - bend.c.abs() * relief.depth);
    let longest = slopes.reach() / speed;
    let (w, h) = relief.field.size();
    let min_step = 1.0 / (MIN_STEP_PER_TEXEL * f64::from(w.max(h)));
    let (mut lo, mut tau) = (0.0, 0.0);
    let (mut g, mut sigma, mut t) = gap(0.0);
    while g > 0.0 {
        // Above the reference surface again (convex), or round half the cylinder: no hit.
        if (tau > 0.0 && t < -TOLERANCE) || sigma.abs() * bend.c.abs() > std::f64::consts::PI {
            return None;
        }
        lo = tau;
        let [u, v] = at(sigma);
        let rate = speed * (1.0 + slopes.near(u, v));
        tau += (g / rate).clamp(min_step, longest.max(min_step));
        (g, sigma, t) = gap(tau);
    }
    let mut hi = tau;
    while hi - lo > TOLERANCE {
        let mid = 0.5 * (lo + hi);
        if gap(mid).0 > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let (sigma, _) = bend.to_relief(Bend::ray(theta, hi));
    Some(sigma / theta.sin())
}
