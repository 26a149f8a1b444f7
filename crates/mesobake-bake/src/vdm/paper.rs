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
use super::{NO_HIT, Relief, VdmGrid, bake_by_azimuth};
use mesobake_core::error::Result;
use mesobake_core::observer::BakeObserver;
use std::f64::consts::FRAC_PI_2;

/// Bakes in parallel over azimuths, casting `oversampling` flat rays per θ bin (1 is the
/// paper's: one per bin, at the bins' angles).
pub fn bake(
    relief: Relief,
    grid: VdmGrid,
    oversampling: u32,
    observer: &dyn BakeObserver,
) -> Result<Vec<f32>> {
    let casts = grid.n_theta * oversampling;
    let thetas: Vec<f64> = (0..casts)
        .map(|m| (f64::from(m) + 0.5) * FRAC_PI_2 / f64::from(casts))
        .collect();
    let flat_fan = Fans::new(relief, &thetas, &[0.0]);
    let sin_cos: Vec<(f64, f64)> = thetas.iter().map(|theta| theta.sin_cos()).collect();
    bake_by_azimuth(
        relief.field.size(),
        grid,
        observer,
        |b| {
            let course = flat_fan.course(grid.phi(b));
            let flat = vec![None; thetas.len()];
            (course, flat, Scratch::default(), Resampling::new(grid))
        },
        |(course, flat, scratch, resampling), texel, out| {
            flat_fan.cast_from(course, texel, flat, scratch);
            resampling.hits.clear();
            resampling.hits.extend(
                (sin_cos.iter().zip(flat.iter()))
                    .filter_map(|(&(sin, cos), &d)| Some((d? * sin, d? * cos))),
            );
            resampling.resample(out);
        },
    )
}

/// The paper's resampling of one texel's flat hits over the θ of a grid, on each of its
/// curvatures, with the scratch space it reuses from texel to texel.
struct Resampling {
    thetas: Vec<f64>,
    curvatures: Vec<f64>,
    /// The flat hits (σ, t), in θ order: what [`Resampling::resample`] bends.
    hits: Vec<(f64, f64)>,
    /// Per hit, sin and cos of σ·c on the curvature being resampled, and of σ times the step
    /// to the next: the grid's curvatures are evenly spaced, so each hit's sines are turned
    /// from one curvature to the next by the angle-sum formulas instead of a `sin_cos` each.
    /// The turns' rounding is absolute (about k units in the last place of 1 after k turns),
    /// so the curvature nearest 0, if not 0 itself, has its sines taken directly: there sin
    /// σc is small and 1/c large.
    turns: Vec<([f64; 2], [f64; 2])>,
    /// (θ′, l / sin θ′) of the hits still seen in order after bending.
    seen: Vec<(f64, f64)>,
}

impl Resampling {
    /// The resampling onto `grid`'s θ and curvatures.
    fn new(grid: VdmGrid) -> Resampling {
        Resampling {
            thetas: grid.thetas(),
            curvatures: grid.curvatures(),
            hits: Vec::new(),
            turns: Vec::new(),
            seen: Vec::new(),
        }
    }

    /// The VDM values of [`Resampling::hits`] on every curvature, written to `out` by
    /// curvature, then θ.
    fn resample(&mut self, out: &mut [f32]) {
        let (first, step) = match self.curvatures[..] {
            [first, second, ..] => (first, second - first),
            [first] => (first, 0.0),
            [] => return,
        };
        self.turns.clear();
        self.turns.extend(self.hits.iter().map(|&(sigma, _)| {
            let (sin, cos) = (sigma * first).sin_cos();
            let (sin_step, cos_step) = (sigma * step).sin_cos();
            ([sin, cos], [sin_step, cos_step])
        }));
        for (&c, column) in self
            .curvatures
            .iter()
            .zip(out.chunks_exact_mut(self.thetas.len()))
        {
            let bend = Bend { c };
            let near_zero = c != 0.0 && c.abs() < 0.5 * step.abs();
            self.seen.clear();
            for (&(sigma, t), (turn, by)) in self.hits.iter().zip(&mut self.turns) {
                let q = if near_zero {
                    bend.to_plane(sigma, t)
                } else {
                    bend.to_plane_turned(sigma, t, *turn)
                };
                *turn = [
                    turn[0].mul_add(by[1], turn[1] * by[0]),
                    turn[1].mul_add(by[1], -(turn[0] * by[0])),
                ];
                // The `libm` crate's atan2 (inlined) bakes 1.2× as fast as the system's, with
                // the same values on the built-in reliefs.
                let theta = libm::atan2(q[0], -q[1]);
                // sin θ′ = q_u / |q|.
                let d = if sigma == 0.0 {
                    t
                } else {
                    sigma * (q[0] * q[0] + q[1] * q[1]).sqrt() / q[0]
                };
                if self.seen.last().is_none_or(|&(last, _)| theta > last) {
                    self.seen.push((theta, d));
                }
            }
            column_of(&self.seen, &self.thetas, c, column);
        }
    }
}

/// The VDM column over `thetas` on curvature `c` from the bent hits `seen` (θ′, value) in
/// ascending θ′: interpolated linearly between them; below the first θ′ the first value, and
/// beyond the last [`NO_HIT`] on a convex surface, else the last value.
fn column_of(seen: &[(f64, f64)], thetas: &[f64], c: f64, column: &mut [f32]) {
    let (Some(&(first_theta, first)), Some(&(last_theta, last))) = (seen.first(), seen.last())
    else {
        column.fill(NO_HIT);
        return;
    };
    for (value, &theta) in column.iter_mut().zip(thetas) {
        *value = if theta <= first_theta {
            first as f32
        } else if theta > last_theta {
            if c > 0.0 { NO_HIT } else { last as f32 }
        } else {
            let q = seen.partition_point(|&(th, _)| th < theta);
            let ((t0, d0), (t1, d1)) = (seen[q - 1], seen[q]);
            (d0 + (d1 - d0) * (theta - t0) / (t1 - t0)) as f32
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The resampling (sines turned from curvature to curvature, `libm`'s atan2) gives the
    /// values of a plain one (a `sin_cos` and the system's atan2 per hit and curvature, a
    /// linear search for each θ) to f32 rounding, on 1024 curvatures (the most turns a grid
    /// allows), on grids whose middle curvature is 1.1·10⁻⁶ (near the least but 0 a grid may
    /// have), and on hits of a flat and of a rough relief.
    #[test]
    fn turned_sines_resample_as_a_sine_per_curvature_does() {
        let grid = |n_curvature, c_min: f64, c_max| VdmGrid {
            n_theta: 8,
            n_phi: 1,
            n_curvature,
            c_min,
            c_max,
        };
        let thetas: Vec<f64> = (0..8).map(|a| grid(1, 0.0, 0.0).theta(a)).collect();
        let plain = |hits: &[(f64, f64)], c: f64| -> Vec<f32> {
            let mut seen: Vec<(f64, f64)> = Vec::new();
            for &(sigma, t) in hits {
                let q = Bend { c }.to_plane(sigma, t);
                let theta = q[0].atan2(-q[1]);
                let d = if sigma == 0.0 {
                    t
                } else {
                    sigma * q[0].hypot(q[1]) / q[0]
                };
                if seen.last().is_none_or(|s| theta > s.0) {
                    seen.push((theta, d));
                }
            }
            let (first, last) = (seen[0], seen[seen.len() - 1]);
            thetas
                .iter()
                .map(|&theta| {
                    if theta <= first.0 {
                        first.1 as f32
                    } else if theta > last.0 {
                        if c > 0.0 { NO_HIT } else { last.1 as f32 }
                    } else {
                        let i = (1..seen.len()).find(|&i| seen[i].0 >= theta).unwrap();
                        let ((t0, d0), (t1, d1)) = (seen[i - 1], seen[i]);
                        (d0 + (d1 - d0) * (theta - t0) / (t1 - t0)) as f32
                    }
                })
                .collect()
        };
        let (mut compared, mut worst) = (0, 0.0f64);
        for (grid, depth) in [
            (grid(1024, -3.9, 3.9), 0.25),
            (grid(3, -3.9, 3.9 + 2.2e-6), 0.25),
            // Turned by 10⁵ per tile to 1.1·10⁻⁶: only the direct sines hold that one.
            (grid(3, -1e5, 1e5 + 2.2e-6), 9e-6),
        ] {
            grid.validate(depth).unwrap();
            let mut resampling = Resampling::new(grid);
            let mut out = vec![0.0; grid.n_curvature as usize * 8];
            for rough in [0.0, 0.3, 0.9] {
                // Each flat ray's hit at depth t ≤ depth, σ = t·tan θ.
                resampling.hits = thetas
                    .iter()
                    .enumerate()
                    .map(|(a, &theta)| {
                        let t = depth * (1.0 - rough * ((a * 7 % 5) as f64 / 5.0));
                        (t * theta.tan(), t)
                    })
                    .collect();
                resampling.resample(&mut out);
                for (k, column) in out.chunks_exact(8).enumerate() {
                    let want = plain(&resampling.hits, grid.curvature(k as u32));
                    for (&got, &want) in column.iter().zip(&want) {
                        assert_eq!(got == NO_HIT, want == NO_HIT, "curvature {k}");
                        if want != NO_HIT {
                            let e = f64::from((got - want).abs()) / f64::from(want.abs());
                            worst = worst.max(e);
                            compared += 1;
                        }
                    }
                }
            }
        }
        assert!(compared > 10_000, "{compared}");
        assert!(worst <= 1e-6, "{worst}");
    }
}
