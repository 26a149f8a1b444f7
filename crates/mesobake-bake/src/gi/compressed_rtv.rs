//! The RTV as packages hold it, in the paper's layout: for each RGB channel c and light SH
//! coefficient i (matrix m = 16·c + i), the transfer values over rows = sample voxels (x, y, z)
//! and columns = view directions (θ, φ) at the centres of the GDM's direction bins,
//! Mₘ[s, v] = y(v)ᵀ·A_s,c[·, i] ([`Rtv::transfer`]), are factored by a truncated SVD
//! Mₘ ≈ Wₘ·Eₘᵀ of rank r ≤ [`MAX_RTV_RANK`] (the paper keeps 4; 16 is exact, the view
//! dependence being band-3 SH): weights Wₘₖ(s) per sample and
//! eigenfunctions Eₘₖ(θ, φ), both rounded to f16. Fewer components are stored when the rest
//! vanish in every matrix (a Lambertian RTV is view-independent: rank 1).
//!
//! **The SVD is exact and cheap.** Each row of Mₘ is a band-3 SH function of the view, so
//! Mₘ = C·Yᵀ with C[s, j] = A_s,c[j, i] and Y[v, j] = yⱼ(v). With the thin QR factorization
//! Y = Q·R, Mₘ = (C·Rᵀ)·Qᵀ and Q has orthonormal columns, so the singular values and right
//! factors of Mₘ are those of K = C·Rᵀ (samples × 16), found from the 16×16 Gram matrix KᵀK
//! in f64: E = Q·V, W = K·V. The error after f16 rounding is also exact, from the same small
//! matrices: ‖M − W̃Ẽᵀ‖² = ‖K‖² − 2·Σₖ W̃ₖᵀ·K·(QᵀẼ)ₖ + Σₖₗ (W̃ᵀW̃)ₖₗ(ẼᵀẼ)ₖₗ.
//!
//! **Reading** the transfer at texture point t towards view v: each eigenfunction bilinear over
//! the view bins ([`bilinear_direction_corners`]: θ clamped, φ periodic), the weights
//! interpolated over the sample voxels around t ([`interpolate_samples`]), then
//! T_c,i = Σₖ Wₘₖ·Eₘₖ(v).

use super::rtv::{Rtv, interpolate_samples};
use super::sh::{self, COEFFS, Sh};
use glam::DVec3;
use half::f16;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid, bilinear_direction_corners};
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;
use std::time::Instant;

pub use mesobake_package::gi::MAX_RTV_RANK;

/// Singular values below this fraction of the largest are treated as zero when choosing
/// how many components to store.
const NEGLIGIBLE: f64 = 1e-6;

/// Matrices per RTV: 3 channels × 16 light coefficients.
pub const MATRICES: usize = mesobake_package::gi::RTV_MATRICES;

/// A compressed RTV.
#[derive(Clone, Debug)]
pub struct CompressedRtv {
    dims: Dims,
    dirs: DirectionGrid,
    rank: usize,
    sample_of: Vec<u32>,
    /// Component k of sample s, matrix m at (s·[`MATRICES`] + m)·rank + k.
    weights: Vec<f32>,
    /// Component k of matrix m at view bin (a, b) at (m·views + a·Nφ + b)·rank + k.
    eigen: Vec<f32>,
}

pub use mesobake_package::manifest::RtvCompression;

impl CompressedRtv {
    /// Compresses `rtv` sampled on the view grid `dirs` to `rank` components per matrix;
    /// returns it with its measured error and the seconds taken.
    pub fn compress(
        rtv: &Rtv,
        dirs: DirectionGrid,
        rank: usize,
        limits: &Limits,
    ) -> Result<(CompressedRtv, RtvCompression, f64)> {
        if !(1..=MAX_RTV_RANK).contains(&rank) {
            return Err(Error::InvalidParameter(format!(
                "the RTV rank must be 1 to {MAX_RTV_RANK}, got {rank}"
            )));
        }
        let start = Instant::now();
        let samples = rtv.voxels().len();
        let views = dirs.count();
        limits.check(
            "compressed RTV",
            (samples * MATRICES + views * MATRICES) as u64,
            (MAX_RTV_RANK * 4 + COEFFS * 8) as u64,
        )?;
        let y = DMatrix::from_fn(views, COEFFS, |v, j| {
            sh::eval(DVec3::from(dirs.vector_of(v)))[j]
        });
        let qr = y.qr();
        let (q, r) = (qr.q(), qr.r());
        let factored: Vec<Factored> = (0..MATRICES)
            .into_par_iter()
            .map(|m| factor(rtv, m, &q, &r, rank))
            .collect();
        // Components whose singular values vanish in every matrix are not stored (a
        // Lambertian RTV is view-independent: rank 1).
        let largest = factored
            .iter()
            .filter_map(|f| f.spectrum.first())
            .fold(0.0f64, |a, &b| a.max(b));
        let rank = (1..=rank)
            .rev()
            .find(|&k| {
                factored.iter().any(|f| {
                    f.spectrum
                        .get(k - 1)
                        .is_some_and(|&s| s > NEGLIGIBLE * largest)
                })
            })
            .unwrap_or(1);
        let mut weights = vec![0.0; samples * MATRICES * rank];
        let mut eigen = vec![0.0; views * MATRICES * rank];
        let (mut total, mut error, mut optimal) = (0.0, 0.0, 0.0);
        let mut spectra = Vec::with_capacity(MATRICES);
        for (m, f) in factored.into_iter().enumerate() {
            for (s, w) in f.weights.chunks(f.kept).enumerate() {
                weights[(s * MATRICES + m) * rank..][..rank].copy_from_slice(&w[..rank]);
            }
            for (v, e) in f.eigen.chunks(f.kept).enumerate() {
                eigen[(m * views + v) * rank..][..rank].copy_from_slice(&e[..rank]);
            }
            total += f.norm2;
            error += f.error2;
            optimal += f.spectrum.iter().skip(rank).map(|s| s * s).sum::<f64>();
            spectra.push(f.spectrum);
        }
        let entries = (samples * views * MATRICES).max(1) as f64;
        let stats = RtvCompression {
            rank,
            rmse: (error.max(0.0) / entries).sqrt(),
            relative_rmse: (error.max(0.0) / total.max(f64::MIN_POSITIVE)).sqrt(),
            svd_rmse: (optimal / entries).sqrt(),
            spectra,
        };
        let compressed = CompressedRtv {
            dims: rtv.dims(),
            dirs,
            rank,
            sample_of: rtv.sample_map().to_vec(),
            weights,
            eigen,
        };
        Ok((compressed, stats, start.elapsed().as_secs_f64()))
    }

    /// Assembles a compressed RTV from its parts (as a package stores them), checking that
    /// they fit together: the sample map covers the grid and names samples in range, and
    /// every component is finite.
    pub fn from_parts(
        dims: Dims,
        dirs: DirectionGrid,
        rank: usize,
        sample_of: Vec<u32>,
        weights: Vec<f32>,
        eigen: Vec<f32>,
    ) -> Result<CompressedRtv> {
        let bad = |what: String| Err(Error::Package(format!("RTV: {what}")));
        if !(1..=MAX_RTV_RANK).contains(&rank) {
            return bad(format!("rank {rank} is not 1 to {MAX_RTV_RANK}"));
        }
        if sample_of.len() as u64 != dims.voxel_count() {
            return bad(format!(
                "the sample map has {} entries for {dims} voxels",
                sample_of.len()
            ));
        }
        if !weights.len().is_multiple_of(MATRICES * rank)
            || eigen.len() != dirs.count() * MATRICES * rank
        {
            return bad("the weights or eigenfunctions have the wrong length".into());
        }
        let samples = weights.len() / (MATRICES * rank);
        if let Some(s) = sample_of
            .iter()
            .find(|&&s| s != super::rtv::NO_SAMPLE && s as usize >= samples)
        {
            return bad(format!("the sample map names sample {s} of {samples}"));
        }
        if weights.iter().chain(&eigen).any(|v| !v.is_finite()) {
            return bad("a weight or eigenfunction value is not finite".into());
        }
        Ok(CompressedRtv {
            dims,
            dirs,
            rank,
            sample_of,
            weights,
            eigen,
        })
    }

    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// The view grid of the eigenfunctions.
    pub fn dirs(&self) -> DirectionGrid {
        self.dirs
    }

    /// Components per matrix.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Per voxel (x fastest), its sample index or [`super::rtv::NO_SAMPLE`].
    pub fn sample_map(&self) -> &[u32] {
        &self.sample_of
    }

    /// The weights: component k of sample s, matrix m at (s·[`MATRICES`] + m)·rank + k.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// The eigenfunctions: component k of matrix m at view bin (a, b) at
    /// (m·views + a·Nφ + b)·rank + k.
    pub fn eigen(&self) -> &[f32] {
        &self.eigen
    }

    /// Every eigenfunction at view `view` (unit, texture space), bilinear over the bins:
    /// component k of matrix m at m·rank + k.
    fn eigen_at(&self, view: DVec3) -> Vec<f64> {
        let (views, rank) = (self.dirs.count(), self.rank);
        let corners = bilinear_direction_corners(self.dirs, view.to_array());
        let mut out = vec![0.0; MATRICES * rank];
        for (m, e) in out.chunks_mut(rank).enumerate() {
            for ([a, b], w) in corners {
                let v = m * views + (a * self.dirs.n_phi + b) as usize;
                e.iter_mut()
                    .zip(&self.eigen[v * rank..][..rank])
                    .for_each(|(e, &s)| *e += w * f64::from(s));
            }
        }
        out
    }

    /// The transfer of sample `s` given the eigenfunctions at the view.
    fn transfer_with(&self, s: usize, eigen: &[f64]) -> [Sh; 3] {
        let rank = self.rank;
        let w = &self.weights[s * MATRICES * rank..][..MATRICES * rank];
        std::array::from_fn(|c| {
            std::array::from_fn(|i| {
                let m = c * COEFFS + i;
                w[m * rank..][..rank]
                    .iter()
                    .zip(&eigen[m * rank..][..rank])
                    .map(|(&w, e)| f64::from(w) * e)
                    .sum()
            })
        })
    }

    /// The transfer vector of sample `s` towards `view`: per channel, 16 light weights.
    pub fn transfer(&self, s: usize, view: DVec3) -> [Sh; 3] {
        self.transfer_with(s, &self.eigen_at(view))
    }

    /// The transfer vector towards `view` at texture point `t` (voxel units).
    pub fn interpolate(&self, t: DVec3, view: DVec3) -> Option<[Sh; 3]> {
        let eigen = self.eigen_at(view);
        interpolate_samples(self.dims, &self.sample_of, t, |s| {
            self.transfer_with(s, &eigen)
        })
    }
}

/// One matrix's factors, rounded to f16 (`kept` components per row, row-major), with its
/// squared norm and squared error.
struct Factored {
    kept: usize,
    weights: Vec<f32>,
    eigen: Vec<f32>,
    spectrum: Vec<f64>,
    norm2: f64,
    error2: f64,
}

/// Factors matrix `m` of `rtv` (see the module doc) given the thin QR of the view basis.
fn factor(rtv: &Rtv, m: usize, q: &DMatrix<f64>, r: &DMatrix<f64>, rank: usize) -> Factored {
    let (c, i) = (m / COEFFS, m % COEFFS);
    let samples = rtv.voxels().len();
    let p = r.nrows();
    let coefficients =
        DMatrix::from_fn(samples, COEFFS, |s, j| f64::from(rtv.matrices(s)[c][j][i]));
    let k = coefficients * r.transpose();
    let gram = k.transpose() * &k;
    let eigen = SymmetricEigen::new(gram.clone());
    let mut order: Vec<usize> = (0..p).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let spectrum: Vec<f64> = order
        .iter()
        .map(|&o| eigen.eigenvalues[o].max(0.0).sqrt())
        .collect();
    let kept = rank.min(p);
    let mut v = DMatrix::from_fn(p, kept, |row, col| eigen.eigenvectors[(row, order[col])]);
    // A deterministic sign: each eigenfunction's largest entry is positive.
    let mut e = q * &v;
    for col in 0..kept {
        let column = e.column(col);
        let largest = column
            .iter()
            .fold(0.0f64, |a, &x| if x.abs() > a.abs() { x } else { a });
        if largest < 0.0 {
            e.column_mut(col).neg_mut();
            v.column_mut(col).neg_mut();
        }
    }
    let w = &k * &v;
    let round = |x: f64| f16::from_f64(x).to_f64();
    let w = w.map(round);
    let e = e.map(round);
    let cross: f64 = (&k * (q.transpose() * &e)).component_mul(&w).sum();
    let norm2 = gram.trace();
    let error2 = norm2 - 2.0 * cross
        + (w.transpose() * &w)
            .component_mul(&(e.transpose() * &e))
            .sum();
    let rows = |mat: &DMatrix<f64>| -> Vec<f32> {
        (0..mat.nrows())
            .flat_map(|r| (0..kept).map(move |c| (r, c)))
            .map(|(r, c)| mat[(r, c)] as f32)
            .collect()
    };
    Factored {
        kept,
        weights: rows(&w),
        eigen: rows(&e),
        spectrum,
        norm2,
        error2,
    }
}
