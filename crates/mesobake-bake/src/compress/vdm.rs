//! VDM compression as the paper does it: the maximal view polar angle map (MVM) θ_MVM(x, y,
//! φ, c) replaces the VDM's −1 values, and one truncated SVD with shared weights factors
//! A = [A_VDM, A_MVM], rows (φ, y, x), columns (c, θ) for the VDM then (c) for the MVM:
//! d(x, y, θ, φ, c) ≈ Σᵢ Wᵢ(x, y, φ)·E_VDMᵢ(θ, c) over the first `vdm_rank` components and
//! θ_MVM(x, y, φ, c) ≈ Σᵢ Wᵢ(x, y, φ)·E_MVMᵢ(c) over the first `mvm_rank` (the paper: 8 and
//! 4). Both factors are quantized like a GDM's ([`Quantization`]).
//!
//! **MVM.** On the θ grid, a texel's hits at one azimuth and curvature are the bins up to some
//! last one (a convex surface loses the grazing views); θ_MVM is taken halfway between the
//! last bin that hits and the first that does not (π/2 when all hit), so that the decision
//! θ ≤ θ_MVM reproduces every bin's. Each −1 is replaced by the value of the last bin that
//! hits (0 when none does), keeping the VDM continuous along θ for the SVD. A renderer calls a
//! view a silhouette (no hit) when θ_V > θ̃_MVM.

use crate::compress::quantize::{Quantization, QuantizedFactor};
use crate::compress::svd::{BlockOrder, RankChoice, RowSource, truncated_svd};
use crate::vdm::{NO_HIT, Vdm, VdmGrid};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
pub use mesobake_package::vdm::{MAX_VDM_RANK, VdmAccuracy, VdmQuery};
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;

/// The VDM with its −1 values filled, and its MVM, in the SVD's layout.
pub struct VdmMatrix<'a> {
    vdm: &'a Vdm,
    /// The VDM, −1 values replaced (the layout of [`Vdm::values`]).
    filled: Vec<f32>,
    /// θ_MVM per curvature, azimuth and texel: `[(k·Nφ + b)·W·H + t]`.
    mvm: Vec<f32>,
}

impl<'a> VdmMatrix<'a> {
    /// Computes the MVM and fills the VDM's −1 values (see the module documentation).
    pub fn new(vdm: &'a Vdm) -> Self {
        let g = vdm.grid;
        let texels = (vdm.size.0 * vdm.size.1) as usize;
        let (nt, np) = (g.n_theta as usize, g.n_phi as usize);
        let mut filled = vdm.values.clone();
        let mut mvm = vec![0.0f32; g.n_curvature as usize * np * texels];
        for k in 0..g.n_curvature as usize {
            for b in 0..np {
                for t in 0..texels {
                    let at = |a: usize| ((k * nt + a) * np + b) * texels + t;
                    let last = (0..nt).rev().find(|&a| vdm.values[at(a)] != NO_HIT);
                    let theta = match last {
                        Some(a) if a + 1 == nt => FRAC_PI_2,
                        Some(a) => 0.5 * (g.theta(a as u32) + g.theta(a as u32 + 1)),
                        None => 0.0,
                    };
                    mvm[(k * np + b) * texels + t] = theta as f32;
                    let fill = last.map_or(0.0, |a| vdm.values[at(a)]);
                    for a in 0..nt {
                        if filled[at(a)] == NO_HIT {
                            filled[at(a)] = fill;
                        }
                    }
                }
            }
        }
        VdmMatrix { vdm, filled, mvm }
    }

    /// θ_MVM of texel `t` at azimuth `b`, curvature `k`.
    pub fn mvm(&self, t: usize, b: u32, k: u32) -> f32 {
        let texels = (self.vdm.size.0 * self.vdm.size.1) as usize;
        self.mvm[(k as usize * self.vdm.grid.n_phi as usize + b as usize) * texels + t]
    }
}

impl RowSource for VdmMatrix<'_> {
    fn rows(&self) -> usize {
        (self.vdm.size.0 * self.vdm.size.1 * self.vdm.grid.n_phi) as usize
    }

    fn cols(&self) -> usize {
        let g = self.vdm.grid;
        (g.n_curvature * (g.n_theta + 1)) as usize
    }

    /// Column after column: each column's rows are runs of consecutive texels.
    fn read_block(&self, start: usize, out: &mut [f32]) -> BlockOrder {
        let g = self.vdm.grid;
        let texels = (self.vdm.size.0 * self.vdm.size.1) as usize;
        let (nt, np, nc) = (g.n_theta as usize, g.n_phi as usize, g.n_curvature as usize);
        let count = out.len() / self.cols();
        for (c, column) in out.chunks_exact_mut(count).enumerate() {
            let (source, image_of): (&[f32], Box<dyn Fn(usize) -> usize>) = if c < nc * nt {
                (&self.filled, Box::new(move |b| c * np + b))
            } else {
                (&self.mvm, Box::new(move |b| (c - nc * nt) * np + b))
            };
            let mut row = start;
            let mut written = 0;
            while written < count {
                let (b, t) = (row / texels, row % texels);
                let run = (texels - t).min(count - written);
                let from = image_of(b) * texels + t;
                column[written..written + run].copy_from_slice(&source[from..from + run]);
                (row, written) = (row + run, written + run);
            }
        }
        BlockOrder::ColumnMajor
    }
}

/// A compressed VDM: the joint factorization, its quantized factors and accuracy.
#[derive(Clone, Debug)]
pub struct CompressedVdm {
    /// Texels and grid of the VDM.
    pub size: (u32, u32),
    /// The view and curvature grid.
    pub grid: VdmGrid,
    /// Components of the VDM's reconstruction.
    pub vdm_rank: usize,
    /// Components of the MVM's reconstruction (≤ `vdm_rank`).
    pub mvm_rank: usize,
    /// All singular values of the matrix, descending.
    pub spectrum: Vec<f64>,
    /// W, rows (φ, y, x), quantized.
    pub weights: QuantizedFactor,
    /// E, rows: the VDM's columns (c, θ), then the MVM's (c), quantized.
    pub eigen: QuantizedFactor,
    /// Measured against the VDM it was made from.
    pub accuracy: VdmAccuracy,
}

/// Compresses `vdm`: MVM, joint SVD to `vdm_rank` components (the MVM uses the first
/// `mvm_rank`), quantization to `q`, and the accuracy of what a renderer reconstructs.
pub fn compress(
    vdm: &Vdm,
    vdm_rank: usize,
    mvm_rank: usize,
    q: Quantization,
    limits: &Limits,
) -> Result<CompressedVdm> {
    if !(1..=MAX_VDM_RANK).contains(&vdm_rank) || !(1..=vdm_rank).contains(&mvm_rank) {
        return Err(Error::InvalidParameter(format!(
            "VDM ranks: the VDM's must be 1 to {MAX_VDM_RANK} and the MVM's 1 to the VDM's, \
             got {vdm_rank} and {mvm_rank}"
        )));
    }
    let matrix = VdmMatrix::new(vdm);
    let svd = truncated_svd(&matrix, RankChoice::Rank(vdm_rank), limits)?;
    let k = svd.rank;
    let weights = QuantizedFactor::new(&svd.weights, k, q);
    let eigen = QuantizedFactor::new(&svd.eigen, k, q);
    let mut compressed = CompressedVdm {
        size: vdm.size,
        grid: vdm.grid,
        vdm_rank: k,
        mvm_rank: mvm_rank.min(k),
        spectrum: svd.spectrum,
        weights,
        eigen,
        accuracy: VdmAccuracy::default(),
    };
    compressed.accuracy = compressed.measure(vdm);
    Ok(compressed)
}

impl CompressedVdm {
    /// The dequantized factors, ready for queries.
    pub fn decode(&self) -> VdmQuery {
        VdmQuery::new(
            self.size,
            self.grid,
            self.mvm_rank,
            &self.weights,
            &self.eigen,
        )
        .with_rmse(self.accuracy.rmse)
    }

    /// Compares every sample's reconstruction with `vdm`: the images (curvature, view) in
    /// parallel, their sums added in image order, so that the figures do not depend on the
    /// number of threads.
    fn measure(&self, vdm: &Vdm) -> VdmAccuracy {
        let decoded = self.decode();
        let g = self.grid;
        let (n_theta, n_phi) = (g.n_theta, g.n_phi);
        let images = g.n_curvature * n_theta * n_phi;
        // Per image: samples, silhouette flips, samples both call hits, Σ error², max error.
        let per_image: Vec<(u64, u64, u64, f64, f64)> = (0..images)
            .into_par_iter()
            .map(|image| {
                let (k, a, b) = (
                    image / (n_theta * n_phi),
                    image / n_phi % n_theta,
                    image % n_phi,
                );
                let mut sums = (0, 0, 0, 0.0, 0.0f64);
                for j in 0..self.size.1 {
                    for i in 0..self.size.0 {
                        let truth = vdm.get(i, j, a, b, k);
                        sums.0 += 1;
                        match (truth == NO_HIT, decoded.distance(i, j, a, b, k)) {
                            (true, None) => {}
                            (false, Some(d)) => {
                                let err = f64::from(d - truth).abs();
                                sums.2 += 1;
                                sums.3 += err * err;
                                sums.4 = sums.4.max(err);
                            }
                            _ => sums.1 += 1,
                        }
                    }
                }
                sums
            })
            .collect();
        let mut acc = VdmAccuracy::default();
        let (mut both, mut sum_sq) = (0u64, 0.0);
        for (samples, flips, hits, squares, max_abs) in per_image {
            acc.samples += samples;
            acc.silhouette_flips += flips;
            both += hits;
            sum_sq += squares;
            acc.max_abs = acc.max_abs.max(max_abs);
        }
        acc.flip_rate = acc.silhouette_flips as f64 / acc.samples.max(1) as f64;
        acc.rmse = (sum_sq / both.max(1) as f64).sqrt();
        acc
    }
}
