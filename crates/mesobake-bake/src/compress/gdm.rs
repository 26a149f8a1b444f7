//! A GDM compressed end to end: truncated SVD in the [`GdmRows`] layout, quantization of both
//! factors, and the accuracy of what a renderer will reconstruct.

use super::accuracy::{Accuracy, measure};
use super::layout::GdmRows;
use super::quantize::{Quantization, QuantizedFactor};
use super::svd::{GramEigen, RankChoice, Truncated};
use crate::gdm::Gdm;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use std::time::Instant;

/// A compressed GDM: its factorization, the quantized factors, and their accuracy.
#[derive(Clone, Debug)]
pub struct CompressedGdm {
    /// How the rank was chosen.
    pub rank_choice: RankChoice,
    /// The unquantized factorization and the spectrum.
    pub svd: Truncated,
    /// Weight maps W (rows (x, y, φ) × rank), quantized.
    pub weights: QuantizedFactor,
    /// Eigenmaps E (columns (θ, z) × rank), quantized.
    pub eigen: QuantizedFactor,
    /// Error of the quantized reconstruction against the GDM it was made from.
    pub accuracy: Accuracy,
    /// Time spent (not part of any package).
    pub seconds: CompressSeconds,
}

/// Seconds spent compressing.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct CompressSeconds {
    /// The SVD's projection step (the shared [`GramEigen`] is not included).
    pub svd: f64,
    /// Quantizing both factors and measuring the reconstruction.
    pub quantize: f64,
}

/// Compresses `gdm` (boundary convention) with `gram`, the [`GramEigen`] of its
/// [`GdmRows`] (computed once, it serves every rank).
pub fn compress(
    gdm: &Gdm,
    gram: &GramEigen,
    rank_choice: RankChoice,
    quantization: Quantization,
    limits: &Limits,
) -> Result<CompressedGdm> {
    let start = Instant::now();
    let svd = gram.truncate(&GdmRows::new(gdm)?, rank_choice, limits)?;
    let svd_s = start.elapsed().as_secs_f64();
    let mut compressed = quantize(gdm, svd, rank_choice, quantization)?;
    compressed.seconds.svd = svd_s;
    Ok(compressed)
}

/// Quantizes the factorization `svd` of `gdm` (boundary convention) and measures it.
pub fn quantize(
    gdm: &Gdm,
    svd: Truncated,
    rank_choice: RankChoice,
    quantization: Quantization,
) -> Result<CompressedGdm> {
    let start = Instant::now();
    let weights = QuantizedFactor::new(&svd.weights, svd.rank, quantization);
    let eigen = QuantizedFactor::new(&svd.eigen, svd.rank, quantization);
    let accuracy = measure(gdm, &weights.dequantize(), &eigen.dequantize(), svd.rank)?;
    Ok(CompressedGdm {
        rank_choice,
        svd,
        weights,
        eigen,
        accuracy,
        seconds: CompressSeconds {
            svd: 0.0,
            quantize: start.elapsed().as_secs_f64(),
        },
    })
}
