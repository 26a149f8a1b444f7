//! Real spherical harmonics, bands 0–3 (16 coefficients), orthonormal over the unit sphere.
//!
//! **Convention.** Directions are unit vectors ω = (sin θ cos φ, sin θ sin φ, cos θ)
//! ([`mesobake_package::grid::spherical_to_vector`]): θ from
//! +z, φ from +x towards +y (the GDM's direction convention; in texture space +z points out
//! of the surface). Coefficient `i = l(l+1) + m` holds yₗᵐ, m = −l…l. The basis is the real
//! one *without* the Condon–Shortley phase, so y₁ = √(3/4π)·(y, z, x):
//!
//! | i | yₗᵐ(x, y, z) |
//! |---|---|
//! | 0 | ½√(1/π) |
//! | 1, 2, 3 | √(3/4π)·y, √(3/4π)·z, √(3/4π)·x |
//! | 4, 5 | ½√(15/π)·xy, ½√(15/π)·yz |
//! | 6 | ¼√(5/π)·(3z² − 1) |
//! | 7, 8 | ½√(15/π)·xz, ¼√(15/π)·(x² − y²) |
//! | 9 | ¼√(35/2π)·y(3x² − y²) |
//! | 10 | ½√(105/π)·xyz |
//! | 11 | ¼√(21/2π)·y(5z² − 1) |
//! | 12 | ¼√(7/π)·(5z³ − 3z) |
//! | 13 | ¼√(21/2π)·x(5z² − 1) |
//! | 14 | ¼√(105/π)·z(x² − y²) |
//! | 15 | ¼√(35/2π)·x(x² − 3y²) |
//!
//! Being polynomials in (x, y, z), they are exact at the poles (no division by sin θ).
//!
//! **Projection** fₗᵐ = ∫ f·yₗᵐ dω is computed with a [`Quadrature`]: the Gauss–Legendre
//! product rule (n nodes in cos θ, m equal steps in φ) integrates every spherical polynomial of
//! degree < min(2n, m) exactly, so products of two band-≤3 functions (degree 6) need n = 4,
//! m = 8. Discontinuous integrands (visibility) use more nodes; their error is measured.
//!
//! **Rotation.** [`rotation_matrix`] gives the 16×16 matrix that maps the coefficients of f to
//! those of f∘Rᵀ (f rotated by R), computed exactly by the product rule above.

use glam::{DMat3, DVec3};
use std::f64::consts::PI;

/// Coefficients per function: bands 0–3.
pub const COEFFS: usize = mesobake_package::gi::SH_COEFFS;

/// An SH vector (one channel).
pub type Sh = [f64; COEFFS];

/// The 16 basis functions at unit vector `d` (not checked for length).
pub fn eval(d: DVec3) -> Sh {
    let (x, y, z) = (d.x, d.y, d.z);
    let c0 = 0.5 * (1.0 / PI).sqrt();
    let c1 = (3.0 / (4.0 * PI)).sqrt();
    let c2 = 0.5 * (15.0 / PI).sqrt();
    let c20 = 0.25 * (5.0 / PI).sqrt();
    let c22 = 0.25 * (15.0 / PI).sqrt();
    let c33 = 0.25 * (35.0 / (2.0 * PI)).sqrt();
    let c32 = 0.5 * (105.0 / PI).sqrt();
    let c31 = 0.25 * (21.0 / (2.0 * PI)).sqrt();
    let c30 = 0.25 * (7.0 / PI).sqrt();
    let c32b = 0.25 * (105.0 / PI).sqrt();
    let z2 = z * z;
    [
        c0,
        c1 * y,
        c1 * z,
        c1 * x,
        c2 * x * y,
        c2 * y * z,
        c20 * (3.0 * z2 - 1.0),
        c2 * x * z,
        c22 * (x * x - y * y),
        c33 * y * (3.0 * x * x - y * y),
        c32 * x * y * z,
        c31 * y * (5.0 * z2 - 1.0),
        c30 * (5.0 * z2 * z - 3.0 * z),
        c31 * x * (5.0 * z2 - 1.0),
        c32b * z * (x * x - y * y),
        c33 * x * (x * x - 3.0 * y * y),
    ]
}

/// The band l of coefficient `i`.
pub fn band(i: usize) -> usize {
    (i as f64).sqrt() as usize
}

/// Directions with weights that sum to 4π, for integrals over the sphere.
#[derive(Clone, Debug)]
pub struct Quadrature {
    /// (direction, weight in steradians).
    pub nodes: Vec<(DVec3, f64)>,
}

impl Quadrature {
    /// The Gauss–Legendre product rule: `n_theta` Legendre nodes in cos θ times `n_phi` equal
    /// steps in φ; exact for spherical polynomials of degree < min(2·n_theta, n_phi).
    pub fn gauss_legendre(n_theta: usize, n_phi: usize) -> Quadrature {
        let (zs, ws) = gauss_legendre_nodes(n_theta.max(1));
        let n_phi = n_phi.max(1);
        let dphi = 2.0 * PI / n_phi as f64;
        let mut nodes = Vec::with_capacity(zs.len() * n_phi);
        for (&z, &w) in zs.iter().zip(&ws) {
            let s = (1.0 - z * z).max(0.0).sqrt();
            for b in 0..n_phi {
                let phi = (b as f64 + 0.5) * dphi;
                nodes.push((DVec3::new(s * phi.cos(), s * phi.sin(), z), w * dphi));
            }
        }
        Quadrature { nodes }
    }

    /// The smallest product rule that integrates products of two band-≤3 functions exactly.
    pub fn exact_for_products() -> Quadrature {
        Quadrature::gauss_legendre(4, 8)
    }

    /// A product rule for integrands cut at the horizon z = 0 (visibility over a surface):
    /// Gauss–Legendre in cos θ on each hemisphere separately (`n_half` nodes each), `n_phi`
    /// equal steps in φ. A band-limited function times the upper-hemisphere indicator is
    /// integrated exactly once n_half ≥ 4 and n_phi ≥ 8; other edges (occluders) converge as
    /// the node count grows, and that error is measured.
    pub fn hemispheres(n_half: usize, n_phi: usize) -> Quadrature {
        let half = Quadrature::gauss_legendre(n_half, n_phi);
        let nodes = half
            .nodes
            .iter()
            .flat_map(|&(d, w)| {
                // z ∈ [−1, 1] ↦ (1 + z)/2 ∈ [0, 1], keeping the direction a unit vector.
                let z = (1.0 + d.z) / 2.0;
                let s = (1.0 - z * z).max(0.0).sqrt();
                let horizontal = d.truncate().normalize_or_zero() * s;
                let up = DVec3::new(horizontal.x, horizontal.y, z);
                [(up, w / 2.0), (DVec3::new(up.x, up.y, -z), w / 2.0)]
            })
            .collect();
        Quadrature { nodes }
    }

    /// [`Quadrature::hemispheres`] with about `count` nodes (n_phi = 4·n_half).
    pub fn with_about(count: usize) -> Quadrature {
        let n_half = ((count as f64 / 8.0).sqrt().round() as usize).max(1);
        Quadrature::hemispheres(n_half, 4 * n_half)
    }

    /// ∫ f·yᵢ dω for the 16 basis functions.
    pub fn project(&self, mut f: impl FnMut(DVec3) -> f64) -> Sh {
        let mut out = [0.0; COEFFS];
        for &(d, w) in &self.nodes {
            let v = f(d) * w;
            if v != 0.0 {
                let y = eval(d);
                out.iter_mut().zip(y).for_each(|(o, y)| *o += v * y);
            }
        }
        out
    }
}

/// Nodes and weights of the n-point Gauss–Legendre rule on [−1, 1], by Newton's method on
/// Pₙ from Chebyshev starting points (converged to round-off; weights sum to 2).
pub fn gauss_legendre_nodes(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                (p0, p1) = (p1, p2);
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let step = p1 / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = x;
        nodes[n - 1 - i] = -x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    (nodes, weights)
}

/// A 16×16 matrix on SH vectors, row-major: `apply(m, f)ᵢ = Σⱼ mᵢⱼ fⱼ`.
pub type ShMatrix = [[f64; COEFFS]; COEFFS];

/// The matrix taking the coefficients of f to those of g(ω) = f(Rᵀω), the function f rotated
/// by `r` (a rotation; not checked). Exact to round-off (see the module doc), band-diagonal.
pub fn rotation_matrix(r: DMat3) -> ShMatrix {
    transfer_matrix(&Quadrature::exact_for_products(), r.transpose(), |_| 1.0)
}

/// Tᵢⱼ = ∫ yᵢ(ω)·v(ω)·yⱼ(M ω) dω by `quadrature`: the matrix from the coefficients of a
/// function f to those of ω ↦ v(ω)·f(M ω). With v ≡ 1 and M = Rᵀ it is a rotation; the
/// macro-scale PRT uses it with M the local frame and v the visibility.
pub fn transfer_matrix(
    quadrature: &Quadrature,
    m: DMat3,
    mut v: impl FnMut(DVec3) -> f64,
) -> ShMatrix {
    let mut t = [[0.0; COEFFS]; COEFFS];
    for &(d, w) in &quadrature.nodes {
        let vis = v(d) * w;
        if vis == 0.0 {
            continue;
        }
        let (yi, yj) = (eval(d), eval(m * d));
        for (row, &a) in t.iter_mut().zip(&yi) {
            let a = a * vis;
            row.iter_mut().zip(&yj).for_each(|(t, &b)| *t += a * b);
        }
    }
    t
}

/// `m · f`.
pub fn apply(m: &ShMatrix, f: &Sh) -> Sh {
    let mut out = [0.0; COEFFS];
    for (o, row) in out.iter_mut().zip(m) {
        *o = row.iter().zip(f).map(|(a, b)| a * b).sum();
    }
    out
}

/// Σ aᵢ bᵢ: for SH vectors of two functions, the integral of their product.
pub fn dot(a: &Sh, b: &Sh) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The SH vector of the clamped cosine lobe max(ω·n, 0) (Lambert's kernel), in closed form:
/// zonal coefficients √π/2, √(π/3), √(5π)/8, 0 for bands 0–3, rotated to `n` by
/// fₗᵐ = √(4π/(2l+1))·zₗ·yₗᵐ(n).
pub fn clamped_cosine(n: DVec3) -> Sh {
    let zonal = [
        PI.sqrt() / 2.0,
        (PI / 3.0).sqrt(),
        (5.0 * PI).sqrt() / 8.0,
        0.0,
    ];
    let y = eval(n.normalize());
    std::array::from_fn(|i| {
        let l = band(i);
        (4.0 * PI / (2 * l + 1) as f64).sqrt() * zonal[l] * y[i]
    })
}

/// Per band l, the factor Λₗ by which convolving with the normalized Phong lobe
/// h(ω) = (s+1)/(2π)·max(ω·r, 0)^s scales a function's band-l coefficients (Funk–Hecke):
/// ∫ h(ω)·f(ω) dω = Σ Λₗ fₗᵐ yₗᵐ(r), with Λₗ = (s+1)·∫₀¹ tˢ Pₗ(t) dt in closed form.
/// Λ₀ = 1: the lobe integrates to one. `exponent` must be ≥ 0.
pub fn phong_convolution(exponent: f64) -> [f64; 4] {
    let s = exponent;
    [
        1.0,
        (s + 1.0) / (s + 2.0),
        (s + 1.0) * (3.0 / (s + 3.0) - 1.0 / (s + 1.0)) / 2.0,
        (s + 1.0) * (5.0 / (s + 4.0) - 3.0 / (s + 2.0)) / 2.0,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in 1..12 {
            let (x, w) = gauss_legendre_nodes(n);
            for k in 0..2 * n {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let exact = if k % 2 == 1 {
                    0.0
                } else {
                    2.0 / (k + 1) as f64
                };
                assert!((q - exact).abs() < 1e-13, "n={n} k={k}: {q} vs {exact}");
            }
        }
    }

    #[test]
    fn bands_are_indexed_l_squared() {
        let bands: Vec<usize> = (0..COEFFS).map(band).collect();
        assert_eq!(bands, [0, 1, 1, 1, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3]);
    }
}
