//! The reference surface bent to curvature c along the view's azimuth, in the plane of the
//! view ray and the normal: 2D coordinates (u along the azimuth, w along the outward normal)
//! with the ray's entry point P at the origin. A relief point at arc length σ (along the
//! azimuth, from P) and depth t below the reference surface lies at
//! centre + (R − t)·(sin(σ/R), cos(σ/R)), centre = (0, −R), R = 1/c (negative for concave
//! surfaces, whose centre lies above); for c = 0 at (σ, −t).

/// The bending of one curvature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bend {
    /// The curvature (1/tile).
    pub c: f64,
}

impl Bend {
    /// The 2D point of relief coordinates (σ, t).
    pub fn to_plane(self, sigma: f64, t: f64) -> [f64; 2] {
        let (sin, cos) = (sigma * self.c).sin_cos();
        self.to_plane_turned(sigma, t, [sin, cos])
    }

    /// The same, given sin and cos of σ·c.
    pub fn to_plane_turned(self, sigma: f64, t: f64, [sin, cos]: [f64; 2]) -> [f64; 2] {
        if self.c == 0.0 {
            return [sigma, -t];
        }
        let r = 1.0 / self.c;
        [(r - t) * sin, -r + (r - t) * cos]
    }

    /// The relief coordinates (σ, t) of 2D point `q` (the inverse of [`Bend::to_plane`] for
    /// |σ/R| < π).
    pub fn to_relief(self, q: [f64; 2]) -> (f64, f64) {
        if self.c == 0.0 {
            return (q[0], -q[1]);
        }
        let r = 1.0 / self.c;
        let sign = r.signum();
        let (du, dw) = (q[0], q[1] + r);
        let radius = du.hypot(dw);
        (r * (sign * du).atan2(sign * dw), r - sign * radius)
    }

    /// The point at distance τ along the view ray entering at polar angle θ.
    pub fn ray(theta: f64, tau: f64) -> [f64; 2] {
        let (s, c) = theta.sin_cos();
        [tau * s, -tau * c]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relief_coordinates_round_trip_and_arcs_have_their_length() {
        for c in [-2.0, -0.5, 0.0, 1.0, 3.0] {
            let bend = Bend { c };
            for (sigma, t) in [(0.0, 0.0), (0.3, 0.05), (-0.2, 0.1), (0.7, 0.0)] {
                let (s2, t2) = bend.to_relief(bend.to_plane(sigma, t));
                assert!(
                    (s2 - sigma).abs() < 1e-12 && (t2 - t).abs() < 1e-12,
                    "c {c}"
                );
            }
            // Depth is distance to the bent reference surface: along the normal at P.
            let q = bend.to_plane(0.0, 0.1);
            assert!((q[0]).abs() < 1e-15 && (q[1] + 0.1).abs() < 1e-12);
            // An arc of the reference surface of length 0.5, by chords.
            let n = 10_000;
            let length: f64 = (0..n)
                .map(|m| {
                    let a = bend.to_plane(0.5 * m as f64 / n as f64, 0.0);
                    let b = bend.to_plane(0.5 * (m + 1) as f64 / n as f64, 0.0);
                    (a[0] - b[0]).hypot(a[1] - b[1])
                })
                .sum();
            assert!((length - 0.5).abs() < 1e-7, "c {c}: {length}");
        }
    }
}
