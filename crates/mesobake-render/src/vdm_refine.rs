//! The VDM's refinement on its height field (a scene's `vdm.refine_texels` N > 0): the
//! paper's lookup answers how far a view ray travels before it meets the relief, interpolated
//! between texels, view directions and curvatures, so that across a dome's outline it blends
//! "meets the dome" with "meets the floor behind it" and the compressed maximum view map
//! draws the silhouettes a texel or two off. The refinement keeps the lookup as the first
//! guess and settles the answer on the height field itself (bilinear, as the hit's depth and
//! normal already read it), along the same ray bent to the view's curvature ([`Bend`]):
//!
//! - **a hit** at distance d: the ray is marched in steps of [`REFINE_STEP`] texels from N
//!   texels before d (walking back first if that point is already inside the relief) to N
//!   texels after it; the first crossing into the relief, bisected [`REFINE_BISECTIONS`]
//!   times, is the hit; without a crossing in the window the lookup's d stands;
//! - **a miss** (the lookup's silhouette): the part of the ray deeper than the relief's
//!   highest point — found in closed form, none on a convex surface the ray leaves first —
//!   is marched for 2N texels from where it begins; a crossing there is a hit.
//!
//! N = ∞ would be an exact height-field ray march; N bounds the cost per fragment (at most
//! 4N/[`REFINE_STEP`] + [`REFINE_BISECTIONS`] height samples). The WGSL (`vdm_preview.wgsl`,
//! `refine_hit`, `refine_miss`) runs the same steps.

use glam::DVec2;
use mesobake_bake::vdm::Relief;
use mesobake_bake::vdm::bend::Bend;

/// The search's step along the view ray, in texels (before bisection).
pub const REFINE_STEP: f64 = 0.5;

/// Bisections of the crossing found (to 1/64 of a step).
pub const REFINE_BISECTIONS: u32 = 6;

/// Curvatures (1/tile) below this are flat: for the refinement's bent ray as for the
/// renderer's shadow geometry (the bent formulas would divide by them).
pub const FLAT_CURVATURE: f64 = 1e-6;

/// One fragment's view ray on the relief bent to its curvature.
pub struct BentRay<'a> {
    /// The relief.
    pub relief: Relief<'a>,
    /// The relief's least depth below the reference surface (tiles): depth · (1 − max h).
    pub top_depth: f64,
    /// Where the ray enters the reference surface (tiles).
    pub entry: DVec2,
    /// The azimuth of its texture-space motion, (cos φ_V, sin φ_V).
    pub azimuth: DVec2,
    /// Its polar angle θ_V from the inward normal.
    pub theta: f64,
    /// The reference surface's curvature along it (1/tile, positive convex).
    pub c: f64,
}

impl BentRay<'_> {
    /// The relief coordinates (σ, t) of the point at distance τ along the ray: those of
    /// [`Bend::to_relief`], in forms that hold as c → 0 and in f32 (the WGSL's).
    fn at(&self, tau: f64) -> (f64, f64) {
        let [u, w] = Bend::ray(self.theta, tau);
        let c = self.c;
        // t = R − sign(R)·|q − centre| = −k / (1 + √(1 + c·k)), k = 2w + c·|q|².
        let k = 2.0 * w + c * (u * u + w * w);
        let t = -k / (1.0 + (1.0 + c * k).max(0.0).sqrt());
        let sigma = if c.abs() < FLAT_CURVATURE {
            u
        } else {
            (c * u).atan2(1.0 + c * w) / c
        };
        (sigma, t)
    }

    /// Whether the point at distance τ lies in the relief (at or below its surface).
    fn inside(&self, tau: f64) -> bool {
        let (sigma, depth) = self.at(tau);
        let p = self.entry + self.azimuth * sigma;
        depth >= self.relief.surface_depth(p.x, p.y)
    }

    /// One texel in tiles (the field's finer side).
    fn texel(&self) -> f64 {
        let (w, h) = self.relief.field.size();
        1.0 / f64::from(w.max(h))
    }

    /// The arc length σ of the hit refined from the lookup's `d` within `texels` texels.
    pub fn refine_hit(&self, d: f64, texels: u32) -> f64 {
        let lookup = d * self.theta.sin();
        let (texel, window) = (self.texel(), f64::from(texels) * self.texel());
        let step = REFINE_STEP * texel;
        let start = ray_length_to_arc(lookup, self.theta, self.c).unwrap_or(d);
        let first = (start - window).max(0.0);
        let (outside, inner) = if self.inside(first) {
            // The hit lies before the window: walk back to the last point outside.
            let (mut a, mut b) = (first, first);
            while a > 0.0 && a > start - 2.0 * window && self.inside(a) {
                b = a;
                a = (a - step).max(0.0);
            }
            (a, b)
        } else {
            match self.first_crossing(first, start + window, step) {
                Some(bracket) => bracket,
                None => return lookup,
            }
        };
        if self.inside(outside) || !self.inside(inner) {
            return lookup;
        }
        self.bisect(outside, inner)
    }

    /// The arc length σ of a hit the lookup called a miss, searched over 2·`texels` texels
    /// where the ray is deep enough to meet the relief; `None` where it does not.
    pub fn refine_miss(&self, texels: u32) -> Option<f64> {
        let (cos, t) = (self.theta.cos(), self.top_depth);
        // The ray's depth reaches t where c·τ² − 2τ·cos θ + 2t − c·t² = 0.
        let e = cos * cos - self.c * (2.0 * t - self.c * t * t);
        if e < 0.0 {
            return None; // the ray leaves a convex surface above the relief
        }
        let root = e.sqrt();
        let deep = (2.0 * t - self.c * t * t) / (cos + root);
        let mut end = deep + 2.0 * f64::from(texels) * self.texel();
        if self.c > FLAT_CURVATURE {
            end = end.min((cos + root) / self.c);
        }
        if !deep.is_finite() || deep < 0.0 {
            return None;
        }
        if self.inside(deep) {
            return Some(self.at(deep).0);
        }
        let (outside, inner) = self.first_crossing(deep, end, REFINE_STEP * self.texel())?;
        Some(self.bisect(outside, inner))
    }

    /// The first step from `from` (outside) that lands inside, no further than `to`: the
    /// distances just before and at it.
    fn first_crossing(&self, from: f64, to: f64, step: f64) -> Option<(f64, f64)> {
        let (mut a, mut b) = (from, from + step);
        while b <= to {
            if self.inside(b) {
                return Some((a, b));
            }
            a = b;
            b += step;
        }
        None
    }

    /// The arc length of the crossing between τ `outside` and τ `inner`, bisected.
    fn bisect(&self, mut outside: f64, mut inner: f64) -> f64 {
        for _ in 0..REFINE_BISECTIONS {
            let mid = 0.5 * (outside + inner);
            if self.inside(mid) {
                inner = mid;
            } else {
                outside = mid;
            }
        }
        self.at(0.5 * (outside + inner)).0
    }
}

/// The distance τ along the view ray entering at `theta` on the reference surface bent to
/// `c` (1/tile) at which the ray lies under the surface point at arc length `sigma`: the
/// inverse of the lookup's σ = d·sin θ (for c = 0, τ = σ / sin θ); `None` where no point of
/// the ray does.
pub fn ray_length_to_arc(sigma: f64, theta: f64, c: f64) -> Option<f64> {
    if c.abs() < FLAT_CURVATURE {
        return (theta.sin() > 0.0).then(|| sigma / theta.sin());
    }
    // The ray (τ sin θ, −τ cos θ) meets the radius at angle α = c·σ about the centre
    // (0, −1/c) where τ = sin α / (c · sin(θ + α)).
    let alpha = c * sigma;
    let tau = alpha.sin() / (c * (theta + alpha).sin());
    (tau.is_finite() && tau >= 0.0).then_some(tau)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesobake_bake::mesostructure::height_field::HeightField;

    /// A hemisphere-like dome on a floor: the refinement against a plain fine march of the
    /// same bent ray (1/200 texel steps), which needs no lookup at all.
    #[test]
    fn the_refined_hit_is_the_marched_hit() {
        let n = 32u32;
        let heights: Vec<f32> = (0..n * n)
            .map(|k| {
                let (x, y) = (
                    (f64::from(k % n) + 0.5) / f64::from(n) - 0.5,
                    (f64::from(k / n) + 0.5) / f64::from(n) - 0.5,
                );
                (1.0 - (x * x + y * y) / 0.09).max(0.0).sqrt() as f32
            })
            .collect();
        let field = HeightField::new(n, n, heights).unwrap();
        let relief = Relief {
            field: &field,
            depth: 0.2,
        };
        let top_depth =
            0.2 * (1.0 - f64::from(field.heights().iter().cloned().fold(0.0, f32::max)));
        let mut checked = 0;
        for c in [-0.5, 0.0, 0.6] {
            for (theta, phi) in [(0.3f64, 0.2f64), (1.0, 1.5), (1.35, -2.0)] {
                let ray = BentRay {
                    relief,
                    top_depth,
                    entry: DVec2::new(0.1, 0.05),
                    azimuth: DVec2::new(phi.cos(), phi.sin()),
                    theta,
                    c,
                };
                // The plain march: first τ inside, from the top.
                let fine = 1.0 / (200.0 * f64::from(n));
                let mut tau = 0.0;
                while !ray.inside(tau) && tau < 20.0 {
                    tau += fine;
                }
                if tau >= 20.0 {
                    continue; // the ray leaves the convex surface
                }
                let marched = ray.at(tau).0;
                // A lookup off by three texels either way (never before the entry) is pulled
                // back to the march.
                for off in [-3.0, 3.0] {
                    let sigma = (marched + off / f64::from(n)).max(0.0);
                    let d = sigma / theta.sin();
                    let refined = ray.refine_hit(d, 8);
                    assert!(
                        (refined - marched).abs() < 0.05 / f64::from(n),
                        "c {c} θ {theta}: {refined} against {marched} (lookup off {off})"
                    );
                }
                // And the miss search finds it too when the lookup says nothing.
                let found = ray.refine_miss(64).expect("a hit within the search");
                assert!(
                    (found - marched).abs() < 0.05 / f64::from(n),
                    "{found} {marched}"
                );
                checked += 1;
            }
        }
        // Only rays that leave a convex surface before any relief are skipped.
        assert!(checked >= 7, "{checked} rays checked");
    }

    #[test]
    fn the_stable_forms_are_the_bend_s() {
        let field = HeightField::new(2, 2, vec![0.0; 4]).unwrap();
        for c in [-0.8, -1e-4, 0.0, 1e-4, 0.4, 2.0] {
            for (theta, tau) in [(0.4, 0.1), (1.2, 0.3), (1.5, 0.05)] {
                let ray = BentRay {
                    relief: Relief {
                        field: &field,
                        depth: 0.1,
                    },
                    top_depth: 0.1,
                    entry: DVec2::ZERO,
                    azimuth: DVec2::X,
                    theta,
                    c,
                };
                let (sigma, t) = ray.at(tau);
                let (s2, t2) = Bend { c }.to_relief(Bend::ray(theta, tau));
                assert!(
                    (sigma - s2).abs() < 1e-9 && (t - t2).abs() < 1e-9,
                    "c {c} θ {theta} τ {tau}: ({sigma}, {t}) against ({s2}, {t2})"
                );
            }
        }
    }

    #[test]
    fn arcs_and_ray_lengths_invert() {
        for c in [-0.8, 0.0, 0.4] {
            for (theta, tau) in [(0.4, 0.1), (1.2, 0.3), (1.5, 0.05)] {
                let (sigma, _) = Bend { c }.to_relief(Bend::ray(theta, tau));
                let back = ray_length_to_arc(sigma, theta, c).unwrap();
                assert!(
                    (back - tau).abs() < 1e-9,
                    "c {c} θ {theta}: {back} against {tau}"
                );
            }
        }
    }
}
