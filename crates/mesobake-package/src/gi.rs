//! The radiance-transfer sections of a package: the compressed RTV as a sample-index volume, a
//! weight buffer and an eigenfunction buffer, and the macro-scale PRT as one buffer of 16×16
//! matrices (see `docs/package-format.md`).

use crate::grid::{Dims, DirectionGrid};
use crate::manifest::{GiInfo, TexelFormat, Texture, TextureDimension};

/// Spherical-harmonic coefficients of the light and view bases (order 4).
pub const SH_COEFFS: usize = 16;
/// Matrices per RTV sample: 3 colour channels × [`SH_COEFFS`] light coefficients.
pub const RTV_MATRICES: usize = 3 * SH_COEFFS;
/// Most SVD components per RTV matrix: the view basis has 16 functions, so 16 is exact.
pub const MAX_RTV_RANK: usize = SH_COEFFS;

/// Section holding the sample index of every voxel (`u32::MAX`: not a sample).
pub const RTV_INDEX: &str = "rtv.index";
/// Section holding the weights of every sample, matrix and component.
pub const RTV_WEIGHTS: &str = "rtv.weights";
/// Section holding the eigenfunctions over the view bins.
pub const RTV_EIGEN: &str = "rtv.eigen";
/// Section holding the per-vertex PRT matrices.
pub const PRT_TRANSFER: &str = "prt.transfer";

/// The four GI sections' textures for `info` on the package's grids, in file order.
pub fn textures(info: &GiInfo, dims: Dims, dirs: DirectionGrid) -> [(&'static str, Texture); 4] {
    let texture = |dimension, format, width, height, depth| Texture {
        dimension,
        format,
        width,
        height,
        depth,
    };
    use TexelFormat::{R16float, R32float, R32uint};
    use TextureDimension::{Buffer, D3};
    let per_sample = (RTV_MATRICES * info.compression.rank) as u32;
    let eigen = per_sample.saturating_mul(dirs.n_theta * dirs.n_phi);
    let buffer = |format, len| texture(Buffer, format, len, 1, 1);
    [
        (RTV_INDEX, texture(D3, R32uint, dims.x, dims.y, dims.z)),
        (
            RTV_WEIGHTS,
            buffer(R16float, info.samples.saturating_mul(per_sample)),
        ),
        (RTV_EIGEN, buffer(R16float, eigen)),
        (
            PRT_TRANSFER,
            buffer(
                R32float,
                info.vertices.saturating_mul((SH_COEFFS * SH_COEFFS) as u32),
            ),
        ),
    ]
}
