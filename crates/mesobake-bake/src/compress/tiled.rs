//! Blockwise SVD of a GDM: the paper's matrix layout cut into tiles of T×T texels over (x, y),
//! each tile with its own truncated SVD and quantized factors — the classic improvement over
//! one global basis (Sloan et al. 2003 cluster texels by content for PRT; tiles cluster them by
//! position, which a shader can find without an index). At rank k the weight maps take as
//! many bytes as the global SVD's; each tile adds its own eigenmaps (Nθ·Z·k values) and
//! decode table. Evaluated against the paper's layout in `mesobake report codecs`; not a
//! package codec.

use super::accuracy::{Accuracy, measure_dense};
use super::quantize::{Quantization, QuantizedFactor};
use super::svd::{DenseRows, GramEigen, RankChoice, gemm};
use crate::gdm::{EscapeConvention, Gdm};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;

/// A GDM compressed tile by tile.
pub struct TiledSvd {
    /// Per tile (x fastest): weight maps, rows (φ, y, x) within the tile, and eigenmaps, rows
    /// (θ, z).
    pub tiles: Vec<(QuantizedFactor, QuantizedFactor)>,
    /// Tile side T in texels.
    pub tile: u32,
    /// The dense reconstruction with the escape rule applied (escapes +∞): what a shader
    /// reconstructing each interpolation corner from its own tile's factors sees.
    pub reconstruction: Gdm,
    /// Error of the reconstruction against the GDM, with its escape margin.
    pub accuracy: Accuracy,
}

impl TiledSvd {
    /// Bytes the factors take, with a per-component scale and bias (f32) per factor and tile.
    pub fn bytes(&self) -> u64 {
        self.tiles
            .iter()
            .map(|(w, e)| {
                ((w.rows + e.rows) * w.rank * w.format.bytes() + 2 * 2 * 4 * w.rank) as u64
            })
            .sum()
    }
}

/// Compresses `gdm` (boundary convention) in tiles of `tile`×`tile` texels, rank `rank` per
/// tile, factors quantized with `quantization`.
pub fn compress_tiled(
    gdm: &Gdm,
    tile: u32,
    rank: usize,
    quantization: Quantization,
    limits: &Limits,
) -> Result<TiledSvd> {
    let (dims, dirs) = (gdm.dims(), gdm.dirs());
    if gdm.escape_convention() != EscapeConvention::Boundary {
        return Err(Error::InvalidParameter(
            "compress the GDM with escapes replaced by the boundary distance".into(),
        ));
    }
    if tile == 0 || !dims.x.is_multiple_of(tile) || !dims.y.is_multiple_of(tile) {
        return Err(Error::InvalidParameter(format!(
            "tiles of {tile} texels do not divide the {dims} grid"
        )));
    }
    let (t, n_phi) = (tile as usize, dirs.n_phi as usize);
    let cols = (dirs.n_theta * dims.z) as usize;
    let rows = t * t * n_phi;
    limits.check("a tile's matrix", (rows * cols) as u64, 8)?;
    let mut recon = vec![0.0f32; gdm.data().len()];
    let mut tiles = Vec::new();
    for ty in 0..dims.y / tile {
        for tx in 0..dims.x / tile {
            // Row (b·T + jj)·T + ii, column a·Z + k.
            let at = |r: usize, c: usize| {
                let (ii, jj, b) = (r % t, r / t % t, r / (t * t));
                let (k, a) = (c % dims.z as usize, c / dims.z as usize);
                let (i, j) = (tx * tile + ii as u32, ty * tile + jj as u32);
                gdm.index(i, j, k as u32, a as u32, b as u32)
            };
            let mut matrix = vec![0.0f32; rows * cols];
            for (r, row) in matrix.chunks_exact_mut(cols).enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = gdm.data()[at(r, c)];
                }
            }
            let source = DenseRows::new(&matrix, cols)?;
            let svd = GramEigen::new(&source, limits)?.truncate(
                &source,
                RankChoice::Rank(rank),
                limits,
            )?;
            let w = QuantizedFactor::new(&svd.weights, svd.rank, quantization);
            let e = QuantizedFactor::new(&svd.eigen, svd.rank, quantization);
            let (wd, ed, k) = (w.dequantize(), e.dequantize(), svd.rank);
            let mut block = vec![0.0f32; rows * cols];
            if k > 0 {
                gemm(
                    rows,
                    k,
                    cols,
                    (&wd, k, 1),
                    (&ed, 1, k),
                    (&mut block, cols, 1),
                );
            }
            for (r, row) in block.chunks_exact(cols).enumerate() {
                for (c, &v) in row.iter().enumerate() {
                    recon[at(r, c)] = v;
                }
            }
            tiles.push((w, e));
        }
    }
    let accuracy = measure_dense(gdm, &recon)?;
    let boundary = Gdm::from_values(dims, dirs, EscapeConvention::Boundary, recon)?;
    let reconstruction = super::accuracy::resolve_escapes(boundary, accuracy.escape_margin)?;
    Ok(TiledSvd {
        tiles,
        tile,
        reconstruction,
        accuracy,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gdm::volume_caster::VolumeCaster;
    use crate::mesostructure::samples::{SampleKind, volume};
    use mesobake_package::grid::{Dims, DirectionGrid};

    fn chain_gdm() -> Gdm {
        let limits = Limits::default();
        let v = volume(SampleKind::Chain, Dims::new(16, 16, 8).unwrap(), &limits).unwrap();
        let dirs = DirectionGrid::new(4, 8).unwrap();
        let mut g = crate::gdm::exact::bake(&VolumeCaster::new(&v), dirs, &limits, &()).unwrap();
        g.set_escape_convention(EscapeConvention::Boundary);
        g
    }

    #[test]
    fn full_rank_tiles_reconstruct_the_gdm_and_one_tile_is_the_global_svd() {
        let g = chain_gdm();
        let limits = Limits::default();
        // Rank 32 = min(8·8·8 rows, 4·8 columns): every tile exact up to f32 round-off.
        let full = compress_tiled(&g, 8, 32, Quantization::F32, &limits).unwrap();
        assert_eq!(full.tiles.len(), 4);
        assert_eq!(full.accuracy.flips, 0);
        assert!(full.accuracy.max_abs < 1e-3, "{:?}", full.accuracy);
        // One tile covering the grid is the paper's global SVD: same error as compress::gdm.
        let one = compress_tiled(&g, 16, 4, Quantization::F32, &limits).unwrap();
        let gram =
            GramEigen::new(&crate::compress::layout::GdmRows::new(&g).unwrap(), &limits).unwrap();
        let global = crate::compress::gdm::compress(
            &g,
            &gram,
            RankChoice::Rank(4),
            Quantization::F32,
            &limits,
        )
        .unwrap();
        let (a, b) = (one.accuracy, global.accuracy);
        assert!((a.rmse - b.rmse).abs() <= 1e-3 * b.rmse, "{a:?} vs {b:?}");
        assert_eq!(a.flips, b.flips);
        // Smaller tiles at the same rank fit better (tiles of 4: the chain at this size repeats
        // every 8 texels, so tiles of 8 would all share the global basis).
        let tiled = compress_tiled(&g, 4, 4, Quantization::F32, &limits).unwrap();
        assert!(
            tiled.accuracy.rmse < one.accuracy.rmse,
            "{:?} vs {:?}",
            tiled.accuracy,
            one.accuracy
        );
        assert!(compress_tiled(&g, 5, 4, Quantization::F32, &limits).is_err());
    }
}
